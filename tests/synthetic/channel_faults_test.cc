#include "stagefit/synthetic/channel_faults.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>

#include "stagefit/model/model_file.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace stagefit::synthetic {
namespace {

measurement::FrfData Data() {
  HiddenEffectOptions o;
  o.num_effects = 0;
  o.num_frequencies = 120;
  return MakeHiddenEffectCase(model::DefaultModelSpec(), 3, o).measurement;
}

TEST(ChannelFaults, ReversedNegatesOneRowOrColumn) {
  const auto d0 = Data();
  auto d = d0;
  InjectReversed(d, "a2x", false);
  InjectReversed(d, "h5", true);
  for (int k = 0; k < d.num_frequencies(); ++k)
    for (int i = 0; i < 12; ++i)
      for (int j = 0; j < 10; ++j) {
        const double s = (i == 3 ? -1.0 : 1.0) * (j == 4 ? -1.0 : 1.0);
        EXPECT_EQ(d.frf[k](i, j), s * d0.frf[k](i, j));
      }
}

TEST(ChannelFaults, SwapExchangesDataAndCoherenceNotNames) {
  const auto d0 = Data();
  auto d = d0;
  InjectSwapped(d, "a1x", "a3y", false);
  EXPECT_EQ(d.outputs[0].name, "a1x");
  for (int k = 0; k < d.num_frequencies(); ++k) {
    EXPECT_EQ(d.frf[k].row(0), d0.frf[k].row(7));
    EXPECT_EQ(d.frf[k].row(7), d0.frf[k].row(0));
    EXPECT_EQ(d.coherence[k].row(0), d0.coherence[k].row(7));
  }
}

TEST(ChannelFaults, DeadIsNoiseOfTheGivenLevelWithLowCoherence) {
  const auto d0 = Data();
  auto d = d0;
  InjectDead(d, "a4z", 1e-2, 7);
  double e0 = 0, e = 0;
  int n = 0;
  for (int k = 0; k < d.num_frequencies(); ++k) {
    e0 += d0.frf[k].row(11).squaredNorm();
    e += d.frf[k].row(11).squaredNorm();
    n += 10;
    EXPECT_LE(d.coherence[k].row(11).maxCoeff(), 0.05);
    EXPECT_EQ(d.frf[k].row(10), d0.frf[k].row(10));
  }
  // Mean |noise|^2 = (1e-2)^2 times the row's mean |H|^2, to the sampling error of 1200 draws.
  EXPECT_NEAR(e / e0, 1e-4, 1e-4 * 0.15);
}

TEST(ChannelFaults, ClipKeepsPhaseAndCapsMagnitude) {
  const auto d0 = Data();
  auto d = d0;
  InjectClipped(d, "a1y", 0.4);
  double mx = 0;
  for (const auto& h : d0.frf) mx = std::max(mx, h.row(1).cwiseAbs().maxCoeff());
  for (int k = 0; k < d.num_frequencies(); ++k)
    for (int j = 0; j < 10; ++j) {
      const auto a = d0.frf[k](1, j), b = d.frf[k](1, j);
      EXPECT_LE(std::abs(b), 0.4 * mx * (1 + 1e-12));
      if (std::abs(a) <= 0.4 * mx) EXPECT_EQ(a, b);
      else EXPECT_NEAR(std::arg(a), std::arg(b), 1e-12);
    }
}

TEST(ChannelFaults, LocalResonanceIsTheMountTransmissibility) {
  auto d0 = Data();
  auto d = d0;
  const double fn = 80.0, q = 10.0;
  InjectLocalResonance(d, "a2y", fn, q);
  for (int k = 0; k < d.num_frequencies(); ++k) {
    // Hand form: T = (1 + j r/Q) / (1 - r^2 + j r/Q), |T(fn)| = sqrt(1 + Q^2).
    const double r = d.frequency_hz(k) / fn;
    const std::complex<double> t = std::complex<double>(1.0, r / q) / std::complex<double>(1.0 - r * r, r / q);
    for (int j = 0; j < 10; ++j) EXPECT_LT(std::abs(d.frf[k](4, j) - t * d0.frf[k](4, j)), 1e-12 * std::abs(d0.frf[k](4, j)) + 1e-300);
  }
  measurement::FrfData one = d0;
  one.frequency_hz.resize(1);
  one.frequency_hz(0) = fn;
  one.frf.resize(1);
  one.frf[0] = Eigen::MatrixXcd::Ones(12, 10);
  one.coherence.resize(1);
  InjectLocalResonance(one, "a2y", fn, q);
  EXPECT_NEAR(std::abs(one.frf[0](4, 0)), std::sqrt(1 + q * q), 1e-12);
}

TEST(ChannelFaults, RandomFaultsNameWhatTheyInject) {
  std::mt19937_64 rng(5);
  for (int kind = 0; kind < 5; ++kind) {
    auto d = Data();
    const auto f = InjectRandomFault(d, static_cast<measurement::ChannelFaultKind>(kind), rng);
    EXPECT_EQ(static_cast<int>(f.kind), kind);
    EXPECT_EQ(f.channels.size(), kind == 1 ? 2u : 1u);
    EXPECT_FALSE(f.description.empty());
  }
}

}  // namespace
}  // namespace stagefit::synthetic
