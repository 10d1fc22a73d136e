#include "stagefit/disturbance/spindle_error.h"

#include <cmath>
#include <sstream>

#include "fft_internal.h"
#include "stagefit/common/error.h"
#include "stagefit/common/units.h"

namespace stagefit::disturbance {
namespace {

void CheckGeometry(const SpindleGeometry& g, const std::string& record) {
  if (!(std::isfinite(g.sphere1_height_m) && std::isfinite(g.sphere2_height_m) &&
        std::isfinite(g.reference_height_m) && g.sphere2_height_m > g.sphere1_height_m)) {
    std::ostringstream message;
    message << record << ": spindle geometry z1 = " << g.sphere1_height_m
            << " m, z2 = " << g.sphere2_height_m << " m, z_ref = " << g.reference_height_m
            << " m, expected finite heights with z2 > z1";
    throw InputError(message.str());
  }
}

// Best circle through (x, y) versus angle: x = cx + p cos - q sin, y = cy + p sin + q cos.
SphereEccentricity FitCircle(const Eigen::VectorXd& x, const Eigen::VectorXd& y,
                             const Eigen::VectorXd& angle) {
  const Eigen::Index n = x.size();
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(2 * n, 4);
  Eigen::VectorXd b(2 * n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double c = std::cos(angle[i]);
    const double s = std::sin(angle[i]);
    a.row(2 * i) << 1.0, 0.0, c, -s;
    a.row(2 * i + 1) << 0.0, 1.0, s, c;
    b[2 * i] = x[i];
    b[2 * i + 1] = y[i];
  }
  const Eigen::Vector4d p = a.colPivHouseholderQr().solve(b);
  return {std::hypot(p[2], p[3]), std::atan2(p[3], p[2]), p[0], p[1]};
}

}  // namespace

std::string SpindleErrorSummary::BriefReport() const {
  std::ostringstream out;
  out << revolutions << " revolutions; sphere 1 eccentricity " << eccentricity[0].amplitude_m * 1e9
      << " nm at " << eccentricity[0].phase_rad * kDegreesPerRadian << " deg, sphere 2 "
      << eccentricity[1].amplitude_m * 1e9 << " nm at " << eccentricity[1].phase_rad * kDegreesPerRadian
      << " deg; axial once-per-rev " << axial_amplitude_m * 1e9 << " nm\nresidual rms:";
  for (int c = 0; c < 5; ++c) {
    out << " " << kSpindleMotionNames[c] << " " << rms[c] * 1e9 << (c < 3 ? " nm" : " nrad");
  }
  return out.str();
}

SpindleErrorSummary AnalyseSpindleError(const SpindleRecord& record, const SpindleOptions& options,
                                        const std::string& record_name) {
  const Eigen::Index n = record.sensors_m.rows();
  if (record.sensors_m.cols() != 5 || n < 8) {
    std::ostringstream message;
    message << record_name << ": spindle record holds " << n << " x " << record.sensors_m.cols()
            << " sensor values, expected N x 5 (x1 y1 x2 y2 z) with N >= 8";
    throw InputError(message.str());
  }
  internal::CheckSampleRate(record.sample_rate_hz, record_name, "time_s");
  for (int c = 0; c < 5; ++c) {
    internal::CheckFinite(record.sensors_m.col(c), record_name, kSpindleSensorNames[c]);
  }
  CheckGeometry(options.geometry, record_name);

  SpindleErrorSummary summary;
  if (record.angle_rad.size() > 0) {
    if (record.angle_rad.size() != n) {
      throw InputError(record_name + ": field 'angle_rad': " +
                       std::to_string(record.angle_rad.size()) + " values for " +
                       std::to_string(n) + " samples, expected one per sample");
    }
    internal::CheckFinite(record.angle_rad, record_name, "angle_rad");
    summary.angle_rad = record.angle_rad;
  } else {
    if (!(std::isfinite(options.rotation_speed_rad_s) && options.rotation_speed_rad_s != 0.0)) {
      throw InputError(record_name +
                       ": no angle_rad column and no rotation speed, expected one of them to "
                       "place the samples on the revolution");
    }
    summary.angle_rad = Eigen::VectorXd::LinSpaced(n, 0.0, n - 1.0) *
                        (options.rotation_speed_rad_s / record.sample_rate_hz);
  }
  // The angle covered is measured by unwrapping consecutive steps.
  double covered = 0.0;
  for (Eigen::Index i = 1; i < n; ++i) {
    covered += std::remainder(summary.angle_rad[i] - summary.angle_rad[i - 1], 2.0 * M_PI);
  }
  summary.revolutions = std::abs(covered) / (2.0 * M_PI);
  if (summary.revolutions < 1.0) {
    std::ostringstream message;
    message << record_name << ": the record covers " << summary.revolutions
            << " revolution(s), expected at least 1 for the once-per-revolution fit";
    throw InputError(message.str());
  }

  const Eigen::MatrixXd& s = record.sensors_m;
  const Eigen::VectorXd& angle = summary.angle_rad;
  Eigen::MatrixXd residual = s;
  for (int sphere = 0; sphere < 2; ++sphere) {
    const SphereEccentricity e = FitCircle(s.col(2 * sphere), s.col(2 * sphere + 1), angle);
    summary.eccentricity[sphere] = e;
    for (Eigen::Index i = 0; i < n; ++i) {
      residual(i, 2 * sphere) -= e.offset_x_m + e.amplitude_m * std::cos(angle[i] + e.phase_rad);
      residual(i, 2 * sphere + 1) -= e.offset_y_m + e.amplitude_m * std::sin(angle[i] + e.phase_rad);
    }
  }
  if (options.remove_axial_once_per_rev) {
    Eigen::MatrixXd a(n, 3);
    a.col(0).setOnes();
    a.col(1) = angle.array().cos().matrix();
    a.col(2) = angle.array().sin().matrix();
    const Eigen::Vector3d p = a.colPivHouseholderQr().solve(s.col(4));
    summary.axial_offset_m = p[0];
    summary.axial_amplitude_m = std::hypot(p[1], p[2]);
    summary.axial_phase_rad = std::atan2(-p[2], p[1]);  // a cos(t + phi) = a cos phi cos t - a sin phi sin t
    residual.col(4) -= a * p;
  } else {
    summary.axial_offset_m = s.col(4).mean();
    residual.col(4).array() -= summary.axial_offset_m;
  }

  const SpindleGeometry& g = options.geometry;
  const double span = g.sphere2_height_m - g.sphere1_height_m;
  summary.motion.resize(n, 5);
  const auto x1 = residual.col(0), y1 = residual.col(1), x2 = residual.col(2), y2 = residual.col(3);
  summary.motion.col(4) = (x2 - x1) / span;                                       // Ry
  summary.motion.col(3) = -(y2 - y1) / span;                                      // Rx
  const double lever = g.sphere1_height_m - g.reference_height_m;
  summary.motion.col(0) = x1 - lever * summary.motion.col(4);                     // Dx
  summary.motion.col(1) = y1 + lever * summary.motion.col(3);                     // Dy
  summary.motion.col(2) = residual.col(4);                                        // Dz

  for (int c = 0; c < 5; ++c) {
    const Eigen::VectorXd column = summary.motion.col(c);
    summary.rms[c] = std::sqrt(column.squaredNorm() / static_cast<double>(n));
    summary.peak_to_peak[c] = column.maxCoeff() - column.minCoeff();
    summary.psd[c] =
        EstimatePsd(column, record.sample_rate_hz, options.welch, record_name, kSpindleMotionNames[c]);
  }
  return summary;
}

Eigen::MatrixXd CalcSpindleSensorSignals(const Eigen::MatrixXd& motion,
                                         const Eigen::VectorXd& angle_rad,
                                         const SpindleGeometry& geometry,
                                         const std::array<SphereEccentricity, 2>& eccentricity,
                                         double axial_offset_m, double axial_amplitude_m,
                                         double axial_phase_rad) {
  STAGEFIT_ASSERT(motion.cols() == 5 && motion.rows() == angle_rad.size(),
                  "spindle motion " << motion.rows() << " x " << motion.cols() << ", angles "
                                    << angle_rad.size());
  const Eigen::Index n = motion.rows();
  const std::array<double, 2> heights = {geometry.sphere1_height_m, geometry.sphere2_height_m};
  Eigen::MatrixXd s(n, 5);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double theta = angle_rad[i];
    for (int k = 0; k < 2; ++k) {
      const SphereEccentricity& e = eccentricity[k];
      const double lever = heights[k] - geometry.reference_height_m;
      s(i, 2 * k) = e.offset_x_m + e.amplitude_m * std::cos(theta + e.phase_rad) + motion(i, 0) +
                    lever * motion(i, 4);
      s(i, 2 * k + 1) = e.offset_y_m + e.amplitude_m * std::sin(theta + e.phase_rad) +
                        motion(i, 1) - lever * motion(i, 3);
    }
    s(i, 4) = axial_offset_m + axial_amplitude_m * std::cos(theta + axial_phase_rad) + motion(i, 2);
  }
  return s;
}

}  // namespace stagefit::disturbance
