#pragma once
// The SPEC §4 error scalar between a model and a measurement: the one definition shared by compare, fit
// and diagnose (docs/error-metric.md gives the equations with their motivation).
//
// Comparison space.
//  - kCompliance (default): the 6x6 compliance at the compliance frame {X}. A measurement whose
//    channels carry geometry is projected with measurement::ProjectToFrame() about p_WXo (the
//    measurement's frame_origin_W, else the origin of the model's compliance frame):
//        H_X = pinv(J_a) H_L pinv(J_F'),
//    outputs Dx Dy Dz Rx Ry Rz, inputs Fx Fy Fz Mx My Mz, W axes. A measurement without geometry that
//    is already 6x6 is taken as projected (same convention). The model side is the motion of the
//    point p_WXo of the compliance frame's body under a force/torque at that point, W axes: the same
//    quantity the projection estimates.
//  - kRaw: the raw channels. Model outputs are sensors (body, position_W, direction_W) and inputs
//    forces built from the measurement's ChannelGeometry, so a measurement with its own geometry
//    needs no [[sensor]] or [[excitation]] entries in the model. The model's [[geometry_correction]]
//    entries (the sensor-geometry effect) move and turn the model's copies of those channels, so a
//    corrected geometry is fitted against the declared one.
//  - Geometry corrections in compliance space: the measurement is re-projected with the channels at
//    their corrected geometry (J_a, J_F rebuilt), with the points and weights chosen at Create() from
//    the declared geometry, so that errors with and without a correction are sums over the same points.
//    The weight of a point is its SNR again (below), |H_X| re-projected over the noise propagated at
//    Create(): an element that was significant only through the geometry error (cross-talk a turned
//    sensor put there) falls to its true SNR. When that leaves an off-diagonal element's median point
//    SNR below min_element_snr, the rule by which Create() drops noise elements, the element stops
//    counting (its weights are 0): a symmetric model's exact zero against measured noise would
//    otherwise leave a log error of ~30 per point, and the right correction would score worse than
//    none. A wrong sensor direction thus shows in both spaces. (A measurement given already projected
//    has no channels to correct.)
// Both sides are in the comparison quantity (the measurement's unless overridden). The ratio
// H_model / H_meas, hence the error, does not depend on the quantity: s^p cancels.
//
// Significance (which elements (o, i) are used). With G_oi = exp(mean_f ln|H_meas,oi(f)|), the
// log-mean (geometric-mean) magnitude of the MEASURED element over the comparison band's frequencies:
//  - compliance space: kappa_oi = exp(mean_f [ln|H_oi| - (ln|H_oo| + ln|H_ii|) / 2]), the coupling
//    coefficient |H_oi| / sqrt(|H_oo| |H_ii|) averaged on a log scale. It is dimensionless for every
//    pair of DoF (m/N, rad/Nm, m/Nm), 1 on the diagonal, <= 1 for a passive static compliance
//    (Cauchy-Schwarz), independent of the quantity, and the log mean is not dominated by a resonance
//    peak or an antiresonance dip;
//  - raw space: kappa_oi = G_oi / sqrt(max_j G_oj * max_k G_ki): the element against the strongest
//    element of its output row and of its input column (all raw elements share one unit).
// The element is used when kappa_oi >= significance_threshold (default 0.1 = -20 dB) and, when the
// measurement has coherence, an off-diagonal element also needs a median point weight (SNR, below)
// of at least min_element_snr (default 3) over the band: otherwise it is noise, not response. The diagonal
// (kappa = 1) is always kept; a strong coupling such as Dx-Ry of a stage whose centre of mass is
// above {X} has kappa ~ 0.1 ... 0.5; cross-talk of a symmetric stage is orders of magnitude below.
// |H| is floored at the smallest normal double before the logarithm (an exact zero gives kappa ~ 0).
//
// Weight per point (element, frequency).
//  - Without coherence: w = 1.
//  - Raw space with coherence gamma^2: w = min(SNR, cap), SNR = sqrt(gamma^2 / (1 - gamma^2)) (the
//    amplitude signal-to-noise ratio of an H1 estimate: |N|^2 / |S|^2 = (1 - gamma^2) / gamma^2), cap =
//    coherence_weight_cap (default 30, i.e. gamma^2 >= 0.99889 counts as noise-free). gamma^2 = 1
//    gives the cap, gamma^2 = 0 gives w = 0 (the point is dropped).
//  - Compliance space with coherence: the noise of each raw point, sigma_L = |H_L| / SNR_L, is
//    propagated through the linear projection as independent errors,
//        sigma_X(a, b)^2 = sum_{o, i} |P(a, o)|^2 |Q(i, b)|^2 sigma_L(o, i)^2,
//    P = pinv(J_a), Q = pinv(J_F'), and w = min(|H_X(a, b)| / sigma_X(a, b), cap).
//  Points whose measured value is exactly zero or whose weight is 0 are not used.
//
// Error. Per used point p, e_p = ln(H_model / H_meas) = ln|H_model / H_meas| + j arg(H_model / H_meas)
// (std::log: phase wrapped to (-pi, pi]), and
//     error = sqrt(sum_p w_p^2 |e_p|^2 / sum_p w_p^2).
// 0.01 means about 1 % in magnitude (|ln 1.01| = 0.00995).
//
// Residual vector (P used points, in element-major order: used element by used element, its
// frequencies ascending):
//     r = [Re(w_p e_p); Im(w_p e_p)] / sqrt(sum_p w_p^2)     (size 2P: all real parts, then all imaginary)
// so that error = ||r||_2, and its Jacobian with respect to parameters p_k in natural units (N/m,
// Nm/rad, N s/m, ...; the fit layer applies its own transforms):
//     de_p/dp_k = (dH_model/dp_k) / H_model,    J(:, k) = [Re(w de/dp_k); Im(w de/dp_k)] / sqrt(sum w^2).
//
// Thread safety: a Comparison is immutable after Create(); its const member functions assemble and
// evaluate the model in local workspaces and may be called from several threads.

#include <Eigen/Core>

#include <complex>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "stagefit/measurement/frf_data.h"
#include "stagefit/measurement/projection.h"
#include "stagefit/model/linear_system.h"
#include "stagefit/model/model_spec.h"
#include "stagefit/model/parameters.h"
#include "stagefit/response/frf_evaluator.h"

namespace stagefit::compare {

/// What one caller (one thread) reuses from one evaluation of a Comparison to the next: the storage of
/// the model's FRFs and derivatives (a fresh Nf x Nout x Nin x P derivative array costs more in page
/// faults than computing it), and the set-up of the last model evaluated (its eigendecomposition),
/// reused when the next model's system and the evaluator's options are the same to the bit: a fit's
/// accepted step evaluates the candidate's residuals, then the Jacobian at the same point.
struct ModelWorkspace {
  response::FrfWithDerivatives frf;
  /// The set-up of `system` with `options` (model::SecondOrderSystem and the options are compared
  /// whole, names included).
  response::FrfEvaluator& SetUp(const model::SecondOrderSystem& system, const response::FrfEvaluatorOptions& options);
  int num_setups = 0, num_reused = 0;  ///< set-ups made and reused (for tests and profiling)

 private:
  std::optional<response::FrfEvaluator> setup_;
  response::FrfEvaluatorOptions options_;
};

/// Where model and measurement are compared.
enum class ComparisonSpace {
  kCompliance,  ///< the 6x6 compliance at {X} (measurement projected with J_a and J_F)
  kRaw,         ///< the raw accelerometer x hammer channels
  /// Sensors on several bodies (a whole-stack test): each body's sensors projected to the 6 DoF of that
  /// body's centre of mass (measurement::ProjectPerBody), outputs "<body>.Dx" ... "<body>.Rz"; the
  /// impacts stay raw. Model side: the motion of each body's centre of mass under forces at the impacts.
  kBodies,
};

/// "compliance" | "bodies" | "raw"; throws InputError naming `context` (e.g. "--space") otherwise.
ComparisonSpace ParseComparisonSpace(const std::string& text, const std::string& context);
std::string ToString(ComparisonSpace space);

/// The space a measurement is compared in when none is asked for: sensors on one body (or no
/// geometry): compliance; sensors on several bodies: bodies. `reason` says why, for the user.
struct DefaultSpace {
  ComparisonSpace space = ComparisonSpace::kCompliance;
  std::string reason;
};
DefaultSpace ChooseDefaultSpace(const measurement::FrfData& measurement);

/// `measurement` with its channels moved and turned as `corrections` say (a model's sensor-geometry
/// effects, model::GeometryCorrection): where the comparison takes them to be. A correction naming no
/// channel of the measurement changes nothing.
measurement::FrfData WithGeometryCorrections(const measurement::FrfData& measurement,
                                             const std::vector<model::GeometryCorrection>& corrections);

/// Default significance threshold on kappa (header): 0.1 = -20 dB below the reference elements.
inline constexpr double kDefaultSignificanceThreshold = 0.1;
/// Default cap of the coherence-derived weight: SNR 30 (gamma^2 = 0.9989) is already a clean point;
/// without a cap a single gamma^2 = 1 point would carry unbounded weight.
inline constexpr double kDefaultCoherenceWeightCap = 30.0;

struct ComparisonOptions {
  ComparisonSpace space = ComparisonSpace::kCompliance;
  /// Comparison band, Hz (inclusive). The band used is the intersection with the measurement's
  /// frequencies; the defaults select all of them.
  double fmin_hz = 0.0;
  double fmax_hz = std::numeric_limits<double>::infinity();
  /// Elements with kappa >= this are used (header). In [0, 1]; 0 uses every element.
  double significance_threshold = kDefaultSignificanceThreshold;
  /// With coherence: an off-diagonal element whose median weight (the SNR of its points) over the band
  /// is below this is not used: it is noise, not response. 0 disables the rule.
  double min_element_snr = 3.0;
  /// Upper bound of the coherence-derived weight (> 0).
  double coherence_weight_cap = kDefaultCoherenceWeightCap;
  /// Ignore the measurement's coherence (w = 1 everywhere).
  bool use_coherence = true;
  /// Quantity in which both sides are held and reported; default the measurement's. The error does
  /// not depend on it.
  std::optional<measurement::FrfQuantity> quantity;
  /// Bands of the breakdown: 1 = octaves, 3 = third octaves (measurement::MakeFractionalOctaveBands).
  int bands_per_octave = 3;
  /// The model's responses are computed on the modal path unless it differs from a direct solve by
  /// more than this (relative) at the probe frequencies (response::FrfEvaluatorOptions::check_tolerance,
  /// >= 0). The comparison resolves log ratios of about 1e-4 at best (1 % noise), so 1e-8 is exact for
  /// it; the response layer's own 1e-10 sent a fifth of a diagnosis' candidate models (a stiffness
  /// probed at 1/8 of its value puts a mode near 0 Hz; modal and direct then differ by 1e-10..1e-8) to
  /// the direct solve per frequency, ten times slower (docs/diagnose.md). The probes look only at
  /// and above the comparison's lowest frequency (FrfEvaluatorOptions::lowest_frequency_hz).
  double frf_check_tolerance = 1e-8;
};

/// E|ln(1 + z)|^2 and E|ln(1 + z)|^4 for z a circular complex Gaussian with E|z|^2 = s^2: the squared log
/// error (and its square) that relative measurement noise of standard deviation s leaves at one point
/// between the noise-free truth and the measurement (docs/error-metric.md §8). For small s the first is
/// s^2 + s^4/2 + 2 s^6/3, the second 2 s^4; beyond, from a quadrature tabulated once. s >= 0.
struct LogErrorMoments {
  double m2 = 0;
  double m4 = 0;
};
LogErrorMoments ExpectedLogErrorMoments(double s);

/// E[min(dof / X, c^2)] for X a chi-square of `dof` (>= 2) degrees of freedom: the mean square of a weight
/// min(SNR_est, cap), with SNR_est^2 = SNR^2 dof / X estimated from a noise variance of `dof` degrees of
/// freedom, over SNR^2, where c = cap / SNR (docs/error-metric.md §8). dof / (dof - 2) far below the cap
/// (c large), c^2 far above it.
double MeanSquareWeightOverSnr(double dof, double c);

/// The error that the measurement's noise alone leaves: the error scalar of the noise-free truth
/// against the measurement, as its coherence says (docs/error-metric.md §8).
struct NoiseFloor {
  bool known = false;  ///< false without coherence (the noise is then unknown)
  double floor = 0;    ///< sqrt(E[error^2]) for the noise-free truth
  double sd = 0;       ///< standard deviation of that error from one noise draw to another
  int num_points = 0;  ///< points that carry it
};

/// "noise floor 0.0213 (sd 0.0002); model error 0.0456 = 2.14 x floor", or a line saying the floor is
/// unknown without coherence.
std::string NoiseFloorLine(double error, const NoiseFloor& floor);

/// One element (output o, input i) of the compared FRF matrix.
struct ElementIndex {
  int output = 0;
  int input = 0;
};

/// The error of one used element over the band.
struct ElementError {
  ElementIndex index;
  std::string name;          ///< "<output>/<input>", e.g. "Dx/Fx" or "a1x/h3"
  double significance = 0;   ///< kappa (header)
  int num_points = 0;
  double error = 0;          ///< sqrt(sum w^2 |e|^2 / sum w^2) over this element's points
  double share = 0;          ///< this element's part of sum w^2 |e|^2 (the shares sum to 1)
  double mean_log_magnitude = 0;  ///< w^2-weighted mean of Re(e) = ln|H_model/H_meas| (> 0: model too soft/large)
  double mean_phase_rad = 0;      ///< w^2-weighted mean of Im(e), rad
  /// The band holding the largest part of this element's error, and that part (0 when it has none).
  /// The bands' shares over all elements can be flat where one element's error is not: a lossy cable
  /// on the hexapod left 13-14 % in each of the two worst bands and 57 % in Dx/Fx.
  measurement::FrequencyBand worst_band;
  double worst_band_share = 0;
};

/// The error in one frequency band, over all used elements.
struct BandError {
  measurement::FrequencyBand band;
  int num_points = 0;
  double error = 0;
  double share = 0;
};

/// Everything Comparison::Evaluate() finds for one model.
struct ComparisonResult {
  double error = 0;                      ///< SPEC §4 error scalar
  std::vector<ElementError> elements;    ///< one per used element, in Comparison::used_elements() order
  std::vector<BandError> bands;          ///< bands holding at least one used point, ascending
  /// elements.size() x bands.size(): the error of element k in band b; NaN where it has no point.
  Eigen::MatrixXd element_band_error;
  /// The model on the comparison grid: num_frequencies() matrices of size num_outputs x num_inputs, in
  /// the comparison quantity.
  std::vector<Eigen::MatrixXcd> model;
  /// The measurement it was compared with (Comparison::MeasuredFor() the model): same layout.
  std::vector<Eigen::MatrixXcd> measured;

  /// The error, the `max_rows` worst elements and the `max_rows` worst bands, as a short table.
  std::string BriefReport(int max_rows = 8) const;
};

class Comparison {
 public:
  /// Prepares the comparison of models of `spec`'s layout (bodies, compliance frame) with
  /// `measurement` (which must have passed measurement::Validate()).
  /// Throws InputError (naming the measurement's source) when: the band holds no measured frequency;
  /// the compliance space is asked for a measurement without geometry that is not 6x6; the projection
  /// fails (channels without geometry, sensors on several bodies, unobservable DoF); the model has no
  /// compliance frame (compliance space); a channel's body is not in the model (raw space); no element
  /// is significant; an option is out of range.
  static Comparison Create(const model::ModelSpec& spec, const measurement::FrfData& measurement,
                           const ComparisonOptions& options = {});

  /// The SPEC §4 error scalar of the model `spec` (header). `spec` must keep the layout given to
  /// Create() (bodies and channels); parameters and effects may differ. Throws InputError when `spec`
  /// is invalid, NumericalError when the model's response is zero or not finite at a used point.
  double Error(const model::ModelSpec& spec) const;

  /// r (resized to num_residuals()) of the header, ||r|| = Error(spec). Same throws as Error().
  void Residuals(const model::ModelSpec& spec, Eigen::VectorXd* r) const;

  /// r and J = dr/dp (num_residuals() x params.size()), analytic from the response layer's
  /// derivatives, parameters in natural units. `params` come from model::ListParameters(spec) or
  /// model::MatchParameters(spec, ...). J may be null. Same throws as Error().
  void ResidualsAndJacobian(const model::ModelSpec& spec, const std::vector<model::ParameterInfo>& params,
                            Eigen::VectorXd* r, Eigen::MatrixXd* J) const;
  /// The same with the model's FRFs and derivatives held in `workspace` (one per thread), whose storage
  /// and last set-up are reused from call to call (ModelWorkspace): a fit loop then allocates nothing
  /// per evaluation, and decomposes the model once per point.
  void ResidualsAndJacobian(const model::ModelSpec& spec, const std::vector<model::ParameterInfo>& params,
                            Eigen::VectorXd* r, Eigen::MatrixXd* J, ModelWorkspace* workspace) const;
  /// The same with further columns after those of `params`, one per entry of `further`: derivatives of
  /// the model's dynamic stiffness (in the generalised coordinates of ModelSystem(spec)) with respect to
  /// parameters that change only M, C, K and K_loss, such as an effect's (diagnose differences the
  /// systems of two specs). Throws InputError when an entry is outside the system.
  void ResidualsAndJacobian(const model::ModelSpec& spec, const std::vector<model::ParameterInfo>& params,
                            const std::vector<response::DynamicStiffnessDerivative>& further, Eigen::VectorXd* r,
                            Eigen::MatrixXd* J, ModelWorkspace* workspace) const;

  /// r of `spec` with the model's responses given: `model_values` in the layout of
  /// response::FrfArray::values on frequency_hz() (the workspace's frf.frf.values after a call above). For a
  /// spec whose ModelSystem() equals that of the spec the values came from, and whose geometry
  /// corrections differ (compliance space: only the measured side moves); ||r|| = Error(spec) then.
  /// `delay_change_s` delays the given responses by that much more (e^{-j omega delay_change_s} at
  /// every point): for a spec whose system differs from theirs only in its delay.
  void ResidualsWithModelResponse(const model::ModelSpec& spec, const Eigen::MatrixXcd& model_values,
                                  Eigen::VectorXd* r, double delay_change_s = 0.0) const;

  /// The second-order system the model `spec` is compared through: its inputs and outputs are the
  /// compared channels (in raw space at the geometry `spec` corrects).
  model::SecondOrderSystem ModelSystem(const model::ModelSpec& spec) const;

  /// The error that the measurement's noise alone leaves (header of NoiseFloor): with the relative
  /// noise s_p = 1 / SNR_p of every used point (uncapped SNR from the coherence, propagated through the
  /// projection in compliance space),
  ///     floor^2 = sum_p w_p^2 m2(s_p) g_p / sum_p w_p^2,
  ///     sd(error^2)^2 = sum_p w_p^4 (m4(s_p) - m2(s_p)^2) / (sum_p w_p^2)^2,  sd = sd(error^2) / (2 floor).
  /// The coherence is taken as that of the FRF estimate (synthesize's), or turned into it with the hits
  /// averaged (FrfData::averages, estimate's: measurement::EstimateCoherence). g_p = 1, or with hits
  /// averaged MeanSquareWeightOverSnr(nu_p, cap / SNR_p) / min(1, (cap / SNR_p)^2): each weight is then
  /// an SNR estimated with nu_p = 2 (n - 1) degrees of freedom (pooled through the projection), and the
  /// error weighs the noise by it (docs/error-metric.md §8).
  NoiseFloor CalcNoiseFloor() const;
  /// The floor of the measurement as `spec` is compared with it. In compliance space a model with
  /// geometry corrections is compared with the measurement re-projected under them, each point weighed
  /// with its own projection's SNR (docs/error-metric.md §1): its floor is the formula above over those
  /// points, with the raw noise propagated through that projection. Equal to CalcNoiseFloor() for a
  /// spec whose corrections do not re-project the measurement.
  NoiseFloor CalcNoiseFloor(const model::ModelSpec& spec) const;

  /// The error with its breakdown by element and band, and the model's FRFs on the grid.
  ComparisonResult Evaluate(const model::ModelSpec& spec) const;

  /// The model's FRFs on the comparison grid (num_frequencies() matrices num_outputs x num_inputs).
  std::vector<Eigen::MatrixXcd> EvaluateModel(const model::ModelSpec& spec) const;

  ComparisonSpace space() const { return space_; }
  /// The response the model's FRFs are computed as (the measurement's quantity).
  response::ResponseQuantity response_quantity() const;
  /// The options of the model's FRF evaluations (their lowest frequency is the grid's).
  const response::FrfEvaluatorOptions& frf_options() const { return frf_options_; }
  measurement::FrfQuantity quantity() const { return quantity_; }
  /// Frequencies of the comparison grid (the measurement's within the band), Hz.
  const Eigen::VectorXd& frequency_hz() const { return frequency_hz_; }
  int num_frequencies() const { return static_cast<int>(frequency_hz_.size()); }
  const std::vector<std::string>& output_names() const { return output_names_; }
  const std::vector<std::string>& input_names() const { return input_names_; }
  int num_outputs() const { return static_cast<int>(output_names_.size()); }
  int num_inputs() const { return static_cast<int>(input_names_.size()); }
  /// The measurement on the grid, in the comparison space and quantity (num_frequencies() matrices),
  /// with the declared channel geometry.
  const std::vector<Eigen::MatrixXcd>& measured() const { return measured_; }
  /// The measurement `spec` is compared with: measured(), or in compliance space, when `spec` holds
  /// geometry corrections of the measurement's channels, the raw data re-projected with the corrected
  /// geometry (header); then `storage` holds it. Throws InputError when a corrected geometry cannot
  /// observe the six DoF.
  const std::vector<Eigen::MatrixXcd>& MeasuredFor(const model::ModelSpec& spec,
                                                   std::vector<Eigen::MatrixXcd>* storage) const;
  /// This comparison on the frequencies `kept` (ascending indices into frequency_hz()): the same
  /// elements, and their points and weights at those frequencies. Under a model's geometry corrections
  /// an off-diagonal element stops counting, as here, when its re-projected median SNR is below
  /// min_element_snr, and that is decided on this comparison's points, all of them: decided on a grid of
  /// every second frequency alone, an element whose median lies near the threshold counted there and not
  /// on the whole grid (seed 33013 of eval_loop, a3z corrected: Rx/Fx, 93 % of the thinned grid's error,
  /// 7.76 against 2.13 on the whole grid), and a diagnosis' search ranked its candidates by that element.
  /// Throws InputError when `kept` leaves no point.
  Comparison OnFrequencies(const std::vector<int>& kept) const;
  /// How many times the measured side under a model's geometry corrections (the raw data re-projected,
  /// its weights and the elements that stop counting) was taken from the sides computed lately for the
  /// same projection, and how many times it was computed; shared by this comparison's copies.
  std::pair<int, int> measured_side_reuse() const;
  /// The names of the channels whose geometry a sensor-geometry effect can correct: the raw outputs
  /// and inputs (in raw space, or in compliance space for a measurement projected here); empty for a
  /// measurement given already projected.
  std::vector<std::string> CorrectableChannels() const;
  /// The weight w of every point (num_frequencies() matrices num_outputs x num_inputs; 0 = unused).
  const std::vector<Eigen::MatrixXd>& weights() const { return weights_; }
  /// Whether the weights are the points' signal-to-noise ratios (from the coherence), rather than 1.
  bool weights_are_snr() const { return weights_are_snr_; }
  /// kappa of every element (num_outputs x num_inputs).
  const Eigen::MatrixXd& significance() const { return significance_; }
  /// The used elements, output-major (o ascending, then i).
  const std::vector<ElementIndex>& used_elements() const { return used_elements_; }
  /// "<output>/<input>".
  std::string ElementName(ElementIndex index) const;
  /// Number of used points P; num_residuals() = 2 P.
  int num_points() const { return static_cast<int>(points_.size()); }
  int num_residuals() const { return 2 * num_points(); }
  /// The point of the compliance projection, p_WXo (m, in W); compliance space only.
  const Eigen::Vector3d& frame_origin_W() const { return p_WXo_; }
  /// The model inputs/outputs that correspond to the compared channels.
  const std::vector<model::InputSpec>& model_inputs() const { return model_inputs_; }
  const std::vector<model::OutputSpec>& model_outputs() const { return model_outputs_; }

 private:
  struct Point {
    int element = 0;   // index into used_elements_
    int frequency = 0;
    double weight = 0;
    double snr = 0;  // uncapped signal-to-noise ratio (infinite: noise-free)
    // Degrees of freedom of the noise variance the point's weight is estimated with (infinite: known,
    // as a coherence that is the estimate's own gives it; measurement::FrfData::averages).
    double dof = std::numeric_limits<double>::infinity();
  };

  Comparison() = default;
  model::SecondOrderSystem BuildModelSystem(const model::AssembledModel& model) const;
  // The measured side for one model: values (MeasuredFor()) and the points' weights with their norm.
  struct MeasuredSide {
    const std::vector<Eigen::MatrixXcd>* declared = nullptr;  // measured_ as declared, or else
    std::vector<Eigen::MatrixXcd> reprojected;                // re-projected under the model's corrections
    std::vector<double> weights;                              // per point
    double norm = 1.0;                                        // sqrt(sum w^2)
    const std::vector<Eigen::MatrixXcd>& values() const { return declared ? *declared : reprojected; }
  };
  // The side for `spec`: a re-projected one from measured_side_cache_ when the same P and Q were
  // asked for lately, else computed (and cached).
  std::shared_ptr<const MeasuredSide> MeasuredSideFor(const model::ModelSpec& spec) const;
  // The points' weights with the measurement re-projected to `values` by P and Q (header).
  std::vector<double> ReprojectedWeights(const std::vector<Eigen::MatrixXcd>& values, const Eigen::MatrixXd& P,
                                         const Eigen::MatrixXd& Q) const;
  // num_outputs x num_inputs, 1 where a used off-diagonal element's median of `weights` (per point) is
  // below min_element_snr_: noise, not counted.
  Eigen::MatrixXi NoiseElements(const std::vector<double>& weights) const;
  // NoiseElements() of the measurement re-projected by P and Q.
  Eigen::MatrixXi NoiseElementsUnder(const Eigen::MatrixXd& P, const Eigen::MatrixXd& Q) const;
  // The projection H_X = P H_L Q of the raw channels under `spec`'s geometry corrections; false (P, Q
  // untouched) when the measurement is not re-projected for it.
  bool CorrectedProjection(const model::ModelSpec& spec, Eigen::MatrixXd* P, Eigen::MatrixXd* Q) const;
  // The raw measurement projected by P and Q into `storage` (returned): P H_k Q at every frequency k,
  // the real and imaginary parts each as one product over the whole grid (ProjectStacked()).
  const std::vector<Eigen::MatrixXcd>& Reproject(const Eigen::MatrixXd& P, const Eigen::MatrixXd& Q,
                                                 std::vector<Eigen::MatrixXcd>* storage) const;
  // e_p for every point, from the model's FRF values (layout of response::FrfArray::values) and the
  // measured side.
  void CalcLogErrors(const Eigen::MatrixXcd& model_values, const std::vector<Eigen::MatrixXcd>& measured,
                     Eigen::VectorXcd* e) const;
  // r (header) from the log errors and the side's weights.
  void WeightResiduals(const Eigen::VectorXcd& e, const MeasuredSide& side, Eigen::VectorXd* r) const;

  ComparisonSpace space_ = ComparisonSpace::kCompliance;
  measurement::FrfQuantity quantity_ = measurement::FrfQuantity::kAccelerance;
  std::string source_;
  Eigen::VectorXd frequency_hz_;
  std::vector<std::string> output_names_, input_names_;
  std::vector<Eigen::MatrixXcd> measured_;
  std::vector<Eigen::MatrixXd> weights_;
  Eigen::MatrixXd significance_;
  std::vector<ElementIndex> used_elements_;
  std::vector<Point> points_;
  double weight_norm_ = 1.0;  // sqrt(sum w^2)
  bool weights_are_snr_ = false;
  int bands_per_octave_ = 3;
  response::FrfEvaluatorOptions frf_options_;
  Eigen::Vector3d p_WXo_ = Eigen::Vector3d::Zero();
  std::vector<model::InputSpec> model_inputs_;
  std::vector<model::OutputSpec> model_outputs_;
  // Compliance space from raw channels: the raw data on the grid in the comparison quantity (raw_),
  // and the declared channel geometry, for re-projection under geometry corrections.
  std::vector<measurement::ChannelGeometry> raw_outputs_, raw_inputs_;
  // The same for the noise floor (Point::snr): (1 - gamma^2) |H_meas|^2, whose expectation is the noise
  // variance itself (Create()).
  std::vector<Eigen::MatrixXd> raw_noise_var_floor_;
  // The raw points' degrees of freedom, 2 (n - 1) for the n hits averaged per input (empty: infinite),
  // pooled through a re-projection as in Create() for the floor of a corrected model.
  Eigen::MatrixXd raw_dof_;
  // The raw data H_k (real and imaginary parts) and, with coherence, the raw channels' noise variance
  // (|H|^2 / SNR^2, the SNR at 1 / cap at least, Create(): the weights of a re-projected measurement
  // come from the noise its own projection propagates), frequency after frequency: raw outputs x (raw
  // inputs * frequencies), so that column k of a part seen as (outputs * inputs) x frequencies is
  // vec(H_k). A re-projection P H_k Q at every frequency is then one product by Q^T kron P rather than
  // two small products per frequency (a fit under a channel's correction re-projects at every
  // evaluation, and its differenced columns two times per parameter of the correction). Shared by the
  // copies; none without raw channels.
  struct RawStacked {
    Eigen::MatrixXd re, im, noise_var;  // noise_var empty without coherence
    Eigen::Index num_inputs = 0;
    Eigen::Index num_frequencies() const { return num_inputs > 0 ? re.cols() / num_inputs : 0; }
    // From the data per frequency (`noise_var` empty or one per frequency); null when `raw` is empty.
    static std::shared_ptr<const RawStacked> Stack(const std::vector<Eigen::MatrixXcd>& raw,
                                                   const std::vector<Eigen::MatrixXd>& noise_var);
    // The frequencies `kept` (ascending indices) alone.
    std::shared_ptr<const RawStacked> OnFrequencies(const std::vector<int>& kept) const;
  };
  std::shared_ptr<const RawStacked> raw_;
  // Each frequency's P H_k Q from a stacked part of H (RawStacked's layout, Q.rows() inputs per
  // frequency): column k of `out` is vec(P H_k Q) (P.rows() x Q.cols(), column-major).
  static void ProjectStacked(const Eigen::MatrixXd& P, const Eigen::MatrixXd& stacked, const Eigen::MatrixXd& Q,
                             Eigen::MatrixXd* out);
  double weight_cap_ = kDefaultCoherenceWeightCap;
  double min_element_snr_ = 0.0;  // ComparisonOptions::min_element_snr, applied again when re-projected
  // A comparison on some of its frequencies (OnFrequencies()): the whole one, which decides the
  // elements that stop counting under re-projection.
  std::shared_ptr<const Comparison> element_reference_;
  // The measured sides re-projected lately, most recent first, each with its P and Q (the side depends
  // on them alone). A fit evaluates many models under one correction: the residuals and then the
  // Jacobian at an accepted step, every differenced column of a parameter other than the correction's.
  // Shared by the copies of one comparison (they hold the same data) and by their threads.
  struct MeasuredSideCache {
    static constexpr size_t kCapacity = 16;
    struct Entry {
      Eigen::MatrixXd P, Q;
      std::shared_ptr<const MeasuredSide> side;
    };
    std::mutex mutex;
    std::vector<Entry> entries;
    int num_hits = 0, num_misses = 0;
  };
  std::shared_ptr<MeasuredSideCache> measured_side_cache_;
};

}  // namespace stagefit::compare
