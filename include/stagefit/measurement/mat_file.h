#pragma once
// MATLAB .mat files through matio: a generic reader/writer of plain variables (double matrices,
// complex double matrices, char strings, cell arrays of char) and the measurement layout of SPEC §3.
// Both the v5 format and the HDF5-based v7.3 format are read and written (the latter needs a matio
// built with HDF5, see IsMatV73Supported()).

#include <Eigen/Core>

#include <filesystem>
#include <string>
#include <variant>
#include <vector>

#include "stagefit/measurement/frf_data.h"

namespace stagefit::measurement {

/// File format written by WriteMatFile.
enum class MatVersion {
  kV5,   ///< MATLAB 5 (readable by every MATLAB and Octave), uncompressed
  kV73,  ///< MATLAB 7.3, an HDF5 file (needed for variables above 2 GB)
};

/// One variable's value: a real or complex double matrix (rows x cols), a string (a 1 x n char
/// array), or a list of strings (a 1 x n cell array of char row vectors).
using MatValue = std::variant<Eigen::MatrixXd, Eigen::MatrixXcd, std::string,
                              std::vector<std::string>>;

/// A named top-level variable of a .mat file.
struct MatVariable {
  std::string name;  ///< a MATLAB identifier: a letter, then letters, digits, '_'; <= 63 characters
  MatValue value;
};

/// True when this build's matio can create v7.3 (HDF5) files.
bool IsMatV73Supported();

/// Writes the variables to `path` atomically (matio writes a TemporaryPath beside it, which is then
/// renamed over `path`). Matrices are stored as double (or complex double) arrays, strings as
/// char arrays, lists of strings as 1 x n cell arrays of char.
/// Values are written as they are (NaN and Inf included). Throws InputError for an invalid or
/// repeated variable name, for v7.3 when matio lacks HDF5 support, and when the file cannot be
/// written.
void WriteMatFile(const std::filesystem::path& path, const std::vector<MatVariable>& variables,
                  MatVersion version = MatVersion::kV5);

/// Reads every top-level variable of a v5 (compressed or not) or v7.3 file, in file order (v7.3:
/// in HDF5's order, which is by name).
/// Numeric classes (double, single, integers, logical) become MatrixXd / MatrixXcd; a 1 x n (or
/// empty) char array becomes a string; a char matrix with several rows becomes a list of its rows
/// (trailing blanks removed); a cell array whose elements are all char becomes a list of strings.
/// Throws InputError naming the file and the variable for: a file that is not a .mat file, a
/// variable of another class (struct, sparse, function handle, cell holding non-char), a numeric
/// array of more than two dimensions, a declared size the file cannot hold, and a read failure.
std::vector<MatVariable> ReadMatFile(const std::filesystem::path& path);

/// Reads a measurement in the SPEC §3 layout: freq_hz (Nf x 1 or 1 x Nf, Hz), frf (Nout x Nin x Nf,
/// complex; real is accepted as a zero imaginary part; with Nf = 1 it may be Nout x Nin), quantity,
/// and the optional coherence, output_names, input_names, sensor_body, sensor_position (Nout x 3,
/// m), sensor_direction (Nout x 3), impact_body, impact_position (Nin x 3, m), impact_direction
/// (Nin x 3), frame_origin (1 x 3 or 3 x 1, m). Channel names default to "out1".."outN" and
/// "in1".."inM". The geometry of a side (sensor_* or impact_*) is all present or all absent; absent
/// means unknown (has_geometry() false) unless `require_geometry`.
/// Throws InputError naming the file, the variable and what was expected for: a missing required
/// variable, wrong sizes or classes, an unknown quantity, partial or (with `require_geometry`)
/// absent geometry, and every Validate() failure (non-monotonic or non-finite frequencies, NaN or
/// Inf in the FRF, coherence outside [0, 1], non-unit directions, dead channels).
FrfData ReadMatMeasurement(const std::filesystem::path& path, bool require_geometry = false);

/// Writes `data` in the SPEC §3 layout (atomically). Geometry variables are written for a side when
/// every channel of it has geometry; sensor_body/impact_body is a char when all channels share one
/// body, else a cell. Coherence and frame_origin are written when present.
/// Throws InputError when Validate(data) fails, when only some channels of a side have geometry,
/// and as WriteMatFile.
void WriteMatMeasurement(const std::filesystem::path& path, const FrfData& data,
                         MatVersion version = MatVersion::kV5);

}  // namespace stagefit::measurement
