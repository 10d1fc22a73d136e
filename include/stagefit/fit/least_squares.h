#pragma once
// The generic least-squares core of the fit layer: Options in, Summary out (FitOptions -> FitSummary).
// Ceres and NLopt stay behind this one interface; the model binding (model_fit.h) and any other caller
// only see LeastSquaresProblem, ParameterSpec, FitOptions and FitSummary.
//
// Problem. Find p (n parameters, natural SI units) minimising
//     cost(p) = 0.5 ||r(p)||^2,        r: R^n -> R^m,
// within lower <= p <= upper. The reported "error" is ||r|| = sqrt(2 cost): for the model comparison
// (compare/residuals.h) r is normalised so that ||r|| is the SPEC §4 error scalar.
//
// Parameterisation. A parameter with log_scale = true (positive physical quantities: stiffness,
// damping) is optimised as theta = ln p, with the Jacobian by the chain rule dr/dtheta = (dr/dp) p and
// the bounds ln(lower) <= theta <= ln(upper). Other parameters are optimised as theta = p.
//
// Uncertainty. At the optimum, with J = dr/dtheta (m x n),
//     Cov(theta) = sigma^2 (J' J)^-1,        sigma^2 = ||r||^2 / (m - n) = 2 cost / (m - n),
// and Cov(p) = diag(dp/dtheta) Cov(theta) diag(dp/dtheta) (linearised). sigma^2 is the unbiased
// estimator of the residual variance of a model that is linear near the optimum with independent
// residuals of equal variance: E[||r*||^2] = (m - n) sigma^2, because the optimum removes the n
// directions spanned by J (the residual is the projection of the noise onto the (m - n)-dimensional
// complement of range(J)). The weights of the comparison make the residuals of equal variance; a
// model that misses a physical effect leaves structured (correlated) residuals, for which the
// standard deviations are lower bounds. J' J is inverted after scaling its columns to unit norm
// (Jacobi scaling), by SVD: a singular value below kRankTolerance times the largest makes the
// parameters involved in its direction undetermined (standard deviation +infinity).
//
// Identifiability warnings (FitSummary::warnings, ParameterEstimate::identifiable = false):
//  - sensitivity: the column norm of dr/dtheta (the change of r for a relative change of the
//    parameter) below FitOptions::min_relative_sensitivity times the largest column norm;
//  - correlation: |corr(theta_i, theta_j)| > FitOptions::max_correlation (the data see a combination);
//  - relative standard deviation std(p)/|p| > FitOptions::max_relative_std (or undetermined).

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace stagefit::fit {

/// The costs of points near one point, cheaper than LeastSquaresProblem::Evaluate() for the points it
/// can cost (LeastSquaresProblem::PrepareProbeCosts()): what the basin probes of SolveWithProbes()
/// evaluate by the hundred.
class ProbeCosts {
 public:
  virtual ~ProbeCosts() = default;
  /// cost(q) = 0.5 ||r(q)||^2 into `cost` (+infinity where r cannot be evaluated at q), equal to
  /// Evaluate()'s to rounding; false when q is not a point it can cost (the caller evaluates it).
  /// Called from several threads at once.
  virtual bool Cost(const Eigen::VectorXd& q, double* cost) const = 0;
};

/// A least-squares problem in natural units. Implementations need not be thread-safe: the solvers call
/// Evaluate() from one thread.
class LeastSquaresProblem {
 public:
  virtual ~LeastSquaresProblem() = default;
  virtual int num_parameters() const = 0;
  virtual int num_residuals() const = 0;
  /// True when Evaluate() can fill the Jacobian.
  virtual bool has_jacobian() const = 0;
  /// Residuals r(p) (resized to num_residuals()) and, when `jacobian` is not null (only called so when
  /// has_jacobian()), J = dr/dp (num_residuals() x num_parameters(), unit of r per unit of p).
  /// Returns false when r cannot be evaluated at `p` (the solver then shortens its step); throws only
  /// for broken invariants.
  virtual bool Evaluate(const Eigen::VectorXd& p, Eigen::VectorXd* residuals, Eigen::MatrixXd* jacobian) const = 0;
  /// An independent copy whose Evaluate() may run on another thread at the same time as this one's;
  /// nullptr (the default) when the problem cannot be copied so: its evaluations then stay on one
  /// thread.
  virtual std::unique_ptr<LeastSquaresProblem> Clone() const { return nullptr; }
  /// Costs of points near `p` (a model fit: those that change only parameters entering the model's
  /// dynamic stiffness linearly, by a low-rank update of the responses at `p`); nullptr (the default)
  /// when the problem has none or `p` cannot be evaluated.
  virtual std::unique_ptr<const ProbeCosts> PrepareProbeCosts(const Eigen::VectorXd& p) const {
    static_cast<void>(p);
    return nullptr;
  }
};

/// One free parameter of a fit.
struct ParameterSpec {
  std::string name;
  std::string unit;                 ///< SI unit, for reports (e.g. "N/m")
  double initial = 0.0;             ///< natural units; within [lower, upper]
  double lower = -std::numeric_limits<double>::infinity();
  double upper = std::numeric_limits<double>::infinity();
  bool log_scale = false;           ///< optimise ln p (requires initial > 0 and lower > 0 or -inf)
  /// Otherwise the optimiser works on p / scale (> 0): a unit of it should be a typical change. Ceres
  /// scales a Jacobian column c by 1 / (1 + |c|), so a column far below 1 (a stiffness coupling in
  /// N/rad, |dr/dk| ~ 1e-7) stays unscaled against columns of order 1; in a fit with 27 stiffnesses,
  /// whose nonlinearity keeps the Levenberg-Marquardt damping up, a coupling started at 1e6 N/rad for a
  /// truth of 2.17e6 ended at 1.003e6, and with a scale at 2.15e6 (docs/diagnose.md). Estimates,
  /// bounds and standard deviations stay in natural units.
  double scale = 1.0;
};

enum class SolverKind { kCeres, kNlopt };
enum class JacobianKind {
  kAnalytic,          ///< the problem's Jacobian (requires has_jacobian())
  kFiniteDifference,  ///< central differences in the optimisation variables theta
};
/// "ceres" | "nlopt"; "analytic" | "finite-difference". Throw InputError naming `context` otherwise.
SolverKind ParseSolverKind(const std::string& text, const std::string& context);
JacobianKind ParseJacobianKind(const std::string& text, const std::string& context);
std::string ToString(SolverKind kind);
std::string ToString(JacobianKind kind);

/// Throws InputError naming `context` when `name` is not an NLopt algorithm name (e.g. "LN_BOBYQA",
/// "LN_SBPLX", "GN_CRS2_LM", "GN_DIRECT", "LD_LBFGS"; the prefix NLOPT_ is optional).
void CheckNloptAlgorithm(const std::string& name, const std::string& context);

enum class FitStatus {
  kConverged,      ///< a tolerance was met
  kMaxIterations,  ///< the iteration or evaluation budget ran out first
  kFailed,         ///< the solver failed (no evaluable start, numerical breakdown)
};
std::string ToString(FitStatus status);  ///< "converged", "max_iterations", "failed"

/// What the progress callback receives after each solver iteration.
struct FitProgress {
  int start = 0;             ///< index of the current start, 0-based
  int num_starts = 1;
  std::string stage;         ///< "ceres", "nlopt", "polish"
  int iteration = 0;         ///< iteration (Ceres) or evaluation count (NLopt) within the stage
  double cost = 0.0;         ///< current cost 0.5 ||r||^2
  double best_cost = 0.0;    ///< best final cost of the completed starts (inf before the first)
  double elapsed_s = 0.0;    ///< since Solve() started
};

struct FitOptions {
  SolverKind solver = SolverKind::kCeres;
  JacobianKind jacobian = JacobianKind::kAnalytic;
  /// Ceres: Levenberg-Marquardt iterations per start (and per polish).
  int max_iterations = 100;
  /// Ceres: the initial trust-region radius (1 / the initial Levenberg-Marquardt damping, in the
  /// scaled variables theta) and whether steps may raise the cost for a while (non-monotonic steps).
  /// Ceres' own default, 1e4, lets the first steps jump far in ln k: a stiffness whose mode is far
  /// off is then moved across other modes into a wrong basin. With 1 the first steps stay short and
  /// the share of fits of the 27 stiffnesses reaching the noise floor rose from 67 % to 85 %
  /// (tests/bench/bench_fit, docs/fitting.md).
  double initial_trust_region_radius = 1.0;
  bool nonmonotonic_steps = false;
  /// Ceres with bounds: follow each successful step with a projected line search, which evaluates the
  /// Jacobian at every trial point. It gets more out of a few iterations (the diagnosis screens its
  /// candidates with 4); a full fit converges as well without it, in two thirds of the time
  /// (tests/bench/bench_fit: median 1.09 -> 0.76 s with the other changes of that step). Its first
  /// trial is the step's candidate: the cost and Jacobian Ceres asks for there next are the trial's.
  bool projected_line_search = false;
  /// Ceres convergence: relative cost change, max-norm of the projected gradient relative to its
  /// start value, and relative step size.
  double function_tolerance = 1e-10;
  double gradient_tolerance = 1e-12;
  double parameter_tolerance = 1e-10;
  /// Ceres: also stop (converged) when the error ||r|| has fallen by less than `stall_relative_decrease`
  /// of itself over the last `stall_iterations` iterations (0: never). A fit crawling along a valley
  /// lowers its cost by more than function_tolerance at every step and can run its whole budget for a
  /// change of its error far below the noise's (docs/fitting.md, "Stall stop").
  int stall_iterations = 0;
  double stall_relative_decrease = 1e-4;
  /// NLopt: algorithm name (nlopt_algorithm_from_string), evaluation budget per start, relative
  /// tolerance on the objective and on theta.
  std::string nlopt_algorithm = "LN_BOBYQA";
  int nlopt_max_evaluations = 4000;
  double nlopt_relative_tolerance = 1e-10;
  /// NLopt: finish every start with Ceres (analytic or finite-difference Jacobian as set above).
  bool nlopt_polish = true;
  /// Multi-start: start 0 is the initial values; starts 1..N-1 are drawn uniformly in theta within
  /// a factor start_factor around the initial value (log-scale parameters: p0 / f .. p0 f; others:
  /// p0 -+ (f - 1) |p0|), clipped to the bounds, from a generator seeded with `seed`. The start with
  /// the lowest final cost is kept.
  int num_starts = 1;
  double start_factor = 1.6;
  std::uint64_t seed = 1;
  /// After the fit: the covariance, correlation, standard deviations and identifiability warnings
  /// (one more Jacobian evaluation). Without it these are NaN and no warnings are given; a caller
  /// that only ranks fits by their error (the diagnosis' candidates) saves the evaluation.
  bool analyse_optimum = true;
  /// Identifiability thresholds (see the header).
  double min_relative_sensitivity = 1e-3;
  double max_correlation = 0.95;
  double max_relative_std = 1.0;
  /// Model fits only (FitModel): basin probes after the fit. Each log-scale parameter in turn is
  /// multiplied by each factor (clipped to its bounds) with the others kept, and the error evaluated
  /// (residuals only, no Jacobian). The best probe that lowers the cost by more than
  /// probe_min_improvement (relative) restarts the fit from there; up to max_probe_rounds times.
  /// A parameter stuck on the wrong side of a mode crossing (its mode moved into a band where it
  /// fits something else) is a factor of several away from its basin: one probe finds it.
  std::vector<double> probe_factors = {0.125, 0.25, 0.5, 2.0, 4.0, 8.0};
  int max_probe_rounds = 4;
  double probe_min_improvement = 1e-3;
  /// Further probes of a round (SolveWithProbes): each log-scale parameter more than a factor 2 away
  /// from its initial value set back to it, the others kept (a parameter walked far off by the first
  /// steps, beyond the reach of probe_factors); and, when no single-parameter probe lowers the cost,
  /// the series probes of pairs of springs in series.
  bool probe_initial_values = true;
  bool probe_series = true;
  /// The probes costed by the problem's LeastSquaresProblem::PrepareProbeCosts() where it can (equal to
  /// Evaluate()'s costs to rounding, at a fraction of the time); false: every probe by Evaluate() (for
  /// the benchmarks' comparison).
  bool fast_probes = true;
  /// When no probe above lowers the cost: each log-scale parameter that ended at a bound is set back to
  /// its initial value and the others refitted from the optimum for this many iterations (0: none). A
  /// spring run to its bound has pushed its mode out of the band and the others have settled without
  /// it; no single-parameter probe then lowers the cost, a short refit does (rz.k.Dy of a hidden-payload
  /// case at 100x its initial value, the truth at 0.63x: 1.23x the noise floor before, 1.05x after a
  /// 20-iteration refit from its initial value).
  int bound_reset_iterations = 20;
  /// Called after each iteration; the library never prints. May be empty. Fits the library runs side
  /// by side (FitModelWithBandContinuation's two routes) call it one at a time.
  std::function<void(const FitProgress&)> progress;
};

/// `progress` wrapped for fits that run side by side: the wrapper runs one call at a time (its copies
/// share the lock). An empty callback stays empty.
std::function<void(const FitProgress&)> OneCallAtATime(std::function<void(const FitProgress&)> progress);

/// The estimate of one parameter.
struct ParameterEstimate {
  std::string name;
  std::string unit;
  double initial = 0.0;
  double value = 0.0;
  /// Standard deviation in natural units (see the header); +infinity when undetermined, NaN when the
  /// residual variance cannot be estimated (m <= n).
  double std_dev = 0.0;
  double lower = 0.0, upper = 0.0;
  bool log_scale = false;
  bool at_bound = false;            ///< within 1e-6 (relative, in theta) of a bound
  double relative_sensitivity = 0.0;  ///< column norm of dr/dtheta over the largest one
  bool identifiable = true;
};

/// The outcome of one start of a multi-start fit.
struct StartOutcome {
  Eigen::VectorXd initial;  ///< natural units
  Eigen::VectorXd value;
  double initial_cost = 0.0;
  double final_cost = 0.0;
  FitStatus status = FitStatus::kFailed;
  int iterations = 0;
};

struct FitSummary {
  FitStatus status = FitStatus::kFailed;
  std::string message;               ///< one line: the solver's termination reason
  std::string solver;                ///< e.g. "ceres (LM, DENSE_NORMAL_CHOLESKY, analytic J)"
  int num_parameters = 0;
  int num_residuals = 0;
  double initial_cost = 0.0;         ///< 0.5 ||r||^2 at the initial values
  double final_cost = 0.0;
  double initial_error = 0.0;        ///< ||r|| at the initial values
  double final_error = 0.0;
  int iterations = 0;                ///< of the kept start (all stages)
  int num_evaluations = 0;           ///< residual evaluations over all starts
  double time_s = 0.0;               ///< wall time of Solve()
  double residual_variance = 0.0;    ///< sigma^2 = 2 cost / (m - n)
  std::vector<ParameterEstimate> parameters;
  Eigen::MatrixXd covariance;        ///< n x n, natural units (+inf / NaN entries when undetermined)
  Eigen::MatrixXd correlation;       ///< n x n, NaN rows/columns for undetermined parameters
  std::vector<std::string> warnings;
  std::vector<StartOutcome> starts;  ///< every start, in order
  int best_start = 0;

  bool converged() const { return status == FitStatus::kConverged; }
  Eigen::VectorXd values() const;
  /// One line: status, error before -> after, iterations, time.
  std::string BriefReport() const;
  /// Several lines: solver, costs, table of parameters (initial, value, std, unit, flags),
  /// correlations above the threshold, start spread, warnings.
  std::string FullReport() const;
};

/// Solves `problem` over `parameters` (sizes must match problem.num_parameters()).
/// Throws InputError for inconsistent parameters (initial outside the bounds, log_scale with a
/// non-positive initial or lower bound, lower > upper), an analytic Jacobian requested from a problem
/// without one, an unknown NLopt algorithm or a global NLopt algorithm with infinite bounds.
/// Numerical failure is reported in FitSummary::status, never thrown.
FitSummary Solve(const LeastSquaresProblem& problem, const std::vector<ParameterSpec>& parameters,
                 const FitOptions& options);

/// Two log-scale parameters that act in series, as two springs on one load path whose compliances
/// 1/p_a + 1/p_b add: data that see mainly the sum leave a second basin where the two trade places.
struct SeriesPair {
  int a = 0, b = 0;  ///< indices into the parameters
};

/// The shares of the pair's compliance c = 1/p_a + 1/p_b given to a by the series probes (besides the
/// share of the initial values and the swapped share).
inline constexpr double kSeriesProbeShares[] = {0.1, 0.5, 0.9};

/// Solve(), then basin probes (up to max_probe_rounds): from the kept optimum, each log-scale parameter
/// in turn times each of FitOptions::probe_factors, the others kept, and set back to its initial value
/// (FitOptions::probe_initial_values). When none of these lowers the cost, the series probes
/// (FitOptions::probe_series): each pair of `series` with its compliance c kept and a's share set to
/// kSeriesProbeShares, to the share of the initial values and to 1 - the current share; and the pair
/// set back to its initial values. When none of these lowers it either, the bound resets
/// (FitOptions::bound_reset_iterations). The fit restarts from the best probe that lowers the cost by more
/// than probe_min_improvement and the restarted fit is kept when it ends lower. The probes of a kind, and
/// the bound resets' fits, are evaluated on the threads of common/parallel.h when the problem has a
/// Clone() (the choice does not depend on the thread count).
/// num_evaluations counts the probes; time_s covers everything.
FitSummary SolveWithProbes(const LeastSquaresProblem& problem, const std::vector<ParameterSpec>& parameters,
                           const FitOptions& options, const std::vector<SeriesPair>& series = {});

/// Keeps the solver's own log off stderr: Ceres writes "Terminating: Residual and Jacobian evaluation
/// failed" through glog whenever a trial point makes the model unusable (a spring run to 0 in a
/// diagnosis' candidate), which the fits here handle (the start or candidate is dropped). A program
/// calls it once at its start; the library never changes the process' logging by itself.
void SilenceSolverLog();

/// Relative rank tolerance on the singular values of the column-scaled Jacobian.
inline constexpr double kRankTolerance = 1e-10;

}  // namespace stagefit::fit
