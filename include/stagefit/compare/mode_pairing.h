#pragma once
// Modes identified from FRFs with the complex mode indicator function (CMIF), and their pairing between
// a measurement and a model by the modal assurance criterion (MAC).
//
// CMIF: the singular values sigma_1(f) >= sigma_2(f) >= ... of H(f) (Nout x Nin) at each frequency.
// A mode shows as a peak of sigma_1; its shape estimate is the left singular vector u_1 at the peak
// (Nout, unit norm), which for a lightly damped, well separated mode is proportional to the mode
// shape seen by the outputs.
//  - Peaks: local maxima of sigma_1 (not at either end of the grid) whose prominence, sigma_1 at the
//    peak over the higher of the two bases (the lowest sigma_1 between the peak and the next higher
//    sample on each side, or the grid's end), is at least min_prominence (default sqrt(2): the
//    half-power points then exist on both sides).
//  - With a noise estimate (the amplitude SNR of sigma_1 at each frequency), a peak's prominence must
//    also exceed exp(noise_prominence / SNR) at the peak: where the data are noisy (the low end of an
//    accelerance), the noise alone makes peaks of sqrt(2) prominence, dozens of them on a fine grid.
//    1 / SNR is the standard deviation of ln sigma_1; a noise peak and its base are the extremes of
//    up to hundreds of samples, about three standard deviations up and down.
//    PairModes() takes the SNR of the measured sigma_1 at a frequency as the weight (SNR) of the used
//    element that dominates it there (the largest scaled |H|), when the comparison's weights are SNRs.
//  - Frequency: the vertex of the parabola through ln sigma_1 at the peak and its two neighbours, on
//    a ln f axis.
//  - Damping: half-power bandwidth, zeta = (f_2 - f_1) / (2 f_n), f_1 and f_2 where sigma_1 crosses
//    sigma_1,peak / sqrt(2), interpolated linearly between samples. This is the SDOF result for light
//    damping; the quantity's s^p factor shifts it by O(zeta^2).
//  - In the compliance space the rows and columns of the rotational DoF are scaled by a length L
//    (rotation_length_m, default 0.1 m: the size of the stage top) so that rad/Nm, m/Nm and m/N
//    compare as displacements per force at that lever arm, before the SVD.
// The model's modes are identified the same way from its FRF on the same grid and channels (the
// consistent choice: both shapes are then the same kind of vector), and each is labelled with the
// nearest natural frequency of model::CalcModes(). Pairs: MAC(u_meas, u_model) = |u_meas^H u_model|^2
// / ((u_meas^H u_meas)(u_model^H u_model)), greedily by decreasing MAC, a pair needing MAC >= min_mac
// (default 0.6); each mode is paired at most once.

#include <Eigen/Core>

#include <string>
#include <vector>

#include "stagefit/compare/residuals.h"
#include "stagefit/model/model_spec.h"

namespace stagefit::compare {

struct ModeIdentificationOptions {
  /// Minimum prominence of a sigma_1 peak (ratio, >= 1).
  double min_prominence = 1.4142135623730951;
  /// Length scaling the rotational DoF in the compliance space, m (> 0).
  double rotation_length_m = 0.1;
  /// Minimum MAC of a pair, in [0, 1].
  double min_mac = 0.6;
  /// With a noise estimate: a peak's prominence must exceed exp(noise_prominence / SNR) (header):
  /// 6 standard deviations of ln sigma_1.
  double noise_prominence = 6.0;
};

/// A mode found as a CMIF peak.
struct IdentifiedMode {
  double frequency_hz = 0;        ///< refined peak frequency, Hz
  double damping_ratio = 0;       ///< half-power estimate; NaN when a half-power point is off the grid
  double peak_singular_value = 0; ///< sigma_1 at the peak sample (unit of H, after scaling)
  int frequency_index = 0;        ///< the peak sample on the grid
  Eigen::VectorXcd shape;         ///< u_1 at the peak (Nout, unit norm, largest element real > 0)
  /// Model side only: the nearest mode of model::CalcModes() (index, frequency Hz, damping ratio,
  /// dominant joint DoF name); -1 / empty on the measured side.
  int model_mode = -1;
  double model_frequency_hz = 0;
  double model_damping_ratio = 0;
  std::string dominant_dof;
};

/// sigma_k(f) for every frequency: Nf x min(Nout, Nin), columns in decreasing order.
Eigen::MatrixXd CalcCmif(const std::vector<Eigen::MatrixXcd>& frf);

/// Modes of `frf` at `frequency_hz` (Hz, strictly increasing, Nf >= 3 for any peak), by the rules of
/// the header, ascending in frequency. `snr` (empty, or Nf values > 0): the amplitude SNR of sigma_1
/// at each frequency, for the noise rule of the header. Throws InputError when the sizes disagree or
/// an option is out of range.
std::vector<IdentifiedMode> IdentifyModes(const Eigen::VectorXd& frequency_hz,
                                          const std::vector<Eigen::MatrixXcd>& frf,
                                          const ModeIdentificationOptions& options = {},
                                          const Eigen::VectorXd& snr = Eigen::VectorXd());

/// MAC(a, b) = |a^H b|^2 / ((a^H a)(b^H b)), in [0, 1]; 0 when either vector is zero.
double CalcMac(const Eigen::VectorXcd& a, const Eigen::VectorXcd& b);

/// One measured/model pair.
struct ModePair {
  int measured = -1;            ///< index into ModePairing::measured
  int model = -1;               ///< index into ModePairing::model
  double mac = 0;
  double frequency_error = 0;   ///< (f_model - f_meas) / f_meas
  double damping_difference = 0;  ///< zeta_model - zeta_meas (NaN when either is unknown)
};

struct ModePairing {
  std::vector<IdentifiedMode> measured;
  std::vector<IdentifiedMode> model;
  Eigen::MatrixXd mac;                 ///< measured.size() x model.size()
  std::vector<ModePair> pairs;         ///< ascending in measured frequency
  std::vector<int> unpaired_measured;  ///< indices into `measured`
  std::vector<int> unpaired_model;     ///< indices into `model`

  /// A table: pairs (frequencies, damping, MAC, model DoF), then the unpaired modes of each side.
  std::string BriefReport() const;
};

/// Identifies the modes of the comparison's measured FRFs and of `model_frf` (the model on the same
/// grid, e.g. ComparisonResult::model) and pairs them. `spec` labels the model modes (CalcModes()).
/// Throws InputError for out-of-range options or a `model_frf` of the wrong size.
ModePairing PairModes(const Comparison& comparison, const std::vector<Eigen::MatrixXcd>& model_frf,
                      const model::ModelSpec& spec, const ModeIdentificationOptions& options = {});

}  // namespace stagefit::compare
