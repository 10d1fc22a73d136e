#include "stagefit/disturbance/straightness.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "stagefit/common/error.h"
#include "stagefit/disturbance/synthesis.h"

namespace stagefit::disturbance {
namespace {

constexpr double kHalfStroke = 4.5e-3;  // m
constexpr int kPoints = 9001;           // 1 um step

// Random straightness error: spatial PSD falling as nu^-2 from 1e3 to 5e4 cycles/m (wavelengths
// 1 mm to 20 um, at least 9 per stroke), ~100 nm rms.
Eigen::VectorXd RandomPart(uint64_t seed) {
  PsdTable t;
  t.frequency_hz = (Eigen::VectorXd(2) << 1e3, 5e4).finished();
  t.psd = (Eigen::VectorXd(2) << 1e-17, 1e-17 * std::pow(1e3 / 5e4, 2)).finished();
  std::mt19937_64 rng(seed);
  const double length = 2 * kHalfStroke * kPoints / (kPoints - 1.0);
  return SynthesiseSignal(t, {length, (kPoints - 1) / (2 * kHalfStroke)}, rng);
}

TEST(AnalyseStraightness, RemovesAKnownTiltAndKeepsTheRandomPart) {
  const Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(kPoints, -kHalfStroke, kHalfStroke);
  const Eigen::VectorXd r = RandomPart(31);
  constexpr double kTilt = 25e-6;    // rad
  constexpr double kOffset = 2e-7;   // m
  const Eigen::VectorXd e = (kOffset + kTilt * x.array()).matrix() + r;
  const StraightnessSummary s = AnalyseStraightness(x, e, {}, "scan.csv", "vertical_m");

  // The line fitted to e is the tilt plus the line that least squares finds in r itself; compute
  // the latter independently (closed form on the centred positions).
  const Eigen::VectorXd xc = x.array() - x.mean();
  const double slope_of_r = xc.dot(r) / xc.squaredNorm();
  const double offset_of_r = r.mean() - slope_of_r * x.mean();
  constexpr double kRoundOff = 1e-12;
  EXPECT_NEAR(s.slope_rad, kTilt + slope_of_r, kRoundOff * kTilt);
  EXPECT_NEAR(s.offset_m, kOffset + offset_of_r, 1e-18);
  // The random part's own tilt is bounded: a component of amplitude A and wavelength lambda fakes at
  // most about 12 A lambda / (2 pi L^2) over a stroke L, 3 urad for 140 nm at 1 mm over 9 mm, and the
  // shorter wavelengths add less; the recovered tilt is within 4 urad of the true one.
  EXPECT_NEAR(s.slope_rad, kTilt, 4e-6);
  const Eigen::VectorXd expected_residual =
      r - (offset_of_r + slope_of_r * x.array()).matrix();
  EXPECT_LT((s.residual_m - expected_residual).cwiseAbs().maxCoeff(), 1e-17);
  EXPECT_GT(s.residual_rms_m, 50e-9);
  EXPECT_LT(s.residual_rms_m, 150e-9);
  EXPECT_FALSE(s.temporal);
  // Spatial PSD: the variance of the residual (its mean is zero) is the integral of the PSD; the
  // default segments (about 2 mm, 500 cycles/m resolution) hold every wavelength of the random part,
  // and 8 averages over ~50 bins leave a few % of scatter: within 15 %.
  EXPECT_NEAR(IntegratePsd(s.psd, 0.0, 1e9), s.residual_rms_m * s.residual_rms_m,
              0.15 * s.residual_rms_m * s.residual_rms_m);
}

TEST(AnalyseStraightness, ScanSpeedTurnsSpatialIntoTemporalFrequency) {
  const Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(kPoints, -kHalfStroke, kHalfStroke);
  const Eigen::VectorXd e = RandomPart(32);
  StraightnessOptions spatial;
  StraightnessOptions temporal;
  constexpr double kSpeed = 1e-3;  // m/s
  temporal.scan_speed_m_s = kSpeed;
  const StraightnessSummary a = AnalyseStraightness(x, e, spatial, "scan", "e");
  const StraightnessSummary b = AnalyseStraightness(x, e, temporal, "scan", "e");
  ASSERT_TRUE(b.temporal);
  ASSERT_EQ(a.psd.psd.size(), b.psd.psd.size());
  for (Eigen::Index k = 0; k < a.psd.psd.size(); k += 50) {
    EXPECT_NEAR(b.psd.frequency_hz[k], kSpeed * a.psd.frequency_hz[k], 1e-12 * b.psd.frequency_hz[k] + 1e-15);
    EXPECT_NEAR(b.psd.psd[k], a.psd.psd[k] / kSpeed, 1e-9 * a.psd.psd[k] / kSpeed);
  }
}

TEST(AnalyseStraightness, UnevenPositionsAreResampled) {
  constexpr int kN = 200;
  Eigen::VectorXd x(kN), e(kN);
  std::mt19937_64 rng(33);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  for (int i = 0; i < kN; ++i) {
    x[i] = (i + (i > 0 && i < kN - 1 ? jitter(rng) : 0.0)) * 1e-5;
    e[i] = 1e-7 - 3e-5 * x[i];  // a pure line: linear interpolation reproduces it
  }
  const StraightnessSummary s = AnalyseStraightness(x, e, {}, "scan", "e");
  EXPECT_NEAR(s.slope_rad, -3e-5, 1e-15);
  EXPECT_LT(s.residual_m.cwiseAbs().maxCoeff(), 1e-18);
  EXPECT_NEAR(s.position_m[1] - s.position_m[0], (x[kN - 1] - x[0]) / (kN - 1), 1e-18);
}

TEST(AnalyseStraightness, RejectsBadRecords) {
  Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(100, 0.0, 1e-3);
  Eigen::VectorXd e = Eigen::VectorXd::Zero(100);
  x[50] = x[49];
  EXPECT_THROW(AnalyseStraightness(x, e, {}, "scan", "e"), InputError);
  x = Eigen::VectorXd::LinSpaced(100, 0.0, 1e-3);
  EXPECT_THROW(AnalyseStraightness(x, e.head(50), {}, "scan", "e"), InputError);
  e[3] = NAN;
  EXPECT_THROW(AnalyseStraightness(x, e, {}, "scan", "e"), InputError);
  e[3] = 0.0;
  StraightnessOptions o;
  o.scan_speed_m_s = -1.0;
  EXPECT_THROW(AnalyseStraightness(x, e, o, "scan", "e"), InputError);
}

}  // namespace
}  // namespace stagefit::disturbance
