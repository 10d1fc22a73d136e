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
//             [--nlopt-algorithm LN_BOBYQA]

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "fit_test_util.h"
#include "stagefit/compare/residuals.h"
#include "stagefit/fit/model_fit.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"

namespace {

using namespace stagefit;

constexpr double kNoise = 0.01;
constexpr double kMaxFactor = 1.6;

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
  for (const auto& info : model::MatchParameters(p.truth, patterns)) {
    const double sigma = std::log(kMaxFactor) / 2.0;
    const double z = std::clamp(fit::testing::Normal(generator), -2.0, 2.0);
    model::SetParameter(p.truth, info, model::GetParameter(p.truth, info) * std::exp(sigma * z));
  }
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
  for (size_t i = 0; i < params.size(); ++i) {
    const auto& e = summary.parameters[i];
    if (!e.identifiable) continue;
    ++t.identifiable;
    t.recovered = t.recovered && std::abs(e.value - model::GetParameter(problem.truth, params[i])) <= 3.0 * e.std_dev;
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
  int trials = 20, frequencies = 1000, compare_trials = 5;
  std::string params = "*.k.*";
  std::string algorithm = "LN_BOBYQA";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const char* value = argv[i + 1];
    if (key == "--trials") trials = std::atoi(value);
    else if (key == "--frequencies") frequencies = std::atoi(value);
    else if (key == "--compare-trials") compare_trials = std::atoi(value);
    else if (key == "--params") params = value;
    else if (key == "--nlopt-algorithm") algorithm = value;
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

  Tally ceres, nlopt, numeric, ceres_subset;
  std::vector<Problem> problems;
  for (int k = 0; k < trials; ++k) {
    problems.push_back(MakeProblem(patterns, frequencies, 100 + k));
    const Trial t = RunTrial(problems.back(), patterns, {});
    ceres.Add(t);
    if (k < compare_trials) ceres_subset.Add(t);
    std::printf("  trial %2d: ceres error %.5f (floor %.5f), %s, %d identifiable, %s, %d evaluations, %.3g s\n", k,
                t.error, t.floor, t.converged ? "converged" : "NOT converged", t.identifiable,
                t.recovered ? "recovered" : "NOT recovered", t.evaluations, t.time_s);
    std::fflush(stdout);
  }
  ceres.Print("ceres LM, analytic J");
  fit::FitOptions nlopt_options;
  nlopt_options.solver = fit::SolverKind::kNlopt;
  nlopt_options.nlopt_algorithm = algorithm;
  nlopt_options.nlopt_polish = false;
  nlopt_options.nlopt_max_evaluations = 20000;
  fit::FitOptions numeric_options;
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
  return 0;
}
