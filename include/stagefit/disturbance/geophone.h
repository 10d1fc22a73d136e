#pragma once
// Ground motion from geophone (velocity sensor) voltages.
//
// A geophone is a mass on a spring whose velocity relative to its case is read by a coil; from the
// case velocity v to the coil voltage u:
//   T(s) = u/v = G s^2 / (s^2 + 2 zeta w0 s + w0^2)     [V/(m/s)],   w0 = 2 pi f0,
// times an optional amplifier gain g (V/V). With ground displacement x, v = s x, so for PSDs
//   S_u(f) = g^2 |T(j w)|^2 w^2 S_x(f),   w = 2 pi f,
// and the correction is S_x(f) = S_u(f) / (g^2 |T(j w)|^2 w^2) (undefined at f = 0).

#include <Eigen/Dense>

#include <complex>
#include <string>
#include <string_view>
#include <vector>

#include "stagefit/disturbance/spectral_density.h"

namespace stagefit::disturbance {

/// Parameters of a geophone and its amplifier.
struct GeophoneModel {
  std::string name;                         ///< e.g. "L-4C"
  double natural_frequency_hz = 1.0;        ///< f0 > 0, Hz
  double damping_ratio = 0.28;              ///< zeta > 0 (open-circuit or shunted, as installed)
  double generator_constant_v_s_m = 276.8;  ///< G > 0, V/(m/s)
  double amplifier_gain = 1.0;              ///< g > 0, V/V
};

/// Sercel L-4C: f0 = 1 Hz, zeta = 0.28, G = 276.8 V/(m/s) (nominal values; shunting the coil
/// changes the damping, so use the calibration sheet of the actual sensor when there is one).
GeophoneModel L4cGeophone();
/// Sercel L-22D: f0 = 2 Hz, zeta = 0.57, G = 88 V/(m/s) (nominal values, same caveat).
GeophoneModel L22Geophone();

/// "L-4C" or "L-22" (also "L4C", "L22", "L-22D", case-insensitive) to the nominal model. Throws
/// InputError naming `context` for anything else.
GeophoneModel GeophoneByName(std::string_view name, std::string_view context);

/// Throws InputError (naming `context` and the field) unless every parameter is finite and > 0.
void ValidateGeophone(const GeophoneModel& geophone, std::string_view context);

/// g T(j 2 pi f) in V/(m/s), the equation above, at f >= 0 Hz.
std::complex<double> CalcGeophoneResponse(const GeophoneModel& geophone, double frequency_hz);

/// |u/x|^2 = g^2 |T(j w)|^2 w^2 in V^2/m^2 at f >= 0 Hz: the factor from a ground displacement PSD
/// to the geophone voltage PSD.
double CalcGeophoneDisplacementGain2(const GeophoneModel& geophone, double frequency_hz);

/// Ground displacement PSD (m^2/Hz) from the PSD of the geophone voltage (V^2/Hz) by
/// S_x = S_u / (g^2 |T|^2 w^2). The DC bin (f = 0, where the sensor has no gain) is dropped: the
/// result holds the bins with f > 0, other fields copied. Throws InputError on an invalid model.
Spectrum CalcGroundDisplacementPsd(const Spectrum& voltage_psd, const GeophoneModel& geophone);

}  // namespace stagefit::disturbance
