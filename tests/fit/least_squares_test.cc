#include "stagefit/fit/least_squares.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <thread>
#include <vector>

#include "stagefit/common/error.h"
#include "stagefit/common/parallel.h"

namespace stagefit::fit {
namespace {

// y(t) = A exp(-t / tau) sampled at t_i, with additive noise of standard deviation kDecayNoise.
class ExponentialDecay final : public LeastSquaresProblem {
 public:
  ExponentialDecay(Eigen::VectorXd t, Eigen::VectorXd y) : t_(std::move(t)), y_(std::move(y)) {}
  int num_parameters() const override { return 2; }
  int num_residuals() const override { return static_cast<int>(t_.size()); }
  bool has_jacobian() const override { return true; }
  bool Evaluate(const Eigen::VectorXd& p, Eigen::VectorXd* r, Eigen::MatrixXd* J) const override {
    const Eigen::ArrayXd g = (-t_.array() / p[1]).exp();
    *r = (p[0] * g - y_.array()).matrix();
    if (J != nullptr) {
      J->resize(t_.size(), 2);
      J->col(0) = g.matrix();
      J->col(1) = (p[0] * g * t_.array() / (p[1] * p[1])).matrix();
    }
    return true;
  }

 private:
  Eigen::VectorXd t_, y_;
};

// y = X b (a straight line a + b t): linear least squares with the closed-form covariance.
// y = 0.5 + slope * unit * t + noise at t = 0.1 i (i < m), seeded; X = [1, unit * t], so that the
// slope's Jacobian column is `unit` per unit of slope.
void MakeLineData(uint64_t seed, double noise, double unit, double slope, int m, Eigen::MatrixXd* X,
                  Eigen::VectorXd* y) {
  std::mt19937_64 generator(seed);
  std::normal_distribution<double> normal(0.0, noise);
  X->resize(m, 2);
  y->resize(m);
  for (int i = 0; i < m; ++i) {
    const double t = 0.1 * i;
    (*X)(i, 0) = 1.0;
    (*X)(i, 1) = unit * t;
    (*y)[i] = 0.5 + unit * slope * t + normal(generator);
  }
}

class StraightLine final : public LeastSquaresProblem {
 public:
  StraightLine(Eigen::MatrixXd X, Eigen::VectorXd y) : X_(std::move(X)), y_(std::move(y)) {}
  int num_parameters() const override { return static_cast<int>(X_.cols()); }
  int num_residuals() const override { return static_cast<int>(X_.rows()); }
  bool has_jacobian() const override { return true; }
  bool Evaluate(const Eigen::VectorXd& p, Eigen::VectorXd* r, Eigen::MatrixXd* J) const override {
    *r = X_ * p - y_;
    if (J != nullptr) *J = X_;
    return true;
  }

 private:
  Eigen::MatrixXd X_;
  Eigen::VectorXd y_;
};

// y = a b t: only the product a b is determined.
class Product final : public LeastSquaresProblem {
 public:
  Product(Eigen::VectorXd t, Eigen::VectorXd y) : t_(std::move(t)), y_(std::move(y)) {}
  int num_parameters() const override { return 2; }
  int num_residuals() const override { return static_cast<int>(t_.size()); }
  bool has_jacobian() const override { return true; }
  bool Evaluate(const Eigen::VectorXd& p, Eigen::VectorXd* r, Eigen::MatrixXd* J) const override {
    *r = p[0] * p[1] * t_ - y_;
    if (J != nullptr) {
      J->resize(t_.size(), 2);
      J->col(0) = p[1] * t_;
      J->col(1) = p[0] * t_;
    }
    return true;
  }

 private:
  Eigen::VectorXd t_, y_;
};

// A local minimum near p = 1 and the global one at p = 8 (x = ln p, L = ln 8):
//     r = [x (x - L), eps (x - L)],  cost ~ 0.5 eps^2 L^2 near x = eps^2 / L,  0 at x = L;
// the fit from p = 1 stops in the first, a basin probe by 8 lands in the second. Counts its
// evaluations; PrepareProbeCosts() (with `costs_probes`) costs the probes that raise p and leaves the
// others to Evaluate().
class TwoBasins final : public LeastSquaresProblem {
 public:
  static constexpr double kEps = 0.1;
  explicit TwoBasins(bool costs_probes) : costs_probes_(costs_probes) {}
  int num_parameters() const override { return 1; }
  int num_residuals() const override { return 2; }
  bool has_jacobian() const override { return true; }
  bool Evaluate(const Eigen::VectorXd& p, Eigen::VectorXd* r, Eigen::MatrixXd* J) const override {
    ++evaluations;
    *r = Residuals(p[0]);
    if (J != nullptr) {
      const double x = std::log(p[0]), L = std::log(8.0);
      J->resize(2, 1);
      (*J)(0, 0) = (2 * x - L) / p[0];
      (*J)(1, 0) = kEps / p[0];
    }
    return true;
  }
  std::unique_ptr<const ProbeCosts> PrepareProbeCosts(const Eigen::VectorXd& p) const override {
    if (!costs_probes_) return nullptr;
    return std::make_unique<Costs>(this, p[0]);
  }
  // A VectorXd, as Evaluate() hands it out: assigning a fixed-size Vector2d to one made GCC 12's
  // array-bounds check warn of an AVX-512 load past its 16 bytes (a path Eigen never takes for 2).
  static Eigen::VectorXd Residuals(double p) {
    const double x = std::log(p), L = std::log(8.0);
    Eigen::VectorXd r(2);
    r << x * (x - L), kEps * (x - L);
    return r;
  }
  mutable int evaluations = 0;
  mutable int costed = 0;

 private:
  class Costs final : public ProbeCosts {
   public:
    Costs(const TwoBasins* problem, double at) : problem_(problem), at_(at) {}
    bool Cost(const Eigen::VectorXd& q, double* cost) const override {
      if (!(q[0] > at_)) return false;
      ++problem_->costed;
      *cost = 0.5 * Residuals(q[0]).squaredNorm();
      return true;
    }

   private:
    const TwoBasins* problem_;
    double at_;
  };
  bool costs_probes_;
};

TEST(SolveWithProbes, TakesTheProbesCostsFromTheProblemWhereItCanAndEvaluatesTheOthers) {
  std::vector<ParameterSpec> specs = {{"p", "N/m", 1.0, 1e-3, 1e3, true}};
  FitOptions plain;
  plain.max_probe_rounds = 0;
  EXPECT_GT(Solve(TwoBasins(false), specs, plain).final_cost, 0.1 * 0.5 * std::pow(TwoBasins::kEps * std::log(8.0), 2))
      << "the fit from p = 1 no longer stops in the local minimum";
  const TwoBasins evaluated(false), costed(true);
  FitOptions options;
  const FitSummary a = SolveWithProbes(evaluated, specs, options);
  const FitSummary b = SolveWithProbes(costed, specs, options);
  EXPECT_NEAR(a.parameters[0].value, 8.0, 1e-6);
  EXPECT_EQ(a.final_cost, b.final_cost);
  EXPECT_EQ(a.parameters[0].value, b.parameters[0].value);
  // Half the six probes of each round raise p: those were costed, the others evaluated.
  EXPECT_GT(costed.costed, 0);
  EXPECT_EQ(costed.evaluations + costed.costed, evaluated.evaluations);
  options.fast_probes = false;
  const TwoBasins off(true);
  SolveWithProbes(off, specs, options);
  EXPECT_EQ(off.costed, 0);
  EXPECT_EQ(off.evaluations, evaluated.evaluations);
}

// Three stiffness-like parameters whose optimum lies beyond their upper bounds (r_k = p_k / t - 1 with
// t = kTarget above them, and a term coupling neighbours so that a refit takes iterations): the fit ends
// with all three at their bounds, and SolveWithProbes resets each one. Clonable; counts its clones and
// the evaluations with a Jacobian made on them (a fit's; a probe evaluates residuals only).
class BeyondBounds final : public LeastSquaresProblem {
 public:
  struct Counts {
    std::atomic<int> clones{0};
    std::atomic<int> clone_jacobians{0};
  };
  BeyondBounds(Counts* counts, bool is_clone) : counts_(counts), is_clone_(is_clone) {}
  int num_parameters() const override { return 3; }
  int num_residuals() const override { return 5; }
  bool has_jacobian() const override { return true; }
  bool Evaluate(const Eigen::VectorXd& p, Eigen::VectorXd* r, Eigen::MatrixXd* J) const override {
    if (is_clone_ && J != nullptr) ++counts_->clone_jacobians;
    r->resize(5);
    for (int k = 0; k < 3; ++k) (*r)[k] = p[k] / kTarget - 1.0;
    for (int k = 0; k < 2; ++k) (*r)[3 + k] = 0.1 * std::log(p[k] / p[k + 1]);
    if (J != nullptr) {
      J->setZero(5, 3);
      for (int k = 0; k < 3; ++k) (*J)(k, k) = 1.0 / kTarget;
      for (int k = 0; k < 2; ++k) {
        (*J)(3 + k, k) = 0.1 / p[k];
        (*J)(3 + k, k + 1) = -0.1 / p[k + 1];
      }
    }
    return true;
  }
  std::unique_ptr<LeastSquaresProblem> Clone() const override {
    ++counts_->clones;
    return std::make_unique<BeyondBounds>(counts_, true);
  }
  static constexpr double kTarget = 100.0;

 private:
  Counts* counts_;
  bool is_clone_;
};

TEST(SolveWithProbes, BoundResetsRunSideBySideOnClonesWithTheResultOfOneThread) {
  std::vector<ParameterSpec> specs;
  for (const char* name : {"a", "b", "c"}) specs.push_back({name, "N/m", 1.0, 0.01, 10.0, true});
  FitSummary summary[2];
  BeyondBounds::Counts counts[2];
  for (const int threads : {1, 2}) {
    SetMaxThreads(threads);
    summary[threads - 1] = SolveWithProbes(BeyondBounds(&counts[threads - 1], false), specs, FitOptions{});
  }
  SetMaxThreads(0);
  // All three end at their upper bound: the resets had something to do.
  for (const auto& e : summary[1].parameters) EXPECT_NEAR(e.value, 10.0, 1e-6) << e.name;
  // On one thread no clone; on two a reset's fit ran on the clone.
  EXPECT_EQ(counts[0].clones, 0);
  EXPECT_EQ(counts[1].clones, 1);
  EXPECT_GT(counts[1].clone_jacobians, 0);
  // And nothing changed: the same optimum, cost and number of evaluations.
  EXPECT_EQ(summary[0].final_cost, summary[1].final_cost);
  EXPECT_EQ(summary[0].num_evaluations, summary[1].num_evaluations);
  EXPECT_TRUE(summary[0].values() == summary[1].values());
}

constexpr double kTrueA = 2.0;
constexpr double kTrueTau = 0.3;   // s
constexpr double kDecayNoise = 0.01;
constexpr int kSamples = 60;

ExponentialDecay MakeDecay(std::uint64_t seed) {
  std::mt19937_64 generator(seed);
  std::normal_distribution<double> normal(0.0, kDecayNoise);
  Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(kSamples, 0.0, 1.5);
  Eigen::VectorXd y(kSamples);
  for (int i = 0; i < kSamples; ++i) y[i] = kTrueA * std::exp(-t[i] / kTrueTau) + normal(generator);
  return ExponentialDecay(t, y);
}

std::vector<ParameterSpec> DecayParameters() {
  ParameterSpec a{"A", "m", 1.0};
  ParameterSpec tau{"tau", "s", 1.0, 1e-3, 10.0, true};
  return {a, tau};
}

TEST(Solve, ExponentialDecayRecoversTruthWithinThreeStd) {
  const ExponentialDecay problem = MakeDecay(7);
  const FitSummary summary = Solve(problem, DecayParameters(), {});
  ASSERT_EQ(summary.status, FitStatus::kConverged) << summary.FullReport();
  EXPECT_LT(summary.final_error, summary.initial_error);
  EXPECT_NEAR(summary.parameters[0].value, kTrueA, 3.0 * summary.parameters[0].std_dev);
  EXPECT_NEAR(summary.parameters[1].value, kTrueTau, 3.0 * summary.parameters[1].std_dev);
  // sigma^2 estimates the noise variance: with 58 degrees of freedom its relative standard deviation
  // is sqrt(2 / 58) = 0.19, so a factor 1.8 either way is a > 3-sigma event.
  EXPECT_GT(summary.residual_variance, kDecayNoise * kDecayNoise / 1.8);
  EXPECT_LT(summary.residual_variance, kDecayNoise * kDecayNoise * 1.8);
  EXPECT_TRUE(summary.warnings.empty()) << summary.FullReport();
  EXPECT_NE(summary.BriefReport().find("converged"), std::string::npos);
  EXPECT_NE(summary.FullReport().find("tau"), std::string::npos);
}

TEST(Solve, LinearProblemCovarianceEqualsClosedForm) {
  const int m = 40;
  Eigen::MatrixXd X;
  Eigen::VectorXd y;
  MakeLineData(11, 0.05, 1.0, 1.5, m, &X, &y);
  const StraightLine problem(X, y);
  const FitSummary summary = Solve(problem, {{"a", "m", 0.0}, {"b", "m/s", 0.0}}, {});
  ASSERT_TRUE(summary.converged()) << summary.FullReport();
  const Eigen::VectorXd b = (X.transpose() * X).ldlt().solve(X.transpose() * y);
  const double sigma2 = (X * b - y).squaredNorm() / (m - 2);
  const Eigen::MatrixXd covariance = sigma2 * (X.transpose() * X).inverse();
  // Levenberg-Marquardt stops when the relative cost change falls below 1e-10; near the optimum
  // that change is (delta / std)^2 / (m - n), so the estimate may sit sqrt(1e-10 * 38) = 6e-5 std
  // away from the normal-equation solution: 3e-4 std allows a few such steps. The covariance depends
  // on the optimum only through sigma^2, to second order: 1e-8 relative.
  constexpr double kStdFraction = 3e-4;
  constexpr double kTolerance = 1e-8;
  EXPECT_NEAR(summary.parameters[0].value, b[0], kStdFraction * std::sqrt(covariance(0, 0)));
  EXPECT_NEAR(summary.parameters[1].value, b[1], kStdFraction * std::sqrt(covariance(1, 1)));
  EXPECT_NEAR(summary.residual_variance / sigma2, 1.0, kTolerance);
  EXPECT_TRUE(summary.covariance.isApprox(covariance, kTolerance));
  const double correlation = covariance(0, 1) / std::sqrt(covariance(0, 0) * covariance(1, 1));
  EXPECT_NEAR(summary.correlation(0, 1), correlation, kTolerance);
  EXPECT_NEAR(summary.parameters[1].std_dev, std::sqrt(covariance(1, 1)), kTolerance);
}

// ParameterSpec::scale: the optimiser works on k / scale, a parameter in large natural units (a
// stiffness coupling in N/rad, whose residuals change by ~1e-7 per unit). It changes the path, not the
// optimum: with and without it the fit reaches the least-squares solution, and the estimates and their
// standard deviations are reported in natural units. (In a fit with 27 stiffnesses, where the other
// parameters' nonlinearity keeps the damping up, the unscaled coupling hardly moved: docs/diagnose.md.)
TEST(Solve, ScaledParameterReachesTheSameOptimumInNaturalUnits) {
  const int m = 40;
  Eigen::MatrixXd X;
  Eigen::VectorXd y;
  MakeLineData(5, 0.01, 1e-7, 2.17e6, m, &X, &y);
  const StraightLine problem(X, y);
  const Eigen::VectorXd b = (X.transpose() * X).ldlt().solve(X.transpose() * y);
  const double sigma2 = (X * b - y).squaredNorm() / (m - 2);
  const double std_k = std::sqrt(sigma2 * (X.transpose() * X).inverse()(1, 1));
  std::vector<ParameterSpec> specs = {{"a", "m", 0.0}, {"k", "N/rad", 1e6, -4e6, 4e6}};
  for (double scale : {1.0, 4e6}) {
    SCOPED_TRACE(scale);
    specs[1].scale = scale;
    const FitSummary summary = Solve(problem, specs, {});
    ASSERT_TRUE(summary.converged()) << summary.FullReport();
    EXPECT_NEAR(summary.parameters[1].value, b[1], 1e-3 * std_k);
    EXPECT_NEAR(summary.parameters[0].value, b[0], 1e-6);
    EXPECT_NEAR(summary.parameters[1].std_dev, std_k, 1e-6 * std_k);
  }
}

TEST(Solve, LogParameterStdMatchesDeltaMethod) {
  const ExponentialDecay problem = MakeDecay(3);
  const FitSummary summary = Solve(problem, DecayParameters(), {});
  ASSERT_TRUE(summary.converged());
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  problem.Evaluate(summary.values(), &r, &J);
  const Eigen::MatrixXd covariance =
      r.squaredNorm() / (kSamples - 2) * (J.transpose() * J).inverse();  // natural units directly
  constexpr double kTolerance = 1e-7;  // same linearisation; differs by rounding only
  EXPECT_NEAR(summary.parameters[1].std_dev / std::sqrt(covariance(1, 1)), 1.0, kTolerance);
  EXPECT_NEAR(summary.parameters[0].std_dev / std::sqrt(covariance(0, 0)), 1.0, kTolerance);
}

TEST(Solve, ReportedStdMatchesScatterOverNoiseRealisations) {
  // 200 seeded realisations: the sample standard deviation of tau has a relative sampling error of
  // about 1 / sqrt(2 * 199) = 5 %, so [0.85, 1.15] is a 3-sigma band.
  constexpr int kRealisations = 200;
  std::vector<double> estimates;
  double mean_std = 0.0;
  for (int k = 0; k < kRealisations; ++k) {
    const FitSummary s = Solve(MakeDecay(1000 + k), DecayParameters(), {});
    ASSERT_TRUE(s.converged());
    estimates.push_back(s.parameters[1].value);
    mean_std += s.parameters[1].std_dev / kRealisations;
  }
  const Eigen::Map<Eigen::VectorXd> e(estimates.data(), kRealisations);
  const double sample_std = std::sqrt((e.array() - e.mean()).square().sum() / (kRealisations - 1));
  EXPECT_GT(sample_std / mean_std, 0.85);
  EXPECT_LT(sample_std / mean_std, 1.15);
}

TEST(Solve, ProductOfTwoParametersIsFlaggedUnidentifiable) {
  Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(20, 0.0, 1.0);
  Eigen::VectorXd y = 6.0 * t;
  y[3] += 1e-3;
  const Product problem(t, y);
  const FitSummary summary = Solve(problem, {{"a", "", 1.0, 1e-2, 1e2, true}, {"b", "", 1.0, 1e-2, 1e2, true}}, {});
  EXPECT_NE(summary.status, FitStatus::kFailed);
  EXPECT_NEAR(summary.parameters[0].value * summary.parameters[1].value, 6.0, 1e-3);
  EXPECT_FALSE(summary.parameters[0].identifiable);
  EXPECT_FALSE(summary.parameters[1].identifiable);
  EXPECT_FALSE(summary.warnings.empty());
}

TEST(Solve, FiniteDifferenceJacobianAgreesWithAnalytic) {
  const ExponentialDecay problem = MakeDecay(5);
  FitOptions options;
  const FitSummary analytic = Solve(problem, DecayParameters(), options);
  options.jacobian = JacobianKind::kFiniteDifference;
  const FitSummary numeric = Solve(problem, DecayParameters(), options);
  ASSERT_TRUE(numeric.converged()) << numeric.FullReport();
  // Central differences are accurate to ~1e-10 relative here; the optimum moves by less than 1e-7
  // relative and the standard deviations likewise.
  for (int i = 0; i < 2; ++i) {
    EXPECT_NEAR(numeric.parameters[i].value / analytic.parameters[i].value, 1.0, 1e-7);
    EXPECT_NEAR(numeric.parameters[i].std_dev / analytic.parameters[i].std_dev, 1.0, 1e-5);
  }
}

TEST(Solve, NloptLocalAndGlobalReachTheCeresOptimum) {
  const ExponentialDecay problem = MakeDecay(9);
  const FitSummary reference = Solve(problem, DecayParameters(), {});
  std::vector<ParameterSpec> bounded = DecayParameters();
  bounded[0].lower = 0.1;
  bounded[0].upper = 10.0;
  for (const char* algorithm : {"LN_BOBYQA", "LN_SBPLX", "GN_CRS2_LM"}) {
    FitOptions options;
    options.solver = SolverKind::kNlopt;
    options.nlopt_algorithm = algorithm;
    options.nlopt_polish = false;
    const FitSummary summary = Solve(problem, bounded, options);
    EXPECT_NE(summary.status, FitStatus::kFailed) << algorithm;
    // Local derivative-free methods stop on a relative objective change: the optimum agrees to ~1e-4.
    // The global CRS stops when its population agrees, far from a local tolerance: it is polished.
    if (algorithm[0] == 'L') {
      EXPECT_NEAR(summary.final_cost / reference.final_cost, 1.0, 1e-4) << algorithm << summary.FullReport();
    }
    options.nlopt_polish = true;
    const FitSummary polished = Solve(problem, bounded, options);
    EXPECT_TRUE(polished.converged()) << algorithm << polished.FullReport();
    EXPECT_NEAR(polished.parameters[1].value / reference.parameters[1].value, 1.0, 1e-6) << algorithm;
  }
}

TEST(Solve, MultiStartIsReproducibleAndReportsEveryStart) {
  const ExponentialDecay problem = MakeDecay(13);
  FitOptions options;
  options.num_starts = 5;
  options.start_factor = 3.0;
  options.seed = 42;
  const FitSummary a = Solve(problem, DecayParameters(), options);
  const FitSummary b = Solve(problem, DecayParameters(), options);
  ASSERT_EQ(a.starts.size(), 5u);
  EXPECT_EQ(a.starts[0].initial[0], 1.0);
  for (int k = 0; k < 5; ++k) EXPECT_EQ(a.starts[k].initial, b.starts[k].initial);
  EXPECT_NE(a.starts[1].initial, a.starts[2].initial);
  EXPECT_EQ(a.values(), b.values());
  EXPECT_NE(a.FullReport().find("Starts:"), std::string::npos);
}

TEST(Solve, IterationBudgetExhaustedIsReportedNotHidden) {
  const ExponentialDecay problem = MakeDecay(17);
  FitOptions options;
  options.max_iterations = 1;
  const FitSummary summary = Solve(problem, DecayParameters(), options);
  EXPECT_EQ(summary.status, FitStatus::kMaxIterations);
  EXPECT_FALSE(summary.converged());
}

TEST(Solve, InconsistentParametersThrowInputError) {
  const ExponentialDecay problem = MakeDecay(1);
  std::vector<ParameterSpec> p = DecayParameters();
  p[1].initial = -1.0;
  EXPECT_THROW(Solve(problem, p, {}), InputError);
  p = DecayParameters();
  p[1].upper = 0.5;
  EXPECT_THROW(Solve(problem, p, {}), InputError);
  p = DecayParameters();
  p[0].scale = 0.0;
  EXPECT_THROW(Solve(problem, p, {}), InputError);
  FitOptions options;
  options.solver = SolverKind::kNlopt;
  options.nlopt_algorithm = "NO_SUCH_METHOD";
  EXPECT_THROW(Solve(problem, DecayParameters(), options), InputError);
  options.nlopt_algorithm = "GN_DIRECT";  // A has no bounds
  EXPECT_THROW(Solve(problem, DecayParameters(), options), InputError);
}

TEST(Solve, ProgressCallbackSeesDecreasingCost) {
  const ExponentialDecay problem = MakeDecay(19);
  FitOptions options;
  std::vector<double> costs;
  options.progress = [&](const FitProgress& progress) { costs.push_back(progress.cost); };
  const FitSummary summary = Solve(problem, DecayParameters(), options);
  ASSERT_GE(costs.size(), 2u);
  EXPECT_LE(costs.back(), costs.front());
  EXPECT_NEAR(costs.back(), summary.final_cost, 1e-12 + 1e-9 * summary.final_cost);
}

TEST(Solve, StallStopEndsAtTheFirstIterationWhoseWindowLoweredTheErrorByLessThanItsShare) {
  const ExponentialDecay problem = MakeDecay(23);
  std::vector<ParameterSpec> parameters = DecayParameters();
  parameters[1].initial = 8.0;  // far from tau = 0.5: the error falls by a few % an iteration at the end
  FitOptions options;
  options.initial_trust_region_radius = 0.1;
  std::vector<double> errors;
  options.progress = [&](const FitProgress& progress) { errors.push_back(std::sqrt(2.0 * progress.cost)); };
  const FitSummary free_run = Solve(problem, parameters, options);
  const std::vector<double> free_errors = errors;

  // A share this large stops the fit a few iterations before Ceres' own tolerances would.
  constexpr int kWindow = 2;
  constexpr double kShare = 0.3;
  options.stall_iterations = kWindow;
  options.stall_relative_decrease = kShare;
  errors.clear();
  const FitSummary stalled = Solve(problem, parameters, options);
  // The rule, applied to the errors of the free run: the first iteration k >= kWindow whose lowest
  // error is less than kShare of itself below the lowest kWindow iterations before.
  std::vector<double> lowest(free_errors.size());
  for (size_t k = 0; k < free_errors.size(); ++k) lowest[k] = k == 0 ? free_errors[0] : std::min(lowest[k - 1], free_errors[k]);
  size_t expected_stop = free_errors.size();
  for (size_t k = kWindow; k < lowest.size(); ++k) {
    if (lowest[k - kWindow] - lowest[k] < kShare * lowest[k]) {
      expected_stop = k;
      break;
    }
  }
  ASSERT_LT(expected_stop + 1, free_errors.size()) << "the rule would not stop this fit before its tolerances";
  // The same path up to the stop, and not one iteration further.
  ASSERT_EQ(errors.size(), expected_stop + 1);
  for (size_t k = 0; k < errors.size(); ++k) EXPECT_EQ(errors[k], free_errors[k]) << "iteration " << k;
  EXPECT_EQ(stalled.status, FitStatus::kConverged);
  EXPECT_NEAR(stalled.final_error, lowest[expected_stop], 1e-12 * lowest[expected_stop]);
  EXPECT_GE(stalled.final_error, free_run.final_error);
  // Stopped where the error fell by less than kShare over kWindow iterations, near the optimum: within
  // kShare of it here (the error falls geometrically at the end).
  EXPECT_LT(stalled.final_error, (1.0 + kShare) * free_run.final_error);
}

// Every Evaluate() call of a problem: its point and whether the Jacobian was asked for.
class RecordedCalls final : public LeastSquaresProblem {
 public:
  explicit RecordedCalls(const LeastSquaresProblem& problem) : problem_(problem) {}
  int num_parameters() const override { return problem_.num_parameters(); }
  int num_residuals() const override { return problem_.num_residuals(); }
  bool has_jacobian() const override { return true; }
  bool Evaluate(const Eigen::VectorXd& p, Eigen::VectorXd* r, Eigen::MatrixXd* J) const override {
    calls.push_back({p, J != nullptr});
    return problem_.Evaluate(p, r, J);
  }
  struct Call {
    Eigen::VectorXd p;
    bool jacobian;
  };
  mutable std::vector<Call> calls;

 private:
  const LeastSquaresProblem& problem_;
};

// With the projected line search (the diagnosis' fits of candidates), from far with long first steps:
// no point is evaluated twice for the same thing. The line search's first trial is the step's
// candidate, evaluated with the Jacobian (Ceres' cubic interpolation asks for it at every trial);
// Ceres then asked again for the candidate's cost and, when it took the step, for its Jacobian.
TEST(Solve, ProjectedLineSearchEvaluatesNoPointTwiceForTheSameThing) {
  const ExponentialDecay decay = MakeDecay(29);
  const RecordedCalls problem(decay);
  std::vector<ParameterSpec> parameters = DecayParameters();
  parameters[1].initial = 8.0;
  FitOptions options;
  options.projected_line_search = true;
  options.initial_trust_region_radius = 1e4;
  options.analyse_optimum = false;
  const FitSummary summary = Solve(problem, parameters, options);
  ASSERT_EQ(summary.status, FitStatus::kConverged) << summary.FullReport();
  EXPECT_NEAR(summary.parameters[1].value, kTrueTau, 0.01);

  int jacobians = 0;
  for (size_t i = 0; i < problem.calls.size(); ++i) {
    jacobians += problem.calls[i].jacobian;
    // The same point again right after: only residuals first and the Jacobian then.
    if (i > 0 && problem.calls[i].p == problem.calls[i - 1].p) {
      EXPECT_TRUE(!problem.calls[i - 1].jacobian && problem.calls[i].jacobian) << "calls " << i - 1 << " and " << i;
    }
  }
  // The Jacobians were computed (the start's and the steps'), and in fewer calls than the three per
  // step of before.
  EXPECT_GE(jacobians, 2);
  EXPECT_LT(problem.calls.size(), 3u * static_cast<size_t>(summary.iterations + 1));
}

// Copies of the wrapper called from four threads: no two calls overlap, and every call is made.
TEST(OneCallAtATime, RunsTheCallsOfAllItsCopiesOneAtATime) {
  EXPECT_FALSE(OneCallAtATime({}));
  std::atomic<int> inside{0}, most{0};
  int calls = 0;  // not atomic: counts right only when the calls do not overlap
  const auto progress = OneCallAtATime([&](const FitProgress&) {
    const int now = ++inside;
    most = std::max(most.load(), now);
    std::this_thread::sleep_for(std::chrono::microseconds(20));
    ++calls;
    --inside;
  });
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([progress] {
      for (int i = 0; i < 100; ++i) progress(FitProgress{});
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(most.load(), 1);
  EXPECT_EQ(calls, 400);
}

}  // namespace
}  // namespace stagefit::fit
