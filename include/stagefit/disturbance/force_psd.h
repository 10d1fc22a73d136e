#pragma once
// Disturbance force PSD from a measured motion PSD and the sensitivity of that motion to the force:
//   S_F(f) = S_x(f) / |H(j 2 pi f)|^2,
// H the transfer function from the force to the measured motion (e.g. m/N for a displacement and a
// force, or any consistent pair of units), given at the PSD's frequencies. The model layer provides H
// from the dynamic model's FRFs; here it is a plain vector of complex values.

#include <Eigen/Dense>

#include <string>
#include <vector>

#include "stagefit/disturbance/spectral_density.h"

namespace stagefit::disturbance {

struct ForcePsdOptions {
  /// Bins where |H| < min_relative_sensitivity * max|H| are flagged unreliable: a small error in H
  /// or a noise floor in S_x there becomes a large error in S_F.
  double min_relative_sensitivity = 1e-3;
};

struct ForcePsdSummary {
  Spectrum force_psd;              ///< S_F at the motion PSD's bins, (unit of force)^2/Hz;
                                   ///< quiet NaN where H = 0
  std::vector<bool> reliable;      ///< one per bin: false where flagged (see ForcePsdOptions)
  std::vector<std::string> warnings;  ///< one per contiguous band of flagged bins, with its range
  std::string BriefReport() const;
};

/// Computes S_F = S_x / |H|^2 bin by bin. motion_psd: K bins; sensitivity: K complex values of H at
/// motion_psd.frequency_hz. `record` names the data in messages. Throws InputError when the sizes
/// differ, a value of H or S_x is NaN/Inf, S_x < 0, H is zero everywhere, or
/// min_relative_sensitivity is not in [0, 1).
ForcePsdSummary EstimateForcePsd(const Spectrum& motion_psd, const Eigen::VectorXcd& sensitivity,
                                 const ForcePsdOptions& options, const std::string& record);

}  // namespace stagefit::disturbance
