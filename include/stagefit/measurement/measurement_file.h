#pragma once
// One entry point for measurement files: the format follows the file name's extension.
//   .mat          MATLAB v5 or v7.3 (mat_file.h), SPEC §3 layout
//   .csv          long-format CSV with a "<stem>.geometry.csv" sidecar (csv_file.h)
//   .uff / .unv   universal file, datasets 58 / 58b (uff58.h)
// Extensions are matched case-insensitively.

#include <filesystem>

#include "stagefit/measurement/frf_data.h"
#include "stagefit/measurement/mat_file.h"
#include "stagefit/measurement/uff58.h"

namespace stagefit::measurement {

/// The file formats of measurements.
enum class MeasurementFormat { kMat, kCsv, kUff };

/// The format named by the extension of `path`. Throws InputError naming the file and the accepted
/// extensions when the extension is none of them.
MeasurementFormat MeasurementFormatOf(const std::filesystem::path& path);

/// Options of ReadMeasurement.
struct MeasurementReadOptions {
  /// When true, a measurement without sensor and impact geometry is rejected (MAT, CSV). UFF
  /// files carry node numbers only: their channels get geometry from `uff.nodes`.
  bool require_geometry = false;
  UffFrfOptions uff;  ///< quantity override and node locations for UFF files
  /// A geometry CSV (kind,name,body,x,y,z,nx,ny,nz) for the channels, over any geometry the file or its
  /// sidecar gives (`--geometry`). Empty: a .uff or .mat file takes "<stem>.geometry.csv" beside it when
  /// there is one (a .csv reads its own sidecar), else the geometry in the file (UFF: node coordinates of
  /// datasets 15 / 2411 on `uff.node_body`).
  std::filesystem::path geometry;
  /// The number of hits (records) averaged for every input, whose ordinary coherence the file holds
  /// (`--averages`; FrfData::averages): for files that do not say it (UFF 58, data from a modal-test
  /// system), over what the file says. 0: the file's, else the coherence is taken as that of the FRF
  /// estimate itself. Must be 0 or >= 2; a file without coherence is refused with it.
  int averages = 0;
};

/// Reads a measurement, dispatching on the extension; the result has passed Validate().
/// Throws InputError (file, field or line, expectation) for an unknown extension and for every
/// error of the format's reader.
FrfData ReadMeasurement(const std::filesystem::path& path,
                        const MeasurementReadOptions& options = {});

/// Options of WriteMeasurement.
struct MeasurementWriteOptions {
  MatVersion mat_version = MatVersion::kV5;
  /// Binary 58b keeps every double exactly; ASCII keeps 13 significant digits.
  UffEncoding uff_encoding = UffEncoding::kBinaryLittleEndian;
};

/// Writes `data` atomically (never half a file) in the format of the extension; a CSV also gets
/// its geometry sidecar. Throws InputError for an unknown extension, when Validate(data) fails and
/// when the file cannot be written.
void WriteMeasurement(const std::filesystem::path& path, const FrfData& data,
                      const MeasurementWriteOptions& options = {});

}  // namespace stagefit::measurement
