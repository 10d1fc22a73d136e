#include "stagefit/measurement/mat_file.h"

#include <matio.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>

#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"
#include "mat_v5_structure.h"

namespace stagefit::measurement {
namespace fs = std::filesystem;

namespace {

// matio reports problems through a log function; the last message is kept for our own errors
// instead of being printed on stderr.
thread_local std::string g_matio_message;

void MatioLog(int log_level, char* message) {
  if (message != nullptr) g_matio_message = message;
}

void InitMatioLog() {
  static const bool initialised = [] {
    Mat_LogInitFunc("stagefit", &MatioLog);
    return true;
  }();
  (void)initialised;
  g_matio_message.clear();
}

std::string MatioDetail() {
  return g_matio_message.empty() ? std::string() : " (matio: " + g_matio_message + ")";
}

struct MatCloser {
  void operator()(mat_t* mat) const { Mat_Close(mat); }
};
struct VarFreer {
  void operator()(matvar_t* var) const { Mat_VarFree(var); }
};
using MatPtr = std::unique_ptr<mat_t, MatCloser>;
using VarPtr = std::unique_ptr<matvar_t, VarFreer>;

// A variable as read from or written to a file, before it is given a C++ type.
struct Array {
  enum class Kind { kNumeric, kChar, kStrings };
  std::string name;
  Kind kind = Kind::kNumeric;
  std::vector<std::size_t> dims;
  std::vector<double> re, im;  // column-major; im used when complex
  bool complex = false;
  std::string text;
  std::vector<std::string> strings;

  bool is_complex() const { return complex; }
  std::size_t numel() const {
    std::size_t n = 1;
    for (std::size_t d : dims) n *= d;
    return n;
  }
  std::string DimsText() const {
    std::string s;
    for (std::size_t i = 0; i < dims.size(); ++i) s += (i ? " x " : "") + std::to_string(dims[i]);
    return s;
  }
};

std::string Quote(const fs::path& path) { return "'" + path.string() + "'"; }

// ---- reading ----

template <typename T>
void CopyNumbers(const void* data, std::size_t n, std::vector<double>* out) {
  out->resize(n);
  const T* p = static_cast<const T*>(data);
  for (std::size_t i = 0; i < n; ++i) (*out)[i] = static_cast<double>(p[i]);
}

bool CopyByClass(matio_classes c, const void* data, std::size_t n, std::vector<double>* out) {
  if (n == 0) {
    out->clear();
    return true;
  }
  if (data == nullptr) return false;
  switch (c) {
    case MAT_C_DOUBLE: CopyNumbers<double>(data, n, out); return true;
    case MAT_C_SINGLE: CopyNumbers<float>(data, n, out); return true;
    case MAT_C_INT8: CopyNumbers<std::int8_t>(data, n, out); return true;
    case MAT_C_UINT8: CopyNumbers<std::uint8_t>(data, n, out); return true;
    case MAT_C_INT16: CopyNumbers<std::int16_t>(data, n, out); return true;
    case MAT_C_UINT16: CopyNumbers<std::uint16_t>(data, n, out); return true;
    case MAT_C_INT32: CopyNumbers<std::int32_t>(data, n, out); return true;
    case MAT_C_UINT32: CopyNumbers<std::uint32_t>(data, n, out); return true;
    case MAT_C_INT64: CopyNumbers<std::int64_t>(data, n, out); return true;
    case MAT_C_UINT64: CopyNumbers<std::uint64_t>(data, n, out); return true;
    default: return false;
  }
}

void AppendUtf8(std::uint32_t code, std::string* out) {
  if (code < 0x80) {
    out->push_back(static_cast<char>(code));
  } else if (code < 0x800) {
    out->push_back(static_cast<char>(0xC0 | (code >> 6)));
    out->push_back(static_cast<char>(0x80 | (code & 0x3F)));
  } else {
    out->push_back(static_cast<char>(0xE0 | ((code >> 12) & 0x0F)));
    out->push_back(static_cast<char>(0x80 | ((code >> 6) & 0x3F)));
    out->push_back(static_cast<char>(0x80 | (code & 0x3F)));
  }
}

std::string TrimRight(std::string s) {
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
  return s;
}

// Rows of a char array (column-major), as UTF-8.
bool ReadCharRows(const matvar_t* var, std::vector<std::string>* rows) {
  const std::size_t r = var->rank >= 1 ? var->dims[0] : 0;
  std::size_t c = 1;
  for (int k = 1; k < var->rank; ++k) c *= var->dims[k];
  const std::size_t n = r * c;
  rows->assign(r, std::string());
  if (n == 0) return true;
  if (var->data == nullptr) return false;
  std::size_t width = 1;
  switch (var->data_type) {
    case MAT_T_UINT8: case MAT_T_INT8: case MAT_T_UTF8: width = 1; break;
    case MAT_T_UINT16: case MAT_T_INT16: case MAT_T_UTF16: width = 2; break;
    case MAT_T_UINT32: case MAT_T_INT32: case MAT_T_UTF32: width = 4; break;
    default: return false;
  }
  if (var->nbytes < n * width) return false;
  for (std::size_t i = 0; i < r; ++i) {
    std::string& row = (*rows)[i];
    for (std::size_t j = 0; j < c; ++j) {
      const std::size_t k = i + r * j;
      std::uint32_t code = 0;
      if (width == 1) {
        row.push_back(static_cast<const char*>(var->data)[k]);
        continue;
      } else if (width == 2) {
        std::uint16_t v;
        std::memcpy(&v, static_cast<const char*>(var->data) + 2 * k, 2);
        code = v;
      } else {
        std::memcpy(&code, static_cast<const char*>(var->data) + 4 * k, 4);
      }
      AppendUtf8(code, &row);
    }
  }
  return true;
}

class MatReader {
 public:
  explicit MatReader(const fs::path& path) : path_(path) {}

  [[noreturn]] void Fail(const std::string& variable, const std::string& message) const {
    throw InputError("MAT file " + Quote(path_) + ", variable '" + variable + "': " + message);
  }

  std::vector<Array> ReadAll() {
    InitMatioLog();
    std::error_code ec;
    if (!fs::is_regular_file(path_, ec)) {
      throw InputError("MAT file " + Quote(path_) + ": does not exist or is not a regular file");
    }
    const std::uintmax_t file_size = fs::file_size(path_, ec);
    // zlib cannot compress by more than about 1032:1, so a variable cannot hold more bytes than
    // this; anything larger is a corrupt size field and is rejected before matio allocates it.
    limit_bytes_ = static_cast<double>(file_size) * 1100.0 + 1048576.0;
    internal::CheckMatFileStructure(path_, static_cast<std::uint64_t>(limit_bytes_));
    MatPtr mat(Mat_Open(path_.string().c_str(), MAT_ACC_RDONLY));
    if (!mat) {
      throw InputError("MAT file " + Quote(path_) +
                       ": not a MATLAB .mat file (v5 or v7.3) or unreadable" + MatioDetail());
    }
    std::vector<std::string> names;
    while (true) {
      g_matio_message.clear();
      VarPtr info(Mat_VarReadNextInfo(mat.get()));
      if (!info) break;
      const std::string name = info->name ? info->name : "";
      if (name.empty()) {
        throw InputError("MAT file " + Quote(path_) + ": variable " +
                         std::to_string(names.size() + 1) + " has no name (corrupt file)");
      }
      CheckSize(info.get(), name);
      names.push_back(name);
    }
    if (!g_matio_message.empty() && names.empty()) {
      throw InputError("MAT file " + Quote(path_) + ": cannot read its variables" + MatioDetail());
    }
    std::vector<Array> arrays;
    for (const std::string& name : names) {
      g_matio_message.clear();
      VarPtr var(Mat_VarRead(mat.get(), name.c_str()));
      if (!var) Fail(name, "cannot be read (truncated or corrupt file)" + MatioDetail());
      arrays.push_back(Convert(var.get(), name));
    }
    return arrays;
  }

 private:
  void CheckSize(const matvar_t* var, const std::string& name) const {
    double numel = 1.0;
    for (int k = 0; k < var->rank; ++k) numel *= static_cast<double>(var->dims[k]);
    const double element = var->class_type == MAT_C_CELL ? 8.0 : 1.0;
    if (var->rank < 0 || var->rank > 32 || numel * element > limit_bytes_) {
      Fail(name, "declares " + std::to_string(numel) +
                     " elements, more than the file can hold (corrupt size field)");
    }
    // An empty array (a zero dimension) may still declare a huge other dimension: a char array's
    // rows become strings, so each dimension is bounded too.
    for (int k = 0; k < var->rank; ++k) {
      if (static_cast<double>(var->dims[k]) > limit_bytes_) {
        Fail(name, "dimension " + std::to_string(k + 1) + " = " + std::to_string(var->dims[k]) +
                       ", more than the file can hold (corrupt size field)");
      }
    }
  }

  Array Convert(const matvar_t* var, const std::string& name) const {
    Array a;
    a.name = name;
    for (int k = 0; k < var->rank; ++k) a.dims.push_back(var->dims[k]);
    const std::size_t n = a.numel();
    if (var->isComplex && var->class_type != MAT_C_CHAR && var->class_type != MAT_C_CELL &&
        var->class_type != MAT_C_STRUCT && var->class_type != MAT_C_SPARSE) {
      const auto* z = static_cast<const mat_complex_split_t*>(var->data);
      if (n > 0 && z == nullptr) Fail(name, "complex data missing (corrupt file)");
      if (!CopyByClass(var->class_type, n ? z->Re : nullptr, n, &a.re) ||
          !CopyByClass(var->class_type, n ? z->Im : nullptr, n, &a.im)) {
        Fail(name, "unsupported numeric class or missing data (corrupt file)");
      }
      a.kind = Array::Kind::kNumeric;
      a.complex = true;
      return a;
    }
    switch (var->class_type) {
      case MAT_C_CHAR: {
        std::vector<std::string> rows;
        if (!ReadCharRows(var, &rows)) Fail(name, "char data missing or of an unknown encoding");
        if (rows.size() <= 1) {
          a.kind = Array::Kind::kChar;
          a.text = rows.empty() ? std::string() : rows[0];
        } else {
          a.kind = Array::Kind::kStrings;
          for (auto& r : rows) a.strings.push_back(TrimRight(r));
        }
        return a;
      }
      case MAT_C_CELL: {
        a.kind = Array::Kind::kStrings;
        for (std::size_t i = 0; i < n; ++i) {
          const matvar_t* cell = Mat_VarGetCell(const_cast<matvar_t*>(var), static_cast<int>(i));
          if (cell == nullptr) Fail(name, "cell " + std::to_string(i + 1) + " is missing");
          if (cell->class_type != MAT_C_CHAR) {
            Fail(name, "cell " + std::to_string(i + 1) + " is not a char array, expected a cell "
                       "array of strings");
          }
          std::vector<std::string> rows;
          if (!ReadCharRows(cell, &rows) || rows.size() > 1) {
            Fail(name, "cell " + std::to_string(i + 1) + " is not a single-row char array");
          }
          a.strings.push_back(rows.empty() ? std::string() : rows[0]);
        }
        return a;
      }
      case MAT_C_STRUCT:
      case MAT_C_OBJECT:
      case MAT_C_SPARSE:
      case MAT_C_FUNCTION:
      case MAT_C_OPAQUE:
      case MAT_C_EMPTY:
        Fail(name, "is a struct, object, sparse matrix or function handle, expected a double "
                   "array, a char array or a cell array of char");
      default:
        break;
    }
    if (!CopyByClass(var->class_type, var->data, n, &a.re)) {
      Fail(name, "unsupported class or missing data (corrupt file)");
    }
    a.kind = Array::Kind::kNumeric;
    return a;
  }

  fs::path path_;
  double limit_bytes_ = 0.0;
};

// ---- writing ----

bool IsValidName(const std::string& name) {
  if (name.empty() || name.size() > 63) return false;
  if (!std::isalpha(static_cast<unsigned char>(name[0]))) return false;
  for (char c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') return false;
  }
  return true;
}

matvar_t* CreateChar(const char* name, const std::string& text) {
  std::size_t dims[2] = {1, text.size()};
  if (text.empty()) dims[0] = 0;
  char empty = 0;
  void* data = text.empty() ? static_cast<void*>(&empty) : const_cast<char*>(text.data());
  return Mat_VarCreate(name, MAT_C_CHAR, MAT_T_UINT8, 2, dims, data, 0);
}

matvar_t* CreateArray(const Array& a) {
  std::vector<std::size_t> dims = a.dims;
  switch (a.kind) {
    case Array::Kind::kChar:
      return CreateChar(a.name.c_str(), a.text);
    case Array::Kind::kStrings: {
      std::size_t cell_dims[2] = {1, a.strings.size()};
      if (a.strings.empty()) cell_dims[0] = 0;
      matvar_t* cell = Mat_VarCreate(a.name.c_str(), MAT_C_CELL, MAT_T_CELL, 2, cell_dims, nullptr, 0);
      if (cell == nullptr) return nullptr;
      for (std::size_t i = 0; i < a.strings.size(); ++i) {
        matvar_t* element = CreateChar(nullptr, a.strings[i]);
        if (element == nullptr) {
          Mat_VarFree(cell);
          return nullptr;
        }
        Mat_VarSetCell(cell, static_cast<int>(i), element);
      }
      return cell;
    }
    case Array::Kind::kNumeric:
      break;
  }
  double empty = 0.0;
  if (a.is_complex()) {
    mat_complex_split_t z{a.re.empty() ? &empty : const_cast<double*>(a.re.data()),
                          a.im.empty() ? &empty : const_cast<double*>(a.im.data())};
    return Mat_VarCreate(a.name.c_str(), MAT_C_DOUBLE, MAT_T_DOUBLE, static_cast<int>(dims.size()),
                         dims.data(), &z, MAT_F_COMPLEX);
  }
  return Mat_VarCreate(a.name.c_str(), MAT_C_DOUBLE, MAT_T_DOUBLE, static_cast<int>(dims.size()),
                       dims.data(), a.re.empty() ? &empty : const_cast<double*>(a.re.data()), 0);
}

void WriteArrays(const fs::path& path, const std::vector<Array>& arrays, MatVersion version) {
  InitMatioLog();
  std::set<std::string> names;
  for (const Array& a : arrays) {
    if (!IsValidName(a.name)) {
      throw InputError("MAT file " + Quote(path) + ": variable name '" + a.name +
                       "' is not a MATLAB identifier (a letter, then letters, digits or '_', at "
                       "most 63 characters)");
    }
    if (!names.insert(a.name).second) {
      throw InputError("MAT file " + Quote(path) + ": variable '" + a.name + "' is given twice");
    }
  }
  if (version == MatVersion::kV73 && !IsMatV73Supported()) {
    throw InputError("MAT file " + Quote(path) +
                     ": v7.3 requested but this build's matio has no HDF5 support; write v5");
  }
  // matio writes to a file name: a temporary beside the target, renamed over it once complete.
  TemporaryPath temporary(path);
  {
    MatPtr mat(Mat_CreateVer(temporary.path().string().c_str(), nullptr,
                             version == MatVersion::kV73 ? MAT_FT_MAT73 : MAT_FT_MAT5));
    if (!mat) {
      throw InputError("cannot write MAT file " + Quote(path) +
                       ": the folder does not exist or is not writable" + MatioDetail());
    }
    for (const Array& a : arrays) {
      VarPtr var(CreateArray(a));
      if (!var || Mat_VarWrite(mat.get(), var.get(), MAT_COMPRESSION_NONE) != 0) {
        throw InputError("MAT file " + Quote(path) + ": writing variable '" + a.name + "' failed" +
                         MatioDetail());
      }
    }
  }
  temporary.MoveOverTarget();
}

Array FromVariable(const MatVariable& v) {
  Array a;
  a.name = v.name;
  if (const auto* m = std::get_if<Eigen::MatrixXd>(&v.value)) {
    a.dims = {static_cast<std::size_t>(m->rows()), static_cast<std::size_t>(m->cols())};
    a.re.assign(m->data(), m->data() + m->size());
  } else if (const auto* z = std::get_if<Eigen::MatrixXcd>(&v.value)) {
    a.dims = {static_cast<std::size_t>(z->rows()), static_cast<std::size_t>(z->cols())};
    for (Eigen::Index i = 0; i < z->size(); ++i) {
      a.re.push_back(z->data()[i].real());
      a.im.push_back(z->data()[i].imag());
    }
    a.complex = true;
  } else if (const auto* s = std::get_if<std::string>(&v.value)) {
    a.kind = Array::Kind::kChar;
    a.text = *s;
  } else {
    a.kind = Array::Kind::kStrings;
    a.strings = std::get<std::vector<std::string>>(v.value);
  }
  return a;
}

MatVariable ToVariable(const Array& a, const fs::path& path) {
  MatVariable v;
  v.name = a.name;
  switch (a.kind) {
    case Array::Kind::kChar:
      v.value = a.text;
      return v;
    case Array::Kind::kStrings:
      v.value = a.strings;
      return v;
    case Array::Kind::kNumeric:
      break;
  }
  if (a.dims.size() > 2) {
    throw InputError("MAT file " + Quote(path) + ", variable '" + a.name + "': size " +
                     a.DimsText() + ", expected a matrix (two dimensions)");
  }
  const Eigen::Index rows = a.dims.empty() ? 0 : static_cast<Eigen::Index>(a.dims[0]);
  const Eigen::Index cols = a.dims.size() < 2 ? 1 : static_cast<Eigen::Index>(a.dims[1]);
  if (a.is_complex()) {
    Eigen::MatrixXcd z(rows, cols);
    for (Eigen::Index i = 0; i < z.size(); ++i) z.data()[i] = {a.re[i], a.im[i]};
    v.value = z;
  } else {
    Eigen::MatrixXd m(rows, cols);
    for (Eigen::Index i = 0; i < m.size(); ++i) m.data()[i] = a.re[i];
    v.value = m;
  }
  return v;
}

// ---- measurement layout ----

class MeasurementReader {
 public:
  MeasurementReader(const fs::path& path, std::vector<Array> arrays) : path_(path) {
    for (Array& a : arrays) arrays_.emplace(a.name, std::move(a));
  }

  [[noreturn]] void Fail(const std::string& variable, const std::string& message) const {
    throw InputError("MAT file " + Quote(path_) + ", variable '" + variable + "': " + message);
  }

  const Array* Find(const std::string& name) const {
    auto it = arrays_.find(name);
    return it == arrays_.end() ? nullptr : &it->second;
  }

  const Array& Require(const std::string& name, const std::string& meaning) const {
    const Array* a = Find(name);
    if (a == nullptr) {
      throw InputError("MAT file " + Quote(path_) + ": variable '" + name + "' is missing, expected " +
                       meaning);
    }
    return *a;
  }

  const Array& Numeric(const std::string& name, const Array& a, bool allow_complex) const {
    if (a.kind != Array::Kind::kNumeric) Fail(name, "is text, expected a numeric array");
    if (a.is_complex() && !allow_complex) Fail(name, "is complex, expected real values");
    return a;
  }

  // Dims with trailing singleton dimensions dropped beyond the second.
  static std::vector<std::size_t> Squeezed(const Array& a) {
    std::vector<std::size_t> d = a.dims;
    while (d.size() > 2 && d.back() == 1) d.pop_back();
    while (d.size() < 2) d.push_back(1);
    return d;
  }

  Eigen::VectorXd Vector(const std::string& name, const Array& a, std::size_t n) const {
    const auto d = Squeezed(a);
    const bool ok = d.size() == 2 && ((d[0] == n && d[1] == 1) || (d[0] == 1 && d[1] == n));
    if (!ok) {
      Fail(name, "size " + a.DimsText() + ", expected " + std::to_string(n) + " x 1 (or 1 x " +
                     std::to_string(n) + ")");
    }
    return Eigen::Map<const Eigen::VectorXd>(a.re.data(), static_cast<Eigen::Index>(n));
  }

  std::vector<Eigen::Vector3d> Rows3(const std::string& name, std::size_t n) const {
    const Array& a = Numeric(name, *Find(name), false);
    const auto d = Squeezed(a);
    if (d.size() != 2 || d[0] != n || d[1] != 3) {
      Fail(name, "size " + a.DimsText() + ", expected " + std::to_string(n) + " x 3");
    }
    std::vector<Eigen::Vector3d> rows(n);
    for (std::size_t i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) {
        const double v = a.re[i + n * c];
        if (!std::isfinite(v)) {
          std::ostringstream m;
          m << "element (" << i + 1 << ", " << c + 1 << ") = " << v << ", expected a finite value";
          Fail(name, m.str());
        }
        rows[i][c] = v;
      }
    }
    return rows;
  }

  std::vector<std::string> Names(const std::string& name, std::size_t n) const {
    const Array& a = *Find(name);
    std::vector<std::string> names;
    if (a.kind == Array::Kind::kStrings) names = a.strings;
    else if (a.kind == Array::Kind::kChar) names = {a.text};
    else Fail(name, "is numeric, expected a cell array of char");
    if (names.size() != n) {
      Fail(name, std::to_string(names.size()) + " names, expected " + std::to_string(n) +
                     " (one per channel)");
    }
    return names;
  }

  std::vector<std::string> Bodies(const std::string& name, std::size_t n) const {
    const Array& a = *Find(name);
    if (a.kind == Array::Kind::kChar) {
      if (a.text.empty()) Fail(name, "is empty, expected a body name");
      return std::vector<std::string>(n, a.text);
    }
    if (a.kind != Array::Kind::kStrings) Fail(name, "is numeric, expected a char or a cell of char");
    if (a.strings.size() != n) {
      Fail(name, std::to_string(a.strings.size()) + " bodies, expected 1 (a char) or " +
                     std::to_string(n) + " (one per channel)");
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (a.strings[i].empty()) Fail(name, "entry " + std::to_string(i + 1) + " is empty, expected a body name");
    }
    return a.strings;
  }

  void Geometry(const std::string& prefix, std::vector<ChannelGeometry>* channels,
                bool require) const {
    const std::string body = prefix + "_body", position = prefix + "_position",
                      direction = prefix + "_direction";
    const int present = (Find(body) != nullptr) + (Find(position) != nullptr) +
                        (Find(direction) != nullptr);
    if (present == 0 && !require) return;
    if (present < 3) {
      std::string missing;
      for (const std::string& v : {body, position, direction}) {
        if (Find(v) == nullptr) missing += (missing.empty() ? "'" : ", '") + v + "'";
      }
      throw InputError("MAT file " + Quote(path_) + ": missing geometry: variable(s) " + missing +
                       " absent, expected " + body + ", " + position + " and " + direction +
                       " together");
    }
    const std::size_t n = channels->size();
    const auto bodies = Bodies(body, n);
    const auto positions = Rows3(position, n);
    const auto directions = Rows3(direction, n);
    for (std::size_t i = 0; i < n; ++i) {
      (*channels)[i].body = bodies[i];
      (*channels)[i].position_W = positions[i];
      (*channels)[i].direction_W = directions[i];
    }
  }

  FrfData Read(bool require_geometry) const {
    FrfData data;
    data.source = path_.string();
    const Array& freq = Numeric("freq_hz", Require("freq_hz", "the Nf x 1 frequencies in Hz"), false);
    const Array& frf = Numeric("frf", Require("frf", "the Nout x Nin x Nf complex FRFs"), true);
    const Array& quantity = Require("quantity", "'accelerance', 'mobility' or 'receptance'");
    if (quantity.kind != Array::Kind::kChar) Fail("quantity", "is not a char array");
    const auto q = ParseFrfQuantity(quantity.text);
    if (!q) {
      Fail("quantity", "'" + quantity.text + "', expected 'accelerance', 'mobility' or 'receptance'");
    }
    data.quantity = *q;
    const auto fd = Squeezed(freq);
    if (fd.size() != 2 || (fd[0] != 1 && fd[1] != 1)) {
      Fail("freq_hz", "size " + freq.DimsText() + ", expected Nf x 1");
    }
    const std::size_t nf = freq.numel();
    if (nf == 0) Fail("freq_hz", "is empty, expected at least one frequency");
    data.frequency_hz = Vector("freq_hz", freq, nf);

    std::vector<std::size_t> d = frf.dims;
    while (d.size() > 3 && d.back() == 1) d.pop_back();
    if (d.size() == 2) d.push_back(1);
    if (d.size() != 3 || d[2] != nf || d[0] == 0 || d[1] == 0) {
      Fail("frf", "size " + frf.DimsText() + ", expected Nout x Nin x " + std::to_string(nf) +
                      " (Nf from freq_hz)");
    }
    const std::size_t nout = d[0], nin = d[1];
    data.frf.assign(nf, Eigen::MatrixXcd(nout, nin));
    for (std::size_t k = 0; k < nf; ++k) {
      for (std::size_t j = 0; j < nin; ++j) {
        for (std::size_t i = 0; i < nout; ++i) {
          const std::size_t idx = i + nout * (j + nin * k);
          data.frf[k](i, j) = {frf.re[idx], frf.is_complex() ? frf.im[idx] : 0.0};
        }
      }
    }
    if (const Array* c = Find("coherence")) {
      Numeric("coherence", *c, false);
      std::vector<std::size_t> cd = c->dims;
      while (cd.size() > 3 && cd.back() == 1) cd.pop_back();
      if (cd.size() == 2) cd.push_back(1);
      if (cd != std::vector<std::size_t>{nout, nin, nf}) {
        Fail("coherence", "size " + c->DimsText() + ", expected " + std::to_string(nout) + " x " +
                              std::to_string(nin) + " x " + std::to_string(nf) + " (like frf)");
      }
      data.coherence.assign(nf, Eigen::MatrixXd(nout, nin));
      for (std::size_t k = 0; k < nf; ++k) {
        for (std::size_t j = 0; j < nin; ++j) {
          for (std::size_t i = 0; i < nout; ++i) data.coherence[k](i, j) = c->re[i + nout * (j + nin * k)];
        }
      }
    }
    if (const Array* a = Find("num_averages")) {
      Numeric("num_averages", *a, false);
      const Eigen::VectorXd n = Vector("num_averages", *a, nin);
      for (std::size_t j = 0; j < nin; ++j) {
        if (!(n[j] >= 2.0 && n[j] == std::floor(n[j]) && n[j] < 1e9)) {
          std::ostringstream m;
          m << "element " << j + 1 << " = " << n[j]
            << ", expected a whole count >= 2 (the hits averaged for input " << j + 1 << ")";
          Fail("num_averages", m.str());
        }
        data.averages.push_back(static_cast<int>(n[j]));
      }
    }
    data.outputs.resize(nout);
    data.inputs.resize(nin);
    const auto out_names = Find("output_names") ? Names("output_names", nout) : std::vector<std::string>{};
    const auto in_names = Find("input_names") ? Names("input_names", nin) : std::vector<std::string>{};
    for (std::size_t i = 0; i < nout; ++i) {
      data.outputs[i].name = out_names.empty() ? "out" + std::to_string(i + 1) : out_names[i];
    }
    for (std::size_t j = 0; j < nin; ++j) {
      data.inputs[j].name = in_names.empty() ? "in" + std::to_string(j + 1) : in_names[j];
    }
    Geometry("sensor", &data.outputs, require_geometry);
    Geometry("impact", &data.inputs, require_geometry);
    if (const Array* o = Find("frame_origin")) {
      Numeric("frame_origin", *o, false);
      data.frame_origin_W = Vector("frame_origin", *o, 3);
    }
    Validate(data);
    return data;
  }

 private:
  fs::path path_;
  std::map<std::string, Array> arrays_;
};

Array Strings(const std::string& name, std::vector<std::string> strings) {
  Array a;
  a.name = name;
  a.kind = Array::Kind::kStrings;
  a.strings = std::move(strings);
  return a;
}

Array Text(const std::string& name, std::string text) {
  Array a;
  a.name = name;
  a.kind = Array::Kind::kChar;
  a.text = std::move(text);
  return a;
}

Array Rows3(const std::string& name, const std::vector<ChannelGeometry>& channels, bool position) {
  Array a;
  a.name = name;
  const std::size_t n = channels.size();
  a.dims = {n, 3};
  a.re.resize(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& v = position ? channels[i].position_W : channels[i].direction_W;
    for (int c = 0; c < 3; ++c) a.re[i + n * c] = v[c];
  }
  return a;
}

void AppendGeometry(const fs::path& path, const std::string& prefix,
                    const std::vector<ChannelGeometry>& channels, std::vector<Array>* arrays) {
  std::size_t with = 0;
  for (const auto& c : channels) with += c.has_geometry() ? 1 : 0;
  if (with == 0) return;
  if (with != channels.size()) {
    throw InputError("MAT file " + Quote(path) + ": " + std::to_string(with) + " of the " +
                     std::to_string(channels.size()) + " " + prefix +
                     " channels have geometry; the .mat layout needs all or none");
  }
  bool same = true;
  for (const auto& c : channels) same = same && c.body == channels[0].body;
  if (same) {
    arrays->push_back(Text(prefix + "_body", channels[0].body));
  } else {
    std::vector<std::string> bodies;
    for (const auto& c : channels) bodies.push_back(c.body);
    arrays->push_back(Strings(prefix + "_body", bodies));
  }
  arrays->push_back(Rows3(prefix + "_position", channels, true));
  arrays->push_back(Rows3(prefix + "_direction", channels, false));
}

}  // namespace

bool IsMatV73Supported() {
  static const bool supported = [] {
    InitMatioLog();
    std::error_code ec;
    const fs::path probe = fs::temp_directory_path(ec) /
                           ("stagefit-matio-probe-" + std::to_string(::getpid()) + ".mat");
    mat_t* mat = Mat_CreateVer(probe.string().c_str(), nullptr, MAT_FT_MAT73);
    const bool ok = mat != nullptr;
    if (mat != nullptr) Mat_Close(mat);
    fs::remove(probe, ec);
    return ok;
  }();
  return supported;
}

void WriteMatFile(const fs::path& path, const std::vector<MatVariable>& variables,
                  MatVersion version) {
  std::vector<Array> arrays;
  for (const MatVariable& v : variables) arrays.push_back(FromVariable(v));
  WriteArrays(path, arrays, version);
}

std::vector<MatVariable> ReadMatFile(const fs::path& path) {
  std::vector<MatVariable> variables;
  for (const Array& a : MatReader(path).ReadAll()) variables.push_back(ToVariable(a, path));
  return variables;
}

FrfData ReadMatMeasurement(const fs::path& path, bool require_geometry) {
  MeasurementReader reader(path, MatReader(path).ReadAll());
  return reader.Read(require_geometry);
}

void WriteMatMeasurement(const fs::path& path, const FrfData& data, MatVersion version) {
  Validate(data);
  const std::size_t nf = data.num_frequencies(), nout = data.num_outputs(), nin = data.num_inputs();
  std::vector<Array> arrays;
  Array freq;
  freq.name = "freq_hz";
  freq.dims = {nf, 1};
  freq.re.assign(data.frequency_hz.data(), data.frequency_hz.data() + nf);
  arrays.push_back(freq);
  Array frf;
  frf.name = "frf";
  frf.dims = {nout, nin, nf};
  frf.re.resize(nout * nin * nf);
  frf.im.resize(nout * nin * nf);
  frf.complex = true;
  for (std::size_t k = 0; k < nf; ++k) {
    for (std::size_t j = 0; j < nin; ++j) {
      for (std::size_t i = 0; i < nout; ++i) {
        frf.re[i + nout * (j + nin * k)] = data.frf[k](i, j).real();
        frf.im[i + nout * (j + nin * k)] = data.frf[k](i, j).imag();
      }
    }
  }
  arrays.push_back(frf);
  arrays.push_back(Text("quantity", ToString(data.quantity)));
  if (data.has_coherence()) {
    Array c;
    c.name = "coherence";
    c.dims = {nout, nin, nf};
    c.re.resize(nout * nin * nf);
    for (std::size_t k = 0; k < nf; ++k) {
      for (std::size_t j = 0; j < nin; ++j) {
        for (std::size_t i = 0; i < nout; ++i) c.re[i + nout * (j + nin * k)] = data.coherence[k](i, j);
      }
    }
    arrays.push_back(c);
  }
  if (!data.averages.empty()) {
    Array a;
    a.name = "num_averages";
    a.dims = {1, nin};
    a.re.assign(data.averages.begin(), data.averages.end());
    arrays.push_back(a);
  }
  std::vector<std::string> out_names, in_names;
  for (const auto& c : data.outputs) out_names.push_back(c.name);
  for (const auto& c : data.inputs) in_names.push_back(c.name);
  arrays.push_back(Strings("output_names", out_names));
  arrays.push_back(Strings("input_names", in_names));
  AppendGeometry(path, "sensor", data.outputs, &arrays);
  AppendGeometry(path, "impact", data.inputs, &arrays);
  if (data.frame_origin_W) {
    Array o;
    o.name = "frame_origin";
    o.dims = {1, 3};
    o.re = {(*data.frame_origin_W)[0], (*data.frame_origin_W)[1], (*data.frame_origin_W)[2]};
    arrays.push_back(o);
  }
  WriteArrays(path, arrays, version);
}

}  // namespace stagefit::measurement
