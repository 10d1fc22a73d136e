#include "stagefit/measurement/measurement_file.h"

#include <gtest/gtest.h>

#include "measurement_test_data.h"

namespace stagefit::measurement {
namespace {
namespace fs = std::filesystem;
using testing::ExpectInputError;
using testing::ExpectSameMeasurement;
using testing::MakeMeasurement;

TEST(MeasurementFile, EveryFormatRoundTripsThroughTheDispatcher) {
  const fs::path dir = testing::MakeTempDir("measurement_file");
  const FrfData data = MakeMeasurement(41);
  for (const char* name : {"m.mat", "m.csv", "M.MAT"}) {
    SCOPED_TRACE(name);
    WriteMeasurement(dir / name, data);
    ExpectSameMeasurement(ReadMeasurement(dir / name), data);
  }
  MeasurementWriteOptions v73;
  v73.mat_version = MatVersion::kV73;
  if (IsMatV73Supported()) {
    WriteMeasurement(dir / "m73.mat", data, v73);
    ExpectSameMeasurement(ReadMeasurement(dir / "m73.mat"), data);
  }
  // UFF keeps names, directions, FRFs and coherence but not positions or bodies.
  const FrfData no_geometry = MakeMeasurement(41, false);
  for (const char* name : {"m.uff", "m.unv"}) {
    WriteMeasurement(dir / name, no_geometry);
    const FrfData back = ReadMeasurement(dir / name);
    EXPECT_EQ(back.frequency_hz, no_geometry.frequency_hz);
    for (int k = 0; k < back.num_frequencies(); ++k) EXPECT_EQ(back.frf[k], no_geometry.frf[k]);
  }
  fs::remove_all(dir);
}

// --averages: the hits averaged, for a file that does not say (UFF 58 carries no count), over what a
// file says; refused below 2 and for a file without coherence.
TEST(MeasurementFile, AveragesOptionSetsOrOverridesTheCount) {
  const fs::path dir = testing::MakeTempDir("measurement_averages");
  const FrfData no_geometry = MakeMeasurement(42, false);
  WriteMeasurement(dir / "m.uff", no_geometry);
  MeasurementReadOptions options;
  EXPECT_TRUE(ReadMeasurement(dir / "m.uff", options).averages.empty());
  options.averages = 6;
  EXPECT_EQ(ReadMeasurement(dir / "m.uff", options).averages, std::vector<int>(no_geometry.num_inputs(), 6));
  FrfData counted = MakeMeasurement(42);
  counted.averages = {3, 4};
  WriteMeasurement(dir / "m.mat", counted);
  EXPECT_EQ(ReadMeasurement(dir / "m.mat").averages, (std::vector<int>{3, 4}));
  EXPECT_EQ(ReadMeasurement(dir / "m.mat", options).averages, (std::vector<int>{6, 6}));
  options.averages = 1;
  ExpectInputError([&] { ReadMeasurement(dir / "m.mat", options); }, "--averages 1, expected the number of hits averaged, >= 2");
  FrfData without = MakeMeasurement(42);
  without.coherence.clear();
  WriteMeasurement(dir / "w.mat", without);
  options.averages = 3;
  ExpectInputError([&] { ReadMeasurement(dir / "w.mat", options); }, "the file holds no coherence");
  fs::remove_all(dir);
}

TEST(MeasurementFile, UnknownExtensionIsAnInputError) {
  ExpectInputError([] { ReadMeasurement("data.xlsx"); }, "extension '.xlsx' is not a measurement format");
  ExpectInputError([] { WriteMeasurement("out", MakeMeasurement(1)); }, "expected .mat, .csv, .uff or .unv");
}

TEST(MeasurementFile, RequiredGeometryIsEnforcedForUff) {
  const fs::path dir = testing::MakeTempDir("measurement_file_uff");
  WriteMeasurement(dir / "m.uff", MakeMeasurement(2, false));
  MeasurementReadOptions options;
  options.require_geometry = true;
  ExpectInputError([&] { ReadMeasurement(dir / "m.uff", options); }, "missing geometry for channel");
  fs::remove_all(dir);
}

TEST(MeasurementFile, FailedWriteLeavesNoFile) {
  const fs::path dir = testing::MakeTempDir("measurement_file_atomic");
  FrfData bad = MakeMeasurement(3);
  bad.frf[0](0, 0) = {std::nan(""), 0.0};
  for (const char* name : {"bad.mat", "bad.csv", "bad.uff"}) {
    ExpectInputError([&] { WriteMeasurement(dir / name, bad); }, "expected a finite value");
    EXPECT_FALSE(fs::exists(dir / name)) << name;
  }
  EXPECT_TRUE(fs::is_empty(dir));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace stagefit::measurement
