#include "mat_v5_structure.h"

#include <hdf5.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>

#include "stagefit/common/error.h"
#include "stagefit/common/utf8.h"

namespace stagefit::measurement::internal {
namespace fs = std::filesystem;

namespace {

// Data types and array classes of the v5 format (MATLAB's "MAT-File Format", chapter 1).
constexpr std::uint32_t kMiInt8 = 1, kMiInt32 = 5, kMiUint32 = 6, kMiMatrix = 14, kMiCompressed = 15;
constexpr std::uint32_t kCellClass = 1, kStructClass = 2, kObjectClass = 3, kCharClass = 4,
                        kSparseClass = 5, kDoubleClass = 6, kUint64Class = 15, kFunctionClass = 16,
                        kOpaqueClass = 17;

// The classes a reader takes: cells (of strings), char and numeric arrays.
bool ReadableClass(std::uint32_t c) {
  return c == kCellClass || c == kCharClass || (c >= kDoubleClass && c <= kUint64Class);
}

std::string ClassText(std::uint32_t c) {
  switch (c) {
    case kStructClass: return " (a struct)";
    case kObjectClass: return " (an object)";
    case kSparseClass: return " (a sparse matrix)";
    case kFunctionClass: return " (a function handle)";
    case kOpaqueClass: return " (an opaque object)";
    default: return " (unknown)";
  }
}

// Bytes read in order from the file or from a compressed variable's inflated stream.
class Source {
 public:
  virtual ~Source() = default;
  // Reads exactly `n` bytes; false when the data end first.
  virtual bool Read(unsigned char* out, std::size_t n) = 0;
  bool Skip(std::uint64_t n) {
    std::array<unsigned char, 4096> scratch;
    while (n > 0) {
      const std::size_t k = static_cast<std::size_t>(std::min<std::uint64_t>(n, scratch.size()));
      if (!Read(scratch.data(), k)) return false;
      n -= k;
    }
    return true;
  }
};

// `remaining` bytes of the file from its current position.
class FileSource : public Source {
 public:
  FileSource(std::ifstream& in, std::uint64_t remaining) : in_(in), remaining_(remaining) {}
  bool Read(unsigned char* out, std::size_t n) override {
    if (n > remaining_) return false;
    remaining_ -= n;
    return static_cast<bool>(in_.read(reinterpret_cast<char*>(out), static_cast<std::streamsize>(n)));
  }

 private:
  std::ifstream& in_;
  std::uint64_t remaining_;
};

class StructureChecker {
 public:
  StructureChecker(const fs::path& path, bool little_endian, std::uint64_t max_bytes)
      : path_(path), little_(little_endian), max_bytes_(max_bytes) {}

  void set_variable(int variable) { variable_ = variable; }

  [[noreturn]] void Fail(const std::string& message, bool damaged = true) const {
    throw InputError("MAT file '" + path_.string() + "', variable " + std::to_string(variable_) +
                     ": " + message + (damaged ? " (damaged file)" : ""));
  }

  std::string DimsText(const unsigned char* dims, std::uint64_t rank) const {
    std::string text;
    for (std::uint64_t k = 0; k < rank; ++k) text += (k ? " x " : "") + std::to_string(U32(dims + 4 * k));
    return text;
  }

  std::uint32_t U32(const unsigned char* b) const {
    return little_ ? std::uint32_t{b[0]} | std::uint32_t{b[1]} << 8 | std::uint32_t{b[2]} << 16 |
                         std::uint32_t{b[3]} << 24
                   : std::uint32_t{b[0]} << 24 | std::uint32_t{b[1]} << 16 |
                         std::uint32_t{b[2]} << 8 | std::uint32_t{b[3]};
  }

  // A matrix element's content of `bytes` bytes: array flags, dimensions, name, then the data or
  // cells. The layout is checked as matio reads it (mat5.c, Mat_VarReadNextInfo5 and ReadNextCell):
  // matio reads the flags and the dimensions' tag as 24 bytes, skips a name only when it is of type
  // miINT8, and reads a char array's data by the size in the tag it finds where the name ends; an
  // element it would read from somewhere other than where this check looked is rejected.
  void Matrix(Source& src, std::uint64_t bytes, int depth) {
    if (depth > kMaxMatNesting) {
      Fail("cells nested more than " + std::to_string(kMaxMatNesting) + " levels deep");
    }
    if (bytes == 0) return;  // an empty element: MATLAB writes them for empty cells
    std::uint64_t left = bytes;
    unsigned char flags[8] = {};
    const std::uint64_t flags_bytes =
        Element(src, &left, "array flags", flags, sizeof flags, kMiUint32, nullptr, Packed::kNo);
    if (flags_bytes != sizeof flags) {
      Fail("array flags of " + std::to_string(flags_bytes) + " bytes, expected 8");
    }
    const std::uint32_t array_class = U32(flags) & 0xFF;

    unsigned char dims[4 * kMaxMatRank] = {};
    const std::uint64_t dims_bytes =
        Element(src, &left, "dimensions", dims, sizeof dims, kMiInt32, nullptr, Packed::kNo);
    if (dims_bytes % 4 != 0 || dims_bytes > sizeof dims) {
      Fail("dimensions of " + std::to_string(dims_bytes) + " bytes, expected at most " +
           std::to_string(kMaxMatRank) + " dimensions of 4 bytes");
    }
    double numel = 1.0;
    for (std::uint64_t k = 0; k < dims_bytes / 4; ++k) {
      // Each dimension is bounded, not only their product: an empty array (a zero dimension) may
      // declare a huge other one, and a char array's rows become strings.
      const std::uint32_t d = U32(dims + 4 * k);
      if (d > max_bytes_) {
        Fail("dimension " + std::to_string(k + 1) + " = " + std::to_string(d) +
             ", more than the file can hold");
      }
      numel *= d;
    }
    char name_bytes[64] = {};
    Element(src, &left, "name", reinterpret_cast<unsigned char*>(name_bytes), sizeof name_bytes - 1);
    const std::uint32_t name_type = last_type_;  // checked below, after the sizes
    const std::string name = *name_bytes ? "'" + EscapeNonUtf8(name_bytes) + "': " : "";
    // No reader takes a struct, object, sparse matrix, function handle or opaque object, and matio
    // allocates by sizes read from their contents (a sparse matrix's index and data tags, found by
    // fuzzing; it also leaks the parts of a function handle it reads): they are rejected before
    // matio reads them, with classes matio does not know.
    if (!ReadableClass(array_class)) {
      const bool known = array_class >= kCellClass && array_class <= kOpaqueClass;
      Fail(name + "array class " + std::to_string(array_class) + ClassText(array_class) +
               ", expected a numeric, char or cell array",
           !known);
    }
    // Every element takes at least a byte of (inflated) data. matio allocates a char array, and
    // any array inside a cell, by its dimensions when it reads it; the readers check the sizes of
    // top-level numeric arrays themselves, with messages of their own.
    const bool unchecked = array_class == kCharClass || depth > 0;
    if (unchecked && numel > static_cast<double>(max_bytes_)) {
      std::ostringstream m;
      m << name << "size " << DimsText(dims, dims_bytes / 4) << " (" << numel
        << " elements), more than the file can hold";
      Fail(m.str());
    }
    if (name_type != kMiInt8) {
      Fail("name: data type " + std::to_string(name_type) + ", expected " + std::to_string(kMiInt8));
    }
    const double children = array_class == kCellClass ? numel : 0.0;  // matrix elements that follow
    // Each is a matrix element of at least a tag (8 bytes).
    if (children * 8.0 > static_cast<double>(left)) {
      Fail("declares " + std::to_string(children) + " cells but only " +
           std::to_string(left) + " bytes follow");
    }
    for (std::uint64_t i = 0; i < static_cast<std::uint64_t>(children); ++i) {
      unsigned char tag[8];
      if (left < 8 || !src.Read(tag, 8)) Fail("cell " + std::to_string(i + 1) + " is missing");
      left -= 8;
      const std::uint32_t type = U32(tag), size = U32(tag + 4);
      if (type != kMiMatrix) {
        Fail("cell " + std::to_string(i + 1) + " has data type " + std::to_string(type) +
             ", expected a matrix (14)");
      }
      if (size > left) {
        Fail("cell " + std::to_string(i + 1) + " declares " + std::to_string(size) +
             " bytes but only " + std::to_string(left) + " follow");
      }
      Matrix(src, size, depth + 1);
      left -= size;
    }
    // Data elements (real and imaginary parts): each must be there in full, and a non-empty char
    // or numeric array's first one must lie inside the array (matio reads its tag from where the
    // name ends, whatever follows). The data may end early between two elements: matio declares
    // compressed char arrays 8 bytes longer than they are.
    if (array_class != kCellClass && numel > 0.0) Element(src, &left, "data", nullptr, 0);
    bool end = false;
    while (left >= 8 && !end) Element(src, &left, "data", nullptr, 0, 0, &end);
  }

  // Whether an element may be a small one (type, size and up to 4 data bytes in its 8-byte tag).
  enum class Packed { kYes, kNo };

  // One data element (tag and data, 8-byte aligned) of a matrix with `*left` bytes still to come.
  // Copies at most `keep` data bytes to `out`; checks the data type when `type` is not 0; returns
  // the number of data bytes. With `end`, the data may end before the tag: *end is set, 0 returned.
  std::uint64_t Element(Source& src, std::uint64_t* left, const char* what, unsigned char* out,
                        std::size_t keep, std::uint32_t type = 0, bool* end = nullptr,
                        Packed packed = Packed::kYes) {
    unsigned char tag[8];
    if (*left < 8 || !src.Read(tag, 8)) {
      if (end == nullptr) Fail(std::string(what) + " missing");
      *end = true;
      return 0;
    }
    *left -= 8;
    const std::uint32_t word = U32(tag);
    last_type_ = (word >> 16) != 0 ? word & 0xFFFF : word;
    if ((word >> 16) != 0) {  // small data element: type and size in 4 bytes, data in the next 4
      const std::uint32_t bytes = word >> 16;
      if (packed == Packed::kNo) Fail(std::string(what) + ": a small element, expected a full one");
      if (bytes > 4) Fail(std::string(what) + ": small element of " + std::to_string(bytes) + " bytes");
      if (type != 0 && (word & 0xFFFF) != type) Fail(std::string(what) + ": unexpected data type");
      if (keep > 0) std::copy(tag + 4, tag + 4 + std::min<std::size_t>(bytes, keep), out);
      return bytes;
    }
    if (type != 0 && word != type) {
      Fail(std::string(what) + ": data type " + std::to_string(word) + ", expected " +
           std::to_string(type));
    }
    const std::uint64_t bytes = U32(tag + 4);
    const std::uint64_t padded = std::min<std::uint64_t>((bytes + 7) / 8 * 8, *left);
    if (bytes > *left) {
      Fail(std::string(what) + ": " + std::to_string(bytes) + " bytes declared, only " +
           std::to_string(*left) + " follow");
    }
    const std::size_t copied = static_cast<std::size_t>(std::min<std::uint64_t>(bytes, keep));
    if ((copied > 0 && !src.Read(out, copied)) || !src.Skip(padded - copied)) {
      Fail(std::string(what) + " ends early");
    }
    *left -= padded;
    return bytes;
  }

 private:
  fs::path path_;
  bool little_;
  std::uint64_t max_bytes_;
  int variable_ = 0;
  std::uint32_t last_type_ = 0;  // data type of the last element Element() read
};

// The zlib stream of a compressed variable, inflated on demand.
class InflateSource : public Source {
 public:
  InflateSource(const StructureChecker& checker, Source& compressed, std::uint64_t limit)
      : checker_(checker), compressed_(compressed), limit_(limit) {
    ok_ = inflateInit(&z_) == Z_OK;
  }
  ~InflateSource() override {
    if (ok_) inflateEnd(&z_);
  }
  InflateSource(const InflateSource&) = delete;
  InflateSource& operator=(const InflateSource&) = delete;

  bool Read(unsigned char* out, std::size_t n) override {
    if (!ok_) return false;
    produced_ += n;
    if (produced_ > limit_) {
      checker_.Fail("compressed data inflate to more than " + std::to_string(limit_) + " bytes");
    }
    z_.next_out = out;
    z_.avail_out = static_cast<uInt>(n);
    while (z_.avail_out > 0) {
      if (z_.avail_in == 0 && input_left_ > 0) {
        const std::size_t k = std::min<std::size_t>(input_left_, buffer_.size());
        if (!compressed_.Read(buffer_.data(), k)) return false;
        input_left_ -= k;
        z_.next_in = buffer_.data();
        z_.avail_in = static_cast<uInt>(k);
      }
      const int status = inflate(&z_, Z_NO_FLUSH);
      if (status == Z_STREAM_END) return z_.avail_out == 0;
      if (status != Z_OK) return false;  // corrupt data, or no progress: the input is used up
    }
    return true;
  }
  // Compressed bytes available to the stream.
  void set_input(std::uint64_t bytes) { input_left_ = bytes; }

 private:
  const StructureChecker& checker_;
  Source& compressed_;
  std::uint64_t limit_;
  std::uint64_t produced_ = 0;
  std::uint64_t input_left_ = 0;
  bool ok_ = false;
  z_stream z_{};
  std::array<unsigned char, 16384> buffer_;
};

// v7.3: the sizes of every dataset and attribute of the HDF5 file, which matio allocates by (a
// cell's element array, a dataset's data) before it reads them.
struct Hdf5Check {
  std::uint64_t max_bytes = 0;
  std::string problem;  // empty while every object passed
};

std::string SizeProblem(int rank, const hsize_t* dims, std::size_t element, std::uint64_t max_bytes) {
  if (rank < 0 || rank > kMaxMatRank) {
    return std::to_string(rank) + " dimensions, expected at most " + std::to_string(kMaxMatRank);
  }
  double bytes = static_cast<double>(element);
  std::string text;
  for (int k = 0; k < rank; ++k) {
    bytes *= static_cast<double>(dims[k]);
    text += (k ? " x " : "") + std::to_string(dims[k]);
    if (static_cast<double>(dims[k]) > static_cast<double>(max_bytes)) bytes = HUGE_VAL;
  }
  if (bytes > static_cast<double>(max_bytes)) {
    return "size " + text + " of " + std::to_string(element) +
           "-byte elements, more than the file can hold";
  }
  return "";
}

herr_t CheckHdf5Attribute(hid_t object, const char* name, const H5A_info_t*, void* data) {
  auto* check = static_cast<Hdf5Check*>(data);
  const hid_t attribute = H5Aopen(object, name, H5P_DEFAULT);
  if (attribute < 0) return 0;
  const hid_t type = H5Aget_type(attribute);
  const hid_t space = H5Aget_space(attribute);
  hsize_t dims[kMaxMatRank] = {};
  const int rank = space < 0 ? -1 : H5Sget_simple_extent_ndims(space);
  if (rank >= 0 && rank <= kMaxMatRank) H5Sget_simple_extent_dims(space, dims, nullptr);
  const std::string problem = SizeProblem(rank, dims, type < 0 ? 1 : H5Tget_size(type), check->max_bytes);
  if (!problem.empty()) check->problem = "attribute '" + std::string(name) + "': " + problem;
  if (space >= 0) H5Sclose(space);
  if (type >= 0) H5Tclose(type);
  H5Aclose(attribute);
  return problem.empty() ? 0 : 1;
}

herr_t CheckHdf5Object(hid_t parent, const char* name, const H5O_info_t* info, void* data) {
  auto* check = static_cast<Hdf5Check*>(data);
  const hid_t object = H5Oopen(parent, name, H5P_DEFAULT);
  if (object < 0) return 0;  // matio reports what it cannot open
  hsize_t position = 0;
  H5Aiterate2(object, H5_INDEX_NAME, H5_ITER_NATIVE, &position, CheckHdf5Attribute, check);
  if (check->problem.empty() && info->type == H5O_TYPE_DATASET) {
    const hid_t type = H5Dget_type(object);
    const hid_t space = H5Dget_space(object);
    hsize_t dims[kMaxMatRank] = {};
    const int rank = space < 0 ? -1 : H5Sget_simple_extent_ndims(space);
    if (rank >= 0 && rank <= kMaxMatRank) H5Sget_simple_extent_dims(space, dims, nullptr);
    check->problem = SizeProblem(rank, dims, type < 0 ? 1 : H5Tget_size(type), check->max_bytes);
    if (space >= 0) H5Sclose(space);
    if (type >= 0) H5Tclose(type);
  }
  if (!check->problem.empty()) check->problem = "'" + std::string(name) + "': " + check->problem;
  H5Oclose(object);
  return check->problem.empty() ? 0 : 1;
}

void CheckMatV73Structure(const fs::path& path, std::uint64_t max_bytes) {
  Hdf5Check check;
  check.max_bytes = max_bytes;
  H5E_BEGIN_TRY {
    const hid_t file = H5Fopen(path.string().c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    if (file >= 0) {
      H5Ovisit2(file, H5_INDEX_NAME, H5_ITER_NATIVE, CheckHdf5Object, &check, H5O_INFO_BASIC);
      H5Fclose(file);
    }
  } H5E_END_TRY;
  if (!check.problem.empty()) {
    throw InputError("MAT file '" + path.string() + "' (v7.3), object " + check.problem +
                     " (damaged file)");
  }
}

}  // namespace

void CheckMatFileStructure(const fs::path& path, std::uint64_t max_inflated_bytes) {
  std::ifstream in(path, std::ios::binary);
  std::error_code ec;
  const std::uint64_t size = fs::file_size(path, ec);
  unsigned char header[128];
  if (ec || !in.read(reinterpret_cast<char*>(header), sizeof header)) {
    throw InputError("MAT file '" + path.string() +
                     "': not a MATLAB .mat file (v5 or v7.3): shorter than the 128-byte header");
  }
  // Bytes 124-125: version 0x0100 (v5) or 0x0200 (v7.3); 126-127: "IM" little-endian, "MI" big.
  const bool little = header[126] == 'I' && header[127] == 'M';
  const bool big = header[126] == 'M' && header[127] == 'I';
  const unsigned version = little ? header[124] | header[125] << 8 : header[124] << 8 | header[125];
  if ((little || big) && version == 0x0200) {  // v7.3: an HDF5 file
    CheckMatV73Structure(path, max_inflated_bytes);
    return;
  }
  if (!(little || big) || version != 0x0100) {
    throw InputError("MAT file '" + path.string() +
                     "': not a MATLAB .mat file (v5 or v7.3): no v5 or v7.3 header in bytes "
                     "124-127 (v4 files are not read)");
  }
  StructureChecker checker(path, little, max_inflated_bytes);
  std::uint64_t at = sizeof header;
  for (int variable = 1; at < size; ++variable) {
    checker.set_variable(variable);
    unsigned char tag[8];
    if (size - at < 8 || !in.read(reinterpret_cast<char*>(tag), sizeof tag)) {
      checker.Fail("the file ends inside the tag at byte " + std::to_string(at));
    }
    const std::uint32_t type = checker.U32(tag);
    const std::uint64_t bytes = checker.U32(tag + 4);
    if (bytes > size - at - 8) {
      checker.Fail("declares " + std::to_string(bytes) + " bytes but only " +
                   std::to_string(size - at - 8) + " remain: the file is truncated");
    }
    FileSource file(in, bytes);
    if (type == kMiMatrix) {
      checker.Matrix(file, bytes, 0);
    } else if (type == kMiCompressed) {
      InflateSource inflated(checker, file, max_inflated_bytes);
      inflated.set_input(bytes);
      unsigned char inner[8];
      if (!inflated.Read(inner, sizeof inner)) checker.Fail("compressed data do not inflate");
      if (checker.U32(inner) != kMiMatrix) {
        checker.Fail("compressed data of type " + std::to_string(checker.U32(inner)) +
                     ", expected a matrix (14)");
      }
      checker.Matrix(inflated, checker.U32(inner + 4), 0);
    } else {
      checker.Fail("top-level element of data type " + std::to_string(type) +
                   ", expected a matrix (14) or compressed data (15)");
    }
    at += 8 + bytes;  // no padding between variables: a matrix's size is a multiple of 8 already
    in.clear();
    in.seekg(static_cast<std::streamoff>(at));
  }
}

}  // namespace stagefit::measurement::internal
