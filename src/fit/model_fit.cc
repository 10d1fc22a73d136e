#include "stagefit/fit/model_fit.h"

#include <fnmatch.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "stagefit/common/error.h"
#include "stagefit/common/parallel.h"
#include "stagefit/common/units.h"
#include "stagefit/model/effects.h"

namespace stagefit::fit {
namespace {

std::string Number(double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.6g", value);
  return buffer;
}

std::string RuleName(const BoundRule& rule) {
  return (rule.source.empty() ? std::string("bounds") : rule.source + ": bounds") + " '" + rule.pattern + "'";
}

}  // namespace

bool MatchesPattern(const std::string& name, const std::string& pattern) {
  return ::fnmatch(pattern.c_str(), name.c_str(), 0) == 0;
}

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

}  // namespace

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

ColumnRoute ChooseColumnRoute(const compare::Comparison& comparison, const model::ModelSpec& at,
                              const model::SecondOrderSystem& at_system, const model::ModelSpec& plus,
                              const model::ModelSpec& minus, model::SecondOrderSystem* plus_system,
                              model::SecondOrderSystem* minus_system) {
  *plus_system = comparison.ModelSystem(plus);
  *minus_system = comparison.ModelSystem(minus);
  if (SameGeometryCorrections(at, plus) && SameGeometryCorrections(at, minus) &&
      model::SameCoordinatesAndChannels(at_system, *plus_system) &&
      model::SameCoordinatesAndChannels(at_system, *minus_system)) {
    return ColumnRoute::kSystemDifference;
  }
  if (model::SameSystem(at_system, *plus_system) && model::SameSystem(at_system, *minus_system)) {
    return ColumnRoute::kMeasuredDifference;
  }
  auto same_but_delay = [&](const model::SecondOrderSystem& other) {
    model::SecondOrderSystem undelayed = other;
    undelayed.delay_s = at_system.delay_s;
    return model::SameSystem(at_system, undelayed);
  };
  if (SameGeometryCorrections(at, plus) && SameGeometryCorrections(at, minus) && same_but_delay(*plus_system) &&
      same_but_delay(*minus_system)) {
    return ColumnRoute::kDelayDifference;
  }
  return ColumnRoute::kResidualDifference;
}

void ResidualsAtSteps(const compare::Comparison& comparison, ColumnRoute route, const model::ModelSpec& plus,
                      const model::ModelSpec& minus, double delay_plus_s, double delay_minus_s,
                      const Eigen::MatrixXcd& values_at, compare::ModelWorkspace* workspace,
                      Eigen::VectorXd* r_plus, Eigen::VectorXd* r_minus) {
  switch (route) {
    case ColumnRoute::kMeasuredDifference:
    case ColumnRoute::kDelayDifference:
      comparison.ResidualsWithModelResponse(plus, values_at, r_plus, delay_plus_s);
      comparison.ResidualsWithModelResponse(minus, values_at, r_minus, delay_minus_s);
      return;
    case ColumnRoute::kResidualDifference:
      comparison.ResidualsAndJacobian(plus, {}, r_plus, nullptr, workspace);
      comparison.ResidualsAndJacobian(minus, {}, r_minus, nullptr, workspace);
      return;
    case ColumnRoute::kAnalytic:
    case ColumnRoute::kSystemDifference:
      break;
  }
  STAGEFIT_ASSERT(false, "ResidualsAtSteps: the route has no residuals at the steps");
}

ModelFitProblem::ModelFitProblem(const model::ModelSpec& spec, const compare::Comparison& comparison,
                                 std::vector<model::ParameterInfo> parameters)
    : spec_(spec), comparison_(&comparison), parameters_(std::move(parameters)) {
  for (size_t i = 0; i < parameters_.size(); ++i) {
    if (model::HasAnalyticDerivative(spec_, parameters_[i])) {
      analytic_.push_back(static_cast<int>(i));
      analytic_params_.push_back(parameters_[i]);
    } else {
      differenced_.push_back(static_cast<int>(i));
    }
  }
}

double DifferenceStep(const model::ModelSpec& spec, const model::ParameterInfo& info, double value) {
  // Relative for a log-scale parameter, a millionth of the range for a bounded one.
  if (info.kind == model::ParameterKind::kEffect) {
    const model::EffectParameterRange range =
        model::EffectRange(model::ExpandedBefore(spec, info.effect), spec.effects.at(info.effect), info.effect_parameter);
    if (range.log_scale && value != 0.0) return 1e-5 * std::abs(value);
    if (std::isfinite(range.upper - range.lower)) return 1e-6 * (range.upper - range.lower);
    return 1e-6 * std::max(1.0, std::abs(value));
  }
  return value != 0.0 ? 1e-5 * std::abs(value) : 1e-9;
}

bool ModelFitProblem::Evaluate(const Eigen::VectorXd& p, Eigen::VectorXd* residuals,
                               Eigen::MatrixXd* jacobian) const {
  STAGEFIT_ASSERT(p.size() == num_parameters(), "expected " << num_parameters() << " parameters, got " << p.size());
  try {
    for (int i = 0; i < num_parameters(); ++i) model::SetParameter(spec_, parameters_[i], p[i]);
    if (jacobian == nullptr || differenced_.empty()) {
      comparison_->ResidualsAndJacobian(spec_, parameters_, residuals, jacobian, &workspace_);
      return true;
    }
    // Columns of the parameters without an analytic derivative (model/parameters.h): by the cheapest
    // route exact for each (ColumnRoute), from the specs at p +- h.
    const int nd = static_cast<int>(differenced_.size());
    routes_.assign(nd, ColumnRoute::kResidualDifference);
    std::vector<double> steps(nd);
    std::vector<model::ModelSpec> plus(nd, spec_), minus(nd, spec_);
    std::vector<response::DynamicStiffnessDerivative> further;
    std::vector<int> further_of;
    std::vector<double> delay_plus(nd), delay_minus(nd);
    const model::SecondOrderSystem at = comparison_->ModelSystem(spec_);
    for (int k = 0; k < nd; ++k) {
      const int i = differenced_[k];
      steps[k] = DifferenceStep(spec_, parameters_[i], p[i]);
      model::SetParameter(plus[k], parameters_[i], p[i] + steps[k]);
      model::SetParameter(minus[k], parameters_[i], p[i] - steps[k]);
      model::SecondOrderSystem sp, sm;
      routes_[k] = ChooseColumnRoute(*comparison_, spec_, at, plus[k], minus[k], &sp, &sm);
      delay_plus[k] = sp.delay_s - at.delay_s;
      delay_minus[k] = sm.delay_s - at.delay_s;
      if (routes_[k] == ColumnRoute::kSystemDifference) {
        further.push_back(SystemDifference(sp, sm, steps[k], parameters_[i].name));
        further_of.push_back(k);
      }
    }
    comparison_->ResidualsAndJacobian(spec_, analytic_params_, further, residuals, &columns_, &workspace_);
    jacobian->resize(residuals->size(), num_parameters());
    for (size_t a = 0; a < analytic_.size(); ++a) jacobian->col(analytic_[a]) = columns_.col(static_cast<int>(a));
    const int na = static_cast<int>(analytic_.size());
    for (size_t f = 0; f < further_of.size(); ++f) {
      jacobian->col(differenced_[further_of[f]]) = columns_.col(na + static_cast<int>(f));
    }
    for (int k = 0; k < nd; ++k) {
      if (routes_[k] == ColumnRoute::kSystemDifference) continue;
      ResidualsAtSteps(*comparison_, routes_[k], plus[k], minus[k], delay_plus[k], delay_minus[k],
                       workspace_.frf.frf.values, &difference_workspace_, &r_plus_, &r_minus_);
      jacobian->col(differenced_[k]) = (r_plus_ - r_minus_) / (2 * steps[k]);
    }
    return residuals->allFinite() && jacobian->allFinite();
  } catch (const NumericalError&) {
    return false;
  } catch (const InputError&) {
    return false;
  }
}

std::unique_ptr<LeastSquaresProblem> ModelFitProblem::Clone() const {
  return std::make_unique<ModelFitProblem>(spec_, *comparison_, parameters_);
}

std::unique_ptr<const ProbeCosts> ModelFitProblem::PrepareProbeCosts(const Eigen::VectorXd& p) const {
  STAGEFIT_ASSERT(p.size() == num_parameters(), "expected " << num_parameters() << " parameters, got " << p.size());
  model::ModelSpec at = spec_;
  try {
    for (int i = 0; i < num_parameters(); ++i) model::SetParameter(at, parameters_[i], p[i]);
  } catch (const InputError&) {
    return nullptr;
  }
  return MakeParameterProbeCosts(*comparison_, at, parameters_, p, 0);
}

std::unique_ptr<const ProbeCosts> MakeParameterProbeCosts(const compare::Comparison& comparison, const model::ModelSpec& spec,
                                                          const std::vector<model::ParameterInfo>& parameters,
                                                          const Eigen::VectorXd& p, int first) {
  try {
    auto probes = std::make_unique<const compare::ParameterProbes>(comparison, spec, parameters);
    if (!probes->any()) return nullptr;
    return std::make_unique<ParameterProbeCosts>(std::move(probes), p, first);
  } catch (const NumericalError&) {
    return nullptr;
  } catch (const InputError&) {
    return nullptr;
  }
}

ParameterProbeCosts::ParameterProbeCosts(std::unique_ptr<const compare::ParameterProbes> probes, Eigen::VectorXd at,
                                         int first)
    : probes_(std::move(probes)), at_(std::move(at)), first_(first) {}

bool ParameterProbeCosts::Cost(const Eigen::VectorXd& q, double* cost) const {
  STAGEFIT_ASSERT(q.size() == at_.size(), "expected " << at_.size() << " parameters, got " << q.size());
  std::vector<std::pair<int, double>> changes;
  for (int i = 0; i < q.size(); ++i) {
    if (q[i] == at_[i]) continue;
    const int k = i - first_;
    if (k < 0 || !probes_->CanProbe(k)) return false;
    changes.emplace_back(k, q[i]);
  }
  Eigen::VectorXd r;
  try {
    if (!probes_->Residuals(changes, &r)) return false;
  } catch (const NumericalError&) {
    *cost = std::numeric_limits<double>::infinity();
    return true;
  } catch (const InputError&) {
    *cost = std::numeric_limits<double>::infinity();
    return true;
  }
  *cost = r.allFinite() ? 0.5 * r.squaredNorm() : std::numeric_limits<double>::infinity();
  return true;
}

std::vector<ParameterSpec> MakeParameterSpecs(const model::ModelSpec& spec,
                                              const std::vector<model::ParameterInfo>& parameters,
                                              const std::vector<BoundRule>& bounds) {
  std::vector<ParameterSpec> specs;
  for (const auto& info : parameters) {
    ParameterSpec s;
    s.name = info.name;
    s.unit = SiUnit(info.dimension);
    s.initial = model::GetParameter(spec, info);
    s.log_scale = info.positive && s.initial > 0.0;
    if (info.kind == model::ParameterKind::kEffect) {
      // The catalogue entry's range around the value, on the model the effect is applied to.
      const model::EffectParameterRange range = model::EffectRange(
          model::ExpandedBefore(spec, info.effect), spec.effects.at(info.effect), info.effect_parameter);
      s.log_scale = range.log_scale && s.initial > 0.0;
      s.lower = std::min(range.lower, s.initial);
      s.upper = std::max(range.upper, s.initial);
      s.scale = range.scale;
    } else if (s.log_scale) {
      s.lower = s.initial / kDefaultBoundFactor;
      s.upper = s.initial * kDefaultBoundFactor;
    } else if (info.positive) {
      s.lower = 0.0;
    }
    specs.push_back(s);
  }
  for (const auto& rule : bounds) {
    if (rule.factor && !(*rule.factor > 1.0)) {
      throw InputError(RuleName(rule) + ": factor = " + Number(*rule.factor) + ", expected a number > 1");
    }
    if (rule.lower && rule.upper && !(*rule.lower <= *rule.upper)) {
      throw InputError(RuleName(rule) + ": lower = " + Number(*rule.lower) + " > upper = " + Number(*rule.upper) +
                       ", expected lower <= upper");
    }
    bool any = false;
    for (size_t i = 0; i < parameters.size(); ++i) {
      if (!MatchesPattern(parameters[i].name, rule.pattern)) continue;
      any = true;
      ParameterSpec& s = specs[i];
      if (rule.dimension && *rule.dimension != parameters[i].dimension && (rule.lower || rule.upper)) {
        throw InputError(RuleName(rule) + ": the bounds are in " + DescribeDimension(*rule.dimension) + ", but '" +
                         s.name + "' is a " + DescribeDimension(parameters[i].dimension));
      }
      if (rule.factor) {
        if (!(s.initial != 0.0)) {
          throw InputError(RuleName(rule) + ": factor bounds need a non-zero initial value, '" + s.name +
                           "' is 0; give lower and upper");
        }
        const double a = s.initial / *rule.factor, b = s.initial * *rule.factor;
        s.lower = std::min(a, b);
        s.upper = std::max(a, b);
      }
      if (rule.lower) s.lower = *rule.lower;
      if (rule.upper) s.upper = *rule.upper;
      if (s.log_scale && !(s.lower > 0.0)) {
        throw InputError(RuleName(rule) + ": lower = " + Number(s.lower) + " " + s.unit + " for '" + s.name +
                         "', expected > 0 (a positive parameter is fitted on a log scale)");
      }
      if (!(s.lower <= s.initial && s.initial <= s.upper)) {
        throw InputError(RuleName(rule) + ": '" + s.name + "' starts at " + Number(s.initial) + " " + s.unit +
                         ", outside the bounds [" + Number(s.lower) + ", " + Number(s.upper) +
                         "]; expected bounds around the initial value");
      }
    }
    if (!any) {
      throw InputError(RuleName(rule) + " matches none of the fitted parameters");
    }
  }
  return specs;
}

std::vector<SeriesPair> SeriesPairs(const model::ModelSpec& spec, const std::vector<model::ParameterInfo>& parameters) {
  // The fitted stiffness of each (joint, DoF).
  std::vector<std::array<int, 6>> fitted(spec.joints.size());
  for (auto& f : fitted) f.fill(-1);
  for (size_t i = 0; i < parameters.size(); ++i) {
    const auto& info = parameters[i];
    if (info.kind == model::ParameterKind::kStiffness) fitted[info.joint][static_cast<int>(info.a)] = static_cast<int>(i);
  }
  // The joint standing on a body, when it is the only one.
  auto joint_on = [&](const std::string& body) {
    int found = -1;
    for (size_t j = 0; j < spec.joints.size(); ++j) {
      if (spec.joints[j].parent != body) continue;
      if (found >= 0) return -1;
      found = static_cast<int>(j);
    }
    return found;
  };
  std::vector<SeriesPair> pairs;
  for (size_t j = 0; j < spec.joints.size(); ++j) {
    for (int d = 0; d < 6; ++d) {
      if (fitted[j][d] < 0) continue;
      int k = static_cast<int>(j);
      for (size_t steps = 0; steps < spec.joints.size(); ++steps) {
        k = joint_on(spec.joints[k].child);
        if (k < 0) break;
        const model::JointSpec& upper = spec.joints[k];
        if (!(upper.R_WJ.transpose() * spec.joints[j].R_WJ).isIdentity(1e-9)) break;
        if (upper.imposed[d]) continue;
        if (fitted[k][d] >= 0) pairs.push_back({fitted[j][d], fitted[k][d]});
        break;
      }
    }
  }
  return pairs;
}

FitSummary FitModel(model::ModelSpec& spec, const compare::Comparison& comparison,
                    const std::vector<model::ParameterInfo>& parameters, const FitOptions& options,
                    const std::vector<BoundRule>& bounds) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<ParameterSpec> specs = MakeParameterSpecs(spec, parameters, bounds);
  const double error_before = comparison.Error(spec);
  const ModelFitProblem problem(spec, comparison, parameters);
  FitSummary summary = SolveWithProbes(problem, specs, options, SeriesPairs(spec, parameters));
  summary.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (size_t i = 0; i < parameters.size(); ++i) model::SetParameter(spec, parameters[i], summary.parameters[i].value);
  summary.initial_error = error_before;
  summary.initial_cost = 0.5 * error_before * error_before;
  try {
    summary.final_error = comparison.Error(spec);
  } catch (const NumericalError& e) {
    summary.final_error = std::numeric_limits<double>::quiet_NaN();
    summary.status = FitStatus::kFailed;
    summary.message += std::string("; the model at the result cannot be evaluated: ") + e.what();
  }
  summary.final_cost = 0.5 * summary.final_error * summary.final_error;
  std::ostringstream detail;
  detail << ToString(summary.status) << ", " << parameters.size() << " parameters (";
  for (size_t i = 0; i < parameters.size(); ++i) detail << (i ? " " : "") << parameters[i].name;
  detail << "), " << summary.solver << ", error " << Number(error_before) << " -> " << Number(summary.final_error);
  spec.history.push_back({"fit", summary.final_error, detail.str()});
  return summary;
}

FitSummary FitModelWithBandContinuation(model::ModelSpec& spec, const measurement::FrfData& measurement,
                                        const compare::ComparisonOptions& comparison_options,
                                        const compare::Comparison& comparison,
                                        const std::vector<model::ParameterInfo>& parameters, const FitOptions& options,
                                        const std::vector<BoundRule>& bounds) {
  const auto t0 = std::chrono::steady_clock::now();
  const Eigen::VectorXd& f = comparison.frequency_hz();
  const double f_low = f(0), f_high = f(f.size() - 1);
  const double error_before = comparison.Error(spec);
  // The two routes are independent: run side by side (each one's FRF evaluations helped by the other's
  // thread once it is done), their progress reported one call at a time.
  FitOptions route_options = options;
  route_options.progress = OneCallAtATime(options.progress);
  // Route 1: the stages, each from the previous one's result.
  model::ModelSpec staged = spec;
  std::vector<double> edges;
  for (double edge = 8.0 * f_low; edge < f_high / 1.25; edge *= 2.5) edges.push_back(edge);
  FitSummary via_stages;
  auto run_stages = [&] {
    const auto history = spec.history;
    for (double edge : edges) {
      compare::ComparisonOptions stage_options = comparison_options;
      stage_options.fmax_hz = edge;
      try {
        const compare::Comparison stage = compare::Comparison::Create(staged, measurement, stage_options);
        FitModel(staged, stage, parameters, route_options, bounds);
      } catch (const InputError&) {
        continue;  // too few points or no significant element below the edge
      }
    }
    staged.history = history;
    via_stages = FitModel(staged, comparison, parameters, route_options, bounds);
  };
  // Route 2: directly on the whole band from the model as given.
  model::ModelSpec direct = spec;
  FitSummary at_once;
  RunConcurrently({run_stages, [&] { at_once = FitModel(direct, comparison, parameters, route_options, bounds); }});
  const bool stages_better = via_stages.final_error < at_once.final_error;
  FitSummary& kept = stages_better ? via_stages : at_once;
  spec = stages_better ? staged : direct;
  std::ostringstream note;
  note << "; kept the " << (stages_better ? "band continuation" : "direct fit") << " (error "
       << Number(via_stages.final_error) << " with " << edges.size() << " band stages, " << Number(at_once.final_error)
       << " directly)";
  kept.message += note.str();
  kept.initial_error = error_before;
  kept.initial_cost = 0.5 * error_before * error_before;
  kept.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!spec.history.empty()) spec.history.back().detail += note.str();
  return kept;
}

}  // namespace stagefit::fit
