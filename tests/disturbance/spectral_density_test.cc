#include "stagefit/disturbance/spectral_density.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <random>
#include <string>

#include "stagefit/common/error.h"

namespace stagefit::disturbance {
namespace {

Eigen::VectorXd WhiteNoise(int n, double sigma, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, sigma);
  Eigen::VectorXd x(n);
  for (int i = 0; i < n; ++i) x[i] = normal(rng);
  return x;
}

// Throws and the message contains every fragment.
template <typename F>
void ExpectInputError(F&& f, std::initializer_list<std::string> fragments) {
  try {
    f();
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    for (const std::string& s : fragments) {
      EXPECT_NE(std::string(e.what()).find(s), std::string::npos) << e.what() << " lacks " << s;
    }
  }
}

TEST(EstimatePsd, ParsevalIsExactWithRectangularWindow) {
  constexpr int kSegment = 256;
  constexpr int kAverages = 16;
  constexpr double kRate = 500.0;
  const Eigen::VectorXd x = WhiteNoise(kSegment * kAverages, 3.0, 1);
  WelchOptions options;
  options.segment_length = kSegment;
  options.overlap = 0.0;
  options.window = Window::kRectangular;
  const Spectrum s = EstimatePsd(x, kRate, options, "white", "x");
  ASSERT_EQ(s.averages, kAverages);
  double expected = 0.0;  // mean over segments of the segment's variance
  for (int m = 0; m < kAverages; ++m) {
    const Eigen::VectorXd seg = x.segment(m * kSegment, kSegment);
    expected += (seg.array() - seg.mean()).square().sum() / kSegment / kAverages;
  }
  constexpr double kRoundOff = 1e-12;  // sums of 4096 squares in double precision
  EXPECT_NEAR(IntegratePsd(s, 0.0, kRate), expected, kRoundOff * expected);
  EXPECT_DOUBLE_EQ(s.degrees_of_freedom, 2.0 * kAverages);
  EXPECT_DOUBLE_EQ(s.resolution_hz, kRate / kSegment);
  EXPECT_EQ(s.frequency_hz.size(), kSegment / 2 + 1);
  EXPECT_DOUBLE_EQ(s.frequency_hz[kSegment / 2], kRate / 2);
}

TEST(EstimatePsd, HannEstimateOfWhiteNoiseHasItsVarianceAndLevel) {
  constexpr double kSigma = 2.0;
  constexpr double kRate = 1000.0;
  const Eigen::VectorXd x = WhiteNoise(1 << 17, kSigma, 2);
  WelchOptions options;
  options.resolution_hz = 1.0;
  const Spectrum s = EstimatePsd(x, kRate, options, "white", "x");
  // With 2^17 samples the variance estimate scatters by about sqrt(2/2^17) = 0.4 %; 2 % is 5 sigma.
  constexpr double kStatisticalTolerance = 0.02;
  const double variance = kSigma * kSigma;
  EXPECT_NEAR(IntegratePsd(s, 0.0, kRate), variance, kStatisticalTolerance * variance);
  const double level = 2.0 * variance / kRate;
  const double mean_level = s.psd.segment(1, s.psd.size() - 2).mean();
  EXPECT_NEAR(mean_level, level, kStatisticalTolerance * level);
  EXPECT_NEAR(s.enbw_hz, 1.5 * s.resolution_hz, 1e-9);  // Hann: ENBW = 1.5 bins
}

TEST(EstimatePsd, WhiteNoiseBinsFallInTheChiSquareBand) {
  constexpr double kSigma = 1.0;
  constexpr double kRate = 200.0;
  const Eigen::VectorXd x = WhiteNoise(200 * 600, kSigma, 3);
  WelchOptions options;
  options.resolution_hz = 0.5;
  const Spectrum s = EstimatePsd(x, kRate, options, "white", "x");
  const PsdConfidenceBand band = CalcPsdConfidenceBand(s.degrees_of_freedom, 0.99);
  const double level = 2.0 * kSigma * kSigma / kRate;
  int inside = 0, total = 0;
  for (Eigen::Index k = 1; k + 1 < s.psd.size(); ++k, ++total) {
    const double ratio = s.psd[k] / level;
    inside += (ratio >= band.lower && ratio <= band.upper) ? 1 : 0;
  }
  // 99 % expected inside; 97 % leaves room for the scatter of 200 binomial draws (sd 0.7 %).
  EXPECT_GE(inside, 0.97 * total);
}

// A known filtered process: white noise e (variance s^2) through the first-order recursion
// x[n] = a x[n-1] + e[n]. Its one-sided PSD per Hz is 2 s^2 / (fs |1 - a exp(-i 2 pi f / fs)|^2),
// which spans a factor (1+a)^2/(1-a)^2 = 361 for a = 0.9 between DC and Nyquist.
TEST(EstimatePsd, FirstOrderFilteredNoiseFollowsItsClosedFormPsd) {
  constexpr double kSigma = 0.5;
  constexpr double kPole = 0.9;
  constexpr double kRate = 100.0;
  const Eigen::VectorXd e = WhiteNoise(100 * 2000, kSigma, 6);
  Eigen::VectorXd x(e.size());
  double state = 0.0;
  for (Eigen::Index n = 0; n < e.size(); ++n) x[n] = state = kPole * state + e[n];
  WelchOptions options;
  options.resolution_hz = 0.1;
  const Spectrum s = EstimatePsd(x, kRate, options, "ar1", "x");
  const auto exact = [&](double f) {
    const std::complex<double> z = std::polar(1.0, -2 * M_PI * f / kRate);
    return 2 * kSigma * kSigma / (kRate * std::norm(1.0 - kPole * z));
  };
  const PsdConfidenceBand band = CalcPsdConfidenceBand(s.degrees_of_freedom, 0.99);
  int inside = 0, total = 0;
  // Skip the lowest bins, where the Hann window's leakage from DC biases the estimate.
  for (Eigen::Index k = 3; k + 1 < s.psd.size(); ++k, ++total) {
    const double ratio = s.psd[k] / exact(s.frequency_hz[k]);
    inside += (ratio >= band.lower && ratio <= band.upper) ? 1 : 0;
  }
  // 99 % expected inside; 97 % leaves room for the binomial scatter of ~500 bins (sd 0.45 %).
  EXPECT_GE(inside, 0.97 * total);
  // The power in 1..49 Hz against the same sum over the exact PSD (below 1 Hz the per-segment mean
  // removal and the window's leakage from DC take their share). ~480 bins of ~360 degrees of freedom
  // each: the sum scatters well under 1 %; 3 % bounds it and the window's smoothing of the curve.
  constexpr double kStatisticalTolerance = 0.03;
  double exact_power = 0.0;
  for (Eigen::Index k = 0; k < s.psd.size(); ++k) {
    const double f = s.frequency_hz[k];
    if (f >= 1.0 && f <= 49.0) exact_power += exact(f) * s.resolution_hz;
  }
  EXPECT_NEAR(IntegratePsd(s, 1.0, 49.0), exact_power, kStatisticalTolerance * exact_power);
}

TEST(EstimatePsd, SinusoidPowerSitsAtItsFrequencyWithFlatTop) {
  constexpr double kRate = 1024.0;
  constexpr double kAmplitude = 0.5;
  constexpr double kFrequency = 100.3;
  const int n = 1 << 15;
  Eigen::VectorXd x(n);
  for (int i = 0; i < n; ++i) x[i] = kAmplitude * std::sin(2 * M_PI * kFrequency * i / kRate);
  WelchOptions options;
  options.segment_length = 1024;
  options.window = Window::kFlatTop;
  const Spectrum s = EstimatePsd(x, kRate, options, "sine", "x");
  Eigen::Index peak;
  s.psd.maxCoeff(&peak);
  EXPECT_NEAR(s.frequency_hz[peak], kFrequency, s.resolution_hz);
  // Peak PSD times ENBW is the line's power A^2/2; the flat-top window's scalloping is < 0.01 dB.
  constexpr double kScallopTolerance = 0.003;
  EXPECT_NEAR(s.psd[peak] * s.enbw_hz, kAmplitude * kAmplitude / 2,
              kScallopTolerance * kAmplitude * kAmplitude / 2);
}

TEST(EstimatePsd, LinearDetrendRemovesARamp) {
  constexpr double kRate = 100.0;
  const int n = 4096;
  Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(n, 0.0, 50.0);  // a large drift, no noise
  WelchOptions options;
  options.segment_length = 512;
  options.detrend = Detrend::kLinear;
  const Spectrum s = EstimatePsd(x, kRate, options, "ramp", "x");
  EXPECT_LT(s.psd.maxCoeff(), 1e-20);  // round-off of a removed line
  options.detrend = Detrend::kMean;
  EXPECT_GT(EstimatePsd(x, kRate, options, "ramp", "x").psd.maxCoeff(), 1e-3);
}

TEST(EstimatePsd, RejectsBadInputNamingRecordAndField) {
  Eigen::VectorXd x = WhiteNoise(1000, 1.0, 4);
  WelchOptions options;
  ExpectInputError([&] { EstimatePsd(x, 0.0, options, "rec.csv", "voltage"); },
                   {"rec.csv", "voltage", "sample rate"});
  ExpectInputError([&] { EstimatePsd(x, -5.0, options, "rec.csv", "voltage"); }, {"rec.csv"});
  options.resolution_hz = 0.01;
  ExpectInputError([&] { EstimatePsd(x, 100.0, options, "rec.csv", "voltage"); },
                   {"rec.csv", "voltage", "too short", "100 s"});
  options.resolution_hz = 0.0;
  options.overlap = 1.0;
  ExpectInputError([&] { EstimatePsd(x, 100.0, options, "rec.csv", "voltage"); }, {"overlap"});
  options.overlap = 0.5;
  x[17] = std::nan("");
  ExpectInputError([&] { EstimatePsd(x, 100.0, options, "rec.csv", "voltage"); },
                   {"rec.csv", "voltage", "sample 17"});
  x[17] = INFINITY;
  ExpectInputError([&] { EstimatePsd(x, 100.0, options, "rec.csv", "voltage"); }, {"sample 17"});
}

TEST(EstimateCrossSpectrum, ScaledDelayedCopyIsCoherentWithItsGainAndDelay) {
  constexpr double kRate = 1000.0;
  constexpr double kGain = 3.0;
  constexpr int kDelay = 2;  // samples
  const Eigen::VectorXd x = WhiteNoise(1 << 15, 1.0, 5);
  Eigen::VectorXd y = Eigen::VectorXd::Zero(x.size());
  y.tail(x.size() - kDelay) = kGain * x.head(x.size() - kDelay);
  WelchOptions options;
  options.segment_length = 1024;
  const CrossSpectrum c = EstimateCrossSpectrum(x, y, kRate, options, "pair", "x", "y");
  // The delay leaves 2 of 1024 samples per segment unshared (bias ~0.4 %); with 63 averages and
  // coherence near 1 the scatter of |H| is far below 1 %; 2 % bounds both.
  constexpr double kGainTolerance = 0.02;
  for (Eigen::Index k = 5; k < c.csd.size() - 5; k += 37) {
    const std::complex<double> h = c.csd[k] / c.psd_x[k];
    EXPECT_NEAR(std::abs(h), kGain, kGainTolerance * kGain);
    const double expected_phase = -2 * M_PI * c.frequency_hz[k] * kDelay / kRate;
    EXPECT_NEAR(std::remainder(std::arg(h) - expected_phase, 2 * M_PI), 0.0, kGainTolerance);
    EXPECT_GT(c.coherence[k], 0.98);
  }
  ExpectInputError(
      [&] { EstimateCrossSpectrum(x, y.head(100), kRate, options, "pair", "x", "y"); },
      {"pair", "'x'", "'y'"});
}

TEST(CalcChiSquareQuantile, MatchesTabulatedValues) {
  // nu = 2 is exponential: exact quantile -2 ln(1 - p).
  EXPECT_NEAR(CalcChiSquareQuantile(2.0, 0.9), -2 * std::log(0.1), 1e-10);
  // Standard table values (4 significant digits).
  EXPECT_NEAR(CalcChiSquareQuantile(10.0, 0.975), 20.483, 1e-3);
  EXPECT_NEAR(CalcChiSquareQuantile(10.0, 0.025), 3.247, 1e-3);
  EXPECT_NEAR(CalcChiSquareQuantile(100.0, 0.995), 140.169, 1e-3);
  EXPECT_NEAR(CalcChiSquareQuantile(1.0, 0.5), 0.4549, 1e-4);
  const PsdConfidenceBand band = CalcPsdConfidenceBand(10.0, 0.95);
  EXPECT_NEAR(band.lower, 0.3247, 1e-4);
  EXPECT_NEAR(band.upper, 2.0483, 1e-4);
}

TEST(CalcWindow, HannIsPeriodicAndParseRoundTrips) {
  const Eigen::VectorXd w = CalcWindow(Window::kHann, 8);
  EXPECT_DOUBLE_EQ(w[0], 0.0);
  EXPECT_NEAR(w[4], 1.0, 1e-15);
  for (Window window : {Window::kHann, Window::kHamming, Window::kBlackmanHarris,
                        Window::kFlatTop, Window::kRectangular}) {
    EXPECT_EQ(ParseWindow(WindowName(window), "t"), window);
  }
  EXPECT_THROW(ParseWindow("kaiser", "--window"), InputError);
  EXPECT_EQ(ParseDetrend("linear", "t"), Detrend::kLinear);
  EXPECT_THROW(ParseDetrend("quadratic", "--detrend"), InputError);
}

}  // namespace
}  // namespace stagefit::disturbance
