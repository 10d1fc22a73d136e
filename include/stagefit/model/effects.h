#pragma once
// The effects catalogue (SPEC §5): named, parameterised edits of a model description, applied at a
// location. An effect is nothing but an edit of the ModelSpec (a body's mass properties, a new body and
// joint, an imposed DoF made compliant, a moved joint origin, a coupling term, loss factors, a channel
// geometry correction, a delay, a spin rate), so everything it does can also be written by hand in a
// model file, and a model with effects applied round-trips through its file.
//
// Text form (--with): EFFECT@LOCATION[:name=value,name=value...], values SI or with units:
//   payload@hexapod:mass=5 kg,z=100 mm      extra-body@rz:mass=20,k=5e7
//   servo-stiffness@ty.Dy:k=2e8 N/m          coupled-stiffness@hexapod.Dx-Ry:k=1e5
//   joint-offset@ty:dz=50 mm                 structural-damping@hexapod:eta=0.05
//   sensor-geometry@a2x:dx=2 mm              delay@acquisition:tau=0.2 ms     gyroscopic@rz:spin=60 rpm

#include <map>
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

struct EffectDefinition {
  std::string name;
  std::string summary;        ///< one line: the edit it makes
  std::string location_kind;  ///< "body", "joint", "joint.DoF (imposed)", "joint.A-B", "channel", "acquisition"
  std::vector<EffectParameterSpec> parameters;
};

/// A catalogued effect with its location and parameter values (SI).
struct Effect {
  std::string name;
  std::string location;
  std::map<std::string, double> parameters;
  /// "name@location:p1=v1,p2=v2" with 17 significant digits, parameters in catalogue order.
  std::string ToString() const;
};

const std::vector<EffectDefinition>& EffectCatalogue();

/// Throws InputError listing the catalogue when `name` is not in it.
const EffectDefinition& FindEffectDefinition(const std::string& name);

/// Every location of `spec` where effect `name` applies. Channel locations (sensor-geometry) come from
/// `channels` (the measurement's channel names) plus the model's sensors and excitations.
std::vector<std::string> EffectLocations(const ModelSpec& spec, const std::string& name,
                                         const std::vector<std::string>& channels = {});

/// Default (starting) parameter values of an effect at a location, derived from the model (e.g. a
/// servo stiffness like the joint's other stiffnesses, a payload of 10 % of the body's mass).
std::map<std::string, double> DefaultEffectParameters(const ModelSpec& spec, const std::string& name,
                                                      const std::string& location);

/// Parses the text form; missing parameters take their defaults. Throws InputError naming the text,
/// the part that is wrong and what was expected (unknown effect, location or parameter; bad value).
Effect ParseEffect(const std::string& text, const ModelSpec& spec, const std::vector<std::string>& channels = {});

/// Applies the edit to `spec` and records effect.ToString() in spec.effects. Throws InputError when the
/// location does not exist or the parameters are out of range (e.g. negative mass).
void ApplyEffect(ModelSpec& spec, const Effect& effect);

/// Every catalogued effect at every location with default parameters (what diagnose tries).
std::vector<Effect> EnumerateEffects(const ModelSpec& spec, const std::vector<std::string>& channels = {});

}  // namespace stagefit::model
