#pragma once
// Seeded measurement data and error-message checks shared by the measurement file tests.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <functional>
#include <random>
#include <string>

#include "stagefit/common/error.h"
#include "stagefit/measurement/frf_data.h"

namespace stagefit::measurement::testing {

/// Nout = 3 sensors on the hexapod, Nin = 2 impacts, Nf = 11 uneven frequencies, with coherence;
/// every value drawn from a generator seeded with `seed`.
inline FrfData MakeMeasurement(unsigned seed, bool with_geometry = true) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  FrfData d;
  d.source = "generated";
  d.quantity = FrfQuantity::kMobility;
  const int nf = 11, nout = 3, nin = 2;
  d.frequency_hz.resize(nf);
  double f = 0.5;
  for (int k = 0; k < nf; ++k) d.frequency_hz[k] = (f += 0.1 + std::abs(u(rng)) * 7.3);
  for (int k = 0; k < nf; ++k) {
    Eigen::MatrixXcd h(nout, nin);
    Eigen::MatrixXd c(nout, nin);
    for (int i = 0; i < h.size(); ++i) {
      h.data()[i] = {u(rng) * std::exp(5.0 * u(rng)), u(rng) * 1e-3};
      c.data()[i] = 0.5 + 0.5 * std::abs(u(rng));
    }
    d.frf.push_back(h);
    d.coherence.push_back(c);
  }
  const char* outs[] = {"a1x", "a1y", "a 2,z"};
  for (int i = 0; i < nout; ++i) {
    ChannelGeometry c;
    c.name = outs[i];
    if (with_geometry) {
      c.body = "hexapod";
      c.position_W = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 0.14;
      c.direction_W = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    }
    d.outputs.push_back(c);
  }
  for (int j = 0; j < nin; ++j) {
    ChannelGeometry c;
    c.name = "h" + std::to_string(j + 1);
    if (with_geometry) {
      c.body = j == 0 ? "hexapod" : "rz";
      c.position_W = Eigen::Vector3d(u(rng), u(rng), u(rng));
      c.direction_W = -Eigen::Vector3d::Unit(j);
    }
    d.inputs.push_back(c);
  }
  if (with_geometry) d.frame_origin_W = Eigen::Vector3d(0.0, 0.0, -0.03);
  return d;
}

/// Exact equality of everything a file stores.
inline void ExpectSameMeasurement(const FrfData& a, const FrfData& b) {
  EXPECT_EQ(a.quantity, b.quantity);
  EXPECT_EQ(a.frequency_hz, b.frequency_hz);
  ASSERT_EQ(a.num_outputs(), b.num_outputs());
  ASSERT_EQ(a.num_inputs(), b.num_inputs());
  for (int k = 0; k < a.num_frequencies(); ++k) EXPECT_EQ(a.frf[k], b.frf[k]) << "frequency " << k;
  ASSERT_EQ(a.has_coherence(), b.has_coherence());
  for (std::size_t k = 0; k < a.coherence.size(); ++k) EXPECT_EQ(a.coherence[k], b.coherence[k]);
  EXPECT_EQ(a.averages, b.averages);
  auto same = [](const ChannelGeometry& x, const ChannelGeometry& y) {
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.body, y.body);
    if (x.has_geometry()) {
      EXPECT_EQ(x.position_W, y.position_W) << x.name;
      EXPECT_EQ(x.direction_W, y.direction_W) << x.name;
    }
  };
  for (int i = 0; i < a.num_outputs(); ++i) same(a.outputs[i], b.outputs[i]);
  for (int j = 0; j < a.num_inputs(); ++j) same(a.inputs[j], b.inputs[j]);
  EXPECT_EQ(a.frame_origin_W.has_value(), b.frame_origin_W.has_value());
  if (a.frame_origin_W && b.frame_origin_W) {
    EXPECT_EQ(*a.frame_origin_W, *b.frame_origin_W);
  }
}

/// Runs `f` and checks that it throws InputError whose message contains `fragment`.
inline void ExpectInputError(const std::function<void()>& f, const std::string& fragment) {
  try {
    f();
    ADD_FAILURE() << "expected InputError containing '" << fragment << "'";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos)
        << "message: " << e.what() << "\nexpected fragment: " << fragment;
  }
}

/// A fresh folder under the system's temporary folder, removed by the caller.
inline std::filesystem::path MakeTempDir(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() /
             ("stagefit_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace stagefit::measurement::testing
