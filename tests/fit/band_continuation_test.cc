// A whole-stack test (sensors on every body, hammer on the translation stage, bodies space) with
// scattered stiffnesses and 2 % noise: fitted on the whole band at once the stiffnesses stop in a basin
// at 2.8x the noise floor; with the continuation in band the fit lands on the truth.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "stagefit/compare/residuals.h"
#include "stagefit/fit/model_fit.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace stagefit::fit {
namespace {

TEST(BandContinuation, AWholeStackFitLandsOnTheTruth) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectOptions hidden;
  hidden.num_effects = 0;
  hidden.layout = synthetic::TestLayout::kWholeStack;
  hidden.noise_min = hidden.noise_max = 0.02;
  hidden.stiffness_scatter = 0.15;
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 3, hidden);
  compare::ComparisonOptions options;
  options.space = compare::ComparisonSpace::kBodies;
  const auto comparison = compare::Comparison::Create(nominal, c.measurement, options);
  const double floor = comparison.Error(c.truth);
  const auto params = model::MatchParameters(nominal, {"*.k.*"});

  model::ModelSpec direct = nominal;
  const FitSummary at_once = FitModel(direct, comparison, params, {});
  model::ModelSpec fitted = nominal;
  const FitSummary summary = FitModelWithBandContinuation(fitted, c.measurement, options, comparison, params, {});
  std::printf("truth %.5f, direct %.5f, with continuation %.5f (%s)\n", floor, at_once.final_error, summary.final_error,
              summary.message.c_str());
  EXPECT_LT(summary.final_error, 1.05 * floor);
  EXPECT_LE(summary.final_error, at_once.final_error);
  // Every stiffness the data determine (relative std below 10 %) is the truth's within 4 std.
  int checked = 0;
  for (size_t k = 0; k < params.size(); ++k) {
    const ParameterEstimate& p = summary.parameters[k];
    const double truth = model::GetParameter(c.truth, params[k]);
    if (!(p.std_dev < 0.1 * std::abs(p.value))) continue;
    ++checked;
    EXPECT_NEAR(p.value, truth, 4 * p.std_dev) << p.name << ": fitted " << p.value << ", truth " << truth;
  }
  EXPECT_GE(checked, 20);
}

}  // namespace
}  // namespace stagefit::fit
