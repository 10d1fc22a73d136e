#include "stagefit/disturbance/record_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "stagefit/common/error.h"

namespace stagefit::disturbance {
namespace {

// A folder of this test process, removed when it exits.
struct TempDirectory {
  std::filesystem::path path = std::filesystem::temp_directory_path() /
                               ("stagefit_record_io_test_" + std::to_string(::getpid()));
  TempDirectory() { std::filesystem::create_directories(path); }
  ~TempDirectory() {
    std::error_code ignored;
    std::filesystem::remove_all(path, ignored);
  }
};

const std::filesystem::path& TempDir() {
  static const TempDirectory dir;
  return dir.path;
}

void WriteText(const std::filesystem::path& p, const std::string& text) {
  std::ofstream(p) << text;
}

template <typename F>
std::string InputErrorMessage(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError";
  return "";
}

TEST(CsvTable, WrittenTableReadsBackWithUnitsAndComments) {
  CsvTable t;
  t.comments = {"synthetic record", "seed 1"};
  t.column_names = {"time_s", "voltage"};
  t.units = {"s", "V"};
  t.values.resize(4, 2);
  t.values << 0.0, 1.234567891e-3, 0.25, -2.5e-7, 0.5, 3.0, 0.75, 1e-300;
  const auto path = TempDir() / "round_trip.csv";
  WriteCsvTable(path, t);
  const CsvTable r = ReadCsvTable(path);
  EXPECT_EQ(r.comments, t.comments);
  EXPECT_EQ(r.column_names, t.column_names);
  EXPECT_EQ(r.units, t.units);
  ASSERT_EQ(r.values.rows(), 4);
  constexpr double kNineDigits = 1e-9;  // values are written with %.9g
  for (int i = 0; i < 4; ++i) {
    for (int c = 0; c < 2; ++c) {
      EXPECT_NEAR(r.values(i, c), t.values(i, c), kNineDigits * std::abs(t.values(i, c)));
    }
  }
  EXPECT_DOUBLE_EQ(CalcSampleRate(r, "time_s"), 4.0);
  EXPECT_NO_THROW(CheckColumnUnit(r, "voltage", "V"));
  EXPECT_THROW(CheckColumnUnit(r, "voltage", "m"), InputError);
  EXPECT_EQ(r.Column("voltage").size(), 4);
  EXPECT_NE(InputErrorMessage([&] { r.Column("x1"); }).find("columns: time_s, voltage"),
            std::string::npos);
}

TEST(ReadCsvTable, NamesFileLineAndColumnOfABadField) {
  const auto path = TempDir() / "bad.csv";
  WriteText(path, "time_s,x\n0,1\n0.1,abc\n");
  const std::string message = InputErrorMessage([&] { ReadCsvTable(path); });
  EXPECT_NE(message.find("bad.csv:3"), std::string::npos) << message;
  EXPECT_NE(message.find("'x'"), std::string::npos) << message;
  WriteText(path, "time_s,x\n0,1,2\n");
  EXPECT_NE(InputErrorMessage([&] { ReadCsvTable(path); }).find("3 fields, expected 2"),
            std::string::npos);
  WriteText(path, "time_s,x\n0,nan\n");
  EXPECT_THROW(ReadCsvTable(path), InputError);
  WriteText(path, "# only a comment\n");
  EXPECT_THROW(ReadCsvTable(path), InputError);
  WriteText(path, "time_s,time_s\n");
  EXPECT_THROW(ReadCsvTable(path), InputError);
  EXPECT_THROW(ReadCsvTable(TempDir() / "missing.csv"), InputError);
}

TEST(CalcSampleRate, RejectsGapsInTime) {
  const auto path = TempDir() / "gap.csv";
  WriteText(path, "time_s,x\n0,0\n0.1,0\n0.2,0\n0.4,0\n");
  const CsvTable t = ReadCsvTable(path);
  const std::string message = InputErrorMessage([&] { CalcSampleRate(t, "time_s"); });
  EXPECT_NE(message.find("rows 2 and 3"), std::string::npos) << message;
}

}  // namespace
}  // namespace stagefit::disturbance
