#pragma once
// Projection of raw hammer-test FRFs (accelerometer channels x hammer impacts) onto the six rigid-body
// degrees of freedom of a frame, with the Jacobians of SPEC §2, conversion between accelerance,
// mobility and receptance, and a rigid-body consistency indicator.
//
// Notation: W world frame, X the frame projected to (the compliance frame {X}, or a body's centre of
// mass), S a sensor, E an impact (excitation). p_WXo is the origin of X in W; r = p_WS - p_WXo.
// DoF order Dx Dy Dz Rx Ry Rz; wrench order Fx Fy Fz Mx My Mz.
//
// Sensor Jacobian J_a (Nout x 6). A sensor at r measuring along the unit vector n sees the
// acceleration of a point of a rigid body, a_S = a_X + alpha x r, so its row is
//     J_a(i, :) = n' [I, -[r]x] = [n', (r x n)'],
// and a_L = J_a [a_X; alpha_X].
// Impact Jacobian J_F (Nin x 6). An impact at r along n with force f_i applies at X the wrench
// [n; r x n] f_i, so its row is J_F(i, :) = [n', (r x n)'] and F_X = J_F' F_L.
// With H_L = J_a H_X J_F' the rigid-body FRFs are recovered by least squares:
//     H_X = pinv(J_a) H_L pinv(J_F').
// For the SPEC §2 geometry these are the seed's equations (2.1) and (2.3).

#include <Eigen/Core>

#include <complex>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "stagefit/measurement/frf_data.h"

namespace stagefit::measurement {

/// Relative singular-value threshold below which a Jacobian direction counts as unobservable: a
/// singular value sigma_i < kObservabilityTolerance * sigma_max is treated as zero. 1e-6 keeps
/// geometries that are merely badly conditioned (condition number up to 1e6, i.e. a 1 m lever
/// against 1 um of placement precision) and rejects exactly degenerate ones.
inline constexpr double kObservabilityTolerance = 1e-6;

/// J_a (channels.size() x 6) of sensors relative to the origin p_WXo (m, in W): row i is
/// [n_i', (r_i x n_i)'] with r_i = channels[i].position_W - p_WXo and n_i = channels[i].direction_W.
/// Throws InputError when a channel has no geometry (empty body) or a direction that is not a unit
/// vector (tolerance 1e-6).
Eigen::MatrixXd CalcSensorJacobian(const std::vector<ChannelGeometry>& channels,
                                   const Eigen::Vector3d& p_WXo);

/// J_F (channels.size() x 6) of impacts relative to p_WXo (m, in W): row i is [n_i', (r_i x n_i)'],
/// so that the wrench at X is F_X = J_F' F_L. Same checks as CalcSensorJacobian().
Eigen::MatrixXd CalcImpactJacobian(const std::vector<ChannelGeometry>& channels,
                                   const Eigen::Vector3d& p_WXo);

/// Checks that a Jacobian J (N x 6) observes all six DoF (rank 6 by the SVD, with
/// kObservabilityTolerance). Otherwise throws InputError "<what>: the geometry cannot observe
/// <DoF list> (...)", naming the DoFs that dominate the null space: for an orthonormal null-space
/// basis V0 (6 x r), DoF k is named when (V0 V0')(k, k) > 0.1, with its share printed, e.g.
/// "Dx (1.00), Dy (1.00), Rz (1.00)". `what` names the data and side (e.g. "'m.mat': sensors").
void CheckObservable(const Eigen::MatrixXd& J, const std::string& what);

/// True when J (N x 6) observes all six DoF by that rule, without a message.
bool Observes6(const Eigen::MatrixXd& J);

/// Moore-Penrose pseudo-inverse by the SVD (singular values below kObservabilityTolerance *
/// sigma_max are dropped).
Eigen::MatrixXd PseudoInverse(const Eigen::MatrixXd& J);

/// Projects raw FRFs to the 6 DoF of the frame {X} at every frequency:
///     H_X(f) = pinv(J_a) H_L(f) pinv(J_F'),
/// with J_a and J_F built about p_WXo = raw.frame_origin_W if the data gives it, else
/// `default_p_WXo` (m, in W; usually the model's {X} origin). Result: Nf matrices 6 x 6, outputs
/// named Dx Dy Dz Rx Ry Rz, inputs Fx Fy Fz Mx My Mz, both at p_WXo with the W axes as directions
/// (rotations: the axis about which they turn); same frequencies and quantity as `raw`; no coherence
/// (it does not carry through a least-squares combination); frame_origin_W = p_WXo.
/// Throws InputError when a channel lacks geometry, when the sensors (or impacts) are on more than
/// one body (use ProjectPerBody()) or when J_a or J_F cannot observe all 6 DoF (the message names the
/// unobservable DoF).
FrfData ProjectToFrame(const FrfData& raw, const Eigen::Vector3d& default_p_WXo);

/// What ProjectPerBody() does with the inputs.
enum class InputProjection {
  kRaw,      ///< keep the raw impacts as inputs
  kBodyCom,  ///< project the impacts on each body to that body's wrench at its centre of mass
};

/// Projects per body (SPEC §3, sensors on several bodies): the sensors on body b give J_a,b about
/// that body's centre of mass p_WBcm[b] (m, in W), and the outputs become the 6 DoF of each body, in
/// the order in which the bodies first appear among the outputs, named "<body>.Dx" ... "<body>.Rz".
/// With InputProjection::kBodyCom the impacts are treated the same way (inputs "<body>.Fx" ...
/// "<body>.Mz"), otherwise the inputs are the raw impacts. Per block of bodies (b, c):
///     H_bc(f) = pinv(J_a,b) H_L[rows of b, cols of c](f) pinv(J_F,c')   (pinv(J_F,c') = I if raw).
/// Throws InputError when a channel lacks geometry, a body has no entry in p_WBcm, or a body's
/// sensors (impacts) cannot observe its 6 DoF (the message names the body and the DoF).
FrfData ProjectPerBody(const FrfData& raw, const std::map<std::string, Eigen::Vector3d>& p_WBcm,
                       InputProjection inputs = InputProjection::kRaw);

/// Power k such that H_quantity = (j*omega)^k * H_receptance: receptance 0, mobility 1,
/// accelerance 2.
int DifferentiationOrder(FrfQuantity quantity);

/// Factor (j*2*pi*f)^(order(to) - order(from)) that converts an FRF at frequency_hz (Hz, > 0) from
/// one quantity to another, e.g. accelerance -> receptance: 1/(j*omega)^2 = -1/omega^2.
std::complex<double> ConversionFactor(double frequency_hz, FrfQuantity from, FrfQuantity to);

/// Returns `data` converted to `to` (every FRF multiplied by ConversionFactor()); coherence and
/// geometry unchanged. Throws InputError when a frequency is not > 0.
FrfData ConvertQuantity(const FrfData& data, FrfQuantity to);

/// A frequency band [low_hz, high_hz), Hz.
struct FrequencyBand {
  double low_hz = 0.0;
  double high_hz = 0.0;
  double centre_hz() const;  ///< geometric centre sqrt(low * high)
};

/// Fractional-octave bands (bands_per_octave = 1: octaves, 3: third octaves) with centres
/// 1000 * 2^(k / bands_per_octave) Hz and edges at centre * 2^(+-1/(2 bands_per_octave)), every band
/// that overlaps [min_hz, max_hz], in increasing order. Throws InputError when 0 < min_hz <= max_hz
/// does not hold or bands_per_octave < 1.
std::vector<FrequencyBand> MakeFractionalOctaveBands(double min_hz, double max_hz,
                                                     int bands_per_octave);

/// The index into `bands` (increasing, as MakeFractionalOctaveBands() gives them) of the band that
/// holds each of `frequency_hz`: [low_hz, high_hz), the last band closed at its high edge; -1 for a
/// frequency in none.
std::vector<int> BandOfEachFrequency(const Eigen::VectorXd& frequency_hz, const std::vector<FrequencyBand>& bands);

/// How well a rigid body explains raw data, per channel and band (see CalcRigidConsistency()).
struct RigidConsistency {
  std::vector<FrequencyBand> bands;        ///< Nb bands (only bands holding frequencies)
  std::vector<std::string> output_names;   ///< Nout
  std::vector<std::string> input_names;    ///< Nin
  /// Nout x Nb: share of output channel i's energy in band b that no rigid motion of {X} explains,
  /// sum_{f in b, j} |R_out(i, j)|^2 / sum_{f in b, j} |H_L(i, j)|^2, R_out = (I - J_a pinv(J_a)) H_L.
  Eigen::MatrixXd output_residual_share;
  /// Nin x Nb: the same for input channel j, R_in = H_L (I - J_F pinv(J_F)).
  Eigen::MatrixXd input_residual_share;
  Eigen::VectorXd output_overall;  ///< Nb: ||R_out||_F^2 / ||H_L||_F^2 summed over the band
  Eigen::VectorXd input_overall;   ///< Nb: ||R_in||_F^2 / ||H_L||_F^2 summed over the band

  /// A table: one line per band with the overall shares and the worst output and input channel.
  std::string BriefReport() const;
};

/// Rigid-body consistency indicator of raw FRFs about {X} (origin as in ProjectToFrame()): the share
/// of the data energy that the rigid projection cannot explain, per output channel, per input
/// channel and overall, aggregated over `bands` (empty: third-octave bands over the data range). A
/// share near 0 means the channels move as one rigid body in that band; a local mode, a flexible
/// mount or a wrong sensor direction raises the share of the channels concerned. Shares are 0 for a
/// band whose data energy is 0. A residual is shared by the channels that observe the same DoF:
/// with the SPEC §2 layout, the 8 in-plane channels observe Dx Dy Rz with 5 redundant channels, so a
/// defect on one of them shows mostly on that channel; the 4 vertical channels observe Dz Rx Ry with
/// a single redundancy, so a defect on one of them shows on all four. Throws InputError as
/// ProjectToFrame() does.
RigidConsistency CalcRigidConsistency(const FrfData& raw, const Eigen::Vector3d& default_p_WXo,
                                      const std::vector<FrequencyBand>& bands = {});

/// The same per body, for sensors on several bodies (a whole-stack test): each output channel against
/// the rigid motion of its own body, projected from that body's sensors about its centre of mass
/// p_WBcm (every sensor body needs 6 observable DoF). Inputs are not checked (impacts on one body
/// rarely observe its six DoF): input_names empty, input_overall 0. Throws InputError naming the body.
RigidConsistency CalcRigidConsistencyPerBody(const FrfData& raw, const std::map<std::string, Eigen::Vector3d>& p_WBcm,
                                             const std::vector<FrequencyBand>& bands = {});

/// A channel's direction as the other channels' rigid-body motion explains it (see
/// EstimateChannelDirections()).
struct ChannelDirectionEstimate {
  std::string name;
  bool is_impact = false;
  bool estimable = false;           ///< false when the other channels cannot observe all six DoF
  Eigen::Vector3d declared_W = Eigen::Vector3d::Zero();   ///< unit vector, as the data declare it
  Eigen::Vector3d estimated_W = Eigen::Vector3d::Zero();  ///< unit vector (declared when not estimable)
  double angle_rad = 0.0;           ///< angle between the two
  /// Share of the channel's (weighted) energy that the fitted direction leaves unexplained. Near the noise
  /// when the other channels are right; when one of them is off (a turned vertical sensor corrupts the
  /// motion the other three vertical ones see), the estimates of the channels that share its DoF are off
  /// too, but only the off channel's own fit leaves no residual.
  double residual_share = 0.0;
  /// The same share left by the declared direction (its gain fitted): what freeing the direction
  /// explains is declared_residual_share - residual_share.
  double declared_residual_share = 0.0;
  /// The least-squares problem of the estimate, sum |h - d' a|^2 = d' normal d - 2 rhs' d + energy
  /// (zero when not estimable).
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  double energy = 0.0;
  /// The share of the channel's energy that `direction_W` leaves with its best gain fitted (the
  /// declared direction's is declared_residual_share, the estimate's residual_share); 1 when not
  /// estimable or for a zero direction.
  double ResidualShareAlong(const Eigen::Vector3d& direction_W) const;
};

/// Model-free estimate of every channel's direction from raw FRFs of one rigid body. For sensor i the
/// rigid motion of {X} is projected from the other sensors, U = pinv(J_a without row i) H_L without row
/// i (6 x Nin per frequency), and the direction d minimising
///     sum_f sum_j |H_L(i, j) - d' A_i U(:, j)|^2,    A_i = [I, -[r_i]x],
/// is a real linear least-squares problem. It is not normalised per frequency: the points of most
/// energy (resonances, and the high end of an accelerance) are those of best SNR, while weighting every
/// frequency alike let the noise of an accelerance's low end in (15.4 degrees came out as 17.8, and
/// right channels up to 3 degrees off, at 1-3 % noise). An impact is the
/// transpose (the wrench response G = H_L without column j times pinv(J_F' without column j), the
/// force direction d minimising sum |H_L(:, j) - G [I; [r_j]x] d|^2). The estimate is returned
/// normalised: a turned channel shows its true direction, a right one its declared direction to within
/// the noise. Frequencies outside [fmin_hz, fmax_hz] are not used. Needs geometry on every channel
/// (throws InputError as ProjectToFrame() does).
std::vector<ChannelDirectionEstimate> EstimateChannelDirections(const FrfData& raw, const Eigen::Vector3d& default_p_WXo,
                                                                double fmin_hz = 0.0,
                                                                double fmax_hz = std::numeric_limits<double>::infinity());

/// FindTurnedChannel()'s rivals: the other corrections that leave the other channels consistent with
/// less than this many times the named channel's residual_share. On 69013 of eval_loop (a2z turned 15
/// degrees beside a hexapod coupling, 600 Hz) a2z and a4z left 0.00602 and 0.00584 (1.03x): the top
/// plate moves almost as one in its plane there, and a horizontal share of either vertical sensor
/// explains the error alike; a4z was named, the wrong one. On 1200 further seeds of that generator
/// (200000-200599 and 201000-201599, 281 with a turned channel) 23 named channels had a rival within
/// 2x (1.02-1.85x, all vertical sensors, all in 600 Hz bands), and the least residual was right in
/// each; singled out, the next rival left 3.0x (60040), 5.6x (65011) and 6.7x (65019). Factor 2 as in
/// the declared-residual rule below.
inline constexpr double kRivalResidualRatio = 2.0;

/// The channel most likely turned, of those EstimateChannelDirections() puts more than `min_angle_rad`
/// off their declared direction. Each is corrected in turn (its declared direction replaced by its
/// estimate) and the others estimated again: of the corrections that leave every other channel within
/// `min_angle_rad`, the channel with the least residual_share; `rivals` (when given) gets the others of
/// those whose residual_share is below kRivalResidualRatio times its own (least first): the channels
/// the rigid motion hardly tells from it. A turned channel corrupts the motion the
/// channels sharing its DoF see, so they look turned too, by less, and can have as little residual: on
/// seed 45020 of eval_loop a1x was turned 23 degrees and a4x estimated 10.4 degrees off with residual
/// share 0.0020 against a1x's 0.0021; corrected, a1x leaves the others near their declared directions,
/// a4x leaves a1x off. The four vertical channels observe three DoF with one redundancy, and correcting
/// either of two of them can leave the others consistent (seed 60040: a3z turned 12 degrees, a1z and
/// a3z both 11.7 degrees off): the residual decides there (0.0037 against 0.0112).
/// When no correction leaves the others consistent, only a channel whose declared direction leaves at
/// least twice the residual of its estimate (declared_residual_share) is named, the one that leaves the
/// others least off. On 1200 cases of eval_loop's generator (seeds 100000-101199, 1-3 effects, 1-3 %
/// noise) the inconsistent pick was wrong in 12 cases: sound impacts (h1, h5) and a sound accelerometer
/// estimated 11-24 degrees off in 150 Hz bands whose motion hardly shows their direction (freeing it
/// lowered their residual by 1.6-5 %), each leaving another channel 10-34 degrees off; it was right in
/// 3, two of them with declared residuals 117x and 427x their estimates' (geometry_correction_test's
/// FindTurnedChannel tests; a channel not named is still a candidate of the diagnosis). nullopt when no
/// channel is that far off or none is named so. Throws as EstimateChannelDirections().
std::optional<ChannelDirectionEstimate> FindTurnedChannel(const FrfData& raw, const Eigen::Vector3d& default_p_WXo,
                                                          double min_angle_rad, double fmin_hz = 0.0,
                                                          double fmax_hz = std::numeric_limits<double>::infinity(),
                                                          std::vector<ChannelDirectionEstimate>* rivals = nullptr);

}  // namespace stagefit::measurement
