// The loop (diagnose::RunLoop): on data with one hidden effect it adds that effect and ends at the
// noise floor; on effect-free data it adds nothing; the final model reloads with its error.
#include "stagefit/diagnose/loop.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <iostream>
#include <string>

#include "stagefit/compare/residuals.h"
#include "stagefit/model/model_file.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace stagefit::diagnose {
namespace {

LoopOptions Options(const std::vector<std::string>& effects) {
  LoopOptions options;
  options.diagnose.effects = effects;
  options.max_rounds = 2;
  return options;
}

// The hexapod's stiffness centre 84 mm below the model's (seed 1017, also diagnose_test): the loop fits
// the stiffnesses, finds the offset, refits, and stops at the floor; the history falls step by step.
TEST(Loop, AddsTheHiddenEffectAndStopsAtTheFloor) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 1017, {});
  ASSERT_EQ(c.effects.size(), 1u);
  ASSERT_EQ(c.effects[0].name, "joint-offset");
  const LoopSummary summary = RunLoop(nominal, c.measurement, Options({"joint-offset", "coupled-stiffness"}));
  std::cout << summary.HistoryTable();
  ASSERT_TRUE(summary.noise_floor.known);
  ASSERT_EQ(summary.effects_added.size(), 1u);
  EXPECT_EQ(summary.effects_added[0].rfind("joint-offset@hexapod:", 0), 0u) << summary.effects_added[0];
  EXPECT_EQ(summary.stop_reason, "at the noise floor");
  EXPECT_LE(summary.history.back().error, kDoneTimesFloor * summary.noise_floor.floor);
  for (size_t k = 1; k < summary.history.size(); ++k) {
    EXPECT_LE(summary.history[k].error, summary.history[k - 1].error) << summary.history[k].action;
  }
  // The truth's own error is the floor the coherence predicts.
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  EXPECT_NEAR(comparison.Error(c.truth) / summary.noise_floor.floor, 1.0, 0.1);

  // The final model written and read back reproduces the last error bit for bit.
  const auto path = std::filesystem::temp_directory_path() / "stagefit_loop_test_final.toml";
  model::WriteModelFile(path, summary.final_model);
  const model::ModelSpec reloaded = model::ReadModelFile(path);
  std::filesystem::remove(path);
  EXPECT_EQ(comparison.Error(reloaded), summary.history.back().error);
  EXPECT_FALSE(FormatLoopHistory(summary).empty());
  EXPECT_EQ(FormatLoopHistory(summary).rfind("step,action,effect,error,noise_floor,times_floor\n", 0), 0u);
}

// Effect-free data (stiffness scatter and noise only, seed 7 as in diagnose_test): the first fit reaches
// the floor and the loop stops there without diagnosing.
TEST(Loop, AddsNothingToEffectFreeData) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectOptions options;
  options.num_effects = 0;
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 7, options);
  const LoopSummary summary = RunLoop(nominal, c.measurement, Options({}));
  std::cout << summary.HistoryTable();
  EXPECT_TRUE(summary.effects_added.empty());
  EXPECT_EQ(summary.stop_reason, "at the noise floor");
  EXPECT_EQ(summary.history.size(), 2u);  // as given, fit
}

}  // namespace
}  // namespace stagefit::diagnose
