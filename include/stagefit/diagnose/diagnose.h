#pragma once
// Diagnose: where a model fails against a measurement, and which physical effect of the catalogue
// (model/effects.h) explains it.
//
// Procedure (docs/diagnose.md):
//  1. Baseline. The model's own parameters (default: every joint stiffness) are fitted to the
//     measurement; what remains is the error a missing effect has to explain.
//  2. Candidates. Every catalogued effect at every location where it applies is added to the baseline
//     model and fitted together with the model's parameters: first a short fit of every candidate
//     (screening), then a full fit of the most promising ones.
//  3. Ranking by the Bayesian information criterion of the weighted residuals against the baseline,
//         delta_BIC = n ln(error_after^2 / error_baseline^2) + k ln(n),
//     n = number of residuals (2 per used point), k = parameters the effect adds. Under the hypothesis
//     that the baseline's remaining error is measurement noise (independent between points), an effect
//     that only fits noise lowers n ln(error^2) by about k, less than its penalty k ln(n): BIC then
//     prefers the baseline, which is how diagnose avoids inventing explanations. An effect is
//     reported as explaining the data when delta_BIC < 0 AND it lowers the error by at least
//     `min_relative_improvement` (a systematic misfit that is not noise would otherwise let any
//     flexible effect "win" by a little).
//  4. Where. The bands and elements carrying the baseline's error, measured modes without a model
//     partner and model modes without a measured one (with the joint DoF holding their strain energy),
//     and the rigid-body consistency of the measurement: the share of the raw data that no rigid
//     motion of the instrumented body explains, per channel (a wrong sensor direction, a local mode).
//
// Fitting. The baseline is a full stiffness fit (fit::FitModel with its defaults: short first steps
// and basin probes), so that a mistuned model is not blamed on a missing effect. Candidates are
// screened with Ceres' long first steps (kDiagnoseTrustRegionRadius), which bring an effect's mass or
// stiffness near its value within a few iterations; a start already near its value (an extra body's
// from the band where the error is, a payload's and a servo's stiff start beside their long-step
// tries) is screened with short ones, which keep it there. The refined ones are finished with basin
// probes.

#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "stagefit/compare/mode_pairing.h"
#include "stagefit/compare/residuals.h"
#include "stagefit/fit/least_squares.h"
#include "stagefit/measurement/frf_data.h"
#include "stagefit/measurement/projection.h"
#include "stagefit/model/effects.h"
#include "stagefit/model/model_spec.h"

namespace stagefit::diagnose {

struct DiagnoseOptions {
  compare::ComparisonOptions comparison;
  /// The model's own parameters fitted in the baseline and with every candidate (--params patterns).
  std::vector<std::string> params = {"*.k.*"};
  /// The parameters of the effects already in the model are fitted too, in the baseline and with every
  /// candidate (model::WithEffectParameters): a second effect is then judged with the first one's
  /// parameters free, as the refit that adds it will hold them.
  bool refit_effects = true;
  /// ... except in the screening, which holds them where the baseline fitted them (their Jacobian
  /// columns are differenced: a joint offset in the model doubled a second round's screening).
  bool hold_effects_in_screening = true;
  /// Effects to try (catalogue names); empty = the whole catalogue.
  std::vector<std::string> effects;
  int screening_iterations = 4;   ///< iterations of the short fit of every candidate
  int num_refined = 5;            ///< candidates refitted fully after screening (docs/diagnose.md)
  int refine_iterations = 30;
  int num_second_starts = 3;      ///< leaders refitted from the model's parameters as given
  int baseline_iterations = 50;
  /// Starts of the refit of the model as given, without the leader's effect (procedure step 3, beside
  /// the refit from the leader's model parameters; fit::FitOptions::num_starts: the model as given and
  /// random draws within a factor 1.6). The baselines of two effect-free cases stopped at 1.4x the noise
  /// floor (seeds 1030, 1035), the refit from the leader's parameters did not reach it, and a payload
  /// was claimed; from three starts both refits reached the floor. Three starts for the first baseline
  /// fit reached it too, but changed the baselines that two extra bodies on the hexapod (seeds 1006,
  /// 2019) were found from, and both were lost (docs/diagnose.md).
  int refit_starts = 3;
  /// "The model as given" for the second starts (model parameter name -> value, SI): the starts from
  /// which the candidates that the baseline's bent parameters would trap are fitted again, and the
  /// refit without the leader's effect. Empty: the parameters of the model passed to Diagnose(). The
  /// loop passes those of the model the user gave it: the model it diagnoses has been fitted already.
  std::map<std::string, double> as_given;
  /// When the baseline stays more than this many times above the noise floor, every candidate is also
  /// screened from the model as given (not only those that add mass or move a joint): a baseline that
  /// has bent its stiffnesses far to mimic an effect holds the effect's own fit in its basin (a
  /// coupling in the hexapod: 1.33x the floor from the model as given, 26x from a baseline at 35x).
  /// 0 or an unknown floor: only the effects named in docs/diagnose.md get that start.
  double far_times_floor = 3.0;
  /// The leaders after the second starts are fitted on until converged (at most this many iterations,
  /// no probes): the rounds before stop at a budget, and the error a leader is reported with should be
  /// its optimum's.
  int num_polished = 2;
  int polish_iterations = 100;
  /// The candidates are searched (screening, refinement, second starts) on at most this many of the
  /// band's frequencies, every k-th of them; the leaders are then finished on all of them with
  /// `finish_iterations`, and every candidate is scored on all of them. 0: search on all.
  int max_search_frequencies = 400;
  /// The screening, and the scans that give it starts, run on at most this many of the band's
  /// frequencies (every k-th); each screened candidate is then scored on the search grid, which ranks
  /// them for the refinement. 0, or a search grid not larger: on the search grid. 200: the six two-effect
  /// loops of eval_loop's seeds 73000-73005 ended with the same effects in 0.91x the time, and on the
  /// fresh seeds 77000 two two-effect cases more were explained (docs/loop-history.md, Time).
  int max_screening_frequencies = 200;
  /// When > 0 and the noise floor is known: after the screening and again after the refinement, the
  /// model without a new effect is refitted from the model parameters of the `num_stop_starts` leaders'
  /// fits; when one such refit ends within this many times the noise floor, the diagnosis stops there:
  /// that model is its baseline, and no effect is sought (DiagnoseSummary::stopped_at_floor). Not
  /// tried on a baseline above far_times_floor, which an effect is missing from. 0: the
  /// search runs to its end. The loop passes its LoopOptions::rounds_above_times_floor: a model that
  /// near the floor ends its rounds anyway.
  double stop_at_times_floor = 0;
  int num_stop_starts = 2;
  /// The leaders' fits to convergence and the refits of the model without a new effect (the stop checks
  /// above and procedure step 3) stop where their error has fallen by less than 1e-4 of itself over this
  /// many iterations (fit::FitOptions::stall_iterations; 0: at their budget or Ceres' own tolerances).
  /// Traced in two two-effect loops, 11 of 34 fits of the leaders ran all their 100 iterations, crawling;
  /// stopped so, the 34 take 0.55x the time and end at most 1.2e-3 of their error higher (docs/diagnose.md).
  int stall_iterations = 10;
  int num_finished = 3;         ///< leaders finished on all frequencies after a thinned search
  int finish_iterations = 4;
  double min_relative_improvement = 0.05;  ///< error must fall by this share to count (header)
  /// Candidates fitted at the same time (each on its own thread, its FRF evaluations then on that
  /// thread alone); 0: common/parallel.h's MaxThreads(). The ranking does not depend on it.
  int num_threads = 0;
  std::function<void(const std::string&)> progress;  ///< one line per stage, for a terminal
};

struct Candidate {
  model::Effect effect;          ///< with its fitted parameters
  std::string with;              ///< the --with text that adds it: effect.ToString()
  double error_after = 0;        ///< SPEC §4 error after fitting effect + model parameters
  /// The noise floor of the measured side the candidate is compared with over the baseline's
  /// (compare::Comparison::CalcNoiseFloor(spec)); 1 but for an effect of the measured side (a channel's
  /// correction re-projects and re-weighs the measurement in compliance space). The candidate is judged
  /// by JudgedError(): a correction that only moves the floor down does not count as a better fit.
  double floor_ratio = 1;
  double delta_bic = 0;          ///< against the baseline (header); < 0 supports the effect
  int num_parameters = 0;        ///< parameters the effect adds: fitted ones, and held ones not at 0
  /// Effect parameters held at their value (not fitted): a channel is also tried turned as the other
  /// channels see it, every parameter of its sensor-geometry held (docs/diagnose.md).
  std::vector<std::string> held_parameters;
  bool helps = false;            ///< the criterion of the header is met
  bool refined = false;          ///< fully fitted (else screening only)
  std::map<std::string, double> model_parameters;  ///< fitted model parameters with the effect
  std::string explanation;       ///< words for a user (top candidates)
  /// Why the fitted effect is physically absurd (a payload heavier than the stack, an offset at the
  /// bound of its search range); such a candidate is not claimed (helps = false). Empty otherwise.
  std::string implausible;
};

/// The error a candidate is ranked and judged by against the baseline (delta_bic, helps): error_after /
/// floor_ratio, its error relative to its own noise floor in the baseline's units. Seed 200055 of
/// eval_loop (a3z turned 17 degrees, held right, 1.07x the floor like the noise-free truth): impact h1's
/// correction lowered the error by 12 %, 10 % of it by re-weighing the measurement (its floor 0.0301
/// against 0.0333), and was added, 0.020 off the truth.
inline double JudgedError(const Candidate& c) { return c.error_after / c.floor_ratio; }

/// Why a fitted effect is physically absurd, or empty: a payload or extra body heavier than the whole
/// stack (the sum of `baseline`'s body masses), or a length or angle parameter (a joint's stiffness
/// centre, a payload's CoM offset, a sensor's position or turn) within 1 % of the bound of its search
/// range, where a fit stops because it cannot go further (an extra body on the hexapod was taken for a
/// channel turned 34 degrees, its rx at the 0.6 rad bound, 12x the noise floor); or a body on a joint (extra-body) whose local mode sqrt(k/mass)
/// lies below `band_low_hz`, the lowest compared frequency (0: not checked): in the band such a body
/// stands still, so its fitted mass is not determined and its joint acts as a spring to the ground (a
/// cable between the granite and the hexapod was fitted as a 1078 kg body with a local mode at 1.3 Hz);
/// or what the effect's own catalogue entry finds absurd (model::EffectDefinition::implausible: a loss
/// factor that leaves its joint undamped); or a channel's correction that turns the channel against
/// what the measurement's own channels say (TurnAgainstTheChannels(), with `directions` of the
/// measurement under `baseline`'s geometry corrections, ChannelDirectionsUnder(); empty: not checked).
std::string ImplausibleBecause(const model::ModelSpec& baseline, const model::Effect& effect, double band_low_hz = 0,
                               const std::vector<measurement::ChannelDirectionEstimate>& directions = {});

/// The directions of `measurement`'s channels as the other channels' rigid-body motion gives them
/// (measurement::EstimateChannelDirections, no model involved; frame origin `p_WXo` unless the data
/// carry one, frequencies in [fmin_hz, fmax_hz]), with `corrections` (a model's geometry corrections)
/// applied to the declared geometry first: what the channels say under the corrections the model
/// already makes. Empty when the measurement has no raw channels with geometry (one given already
/// projected).
std::vector<measurement::ChannelDirectionEstimate> ChannelDirectionsUnder(
    const std::vector<model::GeometryCorrection>& corrections, const measurement::FrfData& measurement,
    const Eigen::Vector3d& p_WXo, double fmin_hz, double fmax_hz);

/// A turned direction is taken as against the channels when it leaves more than this many times the
/// share of the channel's readings that its declared direction leaves unexplained by the other
/// channels' rigid motion (ChannelDirectionEstimate::ResidualShareAlong). The same factor as
/// measurement::kRivalResidualRatio, by which a channel's declared direction must be worse than its
/// estimate for the channel to be named turned.
inline constexpr double kTurnAgainstChannelsRatio = 2.0;

/// Why `effect`, a correction of the measured side (model::EffectDefinition::measured_side_only)
/// applied to `baseline`, turns its channel against the measurement's own evidence, or empty: the
/// corrected direction leaves more than kTurnAgainstChannelsRatio times the declared direction's
/// residual share in `directions` (the measurement under `baseline`'s geometry corrections,
/// ChannelDirectionsUnder()). Where the other channels hardly tell the channel's direction (a flat
/// valley: the declared and the turned directions leave alike), nothing is found. Empty for an effect
/// of the model's side, a channel without an estimable direction, or no turn. Seed 83792 of eval_loop
/// (a payload and the hexapod's stiffness centre 64 mm off, noise per sensor channel): impact h10
/// turned 30 degrees took the place of the offset at 1.05x the noise floor, 0.033 off the noise-free
/// truth, while h10's own readings, against the other impacts' rigid motion, had the declared
/// direction right.
std::string TurnAgainstTheChannels(const model::ModelSpec& baseline, const model::Effect& effect,
                                   const std::vector<measurement::ChannelDirectionEstimate>& directions);

/// The length and angle parameters of `effect` a fit sets that lie within 1 % of the bound of their
/// search range on `baseline` (the check of ImplausibleBecause()), in catalogue order, with that range.
struct ParameterAtBound {
  std::string name;
  double value = 0;
  double lower = 0, upper = 0;
  const char* unit = "";  ///< "m" or "rad"
};
std::vector<ParameterAtBound> ParametersAtBounds(const model::ModelSpec& baseline, const model::Effect& effect);

/// A leader and its rigid limit (model::EffectDefinition::rigid_limit) at the same location are told
/// apart only when the limit's error is more than this share above the leader's.
constexpr double kRigidLimitTolerance = 0.01;

/// When the first of `candidates` helps and its effect has a rigid limit (an extra body: a payload) that
/// also helps, at the same location, with an error within kRigidLimitTolerance of the leader's, the
/// limit is moved first (the others keep their order): the data do not show the compliance, and the
/// simpler effect is named. A 7.4 kg payload on the hexapod (seed 17006, 150 Hz band) was fitted as an
/// extra body with its joint rigid in translation (local mode near 2 kHz) and its rocking invisible: the
/// two errors agreed to 3 digits (0.0374) and the extra body led on the last one. The spread of the
/// noise floor itself was 0.9 % there.
void NameRigidLimitFirst(std::vector<Candidate>* candidates);

/// The Euler angles (rx, ry, rz, rad; kinematics::EulerFromRotation) of the turn that carries a channel's
/// declared direction onto its estimated one, about their common normal; nullopt when the estimate is
/// not estimable or the two directions are parallel.
std::optional<Eigen::Vector3d> CalcChannelTurn(const measurement::ChannelDirectionEstimate& estimate);

/// The bands and elements of `result`, largest share first, at most `max_bands` and `max_elements`.
void SortWorst(const compare::ComparisonResult& result, size_t max_bands, size_t max_elements,
               std::vector<compare::BandError>* bands, std::vector<compare::ElementError>* elements);

/// The centre (geometric mean of its edges) of the band where `model`'s error against `comparison` is
/// largest; nullopt without bands. A missing lightly damped local mode leaves its error around its
/// frequency.
std::optional<double> WorstBandCentreHz(const compare::Comparison& comparison, const model::ModelSpec& model);

/// The error of a model on one raw channel of a measurement (an accelerometer or an impact): the median
/// over the channel's used elements in raw space (its row or column of the FRF matrix) of their errors
/// (compare::ElementError::error, sqrt(sum w^2 |e|^2 / sum w^2) over the element's points). A part the
/// model misses at one sensor raises its whole row and one element of each impact's column: the median
/// names the sensor alone. In compliance space every element mixes all channels (J_a and J_F), so such
/// a part is spread over the elements there; the raw channels show where it enters.
struct ChannelError {
  std::string name;        ///< "a1y", "h3"
  bool is_input = false;   ///< an impact (an input of the raw FRF matrix)
  int num_elements = 0;    ///< used elements on the channel
  double error = 0;
  /// error / the raw comparison's noise floor (NaN when the measurement has no coherence).
  double times_floor = std::numeric_limits<double>::quiet_NaN();
  /// error / the median of every channel's error: a model error that the whole stack shares (a missing
  /// payload) puts every channel near 1, a part missing at one sensor puts that sensor far above.
  double times_median = 0;
};

/// A channel stands out, and the verdicts name it, at this many times the median channel's error.
inline constexpr double kChannelStandsOut = 1.5;

/// The raw channels of `measurement`, worst first by ChannelError::error, of the model `spec`, compared
/// in raw space on the band and with the weights of `options` (its space is ignored), at most
/// `max_channels`. Empty when the measurement has no raw channels (given already projected) or the
/// raw comparison cannot be made (a channel on a body the model lacks, no significant element).
std::vector<ChannelError> WorstChannels(const model::ModelSpec& spec, const measurement::FrfData& measurement,
                                        const compare::ComparisonOptions& options, size_t max_channels);

/// The first two of `channels` (WorstChannels(), worst first) if they stand out (kChannelStandsOut):
/// the channels a verdict names.
std::vector<ChannelError> StandingOut(const std::vector<ChannelError>& channels);

/// The channels of StandingOut() in words, for a verdict: "a1y (3.1 x the floor), h3 (2.0 x)" (the
/// errors when there is no floor); empty when none stands out.
std::string ChannelWords(const std::vector<ChannelError>& channels);

/// Where an error is, in words, from bands and elements sorted worst first (SortWorst()): the first two
/// bands and three elements with their shares, "a-b Hz (s %), ...; elements O/I (s %), ...". The
/// verdicts and the loop's conclusion say it so.
/// With `channels` (WorstChannels()), those that stand out follow: "...; channels a2z (47.8 x the floor)".
std::string WhereWords(const std::vector<compare::BandError>& bands, const std::vector<compare::ElementError>& elements,
                       const std::vector<ChannelError>& channels = {});

/// The verdict's thresholds against the noise floor (compare::Comparison::CalcNoiseFloor()): at most
/// this many times the floor is done; above the second, with no candidate that helps or with the best
/// one still above it, something outside the catalogue is missing.
inline constexpr double kDoneTimesFloor = 1.2;

/// The verdicts' "where" names the worst element's own worst band (compare::ElementError::worst_band)
/// when that band holds more than this share of the element's error: a third, where an even spread
/// over the dozen bands of a test would put a twelfth.
inline constexpr double kElementBandShareNamed = 1.0 / 3;
inline constexpr double kOutsideTimesFloor = 2.0;

struct ModeMismatch {
  double measured_hz = 0;
  double model_hz = 0;
  double mac = 0;
  std::string dominant_dof;      ///< joint DoF holding most of the model mode's strain energy
};

struct DiagnoseSummary {
  double error_initial = 0;      ///< the model as given
  double error_baseline = 0;     ///< after fitting the model's own parameters
  int num_residuals = 0;
  model::ModelSpec baseline;     ///< the fitted model without effects
  std::vector<Candidate> candidates;   ///< ranked, best first
  bool effect_found = false;     ///< the best candidate helps
  /// The stage ("screening" or "refinement") after which the model without a new effect, refitted from a
  /// leader's model parameters, reached DiagnoseOptions::stop_at_times_floor and the search stopped;
  /// empty when it ran to its end. The candidates are then listed as that stage left them, not claimed.
  std::string stopped_at_floor;
  std::string verdict;           ///< one paragraph
  compare::NoiseFloor noise_floor;  ///< of the comparison (unknown without coherence)
  // Where.
  std::vector<compare::BandError> worst_bands;
  std::vector<compare::ElementError> worst_elements;
  /// The baseline's error on the raw channels, worst first (WorstChannels(), at most 6); empty for a
  /// measurement given already projected.
  std::vector<ChannelError> worst_channels;
  std::vector<ModeMismatch> mispaired_modes;
  std::vector<double> unpaired_measured_hz;
  std::vector<std::pair<double, std::string>> unpaired_model;  ///< frequency, dominant DoF
  /// Rigid-body consistency (measurement::CalcRigidConsistency about {X}); NaN / empty when the
  /// measurement has no channel geometry. The largest share over the bands of the data energy that
  /// no rigid motion explains (outputs and inputs), and the least consistent channels, worst first (at
  /// most 4): name, share (the channel's median over the bands), centre of its worst band.
  double rigid_residual_share = std::numeric_limits<double>::quiet_NaN();
  struct ChannelConsistency {
    std::string channel;
    double share = 0;
    double band_hz = 0;
  };
  std::vector<ChannelConsistency> inconsistent_channels;
  /// Channels whose direction, as the other channels' rigid-body motion gives it
  /// (measurement::EstimateChannelDirections), is more than 2 degrees off the declared one: name, angle
  /// and the share of the channel's energy that direction leaves unexplained, smallest first. When one
  /// channel is turned, the channels sharing its DoF are estimated off too (the turned one corrupts
  /// the motion they are checked against), but only the turned one's direction leaves no residual.
  struct TurnedChannel {
    std::string channel;
    double angle_deg = 0;
    double residual_share = 0;
  };
  std::vector<TurnedChannel> turned_channels;
  double time_s = 0;
  std::string BriefReport(int max_candidates = 8) const;
};

/// Runs the procedure of the header. Throws InputError for a measurement or options that the
/// comparison rejects; numerical trouble of individual candidates only drops those candidates.
DiagnoseSummary Diagnose(const model::ModelSpec& spec, const measurement::FrfData& measurement,
                         const DiagnoseOptions& options = {});

/// The baseline of `summary` with `candidate`'s effect applied and the model parameters fitted with it.
model::ModelSpec ApplyCandidate(const DiagnoseSummary& summary, const Candidate& candidate);

/// Relative step of ScanBandHz's grid: a lightly damped mode's dip in the error is a few % wide
/// (23005: 3 %, a body with 2 % damping).
inline constexpr double kModeScanStep = 0.01;

/// Where on a log grid from `from` to `to` (relative step `step`) the error of model_at(x) is lowest,
/// and that error; nullopt when no model of the grid could be evaluated. model_at is called from
/// several threads; a model it cannot build (it throws) is left out.
struct ScanMinimum {
  double at = 0;
  double error = 0;
};
std::optional<ScanMinimum> ScanLogGrid(const compare::Comparison& comparison, double from, double to, double step,
                                       const std::function<model::ModelSpec(double x)>& model_at);
/// The error of model_at(x) at each point of `grid` (+infinity where it cannot be built or evaluated);
/// model_at is called from several threads.
std::vector<double> ScanErrors(const compare::Comparison& comparison, const std::vector<double>& grid,
                               const std::function<model::ModelSpec(double x)>& model_at);
/// As ScanLogGrid, on the points of `grid`.
std::optional<ScanMinimum> ScanGrid(const compare::Comparison& comparison, const std::vector<double>& grid,
                                    const std::function<model::ModelSpec(double x)>& model_at);

/// Which point of a band scan's `errors` (ScanBandHz) to start from: the lowest, unless it is at an end
/// of the band, where the mode has left the band and the model is nearly the one without it; then the
/// deepest dip inside the band by its prominence (the lower of the highest errors on either side of it
/// before a point lower than it), or the lowest when there is no dip. nullopt when no error is finite.
/// 82366 of eval_loop (a 2.9 kg body on the hexapod at 91 Hz, 600 Hz band): the scan of a 1.5 kg body
/// was lowest at 5 Hz, 7.20x the floor (the baseline 7.15x), with its one deep dip at 91-93 Hz, 8.8x
/// between 11.6x and 12.4x; started at 5 Hz no start of the body came near it.
std::optional<size_t> BandScanPick(const std::vector<double>& errors);

/// The frequency, on a log grid of step kModeScanStep across `comparison`'s band, that BandScanPick()
/// picks from the errors of model_at(hz): the lowest, or the deepest dip inside the band when the
/// lowest is at its end; nullopt when no model of the grid could be evaluated. For a parameter that
/// sets a lightly damped mode, whose basin is a few % wide: a fit started outside it puts the mode
/// where it mimics something else. model_at is called from several threads.
std::optional<double> ScanBandHz(const compare::Comparison& comparison,
                                 const std::function<model::ModelSpec(double hz)>& model_at);

/// For an extra-body `candidate`: ScanBandHz over its rocking frequency sqrt(kr / (mass r^2)) (r =
/// kExtraBodyRadiusOfGyration), its other parameters and the model's held as fitted
/// (ApplyCandidate(summary, candidate)); nullopt for another effect, or when the best is within two
/// steps of the candidate's own rocking frequency. Diagnose() starts each extra-body leader's last fit
/// there too.
std::optional<double> ScanRockingHz(const compare::Comparison& comparison, const DiagnoseSummary& summary,
                                    const Candidate& candidate);

/// A servo stiffness that puts the stage's mode in the drive's direction inside the band is found like
/// a local mode: the baseline's stiffnesses bend to absorb the missing mode, and from there the fit of
/// the servo's k falls into another basin. The scan adds the servo to `spec` (the model as given).
/// The share by which the scan's minimum must lie below `spec`'s own error to count: 29009 (ty.Dy,
/// 3.2e8 N/m) 12.6 %, 31005 (ty.Dy, 1.2e8 N/m) 9.8 %; on eight effect-free cases 0-6.8 %.
inline constexpr double kServoScanMinDrop = 0.03;

/// A servo is also screened from this many times the catalogue's k (its mode about three times higher,
/// the drive nearly rigid), where the short fit approaches it from the model without it; from there
/// with long and with short first steps.
inline constexpr double kServoStiffStart = 10.0;

/// For a servo-stiffness `servo` (its k the catalogue's default): ScanLogGrid over its k from 1/100 to
/// 100 times that, in steps of 2 kModeScanStep (1 % in the mode's frequency), the servo added to
/// `spec`; the k of the lowest error when that error is at least kServoScanMinDrop below `spec`'s,
/// else nullopt (also for another effect). Diagnose() refines a servo from there whatever its screening.
std::optional<double> ScanServoStiffness(const compare::Comparison& comparison, const model::ModelSpec& spec,
                                         const model::Effect& servo);

/// A weak servo beside another effect, near the floor: the baseline's stiffnesses have absorbed the
/// drive's mode, so the error of the servo added to them only rises as its k falls, the scan on the
/// model as given is lost in that model's scattered stiffnesses, and the fits from the catalogue's k
/// fall into another basin (83132 of eval_loop: ry.Ry a spring of 4.8e7, beside a delay, 1.12x the
/// floor; no start of the servo came below the baseline, and the loop ended at 1.09x, 0.014 from the
/// noise-free truth). The profile of k: at each k of a grid the model's parameters and the servo's
/// damping ratio fitted with k held (kServoProfileIterations, short first steps, from
/// kServoProfileZeta). Its minimum lies near the truth's k where the free fits do not: on 83132's
/// state after the first round 0.93 of the baseline at 6e7 (refined: 4.8e7, 1.01x the floor); on
/// 83122's (ty.Dy 6.9e7 beside a hexapod coupling) 0.89 at 1e8 (refined: 6.7e7). In 83122's loop, after
/// the refit in band stages, the profile was lowest at 4e8 for two rounds, and the servo was named in
/// the fourth (1.01x, 0.0013 from the noise-free truth; unnamed at 1.09x before).
/// The grid: the catalogue's k times 2^j, j from kServoProfileFirstPower to kServoProfileLastPower
/// (above, the drive is as good as rigid: no profile of the four cases had its minimum there).
inline constexpr int kServoProfileFirstPower = -4;
inline constexpr int kServoProfileLastPower = 2;
/// The damping ratio the profile's fits start from: the generator's drive (3 % of critical with the
/// whole stack above it) is 0.13-0.25 of critical with the stage's own inertia, which the catalogue's
/// zeta refers to; from the catalogue's 0.02 the 10 iterations did not reach it.
inline constexpr double kServoProfileZeta = 0.05;
inline constexpr int kServoProfileIterations = 10;
/// The starts a profile gives the refinement at most: its lowest minimum can be in another basin
/// (83129: ty.Dy 7.2e7 beside a loss factor of rz, the profile lowest at 4e8, refined to 5.4e8 at 1.69x
/// the floor; its next minimum, at 1e8, refined to 5.8e7).
inline constexpr size_t kServoProfileStarts = 2;
/// A profile's starts for the refinement: the k of its lowest local minima (at most `max_starts`, the
/// lowest first), when its lowest lies kServoScanMinDrop below `baseline_error`; none otherwise.
/// `errors` on the grid's k in order; +infinity where the fit failed.
std::vector<size_t> ServoProfileStarts(const std::vector<double>& errors, double baseline_error, size_t max_starts);

/// A coupling between two DoF of a joint is as nonlinear as a local mode: a strong one (correlation
/// 0.76 between hexapod Dx and Ry, seed 33013) moves the joint's modes and their shapes, and a fit from no
/// coupling, on the baseline or on the model as given, stopped at 29x the noise floor (0.998, the
/// baseline at 0.836) while the scan on the model as given has its minimum at correlation 0.80, 0.507
/// against the next location's 1.42. The scan's grid: kCouplingScanSteps steps from minus to plus the
/// bound of the coupling's range (0.95 sqrt(k_a k_b), where the joint stays positive definite).
inline constexpr int kCouplingScanSteps = 40;
/// Of the couplings scanned, the one with the lowest minimum is refined from there when that minimum
/// lies kServoScanMinDrop below the model's error and below this share of the next location's: far
/// from the data every coupling lowers the model's error a little (33013, a3z corrected: 11-33 %, from
/// 2.13), the one in the data stands out (0.507 against the next's 1.42).
inline constexpr double kCouplingScanLead = 0.8;

/// For a coupled-stiffness `coupling`: ScanGrid over its k across its range (kCouplingScanSteps), the
/// coupling added to `spec`; the k of the lowest error and that error, or nullopt when no model of the grid could be evaluated (also for another effect).
std::optional<ScanMinimum> ScanCouplingStiffness(const compare::Comparison& comparison, const model::ModelSpec& spec,
                                                 const model::Effect& coupling);

/// Fits `effect` (parameters as starting values) together with `params` of `base`, returns the fit
/// summary and the fitted effect; `spec_out` (optional) receives the model with the effect applied.
struct EffectFit {
  model::Effect effect;
  fit::FitSummary summary;
  model::ModelSpec spec;
};

/// `comparison` on every k-th of its frequencies, k the smallest step that leaves at most
/// `max_frequencies` of them: the grid a diagnosis searches on (DiagnoseOptions::max_search_frequencies)
/// and the loop's refit from the model as given starts on. nullopt when it has no more than that (or
/// max_frequencies <= 0), or when no compared point is left on the thinned grid.
std::optional<compare::Comparison> ThinnedComparison(const compare::Comparison& comparison, int max_frequencies);

struct EffectFitOptions {
  int max_iterations = 30;
  bool probe_basins = false;           ///< end with fit::SolveWithProbes' basin probes
  std::vector<std::string> held;       ///< effect parameters that keep their value
  /// Ceres' first step. Long (the default) for candidates searched from afar: it gets an effect's mass
  /// or stiffness near its value within a few iterations. Short (1, the stiffness fit's) to finish a
  /// fit near its optimum: long first steps threw a turned sensor's fit, 0.3 rad from its start, into a
  /// basin at 3x the floor.
  double initial_trust_region_radius = 1e4;
  int stall_iterations = 0;  ///< fit::FitOptions::stall_iterations
};
EffectFit FitEffect(const model::ModelSpec& base, const compare::Comparison& comparison, const model::Effect& effect,
                    const std::vector<std::string>& params, const EffectFitOptions& options = {});

/// Several effects applied to `base` in order, their parameters all fitted together with the model's
/// (`params`), each effect's parameters within its search range (EffectParameterSpecs() around the
/// values given). `options.held` applies to every effect.
struct EffectsFit {
  std::vector<model::Effect> effects;
  fit::FitSummary summary;
  model::ModelSpec spec;
};
EffectsFit FitEffects(const model::ModelSpec& base, const compare::Comparison& comparison,
                      const std::vector<model::Effect>& effects, const std::vector<std::string>& params,
                      const EffectFitOptions& options = {});

}  // namespace stagefit::diagnose
