#pragma once
// Measurements as CSV, long format (SPEC §3): one row per output, input and frequency,
//
//   freq_hz,output,input,re,im[,coherence]  header, required, the first line of a written file
//   10,a1x,h1,1.25e-3,-4.5e-4[,0.98]        Hz, channel names, real and imaginary parts
//
// with the quantity, the frame origin and the units in "<stem>.meta.json" (common/csv_meta.h), so that
// csv, numpy and pandas read the file with their defaults. Older files may instead start with
//
//   # quantity: accelerance                 comment lines before the header
//   # frame_origin: 0 0 -0.03               (m, optional: origin of {X} in W)
//
// which are still read (and win over a sidecar).
//
// with the geometry in a sidecar "<stem>.geometry.csv" beside it:
//
//   kind,name,body,x,y,z,nx,ny,nz           header, required
//   sensor,a1x,hexapod,0,0.14,-0.03,1,0,0   kind = sensor (output) or impact (input); m; unit vector
//   impact,h1,,,,,,,                        empty body and numbers: geometry unknown
//
// Quantity: "quantity" in the sidecar, or "# quantity: <accelerance|mobility|receptance|compliance>" in
// a comment line before the header; when absent the FRFs are read as accelerance (the hammer-test case: accelerometers over
// force). Other comment lines ('#' first) and blank lines are ignored. Rows may come in any order;
// every (output, input) pair must list the same strictly increasing frequencies. Fields may be
// double-quoted (RFC 4180). Numbers are written in the shortest form that reads back to the same
// double, so a written file reads back bit-identical.

#include <filesystem>

#include "stagefit/common/csv_meta.h"

#include "stagefit/measurement/frf_data.h"

namespace stagefit::measurement {

/// "<folder>/<stem>.geometry.csv" for "<folder>/<stem>.csv".
std::filesystem::path GeometrySidecarPath(const std::filesystem::path& csv_path);

/// Reads a CSV measurement and, when it exists, its geometry sidecar. Outputs and inputs are in
/// order of first appearance in the CSV.
/// `require_geometry`: when true, a missing sidecar or a channel without geometry is an error.
/// Throws InputError naming the file, the line number, the column and what was expected for: a
/// missing file, a missing or wrong header, a wrong number of fields, a number that does not parse
/// or is not finite, coherence outside [0, 1], an unknown quantity, a repeated row, frequencies that
/// do not increase within a pair, pairs with different frequencies, a missing (output, input) pair,
/// sidecar rows with an unknown kind, unknown or repeated channels, partial geometry or a
/// non-unit direction, a channel of the CSV absent from the sidecar, and every Validate() failure
/// (e.g. a dead channel).
FrfData ReadCsvMeasurement(const std::filesystem::path& path, bool require_geometry = false);

/// Writes `data` as CSV (rows output-major, then input, then frequency; coherence column when
/// present; "# quantity" and "# frame_origin" comments) and the geometry sidecar, each atomically.
/// Throws InputError when Validate(data) fails or a file cannot be written.
void WriteCsvMeasurement(const std::filesystem::path& path, const FrfData& data);

/// Gives the channels of `data` the geometry of a geometry CSV (the sidecar layout above: every output
/// needs a 'sensor' row and every input an 'impact' row, named as the channels), replacing what they
/// had. For measurements of any format: `--geometry FILE.csv`, or "<stem>.geometry.csv" beside a .uff
/// or .mat file. Throws InputError naming the file, the line and the problem.
void ApplyGeometryFile(const std::filesystem::path& geometry_csv, FrfData* data, bool require_geometry = false);

/// The sidecar of an FRF CSV of `quantity`: the quantity and the unit of every column.
CsvMeta FrfCsvMeta(FrfQuantity quantity, bool with_coherence = false);

}  // namespace stagefit::measurement
