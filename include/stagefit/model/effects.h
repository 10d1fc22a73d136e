#pragma once
// The effects catalogue (SPEC §5): named, parameterised edits of a model description, applied at a
// location. An effect is nothing but an edit of the ModelSpec (a body's mass properties, a new body and
// joint, an imposed DoF made compliant, a moved joint origin, a coupling term, loss factors, a channel
// geometry correction, a delay, a spin rate). An applied effect stays a part of the model with its
// parameters (ModelSpec::effects over ModelSpec::base): its parameters are fit parameters
// ("payload@hexapod.mass", model/parameters.h) and a model file keeps it as an [[effect]] table that is
// applied again on load, so a tuned model with effects round-trips through its file bit for bit.
//
// Text form (--with): EFFECT@LOCATION[:name=value,name=value...], values SI or with units:
//   payload@hexapod:mass=5 kg,z=100 mm      extra-body@rz:mass=20,k=5e7
//   servo-stiffness@ty.Dy:k=2e8 N/m          coupled-stiffness@hexapod.Dx-Ry:k=1e5
//   joint-offset@ty:dz=50 mm                 structural-damping@hexapod:eta=0.05
//   sensor-geometry@a2x:dx=2 mm              delay@acquisition:tau=0.2 ms     gyroscopic@rz:spin=60 rpm

#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "stagefit/common/units.h"
#include "stagefit/model/model_spec.h"

namespace stagefit::model {

struct EffectParameterSpec {
  std::string name;
  Dimension dimension;
  bool positive = false;   ///< fitted on a log scale
  std::string doc;
};

/// The range a fit or a search gives an effect parameter (natural SI units), around its value.
struct EffectParameterRange {
  double lower = -std::numeric_limits<double>::infinity();
  double upper = std::numeric_limits<double>::infinity();
  bool log_scale = false;
  double scale = 1.0;   ///< the optimiser works on value / scale (fit::ParameterSpec::scale)
};

/// The range of a sensor-geometry correction's Euler angles, rad (about 34 degrees).
inline constexpr double kMaxCorrectionTurn = 0.6;

/// The smallest loss factor a fitted structural-damping effect may claim: the material loss of steel
/// alone is about 1e-4 to 6e-4, and a joint's adds to it. Below it the effect leaves its joint undamped
/// (EffectDefinition::implausible).
inline constexpr double kMinPlausibleLossFactor = 1e-4;

/// The radius of gyration of an extra body (effect extra-body), m: its rocking modes are at
/// sqrt(kr / (mass r^2)).
inline constexpr double kExtraBodyRadiusOfGyration = 0.05;

struct Effect;

/// The band an effect's other starts in its place are made for (EffectDefinition::starts_in_place).
struct PlaceBand {
  double high_hz = 0;                     ///< the top of the compared band
  std::optional<double> worst_centre_hz;  ///< the centre of the band where the model's error is largest, if known
};

/// `body` (an extra-body effect) with the rotational stiffness kr that puts its rocking modes,
/// sqrt(kr / (mass r^2)) with r = kExtraBodyRadiusOfGyration, at `rocking_hz`; its other parameters
/// as they are.
void SetExtraBodyRockingHz(Effect* body, double rocking_hz);

/// One entry of the catalogue: what the effect is, where it applies, its parameters, and everything
/// that depends on which effect it is (defaults, the edit, search ranges, the words for a user). The
/// rest of the program asks the entry; it does not branch on effect names.
struct EffectDefinition {
  std::string name;
  std::string summary;        ///< one line: the edit it makes
  std::string location_kind;  ///< "body", "joint", "joint.DoF (imposed)", "joint.A-B", "channel", "acquisition"
  std::vector<EffectParameterSpec> parameters;
  /// Starting values at a location, derived from the model (e.g. a payload of 10 % of the body's mass).
  std::function<std::map<std::string, double>(const ModelSpec&, const std::string& location)> defaults;
  /// The edit of the description; `get` returns a parameter's value (finite) or throws InputError.
  std::function<void(ModelSpec&, const Effect&, const std::function<double(const std::string&)>& get)> apply;
  /// The range of parameter `k` around the effect's value, on the model the effect is applied to.
  std::function<EffectParameterRange(const ModelSpec&, const Effect&, const EffectParameterSpec&)> range;
  /// One sentence for a user: what the fitted effect means physically.
  std::function<std::string(const Effect&)> explain;
  /// The effect adds mass to the stack (a payload, an extra body): its "mass" parameter is checked
  /// against the stack's mass before a diagnosis claims it.
  bool adds_mass = false;
  /// Why the fitted effect is physically absurd in itself, in words for a user; empty when it is not
  /// (a loss factor that leaves the joint undamped). Unset: only the checks every effect gets (a mass
  /// beside the stack's, lengths and turns at their search bounds: diagnose::ImplausibleBecause).
  std::function<std::string(const Effect&)> implausible;
  /// Only the measured side changes in compliance space (a channel's geometry): the comparison then
  /// re-projects the data without touching the model (the Jacobian route of fit/column_routes.h).
  bool measured_side_only = false;
  /// Set by the experiment rather than fitted from a hammer test (a spin rate).
  bool set_by_experiment = false;
  /// The simpler effect this one tends to when its compliance goes rigid, at the same location, with the
  /// parameters they share carried over (an extra body: a payload of its mass at its height). Empty when
  /// the effect has none. A diagnosis fits the limit from each leader of this effect, and names the limit
  /// when the data cannot tell the two apart.
  std::function<Effect(const Effect&)> rigid_limit;
  /// The frequencies (Hz) of the effect's own local modes with its host held still (an extra body:
  /// its translation and rocking modes); empty when the effect has none. A mode inside the measured
  /// band is seen by the data, so the effect there is not its rigid limit.
  std::function<std::vector<double>(const Effect&)> local_modes_hz;
  /// The parameters the others make redundant at the effect's location on `before` (the model it is
  /// applied to): no data can set them, and fits leave them at their value (a channel's correction:
  /// the offset along the channel's own direction and the turn about it). Empty when the effect has none.
  std::function<std::vector<std::string>(const ModelSpec& before, const Effect&)> redundant;
  /// Effects of these kinds, two or more at the joint where this one would sit, can be this one effect
  /// (a joint's stiffness centre off its origin couples the joint's translations with its rotations:
  /// Dx-Ry and Dy-Rx, as two coupled-stiffness effects would). The loop tries this one in their place
  /// (diagnose::MergeMimickingEffects), and a diagnosis whose leader is one of them also fits this one
  /// there, from what the leader makes of it. Empty when none.
  std::vector<std::string> mimicked_together_by;
  /// This effect's parameters at `joint` that make what `mimics` (effects of mimicked_together_by
  /// there) make, on `before` (the model without them): where the merge and that fit start. Set with
  /// mimicked_together_by.
  std::function<std::map<std::string, double>(const ModelSpec& before, const std::string& joint, const std::vector<Effect>& mimics)>
      from_mimics;
  /// The effects of mimicked_together_by that make what this one makes on `before` (the model without
  /// it), to first order, one for each term (a joint offset: the couplings of its joint's free
  /// translations with its free rotations, K(Dx,Ry) = kx dz, ...): the inverse of from_mimics, where
  /// the loop's step for this effect beside its own mimics starts (diagnose::ReduceToTheMimicsLeft).
  /// Set with from_mimics.
  std::function<std::vector<Effect>(const ModelSpec& before, const Effect& e)> to_mimics;
  /// A second one at a location that holds one already adds what the first one's parameters cannot (an
  /// extra body: a second local mode). Otherwise the two merge into one (two couplings of one pair
  /// are one coupling of their sum; two turns of a channel are one turn), and no second one is tried.
  bool repeatable = false;
  /// Kinds this one may stand for when it was added in a round and the loop still ends above the floor:
  /// the loop's relocation step (diagnose::RelocateEffects) seeks it as these too (a payload as an extra
  /// body, whose local mode just above the band reads in the band as more mass than a payload's, with a
  /// payload taken for it in the round). Empty when none.
  std::vector<std::string> also_sought_as;
  /// Other starts for this effect in its own place, from its fitted parameters, for the compared
  /// `band`: kinds of also_sought_as (a payload as an extra body of its mass at its height, its
  /// joint stiff enough to put its local modes at twice the band's top); the rigid limit (an extra body
  /// as the payload of its mass at its height: with a stiff joint it still has its own rotary inertia,
  /// which a payload has not); or the same kind with the parameters a fit can leave in another basin
  /// set back (a payload of its mass at the host's centre of mass: a 7 kg payload 115 mm above the
  /// hexapod, fitted from 0.7 kg, stopped 33-40 mm off-axis and 13 mm below; an extra body with its
  /// modes at twice the band's top, where a fit that made its joint rigid in translation has no slope
  /// left, and with its rocking modes at the centre of the band where the model's error is largest,
  /// where a fit that made its joint rigid in rocking has none). The relocation step refits the model
  /// with each in the effect's place, beside its diagnosis, which starts the other kinds from their
  /// defaults on the model without the effect; the step that fits a round's next candidates beside its
  /// leader (diagnose::TryRunnersUpFromAsGiven) refits a pair short of the floor with the leader from
  /// those of its own kind. Unset: the diagnosis only.
  std::function<std::vector<Effect>(const Effect&, const PlaceBand& band)> starts_in_place;
};

const std::vector<EffectDefinition>& EffectCatalogue();

/// Throws InputError listing the catalogue when `name` is not in it.
const EffectDefinition& FindEffectDefinition(const std::string& name);

/// Whether `one` can be fitted in place of effects of kind `kind` at its joint: its
/// mimicked_together_by holds `kind` and its from_mimics is set (a joint offset for couplings).
bool StandsFor(const EffectDefinition& one, const std::string& kind);

/// The joint a location names: its part before the first '.' ("rz" of "rz.Dy-Rx" and of "rz").
std::string LocationJoint(const std::string& location);

/// Every location of `spec` where effect `name` applies: the bodies and joints of its description
/// (BaseOf), not those its effects added (an extra body and its joint), whose effects could not outlive
/// them. Channel locations (sensor-geometry) come from `channels` (the measurement's channel names).
std::vector<std::string> EffectLocations(const ModelSpec& spec, const std::string& name,
                                         const std::vector<std::string>& channels = {});

/// Default (starting) parameter values of an effect at a location, derived from the model (e.g. a
/// servo stiffness like the joint's other stiffnesses, a payload of 10 % of the body's mass).
std::map<std::string, double> DefaultEffectParameters(const ModelSpec& spec, const std::string& name,
                                                      const std::string& location);

/// The search and fit range of parameter `parameter` of `effect` around its value, on `before` (the
/// model the effect is applied to).
EffectParameterRange EffectRange(const ModelSpec& before, const Effect& effect, const std::string& parameter);

/// EffectDefinition::redundant of the effect's entry (empty when it has none).
std::vector<std::string> RedundantEffectParameters(const ModelSpec& before, const Effect& effect);

/// The parameters of `effect` no fit sets: the redundant ones (RedundantEffectParameters) and those it
/// holds (Effect::held).
std::vector<std::string> FixedEffectParameters(const ModelSpec& before, const Effect& effect);

/// Adds `parameter` to `effect`'s held ones (kept in catalogue order). Throws InputError when the
/// effect has no such parameter.
void HoldEffectParameter(Effect* effect, const std::string& parameter);

/// The catalogue entry's sentence for a fitted effect.
std::string ExplainEffect(const Effect& effect);

/// Parses the text form; missing parameters take their defaults. Throws InputError naming the text,
/// the part that is wrong and what was expected (unknown effect, location or parameter; bad value).
Effect ParseEffect(const std::string& text, const ModelSpec& spec, const std::vector<std::string>& channels = {});

/// Applies the edit to `spec` and appends `effect` to spec.effects; the first effect keeps the
/// description before it in spec.base (model_spec.h). Throws InputError when the location does not
/// exist or the parameters are out of range (e.g. negative mass).
void ApplyEffect(ModelSpec& spec, const Effect& effect);

/// `base` (without effects) with `effects` applied in order: the same as ApplyEffect one by one.
ModelSpec ExpandEffects(const ModelSpec& base, const std::vector<Effect>& effects);

/// Replaces spec's effects by `effects` (same base; the history is kept) and re-expands the description.
void SetEffects(ModelSpec& spec, std::vector<Effect> effects);

/// The description before the effects (spec itself when it has none).
const ModelSpec& BaseOf(const ModelSpec& spec);

/// The base with the first `count` effects of spec applied (the model effect `count` is applied to).
ModelSpec ExpandedBefore(const ModelSpec& spec, size_t count);

/// Whether `spec` holds the effect `name` at `location` already.
bool HoldsEffect(const ModelSpec& spec, const std::string& name, const std::string& location);

/// Whether one more effect of `definition` at `location` adds anything to `spec`: always for a
/// repeatable one (EffectDefinition::repeatable), otherwise only where spec does not hold one (HoldsEffect).
bool AddsAnother(const ModelSpec& spec, const EffectDefinition& definition, const std::string& location);

/// Every catalogued effect at every location with default parameters (what diagnose tries), except at
/// a location where another adds nothing (AddsAnother: `spec` holds the same effect and it is not
/// EffectDefinition::repeatable).
std::vector<Effect> EnumerateEffects(const ModelSpec& spec, const std::vector<std::string>& channels = {});

}  // namespace stagefit::model
