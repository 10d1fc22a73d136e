#pragma once
// Named, tunable parameters of a model description, and the derivatives of the assembled matrices with
// respect to them (the system is linear in each of them, so the derivatives are exact and constant).
//
// Names (SPEC §4 --params): "<joint>.k.<Dof>" stiffness, "<joint>.c.<Dof>" damping,
// "<joint>.eta.<Dof>" hysteretic loss factor, "<joint>.k.<A>-<B>" / "<joint>.c.<A>-<B>" coupling terms,
// "<body>.m" the mass of a body (inertia kept).
// Only free DoF have parameters (an imposed DoF is a constraint). Patterns use shell globbing:
// "*.k.*", "hexapod.k.R?", "ty.*".

#include <Eigen/Core>

#include <string>
#include <vector>

#include "stagefit/common/units.h"
#include "stagefit/model/assembled_model.h"

namespace stagefit::model {

enum class ParameterKind { kStiffness, kDamping, kLossFactor, kCouplingStiffness, kCouplingDamping, kMass };

struct ParameterInfo {
  std::string name;
  ParameterKind kind = ParameterKind::kStiffness;
  int joint = -1;
  int body = -1;      ///< kMass only
  Dof a = Dof::kDx;   ///< the DoF (or the first DoF of a coupling)
  Dof b = Dof::kDx;   ///< the second DoF of a coupling
  int coupling = -1;  ///< index into the joint's couplings
  Dimension dimension;
  bool positive = true;  ///< true when the value must stay > 0 (fits use a log parameterisation)
};

/// Every parameter of `spec`, joint by joint: stiffness, damping, loss factor, then couplings; then the
/// body masses.
std::vector<ParameterInfo> ListParameters(const ModelSpec& spec);

/// The parameters whose names match any of `patterns` (fnmatch globbing), in ListParameters() order.
/// Throws InputError naming a pattern that matches nothing, with the list of valid names' forms.
std::vector<ParameterInfo> MatchParameters(const ModelSpec& spec, const std::vector<std::string>& patterns);

/// Looks a parameter up by exact name; throws InputError if there is none.
ParameterInfo FindParameter(const ModelSpec& spec, const std::string& name);

double GetParameter(const ModelSpec& spec, const ParameterInfo& parameter);
void SetParameter(ModelSpec& spec, const ParameterInfo& parameter, double value);

/// d(M, C, K, K_loss)/d(parameter) in generalised coordinates (n x n each; dM is non-zero for masses
/// only: dM = Phi_b' diag(1, 1, 1, 0, 0, 0) Phi_b). A mass also changes the ground-input matrix B2 of
/// a system with ground inputs; that term is not part of SystemDerivative.
struct SystemDerivative {
  Eigen::MatrixXd dM, dC, dK, dK_loss;
};
SystemDerivative CalcSystemDerivative(const AssembledModel& model, const ParameterInfo& parameter);

}  // namespace stagefit::model
