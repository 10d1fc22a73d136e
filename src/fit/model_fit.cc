#include "stagefit/fit/model_fit.h"

#include <fnmatch.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "stagefit/common/error.h"
#include "stagefit/common/units.h"

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

ModelFitProblem::ModelFitProblem(const model::ModelSpec& spec, const compare::Comparison& comparison,
                                 std::vector<model::ParameterInfo> parameters)
    : spec_(spec), comparison_(&comparison), parameters_(std::move(parameters)) {}

bool ModelFitProblem::Evaluate(const Eigen::VectorXd& p, Eigen::VectorXd* residuals,
                               Eigen::MatrixXd* jacobian) const {
  STAGEFIT_ASSERT(p.size() == num_parameters(), "expected " << num_parameters() << " parameters, got " << p.size());
  for (int i = 0; i < num_parameters(); ++i) model::SetParameter(spec_, parameters_[i], p[i]);
  try {
    comparison_->ResidualsAndJacobian(spec_, parameters_, residuals, jacobian, &workspace_);
  } catch (const NumericalError&) {
    return false;
  } catch (const InputError&) {
    return false;
  }
  return true;
}

std::unique_ptr<LeastSquaresProblem> ModelFitProblem::Clone() const {
  return std::make_unique<ModelFitProblem>(spec_, *comparison_, parameters_);
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
    if (s.log_scale) {
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
  // Route 1: the stages, each from the previous one's result.
  model::ModelSpec staged = spec;
  const auto history = spec.history;
  std::vector<double> edges;
  for (double edge = 8.0 * f_low; edge < f_high / 1.25; edge *= 2.5) edges.push_back(edge);
  for (double edge : edges) {
    compare::ComparisonOptions stage_options = comparison_options;
    stage_options.fmax_hz = edge;
    try {
      const compare::Comparison stage = compare::Comparison::Create(staged, measurement, stage_options);
      FitModel(staged, stage, parameters, options, bounds);
    } catch (const InputError&) {
      continue;  // too few points or no significant element below the edge
    }
  }
  staged.history = history;
  FitSummary via_stages = FitModel(staged, comparison, parameters, options, bounds);
  // Route 2: directly on the whole band from the model as given.
  model::ModelSpec direct = spec;
  FitSummary at_once = FitModel(direct, comparison, parameters, options, bounds);
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
