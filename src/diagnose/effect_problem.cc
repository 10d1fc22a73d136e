#include "stagefit/diagnose/effect_problem.h"

#include <algorithm>
#include <cmath>

#include "stagefit/common/dof.h"
#include "stagefit/common/error.h"
#include "stagefit/common/units.h"
#include "stagefit/fit/model_fit.h"

namespace stagefit::diagnose {

std::vector<fit::ParameterSpec> EffectParameterSpecs(const model::ModelSpec& base, const model::Effect& effect,
                                                     const std::vector<std::string>& held,
                                                     std::vector<int>* positions) {
  const model::EffectDefinition& def = model::FindEffectDefinition(effect.name);
  const std::vector<std::string> fixed = model::FixedEffectParameters(base, effect);
  auto left_out = [&](const std::string& name) {
    return std::find(held.begin(), held.end(), name) != held.end() || std::find(fixed.begin(), fixed.end(), name) != fixed.end();
  };
  std::vector<fit::ParameterSpec> specs;
  for (size_t k = 0; k < def.parameters.size(); ++k) {
    const auto& p = def.parameters[k];
    if (left_out(p.name)) continue;
    if (positions) positions->push_back(static_cast<int>(k));
    fit::ParameterSpec s;
    s.name = effect.name + "." + p.name;
    s.unit = SiUnit(p.dimension);
    s.initial = effect.parameters.at(p.name);
    const model::EffectParameterRange range = model::EffectRange(base, effect, p.name);
    s.log_scale = range.log_scale && s.initial > 0;
    s.lower = range.lower;
    s.upper = range.upper;
    s.scale = range.scale;
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

std::unique_ptr<const fit::ProbeCosts> EffectProblem::PrepareProbeCosts(const Eigen::VectorXd& p) const {
  model::ModelSpec spec;
  if (model_params_.empty() || !SpecAt(p, &spec)) return nullptr;
  return fit::MakeParameterProbeCosts(*comparison_, spec, model_params_, p, static_cast<int>(effect_specs_.size()));
}

std::unique_ptr<fit::LeastSquaresProblem> EffectProblem::Clone() const {
  return std::make_unique<EffectProblem>(base_, *comparison_, effects_, effect_specs_, effect_of_, effect_index_,
                                         model_params_);
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
    // The columns by differences (header): every effect parameter, and the model's parameters without
    // an analytic derivative (the parameters of effects already in the model, a body's mass).
    std::vector<int> differenced;
    std::vector<model::ParameterInfo> analytic;
    std::vector<int> analytic_of;
    for (int i = 0; i < ne; ++i) differenced.push_back(i);
    for (int k = 0; k < nm; ++k) {
      if (model::HasAnalyticDerivative(spec, model_params_[k])) {
        analytic.push_back(model_params_[k]);
        analytic_of.push_back(ne + k);
      } else {
        differenced.push_back(ne + k);
      }
    }
    const int nd = static_cast<int>(differenced.size());
    routes_.assign(nd, EffectColumnRoute::kResidualDifference);
    std::vector<double> steps(nd);
    std::vector<model::ModelSpec> plus(nd), minus(nd);
    std::vector<response::DynamicStiffnessDerivative> further;
    std::vector<int> further_of;
    std::vector<double> delay_plus(nd), delay_minus(nd);
    const model::SecondOrderSystem at = comparison_->ModelSystem(spec);
    for (int d = 0; d < nd; ++d) {
      const int i = differenced[d];
      steps[d] = i < ne ? Step(i, p(i)) : fit::DifferenceStep(spec, model_params_[i - ne], p(i));
      Eigen::VectorXd pp = p, pm = p;
      pp(i) += steps[d];
      pm(i) -= steps[d];
      if (!SpecAt(pp, &plus[d]) || !SpecAt(pm, &minus[d])) return false;
      model::SecondOrderSystem sp, sm;
      routes_[d] = fit::ChooseColumnRoute(*comparison_, spec, at, plus[d], minus[d], &sp, &sm);
      delay_plus[d] = sp.delay_s - at.delay_s;
      delay_minus[d] = sm.delay_s - at.delay_s;
      if (routes_[d] == EffectColumnRoute::kSystemDifference) {
        further.push_back(fit::SystemDifference(sp, sm, steps[d], i < ne ? effect_specs_[i].name : model_params_[i - ne].name));
        further_of.push_back(d);
      }
    }
    comparison_->ResidualsAndJacobian(spec, analytic, further, r, &jacobian_, &workspace_);
    J->resize(r->size(), num_parameters());
    const int na = static_cast<int>(analytic.size());
    for (int a = 0; a < na; ++a) J->col(analytic_of[a]) = jacobian_.col(a);
    for (size_t k = 0; k < further_of.size(); ++k) J->col(differenced[further_of[k]]) = jacobian_.col(na + static_cast<int>(k));
    for (int d = 0; d < nd; ++d) {
      if (routes_[d] == EffectColumnRoute::kSystemDifference) continue;
      fit::ResidualsAtSteps(*comparison_, routes_[d], plus[d], minus[d], delay_plus[d], delay_minus[d],
                            workspace_.frf.frf.values, &difference_workspace_, &r_plus_, &r_minus_);
      J->col(differenced[d]) = (r_plus_ - r_minus_) / (2 * steps[d]);
    }
    return r->allFinite() && J->allFinite();
  } catch (const InputError&) {
    return false;
  } catch (const NumericalError&) {
    return false;
  }
}

}  // namespace stagefit::diagnose
