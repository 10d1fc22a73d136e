// The noise floor (docs/error-metric.md §8): the moments of the log error of relative complex Gaussian
// noise against sampling, and the floor against the error of the noise-free truth on noisy data made by
// the independent brute-force generator, in both comparison spaces.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <map>
#include <random>
#include <vector>

#include "stagefit/compare/residuals.h"
#include "stagefit/measurement/hammer_estimation.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace stagefit::compare {
namespace {

// Sample moments of |ln(1 + z)|^2, z ~ CN(0, s^2), with the standard error of the second moment.
struct SampledMoments {
  double m2 = 0, m2_se = 0, m4 = 0;
};
SampledMoments Sample(double s, int n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, s / std::sqrt(2.0));
  double sum = 0, sum_sq = 0;
  for (int k = 0; k < n; ++k) {
    const double e2 = std::norm(std::log(std::complex<double>(1.0 + g(rng), g(rng))));
    sum += e2;
    sum_sq += e2 * e2;
  }
  SampledMoments m;
  m.m2 = sum / n;
  m.m4 = sum_sq / n;
  m.m2_se = std::sqrt((m.m4 - m.m2 * m.m2) / n);
  return m;
}

TEST(ExpectedLogErrorMoments, SmallNoiseIsTheRelativeVariance) {
  // ln(1 + z) = z - z^2/2 + ...: E|.|^2 = s^2 + s^4/2 + O(s^6), E|.|^4 = E|z|^4 = 2 s^4 + O(s^6).
  for (double s : {1e-4, 1e-3, 5e-3}) {
    const LogErrorMoments m = ExpectedLogErrorMoments(s);
    EXPECT_NEAR(m.m2 / (s * s), 1.0 + s * s / 2.0, 1e-9) << s;
    EXPECT_NEAR(m.m4 / (2 * std::pow(s, 4)), 1.0, 1e-3) << s;
  }
  EXPECT_EQ(ExpectedLogErrorMoments(0.0).m2, 0.0);
}

TEST(ExpectedLogErrorMoments, SeriesAndQuadratureMeetWhereTheyHandOver) {
  // Below 0.01 the series, above it the tabulated quadrature: they must agree across the seam.
  const LogErrorMoments below = ExpectedLogErrorMoments(0.0099999), above = ExpectedLogErrorMoments(0.0100001);
  EXPECT_NEAR(above.m2 / below.m2, 1.0, 1e-4);
  EXPECT_NEAR(above.m4 / below.m4, 1.0, 1e-3);
  // Smooth: the interpolated table between two nodes against the series at s = 0.012.
  const double s = 0.012;
  EXPECT_NEAR(ExpectedLogErrorMoments(s).m2 / (s * s * (1 + s * s / 2 + 2 * std::pow(s, 4) / 3)), 1.0, 1e-4);
}

TEST(ExpectedLogErrorMoments, AgreeWithSamplingAtLargeNoise) {
  // Where the logarithm is far from linear (s = 0.3: |z| reaches 1) the quadrature against 400 000 draws.
  uint64_t seed = 11;
  for (double s : {0.05, 0.3, 1.0, 3.0}) {
    const SampledMoments sampled = Sample(s, 400000, seed++);
    const LogErrorMoments m = ExpectedLogErrorMoments(s);
    EXPECT_NEAR(m.m2, sampled.m2, 4 * sampled.m2_se) << "s = " << s;
    EXPECT_NEAR(m.m4 / sampled.m4, 1.0, 0.05) << "s = " << s;
  }
}

// E[min(dof / X, c^2)], X ~ chi-square(dof), against 400 000 draws (the chi-square as a gamma of shape
// dof / 2 and scale 2), below, at and above the cap, down to dof = 2 where the mean of dof / X itself
// is infinite and only the cap bounds it; and its two limits.
TEST(MeanSquareWeightOverSnr, AgreesWithSamplingAndItsLimits) {
  std::mt19937_64 rng(5);
  for (double dof : {2.0, 3.0, 4.0, 8.0, 18.5}) {
    std::gamma_distribution<double> chi2(dof / 2.0, 2.0);
    for (double c : {0.5, 1.0, 3.0, 10.0}) {
      const int n = 400000;
      double sum = 0, sum_sq = 0;
      for (int k = 0; k < n; ++k) {
        const double v = std::min(dof / chi2(rng), c * c);
        sum += v;
        sum_sq += v * v;
      }
      const double mean = sum / n, se = std::sqrt((sum_sq / n - mean * mean) / n);
      EXPECT_NEAR(MeanSquareWeightOverSnr(dof, c), mean, 5 * se + 1e-9) << "dof " << dof << ", c " << c;
    }
  }
  EXPECT_NEAR(MeanSquareWeightOverSnr(8.0, 1e4), 8.0 / 6.0, 1e-6);   // never capped: dof / (dof - 2)
  EXPECT_NEAR(MeanSquareWeightOverSnr(8.0, 1e-3), 1e-6, 1e-12);      // always capped: c^2
}

class NoiseFloorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    truth_ = model::DefaultModelSpec();
    const Eigen::Vector3d p = truth_.frames[model::FindFrame(truth_, truth_.compliance_frame)].origin_W;
    clean_ = synthetic::CalcBruteForceFrf(truth_, synthetic::ComplianceTestSensors("hexapod", p),
                                          synthetic::ComplianceTestImpacts("hexapod", p),
                                          synthetic::LogFrequencies(5.0, 500.0, 200),
                                          measurement::FrfQuantity::kAccelerance);
  }
  measurement::FrfData Noisy(double relative, double absolute, uint64_t seed, bool per_channel = false) const {
    measurement::FrfData data = clean_;
    synthetic::AddNoise(data, {relative, absolute, seed, per_channel});
    return data;
  }
  model::ModelSpec truth_;
  measurement::FrfData clean_;
};

// 20 noise draws at 2 % relative and 1 % absolute noise: the truth's error scatters about the floor
// with the predicted standard deviation. The absolute noise is per element (the element's own RMS) or
// per channel (a sensor's floor, the same for every impact): then the elements the symmetric model
// makes exactly zero are pure noise, with coherence 0, and the floor must still predict the error.
class NoiseFloorModels : public NoiseFloorTest, public ::testing::WithParamInterface<bool> {};

TEST_P(NoiseFloorModels, TheTruthsErrorIsTheFloorInBothSpaces) {
  const bool per_channel = GetParam();
  for (ComparisonSpace space : {ComparisonSpace::kRaw, ComparisonSpace::kCompliance}) {
    ComparisonOptions options;
    options.space = space;
    std::vector<double> z;
    double floor = 0, sd = 0;
    for (uint64_t seed = 1; seed <= 20; ++seed) {
      const Comparison c = Comparison::Create(truth_, Noisy(0.02, 0.01, seed, per_channel), options);
      const NoiseFloor f = c.CalcNoiseFloor();
      ASSERT_TRUE(f.known);
      ASSERT_GT(f.sd, 0.0);
      floor = f.floor;
      sd = f.sd;
      z.push_back((c.Error(truth_) - f.floor) / f.sd);
    }
    double mean = 0, var = 0;
    for (double v : z) mean += v / z.size();
    for (double v : z) var += (v - mean) * (v - mean) / (z.size() - 1);
    SCOPED_TRACE(ToString(space) + ": floor " + std::to_string(floor) + ", sd " + std::to_string(sd));
    // The mean of 20 standardised errors has standard deviation 0.22: within 1 of zero is 4.5 sigma.
    EXPECT_NEAR(mean, 0.0, 1.0);
    // Their spread is the predicted one (the sample variance of 20 draws is within a factor 3 of 1 at
    // more than 99.9 %).
    EXPECT_GT(var, 1.0 / 3.0);
    EXPECT_LT(var, 3.0);
    // The floor is of the order of the relative noise: above 2 % (absolute noise adds), far below 1.
    EXPECT_GT(floor, 0.015);
    EXPECT_LT(floor, 0.2);
  }
}

INSTANTIATE_TEST_SUITE_P(NoiseFloorTest, NoiseFloorModels, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& info) { return info.param ? "PerChannel" : "PerElement"; });

// One raw element measured with coherence 0 at every frequency (a sensor's noise on an element that
// is zero, or a bad pair of channels): it is pure noise, of variance |H_meas|^2. Its weights' variance
// |H|^2 / SNR^2 was infinite and made every projected point weigh 0 (the comparison threw: no usable
// point); with the SNR taken at 1 / cap at least, the other elements still count.
TEST_F(NoiseFloorTest, ARawElementWithCoherenceZeroLeavesTheOthersWeighed) {
  const measurement::FrfData sound = Noisy(0.02, 0.01, 4);
  measurement::FrfData data = sound;
  for (auto& g : data.coherence) g(5, 7) = 0.0;
  const Comparison reference = Comparison::Create(truth_, sound), c = Comparison::Create(truth_, data);
  EXPECT_GT(c.num_points(), 0.9 * reference.num_points());
  const NoiseFloor f = c.CalcNoiseFloor();
  ASSERT_TRUE(f.known);
  EXPECT_NEAR(c.Error(truth_), f.floor, 4 * f.sd);
}

// FRFs estimated from raw hammer records of n hits per impact (the brute-force generator's time data,
// noise 0.5 % of each channel's RMS per hit, through measurement::EstimateFrf): the file's coherence is
// the ordinary coherence of the n hits, and with their number (FrfData::averages) the noise-free truth
// is at its floor. The floor counts that each weight is an SNR estimated from the same n hits (the
// inverse of a variance of 2 (n - 1) degrees of freedom averages (n - 1) / (n - 2) times the true one,
// pooled through the projection in compliance space): without that the truth sat 1.21 x its floor in
// raw space with 5 hits. What is left: the generator's hits differ in force by up to 20 %, their noise
// is a share of each hit's RMS, and H1 weighs the strong hits, which the pooled residual does not (2.6 %
// in the error), so within 7 % in compliance space and 12 % in raw space. Read as the estimate's own
// coherence (no count), the ordinary coherence put the floor sqrt(n - 1) times too high: the truth at
// about 0.6 x its floor for 5 hits, 0.4 x for 10.
TEST_F(NoiseFloorTest, EstimatedFromHitsTheTruthIsAtItsFloor) {
  const Eigen::Vector3d p = truth_.frames[model::FindFrame(truth_, truth_.compliance_frame)].origin_W;
  for (int hits : {5, 10}) {
    std::map<ComparisonSpace, double> with_count, without_count;
    const int draws = 3;
    for (int d = 0; d < draws; ++d) {
      synthetic::RawHammerOptions raw_options;
      raw_options.hits_per_impact = hits;
      raw_options.seed = 500 + 10 * hits + d;
      const measurement::RawHammerData raw =
          synthetic::MakeRawHammerTest(truth_, synthetic::ComplianceTestSensors("hexapod", p),
                                       synthetic::ComplianceTestImpacts("hexapod", p), raw_options);
      measurement::EstimationOptions estimation;
      estimation.min_frequency_hz = 10.0;
      estimation.max_frequency_hz = 400.0;
      measurement::FrfData data = measurement::EstimateFrf(raw, estimation).frf;
      ASSERT_EQ(data.averages, std::vector<int>(data.num_inputs(), hits));
      measurement::FrfData uncounted = data;
      uncounted.averages.clear();
      for (ComparisonSpace space : {ComparisonSpace::kCompliance, ComparisonSpace::kRaw}) {
        ComparisonOptions options;
        options.space = space;
        const Comparison c = Comparison::Create(truth_, data, options), old = Comparison::Create(truth_, uncounted, options);
        with_count[space] += c.Error(truth_) / c.CalcNoiseFloor().floor / draws;
        without_count[space] += old.Error(truth_) / old.CalcNoiseFloor().floor / draws;
      }
    }
    for (ComparisonSpace space : {ComparisonSpace::kCompliance, ComparisonSpace::kRaw}) {
      SCOPED_TRACE(std::to_string(hits) + " hits, " + ToString(space) + ": truth over floor " +
                   std::to_string(with_count[space]) + " with the count, " + std::to_string(without_count[space]) +
                   " without");
      EXPECT_GT(with_count[space], 0.97);
      EXPECT_LT(with_count[space], space == ComparisonSpace::kCompliance ? 1.07 : 1.12);
      EXPECT_LT(without_count[space], 0.7);
    }
  }
}

TEST_F(NoiseFloorTest, AWrongModelIsManyTimesAboveTheFloor) {
  const Comparison c = Comparison::Create(truth_, Noisy(0.01, 0.005, 3));
  model::ModelSpec soft = truth_;
  const auto params = model::MatchParameters(soft, {"hexapod.k.Dz"});
  ASSERT_EQ(params.size(), 1u);
  model::SetParameter(soft, params[0], 0.7 * model::GetParameter(soft, params[0]));
  const NoiseFloor f = c.CalcNoiseFloor();
  EXPECT_LT(c.Error(truth_), 1.5 * f.floor);
  EXPECT_GT(c.Error(soft), 3.0 * f.floor);
}

TEST_F(NoiseFloorTest, UnknownWithoutCoherenceAndZeroForNoiseFreeData) {
  measurement::FrfData data = Noisy(0.01, 0.0, 4);
  data.coherence.clear();
  EXPECT_FALSE(Comparison::Create(truth_, data).CalcNoiseFloor().known);
  EXPECT_NE(NoiseFloorLine(0.1, Comparison::Create(truth_, data).CalcNoiseFloor()).find("unknown"), std::string::npos);

  measurement::FrfData clean = clean_;
  clean.coherence.assign(clean.num_frequencies(), Eigen::MatrixXd::Ones(clean.num_outputs(), clean.num_inputs()));
  const NoiseFloor f = Comparison::Create(truth_, clean).CalcNoiseFloor();
  EXPECT_TRUE(f.known);
  EXPECT_EQ(f.floor, 0.0);
}

TEST(NoiseFloorLine, SaysHowManyTimesAboveTheFloor) {
  NoiseFloor f;
  f.known = true;
  f.floor = 0.02;
  f.sd = 0.0002;
  const std::string line = NoiseFloorLine(0.05, f);
  EXPECT_NE(line.find("noise floor 0.02000"), std::string::npos) << line;
  EXPECT_NE(line.find("2.50 x floor"), std::string::npos) << line;
}

}  // namespace
}  // namespace stagefit::compare
