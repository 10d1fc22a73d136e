#include "stagefit/disturbance/force_psd.h"

#include <gtest/gtest.h>

#include <cmath>

#include "stagefit/common/error.h"

namespace stagefit::disturbance {
namespace {

Spectrum Bins(int count, double df) {
  Spectrum s;
  s.frequency_hz = Eigen::VectorXd::LinSpaced(count, 0.0, (count - 1) * df);
  s.psd = Eigen::VectorXd::Zero(count);
  s.resolution_hz = df;
  return s;
}

// Compliance of a mass-spring-damper, m/N.
std::complex<double> Compliance(double f) {
  constexpr double kMass = 10.0, kStiffness = 4e6, kDamping = 400.0;
  const double w = 2 * M_PI * f;
  return 1.0 / std::complex<double>(kStiffness - kMass * w * w, kDamping * w);
}

TEST(EstimateForcePsd, InvertsAKnownSensitivity) {
  Spectrum motion = Bins(1001, 0.5);
  Eigen::VectorXcd h(motion.psd.size());
  Eigen::VectorXd force(motion.psd.size());
  for (Eigen::Index k = 0; k < motion.psd.size(); ++k) {
    const double f = motion.frequency_hz[k];
    h[k] = Compliance(f);
    force[k] = 1e-2 / (1.0 + f / 50.0);  // N^2/Hz
    motion.psd[k] = force[k] * std::norm(h[k]);
  }
  const ForcePsdSummary s = EstimateForcePsd(motion, h, {}, "test");
  constexpr double kRoundOff = 1e-12;
  for (Eigen::Index k = 0; k < force.size(); ++k) {
    EXPECT_NEAR(s.force_psd.psd[k], force[k], kRoundOff * force[k]) << k;
  }
  // Above resonance (~100 Hz) the compliance falls as f^-2: at 500 Hz it is ~1/600 of the peak,
  // above the default 1e-3 threshold, so nothing is flagged.
  EXPECT_TRUE(s.warnings.empty()) << s.BriefReport();
  EXPECT_EQ(s.force_psd.frequency_hz, motion.frequency_hz);
}

TEST(EstimateForcePsd, FlagsBandsWhereTheSensitivityVanishes) {
  Spectrum motion = Bins(101, 1.0);
  motion.psd.setConstant(1e-18);
  Eigen::VectorXcd h = Eigen::VectorXcd::Constant(101, std::complex<double>(1e-8, 0.0));
  h.segment(40, 5).setConstant(1e-13);  // an antiresonance, 1e-5 of the peak
  h[70] = 0.0;
  const ForcePsdSummary s = EstimateForcePsd(motion, h, {}, "test");
  ASSERT_EQ(s.warnings.size(), 2u) << s.BriefReport();
  EXPECT_NE(s.warnings[0].find("from 40 to 44 Hz"), std::string::npos) << s.warnings[0];
  EXPECT_NE(s.warnings[1].find("from 70 to 70 Hz"), std::string::npos) << s.warnings[1];
  EXPECT_FALSE(s.reliable[42]);
  EXPECT_TRUE(s.reliable[45]);
  EXPECT_TRUE(std::isnan(s.force_psd.psd[70]));
  EXPECT_NEAR(s.force_psd.psd[10], 1e-2, 1e-14);
}

TEST(EstimateForcePsd, RejectsMismatchedOrInvalidInput) {
  Spectrum motion = Bins(10, 1.0);
  EXPECT_THROW(EstimateForcePsd(motion, Eigen::VectorXcd::Ones(9), {}, "t"), InputError);
  EXPECT_THROW(EstimateForcePsd(motion, Eigen::VectorXcd::Zero(10), {}, "t"), InputError);
  Eigen::VectorXcd h = Eigen::VectorXcd::Ones(10);
  h[3] = std::complex<double>(NAN, 0.0);
  EXPECT_THROW(EstimateForcePsd(motion, h, {}, "t"), InputError);
  motion.psd[2] = -1.0;
  EXPECT_THROW(EstimateForcePsd(motion, Eigen::VectorXcd::Ones(10), {}, "t"), InputError);
  motion.psd[2] = 0.0;
  ForcePsdOptions options;
  options.min_relative_sensitivity = 1.5;
  EXPECT_THROW(EstimateForcePsd(motion, Eigen::VectorXcd::Ones(10), options, "t"), InputError);
}

}  // namespace
}  // namespace stagefit::disturbance
