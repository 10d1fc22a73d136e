// The fit benchmark: a plain program printing its figures.
//
// Problem: the default micro-station whose free stiffnesses (--params, default "*.k.*": all 27) are
// scattered log-normally (sigma = ln(1.6) / 2, truncated at a factor 1.6), its compliance at {X} at
// --frequencies log-spaced points from 10 Hz to 1 kHz with 1 % RMS complex noise as the measurement;
// every fit starts from Table 2.1. A trial succeeds when the fit converges to the noise floor
// (error <= 1.05 noise sqrt(1 - n/m)) and every parameter the fit reports identifiable is within 3 of
// its standard deviations of the truth. Then the same trials (the first --compare-trials) with a
// derivative-free NLopt method and with finite-difference Jacobians, with the ratios of median times.
//
//   bench_fit [--trials 20] [--frequencies 1000] [--params "*.k.*"] [--compare-trials 5]
//             [--nlopt-algorithm LN_BOBYQA] [--probe-rounds N] [--radius R] [--nonmonotonic 0|1]
//             [--probe-initial 0|1] [--probe-series 0|1] [--verbose 1|2] [--first-trial K]
//             [--probe-trials P]
//   --probe-trials: the first P trials (default --compare-trials) fitted again with every basin probe
//   costed by Evaluate() instead of the low-rank update (FitOptions::fast_probes), with the time ratio.
//
// Even a fitter that always finds the global optimum fails the 3-standard-deviation test in about
// 1 - 0.9973^n of the trials (7 % for n = 27): the program prints that share beside its own.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "fit_test_util.h"
#include "stagefit/common/memory.h"
#include "stagefit/compare/residuals.h"
#include "stagefit/fit/model_fit.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"

namespace {

using namespace stagefit;

constexpr double kNoise = 0.01;
constexpr double kMaxFactor = 1.6;
bool verbose = false;  // --verbose 1: print the parameters a trial did not recover
bool verbose_all = false;  // --verbose 2: print every parameter

struct Trial {
  bool converged = false;
  bool at_floor = false;
  bool recovered = false;
  double error = 0.0;
  double floor = 0.0;
  double time_s = 0.0;
  int identifiable = 0;
  int evaluations = 0;
};

struct Problem {
  model::ModelSpec truth;
  measurement::FrfData data;
};

Problem MakeProblem(const std::vector<std::string>& patterns, int frequencies, std::uint64_t seed) {
  std::mt19937_64 generator(seed);
  Problem p;
  p.truth = model::DefaultModelSpec();
  fit::testing::ScatterParametersLogNormal(&p.truth, patterns, kMaxFactor, generator);
  p.data = fit::testing::MakeComplianceMeasurement(p.truth, fit::testing::LogFrequencies(10.0, 1000.0, frequencies),
                                                   kNoise, generator);
  return p;
}

Trial RunTrial(const Problem& problem, const std::vector<std::string>& patterns, const fit::FitOptions& options) {
  model::ModelSpec spec = model::DefaultModelSpec();
  const auto comparison = compare::Comparison::Create(spec, problem.data);
  const auto params = model::MatchParameters(spec, patterns);
  const fit::FitSummary summary = fit::FitModel(spec, comparison, params, options);
  Trial t;
  t.converged = summary.converged();
  t.error = summary.final_error;
  t.floor = kNoise * std::sqrt(1.0 - static_cast<double>(params.size()) / summary.num_residuals);
  t.at_floor = summary.final_error <= 1.05 * t.floor;
  t.time_s = summary.time_s;
  t.evaluations = summary.num_evaluations;
  t.recovered = true;
  if (verbose) std::printf("    error at the truth %.6f, found %.6f\n", comparison.Error(problem.truth), summary.final_error);
  for (size_t i = 0; i < params.size(); ++i) {
    const auto& e = summary.parameters[i];
    if (!e.identifiable) continue;
    ++t.identifiable;
    const double truth = model::GetParameter(problem.truth, params[i]);
    const bool within = std::abs(e.value - truth) <= 3.0 * e.std_dev;
    if ((!within && verbose) || verbose_all) {
      std::printf("    %s: %.4g, truth %.4g, start %.4g, std %.3g (%.1f std off)\n", e.name.c_str(), e.value, truth,
                  e.initial, e.std_dev, std::abs(e.value - truth) / e.std_dev);
    }
    t.recovered = t.recovered && within;
  }
  return t;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? NAN : v[v.size() / 2];
}

struct Tally {
  int success = 0, floor = 0, converged = 0, n = 0;
  std::vector<double> times;
  void Add(const Trial& t) {
    ++n;
    success += t.at_floor && t.recovered && t.converged;
    floor += t.at_floor;
    converged += t.converged;
    times.push_back(t.time_s);
  }
  void Print(const char* label) const {
    std::printf("%-34s trials %2d  success %5.1f %%  at floor %5.1f %%  converged %5.1f %%  median time %.3g s\n",
                label, n, 100.0 * success / n, 100.0 * floor / n, 100.0 * converged / n, Median(times));
  }
};

}  // namespace

int main(int argc, char** argv) {
  stagefit::KeepFreedMemory();  // as the stagefit program does
  int trials = 20, frequencies = 1000, compare_trials = 5, first_trial = 0;
  std::string params = "*.k.*";
  std::string algorithm = "LN_BOBYQA";
  int probe_rounds = -1;  // -1: FitOptions' default
  double radius = -1;     // initial trust-region radius; -1: FitOptions' default
  int nonmonotonic = -1;
  int probe_initial = -1, probe_series = -1;  // -1: FitOptions' default
  int probe_trials = -1;                       // -1: compare_trials
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const char* value = argv[i + 1];
    if (key == "--trials") trials = std::atoi(value);
    else if (key == "--first-trial") first_trial = std::atoi(value);
    else if (key == "--frequencies") frequencies = std::atoi(value);
    else if (key == "--compare-trials") compare_trials = std::atoi(value);
    else if (key == "--params") params = value;
    else if (key == "--nlopt-algorithm") algorithm = value;
    else if (key == "--verbose") verbose = std::atoi(value) != 0, verbose_all = std::atoi(value) > 1;
    else if (key == "--probe-rounds") probe_rounds = std::atoi(value);
    else if (key == "--radius") radius = std::atof(value);
    else if (key == "--nonmonotonic") nonmonotonic = std::atoi(value);
    else if (key == "--probe-initial") probe_initial = std::atoi(value);
    else if (key == "--probe-series") probe_series = std::atoi(value);
    else if (key == "--probe-trials") probe_trials = std::atoi(value);
    else {
      std::fprintf(stderr, "unknown option %s\n", key.c_str());
      return 1;
    }
  }
  std::vector<std::string> patterns;
  for (size_t b = 0, e; b <= params.size(); b = e + 1) {
    e = params.find(',', b);
    if (e == std::string::npos) e = params.size();
    patterns.push_back(params.substr(b, e - b));
  }
  std::printf("bench_fit: params %s, %d frequencies 10 Hz..1 kHz, 1 %% noise, scatter <= x%.1f\n", params.c_str(),
              frequencies, kMaxFactor);

  fit::FitOptions ceres_options;
  if (probe_rounds >= 0) ceres_options.max_probe_rounds = probe_rounds;
  if (radius > 0) ceres_options.initial_trust_region_radius = radius;
  if (nonmonotonic >= 0) ceres_options.nonmonotonic_steps = nonmonotonic != 0;
  if (probe_initial >= 0) ceres_options.probe_initial_values = probe_initial != 0;
  if (probe_series >= 0) ceres_options.probe_series = probe_series != 0;
  std::printf("initial trust region radius %g, non-monotonic steps %d, basin probe rounds %d (initial-value "
              "probes %d, series probes %d)\n",
              ceres_options.initial_trust_region_radius, ceres_options.nonmonotonic_steps ? 1 : 0,
              ceres_options.max_probe_rounds, ceres_options.probe_initial_values ? 1 : 0,
              ceres_options.probe_series ? 1 : 0);

  Tally ceres, nlopt, numeric, ceres_subset;
  std::vector<Problem> problems;
  for (int k = 0; k < trials; ++k) {
    problems.push_back(MakeProblem(patterns, frequencies, 100 + first_trial + k));
    const Trial t = RunTrial(problems.back(), patterns, ceres_options);
    ceres.Add(t);
    if (k < compare_trials) ceres_subset.Add(t);
    std::printf("  trial %2d: ceres error %.5f (floor %.5f), %s, %d identifiable, %s, %d evaluations, %.3g s\n", first_trial + k,
                t.error, t.floor, t.converged ? "converged" : "NOT converged", t.identifiable,
                t.recovered ? "recovered" : "NOT recovered", t.evaluations, t.time_s);
    std::fflush(stdout);
  }
  ceres.Print("ceres LM, analytic J");
  std::printf("(a fitter that always finds the optimum passes the 3-std test in about %.1f %% of trials)\n",
              100.0 * std::pow(0.9973, static_cast<double>(model::MatchParameters(model::DefaultModelSpec(),
                                                                                   patterns).size())));
  fit::FitOptions nlopt_options;
  nlopt_options.solver = fit::SolverKind::kNlopt;
  nlopt_options.nlopt_algorithm = algorithm;
  nlopt_options.nlopt_polish = false;
  nlopt_options.nlopt_max_evaluations = 20000;
  fit::FitOptions numeric_options = ceres_options;
  numeric_options.jacobian = fit::JacobianKind::kFiniteDifference;
  for (int k = 0; k < std::min(compare_trials, trials); ++k) {
    nlopt.Add(RunTrial(problems[k], patterns, nlopt_options));
    numeric.Add(RunTrial(problems[k], patterns, numeric_options));
    std::fflush(stdout);
  }
  ceres_subset.Print("ceres LM, analytic J (same subset)");
  nlopt.Print(("nlopt " + algorithm + " (no polish)").c_str());
  numeric.Print("ceres LM, finite-difference J");
  std::printf("median time ratio nlopt / ceres-analytic: %.3g\n", Median(nlopt.times) / Median(ceres_subset.times));
  std::printf("median time ratio finite-difference / analytic: %.3g\n",
              Median(numeric.times) / Median(ceres_subset.times));

  // The basin probes costed by Evaluate() (a set-up per probe) against the low-rank update of the
  // responses (FitOptions::fast_probes), on the same trials: the same fits to rounding.
  if (probe_trials < 0) probe_trials = compare_trials;
  Tally fast_probes, slow_probes;
  fit::FitOptions slow_options = ceres_options;
  slow_options.fast_probes = false;
  int same = 0;
  for (int k = 0; k < std::min(probe_trials, trials); ++k) {
    const Trial fast = RunTrial(problems[k], patterns, ceres_options);
    const Trial slow = RunTrial(problems[k], patterns, slow_options);
    fast_probes.Add(fast);
    slow_probes.Add(slow);
    same += std::abs(fast.error - slow.error) <= 1e-6 * slow.error;
    std::fflush(stdout);
  }
  if (probe_trials > 0) {
    fast_probes.Print("ceres LM, probes by low-rank update");
    slow_probes.Print("ceres LM, probes by Evaluate()");
    std::printf("probe trials ending at the same error (1e-6): %d of %d; median time ratio Evaluate() / low-rank "
                "probes: %.3g\n", same, std::min(probe_trials, trials), Median(slow_probes.times) / Median(fast_probes.times));
    // One probe alone, each way: every parameter of the first trial's model as given by each probe
    // factor, on one thread.
    model::ModelSpec spec = model::DefaultModelSpec();
    const auto comparison = compare::Comparison::Create(spec, problems[0].data);
    const auto params = model::MatchParameters(spec, patterns);
    const fit::ModelFitProblem problem(spec, comparison, params);
    Eigen::VectorXd p(problem.num_parameters());
    for (int i = 0; i < p.size(); ++i) p[i] = model::GetParameter(spec, params[i]);
    const auto t0 = std::chrono::steady_clock::now();
    const auto fast = problem.PrepareProbeCosts(p);
    const auto t1 = std::chrono::steady_clock::now();
    double worst = 0.0, fast_s = 0.0, slow_s = 0.0;
    int count = 0;
    for (int i = 0; i < p.size(); ++i) {
      for (const double factor : fit::FitOptions{}.probe_factors) {
        Eigen::VectorXd q = p;
        q[i] *= factor;
        double cost = 0.0;
        Eigen::VectorXd r;
        const auto a = std::chrono::steady_clock::now();
        const bool ok = fast && fast->Cost(q, &cost);
        const auto b = std::chrono::steady_clock::now();
        problem.Evaluate(q, &r, nullptr);
        const auto c = std::chrono::steady_clock::now();
        if (!ok) continue;
        fast_s += std::chrono::duration<double>(b - a).count();
        slow_s += std::chrono::duration<double>(c - b).count();
        worst = std::max(worst, std::abs(cost - 0.5 * r.squaredNorm()) / (0.5 * r.squaredNorm()));
        ++count;
      }
    }
    std::printf("one probe (%d, %d frequencies): %.3g ms by the update (set-up %.3g ms once), %.3g ms by Evaluate(), "
                "ratio %.3g; largest relative difference of the costs %.2g\n",
                count, frequencies, 1e3 * fast_s / count, 1e3 * std::chrono::duration<double>(t1 - t0).count(),
                1e3 * slow_s / count, slow_s / fast_s, worst);
  }
  return 0;
}
