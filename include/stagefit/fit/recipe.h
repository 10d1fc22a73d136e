#pragma once
// Fit recipes: a TOML file that fixes what `stagefit fit` does, so that a fit can be repeated
// (fitting/recipe-*.toml; docs/fitting.md). Every key is optional; command-line options override them.
//
//     measurement = "../measurements/compliance.mat"   # relative to the recipe's folder
//     model = "tuned.toml"                              # default: the embedded micro-station
//     space = "compliance"                              # compliance | bodies | raw
//     band = ["5 Hz", "700 Hz"]                         # numbers are Hz
//     significance = 0.1                                # compare::ComparisonOptions threshold
//     params = ["*.k.*"]                                # patterns of the free parameters
//     solver = "ceres"                                  # ceres | nlopt
//     jacobian = "analytic"                             # analytic | finite-difference
//     nlopt_algorithm = "LN_BOBYQA"
//     nlopt_max_evaluations = 4000
//     polish = true                                     # NLopt result finished by Ceres
//     starts = 1
//     start_factor = 1.6
//     seed = 1
//     max_iterations = 100
//     [[bounds]]                                        # in order; later rules override earlier ones
//     pattern = "hexapod.k.R?"
//     lower = "0.2 Nm/urad"                             # unit strings, or bare SI numbers
//     upper = "10 Nm/urad"
//     [[bounds]]
//     pattern = "granite.k.*"
//     factor = 10

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "stagefit/compare/residuals.h"
#include "stagefit/fit/least_squares.h"
#include "stagefit/fit/model_fit.h"

namespace stagefit::fit {

/// A parsed recipe: the values it sets, on top of the defaults. The `has_*` flags tell which keys the
/// file gave, so that the command line can override exactly those.
struct FitRecipe {
  std::string source;                   ///< the file, for messages
  std::string measurement;              ///< resolved against the recipe's folder; empty = not given
  std::string model;                    ///< likewise
  compare::ComparisonOptions comparison;
  bool space_given = false;             ///< the recipe names the comparison space
  std::vector<std::string> params;      ///< empty = not given
  std::vector<BoundRule> bounds;
  FitOptions options;
};

/// Parses recipe text. `source` names the file in messages; relative paths are resolved against
/// `base_folder`. Collects every problem (TOML syntax, unknown keys, wrong types, values out of range,
/// unknown solver / space / NLopt algorithm, units of the wrong dimension) and throws one InputError
/// listing them, each as "<source>:<line>: <key> = <value>, expected ...".
FitRecipe ParseFitRecipe(std::string_view text, const std::string& source,
                         const std::filesystem::path& base_folder = {});

/// Reads and parses a recipe file; throws InputError when it cannot be read or is invalid.
FitRecipe ReadFitRecipe(const std::filesystem::path& path);

}  // namespace stagefit::fit
