#include "stagefit/measurement/csv_file.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <sstream>
#include <string_view>

#include "stagefit/common/atomic_file.h"
#include "stagefit/common/csv_meta.h"
#include "stagefit/common/error.h"

namespace stagefit::measurement {
namespace fs = std::filesystem;

namespace {

constexpr std::string_view kBlanks = " \t\r";

std::string_view Trim(std::string_view s) {
  const std::size_t b = s.find_first_not_of(kBlanks);
  if (b == std::string_view::npos) return {};
  return s.substr(b, s.find_last_not_of(kBlanks) - b + 1);
}

std::string ReadFile(const fs::path& path, const char* what) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    throw InputError(std::string(what) + " '" + path.string() +
                     "': does not exist or is not a regular file");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(std::string(what) + " '" + path.string() + "': cannot be opened");
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

class LineError {
 public:
  LineError(std::string file) : file_(std::move(file)) {}
  [[noreturn]] void Fail(int line, const std::string& message) const {
    throw InputError("CSV file '" + file_ + "', line " + std::to_string(line) + ": " + message);
  }
  const std::string& file() const { return file_; }

 private:
  std::string file_;
};

// Splits one CSV line into fields; double quotes protect commas, "" is a quote.
std::vector<std::string> SplitFields(std::string_view line, const LineError& err, int line_no) {
  std::vector<std::string> fields(1);
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        fields.back().push_back('"');
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        fields.back().push_back(c);
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      fields.emplace_back();
    } else {
      fields.back().push_back(c);
    }
  }
  if (quoted) err.Fail(line_no, "unterminated double quote");
  for (auto& f : fields) f = std::string(Trim(f));
  return fields;
}

std::vector<std::pair<int, std::string_view>> Lines(std::string_view content) {
  std::vector<std::pair<int, std::string_view>> lines;
  int n = 0;
  std::size_t pos = 0;
  while (pos < content.size()) {
    std::size_t e = content.find('\n', pos);
    if (e == std::string_view::npos) e = content.size();
    std::string_view line = content.substr(pos, e - pos);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    lines.emplace_back(++n, line);
    pos = e + 1;
  }
  return lines;
}

double ParseNumber(const std::string& text, const LineError& err, int line, const char* column) {
  std::string_view t = text;
  if (!t.empty() && t.front() == '+') t.remove_prefix(1);
  double v = 0.0;
  const auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  if (t.empty() || ec != std::errc() || ptr != t.data() + t.size()) {
    err.Fail(line, "column '" + std::string(column) + "': '" + text + "' is not a number");
  }
  if (!std::isfinite(v)) {
    err.Fail(line, "column '" + std::string(column) + "': " + text + ", expected a finite number");
  }
  return v;
}

std::string FormatNumber(double v) {
  char buffer[64];
  const auto [ptr, ec] = std::to_chars(buffer, buffer + sizeof buffer, v);
  STAGEFIT_ASSERT(ec == std::errc(), "to_chars failed");
  return std::string(buffer, ptr);
}

std::string QuoteField(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos && Trim(s) == s) return s;
  std::string out = "\"";
  for (char c : s) {
    if (c == '"') out += "\"\"";
    else out.push_back(c);
  }
  return out + "\"";
}

struct Point {
  double f, re, im, coherence;
  int line;
};

void ReadSidecar(const fs::path& sidecar, FrfData* data, bool require_geometry, const std::string& of = "the CSV") {
  const std::string content = ReadFile(sidecar, "CSV geometry file");
  const LineError err(sidecar.string());
  std::map<std::string, int> outputs, inputs;
  for (int i = 0; i < data->num_outputs(); ++i) outputs[data->outputs[i].name] = i;
  for (int j = 0; j < data->num_inputs(); ++j) inputs[data->inputs[j].name] = j;
  std::vector<bool> seen_out(data->num_outputs(), false), seen_in(data->num_inputs(), false);
  bool header = false;
  static const char* kColumns[] = {"kind", "name", "body", "x", "y", "z", "nx", "ny", "nz"};
  for (const auto& [line_no, line] : Lines(content)) {
    const std::string_view t = Trim(line);
    if (t.empty() || t.front() == '#') continue;
    const auto fields = SplitFields(line, err, line_no);
    if (!header) {
      bool ok = fields.size() == 9;
      for (int c = 0; ok && c < 9; ++c) ok = fields[c] == kColumns[c];
      if (!ok) {
        err.Fail(line_no, "header '" + std::string(t) + "', expected 'kind,name,body,x,y,z,nx,ny,nz'");
      }
      header = true;
      continue;
    }
    if (fields.size() != 9) {
      err.Fail(line_no, std::to_string(fields.size()) + " fields, expected 9 (kind,name,body,x,y,z,nx,ny,nz)");
    }
    const std::string& kind = fields[0];
    const std::string& name = fields[1];
    ChannelGeometry* channel = nullptr;
    if (kind == "sensor") {
      auto it = outputs.find(name);
      if (it == outputs.end()) err.Fail(line_no, "sensor '" + name + "' is not an output of " + of);
      if (seen_out[it->second]) err.Fail(line_no, "sensor '" + name + "' is listed twice");
      seen_out[it->second] = true;
      channel = &data->outputs[it->second];
    } else if (kind == "impact") {
      auto it = inputs.find(name);
      if (it == inputs.end()) err.Fail(line_no, "impact '" + name + "' is not an input of " + of);
      if (seen_in[it->second]) err.Fail(line_no, "impact '" + name + "' is listed twice");
      seen_in[it->second] = true;
      channel = &data->inputs[it->second];
    } else {
      err.Fail(line_no, "column 'kind': '" + kind + "', expected 'sensor' or 'impact'");
    }
    bool all_empty = fields[2].empty();
    for (int c = 3; c < 9; ++c) all_empty = all_empty && fields[c].empty();
    if (all_empty) {
      if (require_geometry) err.Fail(line_no, kind + " '" + name + "': missing geometry (empty body and coordinates)");
      continue;
    }
    if (fields[2].empty()) err.Fail(line_no, kind + " '" + name + "': column 'body' is empty, expected a body name");
    double v[6];
    for (int c = 0; c < 6; ++c) {
      if (fields[3 + c].empty()) {
        err.Fail(line_no, kind + " '" + name + "': column '" + kColumns[3 + c] +
                              "' is empty, expected a number (missing geometry)");
      }
      v[c] = ParseNumber(fields[3 + c], err, line_no, kColumns[3 + c]);
    }
    channel->body = fields[2];
    channel->position_W = Eigen::Vector3d(v[0], v[1], v[2]);
    channel->direction_W = Eigen::Vector3d(v[3], v[4], v[5]);
    const double norm = channel->direction_W.norm();
    if (std::abs(norm - 1.0) > kUnitDirectionTolerance) {
      std::ostringstream m;
      m << kind << " '" << name << "': direction (nx, ny, nz) has length " << norm
        << ", expected a unit vector";
      err.Fail(line_no, m.str());
    }
  }
  if (!header) err.Fail(0, "empty, expected the header 'kind,name,body,x,y,z,nx,ny,nz'");
  for (int i = 0; i < data->num_outputs(); ++i) {
    if (!seen_out[i]) {
      throw InputError("CSV geometry file '" + sidecar.string() + "': output '" +
                       data->outputs[i].name + "' of " + of + " has no 'sensor' row (missing geometry)");
    }
  }
  for (int j = 0; j < data->num_inputs(); ++j) {
    if (!seen_in[j]) {
      throw InputError("CSV geometry file '" + sidecar.string() + "': input '" +
                       data->inputs[j].name + "' of " + of + " has no 'impact' row (missing geometry)");
    }
  }
}

}  // namespace

void ApplyGeometryFile(const fs::path& geometry_csv, FrfData* data, bool require_geometry) {
  std::error_code ec;
  if (!fs::exists(geometry_csv, ec)) {
    throw InputError("geometry file '" + geometry_csv.string() + "' does not exist, expected a CSV with the header "
                     "kind,name,body,x,y,z,nx,ny,nz");
  }
  ReadSidecar(geometry_csv, data, require_geometry, "the measurement '" + data->source + "'");
  Validate(*data);
}

fs::path GeometrySidecarPath(const fs::path& csv_path) {
  fs::path p = csv_path;
  p.replace_filename(csv_path.stem().string() + ".geometry.csv");
  return p;
}

FrfData ReadCsvMeasurement(const fs::path& path, bool require_geometry) {
  const std::string content = ReadFile(path, "CSV file");
  const LineError err(path.string());
  FrfData data;
  data.source = path.string();
  bool header = false;
  bool with_coherence = false;
  bool quantity_given = false;
  std::map<std::string, int> output_index, input_index;
  std::vector<std::vector<std::vector<Point>>> points;  // [output][input] -> points
  const auto lines = Lines(content);
  for (const auto& [line_no, line] : lines) {
    const std::string_view t = Trim(line);
    if (t.empty()) continue;
    if (t.front() == '#') {
      if (header) continue;
      std::string_view body = Trim(t.substr(1));
      const std::size_t colon = body.find(':');
      if (colon == std::string_view::npos) continue;
      const std::string key(Trim(body.substr(0, colon)));
      const std::string value(Trim(body.substr(colon + 1)));
      if (key == "quantity") {
        quantity_given = true;
        const auto q = ParseFrfQuantity(value);
        if (!q) {
          err.Fail(line_no, "'# quantity: " + value +
                                "', expected accelerance, mobility, receptance or compliance");
        }
        data.quantity = *q;
      } else if (key == "frame_origin") {
        std::istringstream in(value);
        std::string token;
        std::vector<double> v;
        while (in >> token) v.push_back(ParseNumber(token, err, line_no, "frame_origin"));
        if (v.size() != 3) {
          err.Fail(line_no, "'# frame_origin: " + value + "', expected three numbers x y z in m");
        }
        data.frame_origin_W = Eigen::Vector3d(v[0], v[1], v[2]);
      }
      continue;
    }
    const auto fields = SplitFields(line, err, line_no);
    if (!header) {
      const std::vector<std::string> base = {"freq_hz", "output", "input", "re", "im"};
      std::vector<std::string> with = base;
      with.push_back("coherence");
      if (fields == base) {
        with_coherence = false;
      } else if (fields == with) {
        with_coherence = true;
      } else {
        err.Fail(line_no, "header '" + std::string(t) +
                              "', expected 'freq_hz,output,input,re,im' or "
                              "'freq_hz,output,input,re,im,coherence'");
      }
      header = true;
      continue;
    }
    const std::size_t expected = with_coherence ? 6 : 5;
    if (fields.size() != expected) {
      err.Fail(line_no, std::to_string(fields.size()) + " fields, expected " +
                            std::to_string(expected) + " as in the header");
    }
    Point p;
    p.line = line_no;
    p.f = ParseNumber(fields[0], err, line_no, "freq_hz");
    if (fields[1].empty()) err.Fail(line_no, "column 'output' is empty, expected a channel name");
    if (fields[2].empty()) err.Fail(line_no, "column 'input' is empty, expected a channel name");
    p.re = ParseNumber(fields[3], err, line_no, "re");
    p.im = ParseNumber(fields[4], err, line_no, "im");
    p.coherence = 0.0;
    if (with_coherence) {
      p.coherence = ParseNumber(fields[5], err, line_no, "coherence");
      if (p.coherence < 0.0 || p.coherence > 1.0) {
        err.Fail(line_no, "column 'coherence': " + fields[5] + ", expected a value in [0, 1]");
      }
    }
    // Every pair needs a row per frequency: refuse channel counts the file cannot hold before the
    // pair table (outputs x inputs) is allocated.
    const std::size_t nout = output_index.size() + !output_index.count(fields[1]);
    const std::size_t nin = input_index.size() + !input_index.count(fields[2]);
    if (static_cast<double>(nout) * static_cast<double>(nin) > static_cast<double>(lines.size())) {
      std::ostringstream m;
      m << "with output '" << fields[1] << "' and input '" << fields[2] << "' the file names " << nout
        << " outputs and " << nin << " inputs, whose pairs need at least " << nout * nin
        << " rows, but it has only " << lines.size()
        << " lines; expected one row per output, input and frequency";
      err.Fail(line_no, m.str());
    }
    auto [o_it, o_new] = output_index.emplace(fields[1], static_cast<int>(output_index.size()));
    if (o_new) {
      ChannelGeometry c;
      c.name = fields[1];
      data.outputs.push_back(c);
      points.emplace_back(data.inputs.size());
    }
    auto [i_it, i_new] = input_index.emplace(fields[2], static_cast<int>(input_index.size()));
    if (i_new) {
      ChannelGeometry c;
      c.name = fields[2];
      data.inputs.push_back(c);
      for (auto& row : points) row.emplace_back();
    }
    auto& list = points[o_it->second][i_it->second];
    if (!list.empty() && !(p.f > list.back().f)) {
      std::ostringstream m;
      m.precision(17);
      m << "freq_hz = " << p.f << " Hz for output '" << fields[1] << "' and input '" << fields[2]
        << "' is not above the previous " << list.back().f << " Hz (line " << list.back().line
        << "), expected strictly increasing frequencies per pair (a repeated row?)";
      err.Fail(line_no, m.str());
    }
    list.push_back(p);
  }
  if (!header) {
    throw InputError("CSV file '" + path.string() +
                     "': no header line, expected 'freq_hz,output,input,re,im[,coherence]'");
  }
  if (data.outputs.empty()) {
    throw InputError("CSV file '" + path.string() + "': no data rows after the header");
  }
  const auto& reference = points[0][0];
  const int nout = data.num_outputs(), nin = data.num_inputs();
  const int nf = static_cast<int>(reference.size());
  for (int o = 0; o < nout; ++o) {
    for (int j = 0; j < nin; ++j) {
      const auto& list = points[o][j];
      const std::string pair = "output '" + data.outputs[o].name + "' and input '" +
                               data.inputs[j].name + "'";
      if (list.empty()) {
        throw InputError("CSV file '" + path.string() + "': no rows for " + pair +
                         ", expected one row per output, input and frequency");
      }
      for (int k = 0; k < std::min<int>(nf, static_cast<int>(list.size())); ++k) {
        if (list[k].f != reference[k].f) {
          std::ostringstream m;
          m.precision(17);
          m << "frequency " << k + 1 << " of " << pair << " is " << list[k].f
            << " Hz, expected " << reference[k].f << " Hz as for the first pair (line "
            << reference[k].line << ")";
          err.Fail(list[k].line, m.str());
        }
      }
      if (static_cast<int>(list.size()) != nf) {
        throw InputError("CSV file '" + path.string() + "': " + pair + " has " +
                         std::to_string(list.size()) + " frequencies, expected " +
                         std::to_string(nf) + " as the first pair");
      }
    }
  }
  data.frequency_hz.resize(nf);
  data.frf.assign(nf, Eigen::MatrixXcd(nout, nin));
  if (with_coherence) data.coherence.assign(nf, Eigen::MatrixXd(nout, nin));
  for (int k = 0; k < nf; ++k) {
    data.frequency_hz[k] = reference[k].f;
    for (int o = 0; o < nout; ++o) {
      for (int j = 0; j < nin; ++j) {
        const Point& p = points[o][j][k];
        data.frf[k](o, j) = {p.re, p.im};
        if (with_coherence) data.coherence[k](o, j) = p.coherence;
      }
    }
  }
  // A header-first file keeps its quantity and frame origin in "<stem>.meta.json" ("# quantity:" and
  // "# frame_origin:" lines of an older file win).
  if (const auto meta = ReadCsvMeta(path)) {
    const auto q = meta->fields.find("quantity");
    if (!quantity_given && q != meta->fields.end()) {
      const auto parsed = ParseFrfQuantity(q->second);
      if (!parsed) {
        throw InputError("'" + CsvMetaPath(path).string() + "': quantity '" + q->second +
                         "', expected accelerance, mobility, receptance or compliance");
      }
      data.quantity = *parsed;
    }
    if (!data.frame_origin_W && meta->frame_origin_m.size() == 3) {
      data.frame_origin_W = Eigen::Vector3d(meta->frame_origin_m[0], meta->frame_origin_m[1], meta->frame_origin_m[2]);
    }
    if (!meta->num_averages.empty()) {
      if (static_cast<int>(meta->num_averages.size()) != data.num_inputs()) {
        throw InputError("'" + CsvMetaPath(path).string() + "': num_averages: " + std::to_string(meta->num_averages.size()) +
                         " counts, expected " + std::to_string(data.num_inputs()) +
                         " (one per input, in the order the inputs first appear)");
      }
      data.averages = meta->num_averages;
    }
  }
  const fs::path sidecar = GeometrySidecarPath(path);
  std::error_code ec;
  if (fs::exists(sidecar, ec)) {
    ReadSidecar(sidecar, &data, require_geometry);
  } else if (require_geometry) {
    throw InputError("CSV file '" + path.string() + "': missing geometry: the sidecar '" +
                     sidecar.string() + "' does not exist");
  }
  Validate(data);
  return data;
}

void WriteCsvMeasurement(const fs::path& path, const FrfData& data) {
  Validate(data);
  // Header first, data rows only (docs/csv-outputs.md): the quantity, the frame origin and the units
  // go to the "<stem>.meta.json" sidecar.
  CsvMeta meta = FrfCsvMeta(data.quantity, data.has_coherence());
  if (data.frame_origin_W) {
    meta.frame_origin_m = {(*data.frame_origin_W)[0], (*data.frame_origin_W)[1], (*data.frame_origin_W)[2]};
  }
  if (!data.averages.empty()) {
    meta.num_averages = data.averages;
    meta.notes.push_back("coherence: the ordinary coherence of the hits averaged; num_averages: their number per input, "
                         "in the order the inputs first appear");
  }
  std::string out;
  out += data.has_coherence() ? "freq_hz,output,input,re,im,coherence\n"
                              : "freq_hz,output,input,re,im\n";
  for (int o = 0; o < data.num_outputs(); ++o) {
    const std::string out_name = QuoteField(data.outputs[o].name);
    for (int j = 0; j < data.num_inputs(); ++j) {
      const std::string in_name = QuoteField(data.inputs[j].name);
      for (int k = 0; k < data.num_frequencies(); ++k) {
        const std::complex<double> h = data.frf[k](o, j);
        out += FormatNumber(data.frequency_hz[k]) + "," + out_name + "," + in_name + "," +
               FormatNumber(h.real()) + "," + FormatNumber(h.imag());
        if (data.has_coherence()) out += "," + FormatNumber(data.coherence[k](o, j));
        out += "\n";
      }
    }
  }
  std::string geometry = "kind,name,body,x,y,z,nx,ny,nz\n";
  auto add = [&](const char* kind, const ChannelGeometry& c) {
    geometry += std::string(kind) + "," + QuoteField(c.name) + ",";
    if (!c.has_geometry()) {
      geometry += ",,,,,,\n";
      return;
    }
    geometry += QuoteField(c.body);
    for (int a = 0; a < 3; ++a) geometry += "," + FormatNumber(c.position_W[a]);
    for (int a = 0; a < 3; ++a) geometry += "," + FormatNumber(c.direction_W[a]);
    geometry += "\n";
  };
  for (const auto& c : data.outputs) add("sensor", c);
  for (const auto& c : data.inputs) add("impact", c);
  WriteFileAtomically(path, out);
  WriteFileAtomically(GeometrySidecarPath(path), geometry);
  WriteCsvMeta(path, meta);
}

CsvMeta FrfCsvMeta(FrfQuantity quantity, bool with_coherence) {
  CsvMeta meta;
  meta.fields["quantity"] = ToString(quantity);
  const char* unit = quantity == FrfQuantity::kAccelerance ? "m/s^2/N"
                     : quantity == FrfQuantity::kMobility  ? "m/s/N"
                                                           : "m/N";
  meta.units = {{"freq_hz", "Hz"}, {"output", ""}, {"input", ""}, {"re", unit}, {"im", unit}};
  if (with_coherence) meta.units.emplace_back("coherence", "1");
  meta.notes = {std::string("re, im: the FRF (") + ToString(quantity) + ") output/input in SI units: " + unit +
                " for a translation over a force; rad for a rotation output, Nm for a torque input",
                "geometry of the channels: the .geometry.csv sidecar (kind,name,body,x,y,z,nx,ny,nz; m, unit vectors)"};
  return meta;
}

}  // namespace stagefit::measurement
