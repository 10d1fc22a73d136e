#include "stagefit/measurement/uff58.h"

#include <algorithm>
#include <cstdarg>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>
#include <utility>

#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"

namespace stagefit::measurement {
namespace fs = std::filesystem;

namespace {

constexpr std::string_view kBlanks = " \t\r\n\f\v";

std::string_view Trim(std::string_view s) {
  const std::size_t b = s.find_first_not_of(kBlanks);
  if (b == std::string_view::npos) return {};
  const std::size_t e = s.find_last_not_of(kBlanks);
  return s.substr(b, e - b + 1);
}

std::string_view Columns(std::string_view line, std::size_t begin, std::size_t end) {
  if (begin >= line.size()) return {};
  return line.substr(begin, std::min(end, line.size()) - begin);
}

bool IsValidUtf8(std::string_view s) {
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    int extra = 0;
    if (c < 0x80) {
      extra = 0;
    } else if ((c & 0xE0) == 0xC0 && c >= 0xC2) {
      extra = 1;
    } else if ((c & 0xF0) == 0xE0) {
      extra = 2;
    } else if ((c & 0xF8) == 0xF0 && c <= 0xF4) {
      extra = 3;
    } else {
      return false;
    }
    if (extra > 0 && i + extra >= s.size()) return false;
    for (int k = 1; k <= extra; ++k) {
      if ((static_cast<unsigned char>(s[i + k]) & 0xC0) != 0x80) return false;
    }
    i += extra + 1;
  }
  return true;
}

// Header text as UTF-8: kept when it already is, else read as Latin-1.
std::string ToUtf8(std::string_view s) {
  if (IsValidUtf8(s)) return std::string(s);
  std::string out;
  for (char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (c < 0x80) {
      out.push_back(ch);
    } else {
      out.push_back(static_cast<char>(0xC0 | (c >> 6)));
      out.push_back(static_cast<char>(0x80 | (c & 0x3F)));
    }
  }
  return out;
}

std::string Printable(std::string_view s) {
  std::string out = ToUtf8(s.substr(0, 60));
  if (s.size() > 60) out += "...";
  return out;
}

bool ParseInt(std::string_view text, long long* value) {
  text = Trim(text);
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  if (text.empty()) return false;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), *value);
  return ec == std::errc() && ptr == text.data() + text.size();
}

bool ParseReal(std::string_view text, double* value) {
  text = Trim(text);
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  if (text.empty() || text.size() > 64) return false;
  char buffer[65];
  std::size_t n = 0;
  for (char c : text) buffer[n++] = (c == 'D' || c == 'd') ? 'E' : c;
  const auto [ptr, ec] = std::from_chars(buffer, buffer + n, *value);
  return ec == std::errc() && ptr == buffer + n;
}

// Splits at blanks.
std::vector<std::string_view> Tokens(std::string_view line) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  while (i < line.size()) {
    i = line.find_first_not_of(kBlanks, i);
    if (i == std::string_view::npos) break;
    std::size_t e = line.find_first_of(kBlanks, i);
    if (e == std::string_view::npos) e = line.size();
    tokens.push_back(line.substr(i, e - i));
    i = e;
  }
  return tokens;
}

// The content of a file, split into lines on demand; tracks line numbers for messages.
class Cursor {
 public:
  Cursor(std::string_view content, std::string source)
      : content_(content), source_(std::move(source)) {}

  bool AtEnd() const { return pos_ >= content_.size(); }
  std::size_t pos() const { return pos_; }
  std::size_t remaining() const { return content_.size() - pos_; }
  int line() const { return line_; }
  const std::string& source() const { return source_; }
  std::string_view content() const { return content_; }

  // The next line without its line end; nullopt at the end of the content.
  std::optional<std::string_view> NextLine() {
    if (AtEnd()) return std::nullopt;
    std::size_t e = content_.find('\n', pos_);
    std::string_view line;
    if (e == std::string_view::npos) {
      line = content_.substr(pos_);
      pos_ = content_.size();
    } else {
      line = content_.substr(pos_, e - pos_);
      pos_ = e + 1;
    }
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    ++line_;
    return line;
  }

  void Skip(std::size_t bytes) { pos_ += bytes; }

  [[noreturn]] void Fail(const std::string& message) const {
    throw InputError("UFF file '" + source_ + "', line " + std::to_string(line_) + ": " + message);
  }
  [[noreturn]] void FailAt(int line, const std::string& message) const {
    throw InputError("UFF file '" + source_ + "', line " + std::to_string(line) + ": " + message);
  }

 private:
  std::string_view content_;
  std::string source_;
  std::size_t pos_ = 0;
  int line_ = 0;
};

struct FieldSpec {
  std::size_t begin, end;
  const char* name;
};

int IntField(const Cursor& cursor, std::string_view line, const FieldSpec& f, const char* record) {
  long long v = 0;
  if (!ParseInt(Columns(line, f.begin, f.end), &v) || v < INT32_MIN || v > INT32_MAX) {
    cursor.Fail(std::string(record) + ", columns " + std::to_string(f.begin + 1) + "-" +
                std::to_string(f.end) + " (" + f.name + "): '" +
                Printable(Trim(Columns(line, f.begin, f.end))) + "', expected an integer");
  }
  return static_cast<int>(v);
}

double RealField(const Cursor& cursor, std::string_view text, const char* record, const char* name,
                 const std::string& columns) {
  double v = 0.0;
  if (!ParseReal(text, &v) || !std::isfinite(v)) {
    cursor.Fail(std::string(record) + ", " + columns + " (" + name + "): '" + Printable(Trim(text)) +
                "', expected a finite real number");
  }
  return v;
}

void ParseRecord6(const Cursor& cursor, std::string_view line, UffRecord* r) {
  static const FieldSpec kFields[] = {{0, 5, "function type"},     {5, 15, "function id"},
                                      {15, 20, "version number"},  {20, 30, "load case"},
                                      {41, 51, "response node"},   {51, 55, "response direction"},
                                      {66, 76, "reference node"},  {76, 80, "reference direction"}};
  long long probe = 0;
  bool fixed_ok = true;
  for (const FieldSpec& f : kFields) fixed_ok = fixed_ok && ParseInt(Columns(line, f.begin, f.end), &probe);
  if (!fixed_ok) {
    const auto tokens = Tokens(line);
    long long v[8];
    if (tokens.size() == 10 && ParseInt(tokens[0], &v[0]) && ParseInt(tokens[1], &v[1]) &&
        ParseInt(tokens[2], &v[2]) && ParseInt(tokens[3], &v[3]) && ParseInt(tokens[5], &v[4]) &&
        ParseInt(tokens[6], &v[5]) && ParseInt(tokens[8], &v[6]) && ParseInt(tokens[9], &v[7])) {
      r->function_type = static_cast<int>(v[0]);
      r->function_id = static_cast<int>(v[1]);
      r->version_number = static_cast<int>(v[2]);
      r->load_case_id = static_cast<int>(v[3]);
      r->response_entity = ToUtf8(tokens[4]);
      r->response_node = static_cast<int>(v[4]);
      r->response_direction = static_cast<int>(v[5]);
      r->reference_entity = ToUtf8(tokens[7]);
      r->reference_node = static_cast<int>(v[6]);
      r->reference_direction = static_cast<int>(v[7]);
      return;
    }
  }
  const char* kRecord = "record 6";
  r->function_type = IntField(cursor, line, kFields[0], kRecord);
  r->function_id = IntField(cursor, line, kFields[1], kRecord);
  r->version_number = IntField(cursor, line, kFields[2], kRecord);
  r->load_case_id = IntField(cursor, line, kFields[3], kRecord);
  r->response_entity = ToUtf8(Trim(Columns(line, 31, 41)));
  r->response_node = IntField(cursor, line, kFields[4], kRecord);
  r->response_direction = IntField(cursor, line, kFields[5], kRecord);
  r->reference_entity = ToUtf8(Trim(Columns(line, 56, 66)));
  r->reference_node = IntField(cursor, line, kFields[6], kRecord);
  r->reference_direction = IntField(cursor, line, kFields[7], kRecord);
}

struct Record7 {
  int ordinate_type = 0;
  long long num_points = 0;
  int spacing = 0;
  double minimum = 0.0, increment = 0.0, z = 0.0;
};

Record7 ParseRecord7(const Cursor& cursor, std::string_view line) {
  const char* kRecord = "record 7";
  static const char* kNames[] = {"ordinate data type", "number of points", "abscissa spacing",
                                 "abscissa minimum",   "abscissa increment", "z-axis value"};
  static const std::size_t kBounds[] = {0, 10, 20, 30, 43, 56, 69};
  std::vector<std::string_view> fields;
  std::vector<std::string> columns;
  const auto tokens = Tokens(line);
  if (tokens.size() == 6) {
    fields = tokens;
    for (int i = 0; i < 6; ++i) columns.push_back("field " + std::to_string(i + 1));
  } else {
    for (int i = 0; i < 6; ++i) {
      fields.push_back(Columns(line, kBounds[i], kBounds[i + 1]));
      columns.push_back("columns " + std::to_string(kBounds[i] + 1) + "-" +
                        std::to_string(kBounds[i + 1]));
    }
  }
  Record7 r;
  long long v = 0;
  for (int i = 0; i < 3; ++i) {
    if (!ParseInt(fields[i], &v)) {
      cursor.Fail(std::string(kRecord) + ", " + columns[i] + " (" + kNames[i] + "): '" +
                  Printable(Trim(fields[i])) + "', expected an integer");
    }
    if (i == 0) r.ordinate_type = static_cast<int>(std::clamp<long long>(v, -1, 1000));
    if (i == 1) r.num_points = v;
    if (i == 2) r.spacing = static_cast<int>(std::clamp<long long>(v, -1, 1000));
  }
  r.minimum = RealField(cursor, fields[3], kRecord, kNames[3], columns[3]);
  r.increment = RealField(cursor, fields[4], kRecord, kNames[4], columns[4]);
  r.z = RealField(cursor, fields[5], kRecord, kNames[5], columns[5]);
  return r;
}

UffAxis ParseAxisRecord(const Cursor& cursor, std::string_view line, const char* record) {
  static const FieldSpec kFields[] = {{0, 10, "specific data type"},
                                      {10, 15, "length unit exponent"},
                                      {15, 20, "force unit exponent"},
                                      {20, 25, "temperature unit exponent"}};
  UffAxis axis;
  long long probe = 0;
  bool fixed_ok = true;
  for (const FieldSpec& f : kFields) fixed_ok = fixed_ok && ParseInt(Columns(line, f.begin, f.end), &probe);
  if (fixed_ok) {
    axis.specific_data_type = IntField(cursor, line, kFields[0], record);
    axis.length_unit_exponent = IntField(cursor, line, kFields[1], record);
    axis.force_unit_exponent = IntField(cursor, line, kFields[2], record);
    axis.temperature_unit_exponent = IntField(cursor, line, kFields[3], record);
    axis.label = ToUtf8(Trim(Columns(line, 26, 46)));
    axis.units_label = ToUtf8(Trim(Columns(line, 47, line.size())));
    return axis;
  }
  const auto tokens = Tokens(line);
  long long v[4];
  if (tokens.size() >= 4 && ParseInt(tokens[0], &v[0]) && ParseInt(tokens[1], &v[1]) &&
      ParseInt(tokens[2], &v[2]) && ParseInt(tokens[3], &v[3])) {
    axis.specific_data_type = static_cast<int>(v[0]);
    axis.length_unit_exponent = static_cast<int>(v[1]);
    axis.force_unit_exponent = static_cast<int>(v[2]);
    axis.temperature_unit_exponent = static_cast<int>(v[3]);
    if (tokens.size() >= 5) axis.label = ToUtf8(tokens[4]);
    if (tokens.size() >= 6) axis.units_label = ToUtf8(tokens[5]);
    return axis;
  }
  for (const FieldSpec& f : kFields) IntField(cursor, line, f, record);
  return axis;
}

bool IsDelimiter(std::string_view line) { return Trim(line) == "-1"; }

// Field widths of the ASCII data record, cycled over a line (used when numbers touch).
std::vector<std::size_t> AsciiWidths(UffOrdinateType type, bool even) {
  switch (type) {
    case UffOrdinateType::kRealSingle:
    case UffOrdinateType::kComplexSingle:
      return {13};
    case UffOrdinateType::kRealDouble:
      return even ? std::vector<std::size_t>{20} : std::vector<std::size_t>{13, 20};
    case UffOrdinateType::kComplexDouble:
      return even ? std::vector<std::size_t>{20} : std::vector<std::size_t>{13, 20, 20};
  }
  return {13};
}

void ReadAsciiValues(Cursor& cursor, const UffRecord& r, std::size_t expected,
                     std::vector<double>* values, int header_line) {
  const auto widths = AsciiWidths(r.ordinate_type, r.even_abscissa);
  while (true) {
    const auto line = cursor.NextLine();
    if (!line) {
      cursor.Fail("dataset 58 starting at line " + std::to_string(header_line) + " ends after " +
                  std::to_string(values->size()) + " of the " + std::to_string(expected) +
                  " values it declares, without the closing '-1' delimiter: the file is truncated");
    }
    if (IsDelimiter(*line)) break;
    const auto tokens = Tokens(*line);
    std::vector<double> parsed;
    bool tokens_ok = true;
    for (auto t : tokens) {
      double v = 0.0;
      if (!ParseReal(t, &v)) {
        tokens_ok = false;
        break;
      }
      parsed.push_back(v);
    }
    if (!tokens_ok) {
      parsed.clear();
      std::size_t col = 0;
      std::size_t k = values->size() % widths.size();
      while (col < line->size() && !Trim(line->substr(col)).empty()) {
        const std::size_t w = widths[k % widths.size()];
        const std::string_view field = Columns(*line, col, col + w);
        double v = 0.0;
        if (!ParseReal(field, &v)) {
          cursor.Fail("data value in columns " + std::to_string(col + 1) + "-" +
                      std::to_string(col + field.size()) + ": '" + Printable(field) +
                      "', expected a real number (dataset 58 data record)");
        }
        parsed.push_back(v);
        col += w;
        ++k;
      }
    }
    if (values->size() + parsed.size() > expected) {
      cursor.Fail("more data values than the " + std::to_string(r.x.size()) +
                  " points declared in record 7 (expected " + std::to_string(expected) +
                  " values, then the '-1' delimiter)");
    }
    for (double v : parsed) {
      if (!std::isfinite(v)) {
        cursor.Fail("data value " + std::to_string(values->size() + 1) +
                    " is not finite, expected a finite real number");
      }
      values->push_back(v);
    }
  }
  if (values->size() != expected) {
    cursor.Fail("dataset 58 starting at line " + std::to_string(header_line) + " declares " +
                std::to_string(expected) + " values in record 7 but holds " +
                std::to_string(values->size()) + " before the '-1' delimiter (truncated dataset)");
  }
}

bool HostIsLittleEndian() {
  const std::uint16_t probe = 1;
  unsigned char first = 0;
  std::memcpy(&first, &probe, 1);
  return first == 1;
}

void ReadBinaryValues(Cursor& cursor, std::size_t count, std::size_t size, bool little,
                      std::vector<double>* values) {
  const std::string_view content = cursor.content();
  const std::size_t start = cursor.pos();
  const bool swap = little != HostIsLittleEndian();
  values->reserve(count);
  unsigned char bytes[8];
  for (std::size_t i = 0; i < count; ++i) {
    std::memcpy(bytes, content.data() + start + i * size, size);
    if (swap) std::reverse(bytes, bytes + size);
    double v = 0.0;
    if (size == 4) {
      float f = 0.0f;
      std::memcpy(&f, bytes, 4);
      v = f;
    } else {
      std::memcpy(&v, bytes, 8);
    }
    if (!std::isfinite(v)) {
      cursor.Fail("binary data value " + std::to_string(i + 1) +
                  " is not finite, expected a finite real number");
    }
    values->push_back(v);
  }
  cursor.Skip(count * size);
}

struct BinaryHeader {
  bool binary = false;
  bool little_endian = true;
  long long num_bytes = 0;
  long long ascii_lines = 11;
};

// Parses the dataset-number line; returns the dataset number (-1 when unreadable).
long long ParseDatasetLine(const Cursor& cursor, std::string_view line, BinaryHeader* header) {
  const auto tokens = Tokens(line);
  if (tokens.empty()) return -1;
  std::string_view first = tokens[0];
  std::vector<std::string_view> rest(tokens.begin() + 1, tokens.end());
  if (first.size() > 1 && (first.back() == 'b' || first.back() == 'B')) {
    header->binary = true;
    first.remove_suffix(1);
  } else if (!rest.empty() && (rest[0] == "b" || rest[0] == "B")) {
    header->binary = true;
    rest.erase(rest.begin());
  } else if (first.size() > 6 && (first[6] == 'b' || first[6] == 'B')) {
    header->binary = true;
  }
  long long number = -1;
  if (!ParseInt(first, &number)) return -1;
  if (!header->binary) return number;
  if (rest.size() < 4) {
    cursor.Fail("58b header: '" + Printable(line) +
                "', expected byte ordering, floating-point format, number of ASCII lines and "
                "number of bytes after the dataset number");
  }
  long long v[4];
  for (int i = 0; i < 4; ++i) {
    if (!ParseInt(rest[i], &v[i])) {
      cursor.Fail("58b header field " + std::to_string(i + 2) + ": '" + Printable(rest[i]) +
                  "', expected an integer");
    }
  }
  if (v[0] != 1 && v[0] != 2) {
    cursor.Fail("58b header: byte ordering " + std::to_string(v[0]) +
                ", expected 1 (little endian) or 2 (big endian)");
  }
  header->little_endian = v[0] == 1;
  if (number == 58 && v[1] != 2) {
    cursor.Fail("58b header: floating-point format " + std::to_string(v[1]) +
                ", expected 2 (IEEE 754)");
  }
  header->ascii_lines = v[2];
  header->num_bytes = v[3];
  if (v[3] < 0) cursor.Fail("58b header: negative number of bytes " + std::to_string(v[3]));
  return number;
}

void SkipDataset(Cursor& cursor, const BinaryHeader& header) {
  if (header.binary) {
    for (long long i = 0; i < header.ascii_lines; ++i) {
      if (!cursor.NextLine()) return;
    }
    if (static_cast<unsigned long long>(header.num_bytes) > cursor.remaining()) {
      cursor.Fail("binary dataset declares " + std::to_string(header.num_bytes) +
                  " bytes but only " + std::to_string(cursor.remaining()) +
                  " remain in the file (truncated file)");
    }
    cursor.Skip(static_cast<std::size_t>(header.num_bytes));
  }
  while (const auto line = cursor.NextLine()) {
    if (IsDelimiter(*line)) return;
  }
  cursor.Fail("dataset without its closing '-1' delimiter (truncated file)");
}

UffRecord ParseDataset58(Cursor& cursor, const BinaryHeader& header, int start_line) {
  UffRecord r;
  Record7 r7;
  int record7_line = 0;
  const char* kAxisRecords[] = {"record 8", "record 9", "record 10", "record 11"};
  UffAxis* axes[] = {&r.abscissa, &r.ordinate, &r.ordinate_denominator, &r.z_axis};
  for (int i = 0; i < 11; ++i) {
    const auto line = cursor.NextLine();
    if (!line || (IsDelimiter(*line) && i >= 5)) {
      cursor.Fail("dataset 58 starting at line " + std::to_string(start_line) +
                  " ends inside its header: record " + std::to_string(i + 1) +
                  " is missing, expected 11 header records");
    }
    if (i < 5) r.id[i] = ToUtf8(Trim(*line));
    if (i == 5) ParseRecord6(cursor, *line, &r);
    if (i == 6) {
      r7 = ParseRecord7(cursor, *line);
      record7_line = cursor.line();
    }
    if (i >= 7) *axes[i - 7] = ParseAxisRecord(cursor, *line, kAxisRecords[i - 7]);
  }

  switch (r7.ordinate_type) {
    case 2:
    case 4:
    case 5:
    case 6:
      r.ordinate_type = static_cast<UffOrdinateType>(r7.ordinate_type);
      break;
    default:
      cursor.FailAt(record7_line, "record 7, columns 1-10 (ordinate data type): " +
                                      std::to_string(r7.ordinate_type) +
                                      ", expected 2 (real single), 4 (real double), 5 (complex "
                                      "single) or 6 (complex double)");
  }
  if (r7.spacing != 0 && r7.spacing != 1) {
    cursor.FailAt(record7_line, "record 7, columns 21-30 (abscissa spacing): " +
                                    std::to_string(r7.spacing) + ", expected 0 (uneven) or 1 (even)");
  }
  r.even_abscissa = r7.spacing == 1;
  r.abscissa_minimum = r7.minimum;
  r.abscissa_increment = r7.increment;
  r.z_axis_value = r7.z;
  if (r7.num_points < 1) {
    cursor.FailAt(record7_line, "record 7, columns 11-20 (number of points): " +
                                    std::to_string(r7.num_points) + ", expected at least 1");
  }
  if (r.even_abscissa && r7.num_points > 1 && !(r7.increment > 0.0)) {
    cursor.FailAt(record7_line, "record 7, columns 44-56 (abscissa increment): " +
                                    std::to_string(r7.increment) +
                                    ", expected > 0 with even spacing");
  }
  const std::size_t per_point = (r.is_complex() ? 2 : 1) + (r.even_abscissa ? 0 : 1);
  const std::size_t value_size = r.is_double() ? 8 : 4;
  // Every value needs at least two characters in ASCII and value_size bytes in binary: a count that
  // the rest of the file cannot hold is reported before anything is allocated.
  const std::size_t min_bytes_per_value = header.binary ? value_size : 2;
  const std::size_t capacity = cursor.remaining() / min_bytes_per_value + 1;
  if (static_cast<unsigned long long>(r7.num_points) > capacity / per_point) {
    cursor.FailAt(record7_line,
                  "record 7 declares " + std::to_string(r7.num_points) + " points (" +
                      std::to_string(static_cast<unsigned long long>(r7.num_points) * per_point) +
                      " values) but only " + std::to_string(cursor.remaining()) +
                      " bytes remain in the file: the file is truncated or the count is corrupt");
  }
  const std::size_t n = static_cast<std::size_t>(r7.num_points);
  const std::size_t expected = n * per_point;
  r.x.resize(static_cast<Eigen::Index>(n));

  std::vector<double> values;
  if (header.binary) {
    if (header.ascii_lines != 11) {
      cursor.FailAt(start_line + 1, "58b header: " + std::to_string(header.ascii_lines) +
                                        " ASCII header lines, expected 11");
    }
    if (static_cast<unsigned long long>(header.num_bytes) != expected * value_size) {
      cursor.FailAt(start_line + 1,
                    "58b header declares " + std::to_string(header.num_bytes) +
                        " bytes of data, but record 7 implies " + std::to_string(expected) +
                        " values of " + std::to_string(value_size) + " bytes = " +
                        std::to_string(expected * value_size) + " bytes");
    }
    if (expected * value_size > cursor.remaining()) {
      cursor.Fail("58b data: " + std::to_string(expected * value_size) + " bytes declared but only " +
                  std::to_string(cursor.remaining()) + " remain in the file (truncated file)");
    }
    ReadBinaryValues(cursor, expected, value_size, header.little_endian, &values);
    bool closed = false;
    while (const auto line = cursor.NextLine()) {
      if (IsDelimiter(*line)) {
        closed = true;
        break;
      }
      if (!Trim(*line).empty()) {
        cursor.Fail("after the " + std::to_string(expected * value_size) +
                    " bytes of 58b data: '" + Printable(*line) +
                    "', expected the closing '-1' delimiter (wrong byte count?)");
      }
    }
    if (!closed) cursor.Fail("58b dataset without its closing '-1' delimiter (truncated file)");
  } else {
    values.reserve(expected);
    ReadAsciiValues(cursor, r, expected, &values, start_line);
  }

  if (r.is_complex()) r.complex_y.resize(static_cast<Eigen::Index>(n));
  else r.real_y.resize(static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i) {
    const double* p = values.data() + i * per_point;
    const Eigen::Index k = static_cast<Eigen::Index>(i);
    if (r.even_abscissa) {
      r.x[k] = r.abscissa_minimum + static_cast<double>(i) * r.abscissa_increment;
    } else {
      r.x[k] = *p++;
    }
    if (r.is_complex()) r.complex_y[k] = {p[0], p[1]};
    else r.real_y[k] = p[0];
  }
  return r;
}

std::string ReadFile(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    throw InputError("UFF file '" + path.string() + "': does not exist or is not a regular file");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError("UFF file '" + path.string() + "': cannot be opened for reading");
  std::string content((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError("UFF file '" + path.string() + "': read error");
  return content;
}

// ---- writing ----

std::string Fit(const std::string& s, std::size_t width) {
  std::string t = s.empty() ? std::string("NONE") : s;
  for (char& c : t) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return t.size() > width ? t.substr(0, width) : t;
}

void Append(std::string* out, const char* format, ...) __attribute__((format(printf, 2, 3)));
void Append(std::string* out, const char* format, ...) {
  char buffer[512];
  va_list args;
  va_start(args, format);
  const int n = std::vsnprintf(buffer, sizeof buffer, format, args);
  va_end(args);
  STAGEFIT_ASSERT(n >= 0 && n < static_cast<int>(sizeof buffer), "UFF line too long");
  out->append(buffer, static_cast<std::size_t>(n));
}

void AppendAxis(std::string* out, const UffAxis& a) {
  Append(out, "%10d%5d%5d%5d %-20s %-20s\n", a.specific_data_type, a.length_unit_exponent,
         a.force_unit_exponent, a.temperature_unit_exponent, Fit(a.label, 20).c_str(),
         Fit(a.units_label, 20).c_str());
}

void CheckWritable(const UffRecord& r, std::size_t index) {
  const std::string what = "UFF record " + std::to_string(index + 1) + ": ";
  const Eigen::Index n = r.x.size();
  if (n < 1) throw InputError(what + "no points, expected at least one");
  if (r.is_complex() ? r.complex_y.size() != n : r.real_y.size() != n) {
    throw InputError(what + std::to_string(n) + " abscissa values but " +
                     std::to_string(r.is_complex() ? r.complex_y.size() : r.real_y.size()) +
                     " ordinate values of the declared type, expected equal counts");
  }
  const bool finite = r.x.allFinite() &&
                      (r.is_complex() ? r.complex_y.allFinite() : r.real_y.allFinite()) &&
                      std::isfinite(r.abscissa_minimum) && std::isfinite(r.abscissa_increment) &&
                      std::isfinite(r.z_axis_value);
  if (!finite) throw InputError(what + "non-finite value, expected finite numbers");
}

}  // namespace

namespace {

// Numbers of an ASCII node or units record: blank-separated, Fortran D exponents allowed.
std::vector<double> RecordNumbers(Cursor& cursor, std::string_view line, std::size_t expected, const std::string& what) {
  std::vector<double> values;
  std::string text(line);
  for (char& c : text) {
    if (c == 'D' || c == 'd') c = 'E';
  }
  std::istringstream in(text);
  std::string token;
  while (in >> token) {
    char* end = nullptr;
    const double v = std::strtod(token.c_str(), &end);
    if (end == token.c_str() || *end != '\0' || !std::isfinite(v)) {
      cursor.Fail(what + ": '" + Printable(token) + "' is not a finite number");
    }
    values.push_back(v);
  }
  if (values.size() < expected) {
    cursor.Fail(what + ": " + std::to_string(values.size()) + " numbers, expected " + std::to_string(expected));
  }
  return values;
}

// Datasets 15 (one line per node: label, 3 coordinate systems / colour, x y z) and 2411 (two lines per
// node: label, 3 integers; x y z in D25.16). Coordinates in file units.
void ParseNodes(Cursor& cursor, long long number, std::map<int, Eigen::Vector3d>* nodes) {
  const std::string what = "dataset " + std::to_string(number);
  while (true) {
    const auto line = cursor.NextLine();
    if (!line) cursor.Fail(what + " without its closing '-1' delimiter (truncated file)");
    if (IsDelimiter(*line)) return;
    if (Trim(*line).empty()) continue;
    std::vector<double> v;
    Eigen::Vector3d x;
    if (number == 15) {
      v = RecordNumbers(cursor, *line, 7, what + " node line");
      x = Eigen::Vector3d(v[4], v[5], v[6]);
    } else {
      v = RecordNumbers(cursor, *line, 4, what + " record 1 (node label, coordinate systems, colour)");
      const auto coordinates = cursor.NextLine();
      if (!coordinates) cursor.Fail(what + ": the file ends after a node's record 1, expected its coordinates");
      const std::vector<double> c = RecordNumbers(cursor, *coordinates, 3, what + " record 2 (x y z)");
      x = Eigen::Vector3d(c[0], c[1], c[2]);
    }
    if (v[0] != std::floor(v[0]) || v[0] < 0 || v[0] > 2e9) cursor.Fail(what + ": node label " + std::to_string(v[0]) + ", expected an integer >= 0");
    (*nodes)[static_cast<int>(v[0])] = x;
  }
}

// Dataset 164: record 1 units code, description, temperature mode; record 2 length, force and
// temperature factors; record 3 temperature offset.
void ParseUnits(Cursor& cursor, UffFile* file) {
  const auto r1 = cursor.NextLine();
  if (!r1) cursor.Fail("dataset 164 without its closing '-1' delimiter (truncated file)");
  if (IsDelimiter(*r1)) return;  // an empty units dataset: SI
  const auto r2 = cursor.NextLine();
  if (!r2) cursor.Fail("dataset 164 ends early, expected its unit factors (length, force, temperature)");
  if (IsDelimiter(*r2)) return;  // a units code without factors: SI (factors 1)
  file->units_description = std::string(Trim(r1->size() > 10 ? r1->substr(10, std::min<std::size_t>(20, r1->size() - 10)) : std::string_view()));
  const std::vector<double> f = RecordNumbers(cursor, *r2, 3, "dataset 164 record 2 (length, force, temperature factors)");
  if (!(f[0] > 0.0) || !(f[1] > 0.0)) {
    cursor.Fail("dataset 164 record 2: length factor " + std::to_string(f[0]) + ", force factor " + std::to_string(f[1]) +
                ", expected factors > 0");
  }
  file->length_factor = f[0];
  file->force_factor = f[1];
  file->has_units = true;
  while (const auto line = cursor.NextLine()) {
    if (IsDelimiter(*line)) return;
  }
  cursor.Fail("dataset 164 without its closing '-1' delimiter (truncated file)");
}

}  // namespace

UffFile ParseUffFile(std::string_view content, const std::string& source) {
  Cursor cursor(content, source);
  UffFile file;
  std::vector<UffRecord>& records = file.records;
  std::map<int, Eigen::Vector3d> nodes;
  bool any_dataset = false;
  while (true) {
    std::optional<std::string_view> line;
    do {
      line = cursor.NextLine();
    } while (line && Trim(*line).empty());
    if (!line) break;
    if (!IsDelimiter(*line)) {
      cursor.Fail("'" + Printable(*line) +
                  "', expected the dataset delimiter '    -1' (is this a universal file?)");
    }
    const int start_line = cursor.line();
    const auto number_line = cursor.NextLine();
    if (!number_line) cursor.Fail("the file ends after a '-1' delimiter, expected a dataset number");
    if (IsDelimiter(*number_line)) continue;
    BinaryHeader header;
    const long long number = ParseDatasetLine(cursor, *number_line, &header);
    if (number < 0) {
      cursor.Fail("'" + Printable(*number_line) + "', expected a dataset number such as 58 or 58b");
    }
    any_dataset = true;
    if ((number == 15 || number == 2411) && !header.binary) {
      ParseNodes(cursor, number, &nodes);
      continue;
    }
    if (number == 164 && !header.binary) {
      ParseUnits(cursor, &file);
      continue;
    }
    if (number != 58) {
      SkipDataset(cursor, header);
      continue;
    }
    records.push_back(ParseDataset58(cursor, header, start_line));
  }
  if (records.empty()) {
    throw InputError("UFF file '" + source + "': " +
                     (any_dataset ? std::string("holds no dataset 58 (function at nodal DOF)")
                                  : std::string("is empty, expected at least one dataset 58")));
  }
  for (const auto& [label, x] : nodes) file.nodes_m[label] = x / file.length_factor;
  return file;
}

std::vector<UffRecord> ParseUff58(std::string_view content, const std::string& source) {
  return ParseUffFile(content, source).records;
}

UffFile ReadUffFile(const fs::path& path) {
  const std::string content = ReadFile(path);
  return ParseUffFile(content, path.string());
}

std::vector<UffRecord> ReadUff58(const fs::path& path) {
  const std::string content = ReadFile(path);
  return ParseUff58(content, path.string());
}

std::string FormatUff58(const std::vector<UffRecord>& records, UffEncoding encoding) {
  const bool binary = encoding != UffEncoding::kAscii;
  const bool little = encoding == UffEncoding::kBinaryLittleEndian;
  std::string out;
  for (std::size_t index = 0; index < records.size(); ++index) {
    const UffRecord& r = records[index];
    CheckWritable(r, index);
    const std::size_t n = static_cast<std::size_t>(r.x.size());
    const std::size_t per_point = (r.is_complex() ? 2 : 1) + (r.even_abscissa ? 0 : 1);
    std::vector<double> values;
    values.reserve(n * per_point);
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Index k = static_cast<Eigen::Index>(i);
      if (!r.even_abscissa) values.push_back(r.x[k]);
      if (r.is_complex()) {
        values.push_back(r.complex_y[k].real());
        values.push_back(r.complex_y[k].imag());
      } else {
        values.push_back(r.real_y[k]);
      }
    }
    const std::size_t value_size = r.is_double() ? 8 : 4;
    Append(&out, "%6d\n", -1);
    if (binary) {
      Append(&out, "%6db%6d%6d%12d%12lld%6d%6d%12d%12d\n", 58, little ? 1 : 2, 2, 11,
             static_cast<long long>(values.size() * value_size), 0, 0, 0, 0);
    } else {
      Append(&out, "%6d\n", 58);
    }
    for (const std::string& id : r.id) Append(&out, "%-80s\n", Fit(id, 80).c_str());
    Append(&out, "%5d%10d%5d%10d %-10s%10d%4d %-10s%10d%4d\n", r.function_type, r.function_id,
           r.version_number, r.load_case_id, Fit(r.response_entity, 10).c_str(), r.response_node,
           r.response_direction, Fit(r.reference_entity, 10).c_str(), r.reference_node,
           r.reference_direction);
    Append(&out, "%10d%10zu%10d%13.5E%13.5E%13.5E\n", static_cast<int>(r.ordinate_type), n,
           r.even_abscissa ? 1 : 0, r.even_abscissa ? r.abscissa_minimum : 0.0,
           r.even_abscissa ? r.abscissa_increment : 0.0, r.z_axis_value);
    AppendAxis(&out, r.abscissa);
    AppendAxis(&out, r.ordinate);
    AppendAxis(&out, r.ordinate_denominator);
    AppendAxis(&out, r.z_axis);
    if (binary) {
      const bool swap = little != HostIsLittleEndian();
      unsigned char bytes[8];
      for (double v : values) {
        if (value_size == 4) {
          const float f = static_cast<float>(v);
          std::memcpy(bytes, &f, 4);
        } else {
          std::memcpy(bytes, &v, 8);
        }
        if (swap) std::reverse(bytes, bytes + value_size);
        out.append(reinterpret_cast<const char*>(bytes), value_size);
      }
    } else {
      const auto widths = AsciiWidths(r.ordinate_type, r.even_abscissa);
      const std::size_t per_line =
          r.is_double() ? (r.even_abscissa ? 4 : (r.is_complex() ? 3 : 4)) : 6;
      for (std::size_t i = 0; i < values.size(); ++i) {
        if (widths[i % widths.size()] == 13) {
          Append(&out, "%13.5E", values[i]);
        } else {
          Append(&out, "%20.12E", values[i]);
        }
        if ((i + 1) % per_line == 0 || i + 1 == values.size()) out.push_back('\n');
      }
    }
    Append(&out, "%6d\n", -1);
  }
  return out;
}

void WriteUff58(const fs::path& path, const std::vector<UffRecord>& records, UffEncoding encoding) {
  WriteFileAtomically(path, FormatUff58(records, encoding));
}

// ---- FRF conversion ----

namespace {

Eigen::Vector3d DirectionVector(int code) {
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  if (code == 0) return v;
  v[std::abs(code) - 1] = code > 0 ? 1.0 : -1.0;
  return v;
}

std::string ChannelName(int node, int direction) {
  if (direction == 0) return std::to_string(node);
  static const char kAxes[] = {'X', 'Y', 'Z'};
  return std::to_string(node) + (direction > 0 ? "+" : "-") + kAxes[std::abs(direction) - 1];
}

bool ParseChannelName(const std::string& name, int* node, int* direction) {
  if (name.size() < 3) return false;
  const char axis = name.back();
  const char sign = name[name.size() - 2];
  int d = axis == 'X' ? 1 : axis == 'Y' ? 2 : axis == 'Z' ? 3 : 0;
  if (d == 0 || (sign != '+' && sign != '-')) return false;
  long long v = 0;
  if (!ParseInt(std::string_view(name).substr(0, name.size() - 2), &v) || v < 0 || v > 99999999) {
    return false;
  }
  *node = static_cast<int>(v);
  *direction = sign == '+' ? d : -d;
  return true;
}

int DirectionCode(const Eigen::Vector3d& n) {
  for (int a = 0; a < 3; ++a) {
    if (n[a] == 1.0 && n.squaredNorm() == 1.0) return a + 1;
    if (n[a] == -1.0 && n.squaredNorm() == 1.0) return -(a + 1);
  }
  return 0;
}

std::string Lower(std::string s) {
  std::string out;
  for (char c : s) {
    if (c != ' ') out.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(c))));
  }
  return out;
}

// A units label as written by acquisition systems, lower case, without blanks and parentheses, with
// "²" and "s2" written "^2".
std::string NormalisedUnits(const std::string& label) {
  std::string u = Lower(label);
  std::string out;
  for (std::size_t i = 0; i < u.size(); ++i) {
    if (u[i] == '(' || u[i] == ')') continue;
    if (u.compare(i, 2, "\xC2\xB2") == 0) {
      out += "^2";
      ++i;
      continue;
    }
    if (u.compare(i, 2, "\xC2\xB5") == 0 || u.compare(i, 2, "\xCE\xBC") == 0) {  // micro sign, mu
      out += 'u';
      ++i;
      continue;
    }
    out += u[i];
  }
  for (const char* from : {"s2", "sec^2", "sec2"}) {
    const std::size_t at = out.find(from);
    if (at != std::string::npos && at + std::strlen(from) == out.size()) out.replace(at, std::strlen(from), "s^2");
  }
  const std::size_t slash_s2 = out.find("/s2/");
  if (slash_s2 != std::string::npos) out.replace(slash_s2, 4, "/s^2/");
  return out;
}

struct MotionUnit {
  FrfQuantity quantity;
  double to_si;  // SI value per unit
};

// The motion part of a units label ("g", "mm/s^2", "in/s", "um", ...).
std::optional<MotionUnit> ParseMotionUnit(const std::string& u) {
  static const std::pair<const char*, MotionUnit> kUnits[] = {
      {"g", {FrfQuantity::kAccelerance, 9.80665}},       {"m/s^2", {FrfQuantity::kAccelerance, 1.0}},
      {"mm/s^2", {FrfQuantity::kAccelerance, 1e-3}},     {"in/s^2", {FrfQuantity::kAccelerance, 0.0254}},
      {"ft/s^2", {FrfQuantity::kAccelerance, 0.3048}},   {"m/s/s", {FrfQuantity::kAccelerance, 1.0}},
      {"m/s", {FrfQuantity::kMobility, 1.0}},            {"mm/s", {FrfQuantity::kMobility, 1e-3}},
      {"in/s", {FrfQuantity::kMobility, 0.0254}},        {"m", {FrfQuantity::kReceptance, 1.0}},
      {"mm", {FrfQuantity::kReceptance, 1e-3}},          {"um", {FrfQuantity::kReceptance, 1e-6}},
      {"in", {FrfQuantity::kReceptance, 0.0254}},
  };
  for (const auto& [name, unit] : kUnits) {
    if (u == name) return unit;
  }
  return std::nullopt;
}

// Newtons per unit of a force label, or nullopt.
std::optional<double> ParseForceUnit(const std::string& u) {
  if (u == "n") return 1.0;
  if (u == "kn") return 1e3;
  if (u == "lbf" || u == "lb") return 4.4482216152605;
  return std::nullopt;
}

// A record's FRF units from its labels: the ordinate's label is "<motion>" or "<motion>/<force>"; the
// force may also be the denominator record's label.
struct LabelUnits {
  std::optional<MotionUnit> motion;
  std::optional<double> newtons;
};
LabelUnits ParseLabels(const UffRecord& r) {
  LabelUnits out;
  const std::string u = NormalisedUnits(r.ordinate.units_label);
  out.motion = ParseMotionUnit(u);
  if (!out.motion) {
    const std::size_t slash = u.rfind('/');
    if (slash != std::string::npos) {
      const auto force = ParseForceUnit(u.substr(slash + 1));
      const auto motion = ParseMotionUnit(u.substr(0, slash));
      if (force && motion) {
        out.motion = motion;
        out.newtons = force;
      }
    }
  }
  if (!out.newtons) out.newtons = ParseForceUnit(NormalisedUnits(r.ordinate_denominator.units_label));
  return out;
}

std::optional<FrfQuantity> RecogniseQuantity(const UffRecord& r) {
  switch (r.ordinate.specific_data_type) {
    case uff_data_type::kAcceleration:
      return FrfQuantity::kAccelerance;
    case uff_data_type::kVelocity:
      return FrfQuantity::kMobility;
    case uff_data_type::kDisplacement:
      return FrfQuantity::kReceptance;
    default:
      break;
  }
  if (const auto labels = ParseLabels(r); labels.motion) return labels.motion->quantity;
  const std::string u = Lower(r.ordinate.units_label);
  for (const char* p : {"m/s^2", "m/s2", "m/s\xC2\xB2", "m/s/s", "m/(s^2", "/s^2", "/s\xC2\xB2"}) {
    if (u.find(p) != std::string::npos) return FrfQuantity::kAccelerance;
  }
  if (u == "g" || u == "g/n" || u.find("(g)") != std::string::npos) return FrfQuantity::kAccelerance;
  if (u.find("m/s") != std::string::npos) return FrfQuantity::kMobility;
  if (u == "m/n" || u == "m" || u.find("(m)") != std::string::npos ||
      u.find("m/n") != std::string::npos) {
    return FrfQuantity::kReceptance;
  }
  return std::nullopt;
}

constexpr std::string_view kChannelsPrefix = "channels: ";

// Channel names written by ConvertFrfDataToUff in record 4 ("channels: <output> / <input>").
bool ChannelNamesFromId(const UffRecord& r, std::string* output, std::string* input) {
  const std::string& id = r.id[3];
  if (id.rfind(kChannelsPrefix, 0) != 0) return false;
  const std::string rest = id.substr(kChannelsPrefix.size());
  const std::size_t slash = rest.find(" / ");
  if (slash == std::string::npos || slash == 0 || slash + 3 >= rest.size()) return false;
  *output = rest.substr(0, slash);
  *input = rest.substr(slash + 3);
  return true;
}

}  // namespace

std::optional<std::pair<FrfQuantity, double>> UffMotionUnitToSi(const std::string& label) {
  const auto unit = ParseMotionUnit(NormalisedUnits(label));
  if (!unit) return std::nullopt;
  return std::make_pair(unit->quantity, unit->to_si);
}

std::optional<double> UffForceUnitToNewtons(const std::string& label) { return ParseForceUnit(NormalisedUnits(label)); }

double UffFrfScaleToSi(const UffRecord& r, const UffFile& file, std::string* how) {
  const LabelUnits labels = ParseLabels(r);
  char text[160];
  if (labels.motion) {
    const double newtons = labels.newtons.value_or(1.0);
    const double factor = labels.motion->to_si / newtons;
    std::snprintf(text, sizeof text, "units labels '%s' / '%s': x %.10g", r.ordinate.units_label.c_str(),
                  r.ordinate_denominator.units_label.c_str(), factor);
    if (how) *how = text;
    return factor;
  }
  if (file.has_units && (file.length_factor != 1.0 || file.force_factor != 1.0)) {
    // value_file / factor^exponent = value_SI, per axis; the FRF is ordinate / denominator.
    const int length = r.ordinate.length_unit_exponent - r.ordinate_denominator.length_unit_exponent;
    const int force = r.ordinate.force_unit_exponent - r.ordinate_denominator.force_unit_exponent;
    const double factor = std::pow(file.length_factor, -length) * std::pow(file.force_factor, -force);
    std::snprintf(text, sizeof text, "dataset 164 (%s): length^%d force^%d: x %.10g", file.units_description.c_str(),
                  length, force, factor);
    if (how) *how = text;
    return factor;
  }
  if (how) *how = "SI assumed";
  return 1.0;
}

FrfData ConvertUffToFrfData(const std::vector<UffRecord>& records, const std::string& source,
                            const UffFrfOptions& options) {
  const std::string where = "UFF file '" + source + "'";
  std::vector<std::size_t> frf_index, coherence_index;
  for (std::size_t i = 0; i < records.size(); ++i) {
    if (records[i].function_type == uff_function::kFrequencyResponseFunction) frf_index.push_back(i);
    if (records[i].function_type == uff_function::kCoherence) coherence_index.push_back(i);
  }
  if (frf_index.empty()) {
    throw InputError(where + ": no FRF record (dataset 58 with function type 4) among its " +
                     std::to_string(records.size()) + " dataset(s)");
  }
  const UffRecord& first = records[frf_index.front()];
  std::optional<FrfQuantity> quantity = options.quantity;
  if (!quantity) quantity = RecogniseQuantity(first);
  if (!quantity) {
    throw InputError(where + ": record 9 of the first FRF (specific data type " +
                     std::to_string(first.ordinate.specific_data_type) + ", units '" +
                     first.ordinate.units_label +
                     "') does not say whether the FRFs are accelerance, mobility or receptance; "
                     "expected data type 8, 11 or 12 or units such as m/s^2, m/s or m");
  }

  using Dof = std::pair<int, int>;
  std::vector<Dof> outputs, inputs;
  std::map<Dof, std::string> output_names, input_names;
  auto index_of = [](std::vector<Dof>& list, const Dof& d) {
    auto it = std::find(list.begin(), list.end(), d);
    if (it != list.end()) return static_cast<int>(it - list.begin());
    list.push_back(d);
    return static_cast<int>(list.size() - 1);
  };
  auto record_label = [&](std::size_t i) {
    return where + ", dataset 58 number " + std::to_string(i + 1) + " (response " +
           std::to_string(records[i].response_node) + ":" +
           std::to_string(records[i].response_direction) + ", reference " +
           std::to_string(records[i].reference_node) + ":" +
           std::to_string(records[i].reference_direction) + ")";
  };
  for (std::size_t i : frf_index) {
    const UffRecord& r = records[i];
    if (!r.is_complex()) {
      throw InputError(record_label(i) + ": FRF with real ordinate data type " +
                       std::to_string(static_cast<int>(r.ordinate_type)) +
                       ", expected complex data (type 5 or 6)");
    }
    for (int d : {r.response_direction, r.reference_direction}) {
      if (std::abs(d) > 3) {
        throw InputError(record_label(i) + ": direction code " + std::to_string(d) +
                         ", expected 0 or +-1..3 (translations; rotational DOF are not supported)");
      }
    }
    if (r.x.size() != first.x.size() || r.x != first.x) {
      throw InputError(record_label(i) + ": its abscissa (" + std::to_string(r.x.size()) +
                       " points) differs from the first FRF's (" +
                       std::to_string(first.x.size()) + " points), expected the same frequencies");
    }
    const Dof out{r.response_node, r.response_direction};
    const Dof in{r.reference_node, r.reference_direction};
    index_of(outputs, out);
    index_of(inputs, in);
    std::string out_name, in_name;
    if (!ChannelNamesFromId(r, &out_name, &in_name)) {
      out_name = ChannelName(out.first, out.second);
      in_name = ChannelName(in.first, in.second);
    }
    output_names.emplace(out, out_name);
    input_names.emplace(in, in_name);
  }

  const Eigen::Index n_all = first.x.size();
  const Eigen::Index skip = (options.drop_zero_frequency && n_all > 1 && first.x[0] == 0.0) ? 1 : 0;
  const int nf = static_cast<int>(n_all - skip);
  const int nout = static_cast<int>(outputs.size());
  const int nin = static_cast<int>(inputs.size());

  FrfData data;
  data.source = source;
  data.quantity = *quantity;
  data.frequency_hz = first.x.tail(nf);
  data.frf.assign(nf, Eigen::MatrixXcd::Zero(nout, nin));
  std::vector<std::vector<int>> seen(nout, std::vector<int>(nin, -1));
  for (std::size_t i : frf_index) {
    const UffRecord& r = records[i];
    const int o = index_of(outputs, {r.response_node, r.response_direction});
    const int j = index_of(inputs, {r.reference_node, r.reference_direction});
    if (seen[o][j] >= 0) {
      throw InputError(record_label(i) + ": a second FRF for this response/reference pair (the "
                       "first is dataset number " + std::to_string(seen[o][j] + 1) + ")");
    }
    seen[o][j] = static_cast<int>(i);
    const double scale = i < options.scale_to_si.size() ? options.scale_to_si[i] : 1.0;
    for (int k = 0; k < nf; ++k) data.frf[k](o, j) = scale * r.complex_y[k + skip];
  }
  for (int o = 0; o < nout; ++o) {
    for (int j = 0; j < nin; ++j) {
      if (seen[o][j] < 0) {
        throw InputError(where + ": no FRF for response " + output_names[outputs[o]] +
                         " and reference " + input_names[inputs[j]] +
                         ", expected one FRF record per response/reference pair");
      }
    }
  }
  if (!coherence_index.empty()) {
    data.coherence.assign(nf, Eigen::MatrixXd::Zero(nout, nin));
    std::vector<std::vector<bool>> have(nout, std::vector<bool>(nin, false));
    for (std::size_t i : coherence_index) {
      const UffRecord& r = records[i];
      const Dof out{r.response_node, r.response_direction};
      const Dof in{r.reference_node, r.reference_direction};
      auto o_it = std::find(outputs.begin(), outputs.end(), out);
      auto j_it = std::find(inputs.begin(), inputs.end(), in);
      if (o_it == outputs.end() || j_it == inputs.end()) continue;
      if (r.x.size() != first.x.size() || r.x != first.x) {
        throw InputError(record_label(i) + ": coherence abscissa differs from the FRFs'");
      }
      const int o = static_cast<int>(o_it - outputs.begin());
      const int j = static_cast<int>(j_it - inputs.begin());
      for (int k = 0; k < nf; ++k) {
        data.coherence[k](o, j) = r.is_complex() ? r.complex_y[k + skip].real() : r.real_y[k + skip];
      }
      have[o][j] = true;
    }
    for (int o = 0; o < nout; ++o) {
      for (int j = 0; j < nin; ++j) {
        if (!have[o][j]) {
          throw InputError(where + ": coherence records are present but none for response " +
                           output_names[outputs[o]] + " and reference " + input_names[inputs[j]]);
        }
      }
    }
  }
  auto make_channels = [&](const std::vector<Dof>& dofs, std::map<Dof, std::string>& names,
                           std::vector<ChannelGeometry>* channels) {
    for (const Dof& d : dofs) {
      ChannelGeometry c;
      c.name = names[d];
      c.direction_W = DirectionVector(d.second);
      auto it = options.nodes.find(d.first);
      std::optional<UffNodeLocation> from_file;
      if (it == options.nodes.end() && !options.node_body.empty()) {
        const auto f = options.file_nodes_m.find(d.first);
        if (f != options.file_nodes_m.end()) from_file = UffNodeLocation{options.node_body, f->second};
      }
      if (it != options.nodes.end() || from_file) {
        const UffNodeLocation& location = from_file ? *from_file : it->second;
        if (d.second == 0) {
          throw InputError(where + ": node " + std::to_string(d.first) +
                           " has a location but channel '" + c.name +
                           "' has direction code 0 (scalar), expected +-1..3");
        }
        c.body = location.body;
        c.position_W = location.position_W;
      }
      channels->push_back(c);
    }
  };
  make_channels(outputs, output_names, &data.outputs);
  make_channels(inputs, input_names, &data.inputs);
  Validate(data);
  return data;
}

std::vector<UffRecord> ConvertFrfDataToUff(const FrfData& data) {
  Validate(data);
  const int nf = data.num_frequencies();
  UffRecord base;
  base.function_type = uff_function::kFrequencyResponseFunction;
  base.ordinate_type = UffOrdinateType::kComplexDouble;
  base.abscissa.specific_data_type = uff_data_type::kFrequency;
  base.abscissa.label = "Frequency";
  base.abscissa.units_label = "Hz";
  switch (data.quantity) {
    case FrfQuantity::kAccelerance:
      base.ordinate.specific_data_type = uff_data_type::kAcceleration;
      base.ordinate.units_label = "m/s^2";
      break;
    case FrfQuantity::kMobility:
      base.ordinate.specific_data_type = uff_data_type::kVelocity;
      base.ordinate.units_label = "m/s";
      break;
    case FrfQuantity::kReceptance:
      base.ordinate.specific_data_type = uff_data_type::kDisplacement;
      base.ordinate.units_label = "m";
      break;
  }
  base.ordinate.label = ToString(data.quantity);
  base.ordinate_denominator.specific_data_type = uff_data_type::kExcitationForce;
  base.ordinate_denominator.label = "Force";
  base.ordinate_denominator.units_label = "N";

  // Even spacing only when the reader's recomputation from the printed E13.5 values is exact.
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%13.5E", data.frequency_hz[0]);
  double f0 = 0.0;
  ParseReal(buffer, &f0);
  double df = 0.0;
  if (nf > 1) {
    std::snprintf(buffer, sizeof buffer, "%13.5E", data.frequency_hz[1] - data.frequency_hz[0]);
    ParseReal(buffer, &df);
  }
  bool even = nf == 1 ? f0 == data.frequency_hz[0] : df > 0.0;
  for (int k = 0; k < nf && even; ++k) {
    even = f0 + static_cast<double>(k) * df == data.frequency_hz[k];
  }
  base.even_abscissa = even;
  base.abscissa_minimum = even ? f0 : 0.0;
  base.abscissa_increment = even ? df : 0.0;
  base.x = data.frequency_hz;

  auto node_and_direction = [](const ChannelGeometry& c, int fallback_node, int* node, int* dir) {
    if (!ParseChannelName(c.name, node, dir)) {
      *node = fallback_node;
      *dir = DirectionCode(c.direction_W);
    }
  };
  std::vector<UffRecord> records;
  for (int o = 0; o < data.num_outputs(); ++o) {
    for (int j = 0; j < data.num_inputs(); ++j) {
      UffRecord r = base;
      node_and_direction(data.outputs[o], o + 1, &r.response_node, &r.response_direction);
      node_and_direction(data.inputs[j], 1001 + j, &r.reference_node, &r.reference_direction);
      r.id[0] = "FRF " + data.outputs[o].name + " / " + data.inputs[j].name;
      r.id[3] = std::string(kChannelsPrefix) + data.outputs[o].name + " / " + data.inputs[j].name;
      r.complex_y.resize(nf);
      for (int k = 0; k < nf; ++k) r.complex_y[k] = data.frf[k](o, j);
      records.push_back(r);
      if (data.has_coherence()) {
        UffRecord c = r;
        c.function_type = uff_function::kCoherence;
        c.ordinate_type = UffOrdinateType::kRealDouble;
        c.id[0] = "Coherence " + data.outputs[o].name + " / " + data.inputs[j].name;
        c.ordinate = UffAxis{};
        c.ordinate.label = "Coherence";
        c.ordinate_denominator = UffAxis{};
        c.complex_y.resize(0);
        c.real_y.resize(nf);
        for (int k = 0; k < nf; ++k) c.real_y[k] = data.coherence[k](o, j);
        records.push_back(c);
      }
    }
  }
  return records;
}

FrfData ReadUffMeasurement(const fs::path& path, const UffFrfOptions& options) {
  const UffFile file = ReadUffFile(path);
  UffFrfOptions with_file = options;
  if (with_file.file_nodes_m.empty()) with_file.file_nodes_m = file.nodes_m;
  if (with_file.scale_to_si.empty()) {
    for (const UffRecord& r : file.records) with_file.scale_to_si.push_back(UffFrfScaleToSi(r, file));
  }
  return ConvertUffToFrfData(file.records, path.string(), with_file);
}

void WriteUffMeasurement(const fs::path& path, const FrfData& data, UffEncoding encoding) {
  WriteUff58(path, ConvertFrfDataToUff(data), encoding);
}

}  // namespace stagefit::measurement
