#include "stagefit/fit/model_fit.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>
#include <utility>

#include "fit_test_util.h"
#include "stagefit/common/error.h"
#include "stagefit/common/parallel.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"

namespace stagefit::fit {
namespace {

using testing::LogFrequencies;
using testing::MakeComplianceMeasurement;
using testing::ScatterParameters;

// 1 % RMS complex noise per point, as a careful hammer test on a stiff stage reaches.
constexpr double kNoise = 0.01;
// The generating scatter of the true stiffnesses around Table 2.1.
constexpr double kScatter = 1.6;

struct Synthetic {
  model::ModelSpec truth;
  measurement::FrfData data;
};

Synthetic MakeSynthetic(const std::vector<std::string>& scattered, std::uint64_t seed, int num_frequencies,
                        double low_hz = 10.0, double high_hz = 1000.0) {
  std::mt19937_64 generator(seed);
  Synthetic s;
  s.truth = model::DefaultModelSpec();
  ScatterParameters(&s.truth, scattered, kScatter, generator);
  s.data = MakeComplianceMeasurement(s.truth, LogFrequencies(low_hz, high_hz, num_frequencies), kNoise, generator);
  return s;
}

// A trial of tests/bench/bench_fit (seed 100 + trial): all 27 stiffnesses scattered log-normally by
// up to x1.6, the compliance at `num_frequencies` points from 10 Hz to 1 kHz with 1 % noise.
Synthetic MakeBenchTrial(std::uint64_t seed, int num_frequencies = 1000) {
  std::mt19937_64 generator(seed);
  Synthetic s;
  s.truth = model::DefaultModelSpec();
  testing::ScatterParametersLogNormal(&s.truth, {"*.k.*"}, kScatter, generator);
  s.data = MakeComplianceMeasurement(s.truth, LogFrequencies(10.0, 1000.0, num_frequencies), kNoise, generator);
  return s;
}

TEST(FitModel, RecoversScatteredStiffnessesWithinThreeStd) {
  // The hexapod's and the spindle's stiffnesses scattered by up to a factor 1.6 (the full 27-stiffness
  // problem, with its local minima, is measured by tests/bench/bench_fit).
  const std::vector<std::string> patterns = {"hexapod.k.*", "rz.k.*"};
  const Synthetic s = MakeSynthetic(patterns, 2024, 300);
  model::ModelSpec spec = model::DefaultModelSpec();
  const auto comparison = compare::Comparison::Create(spec, s.data);
  const auto params = model::MatchParameters(spec, patterns);
  const FitSummary summary = FitModel(spec, comparison, params, {});
  ASSERT_TRUE(summary.converged()) << summary.FullReport();
  // The noise floor: E||r||^2 = (m - n) / m * noise^2 for residuals normalised by sqrt(sum w^2).
  const double floor = kNoise * std::sqrt(1.0 - static_cast<double>(params.size()) / summary.num_residuals);
  EXPECT_LT(summary.final_error, 1.05 * floor) << summary.FullReport();
  EXPECT_GT(summary.initial_error, 5.0 * floor);
  int identifiable = 0;
  for (size_t i = 0; i < params.size(); ++i) {
    const ParameterEstimate& e = summary.parameters[i];
    if (!e.identifiable) continue;
    ++identifiable;
    const double truth = model::GetParameter(s.truth, params[i]);
    EXPECT_NEAR(e.value, truth, 3.0 * e.std_dev) << e.name << "\n" << summary.FullReport();
  }
  // The compliance at {X} sees at least the hexapod's six stiffnesses.
  EXPECT_GE(identifiable, 6) << summary.FullReport();
  for (const auto& e : summary.parameters) {
    if (e.name.rfind("hexapod.k.", 0) == 0) {
      EXPECT_TRUE(e.identifiable) << e.name << "\n" << summary.FullReport();
    }
  }
  ASSERT_FALSE(spec.history.empty());
  EXPECT_EQ(spec.history.back().step, "fit");
  EXPECT_EQ(spec.history.back().error, summary.final_error);
}

TEST(FitModel, BasinProbesLeaveALocalMinimumThePlainFitStopsIn) {
  // Case 7 of tests/bench/bench_fit: all 27 stiffnesses scattered log-normally by up to x1.6. Started
  // from Table 2.1, the fit alone stops with the spindle's axial and the tilt stage's torsional
  // stiffness far too soft (error ~15 x the noise floor); probing each stiffness by factors 1/8 .. 8
  // finds the way out.
  const std::vector<std::string> patterns = {"*.k.*"};
  const auto data = MakeBenchTrial(107).data;
  model::ModelSpec plain = model::DefaultModelSpec(), probed = plain;
  const auto comparison = compare::Comparison::Create(plain, data);
  const auto params = model::MatchParameters(plain, patterns);
  FitOptions options;
  options.max_probe_rounds = 0;
  const FitSummary stuck = FitModel(plain, comparison, params, options);
  const double floor = kNoise * std::sqrt(1.0 - static_cast<double>(params.size()) / stuck.num_residuals);
  ASSERT_GT(stuck.final_error, 5.0 * floor) << "the case no longer has the local minimum it tests\n"
                                            << stuck.FullReport();
  options.max_probe_rounds = 4;
  const FitSummary summary = FitModel(probed, comparison, params, options);
  EXPECT_LT(summary.final_error, 1.05 * floor) << summary.FullReport();
  EXPECT_GT(summary.num_evaluations, stuck.num_evaluations);
  for (size_t i = 0; i < params.size(); ++i) {
    EXPECT_DOUBLE_EQ(summary.parameters[i].initial, stuck.parameters[i].initial) << params[i].name;
  }
}

TEST(FitModel, ProbesCostedByTheLowRankUpdateAreTheEvaluatedOnes) {
  // The probes' costs from compare::ParameterProbes against Evaluate() at the same points, and the
  // fit of the basin-probe case above with either: the same fit to rounding.
  const std::vector<std::string> patterns = {"*.k.*"};
  const auto data = MakeBenchTrial(107).data;
  model::ModelSpec spec = model::DefaultModelSpec();
  const auto comparison = compare::Comparison::Create(spec, data);
  const auto params = model::MatchParameters(spec, patterns);
  const ModelFitProblem problem(spec, comparison, params);
  Eigen::VectorXd p(problem.num_parameters());
  for (int i = 0; i < p.size(); ++i) p[i] = model::GetParameter(spec, params[i]);
  const auto fast = problem.PrepareProbeCosts(p);
  ASSERT_NE(fast, nullptr);
  for (int i = 0; i < p.size(); i += 5) {
    for (const double factor : {0.125, 8.0}) {
      Eigen::VectorXd q = p;
      q[i] *= factor;
      double cost = 0.0;
      ASSERT_TRUE(fast->Cost(q, &cost)) << params[i].name;
      Eigen::VectorXd r;
      ASSERT_TRUE(problem.Evaluate(q, &r, nullptr));
      EXPECT_NEAR(cost, 0.5 * r.squaredNorm(), 1e-9 * cost) << params[i].name << " x " << factor;
    }
  }

  FitSummary summary[2];
  for (const bool fast_probes : {false, true}) {
    model::ModelSpec fitted = model::DefaultModelSpec();
    FitOptions options;
    options.fast_probes = fast_probes;
    summary[fast_probes] = FitModel(fitted, comparison, params, options);
  }
  EXPECT_NEAR(summary[1].final_error, summary[0].final_error, 1e-9 * summary[0].final_error);
  EXPECT_EQ(summary[1].num_evaluations, summary[0].num_evaluations);
  for (size_t i = 0; i < params.size(); ++i) {
    EXPECT_NEAR(summary[1].parameters[i].value, summary[0].parameters[i].value, 1e-6 * summary[0].parameters[i].value)
        << params[i].name;
  }
}

// One trial of tests/bench/bench_fit (seed 100 + trial): all 27 stiffnesses scattered, fitted from
// Table 2.1 once with the probes of `disabled` turned off (and the bound resets, the last resort
// that can stand in for them, unless `keep_bound_resets`) and once with the default options. Returns
// the first fit's error over the floor and checks that the second reaches the floor and recovers
// every identifiable stiffness within 3 std.
double FitBenchTrialWithAndWithout(std::uint64_t seed, bool FitOptions::*disabled, bool keep_bound_resets = false) {
  const std::vector<std::string> patterns = {"*.k.*"};
  const auto [truth, data] = MakeBenchTrial(seed);
  model::ModelSpec without = model::DefaultModelSpec(), with = without;
  const auto comparison = compare::Comparison::Create(without, data);
  const auto params = model::MatchParameters(without, patterns);
  FitOptions options;
  options.*disabled = false;
  if (!keep_bound_resets) options.bound_reset_iterations = 0;
  const FitSummary stuck = FitModel(without, comparison, params, options);
  const double floor = kNoise * std::sqrt(1.0 - static_cast<double>(params.size()) / stuck.num_residuals);
  const FitSummary summary = FitModel(with, comparison, params, FitOptions{});
  EXPECT_LT(summary.final_error, 1.05 * floor) << summary.FullReport();
  for (size_t i = 0; i < params.size(); ++i) {
    const auto& e = summary.parameters[i];
    if (e.identifiable) {
      EXPECT_NEAR(e.value, model::GetParameter(truth, params[i]), 3.0 * e.std_dev) << e.name;
    }
  }
  return stuck.final_error / floor;
}

TEST(FitModel, SeriesProbesMoveTwoSpringsInSeriesOutOfTradedPlaces) {
  // Trial 5: without the series probes the tilt stage's torsion spring (ry.k.Rz) ends 5 x too soft
  // with the translation stage's (ty.k.Rz, in series with it) nearly rigid; the error stays 4 %
  // above the floor and ry.k.Rz is 230 std from the truth. No single-parameter probe helps: moving
  // one spring changes the pair's compliance, which the data do see.
  const double stuck = FitBenchTrialWithAndWithout(105, &FitOptions::probe_series);
  EXPECT_GT(stuck, 1.02) << "the case no longer has the local minimum it tests";
}

TEST(FitModel, BoundResetsAloneFreeTheSpringsInSeriesToo) {
  // The same trial with the series probes off but the bound resets on: a spring of the pair run to its
  // bound is set back to its initial value and the others refitted for 20 iterations; from there the
  // fit reaches the floor, as with the series probes.
  const double with_resets = FitBenchTrialWithAndWithout(105, &FitOptions::probe_series, true);
  EXPECT_LT(with_resets, 1.05);
}

TEST(FitModel, InitialValueProbesBringBackAStiffnessWalkedFarOff) {
  // Trial 16: without the initial-value probes the granite's vertical stiffness walks from 5e9 to
  // 1.2e8 N/m (the truth is 6.3e9) and the vertical springs above it follow; the error stays at
  // 15 x the floor, and neither a factor 8 nor a series probe reaches back.
  const double stuck = FitBenchTrialWithAndWithout(116, &FitOptions::probe_initial_values);
  EXPECT_GT(stuck, 5.0) << "the case no longer has the local minimum it tests";
}

TEST(FitModel, SameResultOnOneThreadAndOnTwo) {
  // The FRF blocks and the basin probes run on the threads; neither may change a number.
  const std::vector<std::string> patterns = {"*.k.*"};
  const auto data = MakeBenchTrial(103, 300).data;
  FitSummary summary[2];
  for (const int threads : {1, 2}) {
    SetMaxThreads(threads);
    model::ModelSpec spec = model::DefaultModelSpec();
    const auto comparison = compare::Comparison::Create(spec, data);
    summary[threads - 1] = FitModel(spec, comparison, model::MatchParameters(spec, patterns), FitOptions{});
  }
  SetMaxThreads(0);
  EXPECT_EQ(summary[0].final_error, summary[1].final_error);
  EXPECT_EQ(summary[0].num_evaluations, summary[1].num_evaluations);
  EXPECT_TRUE(summary[0].values() == summary[1].values());
}

TEST(SeriesPairs, SameDofOfJointsStackedThroughImposedDofs) {
  const model::ModelSpec spec = model::DefaultModelSpec();
  const auto params = model::MatchParameters(spec, {"*.k.*"});
  std::set<std::pair<std::string, std::string>> pairs;
  for (const SeriesPair& p : SeriesPairs(spec, params)) pairs.insert({params[p.a].name, params[p.b].name});
  // Adjacent stages, and through the DoF a stage imposes (ty Dy, ry Ry, rz Rz).
  EXPECT_TRUE(pairs.count({"ty.k.Rz", "ry.k.Rz"}));
  EXPECT_TRUE(pairs.count({"ry.k.Rz", "hexapod.k.Rz"}));
  EXPECT_TRUE(pairs.count({"granite.k.Dy", "ry.k.Dy"}));
  EXPECT_TRUE(pairs.count({"ty.k.Ry", "rz.k.Ry"}));
  EXPECT_FALSE(pairs.count({"ty.k.Dx", "ry.k.Dz"}));
  // Per DoF, one pair fewer than the free joints of the chain: 4 + 3 + 4 + 4 + 3 + 3.
  EXPECT_EQ(pairs.size(), 21u);
  // Not fitting a spring stops the chain there; a damping parameter is never paired.
  const auto some = model::MatchParameters(spec, {"granite.k.Dz", "ry.k.Dz", "ty.c.Dz"});
  EXPECT_TRUE(SeriesPairs(spec, some).empty());
}

TEST(FitModel, ReportedStdAgreesWithScatterOverNoiseRealisations) {
  // 30 realisations of the noise on one true model: the sample standard deviation of an estimate has a
  // relative sampling error of 1 / sqrt(2 (30 - 1)) = 13 %, so [0.7, 1.4] is about -2.3 / +3 sigma
  // (the sampling distribution is skewed upwards). The reported std varies little between realisations.
  constexpr int kRealisations = 30;
  const std::vector<std::string> patterns = {"hexapod.k.*"};
  std::mt19937_64 truth_generator(77);
  model::ModelSpec truth = model::DefaultModelSpec();
  ScatterParameters(&truth, patterns, kScatter, truth_generator);
  const Eigen::VectorXd frequency_hz = LogFrequencies(10.0, 1000.0, 150);
  const auto params = model::MatchParameters(truth, patterns);
  const int n = static_cast<int>(params.size());
  Eigen::MatrixXd estimates(kRealisations, n);
  Eigen::VectorXd mean_std = Eigen::VectorXd::Zero(n);
  for (int k = 0; k < kRealisations; ++k) {
    std::mt19937_64 generator(5000 + k);
    const auto data = MakeComplianceMeasurement(truth, frequency_hz, kNoise, generator);
    model::ModelSpec spec = model::DefaultModelSpec();
    const auto comparison = compare::Comparison::Create(spec, data);
    const FitSummary summary = FitModel(spec, comparison, params, {});
    ASSERT_TRUE(summary.converged()) << summary.FullReport();
    for (int i = 0; i < n; ++i) {
      estimates(k, i) = summary.parameters[i].value;
      mean_std[i] += summary.parameters[i].std_dev / kRealisations;
    }
  }
  for (int i = 0; i < n; ++i) {
    const Eigen::VectorXd e = estimates.col(i);
    const double sample_std = std::sqrt((e.array() - e.mean()).square().sum() / (kRealisations - 1));
    const double ratio = sample_std / mean_std[i];
    EXPECT_GT(ratio, 0.7) << params[i].name;
    EXPECT_LT(ratio, 1.4) << params[i].name;
    // The estimator is unbiased to well within its standard error sample_std / sqrt(30).
    EXPECT_NEAR(e.mean(), model::GetParameter(truth, params[i]), 4.0 * sample_std / std::sqrt(kRealisations))
        << params[i].name;
  }
}

TEST(FitModel, StiffnessesSeenOnlyInSeriesAreFlagged) {
  // Far below the first resonance (~130 Hz) the vertical compliance at {X} is the sum of the series
  // compliances 1/k_z of the joints: the hexapod's and the granite's vertical stiffnesses enter only
  // through 1/k_hexapod + 1/k_granite, so the data determine that combination, not each of them.
  const Synthetic s = MakeSynthetic({"hexapod.k.Dz"}, 31, 200, 1.0, 20.0);
  model::ModelSpec spec = model::DefaultModelSpec();
  const auto comparison = compare::Comparison::Create(spec, s.data);
  const auto params = model::MatchParameters(spec, {"hexapod.k.Dz", "granite.k.Dz"});
  ASSERT_EQ(params[0].name, "granite.k.Dz");
  const FitSummary summary = FitModel(spec, comparison, params, {});
  EXPECT_NE(summary.status, FitStatus::kFailed);
  EXPECT_FALSE(summary.parameters[0].identifiable) << summary.FullReport();
  EXPECT_FALSE(summary.warnings.empty());
  EXPECT_NE(summary.FullReport().find("granite.k.Dz"), std::string::npos);
}

TEST(FitModel, TunedFileReproducesTheReportedErrorExactly) {
  const Synthetic s = MakeSynthetic({"hexapod.k.*", "rz.k.*"}, 9, 200);
  model::ModelSpec spec = model::DefaultModelSpec();
  const auto comparison = compare::Comparison::Create(spec, s.data);
  const auto params = model::MatchParameters(spec, {"hexapod.k.*", "rz.k.*"});
  const FitSummary summary = FitModel(spec, comparison, params, {});
  const model::ModelSpec loaded = model::ParseModelToml(model::WriteModelToml(spec), "tuned.toml");
  EXPECT_EQ(comparison.Error(loaded), summary.final_error);
  ASSERT_EQ(loaded.history.size(), spec.history.size());
  EXPECT_EQ(loaded.history.back().error, summary.final_error);
  for (size_t i = 0; i < params.size(); ++i) {
    EXPECT_EQ(model::GetParameter(loaded, params[i]), summary.parameters[i].value);
  }
}

TEST(FitModel, NloptDerivativeFreeReachesTheCeresOptimum) {
  const Synthetic s = MakeSynthetic({"hexapod.k.*"}, 4, 120);
  const auto params = model::MatchParameters(s.truth, {"hexapod.k.*"});
  model::ModelSpec ceres_spec = model::DefaultModelSpec();
  const auto comparison = compare::Comparison::Create(ceres_spec, s.data);
  const FitSummary reference = FitModel(ceres_spec, comparison, params, {});
  FitOptions options;
  options.solver = SolverKind::kNlopt;
  options.nlopt_algorithm = "LN_BOBYQA";
  options.nlopt_polish = false;
  model::ModelSpec spec = model::DefaultModelSpec();
  const FitSummary summary = FitModel(spec, comparison, params, options);
  EXPECT_NE(summary.status, FitStatus::kFailed) << summary.FullReport();
  // BOBYQA stops on a relative change of ||r||^2 of 1e-10; the optimum's error agrees to 1e-3 relative.
  EXPECT_NEAR(summary.final_error / reference.final_error, 1.0, 1e-3) << summary.FullReport();
  for (size_t i = 0; i < params.size(); ++i) {
    EXPECT_NEAR(summary.parameters[i].value, reference.parameters[i].value, 0.1 * reference.parameters[i].std_dev)
        << params[i].name;
  }
}

TEST(FitModel, MultiStartNloptGlobalWithPolishConverges) {
  const Synthetic s = MakeSynthetic({"hexapod.k.*"}, 6, 80);
  model::ModelSpec spec = model::DefaultModelSpec();
  const auto comparison = compare::Comparison::Create(spec, s.data);
  const auto params = model::MatchParameters(spec, {"hexapod.k.Dx", "hexapod.k.Dz"});
  FitOptions options;
  options.solver = SolverKind::kNlopt;
  options.nlopt_algorithm = "GN_CRS2_LM";
  options.nlopt_max_evaluations = 400;
  options.num_starts = 3;
  options.seed = 12;
  const FitSummary summary = FitModel(spec, comparison, params, options, {{"hexapod.k.*", {}, {}, 4.0}});
  EXPECT_TRUE(summary.converged()) << summary.FullReport();
  EXPECT_EQ(summary.starts.size(), 3u);
  for (size_t i = 0; i < params.size(); ++i) {
    EXPECT_NEAR(summary.parameters[i].value, model::GetParameter(s.truth, params[i]),
                4.0 * summary.parameters[i].std_dev);
  }
}

TEST(MakeParameterSpecs, DefaultBoundsAreAFactorAroundPositiveParameters) {
  const model::ModelSpec spec = model::DefaultModelSpec();
  const auto params = model::MatchParameters(spec, {"hexapod.k.Dz", "hexapod.c.Dz"});
  const auto specs = MakeParameterSpecs(spec, params);
  ASSERT_EQ(specs.size(), 2u);
  EXPECT_TRUE(specs[0].log_scale);
  EXPECT_DOUBLE_EQ(specs[0].lower, 1e8 / kDefaultBoundFactor);
  EXPECT_DOUBLE_EQ(specs[0].upper, 1e8 * kDefaultBoundFactor);
  EXPECT_EQ(specs[0].unit, "N/m");
}

TEST(MakeParameterSpecs, RulesApplyInOrderAndBadRulesThrow) {
  const model::ModelSpec spec = model::DefaultModelSpec();
  const auto params = model::MatchParameters(spec, {"hexapod.k.*"});
  BoundRule wide{"hexapod.k.*", {}, {}, 10.0};
  BoundRule dz{"hexapod.k.Dz", 5e7, 2e8};
  const auto specs = MakeParameterSpecs(spec, params, {wide, dz});
  EXPECT_DOUBLE_EQ(specs[0].lower, 1e6);
  EXPECT_DOUBLE_EQ(specs[2].lower, 5e7);
  EXPECT_DOUBLE_EQ(specs[2].upper, 2e8);
  EXPECT_THROW(MakeParameterSpecs(spec, params, {{"granite.*", {}, {}, 10.0}}), InputError);  // matches none
  EXPECT_THROW(MakeParameterSpecs(spec, params, {{"hexapod.k.Dz", 2e8, 3e8}}), InputError);  // excludes p0
  EXPECT_THROW(MakeParameterSpecs(spec, params, {{"hexapod.k.Dz", {}, {}, 0.5}}), InputError);
  BoundRule wrong_unit{"hexapod.k.Rx", 1e5, 1e7, {}, dim::kTranslationalStiffness};
  EXPECT_THROW(MakeParameterSpecs(spec, params, {wrong_unit}), InputError);
}

}  // namespace
}  // namespace stagefit::fit
