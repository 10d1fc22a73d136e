#include "stagefit/disturbance/geophone.h"

#include <fftw3.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "stagefit/common/error.h"
#include "stagefit/disturbance/synthesis.h"

namespace stagefit::disturbance {
namespace {

TEST(CalcGeophoneResponse, HasTheSecondOrderHighPassShape) {
  const GeophoneModel g = L4cGeophone();
  const std::complex<double> at_f0 = CalcGeophoneResponse(g, g.natural_frequency_hz);
  // At w0: T = j G / (2 zeta).
  EXPECT_NEAR(at_f0.real(), 0.0, 1e-9);
  EXPECT_NEAR(at_f0.imag(), g.generator_constant_v_s_m / (2 * g.damping_ratio), 1e-9);
  // Far above f0: T -> G (relative error ~ (f0/f)^2).
  EXPECT_NEAR(std::abs(CalcGeophoneResponse(g, 1000.0)), g.generator_constant_v_s_m, 1e-3);
  // Far below: |T| -> G (f/f0)^2, to a relative O((f/f0)^2) = 1e-4 (times a factor below 3).
  const double low = g.generator_constant_v_s_m * 1e-4;
  EXPECT_NEAR(std::abs(CalcGeophoneResponse(g, 0.01)), low, 3e-4 * low);
  GeophoneModel amplified = g;
  amplified.amplifier_gain = 10.0;
  EXPECT_NEAR(std::abs(CalcGeophoneResponse(amplified, 5.0)),
              10.0 * std::abs(CalcGeophoneResponse(g, 5.0)), 1e-9);
}

TEST(GeophoneByName, AcceptsSpellingsAndRejectsUnknownSensors) {
  EXPECT_EQ(GeophoneByName("L-4C", "t").natural_frequency_hz, 1.0);
  EXPECT_EQ(GeophoneByName("l4c", "t").natural_frequency_hz, 1.0);
  EXPECT_EQ(GeophoneByName("L-22D", "t").natural_frequency_hz, 2.0);
  EXPECT_THROW(GeophoneByName("GS-11D", "--geophone"), InputError);
  GeophoneModel bad = L22Geophone();
  bad.damping_ratio = -0.1;
  EXPECT_THROW(ValidateGeophone(bad, "t"), InputError);
}

// Passes a displacement record through the geophone in the frequency domain (exact for the
// periodic synthesised record): V(f) = g T(j w) j w X(f).
Eigen::VectorXd GeophoneVoltage(const Eigen::VectorXd& x, double rate, const GeophoneModel& g) {
  const int n = static_cast<int>(x.size());
  std::vector<double> buffer(x.data(), x.data() + n);
  std::vector<fftw_complex> spectrum(n / 2 + 1);
  fftw_plan forward = fftw_plan_dft_r2c_1d(n, buffer.data(), spectrum.data(), FFTW_ESTIMATE);
  fftw_execute(forward);
  fftw_destroy_plan(forward);
  for (int k = 0; k <= n / 2; ++k) {
    const double f = k * rate / n;
    const std::complex<double> h =
        CalcGeophoneResponse(g, f) * std::complex<double>(0.0, 2 * M_PI * f) / double(n);
    const std::complex<double> v = h * std::complex<double>(spectrum[k][0], spectrum[k][1]);
    spectrum[k][0] = v.real();
    spectrum[k][1] = v.imag();
  }
  fftw_plan inverse = fftw_plan_dft_c2r_1d(n, spectrum.data(), buffer.data(), FFTW_ESTIMATE);
  fftw_execute(inverse);
  fftw_destroy_plan(inverse);
  return Eigen::Map<Eigen::VectorXd>(buffer.data(), n);
}

TEST(CalcGroundDisplacementPsd, RecoversAKnownGroundSpectrumThroughAnL4c) {
  // Quiet hall: ASD 1e-8 m/sqrt(Hz) at 1 Hz falling as f^-2, flat below 0.5 Hz, up to 100 Hz.
  PsdTable ground;
  ground.frequency_hz = (Eigen::VectorXd(3) << 0.1, 0.5, 100.0).finished();
  ground.psd = (Eigen::VectorXd(3) << 16e-16, 16e-16, 1e-16 * std::pow(100.0, -4)).finished();
  constexpr double kRate = 256.0;
  std::mt19937_64 rng(21);
  const Eigen::VectorXd x = SynthesiseSignal(ground, {600.0, kRate}, rng);
  GeophoneModel g = L4cGeophone();
  g.amplifier_gain = 20.0;
  const Eigen::VectorXd volts = GeophoneVoltage(x, kRate, g);

  WelchOptions welch;
  welch.resolution_hz = 0.25;
  const Spectrum voltage_psd = EstimatePsd(volts, kRate, welch, "geophone", "voltage");
  const Spectrum s = CalcGroundDisplacementPsd(voltage_psd, g);
  ASSERT_EQ(s.frequency_hz.size(), voltage_psd.frequency_hz.size() - 1);  // DC dropped
  EXPECT_GT(s.frequency_hz[0], 0.0);
  const PsdConfidenceBand band = CalcPsdConfidenceBand(s.degrees_of_freedom, 0.99);
  int inside = 0, total = 0;
  // 1..90 Hz: away from the 100 Hz edge of the target and from the lowest bins, where Hann leakage
  // of the rising voltage spectrum (f^2 below f0) dominates.
  for (Eigen::Index k = 0; k < s.psd.size(); ++k) {
    const double f = s.frequency_hz[k];
    if (f < 1.0 || f > 90.0) continue;
    const double ratio = s.psd[k] / InterpolatePsd(ground, f);
    inside += (ratio >= band.lower && ratio <= band.upper) ? 1 : 0;
    ++total;
  }
  EXPECT_GE(inside, 0.95 * total) << inside << " of " << total;
  const double asd_at_1hz = std::sqrt(s.psd[3]);  // bin 4 of the original = 1 Hz
  EXPECT_NEAR(s.frequency_hz[3], 1.0, 1e-12);
  EXPECT_NEAR(asd_at_1hz, 1e-8, 0.25e-8);  // one bin: +-25 % covers its 99 % band in ASD
}

}  // namespace
}  // namespace stagefit::disturbance
