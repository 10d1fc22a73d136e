#include "stagefit/measurement/raw_hammer_file.h"

#include <gtest/gtest.h>
#include <matio.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>

#include "stagefit/common/error.h"

namespace stagefit::measurement {
namespace {

namespace fs = std::filesystem;

class RawHammerFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("stagefit_raw_hammer_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
};

// 3 outputs (tri-axial accelerometer), 2 inputs, 3 hits, 64 samples of seeded noise plus a pulse.
RawHammerData MakeData(unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal;
  RawHammerData data;
  data.sample_rate_hz = 2048.0;
  data.quantity = FrfQuantity::kAccelerance;
  const char* axis = "xyz";
  for (int k = 0; k < 3; ++k) {
    ChannelGeometry c;
    c.name = std::string("a1") + axis[k];
    c.body = "hexapod";
    c.position_W = Eigen::Vector3d(0.0, 0.14, -0.03);
    c.direction_W = Eigen::Vector3d::Unit(k);
    data.outputs.push_back(c);
  }
  for (int j = 0; j < 2; ++j) {
    ChannelGeometry c;
    c.name = "F" + std::to_string(j + 1);
    c.body = j == 0 ? "hexapod" : "ty";
    c.position_W = Eigen::Vector3d(-0.14 * j, 0.0, -0.03);
    c.direction_W = -Eigen::Vector3d::UnitZ();
    data.inputs.push_back(c);
  }
  data.hits.resize(2);
  for (int j = 0; j < 2; ++j) {
    for (int h = 0; h < 3; ++h) {
      HammerHit hit;
      hit.force = Eigen::VectorXd::NullaryExpr(64, [&](Eigen::Index) { return normal(rng); });
      hit.force(5) += 100.0;
      hit.response = Eigen::MatrixXd::NullaryExpr(64, 3, [&](Eigen::Index, Eigen::Index) {
        return normal(rng);
      });
      data.hits[j].push_back(hit);
    }
  }
  data.response_full_scale = Eigen::Vector3d(500.0, 500.0, 250.0);
  data.force_full_scale = Eigen::Vector2d(2000.0, 2000.0);
  data.frame_origin_W = Eigen::Vector3d(0.0, 0.0, -0.03);
  return data;
}

void ExpectIdentical(const RawHammerData& a, const RawHammerData& b) {
  EXPECT_EQ(a.sample_rate_hz, b.sample_rate_hz);
  EXPECT_EQ(a.quantity, b.quantity);
  ASSERT_EQ(a.num_outputs(), b.num_outputs());
  ASSERT_EQ(a.num_inputs(), b.num_inputs());
  for (int i = 0; i < a.num_outputs(); ++i) {
    EXPECT_EQ(a.outputs[i].name, b.outputs[i].name);
    EXPECT_EQ(a.outputs[i].body, b.outputs[i].body);
    EXPECT_EQ(a.outputs[i].position_W, b.outputs[i].position_W);
    EXPECT_EQ(a.outputs[i].direction_W, b.outputs[i].direction_W);
  }
  for (int j = 0; j < a.num_inputs(); ++j) {
    EXPECT_EQ(a.inputs[j].name, b.inputs[j].name);
    EXPECT_EQ(a.inputs[j].body, b.inputs[j].body);
    EXPECT_EQ(a.inputs[j].position_W, b.inputs[j].position_W);
    EXPECT_EQ(a.inputs[j].direction_W, b.inputs[j].direction_W);
    ASSERT_EQ(a.hits[j].size(), b.hits[j].size());
    for (std::size_t h = 0; h < a.hits[j].size(); ++h) {
      EXPECT_EQ(a.hits[j][h].force, b.hits[j][h].force) << "input " << j << " hit " << h;
      EXPECT_EQ(a.hits[j][h].response, b.hits[j][h].response) << "input " << j << " hit " << h;
    }
  }
  EXPECT_EQ(a.response_full_scale, b.response_full_scale);
  EXPECT_EQ(a.force_full_scale, b.force_full_scale);
  ASSERT_EQ(a.frame_origin_W.has_value(), b.frame_origin_W.has_value());
  if (a.frame_origin_W) {
    EXPECT_EQ(*a.frame_origin_W, *b.frame_origin_W);
  }
}

TEST_F(RawHammerFileTest, WrittenFileReadsBackIdentical) {
  const RawHammerData data = MakeData(1u);
  const fs::path path = dir_ / "raw.mat";
  WriteRawHammerFile(path, data);
  RawHammerData back = ReadRawHammerFile(path);
  EXPECT_EQ(back.source, path.string());
  ExpectIdentical(data, back);
}

TEST_F(RawHammerFileTest, V73FileReadsBackIdentical) {
  if (!IsMatV73Supported()) GTEST_SKIP() << "matio without HDF5";
  const RawHammerData data = MakeData(2u);
  const fs::path path = dir_ / "raw73.mat";
  WriteRawHammerFile(path, data, MatVersion::kV73);
  ExpectIdentical(data, ReadRawHammerFile(path));
}

TEST_F(RawHammerFileTest, SingleInputWithDroppedTrailingDimensionReads) {
  RawHammerData data = MakeData(3u);
  data.inputs.resize(1);
  data.hits.resize(1);
  data.force_full_scale.resize(0);
  const fs::path path = dir_ / "one.mat";
  WriteRawHammerFile(path, data);  // matio writes Ns x Nhits x 1 as given; read it back
  ExpectIdentical(data, ReadRawHammerFile(path));
}

// Writes a file from raw matio variables for the failure cases.
void WriteVars(const fs::path& path, const std::vector<std::pair<std::string,
                                                                 std::pair<std::vector<std::size_t>,
                                                                           std::vector<double>>>>& vars,
               const char* quantity = "acceleration") {
  mat_t* mat = Mat_CreateVer(path.string().c_str(), nullptr, MAT_FT_MAT5);
  ASSERT_NE(mat, nullptr);
  for (const auto& [name, value] : vars) {
    std::vector<std::size_t> dims = value.first;
    matvar_t* v = Mat_VarCreate(name.c_str(), MAT_C_DOUBLE, MAT_T_DOUBLE,
                                static_cast<int>(dims.size()), dims.data(),
                                const_cast<double*>(value.second.data()), MAT_F_DONT_COPY_DATA);
    Mat_VarWrite(mat, v, MAT_COMPRESSION_NONE);
    Mat_VarFree(v);
  }
  if (quantity != nullptr) {
    std::size_t d[2] = {1, std::strlen(quantity)};
    matvar_t* v = Mat_VarCreate("response_quantity", MAT_C_CHAR, MAT_T_UINT8, 2, d,
                                const_cast<char*>(quantity), MAT_F_DONT_COPY_DATA);
    Mat_VarWrite(mat, v, MAT_COMPRESSION_NONE);
    Mat_VarFree(v);
  }
  Mat_Close(mat);
}

std::string ReadError(const fs::path& path) {
  try {
    ReadRawHammerFile(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::vector<double> Pulse(std::size_t ns, std::size_t records) {
  std::vector<double> v(ns * records, 0.0);
  for (std::size_t r = 0; r < records; ++r) v[r * ns + 3] = 10.0;
  return v;
}

std::vector<double> Ramp(std::size_t n) {
  std::vector<double> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = 0.001 * static_cast<double>(i % 97) - 0.04;
  return v;
}

TEST_F(RawHammerFileTest, RejectsMismatchedResponseSizeNamingTheVariable) {
  const fs::path path = dir_ / "bad.mat";
  WriteVars(path, {{"sample_rate_hz", {{1, 1}, {1000.0}}},
                   {"force", {{32, 2, 1}, Pulse(32, 2)}},
                   {"response", {{32, 3, 3}, Ramp(32 * 3 * 3)}}});
  const std::string message = ReadError(path);
  EXPECT_NE(message.find("bad.mat': response: size 32 x 3 x 3 x 1, expected Ns x Nout x Nhits x "
                         "Nin = 32 x Nout x 2 x 1"),
            std::string::npos)
      << message;
}

TEST_F(RawHammerFileTest, RejectsNaNDeadChannelMissingVariablesAndUnknownQuantity) {
  const fs::path path = dir_ / "bad.mat";
  std::vector<double> response = Ramp(32 * 2 * 2);
  response[40] = std::nan("");
  WriteVars(path, {{"sample_rate_hz", {{1, 1}, {1000.0}}},
                   {"force", {{32, 2}, Pulse(32, 2)}},
                   {"response", {{32, 2, 2}, response}}});
  EXPECT_NE(ReadError(path).find("NaN or Inf"), std::string::npos) << ReadError(path);

  std::vector<double> dead = Ramp(32 * 2 * 2);
  for (std::size_t h = 0; h < 2; ++h) {
    for (std::size_t n = 0; n < 32; ++n) dead[n + 32 * (1 + 2 * h)] = 0.0;
  }
  WriteVars(path, {{"sample_rate_hz", {{1, 1}, {1000.0}}},
                   {"force", {{32, 2}, Pulse(32, 2)}},
                   {"response", {{32, 2, 2}, dead}}});
  EXPECT_NE(ReadError(path).find("'out2' is zero in every hit"), std::string::npos)
      << ReadError(path);

  WriteVars(path, {{"sample_rate_hz", {{1, 1}, {1000.0}}}, {"force", {{32, 2}, Pulse(32, 2)}}});
  EXPECT_NE(ReadError(path).find("response: missing"), std::string::npos) << ReadError(path);

  WriteVars(path, {{"sample_rate_hz", {{1, 1}, {1000.0}}},
                   {"force", {{32, 2}, Pulse(32, 2)}},
                   {"response", {{32, 2, 2}, Ramp(128)}}},
            "force");
  EXPECT_NE(ReadError(path).find("response_quantity: \"force\", expected"), std::string::npos)
      << ReadError(path);

  WriteVars(path, {{"sample_rate_hz", {{1, 1}, {-5.0}}},
                   {"force", {{32, 2}, Pulse(32, 2)}},
                   {"response", {{32, 2, 2}, Ramp(128)}}});
  EXPECT_NE(ReadError(path).find("sample_rate_hz = -5"), std::string::npos) << ReadError(path);

  WriteVars(path, {{"sample_rate_hz", {{1, 1}, {1000.0}}},
                   {"force", {{0, 2}, {}}},
                   {"response", {{32, 2, 2}, Ramp(128)}}});
  EXPECT_NE(ReadError(path).find("force: empty"), std::string::npos) << ReadError(path);
}

TEST_F(RawHammerFileTest, RejectsPartialGeometryAndMissingFile) {
  const RawHammerData data = MakeData(4u);
  const fs::path path = dir_ / "raw.mat";
  WriteRawHammerFile(path, data);
  mat_t* mat = Mat_Open(path.string().c_str(), MAT_ACC_RDWR);
  ASSERT_NE(mat, nullptr);
  Mat_VarDelete(mat, "sensor_direction");
  Mat_Close(mat);
  EXPECT_NE(ReadError(path).find("sensor_direction: missing while"), std::string::npos)
      << ReadError(path);
  EXPECT_NE(ReadError(dir_ / "absent.mat").find("no such file"), std::string::npos);
}

TEST_F(RawHammerFileTest, WriterRejectsUnequalHitCountsAndLeavesNoFile) {
  RawHammerData data = MakeData(5u);
  data.hits[1].pop_back();
  const fs::path path = dir_ / "raw.mat";
  EXPECT_THROW(WriteRawHammerFile(path, data), InputError);
  EXPECT_FALSE(fs::exists(path));
}

}  // namespace
}  // namespace stagefit::measurement
