#include "stagefit/disturbance/record_io.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>

#include "stagefit/common/atomic_file.h"
#include "stagefit/common/csv_meta.h"
#include "stagefit/common/error.h"
#include "stagefit/common/utf8.h"

namespace stagefit::disturbance {
namespace {

std::string Trim(const std::string& s) {
  const auto begin = s.find_first_not_of(" \t\r");
  if (begin == std::string::npos) return "";
  const auto end = s.find_last_not_of(" \t\r");
  return s.substr(begin, end - begin + 1);
}

std::vector<std::string> SplitFields(const std::string& line) {
  std::vector<std::string> fields;
  std::string field;
  std::istringstream in(line);
  while (std::getline(in, field, ',')) fields.push_back(Trim(field));
  if (!line.empty() && line.back() == ',') fields.push_back("");
  return fields;
}

std::string Format(double value, int digits) {
  char buffer[40];
  std::snprintf(buffer, sizeof(buffer), "%.*g", digits, value);
  return buffer;
}

}  // namespace

int CsvTable::FindColumn(const std::string& name) const {
  for (size_t c = 0; c < column_names.size(); ++c) {
    if (column_names[c] == name) return static_cast<int>(c);
  }
  return -1;
}

Eigen::VectorXd CsvTable::Column(const std::string& name) const {
  const int c = FindColumn(name);
  if (c < 0) {
    std::string list;
    for (const std::string& n : column_names) list += (list.empty() ? "" : ", ") + n;
    throw InputError(source + ": no column '" + name + "' (columns: " + list + ")");
  }
  return values.col(c);
}

CsvTable ReadCsvTable(const std::filesystem::path& path) {
  CsvTable table;
  table.source = path.string();
  std::ifstream in(path);
  if (!in) throw InputError(table.source + ": cannot open the file for reading");
  std::vector<std::pair<std::string, std::string>> unit_lines;
  std::vector<std::vector<double>> rows;
  std::string line;
  int line_number = 0;
  bool have_header = false;
  while (std::getline(in, line)) {
    ++line_number;
    const std::string trimmed = Trim(line);
    if (trimmed.empty()) continue;
    if (trimmed[0] == '#') {
      const std::string text = Trim(trimmed.substr(1));
      std::istringstream words(text);
      std::string keyword, column, unit;
      words >> keyword;
      if (keyword == "unit" && (words >> column)) {
        std::getline(words, unit);
        unit_lines.emplace_back(column, Trim(unit));
      } else {
        table.comments.push_back(text);
      }
      continue;
    }
    const std::vector<std::string> fields = SplitFields(trimmed);
    if (!have_header) {
      std::set<std::string> seen;
      for (const std::string& name : fields) {
        if (!IsValidUtf8(name)) {
          throw InputError(table.source + ":" + std::to_string(line_number) + ": header column '" +
                           EscapeNonUtf8(name) + "' is not valid UTF-8, expected UTF-8 column names");
        }
        if (name.empty() || !seen.insert(name).second) {
          throw InputError(table.source + ":" + std::to_string(line_number) + ": header column '" +
                           name + "' is empty or repeated, expected distinct column names");
        }
      }
      table.column_names = fields;
      have_header = true;
      continue;
    }
    if (fields.size() != table.column_names.size()) {
      throw InputError(table.source + ":" + std::to_string(line_number) + ": " +
                       std::to_string(fields.size()) + " fields, expected " +
                       std::to_string(table.column_names.size()) + " (one per header column)");
    }
    std::vector<double> row(fields.size());
    for (size_t c = 0; c < fields.size(); ++c) {
      const char* begin = fields[c].c_str();
      char* end = nullptr;
      errno = 0;
      row[c] = std::strtod(begin, &end);
      if (fields[c].empty() || *end != '\0' || !std::isfinite(row[c])) {
        throw InputError(table.source + ":" + std::to_string(line_number) + ": column '" +
                         table.column_names[c] + "': '" + fields[c] +
                         "', expected a finite number");
      }
    }
    rows.push_back(std::move(row));
  }
  if (!have_header) throw InputError(table.source + ": no header line, expected column names");
  table.units.assign(table.column_names.size(), "");
  // Units and notes from the sidecar of a header-first file ("# unit" lines of an older file win).
  if (const auto meta = ReadCsvMeta(path)) {
    for (const auto& [column, unit] : meta->units) {
      const int c = table.FindColumn(column);
      if (c >= 0) table.units[c] = unit;
    }
    if (table.comments.empty()) table.comments = meta->notes;
  }
  for (const auto& [column, unit] : unit_lines) {
    const int c = table.FindColumn(column);
    if (c < 0) {
      throw InputError(table.source + ": unit line for '" + column + "', which is not a column");
    }
    table.units[c] = unit;
  }
  table.values.resize(static_cast<Eigen::Index>(rows.size()),
                      static_cast<Eigen::Index>(table.column_names.size()));
  for (size_t r = 0; r < rows.size(); ++r) {
    for (size_t c = 0; c < rows[r].size(); ++c) table.values(r, c) = rows[r][c];
  }
  return table;
}

void WriteCsvTable(const std::filesystem::path& path, const CsvTable& table) {
  STAGEFIT_ASSERT(table.values.cols() == static_cast<Eigen::Index>(table.column_names.size()),
                  "CSV table with " << table.column_names.size() << " names and "
                                    << table.values.cols() << " columns");
  // Header first, data rows only (docs/csv-outputs.md); the comments and units go to the sidecar.
  CsvMeta meta;
  meta.notes = table.comments;
  for (size_t c = 0; c < table.units.size() && c < table.column_names.size(); ++c) {
    if (!table.units[c].empty()) meta.units.emplace_back(table.column_names[c], table.units[c]);
  }
  AtomicFile file(path);
  std::ostream& out = file.stream();
  for (size_t c = 0; c < table.column_names.size(); ++c) {
    out << (c ? "," : "") << table.column_names[c];
  }
  out << "\n";
  constexpr int kFirstColumnDigits = 12;  // time or frequency: keeps even spacing visible
  constexpr int kValueDigits = 9;
  for (Eigen::Index r = 0; r < table.values.rows(); ++r) {
    for (Eigen::Index c = 0; c < table.values.cols(); ++c) {
      out << (c ? "," : "") << Format(table.values(r, c), c == 0 ? kFirstColumnDigits : kValueDigits);
    }
    out << "\n";
  }
  file.Commit();
  WriteCsvMeta(path, meta);
}

double CalcSampleRate(const CsvTable& table, const std::string& column) {
  const Eigen::VectorXd t = table.Column(column);
  const Eigen::Index n = t.size();
  if (n < 2) {
    throw InputError(table.source + ": column '" + column + "': " + std::to_string(n) +
                     " rows, expected at least 2 to know the sample rate");
  }
  const double step = (t[n - 1] - t[0]) / static_cast<double>(n - 1);
  if (!(step > 0.0)) {
    throw InputError(table.source + ": column '" + column + "' does not increase");
  }
  // Steps are compared with the median step, so that the message points at the gap itself.
  std::vector<double> steps(static_cast<size_t>(n - 1));
  for (Eigen::Index i = 1; i < n; ++i) steps[i - 1] = t[i] - t[i - 1];
  std::vector<double> sorted = steps;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double median = sorted[sorted.size() / 2];
  constexpr double kStepTolerance = 1e-3;
  for (Eigen::Index i = 1; i < n; ++i) {
    const double d = steps[i - 1];
    if (std::abs(d - median) > kStepTolerance * median) {
      std::ostringstream message;
      message << table.source << ": column '" << column << "': step " << d << " between rows "
              << i - 1 << " and " << i << " (values " << t[i - 1] << ", " << t[i]
              << "), expected even steps of " << median << " (within 0.1 %)";
      throw InputError(message.str());
    }
  }
  return 1.0 / step;
}

void CheckColumnUnit(const CsvTable& table, const std::string& name,
                     const std::string& expected_unit) {
  const int c = table.FindColumn(name);
  if (c < 0 || table.units[c].empty() || table.units[c] == expected_unit) return;
  throw InputError(table.source + ": column '" + name + "' is declared in '" + table.units[c] +
                   "', expected SI values in '" + expected_unit + "'");
}

}  // namespace stagefit::disturbance
