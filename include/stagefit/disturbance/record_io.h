#pragma once
// CSV files of the disturbance layer: time records, scan records and PSD tables share one layout.
//
//   time_s,voltage                  (header: column names, comma-separated, required; the first line
//   0,0.00123                        of a written file)
//   0.00390625,-0.000456
//
// Written files keep their notes and units (informative: values are always SI) in the sidecar
// "<stem>.meta.json" (common/csv_meta.h). Read files may also carry, before the header,
//   # free comment lines
//   # unit <column> <unit>          (one per column; they win over the sidecar's units)
//
// Time records have a first column time_s (s, evenly spaced); straightness scans a first column
// position_m (m); PSD tables a first column frequency_hz (Hz) or spatial_frequency_per_m (1/m) and one
// column per channel in U^2/Hz (or U^2/(1/m)). Blank lines are ignored. Numbers are written with 9
// significant digits (the first column with 12).

#include <Eigen/Dense>

#include <filesystem>
#include <string>
#include <vector>

namespace stagefit::disturbance {

struct CsvTable {
  std::string source;                     ///< file the table came from (for messages)
  std::vector<std::string> comments;      ///< comment lines without the leading "# "
  std::vector<std::string> column_names;  ///< C names
  std::vector<std::string> units;         ///< C unit strings, "" where not given
  Eigen::MatrixXd values;                 ///< R x C

  /// Index of the named column, or -1.
  int FindColumn(const std::string& name) const;
  /// The named column; throws InputError "<source>: no column '<name>' (columns: ...)".
  Eigen::VectorXd Column(const std::string& name) const;
};

/// Reads a table in the layout above. Throws InputError naming the file, line and column when the
/// file cannot be opened, the header is missing or has duplicate or empty names, a row has the wrong
/// number of fields, or a field is not a number (NaN and Inf are rejected as well).
CsvTable ReadCsvTable(const std::filesystem::path& path);

/// Writes the table atomically in the layout above (comments, unit lines, header, rows).
/// Throws InputError when the file cannot be written.
void WriteCsvTable(const std::filesystem::path& path, const CsvTable& table);

/// The sample rate of an evenly spaced column (e.g. time_s, s): (R - 1) / (last - first). Throws
/// InputError naming the file and column when R < 2, the values do not increase, or any step departs
/// from the mean step by more than 0.1 % (a gap or a jitter that the PSD would hide).
double CalcSampleRate(const CsvTable& table, const std::string& column);

/// Throws InputError when column `name` declares a unit other than `expected_unit` (values must be SI;
/// a column given in nm or mV would otherwise be misread by orders of magnitude). Columns without a
/// unit line pass.
void CheckColumnUnit(const CsvTable& table, const std::string& name,
                     const std::string& expected_unit);

}  // namespace stagefit::disturbance
