#include "stagefit/diagnose/effect_problem.h"

#include <algorithm>
#include <cmath>

#include "stagefit/common/dof.h"
#include "stagefit/common/error.h"
#include "stagefit/common/units.h"

namespace stagefit::diagnose {
namespace {

bool SameGeometryCorrections(const model::ModelSpec& a, const model::ModelSpec& b) {
  if (a.geometry_corrections.size() != b.geometry_corrections.size()) return false;
  for (size_t i = 0; i < a.geometry_corrections.size(); ++i) {
    const auto& x = a.geometry_corrections[i];
    const auto& y = b.geometry_corrections[i];
    if (x.channel != y.channel || x.is_impact != y.is_impact || x.offset_W != y.offset_W || x.rotation_rad != y.rotation_rad) {
      return false;
    }
  }
  return true;
}

/// Same generalised coordinates, channels and delay: the systems differ at most in M, C, K, K_loss.
bool SameCoordinatesAndChannels(const model::SecondOrderSystem& a, const model::SecondOrderSystem& b) {
  return a.num_dofs() == b.num_dofs() && a.dof_names == b.dof_names && a.input_names == b.input_names &&
         a.output_names == b.output_names && a.B0 == b.B0 && a.B2 == b.B2 && a.Cq == b.Cq && a.D0 == b.D0 &&
         a.delay_s == b.delay_s;
}

bool SameSystem(const model::SecondOrderSystem& a, const model::SecondOrderSystem& b) {
  return SameCoordinatesAndChannels(a, b) && a.M == b.M && a.C == b.C && a.K == b.K && a.K_loss == b.K_loss;
}

/// (plus - minus) / (2 h) of the dynamic stiffness, as a derivative.
response::DynamicStiffnessDerivative SystemDifference(const model::SecondOrderSystem& plus,
                                                      const model::SecondOrderSystem& minus, double h,
                                                      const std::string& name) {
  model::SystemDerivative d;
  d.dM = (plus.M - minus.M) / (2 * h);
  d.dC = (plus.C - minus.C) / (2 * h);
  d.dK = (plus.K - minus.K) / (2 * h);
  d.dK_loss = (plus.K_loss - minus.K_loss) / (2 * h);
  return response::MakeDynamicStiffnessDerivative(d, name);
}

}  // namespace

std::vector<fit::ParameterSpec> EffectParameterSpecs(const model::ModelSpec& base, const model::Effect& effect,
                                                     const std::vector<std::string>& held,
                                                     std::vector<int>* positions) {
  const model::EffectDefinition& def = model::FindEffectDefinition(effect.name);
  std::vector<fit::ParameterSpec> specs;
  for (size_t k = 0; k < def.parameters.size(); ++k) {
    const auto& p = def.parameters[k];
    if (std::find(held.begin(), held.end(), p.name) != held.end()) continue;
    if (positions) positions->push_back(static_cast<int>(k));
    fit::ParameterSpec s;
    s.name = effect.name + "." + p.name;
    s.unit = SiUnit(p.dimension);
    s.initial = effect.parameters.at(p.name);
    if (p.dimension == dim::kLength) {
      // A channel's position is known to a few centimetres (it is measured on the structure); the
      // larger range of a stiffness centre or a payload's offset let a correction of a channel that is
      // right mimic another channel's turn in compliance space (docs/diagnose.md).
      const double range = effect.name == "sensor-geometry" ? 0.05 : 0.3;
      s.lower = -range;
      s.upper = range;
    } else if (p.dimension == dim::kAngle) {
      s.lower = -kMaxCorrectionTurn;
      s.upper = kMaxCorrectionTurn;
    } else if (effect.name == "coupled-stiffness") {
      // |k_ab| < sqrt(k_aa k_bb) keeps the joint positive definite.
      const int dot = static_cast<int>(effect.location.rfind('.'));
      const auto& joint = base.joints[model::FindJoint(base, effect.location.substr(0, dot))];
      const auto a = *ParseDof(effect.location.substr(dot + 1, 2));
      const auto b = *ParseDof(effect.location.substr(dot + 4, 2));
      const double limit = 0.95 * std::sqrt(joint.stiffness[index(a)] * joint.stiffness[index(b)]);
      s.lower = -limit;
      s.upper = limit;
      s.scale = limit;  // N/m to Nm/rad: its Jacobian column is far below 1 per unit (fit::ParameterSpec)
    } else if (effect.name == "gyroscopic") {
      s.lower = -1000;
      s.upper = 1000;
    } else if (p.positive && s.initial > 0) {
      s.log_scale = true;
      double factor = 1e3;
      if (p.name == "eta" || p.name == "zeta") factor = 30;
      if (effect.name == "delay") factor = 100;
      s.lower = s.initial / factor;
      s.upper = s.initial * factor;
      if (p.name == "mass" && effect.name == "payload") s.upper = std::min(s.upper, 20.0 * s.initial);
    }
    specs.push_back(s);
  }
  return specs;
}


EffectProblem::EffectProblem(const model::ModelSpec& base, const compare::Comparison& comparison, model::Effect effect,
                             std::vector<fit::ParameterSpec> effect_specs, std::vector<int> effect_index,
                             std::vector<model::ParameterInfo> model_params)
    : EffectProblem(base, comparison, std::vector<model::Effect>{std::move(effect)}, effect_specs,
                    std::vector<int>(effect_specs.size(), 0), std::move(effect_index), std::move(model_params)) {}

EffectProblem::EffectProblem(const model::ModelSpec& base, const compare::Comparison& comparison,
                             std::vector<model::Effect> effects, std::vector<fit::ParameterSpec> effect_specs,
                             std::vector<int> effect_of, std::vector<int> effect_index,
                             std::vector<model::ParameterInfo> model_params)
    : base_(base),
      comparison_(&comparison),
      effects_(std::move(effects)),
      effect_specs_(std::move(effect_specs)),
      effect_of_(std::move(effect_of)),
      effect_index_(std::move(effect_index)),
      model_params_(std::move(model_params)) {
  STAGEFIT_ASSERT(effect_specs_.size() == effect_index_.size() && effect_specs_.size() == effect_of_.size(),
                  "one effect and one definition index per effect parameter");
  STAGEFIT_ASSERT(!effects_.empty(), "at least one effect");
}

std::vector<model::Effect> EffectProblem::EffectsAt(const Eigen::VectorXd& p) const {
  std::vector<model::Effect> out = effects_;
  for (size_t i = 0; i < effect_specs_.size(); ++i) {
    model::Effect& e = out[effect_of_[i]];
    e.parameters[model::FindEffectDefinition(e.name).parameters[effect_index_[i]].name] = p(static_cast<int>(i));
  }
  return out;
}

model::Effect EffectProblem::EffectAt(const Eigen::VectorXd& p) const { return EffectsAt(p).front(); }

bool EffectProblem::SpecAt(const Eigen::VectorXd& p, model::ModelSpec* spec) const {
  *spec = base_;
  try {
    for (const model::Effect& e : EffectsAt(p)) model::ApplyEffect(*spec, e);
    const int ne = static_cast<int>(effect_specs_.size());
    for (size_t k = 0; k < model_params_.size(); ++k) model::SetParameter(*spec, model_params_[k], p(ne + static_cast<int>(k)));
  } catch (const InputError&) {
    return false;
  }
  return true;
}

double EffectProblem::Step(int i, double value) const {
  const fit::ParameterSpec& s = effect_specs_[i];
  if (s.log_scale) return 1e-5 * std::abs(value);
  if (std::isfinite(s.upper - s.lower)) return 1e-6 * (s.upper - s.lower);
  return 1e-6 * std::max(1.0, std::abs(value));
}

bool EffectProblem::Evaluate(const Eigen::VectorXd& p, Eigen::VectorXd* r, Eigen::MatrixXd* J) const {
  model::ModelSpec spec;
  if (!SpecAt(p, &spec)) return false;
  const int ne = static_cast<int>(effect_specs_.size());
  const int nm = static_cast<int>(model_params_.size());
  try {
    if (!J) {
      comparison_->ResidualsAndJacobian(spec, {}, r, nullptr, &workspace_);
      return r->allFinite();
    }
    // Each effect parameter's route (header), from the specs at p +- h.
    routes_.assign(ne, EffectColumnRoute::kResidualDifference);
    std::vector<double> steps(ne);
    std::vector<model::ModelSpec> plus(ne), minus(ne);
    std::vector<response::DynamicStiffnessDerivative> further;
    std::vector<int> further_of;
    const model::SecondOrderSystem at = comparison_->ModelSystem(spec);
    for (int i = 0; i < ne; ++i) {
      steps[i] = Step(i, p(i));
      Eigen::VectorXd pp = p, pm = p;
      pp(i) += steps[i];
      pm(i) -= steps[i];
      if (!SpecAt(pp, &plus[i]) || !SpecAt(pm, &minus[i])) return false;
      const model::SecondOrderSystem sp = comparison_->ModelSystem(plus[i]);
      const model::SecondOrderSystem sm = comparison_->ModelSystem(minus[i]);
      if (SameGeometryCorrections(spec, plus[i]) && SameGeometryCorrections(spec, minus[i]) &&
          SameCoordinatesAndChannels(at, sp) && SameCoordinatesAndChannels(at, sm)) {
        routes_[i] = EffectColumnRoute::kSystemDifference;
        further.push_back(SystemDifference(sp, sm, steps[i], effect_specs_[i].name));
        further_of.push_back(i);
      } else if (SameSystem(at, sp) && SameSystem(at, sm)) {
        routes_[i] = EffectColumnRoute::kMeasuredDifference;
      }
    }
    comparison_->ResidualsAndJacobian(spec, model_params_, further, r, &jacobian_, &workspace_);
    J->resize(r->size(), num_parameters());
    J->rightCols(nm) = jacobian_.leftCols(nm);
    for (size_t k = 0; k < further_of.size(); ++k) J->col(further_of[k]) = jacobian_.col(nm + static_cast<int>(k));
    for (int i = 0; i < ne; ++i) {
      if (routes_[i] == EffectColumnRoute::kSystemDifference) continue;
      if (routes_[i] == EffectColumnRoute::kMeasuredDifference) {
        comparison_->ResidualsWithModelResponse(plus[i], workspace_.frf.values, &r_plus_);
        comparison_->ResidualsWithModelResponse(minus[i], workspace_.frf.values, &r_minus_);
      } else {
        comparison_->ResidualsAndJacobian(plus[i], {}, &r_plus_, nullptr, &difference_workspace_);
        comparison_->ResidualsAndJacobian(minus[i], {}, &r_minus_, nullptr, &difference_workspace_);
      }
      J->col(i) = (r_plus_ - r_minus_) / (2 * steps[i]);
    }
    return r->allFinite() && J->allFinite();
  } catch (const InputError&) {
    return false;
  } catch (const NumericalError&) {
    return false;
  }
}

}  // namespace stagefit::diagnose
