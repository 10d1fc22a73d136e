#include "stagefit/measurement/hammer_estimation.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <complex>
#include <random>
#include <string>
#include <vector>

#include "stagefit/common/eigen_decomposition.h"
#include "stagefit/common/error.h"
#include "stagefit/common/units.h"

namespace stagefit::measurement {
namespace {

using Complex = std::complex<double>;

// A continuous-time linear system x' = A x + B f, y = C x + D f (one force input).
struct LinearSystem {
  Eigen::MatrixXd A, B, C, D;
};

// M q'' + Cd q' + K q = b f, outputs: the accelerations of the DoFs listed in `sensed`.
LinearSystem Mechanical(const Eigen::MatrixXd& M, const Eigen::MatrixXd& Cd,
                        const Eigen::MatrixXd& K, const Eigen::VectorXd& b,
                        const std::vector<int>& sensed) {
  const int n = static_cast<int>(M.rows());
  const Eigen::MatrixXd Minv = M.inverse();
  LinearSystem s;
  s.A = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  s.A.topRightCorner(n, n) = Eigen::MatrixXd::Identity(n, n);
  s.A.bottomLeftCorner(n, n) = -Minv * K;
  s.A.bottomRightCorner(n, n) = -Minv * Cd;
  s.B = Eigen::MatrixXd::Zero(2 * n, 1);
  s.B.bottomRows(n) = Minv * b;
  s.C.resize(sensed.size(), 2 * n);
  s.D.resize(sensed.size(), 1);
  for (std::size_t i = 0; i < sensed.size(); ++i) {
    s.C.row(i) = s.A.row(n + sensed[i]);
    s.D.row(i) = s.B.row(n + sensed[i]);
  }
  return s;
}

LinearSystem Sdof(double f_n_hz, double zeta) {
  const double w = 2.0 * kPi * f_n_hz;
  return Mechanical(Eigen::MatrixXd::Constant(1, 1, 1.0), Eigen::MatrixXd::Constant(1, 1, 2 * zeta * w),
                    Eigen::MatrixXd::Constant(1, 1, w * w), Eigen::VectorXd::Ones(1), {0});
}

// Two masses of 1 kg in a chain ground - k1 - m1 - k2 - m2, hammered and measured at m2 (drive
// point). Resonances 22.5 Hz and 55.1 Hz, antiresonance sqrt((k1 + k2)/m1)/(2 pi) = 50.33 Hz.
// Dampers 0.3 N s/m from m1 and 10 N s/m from m2 to the ground: the modes decay at 1.1 and 4.0 1/s,
// the antiresonance (m2 held) keeps its light damping: |H| = 0.006 there, 0.2-30 elsewhere.
LinearSystem TwoDofDrivePoint() {
  const double k1 = 6e4, k2 = 4e4;
  Eigen::MatrixXd M = Eigen::MatrixXd::Identity(2, 2);
  Eigen::MatrixXd K(2, 2);
  K << k1 + k2, -k2, -k2, k2;
  const Eigen::MatrixXd Cd = Eigen::Vector2d(0.3, 10.0).asDiagonal();
  return Mechanical(M, Cd, K, Eigen::Vector2d(0.0, 1.0), {1});
}

Complex Frf(const LinearSystem& s, double f_hz) {
  const int n = static_cast<int>(s.A.rows());
  const Eigen::MatrixXcd sI = Complex(0.0, 2.0 * kPi * f_hz) * Eigen::MatrixXcd::Identity(n, n);
  const Eigen::MatrixXcd G = (sI - s.A.cast<Complex>()).partialPivLu().solve(s.B.cast<Complex>());
  return (s.C.cast<Complex>() * G)(0, 0) + s.D(0, 0);
}

struct HalfSine {
  double start_s = 0.0;
  double duration_s = 0.0;
  double amplitude_n = 0.0;
};

double ForceAt(const std::vector<HalfSine>& pulses, double t) {
  double f = 0.0;
  for (const HalfSine& p : pulses) {
    if (t >= p.start_s && t <= p.start_s + p.duration_s) {
      f += p.amplitude_n * std::sin(kPi * (t - p.start_s) / p.duration_s);
    }
  }
  return f;
}

// Exact response to half-sine pulses, by the modal decomposition of A: each mode z' = l z + b f
// is integrated in closed form, int_0^u exp(-l s) sin(W s) ds = (exp(-l u)(-l sin Wu - W cos Wu)
// + W) / (l^2 + W^2).
Eigen::VectorXd Respond(const LinearSystem& s, const std::vector<HalfSine>& pulses, double fs,
                        int ns) {
  const auto eig = CalcEigenPairs(s.A);
  EXPECT_TRUE(eig);
  const Eigen::MatrixXcd V = eig->vectors;
  const Eigen::VectorXcd lambda = eig->values;
  const Eigen::VectorXcd b = V.partialPivLu().solve(s.B.cast<Complex>());
  const Eigen::RowVectorXcd c = s.C.row(0).cast<Complex>() * V;
  Eigen::VectorXd y(ns);
  for (int n = 0; n < ns; ++n) {
    const double t = n / fs;
    Complex acc = 0.0;
    for (const HalfSine& p : pulses) {
      if (t <= p.start_s) continue;
      const double W = kPi / p.duration_s;
      const double u = std::min(t - p.start_s, p.duration_s);
      for (int i = 0; i < lambda.size(); ++i) {
        const Complex l = lambda(i);
        const Complex integral =
            (std::exp(l * (t - p.start_s - u)) * (-l * std::sin(W * u) - W * std::cos(W * u)) +
             W * std::exp(l * (t - p.start_s))) / (l * l + W * W);
        acc += c(i) * b(i) * p.amplitude_n * integral;
      }
    }
    y(n) = acc.real() + s.D(0, 0) * ForceAt(pulses, t);
  }
  return y;
}

struct TestSetup {
  double fs = 8192.0;
  int ns = 32768;
  double pulse_s = 0.002;
  double amplitude_n = 100.0;
  int hits = 5;
  double force_noise_n = 0.0;
  double response_noise = 0.0;
  unsigned seed = 1u;
};

// One input, one output; hit h starts at 0.1 s + 0.37 h / fs (pulses off the sample grid).
RawHammerData Simulate(const LinearSystem& system, const TestSetup& setup,
                       std::vector<std::vector<HalfSine>> pulses = {}) {
  std::mt19937 rng(setup.seed);
  std::normal_distribution<double> normal;
  RawHammerData data;
  data.sample_rate_hz = setup.fs;
  data.quantity = FrfQuantity::kAccelerance;
  data.outputs.resize(1);
  data.outputs[0].name = "a1";
  data.inputs.resize(1);
  data.inputs[0].name = "F1";
  data.source = "simulated";
  data.hits.resize(1);
  for (int h = 0; h < setup.hits; ++h) {
    std::vector<HalfSine> p = h < static_cast<int>(pulses.size()) && !pulses[h].empty()
                                  ? pulses[h]
                                  : std::vector<HalfSine>{{0.1 + 0.37 * h / setup.fs,
                                                           setup.pulse_s, setup.amplitude_n}};
    HammerHit hit;
    hit.force.resize(setup.ns);
    for (int n = 0; n < setup.ns; ++n) {
      hit.force(n) = ForceAt(p, n / setup.fs) + setup.force_noise_n * normal(rng);
    }
    hit.response = Respond(system, p, setup.fs, setup.ns);
    for (int n = 0; n < setup.ns; ++n) hit.response(n, 0) += setup.response_noise * normal(rng);
    data.hits[0].push_back(hit);
  }
  return data;
}

// |F(f)| of a half-sine pulse of amplitude A and duration T: (2 A T / pi) |cos(pi f T)| /
// |1 - (2 f T)^2|.
double HalfSineSpectrum(double f_hz, double amplitude_n, double duration_s) {
  const double x = 2.0 * f_hz * duration_s;
  if (std::abs(1.0 - x * x) < 1e-12) return amplitude_n * duration_s / 2.0;
  return 2.0 * amplitude_n * duration_s / kPi * std::abs(std::cos(kPi * f_hz * duration_s)) /
         std::abs(1.0 - x * x);
}

// Systematic error allowance (relative) of H1 on noise-free data: the sampled records alias the
// spectrum at fs -+ f; with fs = 8192 Hz and a 2 ms half-sine the force spectrum there is below
// 1e-3 of its low-frequency value, and its effect is further weighted by H(fs - f) - H(f), small on
// the mass line. 5e-3 bounds it over 30-1000 Hz with margin.
constexpr double kAliasingAllowance = 5e-3;
// Random error: per bin, H1 - H ~ N_x(k) / F(k) averaged over the hits, with |N_x|^2 = Ns sigma_x^2
// (white noise, unnormalised DFT) and F(k) = fs F(f): sigma_H = sigma_x sqrt(Ns) / (fs |F(f)|
// sqrt(hits)). For a complex Gaussian error P(|e| > 5 sigma) = exp(-25), so over a few thousand
// bins no bin should exceed 5 sigma.
constexpr double kNoiseSigmas = 5.0;

TEST(EstimateFrf, H1RecoversSdofAccelerance) {
  const LinearSystem sdof = Sdof(40.0, 0.02);
  TestSetup setup;
  const EstimationSummary clean = EstimateFrf(Simulate(sdof, setup));
  setup.force_noise_n = 0.02;
  setup.response_noise = 0.02;
  setup.seed = 42u;
  const EstimationSummary noisy = EstimateFrf(Simulate(sdof, setup));
  ASSERT_EQ(clean.frf.num_outputs(), 1);
  EXPECT_NEAR(clean.frf.frequency_hz(0), setup.fs / setup.ns, 1e-12);
  int checked = 0;
  for (int k = 0; k < clean.frf.num_frequencies(); ++k) {
    const double f = clean.frf.frequency_hz(k);
    if (f < 30.0 || f > 1000.0) continue;
    const Complex truth = Frf(sdof, f);
    const Complex h_clean = clean.frf.frf[k](0, 0);
    const Complex h_noisy = noisy.frf.frf[k](0, 0);
    if (std::abs(f - 750.0) > 20.0) {  // 750 Hz: zero of the force spectrum, aliasing dominates
      EXPECT_LT(std::abs(h_clean - truth), kAliasingAllowance * std::abs(truth)) << f << " Hz";
    }
    const double sigma = setup.response_noise * std::sqrt(setup.ns) /
                         (setup.fs * HalfSineSpectrum(f, setup.amplitude_n, setup.pulse_s) *
                          std::sqrt(setup.hits));
    EXPECT_LT(std::abs(h_noisy - truth),
              kNoiseSigmas * sigma + kAliasingAllowance * std::abs(truth))
        << f << " Hz";
    ++checked;
  }
  EXPECT_GT(checked, 3000);
  EXPECT_TRUE(noisy.rejected_hits.empty());
  for (const HitDiagnostics& d : noisy.hits) EXPECT_FALSE(d.flagged()) << d.hit;
}

TEST(EstimateFrf, H1AndH2AgreeWhereCoherenceIsHigh) {
  TestSetup setup;
  setup.force_noise_n = 0.02;
  setup.response_noise = 0.02;
  const EstimationSummary s = EstimateFrf(Simulate(Sdof(40.0, 0.02), setup));
  // gamma^2 = H1 / H2 exactly; check it on a few bins and that H2 >= H1 in magnitude.
  for (int k = 100; k < 4000; k += 500) {
    const Complex ratio = s.h1[k](0, 0) / s.h2[k](0, 0);
    EXPECT_NEAR(ratio.real(), s.frf.coherence[k](0, 0), 1e-9);
    EXPECT_NEAR(ratio.imag(), 0.0, 1e-9);
  }
}

TEST(EstimateFrf, CoherenceDropsAtAntiresonanceAndAtForceSpectrumZero) {
  // 8 s records (the slower mode decays to 2e-4); the per-hit noise on H near 50 Hz,
  // sigma_x sqrt(Ns) / (fs |F|) = 0.017, dwarfs |H| = 0.006 at the antiresonance only.
  TestSetup setup;
  setup.fs = 4096.0;
  setup.ns = 32768;
  setup.force_noise_n = 0.02;
  setup.response_noise = 0.05;
  setup.seed = 7u;
  const EstimationSummary s = EstimateFrf(Simulate(TwoDofDrivePoint(), setup));
  double min_antiresonance = 1.0, min_zero = 1.0;
  std::vector<double> elsewhere;
  for (int k = 0; k < s.frf.num_frequencies(); ++k) {
    const double f = s.frf.frequency_hz(k);
    const double c = s.frf.coherence[k](0, 0);
    if (std::abs(f - 50.33) < 1.0) min_antiresonance = std::min(min_antiresonance, c);
    if (std::abs(f - 750.0) < 10.0) min_zero = std::min(min_zero, c);
    if ((f > 10.0 && f < 40.0) || (f > 60.0 && f < 600.0)) elsewhere.push_back(c);
  }
  EXPECT_LT(min_antiresonance, 0.5);
  EXPECT_LT(min_zero, 0.5);
  std::sort(elsewhere.begin(), elsewhere.end());
  // Away from both, the signal dominates: 95 % of the bins have gamma^2 > 0.9.
  EXPECT_GT(elsewhere[elsewhere.size() / 20], 0.9);
}

TEST(EstimateFrf, FlagsADoubleHitWithItsNumber) {
  TestSetup setup;
  setup.force_noise_n = 0.02;
  setup.response_noise = 0.02;
  std::vector<std::vector<HalfSine>> pulses(setup.hits);
  pulses[2] = {{0.1, 0.002, 100.0}, {0.125, 0.002, 30.0}};  // hit 3: a 30 % rebound 25 ms later
  const RawHammerData data = Simulate(Sdof(40.0, 0.02), setup, pulses);
  const EstimationSummary s = EstimateFrf(data);
  ASSERT_EQ(s.hits.size(), 5u);
  for (const HitDiagnostics& d : s.hits) {
    EXPECT_EQ(d.double_hit, d.hit == 2) << "hit " << d.hit + 1;
  }
  EXPECT_NEAR(s.hits[2].second_peak_ratio, 0.3, 0.01);
  EXPECT_NEAR(s.hits[2].second_peak_time_s, 0.126, 2.0 / setup.fs);
  EXPECT_NE(s.BriefReport().find("hit 3: double hit"), std::string::npos) << s.BriefReport();
  EXPECT_TRUE(s.rejected_hits.empty());
  EXPECT_EQ(s.hits_used[0], 5);

  EstimationOptions exclude;
  exclude.exclude_flagged = true;
  const EstimationSummary r = EstimateFrf(data, exclude);
  ASSERT_EQ(r.rejected_hits.size(), 1u);
  EXPECT_EQ(r.rejected_hits[0].hit, 2);
  EXPECT_EQ(r.hits_used[0], 4);
}

TEST(EstimateFrf, FlagsAClippedResponseByRangeAndByFlatTop) {
  TestSetup setup;
  setup.response_noise = 0.001;
  RawHammerData data = Simulate(Sdof(40.0, 0.02), setup);
  const double peak = data.hits[0][1].response.cwiseAbs().maxCoeff();
  const double range = 0.5 * peak;
  for (int h = 0; h < setup.hits; ++h) {
    if (h == 1) {
      data.hits[0][h].response = data.hits[0][h].response.cwiseMax(-range).cwiseMin(range);
    }
  }
  const EstimationSummary flat = EstimateFrf(data);
  for (const HitDiagnostics& d : flat.hits) {
    EXPECT_EQ(d.overloaded_outputs.size(), d.hit == 1 ? 1u : 0u) << "hit " << d.hit + 1;
  }
  EXPECT_NE(flat.BriefReport().find("hit 2: output 'a1' overloaded"), std::string::npos);

  // Declared range: hit 4 reaches 99 % of it without a flat top.
  RawHammerData ranged = Simulate(Sdof(40.0, 0.02), setup);
  ranged.response_full_scale = Eigen::VectorXd::Constant(
      1, ranged.hits[0][3].response.cwiseAbs().maxCoeff() / 0.99);
  ranged.force_full_scale = Eigen::VectorXd::Constant(1, 1000.0);
  const EstimationSummary by_range = EstimateFrf(ranged);
  EXPECT_EQ(by_range.hits[3].overloaded_outputs.size(), 1u);
  EXPECT_FALSE(by_range.hits[3].force_overload);
}

TEST(EstimateFrf, FlagsAHitThatDisagreesWithTheOthers) {
  TestSetup setup;
  setup.response_noise = 0.01;
  RawHammerData data = Simulate(Sdof(40.0, 0.02), setup);
  // Hit 4 hit a different spot: its response is that of a 45 Hz mode.
  RawHammerData other = Simulate(Sdof(45.0, 0.02), setup);
  data.hits[0][3] = other.hits[0][3];
  const EstimationSummary s = EstimateFrf(data);
  for (const HitDiagnostics& d : s.hits) {
    EXPECT_EQ(d.poor_coherence, d.hit == 3) << "hit " << d.hit + 1 << " " << d.hit_coherence;
  }
}

// The estimate carries the hits it averaged (FrfData::averages), and the coherence turned with them
// into the estimate's own (EstimateCoherence) gives the estimate's noise: (1 - c) |H_est|^2 against the
// known sigma_H^2 of the random error above, bin by bin over 30-1000 Hz, averages to 1 (per bin it
// scatters as a chi-square of 2 (n - 1) degrees of freedom: sd 0.5 for 5 hits, 0.01 over the ~3000
// bins). Read as the estimate's own, the ordinary coherence of the 5 hits gives n - 1 = 4 times that.
// The response noise is 10 times the other tests': at 0.02 it is near 1e-3 of |H| over much of the
// band, where the sampled pulses, each off the sample grid by its own fraction, differ from hit to hit
// by about as much, and the coherence counts that too (the ratio was 1.07, 1.41 below 200 Hz).
TEST(EstimateFrf, TheCoherenceWithTheHitsAveragedGivesTheEstimatesNoise) {
  const LinearSystem sdof = Sdof(40.0, 0.02);
  TestSetup setup;
  setup.response_noise = 0.2;
  setup.seed = 7u;
  const EstimationSummary s = EstimateFrf(Simulate(sdof, setup));
  ASSERT_EQ(s.frf.averages, std::vector<int>{setup.hits});
  double estimate = 0, ordinary = 0, actual = 0;
  int bins = 0;
  for (int k = 0; k < s.frf.num_frequencies(); ++k) {
    const double f = s.frf.frequency_hz(k);
    if (f < 30.0 || f > 1000.0 || std::abs(f - 750.0) < 20.0) continue;
    const double sigma = setup.response_noise * std::sqrt(setup.ns) /
                         (setup.fs * HalfSineSpectrum(f, setup.amplitude_n, setup.pulse_s) * std::sqrt(setup.hits));
    const double h2 = std::norm(s.frf.frf[k](0, 0));
    estimate += (1.0 - s.frf.estimate_coherence(k, 0, 0)) * h2 / (sigma * sigma);
    ordinary += (1.0 - s.frf.coherence[k](0, 0)) / s.frf.coherence[k](0, 0) * h2 / (sigma * sigma);
    actual += std::norm(s.frf.frf[k](0, 0) - Frf(sdof, f)) / (sigma * sigma);
    ++bins;
  }
  ASSERT_GT(bins, 3000);
  EXPECT_NEAR(actual / bins, 1.0, 0.1);  // the sigma_H of the test is the estimate's noise
  EXPECT_NEAR(estimate / bins, 1.0, 0.05);
  EXPECT_GT(ordinary / bins, 3.5);
  EXPECT_LT(ordinary / bins, 4.5);
}

// One hit's coherence is 1 whatever the noise: with a single hit on an input none is written. A hit
// left out of the averages is not counted.
TEST(EstimateFrf, WritesNoCoherenceForOneHitAndCountsOnlyTheHitsUsed) {
  TestSetup setup;
  setup.response_noise = 0.01;
  setup.hits = 1;
  const EstimationSummary one = EstimateFrf(Simulate(Sdof(40.0, 0.02), setup));
  EXPECT_FALSE(one.frf.has_coherence());
  EXPECT_TRUE(one.frf.averages.empty());
  ASSERT_FALSE(one.warnings.empty());
  EXPECT_NE(one.warnings.back().find("input 1 'F1': one hit averaged"), std::string::npos) << one.warnings.back();
  setup.hits = 5;
  RawHammerData data = Simulate(Sdof(40.0, 0.02), setup);
  data.hits[0][3] = Simulate(Sdof(45.0, 0.02), setup).hits[0][3];  // a hit on another spot
  EstimationOptions options;
  options.exclude_flagged = true;
  const EstimationSummary s = EstimateFrf(data, options);
  EXPECT_EQ(s.frf.averages, std::vector<int>{4});
  EXPECT_EQ(s.hits_used, std::vector<int>{4});
}

// Fits H(s) = (n2 s^2 + n1 s + n0) / (s^2 + b1 s + b0) to data by linear least squares (Levy),
// with s normalised by omega0, and returns the pole's natural frequency and damping ratio.
ModalParameters FitSecondOrder(const FrfData& frf, double low_hz, double high_hz) {
  const double w0 = 2.0 * kPi * 0.5 * (low_hz + high_hz);
  std::vector<int> bins;
  for (int k = 0; k < frf.num_frequencies(); ++k) {
    if (frf.frequency_hz(k) >= low_hz && frf.frequency_hz(k) <= high_hz) bins.push_back(k);
  }
  Eigen::MatrixXd A(2 * bins.size(), 5);
  Eigen::VectorXd rhs(2 * bins.size());
  for (std::size_t r = 0; r < bins.size(); ++r) {
    const Complex s(0.0, 2.0 * kPi * frf.frequency_hz(bins[r]) / w0);
    const Complex H = frf.frf[bins[r]](0, 0);
    const Complex row[5] = {-H * s, -H, s * s, s, 1.0};
    for (int c = 0; c < 5; ++c) {
      A(2 * r, c) = row[c].real();
      A(2 * r + 1, c) = row[c].imag();
    }
    rhs(2 * r) = (H * s * s).real();
    rhs(2 * r + 1) = (H * s * s).imag();
  }
  const Eigen::VectorXd x = A.colPivHouseholderQr().solve(rhs);
  const double wn = w0 * std::sqrt(x(1));
  return {wn / (2.0 * kPi), x(0) / (2.0 * std::sqrt(x(1)))};
}

TEST(CorrectExponentialWindowDamping, RecoversTheTrueDampingOfAnSdof) {
  // A lightly damped mode (40 Hz, zeta 0.005, decay time 0.8 s) in a 1 s record: without a window
  // the record truncates it (leakage warning); with tau = 0.1 s it decays to 1e-4 in the record.
  const double f_n = 40.0, zeta = 0.005, tau = 0.1;
  TestSetup setup;
  setup.fs = 4096.0;
  setup.ns = 4096;
  setup.hits = 3;
  setup.force_noise_n = 0.01;
  setup.response_noise = 0.01;
  const RawHammerData data = Simulate(Sdof(f_n, zeta), setup);
  const EstimationSummary plain = EstimateFrf(data);
  ASSERT_FALSE(plain.warnings.empty());
  EXPECT_NE(plain.warnings[0].find("has not decayed"), std::string::npos);

  EstimationOptions options;
  options.exp_tau_s = tau;
  const EstimationSummary windowed = EstimateFrf(data, options);
  EXPECT_TRUE(windowed.warnings.empty()) << windowed.BriefReport();
  EXPECT_DOUBLE_EQ(windowed.added_decay_rate_1_s, 10.0);
  EXPECT_NE(windowed.BriefReport().find("adds the decay rate 10 1/s"), std::string::npos);

  const ModalParameters measured = FitSecondOrder(windowed.frf, 30.0, 50.0);
  // The window shifts the pole's decay rate by 1/tau: zeta_m ~ zeta + 1/(tau omega_n) = 0.0448.
  EXPECT_NEAR(measured.damping_ratio, zeta + ExponentialWindowAddedDamping(f_n, tau), 1e-3);
  const ModalParameters corrected = CorrectExponentialWindowDamping(measured, tau);
  // The windowed estimate is the FRF of the system with its pole moved by -1/tau (exact for the
  // continuous records); what remains is aliasing and the 1e-4 truncation, and the noise in a
  // 20 Hz band around a peak of high signal-to-noise ratio. Tolerances: 2 % on zeta, 1e-3 on f.
  constexpr double kDampingTolerance = 0.02;
  constexpr double kFrequencyTolerance = 1e-3;
  EXPECT_NEAR(corrected.damping_ratio, zeta, kDampingTolerance * zeta);
  EXPECT_NEAR(corrected.natural_frequency_hz, f_n, kFrequencyTolerance * f_n);
}

TEST(CorrectExponentialWindowDamping, MatchesTheFirstOrderFormulaAndRejectsTooLowDamping) {
  const ModalParameters measured{100.0, 0.02};
  const ModalParameters c = CorrectExponentialWindowDamping(measured, 1.0);
  EXPECT_NEAR(c.damping_ratio, 0.02 - 1.0 / (2.0 * kPi * 100.0), 2e-6);
  EXPECT_THROW(CorrectExponentialWindowDamping({100.0, 0.0001}, 0.1), InputError);
  EXPECT_THROW(ExponentialWindowAddedDamping(100.0, 0.0), InputError);
}

TEST(Validate, RejectsDeadChannelsNonFiniteSamplesAndBadSizes) {
  TestSetup setup;
  setup.ns = 256;
  setup.fs = 1024.0;
  setup.hits = 2;
  const RawHammerData good = Simulate(Sdof(40.0, 0.02), setup);
  EXPECT_NO_THROW(Validate(good));

  RawHammerData dead = good;
  for (auto& hit : dead.hits[0]) hit.response.setZero();
  try {
    Validate(dead);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'a1' is zero in every hit"), std::string::npos) << e.what();
  }
  RawHammerData nan = good;
  nan.hits[0][1].force(10) = std::nan("");
  EXPECT_THROW(Validate(nan), InputError);
  RawHammerData zero_force = good;
  zero_force.hits[0][1].force.setZero();
  EXPECT_THROW(Validate(zero_force), InputError);
  RawHammerData ragged = good;
  ragged.hits[0][1].force.conservativeResize(200);
  EXPECT_THROW(Validate(ragged), InputError);
  RawHammerData no_rate = good;
  no_rate.sample_rate_hz = 0.0;
  EXPECT_THROW(Validate(no_rate), InputError);

  EstimationOptions bad;
  bad.exp_tau_s = -1.0;
  EXPECT_THROW(EstimateFrf(good, bad), InputError);
  EstimationOptions empty_band;
  empty_band.min_frequency_hz = 600.0;
  EXPECT_THROW(EstimateFrf(good, empty_band), InputError);
}

}  // namespace
}  // namespace stagefit::measurement
