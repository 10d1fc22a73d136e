#include "stagefit/measurement/mat_file.h"

#include <gtest/gtest.h>

#include <cstring>
#include <fstream>

#include "measurement_test_data.h"

namespace stagefit::measurement {
namespace {
namespace fs = std::filesystem;
using testing::ExpectInputError;
using testing::ExpectSameMeasurement;
using testing::MakeMeasurement;

std::vector<MatVersion> Versions() {
  std::vector<MatVersion> v = {MatVersion::kV5};
  if (IsMatV73Supported()) v.push_back(MatVersion::kV73);
  return v;
}

std::vector<MatVariable> SampleVariables() {
  std::mt19937 rng(42);
  std::normal_distribution<double> n(0.0, 1e3);
  Eigen::MatrixXd a(4, 3);
  for (int i = 0; i < a.size(); ++i) a.data()[i] = n(rng);
  Eigen::MatrixXcd b(2, 5);
  for (int i = 0; i < b.size(); ++i) b.data()[i] = {n(rng), n(rng)};
  return {{"A", a},
          {"B", b},
          {"empty", Eigen::MatrixXd(0, 0)},
          {"title", std::string("state space of the micro-station")},
          {"state_names", std::vector<std::string>{"granite.Dx", "ty.Dz", "", "hexapod.Rz"}}};
}

TEST(MatFile, GenericRoundTripIsBitIdenticalInEveryVersion) {
  const fs::path dir = testing::MakeTempDir("mat_generic");
  for (MatVersion version : Versions()) {
    const fs::path path = dir / (version == MatVersion::kV5 ? "v5.mat" : "v73.mat");
    const auto written = SampleVariables();
    WriteMatFile(path, written, version);
    const auto read = ReadMatFile(path);
    ASSERT_EQ(read.size(), written.size());
    for (const MatVariable& w : written) {
      SCOPED_TRACE(w.name);
      auto it = std::find_if(read.begin(), read.end(),
                             [&](const MatVariable& r) { return r.name == w.name; });
      ASSERT_NE(it, read.end());
      ASSERT_EQ(it->value.index(), w.value.index());
      EXPECT_TRUE(it->value == w.value);
    }
  }
  fs::remove_all(dir);
}

TEST(MatFile, V73IsSupportedByThisMatio) {
  // Debian's matio is built with HDF5; if this fails, v7.3 requests are reported as errors.
  EXPECT_TRUE(IsMatV73Supported());
}

TEST(MatFile, MeasurementRoundTripIsBitIdenticalInEveryVersion) {
  const fs::path dir = testing::MakeTempDir("mat_measurement");
  const FrfData data = MakeMeasurement(17);
  for (MatVersion version : Versions()) {
    const fs::path path = dir / (version == MatVersion::kV5 ? "m5.mat" : "m73.mat");
    WriteMatMeasurement(path, data, version);
    ExpectSameMeasurement(ReadMatMeasurement(path, true), data);
  }
  fs::remove_all(dir);
}

// The number of hits averaged per input, with the coherence they give (FrfData::averages).
TEST(MatFile, NumAveragesRoundTripsAndBadCountsAreRefused) {
  const fs::path dir = testing::MakeTempDir("mat_averages");
  FrfData data = MakeMeasurement(19);
  data.averages = {3, 5};
  for (MatVersion version : Versions()) {
    const fs::path path = dir / (version == MatVersion::kV5 ? "m5.mat" : "m73.mat");
    WriteMatMeasurement(path, data, version);
    ExpectSameMeasurement(ReadMatMeasurement(path, true), data);
  }
  Eigen::MatrixXcd frf(1, 2);
  frf << 1.0, 2.0;
  auto write = [&](const Eigen::MatrixXd& counts) -> fs::path {
    WriteMatFile(dir / "bad.mat", {{"freq_hz", Eigen::MatrixXd(Eigen::MatrixXd::Constant(1, 1, 10.0))},
                                   {"frf", frf},
                                   {"coherence", Eigen::MatrixXd(Eigen::MatrixXd::Constant(1, 2, 0.9))},
                                   {"num_averages", Eigen::MatrixXd(counts)},
                                   {"quantity", std::string("mobility")}});
    return dir / "bad.mat";
  };
  ExpectInputError([&] { ReadMatMeasurement(write(Eigen::MatrixXd(Eigen::RowVector2d(3, 2.5)))); },
                   "variable 'num_averages': element 2 = 2.5, expected a whole count >= 2");
  ExpectInputError([&] { ReadMatMeasurement(write(Eigen::MatrixXd(Eigen::RowVector2d(1, 3)))); }, "element 1 = 1, expected a whole count >= 2");
  ExpectInputError([&] { ReadMatMeasurement(write(Eigen::MatrixXd(Eigen::RowVector3d(3, 3, 3)))); }, "variable 'num_averages': size 1 x 3, expected 2 x 1");
  fs::remove_all(dir);
}

TEST(MatFile, MeasurementWithoutGeometryRoundTrips) {
  const fs::path dir = testing::MakeTempDir("mat_nogeometry");
  const FrfData data = MakeMeasurement(18, false);
  WriteMatMeasurement(dir / "m.mat", data);
  ExpectSameMeasurement(ReadMatMeasurement(dir / "m.mat"), data);
  ExpectInputError([&] { ReadMatMeasurement(dir / "m.mat", true); }, "missing geometry");
  fs::remove_all(dir);
}

// A measurement file made of the standard variables with one of them replaced or removed.
class MatBadInput : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::MakeTempDir("mat_bad");
    const FrfData d = MakeMeasurement(23);
    Eigen::MatrixXd freq = d.frequency_hz;
    base_ = {{"freq_hz", freq},
             {"quantity", std::string("accelerance")},
             {"sensor_body", std::string("hexapod")},
             {"impact_body", std::vector<std::string>{"hexapod", "rz"}}};
    Eigen::MatrixXd sp(3, 3), sd(3, 3), ip(2, 3), id(2, 3);
    for (int i = 0; i < 3; ++i) {
      sp.row(i) = d.outputs[i].position_W.transpose();
      sd.row(i) = d.outputs[i].direction_W.transpose();
    }
    for (int j = 0; j < 2; ++j) {
      ip.row(j) = d.inputs[j].position_W.transpose();
      id.row(j) = d.inputs[j].direction_W.transpose();
    }
    base_.push_back({"sensor_position", sp});
    base_.push_back({"sensor_direction", sd});
    base_.push_back({"impact_position", ip});
    base_.push_back({"impact_direction", id});
    data_ = d;
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A valid v5 file of data_ whose bytes are then edited: swaps the stored doubles `a` and `b`
  // (the v5 writer stores arrays uncompressed, so each value appears as its 8 raw bytes).
  fs::path WriteSwapped(const std::string& name, double a, double b) {
    const fs::path path = dir_ / name;
    WriteMatMeasurement(path, data_);
    std::ifstream in(path, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::string pa(8, '\0'), pb(8, '\0');
    std::memcpy(pa.data(), &a, 8);
    std::memcpy(pb.data(), &b, 8);
    const std::size_t ia = bytes.find(pa), ib = bytes.find(pb);
    EXPECT_NE(ia, std::string::npos);
    EXPECT_NE(ib, std::string::npos);
    bytes.replace(ia, 8, pb);
    bytes.replace(ib, 8, pa);
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    return path;
  }

  fs::path dir_;
  std::vector<MatVariable> base_;
  FrfData data_;
};

TEST_F(MatBadInput, NotAMatFileIsAnInputError) {
  const fs::path path = dir_ / "text.mat";
  std::ofstream(path) << "freq_hz,output,input,re,im\n";
  ExpectInputError([&] { ReadMatMeasurement(path); }, "not a MATLAB .mat file");
  ExpectInputError([&] { ReadMatFile(dir_ / "absent.mat"); }, "does not exist");
}

TEST_F(MatBadInput, TruncatedFileIsAnInputError) {
  const fs::path good = dir_ / "good.mat";
  WriteMatMeasurement(good, data_);
  std::ifstream in(good, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const fs::path cut = dir_ / "cut.mat";
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  ExpectInputError([&] { ReadMatMeasurement(cut); }, "cut.mat");
}

TEST_F(MatBadInput, MissingFrequenciesIsAnInputError) {
  const fs::path path = dir_ / "nofreq.mat";
  WriteMatFile(path, {{"quantity", std::string("mobility")}});
  ExpectInputError([&] { ReadMatMeasurement(path); }, "variable 'freq_hz' is missing");
}

TEST_F(MatBadInput, MissingFrfIsAnInputError) {
  const fs::path path = dir_ / "nofrf.mat";
  WriteMatFile(path, base_);
  ExpectInputError([&] { ReadMatMeasurement(path); }, "variable 'frf' is missing");
}

TEST_F(MatBadInput, FrfOfWrongSizeIsAnInputError) {
  auto vars = base_;
  vars.push_back({"frf", Eigen::MatrixXcd(Eigen::MatrixXcd::Ones(3, 2))});
  const fs::path path = dir_ / "size.mat";
  WriteMatFile(path, vars);
  ExpectInputError([&] { ReadMatMeasurement(path); }, "variable 'frf': size 3 x 2, expected Nout x Nin x 11");
}

TEST_F(MatBadInput, UnknownQuantityIsAnInputError) {
  Eigen::MatrixXd freq(1, 1);
  freq << 10.0;
  const fs::path path = dir_ / "quantity.mat";
  WriteMatFile(path, {{"freq_hz", freq},
                      {"frf", Eigen::MatrixXcd(Eigen::MatrixXcd::Ones(1, 1))},
                      {"quantity", std::string("inertance")}});
  ExpectInputError([&] { ReadMatMeasurement(path); }, "'inertance', expected 'accelerance'");
}

TEST_F(MatBadInput, NonMonotonicFrequenciesAreAnInputError) {
  const fs::path path = WriteSwapped("order.mat", data_.frequency_hz[3], data_.frequency_hz[4]);
  ExpectInputError([&] { ReadMatMeasurement(path); }, "freq_hz[5]");
  ExpectInputError([&] { ReadMatMeasurement(path); }, "expected strictly increasing frequencies");
}

TEST_F(MatBadInput, NanInFrfIsAnInputError) {
  Eigen::MatrixXd freq(1, 1);
  freq << 10.0;
  Eigen::MatrixXcd h(2, 1);
  h << std::complex<double>(1.0, 0.0), std::complex<double>(std::nan(""), 0.0);
  const fs::path path = dir_ / "nan.mat";
  WriteMatFile(path, {{"freq_hz", freq}, {"frf", h}, {"quantity", std::string("mobility")}});
  ExpectInputError([&] { ReadMatMeasurement(path); }, "frf(2, 1, 1) = (nan,0)");
}

TEST_F(MatBadInput, DeadChannelIsAnInputError) {
  Eigen::MatrixXd freq(1, 1);
  freq << 10.0;
  Eigen::MatrixXcd h = Eigen::MatrixXcd::Ones(2, 2);
  h.row(1).setZero();
  const fs::path path = dir_ / "dead.mat";
  WriteMatFile(path, {{"freq_hz", freq},
                      {"frf", h},
                      {"quantity", std::string("mobility")},
                      {"output_names", std::vector<std::string>{"a1x", "a1y"}}});
  ExpectInputError([&] { ReadMatMeasurement(path); }, "output channel 2 'a1y' is dead");
}

TEST_F(MatBadInput, PartialGeometryIsAnInputError) {
  Eigen::MatrixXd freq(1, 1);
  freq << 10.0;
  const fs::path path = dir_ / "partial.mat";
  WriteMatFile(path, {{"freq_hz", freq},
                      {"frf", Eigen::MatrixXcd(Eigen::MatrixXcd::Ones(1, 1))},
                      {"quantity", std::string("mobility")},
                      {"sensor_body", std::string("hexapod")},
                      {"sensor_position", Eigen::MatrixXd(Eigen::MatrixXd::Zero(1, 3))}});
  ExpectInputError([&] { ReadMatMeasurement(path); }, "missing geometry: variable(s) 'sensor_direction'");
}

TEST_F(MatBadInput, GeometryOfWrongSizeIsAnInputError) {
  Eigen::MatrixXd freq(1, 1);
  freq << 10.0;
  Eigen::MatrixXd dir(1, 3);
  dir << 0.0, 0.0, 1.0;
  const fs::path path = dir_ / "geomsize.mat";
  WriteMatFile(path, {{"freq_hz", freq},
                      {"frf", Eigen::MatrixXcd(Eigen::MatrixXcd::Ones(1, 1))},
                      {"quantity", std::string("mobility")},
                      {"sensor_body", std::string("hexapod")},
                      {"sensor_position", Eigen::MatrixXd(Eigen::MatrixXd::Zero(3, 1))},
                      {"sensor_direction", dir}});
  ExpectInputError([&] { ReadMatMeasurement(path); }, "variable 'sensor_position': size 3 x 1, expected 1 x 3");
}

TEST_F(MatBadInput, NonUnitDirectionIsAnInputError) {
  Eigen::MatrixXd freq(1, 1);
  freq << 10.0;
  Eigen::MatrixXd dir(1, 3);
  dir << 0.0, 0.5, 1.0;
  const fs::path path = dir_ / "unit.mat";
  WriteMatFile(path, {{"freq_hz", freq},
                      {"frf", Eigen::MatrixXcd(Eigen::MatrixXcd::Ones(1, 1))},
                      {"quantity", std::string("mobility")},
                      {"sensor_body", std::string("hexapod")},
                      {"sensor_position", Eigen::MatrixXd(Eigen::MatrixXd::Zero(1, 3))},
                      {"sensor_direction", dir}});
  ExpectInputError([&] { ReadMatMeasurement(path); }, "expected a unit vector");
}

TEST_F(MatBadInput, WrongNameCountIsAnInputError) {
  Eigen::MatrixXd freq(1, 1);
  freq << 10.0;
  const fs::path path = dir_ / "names.mat";
  WriteMatFile(path, {{"freq_hz", freq},
                      {"frf", Eigen::MatrixXcd(Eigen::MatrixXcd::Ones(2, 1))},
                      {"quantity", std::string("mobility")},
                      {"output_names", std::vector<std::string>{"a1x"}}});
  ExpectInputError([&] { ReadMatMeasurement(path); }, "'output_names': 1 names, expected 2");
}

TEST_F(MatBadInput, CoherenceOutOfRangeIsAnInputError) {
  Eigen::MatrixXd freq(1, 1);
  freq << 10.0;
  const fs::path path = dir_ / "coh.mat";
  WriteMatFile(path, {{"freq_hz", freq},
                      {"frf", Eigen::MatrixXcd(Eigen::MatrixXcd::Ones(1, 1))},
                      {"coherence", Eigen::MatrixXd(Eigen::MatrixXd::Constant(1, 1, 1.5))},
                      {"quantity", std::string("mobility")}});
  ExpectInputError([&] { ReadMatMeasurement(path); }, "coherence(1, 1, 1) = 1.5");
}

TEST_F(MatBadInput, InvalidVariableNameIsRejectedOnWrite) {
  ExpectInputError([&] { WriteMatFile(dir_ / "n.mat", {{"1abc", std::string("x")}}); },
                   "'1abc' is not a MATLAB identifier");
  ExpectInputError(
      [&] { WriteMatFile(dir_ / "n.mat", {{"a", std::string("x")}, {"a", std::string("y")}}); },
      "variable 'a' is given twice");
}

}  // namespace
}  // namespace stagefit::measurement
