#pragma once
// Named, tunable parameters of a model description, and the derivatives of the assembled matrices with
// respect to them (the system is linear in each of them, so the derivatives are exact and constant).
//
// Names (SPEC §4 --params): "<joint>.k.<Dof>" stiffness, "<joint>.c.<Dof>" damping,
// "<joint>.eta.<Dof>" hysteretic loss factor, "<joint>.k.<A>-<B>" / "<joint>.c.<A>-<B>" coupling terms,
// "<body>.m" the mass of a body (inertia kept), and "<effect>@<location>.<parameter>" a parameter of an
// effect of the model (model/effects.h), e.g. "payload@hexapod.mass", "sensor-geometry@a2y.rz".
// Only free DoF have parameters (an imposed DoF is a constraint). Patterns use shell globbing:
// "*.k.*", "hexapod.k.R?", "ty.*", "*@*" (every effect parameter).
//
// A model with effects (ModelSpec::effects): the joint and body parameters are those of its base
// (the description before the effects, so a fitted effect's joint or body does not appear twice), and
// SetParameter keeps the base and the expanded description in step: a parameter the effects leave as
// it is (a stiffness) is set in both, one they build on (a body's mass under a payload, an effect's own
// parameter) re-expands the description from the base.

#include <Eigen/Core>

#include <string>
#include <vector>

#include "stagefit/common/units.h"
#include "stagefit/model/assembled_model.h"

namespace stagefit::model {

enum class ParameterKind { kStiffness, kDamping, kLossFactor, kCouplingStiffness, kCouplingDamping, kMass, kEffect };

struct ParameterInfo {
  std::string name;
  ParameterKind kind = ParameterKind::kStiffness;
  int joint = -1;
  int body = -1;      ///< kMass only
  Dof a = Dof::kDx;   ///< the DoF (or the first DoF of a coupling)
  Dof b = Dof::kDx;   ///< the second DoF of a coupling
  int coupling = -1;  ///< index into the joint's couplings
  int effect = -1;                ///< kEffect: index into ModelSpec::effects
  std::string effect_parameter;   ///< kEffect: the parameter's name in the effect's catalogue entry
  Dimension dimension;
  bool positive = true;  ///< true when the value must stay > 0 (fits use a log parameterisation)
};

/// The dimension of a joint stiffness (damping) from DoF a to DoF b: N/m (N s/m) between translations,
/// N m/rad (N m s/rad) between rotations, N/rad (N s/rad) between a translation and a rotation.
Dimension StiffnessDimension(Dof a, Dof b);
Dimension DampingDimension(Dof a, Dof b);

/// Every parameter of `spec` (of its base when it has effects), joint by joint: stiffness, damping, loss
/// factor, then couplings; then the body masses; then every effect's parameters in order.
std::vector<ParameterInfo> ListParameters(const ModelSpec& spec);

/// The parameters whose names match any of `patterns` (fnmatch globbing), in ListParameters() order.
/// Throws InputError naming a pattern that matches nothing, with the list of valid names' forms.
std::vector<ParameterInfo> MatchParameters(const ModelSpec& spec, const std::vector<std::string>& patterns);

/// The patterns of every parameter of the model's effects ("payload@hexapod.*", ...), leaving out
/// those an experiment sets rather than a fit (a spin rate: EffectDefinition::set_by_experiment) and
/// those the others make redundant (a channel's offset along and turn about its own direction:
/// EffectDefinition::redundant); an effect with such parameters is listed by its others' names.
std::vector<std::string> EffectParameterPatterns(const ModelSpec& spec);

/// `patterns` followed by EffectParameterPatterns(spec): what fit, diagnose and loop free by default
/// ("*.k.*" and every effect's parameters).
std::vector<std::string> WithEffectParameters(std::vector<std::string> patterns, const ModelSpec& spec);

/// Looks a parameter up by exact name; throws InputError if there is none.
ParameterInfo FindParameter(const ModelSpec& spec, const std::string& name);

double GetParameter(const ModelSpec& spec, const ParameterInfo& parameter);
/// Sets the parameter (header: with effects, in the base and the expanded description). Throws
/// InputError when an effect's edit rejects the value (e.g. a negative payload mass); `spec` is then
/// unchanged.
void SetParameter(ModelSpec& spec, const ParameterInfo& parameter, double value);

/// True when d(M, C, K, K_loss)/d(parameter) of the expanded description is CalcSystemDerivative()'s:
/// every joint and body parameter of a model without effects, and with effects those the effects do
/// not build on (a stiffness). False for an effect's parameter, a body's mass when the model has
/// effects and a damping or loss factor of a joint with structural damping: their Jacobian columns
/// come from differences (fit/column_routes.h).
bool HasAnalyticDerivative(const ModelSpec& spec, const ParameterInfo& parameter);

/// d(M, C, K, K_loss)/d(parameter) in generalised coordinates (n x n each; dM is non-zero for masses
/// only: dM = Phi_b' diag(1, 1, 1, 0, 0, 0) Phi_b). A mass also changes the ground-input matrix B2 of
/// a system with ground inputs; that term is not part of SystemDerivative.
struct SystemDerivative {
  Eigen::MatrixXd dM, dC, dK, dK_loss;
};
SystemDerivative CalcSystemDerivative(const AssembledModel& model, const ParameterInfo& parameter);

}  // namespace stagefit::model
