#include "stagefit/compare/mode_pairing.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <random>

#include "compare_test_util.h"
#include "stagefit/common/error.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"

namespace stagefit::compare {
namespace {

using testing::LogFrequencies;
using testing::MakeSyntheticMeasurement;

constexpr double kTwoPi = 6.283185307179586;

// Receptance of a single DoF: 1 / (k - m w^2 + j c w).
std::vector<Eigen::MatrixXcd> SdofReceptance(const Eigen::VectorXd& f, double fn_hz, double zeta) {
  const double m = 2.0, wn = kTwoPi * fn_hz, k = m * wn * wn, c = 2.0 * zeta * m * wn;
  std::vector<Eigen::MatrixXcd> H;
  for (int i = 0; i < f.size(); ++i) {
    const double w = kTwoPi * f(i);
    H.push_back(Eigen::MatrixXcd::Constant(1, 1, 1.0 / std::complex<double>(k - m * w * w, c * w)));
  }
  return H;
}

TEST(IdentifyModes, RecoversFrequencyAndDampingOfASingleDof) {
  const Eigen::VectorXd f = Eigen::VectorXd::LinSpaced(2001, 20.0, 120.0);  // 0.05 Hz steps
  const auto modes = IdentifyModes(f, SdofReceptance(f, 50.0, 0.02));
  ASSERT_EQ(modes.size(), 1u);
  // Receptance peaks at fn sqrt(1 - 2 zeta^2) (0.04 % below fn); parabolic refinement on 0.05 Hz steps
  // is much finer than that.
  EXPECT_NEAR(modes[0].frequency_hz, 50.0 * std::sqrt(1 - 2 * 0.02 * 0.02), 0.005);
  // Half-power bandwidth: 2 zeta to O(zeta^2) (0.04 %), plus the linear interpolation of the
  // crossings over 0.05 Hz steps of a 2 Hz bandwidth: 1 % covers both.
  EXPECT_NEAR(modes[0].damping_ratio, 0.02, 0.02 * 0.01);
}

TEST(IdentifyModes, IgnoresPeaksBelowTheProminenceThreshold) {
  const Eigen::VectorXd f = Eigen::VectorXd::LinSpaced(401, 20.0, 120.0);
  auto H = SdofReceptance(f, 50.0, 0.02);
  ModeIdentificationOptions options;
  options.min_prominence = 1e6;
  EXPECT_TRUE(IdentifyModes(f, H, options).empty());
  options.min_prominence = 0.5;
  EXPECT_THROW(IdentifyModes(f, H, options), InputError);
}

TEST(IdentifyModes, DropsPeaksTheNoiseCanMakeWhenGivenTheSnr) {
  // A fine grid whose low end is noisy (SNR 4, as an accelerance's low end), the mode at 100 Hz clean.
  const int nf = 1000;
  Eigen::VectorXd f(nf), snr(nf);
  for (int k = 0; k < nf; ++k) f(k) = 10.0 * std::pow(20.0, k / (nf - 1.0));  // 10-200 Hz
  auto H = SdofReceptance(f, 100.0, 0.02);
  std::mt19937_64 generator(3);
  std::normal_distribution<double> normal;
  for (int k = 0; k < nf; ++k) {
    snr(k) = f(k) < 40.0 ? 4.0 : 30.0;
    const double sigma = 1.0 / snr(k) / std::sqrt(2.0);  // per real and imaginary part
    H[k](0, 0) *= std::complex<double>(1.0 + sigma * normal(generator), sigma * normal(generator));
  }
  // The noise alone makes peaks of sqrt(2) prominence...
  ASSERT_GT(IdentifyModes(f, H).size(), 3u);
  // ...which the noise rule drops, keeping the mode.
  const auto modes = IdentifyModes(f, H, {}, snr);
  ASSERT_EQ(modes.size(), 1u);
  EXPECT_NEAR(modes[0].frequency_hz, 100.0, 1.0);
  EXPECT_THROW(IdentifyModes(f, H, {}, snr.head(10)), InputError);
}

TEST(CalcMac, IsOneForParallelAndZeroForOrthogonalVectors) {
  Eigen::VectorXcd a(3), b(3);
  a << 1.0, std::complex<double>(0.0, 2.0), -0.5;
  EXPECT_NEAR(CalcMac(a, std::complex<double>(0.3, -1.2) * a), 1.0, 1e-15);
  b << std::complex<double>(0.0, 2.0), 1.0, 0.0;  // a^H b = 2j - 2j = 0
  EXPECT_NEAR(CalcMac(a, b), 0.0, 1e-15);
  EXPECT_EQ(CalcMac(a, Eigen::VectorXcd::Zero(3)), 0.0);
}

TEST(PairModes, PairsEveryModeWithItselfForTheModelsOwnFrf) {
  const model::ModelSpec spec = model::DefaultModelSpec();
  const auto data = MakeSyntheticMeasurement(spec, LogFrequencies(5.0, 500.0, 800));
  const Comparison comparison = Comparison::Create(spec, data);
  const ModePairing pairing = PairModes(comparison, comparison.EvaluateModel(spec), spec);
  ASSERT_GE(pairing.measured.size(), 3u);
  EXPECT_EQ(pairing.pairs.size(), pairing.measured.size());
  EXPECT_TRUE(pairing.unpaired_measured.empty());
  EXPECT_TRUE(pairing.unpaired_model.empty());
  for (const auto& p : pairing.pairs) {
    EXPECT_EQ(p.measured, p.model);
    EXPECT_NEAR(p.mac, 1.0, 1e-9);
    EXPECT_NEAR(p.frequency_error, 0.0, 1e-9);
    // The CMIF peak lies near a natural frequency of the model.
    const auto& m = pairing.model[p.model];
    EXPECT_LT(std::abs(std::log(m.frequency_hz / m.model_frequency_hz)), 0.05) << m.frequency_hz;
  }
  EXPECT_FALSE(pairing.BriefReport().empty());
}

TEST(PairModes, ReportsTheFrequencyShiftOfASofterModel) {
  const model::ModelSpec spec = model::DefaultModelSpec();
  const auto data = MakeSyntheticMeasurement(spec, LogFrequencies(5.0, 500.0, 800));
  const Comparison comparison = Comparison::Create(spec, data);
  // Every stiffness 0.81 times: every natural frequency 0.9 times, shapes unchanged.
  model::ModelSpec softer = spec;
  for (const auto& p : model::MatchParameters(softer, {"*.k.*"})) {
    model::SetParameter(softer, p, 0.81 * model::GetParameter(softer, p));
  }
  const ModePairing pairing = PairModes(comparison, comparison.EvaluateModel(softer), softer);
  ASSERT_FALSE(pairing.pairs.empty());
  for (const auto& p : pairing.pairs) {
    EXPECT_GT(p.mac, 0.9);
    // 2 % covers the grid's resolution (0.6 % steps refined by the parabola) and the damping's shift
    // of the peak (the damping is unchanged while the stiffness falls).
    EXPECT_NEAR(p.frequency_error, -0.1, 0.02);
  }
}

}  // namespace
}  // namespace stagefit::compare
