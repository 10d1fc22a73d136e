#include "stagefit/disturbance/synthesis.h"

#include <gtest/gtest.h>

#include <cmath>

#include "stagefit/common/error.h"
#include "stagefit/disturbance/spectral_density.h"

namespace stagefit::disturbance {
namespace {

// A target with a plateau and a f^-2 fall (ASD f^-1), zero below 1 Hz and above 400 Hz.
PsdTable Target() {
  PsdTable t;
  t.frequency_hz = (Eigen::VectorXd(3) << 1.0, 20.0, 400.0).finished();
  t.psd = (Eigen::VectorXd(3) << 1e-12, 1e-12, 1e-12 * std::pow(20.0 / 400.0, 2)).finished();
  t.name = "target";
  return t;
}

TEST(InterpolatePsd, IsLinearInLogLogAndZeroOutside) {
  PsdTable t;
  t.frequency_hz = (Eigen::VectorXd(2) << 1.0, 100.0).finished();
  t.psd = (Eigen::VectorXd(2) << 1e-10, 1e-14).finished();
  EXPECT_NEAR(InterpolatePsd(t, 10.0), 1e-12, 1e-24);
  EXPECT_DOUBLE_EQ(InterpolatePsd(t, 1.0), 1e-10);
  EXPECT_DOUBLE_EQ(InterpolatePsd(t, 100.0), 1e-14);
  EXPECT_EQ(InterpolatePsd(t, 0.5), 0.0);
  EXPECT_EQ(InterpolatePsd(t, 101.0), 0.0);
  t.frequency_hz[0] = 0.0;  // a zero frequency: linear on that interval
  EXPECT_NEAR(InterpolatePsd(t, 50.0), 0.5 * (1e-10 + 1e-14), 1e-24);
}

TEST(SynthesiseSignal, MeanSquareEqualsTheIntegralOfTheTarget) {
  const PsdTable target = Target();
  SynthesisOptions options{20.0, 1000.0};
  std::mt19937_64 rng(11);
  const Eigen::VectorXd x = SynthesiseSignal(target, options, rng);
  ASSERT_EQ(x.size(), 20000);
  const double df = 1.0 / options.duration_s;
  double integral = 0.0;
  for (int k = 1; k < 10000; ++k) integral += InterpolatePsd(target, k * df) * df;
  constexpr double kRoundOff = 1e-10;  // deterministic amplitudes: equal up to FFT round-off
  EXPECT_NEAR(x.squaredNorm() / x.size(), integral, kRoundOff * integral);
  EXPECT_NEAR(x.mean(), 0.0, 1e-12 * std::sqrt(integral));
}

TEST(SynthesiseSignal, WelchPsdLiesInTheChiSquareBandOfTheTarget) {
  const PsdTable target = Target();
  SynthesisOptions options{400.0, 1000.0};
  std::mt19937_64 rng(12);
  const Eigen::VectorXd x = SynthesiseSignal(target, options, rng);
  WelchOptions welch;
  welch.resolution_hz = 1.0;
  const Spectrum s = EstimatePsd(x, options.sample_rate_hz, welch, "synthetic", "x");
  const PsdConfidenceBand band = CalcPsdConfidenceBand(s.degrees_of_freedom, 0.99);
  int inside = 0, total = 0;
  // Bins within 3 resolution bins of the target's edges (1 Hz, 400 Hz) see Hann leakage of the
  // step to zero and are left out.
  for (Eigen::Index k = 0; k < s.psd.size(); ++k) {
    const double f = s.frequency_hz[k];
    if (f < 4.0 || f > 397.0) continue;
    const double ratio = s.psd[k] / InterpolatePsd(target, f);
    inside += (ratio >= band.lower && ratio <= band.upper) ? 1 : 0;
    ++total;
  }
  EXPECT_GE(inside, 0.95 * total) << inside << " of " << total << " bins in the 99 % band";
  // The overall level: the mean ratio over ~390 bins scatters by ~0.5 %.
  double integral = 0.0;
  for (Eigen::Index k = 1; k < s.psd.size(); ++k) integral += InterpolatePsd(target, s.frequency_hz[k]);
  integral *= s.resolution_hz;
  EXPECT_NEAR(IntegratePsd(s, 0.0, 500.0), integral, 0.03 * integral);
}

TEST(SynthesiseSignal, IsReproducibleForASeedAndHandlesOddLengths) {
  const PsdTable target = Target();
  SynthesisOptions options{1.001, 1000.0};  // 1001 samples
  std::mt19937_64 a(7), b(7), c(8);
  const Eigen::VectorXd xa = SynthesiseSignal(target, options, a);
  const Eigen::VectorXd xb = SynthesiseSignal(target, options, b);
  const Eigen::VectorXd xc = SynthesiseSignal(target, options, c);
  ASSERT_EQ(xa.size(), 1001);
  EXPECT_EQ(xa, xb);
  EXPECT_GT((xa - xc).norm(), 0.1 * xa.norm());
}

TEST(SynthesiseSignal, Gain2ScalesThePsdAtEverySynthesisFrequency) {
  const PsdTable target = Target();
  const SynthesisOptions options{2.0, 1000.0};
  std::mt19937_64 a(9), b(9);
  const Eigen::VectorXd plain = SynthesiseSignal(target, options, a);
  // gain2 = f^2 multiplies each line's amplitude by f_k: the derivative of the signal over 2 pi.
  const Eigen::VectorXd scaled = SynthesiseSignal(target, options, b, [](double f) { return f * f; });
  const double df = 1.0 / options.duration_s;
  double expected = 0.0;
  for (int k = 1; k < 1000; ++k) expected += InterpolatePsd(target, k * df) * (k * df) * (k * df) * df;
  EXPECT_NEAR(scaled.squaredNorm() / scaled.size(), expected, 1e-10 * expected);
  EXPECT_GT(scaled.norm(), plain.norm());
}

TEST(SynthesiseSignal, RejectsBadTablesAndOptions) {
  PsdTable t = Target();
  std::mt19937_64 rng(1);
  t.frequency_hz[1] = 0.5;
  EXPECT_THROW(SynthesiseSignal(t, {1.0, 100.0}, rng), InputError);
  t = Target();
  t.psd[2] = -1.0;
  EXPECT_THROW(SynthesiseSignal(t, {1.0, 100.0}, rng), InputError);
  t = Target();
  EXPECT_THROW(SynthesiseSignal(t, {0.0, 100.0}, rng), InputError);
  EXPECT_THROW(SynthesiseSignal(t, {1.0, -1.0}, rng), InputError);
  EXPECT_THROW(SynthesiseSignal(t, {0.001, 1000.0}, rng), InputError);  // one sample
}

}  // namespace
}  // namespace stagefit::disturbance
