#pragma once
// The loop of the README as one call: fit the model's parameters, diagnose, add the best effect of
// the catalogue with its fitted state, refit, and again, until the model is at the noise floor or no
// effect of the catalogue helps (docs/diagnose.md, "The loop").
//
// Each round's diagnosis starts from the model the previous round ended with: its baseline is that
// model refitted, and its best candidate is applied with the candidate's whole fitted state (effect
// parameters and the model's parameters, diagnose::ApplyCandidate()), so the round reproduces the
// candidate's error before its own refit. The refit then runs from two starts and keeps the better:
// that state with the model's parameters (`params`) freed, and the model as given with every effect
// added so far, all their parameters fitted again together with the model's (diagnose::FitEffects()).
// Inside a round's diagnosis the effects already added are refitted with each candidate
// (DiagnoseOptions::refit_effects).

#include <functional>
#include <limits>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "stagefit/compare/residuals.h"
#include "stagefit/diagnose/diagnose.h"
#include "stagefit/fit/least_squares.h"
#include "stagefit/measurement/frf_data.h"
#include "stagefit/model/model_spec.h"

namespace stagefit::diagnose {

struct LoopOptions {
  /// The comparison, the model's parameters (`params`) and the effects tried (`effects`) of every round.
  DiagnoseOptions diagnose;
  /// The fits of the model's parameters: the first one, and the refit after each added effect.
  fit::FitOptions fit;
  int max_rounds = 4;  ///< rounds of diagnosis at most, each adding one effect at most
  /// A round runs while the error is above this many times the noise floor; the model is confirmed
  /// within kDoneTimesFloor (1.2x). A correct model's error lies within 1.05x of the floor (its
  /// standard deviation is about 1 % of it), so 1.16x is a dozen standard deviations above: a servo
  /// stiffness of ry.Ry absorbed by the stiffnesses at 1.16x the floor was 0.022 off the noise-free
  /// truth, and found at 1.01x when a round ran. 1.06 (six standard deviations) rather than 1.1: 43020
  /// of eval_loop (a 38 kg payload on rz among three effects) stopped at 1.098x, 0.0169 off the truth,
  /// and a round from there found the payload (1.03x, 0.0058); four plate modes outside the catalogue
  /// that ended at 1.05-1.10x ran that round and still added nothing.
  double rounds_above_times_floor = 1.06;
  /// The relocation step (RelocateEffects()) runs after the rounds above rounds_above_times_floor,
  /// and for a payload or an extra body alone (model::EffectDefinition::adds_mass) from this many times
  /// the noise floor up to it. Near the floor a mass effect can stand for the one in the data: a body
  /// whose local mode lies just above the band reads in it as a payload, a body on the next joint moves
  /// nearly as the body does. Of the 128 two-effect loops of sets 82920-83086, 23 ended between 1.035x
  /// and 1.06x, 11 of them with a mass effect added; five of the 23 were misses, three of those a mass
  /// effect of the wrong kind or place (83040, 83060, 83074), which the step moves to the truth (1.06x
  /// -> 1.01x, 1.05x -> 1.01x, 1.04x -> 1.03x). The step costs 20-65 s a loop; the other effects are not
  /// sought again there, and neither of the other two misses was an effect in the wrong place. From
  /// 1.03x the step would run in 16 of the 128 loops for the same three.
  double relocate_above_times_floor = 1.035;
  /// The turned-channel step, right after the first fit (faults of the test bench before faults of
  /// the model: seed 57020's a3z turned 24 degrees was taken for two effects by the rounds before the
  /// step corrected it, 1.48x the floor; checked first, 0.94x) and again after the rounds when the
  /// first did not correct a channel: a channel whose direction, as the other channels'
  /// rigid-body motion gives it (measurement::EstimateChannelDirections, no model involved), is more
  /// than this many degrees off the declared one, and of the channels that far off the one whose
  /// correction leaves the others consistent (measurement::FindTurnedChannel), is added as a
  /// sensor-geometry correction held at that turn with no offset (the history names with it any channel
  /// whose correction fits the rigid motion nearly as well, measurement::kRivalResidualRatio, as the
  /// one to check next on the bench), in that refit and every later one
  /// (model::Effect::held), and the model refitted; kept unless the error rises by more than `turned_channel_max_rise`. In
  /// compliance space a turned accelerometer is often absorbed by the stiffnesses at the noise floor
  /// (15 degrees: 1.03x the floor, 2.8 % off the noise-free truth), while its direction estimate stands
  /// out (15.3 degrees; sound channels of six effect-free cases at most 0.8). With effects in the data,
  /// sound impacts were estimated 6.1 and 6.3 degrees off (seeds 5004, 9018 of eval_loop) and their
  /// corrections raised the error by 0.4 % and 1.3 %; turned channels were estimated 11.8-19.8 degrees
  /// off, within 0.3 degrees of their turns, and their corrections raised it by up to 2.1 % (13012,
  /// 15008, 15011) or lowered it. The error alone does not tell them apart; the angle does. 0: no such
  /// step.
  double turned_channel_deg = 10.0;
  /// The largest relative rise of the error with which a turned-channel correction is kept (the noise
  /// floor's standard deviation is about 1 % of it).
  double turned_channel_max_rise = 0.03;
  /// Rounds run after holding the parameters an added effect ran to the bound of their range
  /// (HoldParametersAtBounds) when the loop ends at the noise floor with them; 0: no such step.
  int hold_rounds = 2;
  /// The starts of the first fit's second route near the floor (FitFromSeveralStarts); 1 or less: no
  /// such step.
  int first_fit_starts = 4;
  /// A state of the loop to go on from: the model as given with the effects the loop added after its
  /// own, fitted (a model a loop wrote, or the state before a later step). Its effects beyond the
  /// given model's are the loop's own: they earn their place, merge, move and are dropped as a
  /// round's are. The first fit and the turned-channel check before the rounds are left out (the
  /// history's second step is "resumed"); the rounds and the steps after them run as usual. Unset:
  /// from the model as given. Its effects must begin with the given model's.
  std::optional<model::ModelSpec> resume_from;
  std::function<void(const std::string&)> progress;  ///< one line per step, for a terminal
};

/// Throws InputError unless `resumed` (LoopOptions::resume_from) holds the effects of `as_given` first,
/// in order, and the same sensors and excitations.
void CheckResumedState(const model::ModelSpec& as_given, const model::ModelSpec& resumed);

/// The compared band as an effect's other starts in its place see it
/// (model::EffectDefinition::starts_in_place): its top, and the centre of its worst part with `model`
/// (WorstBandCentreHz; unknown when the model cannot be evaluated). The relocation and runners-up
/// steps make the starts with it.
model::PlaceBand PlaceBandOf(const compare::Comparison& comparison, const model::ModelSpec& model);

/// One step of the loop: what was done and the error after it.
struct LoopStep {
  std::string action;  ///< "as given", "fit", "add <with>", "refit"
  std::string effect;  ///< the --with text of the effect added at this step; empty otherwise
  double error = 0;
};

struct LoopSummary {
  model::ModelSpec initial;            ///< the model as given
  model::ModelSpec final_model;        ///< with every added effect and its history entries
  /// The model as the rounds left it, before the steps after them (merges, moves, the turned channel,
  /// rigid limits, holds): a state to resume from (LoopOptions::resume_from) to run those steps again.
  model::ModelSpec after_rounds;
  std::vector<LoopStep> history;       ///< in order; history.back().error is the final model's
  std::vector<std::string> effects_added;
  compare::NoiseFloor noise_floor;
  /// Why it stopped: "at the noise floor", "no effect of the catalogue helps", "the round limit", ...
  std::string stop_reason;
  std::string last_verdict;            ///< the last diagnosis' verdict
  /// The final model is within kDoneTimesFloor of a known noise floor: the effects added explain the
  /// measurement. Otherwise they are not confirmed: the catalogue did not bring the model to the floor,
  /// so something it does not hold is still missing, and the effects fitted beside it may stand in for
  /// it (a cable from the granite to the hexapod was fitted as an extra body at 1.8x the floor, and as
  /// a loss factor at 1.7x). They stay in the final model, the best the loop found, marked so.
  bool confirmed = false;
  /// Effects the loop added whose final, refitted values are physically absurd (ImplausibleBecause():
  /// a length or turn at the bound of its range, a mass above the stack's), "<effect>@<location>: why".
  /// The diagnosis checks its candidates; the refits after it can carry a value to its bound. The
  /// model is then not confirmed, at the floor or not.
  std::vector<std::string> implausible_effects;
  /// In words: which effects explain the measurement, or that nothing is confirmed and where (bands,
  /// elements) the final model's remaining error sits.
  std::string conclusion;
  /// The final model's error on the raw channels, worst first (WorstChannels(), at most 6): the
  /// conclusion names those that stand out, at the floor too, where the compliance space may not see a
  /// part that one sensor or a few carry (a local mode of the plate, a resonant mount). At the floor,
  /// when one stands out, these are the channels of the final model with its parameters and its
  /// effects' refitted in raw space (when that lowers its raw error): a channel the model can fit there
  /// is not the bench's fault (a payload's lateral offset the compliance space hardly sees put one
  /// sensor at 1.8x the floor, seed 63012 of eval_loop). Empty for a measurement given already
  /// projected.
  std::vector<ChannelError> final_channels;
  /// When the final model ends above the floor: the two bands where the first fit's error was largest
  /// (the model before the rounds, with a turned channel's correction; or the state resumed from),
  /// worst first, which the conclusion names as where what is missing acts. The effects added on the way
  /// stand in for part of it, and the error they leave often lies a third octave beside it: on the
  /// cables 83532-83536 of eval_loop (development data), the first fit's two worst bands held a band of
  /// the cable's change in 5 of 5, the final model's in 3 of 5. Empty at the floor or without one.
  std::vector<compare::BandError> missing_bands;
  /// The last diagnosis whole (its "where": worst bands, elements, inconsistent channels); empty
  /// (no candidates, no bands) when the first fit already ended at the noise floor.
  DiagnoseSummary last_diagnosis;
  double time_s = 0;

  /// The error history as a table (step, action, error, x floor) with the stop reason.
  std::string HistoryTable() const;
};

/// The raw channels of `model` refitted in raw space (its parameters and its effects', on the band and
/// with the weights of `options`' comparison), worst first and as many as `channels`, when that lowers
/// its raw error; `channels` (WorstChannels() of `model`) otherwise, and when the refit fails. RunLoop()
/// weighs the channels of a final model at the floor so, when one stands out: a channel the model can
/// fit there is not blamed on the bench.
std::vector<ChannelError> ChannelsAfterRawRefit(const model::ModelSpec& model, const measurement::FrfData& measurement,
                                                const LoopOptions& options, const std::vector<ChannelError>& channels);

/// The raw channels LoopSummary::conclusion names (of `summary`'s final_channels, its floor, history
/// and implausible effects): above the floor those that stand out (StandingOut()); at the floor, with
/// the effects confirmed, those too when the first is also kChannelStandsOut x the floor (a part the
/// compliance space cannot see); none without a floor or with an implausible effect at the floor.
std::vector<ChannelError> ConclusionChannels(const LoopSummary& summary);

/// Runs the loop on `spec` against `measurement`. Throws as diagnose::Diagnose() does.
LoopSummary RunLoop(const model::ModelSpec& spec, const measurement::FrfData& measurement, const LoopOptions& options = {});

/// DropUnneededEffects on more frequencies than DiagnoseOptions::max_search_frequencies: the model
/// without an effect is refitted on the search grid first (RefitRatioOnSearchGrid), and when it stays
/// more than this many times above what dropping the effect asks of it there (1 / (1 -
/// min_relative_improvement) of the model with it), the effect earns its place without the refit on
/// all frequencies (9-12 s of seed 83140 of eval_loop, 1015 frequencies). The thinned grid's error is
/// the same model's on a subset of the frequencies: in four two-effect loops (83135-83140, 493-1015
/// frequencies) the final model's errors on the two grids were within 2 % of each other, and the models
/// without the first effect stood 11-46 times above them.
constexpr double kSearchGridMargin = 1.5;

/// `current` with `effects` in place of its own (their parameters as they are) refitted on `search` (the
/// loop's comparison thinned to DiagnoseOptions::max_search_frequencies) from two starts as the loop
/// refits it (`current`'s state, and the model as given with `effects`; the better kept), its error
/// there over `current`'s own error there, each over its own noise floor where both are known (the two
/// can correct different channels). NaN when either cannot be evaluated: the decision is left to the
/// refit on all frequencies.
double RefitRatioOnSearchGrid(const model::ModelSpec& as_given, const compare::Comparison& search, const LoopOptions& options,
                              const model::ModelSpec& current, const std::vector<model::Effect>& effects);

/// The loop's check after each round that adds an effect, and after the turned-channel step when it
/// keeps a correction: every effect the loop added before `newest`
/// (those of `current` after the effects of `as_given`) must still earn its place beside the later ones
/// by the rule that added it (DiagnoseOptions::min_relative_improvement and delta BIC against the model
/// without it). The model is refitted without it from `current`'s state and from the model as given
/// (every remaining effect refitted with the model, FitEffects), the better kept, and its error put on
/// `current`'s noise floor (without a channel's correction the measurement is weighed otherwise and
/// its floor moves: the correction earns its place by what it explains); where the effect does
/// not lower the error by that share it is dropped, unless `current` is within
/// LoopOptions::rounds_above_times_floor of the noise floor with it and above that without it (near the
/// floor no effect lowers the error by 5 %): `current` becomes the model without it and a
/// "drop" step with its error is appended to `history` (whose last step holds `current`'s error).
/// A first round names what mimics the strongest effect best, a later one can name the truth beside it
/// (docs/diagnose.md). On more frequencies than DiagnoseOptions::max_search_frequencies the model
/// without an effect is refitted on the search grid first (kSearchGridMargin). Returns the
/// "<effect>@<location>" of the dropped effects.
std::vector<std::string> DropUnneededEffects(const model::ModelSpec& as_given, const compare::Comparison& comparison,
                                             const LoopOptions& options, const model::Effect& newest,
                                             model::ModelSpec* current, std::vector<LoopStep>* history);

/// The options of the loop's diagnoses: LoopOptions::diagnose with the loop's progress, its stop at
/// LoopOptions::rounds_above_times_floor (DiagnoseOptions::stop_at_times_floor), and second starts from
/// `as_given`'s parameters (DiagnoseOptions::as_given, unless set).
DiagnoseOptions LoopDiagnoseOptions(const LoopOptions& options, const model::ModelSpec& as_given);

/// The loop's step after its rounds when it ends above LoopOptions::rounds_above_times_floor with
/// effects it added: each of them in turn is taken out and sought again at every location of its kind,
/// by a diagnosis of that effect alone (`diagnose` with DiagnoseOptions::effects set to it) on the
/// model without it, which fits the model's and the other effects' parameters with each candidate. A
/// round judges its candidates beside the effects of the rounds before; one of those in the wrong place
/// makes a later round add another to make up for it (seed 21020: a loss factor put in ty that is in
/// rz). Where the diagnosis names another location, and the model with the effect there, refitted from
/// the diagnosis' state and from the model as given (the better kept), lowers `history`'s last error by
/// more than 1 %, the move is taken: `current` becomes that model (the moved effect last) and a "move"
/// step is appended (the loop then checks the other added effects with DropUnneededEffects). Effects
/// with one location (a delay) and channel corrections (located by the channels' own directions, not by
/// the model) are not moved. An effect is sought as the kinds of its model::EffectDefinition::also_sought_as
/// too, and moved to one of them on the same rule (81805 of eval_loop: a payload of the hexapod that
/// stood for a body whose mode lies just above the band, 2.15x -> 1.12x the floor as that body). Beside
/// the diagnosis, the effect is refitted from each of its starts in its own place
/// (model::EffectDefinition::starts_in_place), from the loop's state and from the model as given; the
/// best of these and the diagnosis' move is taken on the same rule (82296: a payload standing for a body
/// above the band, 1.13x -> 1.01x as that body; 82315: a payload fitted off-axis and below its host's
/// centre, 4.9x -> 1.05x started again at the centre, history: "refit <effect>@<location> from another
/// start in its place"; 82343: a payload taken for a body with a joint far stiffer than the band,
/// 2.43x -> 1.01x as its rigid limit). Returns "<effect>@<from> -> <effect>@<to>", and "<effect>@<location> ->
/// <effect>@<location> (started again)" for a start in place of the same kind.
/// With `mass_effects_only`, only the added effects that add mass (model::EffectDefinition::adds_mass:
/// a payload, an extra body) are sought again: the loop's step near the floor
/// (LoopOptions::relocate_above_times_floor).
std::vector<std::string> RelocateEffects(const model::ModelSpec& as_given, const measurement::FrfData& measurement,
                                         const compare::Comparison& comparison, const LoopOptions& options,
                                         const DiagnoseOptions& diagnose, model::ModelSpec* current,
                                         std::vector<LoopStep>* history, bool mass_effects_only = false);

/// RefitInBandStages() runs at the start of a round whose model is within this many times the noise
/// floor. Seen: the right effects, stuck beside stiffnesses in the wrong basin, at 1.09x (82311 of
/// eval_loop) and 1.60x (82354); further above, an effect still missing holds most of the error and
/// the round's diagnosis refits the model with its candidates anyway.
constexpr double kBandStagesTimesFloor = 2.0;

/// The loop's step at the start of a round within kBandStagesTimesFloor of the noise floor (above
/// LoopOptions::rounds_above_times_floor) with effects it added, once for each set of effects: the
/// model as given with `current`'s effects, as fitted, refitted with them in band stages
/// (fit::FitModelWithBandContinuation, the first fit's route, with LoopOptions::fit). The rounds' refits
/// start from the loop's state and from the model as given fitted on the whole band at once, and an
/// effect beside stiffnesses in the wrong basin leaves a misfit a weak candidate takes up (82311 of
/// eval_loop: a payload and a coupling of the hexapod, both right, 1.09x the floor; a coupling of the
/// granite added beside them reached 1.04x; in band stages the two reach 1.04x. 82354: a coupling of the
/// hexapod and a delay, both right, 1.60x; in band stages 1.02x). Taken when more than
/// 1 % lower than `history`'s last error: `current` becomes that model and a "refit in band stages from
/// the model as given" step is appended. False, nothing changed, otherwise.
bool RefitInBandStages(const model::ModelSpec& as_given, const measurement::FrfData& measurement,
                       const compare::Comparison& comparison, const LoopOptions& options, model::ModelSpec* current,
                       std::vector<LoopStep>* history);

/// The loop's step right after its first fit when that ends above LoopOptions::rounds_above_times_floor
/// but within kBandStagesTimesFloor of the noise floor, where what is missing is weak and the basin the
/// stiffnesses stop in decides whether it shows: the model as given fitted again from
/// LoopOptions::first_fit_starts starts drawn around it, itself among them (fit::FitOptions::num_starts,
/// LoopOptions::fit otherwise), the lowest kept.
/// 82679 of eval_loop (ty.Dy a spring of 1.1e8 N/m, visibility 1.5, 600 Hz band): the first fit in band
/// stages stopped at 1.17x the floor with the granite's Dy spring 15x soft, standing in for the drive,
/// where the servo fitted from there reached 1.15x and no round added it; from random starts 1.12x (the
/// granite's Dy at the truth's, ry's soft in its place), and the servo from there 1.04x, 0.0024 from the
/// noise-free truth. Taken when more than 1 % lower than `history`'s last error: `current` becomes that
/// model and a "fit from several starts" step is appended. False, nothing changed, otherwise (and when
/// `current` is not in that range, or with first_fit_starts <= 1).
bool FitFromSeveralStarts(const model::ModelSpec& as_given, const compare::Comparison& comparison,
                          const LoopOptions& options, model::ModelSpec* current, std::vector<LoopStep>* history);

/// How many of a round's next candidates TryRunnersUpFromAsGiven() fits beside its leader.
constexpr int kRunnersUpTried = 2;

/// The loop's step after a round added its leader (and dropped what no longer earns its place) with the
/// model still above kBandStagesTimesFloor: up to kRunnersUpTried of the round's next candidates, each
/// fitted together with `current`'s effects, as fitted, from the model as given (FitFromAsGiven, the
/// start (b) of the round's refit), concurrently. Tried: a negative delta BIC, plausible, not in
/// `dropped` or the model, and at another joint or body than the leader (at the leader's place stand
/// its mimics: an extra body beside a payload). The lowest is taken when it lowers `history`'s last
/// error by the share and the delta BIC by which a round adds an effect
/// (DiagnoseOptions::min_relative_improvement) and reaches LoopOptions::rounds_above_times_floor, where
/// the rounds end: `current` becomes that model and an "add <effect>@<location> beside <leader> (fitted
/// together from the model as given)" step is appended. Short of that the rounds go on as before: a
/// wrong effect fitted so can take a model a good way down (82473 of eval_loop: a loss factor of rz
/// beside a coupling of the hexapod, 2.76x -> 1.71x the floor; 82474: a sensor's correction beside an
/// extra body, 2.94x -> 1.19x), and only later rounds drop it again.
/// The next round's diagnosis screens its candidates on the fitted model, whose stiffnesses the first
/// fit bent to stand in for what is still missing, and from there a candidate can stay in that basin:
/// 82314 of eval_loop (a 6.2 kg payload on the hexapod and a loss factor of rz) added the payload at
/// 3.54x the floor, where the loss factor, third in that round, fitted from the model's state ended at
/// 4.9x, and the loop added three other effects (1.22x, 0.025 off the noise-free truth, 592 s); fitted
/// with the payload from the model as given, the loss factor reaches 1.02x.
/// A pair that ends above the round threshold but within kBandStagesTimesFloor is fitted again with the
/// leader from each of its other starts of its own kind (model::EffectDefinition::starts_in_place), the
/// lowest kept: the leader's own fit can leave it where the pair has no slope to the data (82536 of
/// eval_loop: a 2.5 kg body at 213 Hz on the hexapod, 150 Hz band, added as 4.2 kg on a joint rigid in
/// translation; the servo of ry.Ry beside it 1.11x, beside the body started with its modes above the
/// band 1.003x). The pair taken is refitted on all frequencies, as a round's add is (FitFromAsGiven
/// finishes there with the diagnosis' few iterations), and a "refit" step follows the add. Returns the
/// effect added, or nullopt with nothing changed.
std::optional<model::Effect> TryRunnersUpFromAsGiven(const model::ModelSpec& as_given, const compare::Comparison& comparison,
                                                     const LoopOptions& options, const DiagnoseSummary& diagnosis,
                                                     const std::set<std::string>& dropped, model::ModelSpec* current,
                                                     std::vector<LoopStep>* history);

/// An effect with a local mode in the band whose rigid limit, put in its place without a refit, raises the
/// error by more than this share has its mode in the data (TakeRigidLimits). Seen: 18.9x for a body at
/// 288 Hz in a 600 Hz band, 1.005x for a rocking at 31 Hz that the data did not show.
constexpr double kLocalModeSeenRise = 0.10;
/// ... and still does after this many iterations of the model's and effects' fit from the loop's state
/// with the limit in the effect's place (the model's parameters may lean on a mode the data do not see).
constexpr int kLocalModeSeenIterations = 3;

/// The loop's last check at the noise floor (followed by MergeMimickingEffects() again when a limit is
/// taken): every effect the loop added that has a rigid limit
/// (model::EffectDefinition::rigid_limit: an extra body -> a payload) is replaced by it and the model
/// refitted from `current`'s state and from the model as given (the better kept); where that error is
/// within kRigidLimitTolerance of `history`'s last, the limit is taken: `current` becomes that model and
/// a "take" step is appended. A diagnosis compares an effect with its limit only among its own
/// candidates, with the effects of later rounds still missing: a 6.9 kg payload on the hexapod found
/// in a first round at 3.7x the floor was an extra body whose joint later sat rigid (local mode near
/// 1 kHz in a 150 Hz band, kr at its 1e14 bound) in the final model at the floor (seed 19018). An effect
/// with a local mode inside the comparison's band (model::EffectDefinition::local_modes_hz) is refitted
/// as its limit only when the limit put in its place as it stands, or after kLocalModeSeenIterations of
/// refit, raises the error by at most kLocalModeSeenRise: otherwise the data see the mode. Returns
/// "<effect>@<location> -> <limit>@<location>" for each limit taken.
std::vector<std::string> TakeRigidLimits(const model::ModelSpec& as_given, const compare::Comparison& comparison,
                                         const LoopOptions& options, model::ModelSpec* current, std::vector<LoopStep>* history);

/// The loop's step for effects that one effect can be (model::EffectDefinition::mimicked_together_by):
/// where two or more effects the loop added, of kinds another effect lists, sit at one joint, that
/// effect is put in their place with the parameters that make what they make
/// (EffectDefinition::from_mimics) and refitted from there and from the model as given. It takes their
/// place when its error is within kRigidLimitTolerance of `history`'s last: one physical effect rather
/// than several the data cannot tell from it. Seed 51012 of eval_loop (rz's stiffness centre 149 mm
/// off, visibility 2.9, beside a 0.63 ms delay): the loop added rz's Dy-Rx and Dx-Ry couplings, 1.06x
/// the floor, 0.011 off the noise-free truth; a diagnosis of the offset alone, started at no offset,
/// did not reach them.
/// Where that effect cannot stand for them all, it may be one of them beside what is left of the others:
/// it is made from each mimic alone, put beside each other mimic less the term it makes of that kind
/// (EffectDefinition::to_mimics), and refitted the same way; the lowest is taken when it lowers the error
/// by more than 1 % and pays for its parameters (delta BIC < 0), and only above
/// LoopOptions::rounds_above_times_floor (it adds parameters; at the floor the loop looks no further). Seed 82755 of eval_loop (the hexapod's
/// stiffness centre 109 mm below the model's and a Dx-Ry coupling of 2.52e6 N/rad there, 150 Hz band): the
/// loop added the hexapod's Dy-Rx and Dx-Ry couplings (1.15x the floor, 0.0185 off the noise-free truth),
/// both positive where an offset makes terms of opposite signs, so no offset alone fits them; the offset
/// made from the Dy-Rx coupling beside the Dx-Ry coupling less the offset's own term is the truth's.
/// Returns "<effect>, <effect> -> <effect>[, <effect>...]" for each merge (a "merge" step is appended to
/// `history`); empty when none was taken.
std::vector<std::string> MergeMimickingEffects(const model::ModelSpec& as_given, const compare::Comparison& comparison,
                                               const LoopOptions& options, model::ModelSpec* current,
                                               std::vector<LoopStep>* history);

/// ReduceToTheMimicsLeft() tries the largest this many of what an effect and its mimics make together,
/// each set with the ones before it.
constexpr int kMimicsLeftTried = 2;
/// A term of what an effect and its mimics make together below this share of the largest (on the scale
/// of their ranges) has cancelled out and is not tried.
constexpr double kMimicCancelled = 0.01;

/// The reverse of MergeMimickingEffects(): an effect the loop added that mimics several others
/// (model::EffectDefinition::to_mimics: a joint offset, the couplings of its joint's translations with
/// its rotations), beside effects the loop added of those kinds at its joint, is put with them as what
/// they make together, term by term (a coupling the offset makes plus the added one of its pair); the
/// largest term alone, and then with the next, replaces them when it has fewer parameters and its
/// error, refitted from there and from the model as given (RefitWithEffects), is within
/// kRigidLimitTolerance of `history`'s last. Seed 82516 of eval_loop (a payload on the hexapod and a
/// Dx-Ry coupling there): round 1 took the hexapod's offset, 157 mm up, for the coupling, and round 3
/// added its Dy-Rx coupling against the other term the offset makes (1.55x the floor); reduced, the
/// one Dx-Ry coupling, 1.03x. The loop calls it after each round's add and with the merge. Returns
/// "<effect>, <mimic>, ... -> <effect>, ..." for the replacement taken (a "reduce" step is appended to
/// `history`); empty when none was taken.
std::vector<std::string> ReduceToTheMimicsLeft(const model::ModelSpec& as_given, const compare::Comparison& comparison,
                                               const LoopOptions& options, model::ModelSpec* current,
                                               std::vector<LoopStep>* history);

/// The loop's step when it ends at the noise floor with an added effect whose length or turn ran to the
/// bound of its range (ParametersAtBounds(), checked against `current` without the effect): each such
/// parameter is set to its nominal value (the catalogue's default at the location: no offset, no turn)
/// and held there (model::Effect::held); a channel's correction (model::EffectDefinition::
/// measured_side_only) also has its turn held at the channel's direction as the other channels' rigid
/// motion sees it (measurement::EstimateChannelDirections, CalcChannelTurn()), where that is estimable.
/// The model is then refitted from `current`'s state and from the
/// model as given (the better kept); a "hold" step with its error is appended to `history` and `current`
/// becomes that model. The loop then runs more rounds (LoopOptions::hold_rounds, the first even at the
/// floor), checks the effects added before the held one again (DropUnneededEffects), and keeps their
/// model only as KeepModelAfterHold() says. An effect at its bound stands in for
/// something else beside what it is: a channel turned 20 degrees and a servo of ry.Ry were fitted as the
/// channel's correction with its offset at 5 cm (seed 29011). Returns "<effect>@<location>.<parameter>"
/// of the parameters held; empty (nothing changed) when there are none or the refit fails.
std::vector<std::string> HoldParametersAtBounds(const model::ModelSpec& as_given, const measurement::FrfData& measurement,
                                                const compare::Comparison& comparison, const LoopOptions& options,
                                                model::ModelSpec* current, std::vector<LoopStep>* history);

/// Whether the loop keeps the model its hold step (HoldParametersAtBounds() and the rounds after it)
/// ends with, of error `error_after`, over the model before the hold, of `error_before` with a
/// parameter at a bound: when it is at the floor (kDoneTimesFloor) with every added effect plausible,
/// and its error is within kRigidLimitTolerance of the model's before or as low as the loop looks for
/// (LoopOptions::rounds_above_times_floor). A bound lets the freed parameter take up part of the noise:
/// 51010 of eval_loop (a3x turned 21 degrees, rz's hysteretic damping) ended at 0.97x the floor with
/// a3x's correction at dz = 5 cm, 0.018 off the noise-free truth; held, 0.99x and 0.0019 off it, a
/// rise of 2.2 % (the floor's standard deviation was 0.9 % of it). Not kept when the floor is unknown.
bool KeepModelAfterHold(double error_before, double error_after, bool all_plausible, const compare::NoiseFloor& floor,
                        const LoopOptions& options);

/// A round's step that adds an effect: `with_state` is the candidate's whole fitted state (its effect
/// `effect`, the effects already in the model and the model's parameters as the diagnosis fitted them
/// together, diagnose::ApplyCandidate()). When its error is below `history`'s last, an "add" step is
/// appended and it is refitted from two starts, the better kept: that state with the model's and every
/// effect's parameters freed, and the model as given with `current`'s effects (as fitted there,
/// holds included) and `effect`, all their parameters fitted again together with the model's
/// (FitEffects); a "refit" step holds the error. `current` becomes that model. False, nothing changed,
/// when the state does not lower the error.
bool AddEffectAndRefit(const model::ModelSpec& as_given, const compare::Comparison& comparison, const LoopOptions& options,
                       const model::ModelSpec& with_state, const model::Effect& effect, model::ModelSpec* current,
                       std::vector<LoopStep>* history);

/// The loop's step when a round's diagnosis finds no effect that counts by itself
/// (DiagnoseOptions::min_relative_improvement) above LoopOptions::rounds_above_times_floor in a model
/// with effects the loop added: its best candidate (delta BIC < 0, plausible, not dropped before) is
/// tried beside them. An effect added in an early round can stand in for the one the data hold, and
/// near the floor the true one then lowers the error by less than the share beside it (81511 of
/// eval_loop: a servo of ry.Ry, a loss factor and an extra body in the hexapod; the servo was taken for
/// an impact's correction, the loop stopped at 1.21x the floor, 0.027 off the noise-free truth, with
/// the servo's candidate 4.4 % lower; replaced, 1.02x and 0.0040 off it); or the last effect of the
/// data is a weak one that cannot lower the error by the share so near the floor (81706: a servo of
/// ty.Dy beside a payload, 1.06x -> 1.03x). The candidate is added and refitted
/// (AddEffectAndRefit) and every other added effect checked beside it (DropUnneededEffects); the new
/// model is kept as TriedCandidateEarnsPlace() says, each model's error taken in times its own noise
/// floor (compare::Comparison::CalcNoiseFloor(spec): a channel's correction moves it), and the floor
/// reached counting for an effect of the model only (not model::EffectDefinition::measured_side_only:
/// seed 200055's a3z turned 17 degrees, where h1's correction beside a3z's took the error from 1.08x
/// to 0.95x the floor, mostly by moving the floor, and is not in the data). Otherwise `current` goes
/// back to the model before, a "back to the model before" step with its error is appended
/// to `history`, and the result is empty; kept, it holds the "<effect>@<location>" of the effects the
/// candidate replaced (none when it was kept beside them).
std::optional<std::vector<std::string>> TryCandidateBesideAddedEffects(
    const model::ModelSpec& as_given, const compare::Comparison& comparison, const LoopOptions& options,
    const model::ModelSpec& with_state, const model::Effect& effect, model::ModelSpec* current,
    std::vector<LoopStep>* history);

/// Whether TryCandidateBesideAddedEffects() keeps the model it reached: the candidate `added` was added
/// and refitted, and the effects `removed` were then dropped as not needed (DropUnneededEffects), taking
/// the error from `error_before` to `error_after`. Kept when the error fell, delta BIC against the
/// model before is negative (as diagnose's header, with k the free parameters added less those
/// removed), and either an effect was removed (a replacement adds no flexibility to a misfit, which
/// the share a new effect must lower the error by guards against, or pays for it in BIC) or the error
/// crossed `round_threshold` (LoopOptions::rounds_above_times_floor times the floor; NaN: never) from
/// above: the rule by which DropUnneededEffects keeps an effect near the floor.
bool TriedCandidateEarnsPlace(double error_before, double error_after, const model::Effect& added,
                              const std::vector<model::Effect>& removed, double num_residuals, double round_threshold);

/// The effects of `final` after those of `as_given` (the ones the loop added) that ImplausibleBecause()
/// finds absurd, each checked against `final` without it: "<effect>@<location>: why". A correction of
/// the measured side is checked against the channels' own directions under the model without it
/// (`directions_under`, ChannelDirectionsUnder() of the loop's measurement; empty: not checked).
std::vector<std::string> ImplausibleAddedEffects(
    const model::ModelSpec& as_given, const model::ModelSpec& final, double band_low_hz,
    const std::function<std::vector<measurement::ChannelDirectionEstimate>(const model::ModelSpec&)>& directions_under = {});

/// `step,action,effect,error,noise_floor,times_floor` (header first; empty noise fields when the
/// floor is unknown), one row per step.
std::string FormatLoopHistory(const LoopSummary& summary);

}  // namespace stagefit::diagnose
