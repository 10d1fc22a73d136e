#include "stagefit/disturbance/straightness.h"

#include <cmath>
#include <sstream>

#include "fft_internal.h"
#include "stagefit/common/error.h"

namespace stagefit::disturbance {

std::string StraightnessSummary::BriefReport() const {
  std::ostringstream out;
  out << "line fit: offset " << offset_m * 1e9 << " nm, tilt " << slope_rad * 1e6
      << " urad; residual rms " << residual_rms_m * 1e9 << " nm, peak-to-peak "
      << residual_peak_to_peak_m * 1e9 << " nm; PSD versus " << (temporal ? "Hz" : "cycles/m")
      << ", " << psd.averages << " averages, resolution " << psd.resolution_hz
      << (temporal ? " Hz" : " 1/m");
  return out.str();
}

StraightnessSummary AnalyseStraightness(const Eigen::VectorXd& position_m,
                                        const Eigen::VectorXd& error_m,
                                        const StraightnessOptions& options,
                                        const std::string& record, const std::string& field) {
  auto fail = [&](const std::string& what) {
    throw InputError(record + ": field '" + field + "': " + what);
  };
  internal::CheckFinite(position_m, record, "position");
  internal::CheckFinite(error_m, record, field);
  const Eigen::Index n = position_m.size();
  if (error_m.size() != n) {
    fail(std::to_string(error_m.size()) + " values for " + std::to_string(n) +
         " positions, expected one per position");
  }
  constexpr Eigen::Index kMinPoints = 8;
  if (n < kMinPoints) fail(std::to_string(n) + " points, expected at least 8");
  if (!(std::isfinite(options.scan_speed_m_s) && options.scan_speed_m_s >= 0.0)) {
    fail("scan speed " + std::to_string(options.scan_speed_m_s) + " m/s, expected >= 0");
  }
  const double range = position_m[n - 1] - position_m[0];
  const double direction = range > 0.0 ? 1.0 : -1.0;
  if (range == 0.0) fail("the positions span a zero range, expected a scan");
  for (Eigen::Index i = 1; i < n; ++i) {
    if (!((position_m[i] - position_m[i - 1]) * direction > 0.0)) {
      std::ostringstream what;
      what << "position " << i << " = " << position_m[i] << " m after " << position_m[i - 1]
           << " m, expected strictly monotonic positions";
      fail(what.str());
    }
  }

  StraightnessSummary summary;
  const double step = range / static_cast<double>(n - 1);
  summary.position_m = Eigen::VectorXd::LinSpaced(n, position_m[0], position_m[n - 1]);
  bool even = true;
  constexpr double kEvenTolerance = 0.01;  // 1 % of a step: printing round-off, not a real gap
  for (Eigen::Index i = 1; i < n && even; ++i) {
    even = std::abs(position_m[i] - position_m[i - 1] - step) <= kEvenTolerance * std::abs(step);
  }
  Eigen::VectorXd error = error_m;
  if (!even) {
    Eigen::Index j = 0;
    for (Eigen::Index i = 0; i < n; ++i) {
      const double x = summary.position_m[i];
      while (j + 2 < n && (position_m[j + 1] - x) * direction <= 0.0) ++j;
      const double t = (x - position_m[j]) / (position_m[j + 1] - position_m[j]);
      error[i] = error_m[j] + t * (error_m[j + 1] - error_m[j]);
    }
  }
  summary.residual_m =
      internal::RemoveLine(summary.position_m, error, &summary.offset_m, &summary.slope_rad);
  summary.residual_rms_m = std::sqrt(summary.residual_m.squaredNorm() / static_cast<double>(n));
  summary.residual_peak_to_peak_m = summary.residual_m.maxCoeff() - summary.residual_m.minCoeff();

  const double samples_per_m = 1.0 / std::abs(step);
  summary.temporal = options.scan_speed_m_s > 0.0;
  const double rate = summary.temporal ? samples_per_m * options.scan_speed_m_s : samples_per_m;
  summary.psd = EstimatePsd(summary.residual_m, rate, options.welch, record, field);
  return summary;
}

}  // namespace stagefit::disturbance
