// Inputs that once crashed a measurement reader under libFuzzer (tests/fuzz/regressions/, found by
// scripts/fuzz.sh): each must now be rejected with an InputError naming the problem. The same bytes
// are replayed by the fuzz programs (scripts/fuzz.sh --replay); docs/reliability.md lists them.

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>

#include "stagefit/common/error.h"
#include "stagefit/measurement/mat_file.h"
#include "stagefit/measurement/raw_hammer_file.h"
#include "measurement_test_data.h"

namespace stagefit::measurement {
namespace {

namespace fs = std::filesystem;
using testing::ExpectInputError;

fs::path Regressions(const std::string& target) {
  return fs::path(STAGEFIT_SOURCE_DIR) / "tests" / "fuzz" / "regressions" / target;
}

std::string ReadBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// The v5 dimensions tag of a matrix declares 1 GiB: matio allocated 2 GiB for the dimension array
// before reading it.
TEST(MatFileFuzzRegression, DimensionsLargerThanTheVariableAreRejected) {
  ExpectInputError(
      [] { ReadMatMeasurement(Regressions("mat_measurement_fuzz") / "v5_dims_size_1gb.mat"); },
      "dimensions: 1073741836 bytes declared, only 96 follow");
}

// A char array of 2216951809 x 0: no data, but one std::string per row was allocated (70 GB).
TEST(MatFileFuzzRegression, HugeDimensionOfAnEmptyArrayIsRejected) {
  ExpectInputError(
      [] {
        ReadMatMeasurement(Regressions("mat_measurement_fuzz") / "v5_char_rows_huge_zero_columns.mat");
      },
      "dimension 1 = 2216951809, more than the file can hold");
}

// A compressed char array whose data are shorter than its dimensions: the raw reader read past
// matio's buffer (heap-buffer-overflow).
TEST(RawHammerFileFuzzRegression, CharDataShorterThanItsDimensionsIsRejected) {
  ExpectInputError(
      [] {
        ReadRawHammerFile(Regressions("raw_hammer_fuzz") / "v5_char_data_shorter_than_dims.mat");
      },
      "variable 3: data ends early");
}

// A char array of 524289 x 65536 in a 2 kB file: matio allocated its data (137 GB) when the raw
// reader read the names.
TEST(RawHammerFileFuzzRegression, CharArrayLargerThanTheFileIsRejected) {
  ExpectInputError(
      [] { ReadRawHammerFile(Regressions("raw_hammer_fuzz") / "v5_char_dims_product_huge.mat"); },
      "variable 5: size 524289 x 65536 (3.43598e+10 elements), more than the file can hold");
}

// A v7.3 (HDF5) cell array declaring 399431958529 elements: matio's calloc of the element array
// exceeded the address space.
TEST(RawHammerFileFuzzRegression, HugeV73DatasetIsRejectedBeforeMatioAllocates) {
  if (!IsMatV73Supported()) GTEST_SKIP() << "matio without HDF5";
  ExpectInputError(
      [] { ReadRawHammerFile(Regressions("raw_hammer_fuzz") / "v73_cell_dims_huge.mat"); },
      "object 'output_names': size 399431958529 x 1");
}

// A function handle (array class 16) holding cells: matio 1.5 leaked what it had read of it.
TEST(MatFileFuzzRegression, FunctionHandleIsRejectedBeforeMatioReadsIt) {
  ExpectInputError(
      [] { ReadMatMeasurement(Regressions("mat_measurement_fuzz") / "v5_function_handle_leak.mat"); },
      "variable 4: 'o': array class 16 (a function handle)");
}

// A cell's char array whose name element is of type miDOUBLE (9): matio skips only miINT8 names,
// so it read the name's bytes as the data tag and allocated 0xffffffffd6000006 bytes (CI's fuzz
// run; this file reproduces it from a seed).
TEST(MatFileFuzzRegression, NameOfAnotherTypeThanInt8IsRejected) {
  ExpectInputError(
      [] { ReadMatMeasurement(Regressions("mat_measurement_fuzz") / "v5_cell_name_not_int8.mat"); },
      "name: data type 9, expected 1");
}

// A sparse matrix in a mutated measurement: matio allocated 2 GiB reading it, before the reader
// refused the class.
TEST(MatFileFuzzRegression, SparseMatrixIsRejectedBeforeMatioReadsIt) {
  ExpectInputError(
      [] {
        ReadMatMeasurement(Regressions("mat_measurement_fuzz") / "v5_sparse_unknown_data_type.mat");
      },
      "variable 12: 'impact_directi");
  ExpectInputError(
      [] {
        ReadMatMeasurement(Regressions("mat_measurement_fuzz") / "v5_sparse_unknown_data_type.mat");
      },
      "array class 5 (a sparse matrix), expected a numeric, char or cell array");
}

// Edits of a valid v5 file at the places where matio and the structure check could read the
// layout differently. The first variable, 'freq_hz', starts at byte 128: its tag (8 bytes), the
// array flags' tag and flags (8 + 8), the dimensions' tag and two dimensions (8 + 8), the name's
// tag and 'freq_hz' padded to 8 bytes (8 + 8), then the data.
TEST(MatFileFuzzRegression, LayoutMatioWouldReadElsewhereIsRejected) {
  const fs::path dir = testing::MakeTempDir("fuzz_regression_layout");
  const fs::path valid = dir / "valid.mat";
  WriteMatMeasurement(valid, testing::MakeMeasurement(3, false), MatVersion::kV5);
  ASSERT_NO_THROW(ReadMatMeasurement(valid));
  const std::string bytes = ReadBytes(valid);
  auto word = [&](std::size_t at) {
    std::uint32_t w;
    std::memcpy(&w, bytes.data() + at, 4);
    return w;
  };
  ASSERT_EQ(word(128), 14u);       // miMATRIX
  ASSERT_EQ(word(136), 6u);        // flags: miUINT32,
  ASSERT_EQ(word(140), 8u);        //        8 bytes
  ASSERT_EQ(word(144) & 0xFF, 6u);  // class double
  ASSERT_EQ(word(152), 5u);        // dimensions: miINT32
  ASSERT_EQ(word(168), 1u);        // name: miINT8,
  ASSERT_EQ(word(172), 7u);        //       'freq_hz'
  auto expect_edit = [&](std::size_t at, std::uint32_t value, const std::string& message) {
    SCOPED_TRACE(message);
    std::string edited = bytes;
    std::memcpy(edited.data() + at, &value, 4);
    const fs::path path = dir / "edited.mat";
    std::ofstream(path, std::ios::binary | std::ios::trunc) << edited;
    ExpectInputError([&] { ReadMatMeasurement(path); }, message);
  };
  expect_edit(168, 2, "variable 1: name: data type 2, expected 1");
  expect_edit(136, 6u | 4u << 16, "variable 1: array flags: a small element, expected a full one");
  expect_edit(152, 5u | 4u << 16, "variable 1: dimensions: a small element, expected a full one");
  // The variable ends after its name: matio would read its data tag from the next variable.
  expect_edit(132, 48, "variable 1: data missing");
  expect_edit(144, 5, "variable 1: 'freq_hz': array class 5 (a sparse matrix)");
  expect_edit(144, 2, "variable 1: 'freq_hz': array class 2 (a struct)");
  fs::remove_all(dir);
}

// The readable equivalent of the first case: a valid file with one size field made too large.
TEST(MatFileFuzzRegression, EditedDimensionsTagIsRejected) {
  const fs::path dir = testing::MakeTempDir("fuzz_regression");
  const fs::path path = dir / "m.mat";
  WriteMatMeasurement(path, testing::MakeMeasurement(3, false), MatVersion::kV5);
  ASSERT_NO_THROW(ReadMatMeasurement(path));
  std::string bytes = ReadBytes(path);
  // The first variable starts at byte 128: its tag (8 bytes), the array flags (16), then the
  // dimensions tag: type miINT32 (5), size 8 bytes for two dimensions.
  std::uint32_t tag[2];
  std::memcpy(tag, bytes.data() + 128 + 8 + 16, sizeof tag);
  ASSERT_EQ(tag[0], 5u);
  ASSERT_EQ(tag[1], 8u);
  tag[1] = 0x40000008;
  std::memcpy(bytes.data() + 128 + 8 + 16, tag, sizeof tag);
  std::ofstream(path, std::ios::binary) << bytes;
  ExpectInputError([&] { ReadMatMeasurement(path); }, "dimensions: 1073741832 bytes declared");
  ExpectInputError([&] { ReadMatFile(path); }, "variable 1: dimensions");
  fs::remove_all(dir);
}

// Every stored input of every measurement target ends in an InputError (none may crash or throw
// anything else), including inputs added later without a test of their own.
TEST(MeasurementFuzzRegression, EveryStoredInputIsAnInputError) {
  const std::function<void(const fs::path&)> readers[] = {
      [](const fs::path& p) { ReadMatMeasurement(p); },
      [](const fs::path& p) { ReadRawHammerFile(p); },
  };
  const char* targets[] = {"mat_measurement_fuzz", "raw_hammer_fuzz"};
  int count = 0;
  for (int t = 0; t < 2; ++t) {
    if (!fs::is_directory(Regressions(targets[t]))) continue;
    for (const auto& entry : fs::directory_iterator(Regressions(targets[t]))) {
      if (entry.path().filename().string().find("v73") != std::string::npos &&
          !IsMatV73Supported()) {
        continue;
      }
      SCOPED_TRACE(entry.path().string());
      EXPECT_THROW(readers[t](entry.path()), InputError);
      ++count;
    }
  }
  EXPECT_GE(count, 8);
}

}  // namespace
}  // namespace stagefit::measurement
