#pragma once
// FRF estimation from raw hammer-test time data (force and response records, several hits per impact
// location), with FFTW.
//
// Per input (impact location) j, output channel i and frequency bin k, with F_h and X_h the DFTs of
// the windowed force and response of hit h and sums over the hits used:
//     G_ff = sum |F_h|^2,  G_xx = sum |X_h|^2,  G_fx = sum conj(F_h) X_h  (G_xf = conj(G_fx)),
//     H1 = G_fx / G_ff,    H2 = G_xx / G_xf,    gamma^2 = |G_fx|^2 / (G_ff G_xx) = H1 / H2.
// H1 is unbiased by noise on the response, H2 by noise on the force; gamma^2 (0..1) drops where noise
// or non-linearity dominates (antiresonances, zeros of the force spectrum). With one hit gamma^2 = 1.
// The estimate of n hits written out (EstimationSummary::frf) holds gamma^2 with n per input
// (FrfData::averages): its noise is not gamma^2's but (1 - gamma^2) / ((n - 1) gamma^2) relative
// (EstimateCoherence()), what the comparison's weights and noise floor take. With a single hit on
// some input no coherence is written.
//
// Windows (t measured from the start of each record; t0 = start of the detected impact pulse):
// - Force window (force only): 1 on [t0 - taper, t0 + length], half-cosine tapers of `taper` seconds
//   on both sides, 0 elsewhere. It removes the force channel's noise between impacts.
// - Exponential window w(t) = exp(-(t - t0)/tau) for t >= t0 (1 before), applied to the response AND
//   the force. Because (h * f)(t) w(t) = ((h w) * (f w))(t), the estimate is then exactly the FRF of
//   the system whose impulse response is h(t) exp(-t/tau): every pole s_r = -sigma_r + j omega_d,r
//   moves to -(sigma_r + 1/tau) + j omega_d,r. The window adds the decay rate 1/tau (1/s), i.e. an
//   apparent modal damping ratio of about 1/(tau omega_n). Correct identified modes with
//   CorrectExponentialWindowDamping(): sigma_true = sigma_measured - 1/tau, so to first order
//   zeta_true = zeta_measured - 1/(tau omega_n).

#include <Eigen/Core>

#include <complex>
#include <optional>
#include <string>
#include <vector>

#include "stagefit/measurement/frf_data.h"

namespace stagefit::measurement {

/// One hammer hit: the force record and the simultaneous response records of all output channels.
struct HammerHit {
  Eigen::VectorXd force;     ///< Ns samples, N (positive along the impact direction)
  Eigen::MatrixXd response;  ///< Ns x Nout samples, SI units of the response quantity
};

/// Raw hammer-test time data (see measurements/README.md for the file layout).
struct RawHammerData {
  double sample_rate_hz = 0.0;                       ///< Hz, > 0
  /// Quantity of the FRFs the response gives: accelerometers -> kAccelerance (m/s^2 records),
  /// velocity -> kMobility (m/s), displacement -> kReceptance (m).
  FrfQuantity quantity = FrfQuantity::kAccelerance;
  std::vector<ChannelGeometry> outputs;              ///< Nout response channels
  std::vector<ChannelGeometry> inputs;               ///< Nin impact locations
  std::vector<std::vector<HammerHit>> hits;          ///< [input][hit], every record Ns samples
  /// Full-scale range per output channel in the response's SI unit (|x| <= range); empty or
  /// entries <= 0 = not declared.
  Eigen::VectorXd response_full_scale;
  /// Full-scale range of the force channel per input, N; empty or entries <= 0 = not declared.
  Eigen::VectorXd force_full_scale;
  std::optional<Eigen::Vector3d> frame_origin_W;     ///< origin of {X} in W, m, if given
  std::string source;                                ///< file it came from (for messages)

  int num_outputs() const { return static_cast<int>(outputs.size()); }
  int num_inputs() const { return static_cast<int>(inputs.size()); }
  /// Samples per record (0 without hits).
  int num_samples() const;
};

/// Largest accepted record length and total sample count (a larger file is rejected as bad input
/// rather than exhausting memory): 2^26 samples per record, 2^28 samples in all (2 GiB of doubles).
inline constexpr long long kMaxRawSamplesPerRecord = 1LL << 26;
inline constexpr long long kMaxRawSamplesTotal = 1LL << 28;

/// Checks: sample rate finite and > 0; at least one output, one input and one hit per input; every
/// record the same length Ns >= 16 and within the limits above; all samples finite; no force record
/// that is all zero (names input and hit); no response channel that is all zero in every hit of
/// every input (a dead channel, named); names present and unique; full-scale vectors empty or of
/// the right size; geometry either absent (empty body) or with unit directions (1e-6).
/// Throws InputError naming data.source, the field, the value and what was expected.
void Validate(const RawHammerData& data);

/// Which estimator goes into EstimationSummary::frf.
enum class FrfEstimator { kH1, kH2 };

/// Options of EstimateFrf().
struct EstimationOptions {
  FrfEstimator estimator = FrfEstimator::kH1;
  /// Force window: apply it at all.
  bool apply_force_window = true;
  /// Force window flat length after the pulse start, s; 0 = automatic: max(3 pulse widths,
  /// 8 samples).
  double force_window_s = 0.0;
  /// Force window cosine taper length, s; 0 = automatic: max(1 pulse width, 4 samples).
  double force_taper_s = 0.0;
  /// Exponential window time constant tau, s; 0 = no exponential window.
  double exp_tau_s = 0.0;
  /// Band of the estimate, Hz: DFT bins f_k = k fs / Ns, k >= 1, with min <= f_k <= max;
  /// max 0 = up to Nyquist.
  double min_frequency_hz = 0.0;
  double max_frequency_hz = 0.0;
  /// Pulse detection: the pulse is the run of samples around the force peak with
  /// |f| >= pulse_threshold * peak.
  double pulse_threshold = 0.05;
  /// Double hit: a second force peak above double_hit_ratio * first peak, more than one pulse width
  /// outside the first pulse (before or after it).
  double double_hit_ratio = 0.1;
  /// Overload: a sample with |x| >= overload_fraction * full-scale range (when declared), or a
  /// flat top: clip_run_samples or more consecutive equal samples (within 1e-9 of the record's
  /// peak) at |x| >= 0.9 * the record's peak.
  double overload_fraction = 0.98;
  int clip_run_samples = 5;
  /// Usable band of an input: the bins where the force autospectrum averaged over its hits is within
  /// force_band_db dB of its largest value (a hammer tip excites a limited band). Hit coherence and
  /// the low-coherence warning are evaluated there only.
  double force_band_db = 20.0;
  /// Poor hit: the hit's coherence with the others (see HitDiagnostics::hit_coherence) is below.
  double min_hit_coherence = 0.9;
  /// Low-coherence warning: an input whose averaged gamma^2 is below low_coherence in more than
  /// low_coherence_share of its (output, bin) points in its usable band gets a warning.
  double low_coherence = 0.8;
  double low_coherence_share = 0.1;
  /// Exclude flagged hits (double hit, overload, poor coherence) from the averages. When every hit
  /// of an input is flagged, all are kept and a warning says so.
  bool exclude_flagged = false;
};

/// Diagnostics of one hit (indices 0-based; reports print them 1-based).
struct HitDiagnostics {
  int input = 0;
  int hit = 0;
  double peak_force_n = 0.0;      ///< N, signed peak of the force record
  double impact_time_s = 0.0;     ///< s from the record start to the pulse start
  double pulse_width_s = 0.0;     ///< s, duration of |f| >= pulse_threshold * peak
  bool double_hit = false;
  double second_peak_ratio = 0.0; ///< largest |f| outside the pulse / |peak|
  double second_peak_time_s = 0.0;
  bool force_overload = false;
  std::vector<int> overloaded_outputs;  ///< output channels that overloaded or clipped
  /// How well the other hits of this input predict this one, in the input's usable band
  /// (EstimationOptions::force_band_db): for each other hit g,
  ///     c_hg = 1 - sum_{i,k} |X_h,i(k) - (X_g,i(k) / F_g(k)) F_h(k)|^2 / sum_{i,k} |X_h,i(k)|^2
  /// (clamped to [0, 1]), and hit_coherence is the upper median of c_hg over g, so that one bad hit
  /// does not spoil the others' figures. 1 when the input has a single hit; with two hits both get
  /// the same figure (the data cannot tell which one is bad).
  double hit_coherence = 1.0;
  bool poor_coherence = false;
  bool rejected = false;          ///< left out of the averages
  std::vector<std::string> messages;  ///< one line per flag

  bool flagged() const {
    return double_hit || force_overload || !overloaded_outputs.empty() || poor_coherence;
  }
};

/// Result of EstimateFrf().
struct EstimationSummary {
  /// The estimate chosen by EstimationOptions::estimator, with coherence and the hits averaged per
  /// input (FrfData::averages; neither when an input has a single hit), geometry and frame origin of
  /// the raw data; source = the raw data's source.
  FrfData frf;
  std::vector<Eigen::MatrixXcd> h1;  ///< Nf matrices Nout x Nin
  std::vector<Eigen::MatrixXcd> h2;  ///< Nf matrices Nout x Nin
  std::vector<HitDiagnostics> hits;  ///< every hit, input by input
  std::vector<std::string> warnings;
  std::vector<HitDiagnostics> rejected_hits;  ///< the hits left out of the averages
  std::vector<int> hits_used;        ///< Nin: hits averaged per input
  /// Decay rate the exponential window adds, 1/s (0 without the window): the added damping ratio
  /// at a frequency f is added_decay_rate_1_s / (2 pi f).
  double added_decay_rate_1_s = 0.0;
  double frequency_resolution_hz = 0.0;

  /// A few lines: sizes, windows, added damping at 10/100/1000 Hz, hits used, each flagged hit
  /// with its number and reason, and the warnings.
  std::string BriefReport() const;
};

/// Estimates H1, H2 and gamma^2 from raw hammer data (see the file comment for the equations and
/// windows). Calls Validate(data). Each record is transformed with one FFTW plan (r2c, Ns points,
/// made once and reused). Throws InputError for invalid data or options (a non-positive tau, a band
/// without DFT bins, thresholds outside (0, 1)).
EstimationSummary EstimateFrf(const RawHammerData& data, const EstimationOptions& options = {});

/// A mode's natural frequency (Hz) and damping ratio.
struct ModalParameters {
  double natural_frequency_hz = 0.0;
  double damping_ratio = 0.0;
};

/// Damping ratio the exponential window exp(-t/tau) adds to a mode at natural frequency f:
/// 1 / (tau 2 pi f). Throws InputError unless tau > 0 and f > 0.
double ExponentialWindowAddedDamping(double natural_frequency_hz, double tau_s);

/// Removes the exponential window's effect from a mode identified on windowed data: the identified
/// pole -zeta_m omega_m + j omega_m sqrt(1 - zeta_m^2) has its decay rate reduced by 1/tau,
///     sigma = zeta_m omega_m - 1/tau,  omega_d = omega_m sqrt(1 - zeta_m^2),
///     omega_n = sqrt(sigma^2 + omega_d^2),  zeta = sigma / omega_n
/// (exact; to first order zeta = zeta_m - 1/(tau omega_m)). Throws InputError unless tau > 0,
/// f > 0, 0 <= zeta_m < 1 and sigma >= 0 (a measured damping below what the window adds means the
/// mode was not identified from data with this window).
ModalParameters CorrectExponentialWindowDamping(const ModalParameters& measured, double tau_s);

}  // namespace stagefit::measurement
