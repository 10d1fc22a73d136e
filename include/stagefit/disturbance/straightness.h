#pragma once
// Straightness of a translation stage: the vertical or lateral error e(x) measured along a scan of
// the stage position x. The best straight line e = a + b x (the mounting tilt of the reference and
// a constant offset) is removed by least squares first; the residual is the stage's straightness
// error, whose PSD is given versus spatial frequency (cycles/m) or, for a scan at speed v, versus
// temporal frequency f = v nu (Hz), with S_t(f) = S_s(nu) / v.

#include <Eigen/Dense>

#include <string>

#include "stagefit/disturbance/spectral_density.h"

namespace stagefit::disturbance {

struct StraightnessOptions {
  WelchOptions welch;            ///< segmenting of the residual (resolution in cycles/m or Hz)
  double scan_speed_m_s = 0.0;   ///< v > 0: PSD versus time frequency (Hz); 0: versus cycles/m
};

struct StraightnessSummary {
  double offset_m = 0.0;              ///< a: fitted error at x = 0, m
  double slope_rad = 0.0;             ///< b: fitted tilt (small angle), rad
  Eigen::VectorXd position_m;         ///< N evenly spaced positions the residual is given at, m
  Eigen::VectorXd residual_m;         ///< N values e - (a + b x), m
  double residual_rms_m = 0.0;        ///< rms of the residual, m
  double residual_peak_to_peak_m = 0.0;
  bool temporal = false;              ///< psd versus Hz (true) or cycles/m (false)
  Spectrum psd;                       ///< m^2/Hz or m^2/(1/m); frequency_hz holds Hz or 1/m
  std::string BriefReport() const;
};

/// Analyses one error channel. position_m: N >= 8 strictly monotonic positions, m; error_m: N
/// errors, m. When the spacing is uneven (any step departs from the mean step by more than 1 %), the
/// error is first interpolated linearly onto N evenly spaced positions spanning the same range.
/// Throws InputError naming `record` and `field` for NaN/Inf, mismatched sizes, non-monotonic
/// positions, a zero range, a negative speed or a record too short for the Welch options.
StraightnessSummary AnalyseStraightness(const Eigen::VectorXd& position_m,
                                        const Eigen::VectorXd& error_m,
                                        const StraightnessOptions& options,
                                        const std::string& record, const std::string& field);

}  // namespace stagefit::disturbance
