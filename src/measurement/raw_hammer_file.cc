#include "stagefit/measurement/raw_hammer_file.h"

#include <matio.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <optional>
#include <sstream>
#include <system_error>

#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"
#include "mat_v5_structure.h"

namespace stagefit::measurement {
namespace {

struct MatCloser {
  void operator()(mat_t* m) const {
    if (m != nullptr) Mat_Close(m);
  }
};
struct VarFreer {
  void operator()(matvar_t* v) const {
    if (v != nullptr) Mat_VarFree(v);
  }
};
using MatPtr = std::unique_ptr<mat_t, MatCloser>;
using VarPtr = std::unique_ptr<matvar_t, VarFreer>;

std::string SizeText(const std::vector<std::size_t>& dims) {
  std::ostringstream s;
  for (std::size_t i = 0; i < dims.size(); ++i) s << (i ? " x " : "") << dims[i];
  return s.str();
}

class Reader {
 public:
  explicit Reader(const std::filesystem::path& path) : path_(path) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) {
      throw InputError("'" + path.string() + "': no such file, expected a raw hammer .mat file");
    }
    // zlib compresses by at most about 1032:1 and every value takes at least one byte: a variable
    // declaring more values than this is a corrupt size field, rejected before matio allocates it.
    max_values_ = static_cast<long double>(std::filesystem::file_size(path, ec)) * 1100.0L + 1048576.0L;
    internal::CheckMatFileStructure(path, static_cast<std::uint64_t>(max_values_));
    mat_.reset(Mat_Open(path.string().c_str(), MAT_ACC_RDONLY));
    if (!mat_) {
      throw InputError("'" + path.string() +
                       "': not a MATLAB .mat file (v5 or v7.3), expected raw hammer time data");
    }
  }

  [[noreturn]] void Fail(const std::string& variable, const std::string& message) const {
    throw InputError("'" + path_.string() + "': " + variable + ": " + message);
  }

  // Header only (class and sizes); null when absent.
  VarPtr Info(const char* name) const { return VarPtr(Mat_VarReadInfo(mat_.get(), name)); }

  static std::vector<std::size_t> Dims(const matvar_t* v) {
    return std::vector<std::size_t>(v->dims, v->dims + v->rank);
  }

  // A numeric variable's dimensions padded with trailing ones to `rank`, checked against the size
  // limit before any data are read, then its values (column-major) as doubles.
  std::vector<double> Numeric(const char* name, int rank, std::vector<std::size_t>& dims) const {
    VarPtr info = Info(name);
    if (!info) Fail(name, "missing, expected this variable (layout: measurements/README.md)");
    dims = Dims(info.get());
    if (static_cast<int>(dims.size()) > rank) {
      std::size_t extra = 1;
      for (std::size_t i = rank; i < dims.size(); ++i) extra *= dims[i];
      if (extra != 1) {
        Fail(name, "size " + SizeText(dims) + ", expected at most " + std::to_string(rank) +
                       " dimensions");
      }
      dims.resize(rank);
    }
    while (static_cast<int>(dims.size()) < rank) dims.push_back(1);
    long double count = 1;
    for (std::size_t d : dims) count *= static_cast<long double>(d);
    if (count > static_cast<long double>(kMaxRawSamplesTotal)) {
      Fail(name, "size " + SizeText(dims) + " (" + std::to_string(static_cast<double>(count)) +
                     " values), expected at most " + std::to_string(kMaxRawSamplesTotal));
    }
    if (count > max_values_) {
      Fail(name, "size " + SizeText(dims) + " (" + std::to_string(static_cast<long long>(count)) +
                     " values), more than the file can hold (a corrupt size field)");
    }
    if (count == 0) Fail(name, "empty (size " + SizeText(dims) + "), expected data");
    if (info->isComplex) Fail(name, "complex, expected real values");
    VarPtr var(Mat_VarRead(mat_.get(), name));
    if (!var || var->data == nullptr) Fail(name, "could not be read (damaged file?)");
    const std::size_t n = static_cast<std::size_t>(count);
    std::vector<double> out(n);
    const void* data = var->data;
    switch (var->class_type) {
      case MAT_C_DOUBLE: Copy(static_cast<const double*>(data), out); break;
      case MAT_C_SINGLE: Copy(static_cast<const float*>(data), out); break;
      case MAT_C_INT8: Copy(static_cast<const std::int8_t*>(data), out); break;
      case MAT_C_UINT8: Copy(static_cast<const std::uint8_t*>(data), out); break;
      case MAT_C_INT16: Copy(static_cast<const std::int16_t*>(data), out); break;
      case MAT_C_UINT16: Copy(static_cast<const std::uint16_t*>(data), out); break;
      case MAT_C_INT32: Copy(static_cast<const std::int32_t*>(data), out); break;
      case MAT_C_UINT32: Copy(static_cast<const std::uint32_t*>(data), out); break;
      case MAT_C_INT64: Copy(static_cast<const std::int64_t*>(data), out); break;
      case MAT_C_UINT64: Copy(static_cast<const std::uint64_t*>(data), out); break;
      default: Fail(name, "not a numeric array, expected double values");
    }
    return out;
  }

  // The characters of char array `v` (variable `name`, for messages).
  std::string CharData(const char* name, const matvar_t* v) const {
    std::size_t n = 1;
    for (int i = 0; i < v->rank; ++i) n *= v->dims[i];
    std::string s;
    if (n == 0 || v->data == nullptr) return s;
    const std::size_t width = Mat_SizeOf(v->data_type);
    if ((width != 1 && width != 2) || v->nbytes / width < n) {
      Fail(name, "char data of " + std::to_string(v->nbytes) + " bytes for " + std::to_string(n) +
                     " characters (damaged file?), expected " + std::to_string(n) +
                     " characters of 1 or 2 bytes");
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (width == 2) {
        const std::uint16_t c = static_cast<const std::uint16_t*>(v->data)[i];
        s.push_back(c < 128 ? static_cast<char>(c) : '?');
      } else {
        s.push_back(static_cast<const char*>(v->data)[i]);
      }
    }
    return s;
  }

  std::optional<std::string> String(const char* name) const {
    VarPtr info = Info(name);
    if (!info) return std::nullopt;
    VarPtr var(Mat_VarRead(mat_.get(), name));
    if (!var || var->class_type != MAT_C_CHAR || var->rank != 2 || var->dims[0] > 1) {
      Fail(name, "expected a char row vector");
    }
    return CharData(name, var.get());
  }

  // A char (one string, replicated to `count`) or a cell of `count` char arrays; nullopt if absent.
  std::optional<std::vector<std::string>> Strings(const char* name, std::size_t count,
                                                  bool allow_single) const {
    VarPtr info = Info(name);
    if (!info) return std::nullopt;
    VarPtr var(Mat_VarRead(mat_.get(), name));
    if (!var) Fail(name, "could not be read (damaged file?)");
    if (var->class_type == MAT_C_CHAR && allow_single && var->rank == 2 && var->dims[0] <= 1) {
      return std::vector<std::string>(count, CharData(name, var.get()));
    }
    if (var->class_type != MAT_C_CELL) {
      Fail(name, std::string("expected a cell array of ") + std::to_string(count) + " char arrays" +
                     (allow_single ? " or one char array" : ""));
    }
    std::size_t n = 1;
    for (int i = 0; i < var->rank; ++i) n *= var->dims[i];
    if (n != count) {
      Fail(name, "cell of size " + SizeText(Dims(var.get())) + ", expected " +
                     std::to_string(count) + " elements");
    }
    std::vector<std::string> out;
    for (std::size_t i = 0; i < n; ++i) {
      matvar_t* cell = Mat_VarGetCell(var.get(), static_cast<int>(i));
      if (cell == nullptr || cell->class_type != MAT_C_CHAR) {
        Fail(name, "element " + std::to_string(i + 1) + " is not a char array, expected text");
      }
      out.push_back(CharData(name, cell));
    }
    return out;
  }

  bool Has(const char* name) const { return static_cast<bool>(Info(name)); }
  const std::filesystem::path& path() const { return path_; }

 private:
  template <typename T>
  static void Copy(const T* in, std::vector<double>& out) {
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = static_cast<double>(in[i]);
  }

  std::filesystem::path path_;
  long double max_values_ = 0.0L;
  MatPtr mat_;
};

void ReadGeometry(const Reader& r, const char* body_name, const char* position_name,
                  const char* direction_name, std::vector<ChannelGeometry>& channels) {
  const bool any = r.Has(body_name) || r.Has(position_name) || r.Has(direction_name);
  if (!any) return;
  for (const char* name : {body_name, position_name, direction_name}) {
    if (!r.Has(name)) {
      r.Fail(name, std::string("missing while ") +
                       (r.Has(body_name) ? body_name : r.Has(position_name) ? position_name
                                                                              : direction_name) +
                       " is present, expected all three of " + body_name + ", " + position_name +
                       ", " + direction_name + " or none");
    }
  }
  const std::size_t n = channels.size();
  const auto bodies = r.Strings(body_name, n, true);
  for (const char* name : {position_name, direction_name}) {
    std::vector<std::size_t> dims;
    const std::vector<double> v = r.Numeric(name, 2, dims);
    if (dims[0] != n || dims[1] != 3) {
      r.Fail(name, "size " + SizeText(dims) + ", expected " + std::to_string(n) + " x 3");
    }
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d x(v[i], v[i + n], v[i + 2 * n]);
      if (!x.allFinite()) r.Fail(name, "row " + std::to_string(i + 1) + " is not finite");
      if (name == position_name) {
        channels[i].position_W = x;
      } else {
        channels[i].direction_W = x;
      }
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    if ((*bodies)[i].empty()) {
      r.Fail(body_name, "entry " + std::to_string(i + 1) + " is empty, expected a body name");
    }
    channels[i].body = (*bodies)[i];
  }
}

Eigen::VectorXd ReadRanges(const Reader& r, const char* name, std::size_t count) {
  if (!r.Has(name)) return Eigen::VectorXd();
  std::vector<std::size_t> dims;
  const std::vector<double> v = r.Numeric(name, 2, dims);
  const std::size_t n = dims[0] * dims[1];
  for (double x : v) {
    if (!(x >= 0.0) || !std::isfinite(x)) {
      r.Fail(name, "value " + std::to_string(x) + ", expected finite ranges >= 0 (0 = unknown)");
    }
  }
  if (n == 1) return Eigen::VectorXd::Constant(count, v[0]);
  if (n != count || (dims[0] != 1 && dims[1] != 1)) {
    r.Fail(name, "size " + SizeText(dims) + ", expected 1 x 1 or " + std::to_string(count) +
                     " x 1");
  }
  return Eigen::Map<const Eigen::VectorXd>(v.data(), count);
}

// matio variables that point at caller-owned data (MAT_F_DONT_COPY_DATA).
class Writer {
 public:
  Writer(mat_t* mat, const std::filesystem::path& target, matio_compression compression)
      : mat_(mat), target_(target), compression_(compression) {}

  void Numeric(const char* name, const std::vector<std::size_t>& dims, const double* data) {
    std::vector<std::size_t> d = dims;
    VarPtr v(Mat_VarCreate(name, MAT_C_DOUBLE, MAT_T_DOUBLE, static_cast<int>(d.size()), d.data(),
                           const_cast<double*>(data), MAT_F_DONT_COPY_DATA));
    Write(name, v.get());
  }

  void String(const char* name, const std::string& text) {
    std::size_t d[2] = {1, text.size()};
    VarPtr v(Mat_VarCreate(name, MAT_C_CHAR, MAT_T_UINT8, 2, d, const_cast<char*>(text.data()),
                           MAT_F_DONT_COPY_DATA));
    Write(name, v.get());
  }

  void Strings(const char* name, const std::vector<std::string>& texts) {
    std::size_t d[2] = {1, texts.size()};
    VarPtr cell(Mat_VarCreate(name, MAT_C_CELL, MAT_T_CELL, 2, d, nullptr, 0));
    for (std::size_t i = 0; i < texts.size(); ++i) {
      std::size_t sd[2] = {1, texts[i].size()};
      matvar_t* e = Mat_VarCreate(nullptr, MAT_C_CHAR, MAT_T_UINT8, 2, sd,
                                  const_cast<char*>(texts[i].data()), 0);
      if (e == nullptr) Fail(name);
      Mat_VarSetCell(cell.get(), static_cast<int>(i), e);
    }
    // Uncompressed: matio 1.5.23 cannot read back a zlib-compressed cell of char arrays of unequal
    // odd lengths (the second element comes back empty); these variables are small anyway.
    Write(name, cell.get(), MAT_COMPRESSION_NONE);
  }

 private:
  [[noreturn]] void Fail(const char* name) const {
    throw InputError("'" + target_.string() + "': could not write variable " + name);
  }
  void Write(const char* name, matvar_t* v) { Write(name, v, compression_); }
  void Write(const char* name, matvar_t* v, matio_compression compression) {
    if (v == nullptr || Mat_VarWrite(mat_, v, compression) != 0) Fail(name);
  }

  mat_t* mat_;
  std::filesystem::path target_;
  matio_compression compression_;
};

const char* ResponseQuantityName(FrfQuantity q) {
  switch (q) {
    case FrfQuantity::kAccelerance: return "acceleration";
    case FrfQuantity::kMobility: return "velocity";
    case FrfQuantity::kReceptance: return "displacement";
  }
  STAGEFIT_ASSERT(false, "unknown FrfQuantity " << static_cast<int>(q));
}

void WriteGeometry(Writer& w, const std::vector<ChannelGeometry>& channels, const char* body_name,
                   const char* position_name, const char* direction_name,
                   const std::filesystem::path& path) {
  int with = 0;
  for (const ChannelGeometry& c : channels) with += c.has_geometry() ? 1 : 0;
  if (with == 0) return;
  if (with != static_cast<int>(channels.size())) {
    throw InputError("'" + path.string() + "': " + body_name + ": " + std::to_string(with) +
                     " of " + std::to_string(channels.size()) +
                     " channels have geometry, expected all or none");
  }
  const std::size_t n = channels.size();
  std::vector<std::string> bodies;
  bool one_body = true;
  for (const ChannelGeometry& c : channels) {
    bodies.push_back(c.body);
    one_body = one_body && c.body == channels.front().body;
  }
  if (one_body) {
    w.String(body_name, bodies.front());
  } else {
    w.Strings(body_name, bodies);
  }
  std::vector<double> position(3 * n), direction(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) {
      position[i + c * n] = channels[i].position_W(c);
      direction[i + c * n] = channels[i].direction_W(c);
    }
  }
  w.Numeric(position_name, {n, 3}, position.data());
  w.Numeric(direction_name, {n, 3}, direction.data());
}

}  // namespace

RawHammerData ReadRawHammerFile(const std::filesystem::path& path) {
  const Reader r(path);
  RawHammerData data;
  data.source = path.string();

  std::vector<std::size_t> dims;
  const std::vector<double> rate = r.Numeric("sample_rate_hz", 2, dims);
  if (rate.size() != 1) r.Fail("sample_rate_hz", "size " + SizeText(dims) + ", expected 1 x 1");
  data.sample_rate_hz = rate[0];

  std::vector<std::size_t> fdims;
  const std::vector<double> force = r.Numeric("force", 3, fdims);
  const std::size_t ns = fdims[0], nhits = fdims[1], nin = fdims[2];
  if (static_cast<long long>(ns) > kMaxRawSamplesPerRecord) {
    r.Fail("force", "records of " + std::to_string(ns) + " samples, expected at most " +
                        std::to_string(kMaxRawSamplesPerRecord));
  }
  std::vector<std::size_t> rdims;
  const std::vector<double> response = r.Numeric("response", 4, rdims);
  const std::size_t nout = rdims[1];
  if (rdims[0] != ns || rdims[2] != nhits || rdims[3] != nin) {
    r.Fail("response", "size " + SizeText(rdims) + ", expected Ns x Nout x Nhits x Nin = " +
                           std::to_string(ns) + " x Nout x " + std::to_string(nhits) + " x " +
                           std::to_string(nin) + " (force is " + SizeText(fdims) + ")");
  }

  const auto quantity = r.String("response_quantity");
  if (!quantity) r.Fail("response_quantity", "missing, expected \"acceleration\", \"velocity\" or \"displacement\"");
  if (*quantity == "acceleration") {
    data.quantity = FrfQuantity::kAccelerance;
  } else if (*quantity == "velocity") {
    data.quantity = FrfQuantity::kMobility;
  } else if (*quantity == "displacement") {
    data.quantity = FrfQuantity::kReceptance;
  } else {
    r.Fail("response_quantity", "\"" + *quantity +
                                    "\", expected \"acceleration\", \"velocity\" or \"displacement\"");
  }

  data.outputs.resize(nout);
  data.inputs.resize(nin);
  const auto output_names = r.Strings("output_names", nout, false);
  const auto input_names = r.Strings("input_names", nin, false);
  for (std::size_t i = 0; i < nout; ++i) {
    data.outputs[i].name = output_names ? (*output_names)[i] : "out" + std::to_string(i + 1);
  }
  for (std::size_t j = 0; j < nin; ++j) {
    data.inputs[j].name = input_names ? (*input_names)[j] : "in" + std::to_string(j + 1);
  }
  ReadGeometry(r, "sensor_body", "sensor_position", "sensor_direction", data.outputs);
  ReadGeometry(r, "impact_body", "impact_position", "impact_direction", data.inputs);
  if (r.Has("frame_origin")) {
    const std::vector<double> origin = r.Numeric("frame_origin", 2, dims);
    if (origin.size() != 3) r.Fail("frame_origin", "size " + SizeText(dims) + ", expected 1 x 3");
    data.frame_origin_W = Eigen::Vector3d(origin[0], origin[1], origin[2]);
    if (!data.frame_origin_W->allFinite()) r.Fail("frame_origin", "not finite");
  }
  data.response_full_scale = ReadRanges(r, "response_full_scale", nout);
  data.force_full_scale = ReadRanges(r, "force_full_scale_n", nin);

  data.hits.assign(nin, std::vector<HammerHit>(nhits));
  for (std::size_t j = 0; j < nin; ++j) {
    for (std::size_t h = 0; h < nhits; ++h) {
      HammerHit& hit = data.hits[j][h];
      hit.force = Eigen::Map<const Eigen::VectorXd>(force.data() + ns * (h + nhits * j), ns);
      hit.response.resize(ns, nout);
      for (std::size_t o = 0; o < nout; ++o) {
        hit.response.col(o) = Eigen::Map<const Eigen::VectorXd>(
            response.data() + ns * (o + nout * (h + nhits * j)), ns);
      }
    }
  }
  Validate(data);
  return data;
}

void WriteRawHammerFile(const std::filesystem::path& path, const RawHammerData& data,
                        MatVersion version) {
  Validate(data);
  const std::size_t ns = data.num_samples();
  const std::size_t nout = data.num_outputs();
  const std::size_t nin = data.num_inputs();
  const std::size_t nhits = data.hits.front().size();
  for (std::size_t j = 0; j < nin; ++j) {
    if (data.hits[j].size() != nhits) {
      throw InputError("'" + path.string() + "': input " + std::to_string(j + 1) + " has " +
                       std::to_string(data.hits[j].size()) + " hits, expected " +
                       std::to_string(nhits) + " like input 1 (the file holds Nhits per input)");
    }
  }
  if (version == MatVersion::kV73 && !IsMatV73Supported()) {
    throw InputError("'" + path.string() + "': this build's matio cannot write v7.3 files");
  }
  std::vector<double> force(ns * nhits * nin), response(ns * nout * nhits * nin);
  for (std::size_t j = 0; j < nin; ++j) {
    for (std::size_t h = 0; h < nhits; ++h) {
      const HammerHit& hit = data.hits[j][h];
      Eigen::Map<Eigen::VectorXd>(force.data() + ns * (h + nhits * j), ns) = hit.force;
      for (std::size_t o = 0; o < nout; ++o) {
        Eigen::Map<Eigen::VectorXd>(response.data() + ns * (o + nout * (h + nhits * j)), ns) =
            hit.response.col(o);
      }
    }
  }

  TemporaryPath temporary(path);  // removed unless moved over `path` at the end
  {
    MatPtr mat(Mat_CreateVer(temporary.path().string().c_str(), nullptr,
                             version == MatVersion::kV73 ? MAT_FT_MAT73 : MAT_FT_MAT5));
    if (!mat) {
      throw InputError("'" + path.string() + "': cannot create the file (does the folder exist "
                       "and is it writable?)");
    }
    try {
      Writer w(mat.get(), path, MAT_COMPRESSION_ZLIB);
      const double rate = data.sample_rate_hz;
      w.Numeric("sample_rate_hz", {1, 1}, &rate);
      w.Numeric("force", {ns, nhits, nin}, force.data());
      w.Numeric("response", {ns, nout, nhits, nin}, response.data());
      w.String("response_quantity", ResponseQuantityName(data.quantity));
      std::vector<std::string> names;
      for (const ChannelGeometry& c : data.outputs) names.push_back(c.name);
      w.Strings("output_names", names);
      names.clear();
      for (const ChannelGeometry& c : data.inputs) names.push_back(c.name);
      w.Strings("input_names", names);
      if (data.response_full_scale.size() > 0) {
        w.Numeric("response_full_scale", {nout, 1}, data.response_full_scale.data());
      }
      if (data.force_full_scale.size() > 0) {
        w.Numeric("force_full_scale_n", {nin, 1}, data.force_full_scale.data());
      }
      WriteGeometry(w, data.outputs, "sensor_body", "sensor_position", "sensor_direction", path);
      WriteGeometry(w, data.inputs, "impact_body", "impact_position", "impact_direction", path);
      if (data.frame_origin_W) {
        w.Numeric("frame_origin", {1, 3}, data.frame_origin_W->data());
      }
    } catch (...) {
      mat.reset();
      throw;
    }
  }
  temporary.MoveOverTarget();
}

}  // namespace stagefit::measurement
