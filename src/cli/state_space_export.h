#pragma once
// Writing a state space to files (a file-format edge, so it lives with the command line).

#include <string>
#include <vector>

#include "stagefit/model/linear_system.h"
#include "stagefit/model/state_space.h"

namespace stagefit::cli {

/// `out` ending in .mat: one MATLAB file with A, B, C, D, M, C_damping, K (plain double arrays) and
/// state_names, input_names, output_names, dof_names (cell arrays of char). Otherwise CSV: files
/// <stem>_A.csv ... <stem>_K.csv, each with a header row of column names and the row name first.
/// Returns the paths written. Every file is written atomically.
std::vector<std::string> WriteStateSpace(const std::string& out, const model::StateSpace& ss,
                                         const model::SecondOrderSystem& system);

/// The paths WriteStateSpace(out, ...) writes, to check them against the inputs beforehand.
std::vector<std::string> StateSpaceFiles(const std::string& out);

}  // namespace stagefit::cli
