#pragma once
// The sidecar of a CSV output (docs/csv-outputs.md): every CSV file stagefit writes starts with its
// header row (column names, comma-separated) and holds nothing but data rows, so that Python's csv
// module, numpy.genfromtxt(names=True) and pandas.read_csv load it with their default options. What
// does not fit in a data row (the FRF quantity, the frame origin, the unit of each column, notes) goes
// to "<stem>.meta.json" beside "<stem>.csv":
//
//   {"file": "compliance.csv", "quantity": "accelerance", "frame_origin_m": [0, 0, -0.03],
//    "units": {"freq_hz": "Hz", "re": "m/s^2/N", ...}, "notes": ["..."]}
//
// Readers take the sidecar when present and still accept older files whose first lines are
// "# key: value" / "# unit column unit" comments.

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace stagefit {

struct CsvMeta {
  std::vector<std::pair<std::string, std::string>> units;  ///< column -> unit, in column order
  std::map<std::string, std::string> fields;               ///< e.g. "quantity" -> "accelerance"
  std::vector<double> frame_origin_m;                      ///< empty or x y z, m in W
  std::vector<int> num_averages;                           ///< empty, or the hits averaged per input (measurements)
  std::vector<std::string> notes;
};

/// "<stem>.meta.json" for "<stem>.csv" (or "<name>.meta.json" for a file without the .csv extension).
std::filesystem::path CsvMetaPath(const std::filesystem::path& csv_path);

/// Writes the sidecar of `csv_path` atomically.
void WriteCsvMeta(const std::filesystem::path& csv_path, const CsvMeta& meta);

/// The sidecar of `csv_path`, or nullopt when there is none. Throws InputError naming the sidecar when
/// it is not a JSON object of the layout above.
std::optional<CsvMeta> ReadCsvMeta(const std::filesystem::path& csv_path);

}  // namespace stagefit
