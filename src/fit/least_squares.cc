#include "stagefit/fit/least_squares.h"

#include <ceres/ceres.h>
#include <glog/logging.h>
#include <nlopt.h>


#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <mutex>
#include <random>
#include <sstream>

#include "stagefit/common/eigen_decomposition.h"
#include "stagefit/common/error.h"
#include "stagefit/common/parallel.h"

namespace stagefit::fit {
namespace {

using Clock = std::chrono::steady_clock;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A component of a null-space direction above this marks a parameter as undetermined.
constexpr double kNullSpaceComponent = 1e-2;
// A parameter within this (relative, in theta) of a bound is reported at the bound.
constexpr double kAtBoundTolerance = 1e-6;
// Relative rounding allowance between the cost of NLopt (||r||^2 / 2 summed here) and that of Ceres.
constexpr double kPolishCostSlack = 1e-9;

std::string Format(const char* format, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), format, value);
  return buffer;
}

// The map between the natural parameters p and the optimisation variables theta.
struct ParameterMap {
  std::vector<ParameterSpec> specs;

  int size() const { return static_cast<int>(specs.size()); }
  double ToTheta(int i, double p) const { return specs[i].log_scale ? std::log(p) : p / specs[i].scale; }
  double ToP(int i, double theta) const { return specs[i].log_scale ? std::exp(theta) : theta * specs[i].scale; }
  Eigen::VectorXd ToTheta(const Eigen::VectorXd& p) const {
    Eigen::VectorXd theta(p.size());
    for (int i = 0; i < size(); ++i) theta[i] = ToTheta(i, p[i]);
    return theta;
  }
  Eigen::VectorXd ToP(const double* theta) const {
    Eigen::VectorXd p(size());
    for (int i = 0; i < size(); ++i) p[i] = ToP(i, theta[i]);
    return p;
  }
  // dp/dtheta.
  Eigen::VectorXd Scale(const Eigen::VectorXd& p) const {
    Eigen::VectorXd d(size());
    for (int i = 0; i < size(); ++i) d[i] = specs[i].log_scale ? p[i] : specs[i].scale;
    return d;
  }
  double LowerTheta(int i) const {
    const double lo = specs[i].lower;
    if (specs[i].log_scale) return lo > 0.0 ? std::log(lo) : -kInf;
    return lo / specs[i].scale;
  }
  double UpperTheta(int i) const {
    const double hi = specs[i].upper;
    if (specs[i].log_scale) return std::isfinite(hi) ? std::log(hi) : kInf;
    return hi / specs[i].scale;
  }
};

// Shared state of the cost functions: the problem, the map and an evaluation counter.
struct EvaluationContext {
  const LeastSquaresProblem* problem = nullptr;
  ParameterMap map;
  mutable int num_evaluations = 0;
};

bool AllFinite(const Eigen::VectorXd& v) { return v.allFinite(); }

// r(theta), and dr/dtheta from the problem's analytic Jacobian and the chain rule.
class AnalyticCost final : public ceres::CostFunction {
 public:
  explicit AnalyticCost(const EvaluationContext* context) : context_(context) {
    set_num_residuals(context->problem->num_residuals());
    mutable_parameter_block_sizes()->push_back(context->problem->num_parameters());
  }

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const int n = context_->map.size();
    const int m = num_residuals();
    const Eigen::VectorXd p = context_->map.ToP(parameters[0]);
    const bool want_jacobian = jacobians != nullptr && jacobians[0] != nullptr;
    // The last point again (bit for bit): its residuals, and its Jacobian when it was evaluated there.
    // With bounds, each Levenberg-Marquardt step is a projected line search from step 1 (FitOptions::
    // projected_line_search), whose first trial evaluates r and J at the candidate; the minimizer
    // then evaluates the candidate's cost, and its r and J once the step is taken: three evaluations of
    // one point, two of them with the Jacobian.
    const bool again = at_.size() == n && std::memcmp(at_.data(), parameters[0], sizeof(double) * n) == 0 &&
                       (!want_jacobian || jacobian_at_);
    if (!again) {
      ++context_->num_evaluations;
      at_.resize(0);
      if (!context_->problem->Evaluate(p, &r_, want_jacobian ? &J_ : nullptr)) return false;
      at_ = Eigen::Map<const Eigen::VectorXd>(parameters[0], n);
      jacobian_at_ = want_jacobian;
    }
    STAGEFIT_ASSERT(r_.size() == m, "the problem returned " << r_.size() << " residuals, expected " << m);
    if (!AllFinite(r_)) return false;
    Eigen::Map<Eigen::VectorXd>(residuals, m) = r_;
    if (want_jacobian) {
      STAGEFIT_ASSERT(J_.rows() == m && J_.cols() == n,
                      "the problem returned a " << J_.rows() << " x " << J_.cols() << " Jacobian, expected "
                                                << m << " x " << n);
      if (!J_.allFinite()) return false;
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(jacobians[0], m, n) =
          J_ * context_->map.Scale(p).asDiagonal();
    }
    return true;
  }

 private:
  const EvaluationContext* context_;
  mutable Eigen::VectorXd r_;
  mutable Eigen::MatrixXd J_;
  mutable Eigen::VectorXd at_;       // the theta r_ was evaluated at (empty: none)
  mutable bool jacobian_at_ = false;  // J_ too
};

// r(theta) alone, for ceres::DynamicNumericDiffCostFunction.
struct ResidualFunctor {
  const EvaluationContext* context;
  bool operator()(double const* const* parameters, double* residuals) const {
    ++context->num_evaluations;
    Eigen::VectorXd r;
    if (!context->problem->Evaluate(context->map.ToP(parameters[0]), &r, nullptr)) return false;
    if (r.size() != context->problem->num_residuals() || !AllFinite(r)) return false;
    Eigen::Map<Eigen::VectorXd>(residuals, r.size()) = r;
    return true;
  }
};

std::unique_ptr<ceres::CostFunction> MakeCostFunction(const EvaluationContext* context, JacobianKind kind) {
  if (kind == JacobianKind::kAnalytic) return std::make_unique<AnalyticCost>(context);
  auto cost = std::make_unique<ceres::DynamicNumericDiffCostFunction<ResidualFunctor, ceres::CENTRAL>>(
      new ResidualFunctor{context});
  cost->AddParameterBlock(context->map.size());
  cost->SetNumResiduals(context->problem->num_residuals());
  return cost;
}

// Residuals and (optionally) the Jacobian dr/dtheta through a cost function.
bool EvaluateTheta(const ceres::CostFunction& cost, const Eigen::VectorXd& theta, Eigen::VectorXd* r,
                   Eigen::MatrixXd* J_theta) {
  const int m = cost.num_residuals();
  const int n = static_cast<int>(theta.size());
  r->resize(m);
  const double* parameters[] = {theta.data()};
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> J_row;
  double* jacobians[] = {nullptr};
  if (J_theta != nullptr) {
    J_row.resize(m, n);
    jacobians[0] = J_row.data();
  }
  if (!cost.Evaluate(parameters, r->data(), J_theta != nullptr ? jacobians : nullptr)) return false;
  if (J_theta != nullptr) *J_theta = J_row;
  return r->allFinite();
}

struct StageResult {
  Eigen::VectorXd theta;
  double cost = kNaN;
  FitStatus status = FitStatus::kFailed;
  int iterations = 0;
  std::string message;
};

class ProgressCallback final : public ceres::IterationCallback {
 public:
  ProgressCallback(const FitOptions& options, FitProgress base, Clock::time_point t0)
      : options_(options), base_(std::move(base)), t0_(t0) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override {
    FitProgress progress = base_;
    progress.iteration = summary.iteration;
    progress.cost = summary.cost;
    progress.elapsed_s = std::chrono::duration<double>(Clock::now() - t0_).count();
    options_.progress(progress);
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const FitOptions& options_;
  FitProgress base_;
  Clock::time_point t0_;
};

// Stops a Ceres run whose lowest error has fallen by less than FitOptions::stall_relative_decrease of
// itself over the last FitOptions::stall_iterations iterations.
class StallCallback final : public ceres::IterationCallback {
 public:
  StallCallback(int iterations, double relative_decrease) : iterations_(iterations), relative_decrease_(relative_decrease) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override {
    const double error = std::sqrt(2.0 * summary.cost);
    lowest_.push_back(lowest_.empty() ? error : std::min(lowest_.back(), error));
    const size_t n = lowest_.size();
    if (n > static_cast<size_t>(iterations_) &&
        lowest_[n - 1 - static_cast<size_t>(iterations_)] - lowest_[n - 1] < relative_decrease_ * lowest_[n - 1]) {
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    }
    return ceres::SOLVER_CONTINUE;
  }

 private:
  int iterations_;
  double relative_decrease_;
  std::vector<double> lowest_;  // the lowest error up to each iteration
};

StageResult RunCeres(const ceres::CostFunction& cost, const ParameterMap& map, const Eigen::VectorXd& theta0,
                     const FitOptions& options, const FitProgress& base, Clock::time_point t0) {
  StageResult result;
  result.theta = theta0;
  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  problem.AddResidualBlock(const_cast<ceres::CostFunction*>(&cost), nullptr, result.theta.data());
  for (int i = 0; i < map.size(); ++i) {
    if (std::isfinite(map.LowerTheta(i))) problem.SetParameterLowerBound(result.theta.data(), i, map.LowerTheta(i));
    if (std::isfinite(map.UpperTheta(i))) problem.SetParameterUpperBound(result.theta.data(), i, map.UpperTheta(i));
  }
  ceres::Solver::Options solver_options;
  solver_options.max_num_line_search_step_size_iterations = options.projected_line_search ? 20 : 0;
  solver_options.minimizer_type = ceres::TRUST_REGION;
  solver_options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  // The normal equations J'J (n x n, n a few tens) by Cholesky rather than a QR of J (m x n, m up to
  // 10^5 residuals): the Levenberg-Marquardt damping keeps J'J + D positive definite, and the two-effect
  // loops of eval_loop's seeds 73000-73005 and 75008-75009 ended with the same effects (one nearer the
  // truth) in 0.92x the time (docs/fitting.md).
  solver_options.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.initial_trust_region_radius = options.initial_trust_region_radius;
  solver_options.use_nonmonotonic_steps = options.nonmonotonic_steps;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.gradient_tolerance = options.gradient_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  solver_options.logging_type = ceres::SILENT;
  solver_options.minimizer_progress_to_stdout = false;
  solver_options.num_threads = 1;
  std::unique_ptr<ProgressCallback> callback;
  if (options.progress) {
    callback = std::make_unique<ProgressCallback>(options, base, t0);
    solver_options.callbacks.push_back(callback.get());
  }
  std::unique_ptr<StallCallback> stall;
  if (options.stall_iterations > 0) {
    stall = std::make_unique<StallCallback>(options.stall_iterations, options.stall_relative_decrease);
    solver_options.callbacks.push_back(stall.get());
  }
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);
  result.iterations = summary.num_successful_steps + summary.num_unsuccessful_steps;
  result.message = "ceres: " + summary.message;
  switch (summary.termination_type) {
    case ceres::CONVERGENCE:
    case ceres::USER_SUCCESS:
      result.status = FitStatus::kConverged;
      break;
    case ceres::NO_CONVERGENCE:
      result.status = FitStatus::kMaxIterations;
      break;
    default:
      result.status = FitStatus::kFailed;
      break;
  }
  result.cost = summary.IsSolutionUsable() && std::isfinite(summary.final_cost) ? summary.final_cost : kNaN;
  return result;
}

struct NloptContext {
  const ceres::CostFunction* cost = nullptr;
  const FitOptions* options = nullptr;
  FitProgress base;
  Clock::time_point t0;
  int evaluations = 0;
  double best = kInf;
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
};

double NloptObjective(unsigned n, const double* x, double* grad, void* data) {
  auto* context = static_cast<NloptContext*>(data);
  const Eigen::VectorXd theta = Eigen::Map<const Eigen::VectorXd>(x, n);
  ++context->evaluations;
  if (!EvaluateTheta(*context->cost, theta, &context->r, grad != nullptr ? &context->J : nullptr)) {
    if (grad != nullptr) std::fill(grad, grad + n, 0.0);
    return kInf;
  }
  const double f = context->r.squaredNorm();
  if (grad != nullptr) Eigen::Map<Eigen::VectorXd>(grad, n) = 2.0 * context->J.transpose() * context->r;
  context->best = std::min(context->best, 0.5 * f);
  if (context->options->progress) {
    FitProgress progress = context->base;
    progress.iteration = context->evaluations;
    progress.cost = 0.5 * f;
    progress.elapsed_s = std::chrono::duration<double>(Clock::now() - context->t0).count();
    context->options->progress(progress);
  }
  return f;
}

nlopt_algorithm LookUpNloptAlgorithm(const std::string& name, const std::string& context) {
  std::string bare = name;
  if (bare.rfind("NLOPT_", 0) == 0) bare = bare.substr(6);
  const nlopt_algorithm algorithm = nlopt_algorithm_from_string(bare.c_str());
  if (static_cast<int>(algorithm) < 0) {
    throw InputError(context + " = '" + name +
                     "' is not an NLopt algorithm, expected a name such as LN_BOBYQA, LN_SBPLX, LN_NELDERMEAD, "
                     "LN_COBYLA, GN_CRS2_LM, GN_DIRECT, GN_ISRES, LD_LBFGS, LD_SLSQP");
  }
  return algorithm;
}

bool IsGlobal(const std::string& name) {
  std::string bare = name.rfind("NLOPT_", 0) == 0 ? name.substr(6) : name;
  return bare.rfind("G", 0) == 0;
}

StageResult RunNlopt(const ceres::CostFunction& cost, const ParameterMap& map, const Eigen::VectorXd& theta0,
                     const FitOptions& options, const FitProgress& base, Clock::time_point t0) {
  const int n = map.size();
  const nlopt_algorithm algorithm = LookUpNloptAlgorithm(options.nlopt_algorithm, "--nlopt-algorithm");
  std::unique_ptr<nlopt_opt_s, void (*)(nlopt_opt)> opt(nlopt_create(algorithm, n), nlopt_destroy);
  STAGEFIT_ASSERT(opt != nullptr, "nlopt_create failed");
  std::vector<double> lower(n), upper(n), step(n);
  for (int i = 0; i < n; ++i) {
    lower[i] = map.LowerTheta(i);
    upper[i] = map.UpperTheta(i);
    // Initial step: 10 % of the value (0.1 in ln p), at most a quarter of the bound interval.
    double s = map.specs[i].log_scale ? 0.1 : 0.1 * std::max(std::abs(theta0[i]), 1e-12);
    if (std::isfinite(upper[i] - lower[i])) s = std::min(s, 0.25 * (upper[i] - lower[i]));
    step[i] = s;
  }
  nlopt_set_lower_bounds(opt.get(), lower.data());
  nlopt_set_upper_bounds(opt.get(), upper.data());
  nlopt_set_initial_step(opt.get(), step.data());
  nlopt_set_maxeval(opt.get(), options.nlopt_max_evaluations);
  nlopt_set_ftol_rel(opt.get(), options.nlopt_relative_tolerance);
  nlopt_set_xtol_rel(opt.get(), options.nlopt_relative_tolerance);
  NloptContext context;
  context.cost = &cost;
  context.options = &options;
  context.base = base;
  context.base.stage = "nlopt";
  context.t0 = t0;
  nlopt_set_min_objective(opt.get(), NloptObjective, &context);
  // Stochastic algorithms (CRS, ISRES, MLSL) draw from NLopt's global generator: seed it per start.
  nlopt_srand(static_cast<unsigned long>(options.seed + 7919u * static_cast<std::uint64_t>(base.start)));
  std::vector<double> x(theta0.data(), theta0.data() + n);
  double f = kInf;
  const nlopt_result code = nlopt_optimize(opt.get(), x.data(), &f);
  StageResult result;
  result.theta = Eigen::Map<Eigen::VectorXd>(x.data(), n);
  result.iterations = context.evaluations;
  result.cost = std::isfinite(f) ? 0.5 * f : kNaN;
  result.message = std::string("nlopt ") + nlopt_algorithm_name(algorithm) + ": " + nlopt_result_to_string(code) +
                   " after " + std::to_string(context.evaluations) + " evaluations";
  if (code == NLOPT_MAXEVAL_REACHED || code == NLOPT_MAXTIME_REACHED) {
    result.status = FitStatus::kMaxIterations;
  } else if (code > 0) {
    result.status = FitStatus::kConverged;
  } else {
    result.status = FitStatus::kFailed;
  }
  if (!std::isfinite(f)) result.status = FitStatus::kFailed;
  return result;
}

void CheckParameters(const std::vector<ParameterSpec>& parameters) {
  for (const auto& p : parameters) {
    std::ostringstream where;
    where << "parameter '" << p.name << "'";
    if (!std::isfinite(p.initial)) throw InputError(where.str() + ": initial value is not finite");
    if (!(p.lower <= p.upper)) {
      throw InputError(where.str() + ": lower bound " + Format("%.6g", p.lower) + " > upper bound " +
                       Format("%.6g", p.upper) + ", expected lower <= upper");
    }
    if (p.initial < p.lower || p.initial > p.upper) {
      throw InputError(where.str() + ": initial value " + Format("%.6g", p.initial) + " " + p.unit +
                       " is outside its bounds [" + Format("%.6g", p.lower) + ", " + Format("%.6g", p.upper) + "]");
    }
    if (!(p.scale > 0.0 && std::isfinite(p.scale))) {
      throw InputError(where.str() + ": scale " + Format("%.6g", p.scale) + ", expected a finite value > 0");
    }
    if (p.log_scale && !(p.initial > 0.0)) {
      throw InputError(where.str() + ": initial value " + Format("%.6g", p.initial) +
                       " is not positive, expected > 0 for a log-scale parameter");
    }
    if (p.log_scale && p.lower < 0.0 && std::isfinite(p.lower)) {
      throw InputError(where.str() + ": lower bound " + Format("%.6g", p.lower) +
                       " is negative, expected >= 0 for a positive (log-scale) parameter");
    }
  }
}

// A uniform number in [0, 1) from 53 bits of the generator (the same on every standard library).
double Uniform(std::mt19937_64& generator) {
  return static_cast<double>(generator() >> 11) * 0x1.0p-53;
}

Eigen::VectorXd DrawStart(const ParameterMap& map, const Eigen::VectorXd& theta0, double factor,
                          std::mt19937_64& generator) {
  Eigen::VectorXd theta = theta0;
  for (int i = 0; i < map.size(); ++i) {
    double lo, hi;
    if (map.specs[i].log_scale) {
      lo = theta0[i] - std::log(factor);
      hi = theta0[i] + std::log(factor);
    } else {
      const double half = (factor - 1.0) * std::abs(theta0[i]);
      lo = theta0[i] - half;
      hi = theta0[i] + half;
    }
    const double u = Uniform(generator);
    theta[i] = std::clamp(lo + u * (hi - lo), map.LowerTheta(i), map.UpperTheta(i));
  }
  return theta;
}

// Covariance, correlation, sensitivities and identifiability warnings at the optimum.
void AnalyseOptimum(const ceres::CostFunction& cost, const ParameterMap& map, const Eigen::VectorXd& theta,
                    const FitOptions& options, FitSummary* summary) {
  const int n = map.size();
  const int m = summary->num_residuals;
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  summary->covariance = Eigen::MatrixXd::Constant(n, n, kNaN);
  summary->correlation = Eigen::MatrixXd::Constant(n, n, kNaN);
  if (n == 0) return;
  if (!EvaluateTheta(cost, theta, &r, &J)) {
    summary->warnings.push_back("the Jacobian cannot be evaluated at the optimum: no standard deviations");
    for (auto& p : summary->parameters) p.std_dev = kNaN;
    return;
  }
  const Eigen::VectorXd p = map.ToP(theta.data());
  const Eigen::VectorXd scale = map.Scale(p);
  summary->residual_variance = m > n ? r.squaredNorm() / (m - n) : kNaN;
  if (m <= n) {
    summary->warnings.push_back("as many parameters as residuals (" + std::to_string(n) + " >= " +
                                std::to_string(m) + "): the residual variance and the standard deviations "
                                "cannot be estimated");
  }

  const Eigen::VectorXd column_norm = J.colwise().norm().transpose();
  const double max_norm = column_norm.maxCoeff();
  std::vector<bool> undetermined(n, false);
  Eigen::VectorXd inverse_norm(n);
  for (int i = 0; i < n; ++i) {
    summary->parameters[i].relative_sensitivity = max_norm > 0.0 ? column_norm[i] / max_norm : 0.0;
    undetermined[i] = !(column_norm[i] > 0.0);
    inverse_norm[i] = undetermined[i] ? 0.0 : 1.0 / column_norm[i];
  }
  const Eigen::MatrixXd Js = J * inverse_norm.asDiagonal();
  const SingularValueDecomposition svd = CalcSvd(Js, kSvdThinV);
  const Eigen::VectorXd& s = svd.values;
  const Eigen::MatrixXd& V = svd.V;
  const double s_max = s.size() > 0 ? s[0] : 0.0;
  Eigen::VectorXd inverse_s2 = Eigen::VectorXd::Zero(s.size());
  for (int k = 0; k < s.size(); ++k) {
    if (s[k] > kRankTolerance * s_max) {
      inverse_s2[k] = 1.0 / (s[k] * s[k]);
    } else {
      for (int i = 0; i < n; ++i) {
        if (std::abs(V(i, k)) > kNullSpaceComponent) undetermined[i] = true;
      }
    }
  }
  // Columns of J beyond its rank (m < n) have no singular value: their V components are missing.
  const Eigen::MatrixXd cov_scaled = V * inverse_s2.asDiagonal() * V.transpose();
  Eigen::MatrixXd cov_theta = inverse_norm.asDiagonal() * cov_scaled * inverse_norm.asDiagonal();
  cov_theta *= summary->residual_variance;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      if (undetermined[i] || undetermined[j]) {
        summary->covariance(i, j) = i == j ? kInf : kNaN;
        summary->correlation(i, j) = i == j ? 1.0 : kNaN;
      } else {
        summary->covariance(i, j) = scale[i] * cov_theta(i, j) * scale[j];
        summary->correlation(i, j) = cov_theta(i, j) / std::sqrt(cov_theta(i, i) * cov_theta(j, j));
      }
    }
  }

  for (int i = 0; i < n; ++i) {
    ParameterEstimate& e = summary->parameters[i];
    e.std_dev = std::sqrt(summary->covariance(i, i));
    const double lo = map.LowerTheta(i), hi = map.UpperTheta(i);
    const double tol = kAtBoundTolerance * std::max(1.0, std::abs(theta[i]));
    e.at_bound = (std::isfinite(lo) && theta[i] - lo <= tol) || (std::isfinite(hi) && hi - theta[i] <= tol);
    if (e.relative_sensitivity < options.min_relative_sensitivity) {
      e.identifiable = false;
      summary->warnings.push_back(e.name + ": the data barely sense it (relative sensitivity " +
                                  Format("%.2g", e.relative_sensitivity) + " < " +
                                  Format("%.2g", options.min_relative_sensitivity) + " of the most sensed)");
    }
    if (undetermined[i]) {
      e.identifiable = false;
      summary->warnings.push_back(e.name + ": undetermined (J'J is singular in its direction)");
    } else if (std::isfinite(e.std_dev) && e.std_dev > options.max_relative_std * std::abs(e.value)) {
      e.identifiable = false;
      summary->warnings.push_back(e.name + ": relative standard deviation " +
                                  Format("%.3g", e.std_dev / std::abs(e.value)) + " > " +
                                  Format("%.3g", options.max_relative_std));
    }
    if (e.at_bound) {
      summary->warnings.push_back(e.name + ": ended at a bound (" + Format("%.6g", e.value) + " " + e.unit +
                                  " in [" + Format("%.6g", e.lower) + ", " + Format("%.6g", e.upper) +
                                  "]); its standard deviation ignores the bound");
    }
  }
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      const double c = summary->correlation(i, j);
      if (std::isfinite(c) && std::abs(c) > options.max_correlation) {
        summary->parameters[i].identifiable = false;
        summary->parameters[j].identifiable = false;
        summary->warnings.push_back(summary->parameters[i].name + " and " + summary->parameters[j].name +
                                    " are correlated (" + Format("%+.3f", c) + ", |c| > " +
                                    Format("%.2f", options.max_correlation) +
                                    "): the data determine a combination of the two");
      }
    }
  }
}

}  // namespace

SolverKind ParseSolverKind(const std::string& text, const std::string& context) {
  if (text == "ceres") return SolverKind::kCeres;
  if (text == "nlopt") return SolverKind::kNlopt;
  throw InputError(context + " = '" + text + "', expected ceres or nlopt");
}

JacobianKind ParseJacobianKind(const std::string& text, const std::string& context) {
  if (text == "analytic") return JacobianKind::kAnalytic;
  if (text == "finite-difference") return JacobianKind::kFiniteDifference;
  throw InputError(context + " = '" + text + "', expected analytic or finite-difference");
}

std::string ToString(SolverKind kind) { return kind == SolverKind::kCeres ? "ceres" : "nlopt"; }
std::string ToString(JacobianKind kind) {
  return kind == JacobianKind::kAnalytic ? "analytic" : "finite-difference";
}

std::string ToString(FitStatus status) {
  switch (status) {
    case FitStatus::kConverged:
      return "converged";
    case FitStatus::kMaxIterations:
      return "max_iterations";
    case FitStatus::kFailed:
      return "failed";
  }
  return "failed";
}

std::function<void(const FitProgress&)> OneCallAtATime(std::function<void(const FitProgress&)> progress) {
  if (!progress) return progress;
  auto lock = std::make_shared<std::mutex>();
  return [lock, progress = std::move(progress)](const FitProgress& p) {
    const std::lock_guard<std::mutex> hold(*lock);
    progress(p);
  };
}

void CheckNloptAlgorithm(const std::string& name, const std::string& context) {
  LookUpNloptAlgorithm(name, context);
}

Eigen::VectorXd FitSummary::values() const {
  Eigen::VectorXd v(parameters.size());
  for (size_t i = 0; i < parameters.size(); ++i) v[i] = parameters[i].value;
  return v;
}

std::string FitSummary::BriefReport() const {
  char line[256];
  std::snprintf(line, sizeof(line), "fit %s: error %.6g -> %.6g (%d parameters, %d iterations, %.3g s%s%s)",
                ToString(status).c_str(), initial_error, final_error, num_parameters, iterations, time_s,
                warnings.empty() ? "" : ", ",
                warnings.empty() ? "" : (std::to_string(warnings.size()) + " warnings").c_str());
  return line;
}

std::string FitSummary::FullReport() const {
  std::ostringstream out;
  out << "Solver:      " << solver << "\n";
  out << "Status:      " << ToString(status) << " (" << message << ")\n";
  out << "Residuals:   " << num_residuals << ", parameters: " << num_parameters << "\n";
  char line[512];
  std::snprintf(line, sizeof(line), "Error:       %.6g -> %.6g   (cost %.6g -> %.6g)\n", initial_error, final_error,
                initial_cost, final_cost);
  out << line;
  std::snprintf(line, sizeof(line), "Iterations:  %d, evaluations: %d, time: %.3g s, sigma^2 = %.3g\n", iterations,
                num_evaluations, time_s, residual_variance);
  out << line;
  size_t width = 9;
  for (const auto& p : parameters) width = std::max(width, p.name.size());
  std::snprintf(line, sizeof(line), "%-*s %13s %13s %11s %8s  %-8s %s\n", static_cast<int>(width), "parameter",
                "initial", "value", "std", "std/val", "unit", "flags");
  out << line;
  for (const auto& p : parameters) {
    std::string flags;
    if (!p.identifiable) flags += "unidentifiable ";
    if (p.at_bound) flags += "at-bound ";
    std::snprintf(line, sizeof(line), "%-*s %13.6g %13.6g %11.3g %8.3g  %-8s %s\n", static_cast<int>(width),
                  p.name.c_str(), p.initial, p.value, p.std_dev, p.std_dev / std::abs(p.value), p.unit.c_str(),
                  flags.c_str());
    out << line;
  }
  if (starts.size() > 1) {
    std::vector<double> errors;
    int failed = 0;
    for (const auto& s : starts) {
      if (std::isfinite(s.final_cost)) {
        errors.push_back(std::sqrt(2.0 * s.final_cost));
      } else {
        ++failed;
      }
    }
    std::sort(errors.begin(), errors.end());
    if (!errors.empty()) {
      const double best = errors.front();
      const auto near = std::count_if(errors.begin(), errors.end(), [&](double e) { return e <= 1.01 * best; });
      std::snprintf(line, sizeof(line),
                    "Starts:      %zu (best #%d); final error min %.6g, median %.6g, max %.6g; %ld within 1 %% of "
                    "the best; %d failed\n",
                    starts.size(), best_start, best, errors[errors.size() / 2], errors.back(),
                    static_cast<long>(near), failed);
      out << line;
    }
  }
  for (const auto& w : warnings) out << "warning: " << w << "\n";
  return out.str();
}

FitSummary Solve(const LeastSquaresProblem& problem, const std::vector<ParameterSpec>& parameters,
                 const FitOptions& options) {
  const auto t0 = Clock::now();
  const int n = problem.num_parameters();
  if (static_cast<int>(parameters.size()) != n) {
    throw InputError("fit: " + std::to_string(parameters.size()) + " parameter specifications for a problem of " +
                     std::to_string(n) + " parameters");
  }
  CheckParameters(parameters);
  if (options.jacobian == JacobianKind::kAnalytic && !problem.has_jacobian()) {
    throw InputError("fit: an analytic Jacobian was requested from a problem that has none; use finite-difference");
  }
  if (options.num_starts < 1) {
    throw InputError("fit: starts = " + std::to_string(options.num_starts) + ", expected >= 1");
  }
  if (!(options.start_factor >= 1.0)) {
    throw InputError("fit: start factor = " + Format("%.6g", options.start_factor) + ", expected >= 1");
  }
  if (options.max_iterations < 1) {
    throw InputError("fit: max iterations = " + std::to_string(options.max_iterations) + ", expected >= 1");
  }

  EvaluationContext context;
  context.problem = &problem;
  context.map.specs = parameters;
  const ParameterMap& map = context.map;
  if (options.solver == SolverKind::kNlopt) {
    LookUpNloptAlgorithm(options.nlopt_algorithm, "--nlopt-algorithm");
    if (IsGlobal(options.nlopt_algorithm)) {
      for (int i = 0; i < n; ++i) {
        if (!std::isfinite(map.LowerTheta(i)) || !std::isfinite(map.UpperTheta(i))) {
          throw InputError("fit: the global NLopt algorithm " + options.nlopt_algorithm + " needs finite bounds; '" +
                           parameters[i].name + "' has none (give bounds for it)");
        }
      }
    }
  }
  const std::unique_ptr<ceres::CostFunction> cost = MakeCostFunction(&context, options.jacobian);

  FitSummary summary;
  summary.num_parameters = n;
  summary.num_residuals = problem.num_residuals();
  summary.solver = options.solver == SolverKind::kCeres
                       ? "ceres (Levenberg-Marquardt, DENSE_NORMAL_CHOLESKY, " + ToString(options.jacobian) + " Jacobian)"
                       : "nlopt " + options.nlopt_algorithm +
                             (options.nlopt_polish ? " + ceres polish (" + ToString(options.jacobian) + " Jacobian)"
                                                   : std::string());
  if (options.num_starts > 1) summary.solver += ", " + std::to_string(options.num_starts) + " starts";

  Eigen::VectorXd p0(n);
  for (int i = 0; i < n; ++i) p0[i] = parameters[i].initial;
  const Eigen::VectorXd theta0 = map.ToTheta(p0);
  std::mt19937_64 generator(options.seed);

  double best_cost = kInf;
  StageResult best;
  best.theta = theta0;
  for (int start = 0; start < options.num_starts; ++start) {
    const Eigen::VectorXd theta_start = start == 0 ? theta0 : DrawStart(map, theta0, options.start_factor, generator);
    StartOutcome outcome;
    outcome.initial = map.ToP(theta_start.data());
    Eigen::VectorXd r;
    outcome.initial_cost = EvaluateTheta(*cost, theta_start, &r, nullptr) ? 0.5 * r.squaredNorm() : kNaN;
    FitProgress base;
    base.start = start;
    base.num_starts = options.num_starts;
    base.best_cost = best_cost;
    StageResult result;
    if (options.solver == SolverKind::kCeres) {
      base.stage = "ceres";
      result = RunCeres(*cost, map, theta_start, options, base, t0);
    } else {
      result = RunNlopt(*cost, map, theta_start, options, base, t0);
      if (options.nlopt_polish && result.status != FitStatus::kFailed) {
        base.stage = "polish";
        StageResult polished = RunCeres(*cost, map, result.theta, options, base, t0);
        polished.iterations += result.iterations;
        polished.message = result.message + "; polish " + polished.message;
        // The polish starts at the NLopt optimum; it keeps it when it finds nothing better (the costs
        // then differ by rounding only).
        if (!(polished.cost <= result.cost * (1.0 + kPolishCostSlack))) {
          polished.theta = result.theta;
          polished.cost = result.cost;
        }
        result = polished;
      }
    }
    outcome.value = map.ToP(result.theta.data());
    outcome.final_cost = result.cost;
    outcome.status = result.status;
    outcome.iterations = result.iterations;
    summary.starts.push_back(outcome);
    const bool better = std::isfinite(result.cost) && result.status != FitStatus::kFailed &&
                        (!std::isfinite(best_cost) || result.cost < best_cost);
    if (better || (start == 0 && !std::isfinite(best_cost))) {
      if (better) best_cost = result.cost;
      best = result;
      summary.best_start = start;
    }
  }

  summary.initial_cost = summary.starts.front().initial_cost;
  summary.initial_error = std::sqrt(2.0 * summary.initial_cost);
  summary.status = best.status;
  summary.message = best.message;
  summary.iterations = best.iterations;
  summary.num_evaluations = context.num_evaluations;
  const Eigen::VectorXd p_best = map.ToP(best.theta.data());
  Eigen::VectorXd r;
  if (EvaluateTheta(*cost, best.theta, &r, nullptr)) {
    summary.final_cost = 0.5 * r.squaredNorm();
  } else {
    summary.final_cost = kNaN;
    summary.status = FitStatus::kFailed;
  }
  summary.final_error = std::sqrt(2.0 * summary.final_cost);
  for (int i = 0; i < n; ++i) {
    ParameterEstimate e;
    e.name = parameters[i].name;
    e.unit = parameters[i].unit;
    e.initial = parameters[i].initial;
    e.value = p_best[i];
    e.lower = parameters[i].lower;
    e.upper = parameters[i].upper;
    e.log_scale = parameters[i].log_scale;
    summary.parameters.push_back(e);
  }
  if (summary.status != FitStatus::kFailed && options.analyse_optimum) {
    AnalyseOptimum(*cost, map, best.theta, options, &summary);
  } else {
    summary.covariance = Eigen::MatrixXd::Constant(n, n, kNaN);
    summary.correlation = Eigen::MatrixXd::Constant(n, n, kNaN);
    for (auto& e : summary.parameters) e.std_dev = kNaN;
  }
  summary.num_evaluations = context.num_evaluations;
  summary.time_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return summary;
}

namespace {

// How many problems `num_tasks` tasks can run on side by side: `problem` and its clones, made up to
// one per extra thread (none when the problem cannot be cloned). Task t of a ParallelFor over that
// many runs on `problem` (t = 0) or (*clones)[t - 1]: a problem is not evaluated from two threads.
int PrepareClones(const LeastSquaresProblem& problem, std::vector<std::unique_ptr<LeastSquaresProblem>>* clones,
                  int num_tasks) {
  const int workers = WorkersFor(num_tasks);
  while (static_cast<int>(clones->size()) < workers - 1) {
    auto clone = problem.Clone();
    if (!clone) break;
    clones->push_back(std::move(clone));
  }
  return 1 + std::min(static_cast<int>(clones->size()), workers - 1);
}

// The probe with the lowest cost below `threshold` (the first such in order on ties), or an empty
// vector. Evaluated on up to 1 + clones threads when the problem can be cloned.
Eigen::VectorXd BestProbe(const LeastSquaresProblem& problem, std::vector<std::unique_ptr<LeastSquaresProblem>>& clones,
                          const ProbeCosts* fast, const std::vector<Eigen::VectorXd>& probes, double threshold) {
  const int num_probes = static_cast<int>(probes.size());
  const int used = PrepareClones(problem, &clones, num_probes);
  std::vector<double> cost(num_probes, kInf);
  std::vector<Eigen::VectorXd> r(used);
  ParallelFor(used, [&](int worker, int) {
    const LeastSquaresProblem& p = worker == 0 ? problem : *clones[worker - 1];
    for (int k = worker; k < num_probes; k += used) {
      if (fast && fast->Cost(probes[k], &cost[k])) continue;
      if (p.Evaluate(probes[k], &r[worker], nullptr) && r[worker].allFinite()) cost[k] = 0.5 * r[worker].squaredNorm();
    }
  });
  int best = -1;
  for (int k = 0; k < num_probes; ++k) {
    if (cost[k] < threshold && (best < 0 || cost[k] < cost[best])) best = k;
  }
  return best < 0 ? Eigen::VectorXd() : probes[best];
}

}  // namespace

/// A log-scale parameter within this (natural-log) distance of a bound is taken as run to it.
constexpr double kAtBound = 0.01;

FitSummary SolveWithProbes(const LeastSquaresProblem& problem, const std::vector<ParameterSpec>& parameters,
                           const FitOptions& options, const std::vector<SeriesPair>& series) {
  const auto t0 = Clock::now();
  for (const SeriesPair& pair : series) {
    STAGEFIT_ASSERT(pair.a != pair.b && pair.a >= 0 && pair.b >= 0 && pair.a < static_cast<int>(parameters.size()) &&
                        pair.b < static_cast<int>(parameters.size()),
                    "series pair (" << pair.a << ", " << pair.b << ") outside the " << parameters.size()
                                    << " parameters");
  }
  std::vector<ParameterSpec> start = parameters;
  FitSummary summary = Solve(problem, start, options);
  const double initial_cost = summary.initial_cost, initial_error = summary.initial_error;
  FitOptions restart_options = options;
  restart_options.num_starts = 1;
  int evaluations = 0;
  // One copy of the problem per extra thread, made when the first probes run.
  std::vector<std::unique_ptr<LeastSquaresProblem>> clones;
  for (int round = 0; round < options.max_probe_rounds && summary.status != FitStatus::kFailed; ++round) {
    const Eigen::VectorXd p = summary.values();
    // Single-parameter probes: each factor, and back to the initial value.
    std::vector<Eigen::VectorXd> probes;
    for (size_t i = 0; i < start.size(); ++i) {
      const ParameterSpec& s = start[i];
      if (!s.log_scale) continue;
      for (const double factor : options.probe_factors) {
        Eigen::VectorXd q = p;
        q[i] = std::clamp(p[i] * factor, s.lower, s.upper);
        if (q[i] != p[i]) probes.push_back(q);
      }
      if (options.probe_initial_values && std::abs(std::log(p[i] / parameters[i].initial)) > std::log(2.0)) {
        Eigen::VectorXd q = p;
        q[i] = parameters[i].initial;
        probes.push_back(q);
      }
    }
    const double threshold = summary.final_cost * (1.0 - options.probe_min_improvement);
    evaluations += static_cast<int>(probes.size());
    const std::unique_ptr<const ProbeCosts> fast = options.fast_probes ? problem.PrepareProbeCosts(p) : nullptr;
    Eigen::VectorXd best = BestProbe(problem, clones, fast.get(), probes, threshold);
    if (best.size() == 0 && options.probe_series) {
      // Pairs in series: the pair's compliance kept, its share moved.
      probes.clear();
      for (const SeriesPair& pair : series) {
        const int a = pair.a, b = pair.b;
        const ParameterSpec &sa = parameters[a], &sb = parameters[b];
        if (!sa.log_scale || !sb.log_scale) continue;
        const double c = 1.0 / p[a] + 1.0 / p[b];
        const double share = 1.0 / p[a] / c;
        std::vector<double> shares(std::begin(kSeriesProbeShares), std::end(kSeriesProbeShares));
        shares.push_back(1.0 / sa.initial / (1.0 / sa.initial + 1.0 / sb.initial));
        shares.push_back(1.0 - share);
        for (const double to : shares) {
          if (std::abs(to - share) < 0.05) continue;
          Eigen::VectorXd q = p;
          q[a] = std::clamp(1.0 / (to * c), sa.lower, sa.upper);
          q[b] = std::clamp(1.0 / ((1.0 - to) * c), sb.lower, sb.upper);
          probes.push_back(q);
        }
        // Both back to their initial values: the pair's compliance as well as its share.
        Eigen::VectorXd q = p;
        q[a] = sa.initial;
        q[b] = sb.initial;
        probes.push_back(q);
      }
      evaluations += static_cast<int>(probes.size());
      best = BestProbe(problem, clones, fast.get(), probes, threshold);
    }
    if (best.size() == 0 && options.bound_reset_iterations > 0) {
      // Parameters at a bound: each set back to its initial value, the others refitted shortly. The
      // refits are independent: they run side by side on the problem and its clones, the k-th on the
      // (k mod used)-th (a core left idle by the caller's partner fits takes a share: the last candidate
      // of a diagnosis' refinement ran its resets one after the other on one core). The lowest one
      // below the threshold is kept, the first in order on ties: the numbers of one thread.
      FitOptions reset_options = restart_options;
      reset_options.max_iterations = options.bound_reset_iterations;
      reset_options.analyse_optimum = false;
      reset_options.progress = OneCallAtATime(options.progress);
      std::vector<size_t> at_bound;
      for (size_t i = 0; i < start.size(); ++i) {
        const ParameterSpec& s = start[i];
        if (s.log_scale && (std::abs(std::log(p[i] / s.upper)) < kAtBound || std::abs(std::log(p[i] / s.lower)) < kAtBound)) {
          at_bound.push_back(i);
        }
      }
      // Every reset starts from the optimum with its own parameter set back.
      std::vector<ParameterSpec> at_optimum = start;
      for (size_t j = 0; j < at_optimum.size(); ++j) {
        at_optimum[j].initial = std::clamp(p[j], at_optimum[j].lower, at_optimum[j].upper);
      }
      std::vector<FitSummary> resets(at_bound.size());
      const int used = PrepareClones(problem, &clones, static_cast<int>(at_bound.size()));
      ParallelFor(used, [&](int task, int) {
        const LeastSquaresProblem& on = task == 0 ? problem : *clones[task - 1];
        for (size_t k = static_cast<size_t>(task); k < at_bound.size(); k += static_cast<size_t>(used)) {
          std::vector<ParameterSpec> from = at_optimum;
          from[at_bound[k]].initial = parameters[at_bound[k]].initial;
          resets[k] = Solve(on, from, reset_options);
        }
      });
      double best_cost = threshold;
      for (const FitSummary& reset : resets) {
        evaluations += reset.num_evaluations;
        if (reset.status != FitStatus::kFailed && reset.final_cost < best_cost) {
          best_cost = reset.final_cost;
          best = reset.values();
        }
      }
    }
    if (best.size() == 0) break;
    // exp(ln p) of a parameter at its bound can land one rounding step outside it: clip every value.
    for (size_t i = 0; i < start.size(); ++i) start[i].initial = std::clamp(best[i], start[i].lower, start[i].upper);
    FitSummary restarted = Solve(problem, start, restart_options);
    if (!(restarted.final_cost < summary.final_cost)) {
      evaluations += restarted.num_evaluations;
      break;
    }
    restarted.num_evaluations += summary.num_evaluations;
    summary = std::move(restarted);
  }
  summary.num_evaluations += evaluations;
  for (size_t i = 0; i < parameters.size(); ++i) summary.parameters[i].initial = parameters[i].initial;
  summary.initial_cost = initial_cost;
  summary.initial_error = initial_error;
  summary.time_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return summary;
}

void SilenceSolverLog() { FLAGS_minloglevel = google::GLOG_FATAL; }

}  // namespace stagefit::fit
