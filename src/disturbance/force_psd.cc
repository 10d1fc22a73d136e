#include "stagefit/disturbance/force_psd.h"

#include <cmath>
#include <limits>
#include <sstream>

#include "stagefit/common/error.h"

namespace stagefit::disturbance {

std::string ForcePsdSummary::BriefReport() const {
  std::ostringstream out;
  size_t flagged = 0;
  for (bool ok : reliable) flagged += ok ? 0 : 1;
  out << "force PSD at " << reliable.size() << " bins, " << flagged << " flagged unreliable";
  for (const std::string& w : warnings) out << "\nwarning: " << w;
  return out.str();
}

ForcePsdSummary EstimateForcePsd(const Spectrum& motion_psd, const Eigen::VectorXcd& sensitivity,
                                 const ForcePsdOptions& options, const std::string& record) {
  const Eigen::Index k_count = motion_psd.psd.size();
  if (sensitivity.size() != k_count || motion_psd.frequency_hz.size() != k_count) {
    std::ostringstream message;
    message << record << ": the sensitivity has " << sensitivity.size()
            << " values for a motion PSD of " << k_count << " bins, expected one per bin";
    throw InputError(message.str());
  }
  if (!(options.min_relative_sensitivity >= 0.0 && options.min_relative_sensitivity < 1.0)) {
    throw InputError(record + ": min_relative_sensitivity = " +
                     std::to_string(options.min_relative_sensitivity) + ", expected 0 <= value < 1");
  }
  double peak = 0.0;
  for (Eigen::Index k = 0; k < k_count; ++k) {
    const double f = motion_psd.frequency_hz[k];
    if (!std::isfinite(sensitivity[k].real()) || !std::isfinite(sensitivity[k].imag())) {
      std::ostringstream message;
      message << record << ": sensitivity at bin " << k << " (" << f << " Hz) is " << sensitivity[k]
              << ", expected a finite complex value";
      throw InputError(message.str());
    }
    if (!std::isfinite(motion_psd.psd[k]) || motion_psd.psd[k] < 0.0) {
      std::ostringstream message;
      message << record << ": motion PSD at bin " << k << " (" << f << " Hz) is "
              << motion_psd.psd[k] << ", expected a finite value >= 0";
      throw InputError(message.str());
    }
    peak = std::max(peak, std::abs(sensitivity[k]));
  }
  if (peak == 0.0) throw InputError(record + ": the sensitivity is zero at every frequency");

  ForcePsdSummary summary;
  summary.force_psd = motion_psd;
  summary.reliable.assign(static_cast<size_t>(k_count), true);
  const double threshold = options.min_relative_sensitivity * peak;
  for (Eigen::Index k = 0; k < k_count; ++k) {
    const double magnitude = std::abs(sensitivity[k]);
    summary.force_psd.psd[k] = magnitude > 0.0 ? motion_psd.psd[k] / (magnitude * magnitude)
                                               : std::numeric_limits<double>::quiet_NaN();
    summary.reliable[k] = magnitude >= threshold && magnitude > 0.0;
  }
  for (Eigen::Index k = 0; k < k_count;) {
    if (summary.reliable[k]) {
      ++k;
      continue;
    }
    Eigen::Index end = k;
    double smallest = std::abs(sensitivity[k]);
    while (end + 1 < k_count && !summary.reliable[end + 1]) {
      ++end;
      smallest = std::min(smallest, std::abs(sensitivity[end]));
    }
    std::ostringstream w;
    w << record << ": |sensitivity| below " << options.min_relative_sensitivity
      << " of its peak from " << motion_psd.frequency_hz[k] << " to " << motion_psd.frequency_hz[end]
      << " Hz (" << end - k + 1 << " bins, down to " << smallest / peak
      << " of the peak): the force PSD there is not meaningful";
    summary.warnings.push_back(w.str());
    k = end + 1;
  }
  return summary;
}

}  // namespace stagefit::disturbance
