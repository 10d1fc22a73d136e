#include "stagefit/disturbance/spindle_error.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "stagefit/common/error.h"

namespace stagefit::disturbance {
namespace {

constexpr double kRate = 1000.0;                // Hz
constexpr double kSpeed = 2 * M_PI;             // 60 rpm, rad/s
constexpr int kSamples = 20000;                 // 20 revolutions
constexpr double kTranslationNoise = 10e-9;     // m rms, white
constexpr double kRotationNoise = 0.1e-6;       // rad rms, white

Eigen::MatrixXd RandomMotion(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> t(0.0, kTranslationNoise), r(0.0, kRotationNoise);
  Eigen::MatrixXd m(kSamples, 5);
  for (int i = 0; i < kSamples; ++i) m.row(i) << t(rng), t(rng), t(rng), r(rng), r(rng);
  return m;
}

std::array<SphereEccentricity, 2> KnownCircles() {
  return {SphereEccentricity{1e-6, 30 * M_PI / 180, 5e-6, -3e-6},
          SphereEccentricity{2e-6, -60 * M_PI / 180, -1e-6, 4e-6}};
}

TEST(AnalyseSpindleError, RecoversKnownEccentricityAndRandomMotion) {
  const Eigen::MatrixXd motion = RandomMotion(41);
  const Eigen::VectorXd angle = Eigen::VectorXd::LinSpaced(kSamples, 0.0, kSamples - 1.0) * (kSpeed / kRate);
  SpindleOptions options;
  options.rotation_speed_rad_s = kSpeed;
  constexpr double kAxialAmplitude = 15e-9;
  constexpr double kAxialPhase = 1.0;
  SpindleRecord record;
  record.sample_rate_hz = kRate;
  record.sensors_m = CalcSpindleSensorSignals(motion, angle, options.geometry, KnownCircles(),
                                              3e-6, kAxialAmplitude, kAxialPhase);
  const SpindleErrorSummary s = AnalyseSpindleError(record, options, "spindle.csv");
  EXPECT_NEAR(s.revolutions, 20.0, 1e-3);

  // Least squares over 2N = 40000 equations with ~15 nm rms sensor noise: the standard deviation of
  // each circle coefficient is about 15 nm / sqrt(N) = 0.1 nm. Tolerance 1 nm (10 sigma) on the
  // amplitude, 1 nm / e on the phase.
  constexpr double kAmplitudeTolerance = 1e-9;
  for (int k = 0; k < 2; ++k) {
    const SphereEccentricity truth = KnownCircles()[k];
    EXPECT_NEAR(s.eccentricity[k].amplitude_m, truth.amplitude_m, kAmplitudeTolerance) << k;
    EXPECT_NEAR(s.eccentricity[k].phase_rad, truth.phase_rad, kAmplitudeTolerance / truth.amplitude_m);
    EXPECT_NEAR(s.eccentricity[k].offset_x_m, truth.offset_x_m, kAmplitudeTolerance);
    EXPECT_NEAR(s.eccentricity[k].offset_y_m, truth.offset_y_m, kAmplitudeTolerance);
  }
  // Axial: 10 nm rms noise, N samples: ~0.1 nm standard deviation.
  EXPECT_NEAR(s.axial_amplitude_m, kAxialAmplitude, kAmplitudeTolerance);
  EXPECT_NEAR(s.axial_phase_rad, kAxialPhase, kAmplitudeTolerance / kAxialAmplitude);
  EXPECT_NEAR(s.axial_offset_m, 3e-6, kAmplitudeTolerance);

  // The residual motions are the true random motions less the small part of them the fits absorbed
  // (about 0.1 nm): compare column by column to 1 % of the noise level.
  const std::array<double, 5> scale = {kTranslationNoise, kTranslationNoise, kTranslationNoise,
                                       kRotationNoise, kRotationNoise};
  for (int c = 0; c < 5; ++c) {
    const double rms_difference = std::sqrt((s.motion.col(c) - motion.col(c)).squaredNorm() / kSamples);
    EXPECT_LT(rms_difference, 0.05 * scale[c]) << kSpindleMotionNames[c];
    EXPECT_NEAR(s.rms[c], scale[c], 0.03 * scale[c]) << kSpindleMotionNames[c];
    // White noise: the PSD integrates to the variance (Hann, many averages: within 3 %).
    EXPECT_NEAR(IntegratePsd(s.psd[c], 0.0, kRate), s.rms[c] * s.rms[c], 0.03 * s.rms[c] * s.rms[c]);
  }
}

TEST(AnalyseSpindleError, AngleColumnAndRotationSpeedAgree) {
  const Eigen::MatrixXd motion = RandomMotion(42);
  const Eigen::VectorXd angle = Eigen::VectorXd::LinSpaced(kSamples, 0.0, kSamples - 1.0) * (kSpeed / kRate);
  SpindleOptions options;
  SpindleRecord record;
  record.sample_rate_hz = kRate;
  record.sensors_m = CalcSpindleSensorSignals(motion, angle, options.geometry, KnownCircles(), 0, 0, 0);
  record.angle_rad = angle.unaryExpr([](double a) { return std::remainder(a, 2 * M_PI); });  // wrapped
  const SpindleErrorSummary with_angle = AnalyseSpindleError(record, options, "spindle");
  record.angle_rad.resize(0);
  options.rotation_speed_rad_s = kSpeed;
  const SpindleErrorSummary with_speed = AnalyseSpindleError(record, options, "spindle");
  EXPECT_LT((with_angle.motion - with_speed.motion).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_NEAR(with_angle.revolutions, with_speed.revolutions, 1e-9);
}

TEST(AnalyseSpindleError, RejectsRecordsThatCannotBeFitted) {
  SpindleOptions options;
  options.rotation_speed_rad_s = kSpeed;
  SpindleRecord record;
  record.sample_rate_hz = kRate;
  record.sensors_m = Eigen::MatrixXd::Zero(500, 5);  // half a revolution
  EXPECT_THROW(AnalyseSpindleError(record, options, "spindle"), InputError);
  record.sensors_m = Eigen::MatrixXd::Zero(2000, 4);
  EXPECT_THROW(AnalyseSpindleError(record, options, "spindle"), InputError);
  record.sensors_m = Eigen::MatrixXd::Zero(2000, 5);
  record.sensors_m(10, 2) = NAN;
  try {
    AnalyseSpindleError(record, options, "spindle.csv");
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'x2'"), std::string::npos) << e.what();
  }
  record.sensors_m(10, 2) = 0.0;
  options.rotation_speed_rad_s = 0.0;
  EXPECT_THROW(AnalyseSpindleError(record, options, "spindle"), InputError);
  options.rotation_speed_rad_s = kSpeed;
  options.geometry.sphere2_height_m = options.geometry.sphere1_height_m;
  EXPECT_THROW(AnalyseSpindleError(record, options, "spindle"), InputError);
}

}  // namespace
}  // namespace stagefit::disturbance
