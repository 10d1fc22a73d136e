// The loop (diagnose::RunLoop): on data with one hidden effect it adds that effect and ends at the
// noise floor; on effect-free data it adds nothing; the final model reloads with its error.
#include "stagefit/diagnose/loop.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "stagefit/compare/residuals.h"
#include "stagefit/fit/model_fit.h"
#include "stagefit/measurement/projection.h"
#include "stagefit/model/effects.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"
#include "stagefit/synthetic/outside_catalogue.h"
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
  EXPECT_TRUE(summary.confirmed);
  EXPECT_NE(summary.conclusion.find("with joint-offset@hexapod: they explain the measurement"), std::string::npos) << summary.conclusion;
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

// A single-effect case of tests/bench/eval_loop (5 Hz to `fmax_hz`, `num_frequencies`, the seed's own
// noise and scatter) whose hidden effect is `effect` ("<name>@<location>").
void MakeEvalLoopCase(uint64_t seed, int num_frequencies, const std::string& effect, synthetic::HiddenEffectCase* c,
                      double fmax_hz = 600) {
  *c = synthetic::MakeHiddenEffectCase(model::DefaultModelSpec(), seed, synthetic::EvalLoopCaseOptions(1, fmax_hz, num_frequencies));
  ASSERT_EQ(c->effects.size(), 1u);
  ASSERT_EQ(c->effects[0].name + "@" + c->effects[0].location, effect);
}

// "<name>@<location>" of each of `effects` (a case's hidden ones or a model's), in order.
template <typename Effect>
std::vector<std::string> Keys(const std::vector<Effect>& effects) {
  std::vector<std::string> keys;
  for (const Effect& e : effects) keys.push_back(e.name + "@" + e.location);
  return keys;
}

// The distance of `model` to the case's noise-free truth as eval_loop measures it: the error scalar of
// ln(H_model / H_truth) on the measurement's points and weights.
double DistanceToTruth(const model::ModelSpec& model, const synthetic::HiddenEffectCase& c) {
  const auto comparison = compare::Comparison::Create(model::DefaultModelSpec(), c.measurement);
  Eigen::VectorXd r, r_truth;
  comparison.Residuals(model, &r);
  comparison.Residuals(c.truth, &r_truth);
  return (r - r_truth).norm();
}

// A loop state stored in tests/diagnose/data (its README says how each was written), to resume from.
model::ModelSpec StoredLoopState(const std::string& file) {
  return model::ReadModelFile(std::string(STAGEFIT_SOURCE_DIR) + "/tests/diagnose/data/" + file);
}

// The loop on case `c` resumed from the stored state `file` (StoredLoopState), whose effects must be
// `resumed` ("<name>@<location>", in order), with `options` and its progress printed; its history too.
void ResumeStoredLoop(const synthetic::HiddenEffectCase& c, LoopOptions options, const std::string& file,
                      const std::vector<std::string>& resumed, LoopSummary* summary) {
  options.progress = [](const std::string& line) { std::cout << line << std::endl; };
  options.resume_from = StoredLoopState(file);
  ASSERT_EQ(Keys(options.resume_from->effects), resumed);
  *summary = RunLoop(model::DefaultModelSpec(), c.measurement, options);
  std::cout << summary->HistoryTable();
}

// An extra body on the hexapod with the mass and height of the case's hidden body `body_name` and the
// joint stiffnesses k (translations) and kr (rotations): where the rigid-limit tests start its fit.
model::Effect ExtraBodyOnTheHexapod(const synthetic::HiddenEffectCase& c, const std::string& body_name, double k, double kr) {
  const auto& body = c.truth.bodies[model::FindBody(c.truth, body_name)];
  const auto& host = c.truth.bodies[model::FindBody(c.truth, "hexapod")];
  model::Effect e;
  e.name = "extra-body";
  e.location = "hexapod";
  e.parameters = {{"mass", body.mass_kg}, {"k", k}, {"kr", kr}, {"z", body.com_W.z() - host.com_W.z()}};
  return e;
}

// `nominal` with the joint stiffnesses of the case's truth (where the loop's rounds had brought them,
// for tests of a step after the rounds) on its free DoF; an imposed one stays imposed (a truth with a
// servo stiffness has one there). The truth's joints are matched by name: a hidden body adds its own.
model::ModelSpec WithTruthStiffnesses(const model::ModelSpec& nominal, const synthetic::HiddenEffectCase& c) {
  model::ModelSpec start = nominal;
  for (model::JointSpec& joint : start.joints) {
    const model::JointSpec& truth = c.truth.joints[model::FindJoint(c.truth, joint.name)];
    for (int d = 0; d < 6; ++d) {
      if (!joint.imposed[d]) joint.stiffness[d] = truth.stiffness[d];
    }
  }
  return start;
}

// A coupling in the hexapod (seed 5008 of eval_loop: correlation -0.56, 600 Hz, 838 frequencies) that
// the first stiffness fit cannot mimic: it stops at 35x the floor, and every candidate fitted from there
// stays far above it (a joint offset was added at 27x). With the baseline that far
// (DiagnoseOptions::far_times_floor) the candidates are also screened from the model the user gave
// the loop (DiagnoseOptions::as_given) with short first steps, and the coupling reaches the floor in one
// round. The whole catalogue competes (with only couplings and joint offsets tried, the coupling from
// the bent baseline gets a refinement slot and is found without the rule).
TEST(Loop, ACandidateTheBentBaselineTrapsIsFoundFromTheModelAsGiven) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectCase c;
  ASSERT_NO_FATAL_FAILURE(MakeEvalLoopCase(5008, 838, "coupled-stiffness@hexapod.Dx-Ry", &c));
  LoopOptions options = Options({});
  options.max_rounds = 1;
  options.progress = [](const std::string& line) { std::cout << line << std::endl; };
  const LoopSummary summary = RunLoop(nominal, c.measurement, options);
  std::cout << summary.HistoryTable();
  ASSERT_TRUE(summary.noise_floor.known);
  EXPECT_GT(summary.history[1].error, 10 * summary.noise_floor.floor);  // the first fit, far from the floor
  ASSERT_EQ(summary.effects_added.size(), 1u);
  EXPECT_EQ(summary.effects_added[0].rfind("coupled-stiffness@hexapod.Dx-Ry:", 0), 0u) << summary.effects_added[0];
  EXPECT_LE(summary.history.back().error, kDoneTimesFloor * summary.noise_floor.floor);
  const double k_truth = c.truth.joints[model::FindJoint(c.truth, "hexapod")].couplings.at(0).stiffness;
  const double k = summary.final_model.effects.back().parameters.at("k");
  EXPECT_NEAR(k, k_truth, 0.02 * std::abs(k_truth));
}

// An accelerometer turned by 16 degrees (seed 7006 of eval_loop: a2x, 600 Hz, 477 frequencies),
// compared in compliance space: the stiffness fit absorbs it at the noise floor, so no round runs. The
// turned-channel step sees a2x 15.7 degrees off as the other channels' rigid motion gives it and adds
// the correction held there (and in every later fit); the model stays at the floor and comes within
// 0.5 % of the noise-free truth. (Effect-free data get no such step: AddsNothingToEffectFreeData.)
TEST(Loop, AddsATurnedChannelTheStiffnessesAbsorbed) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectCase c;
  ASSERT_NO_FATAL_FAILURE(MakeEvalLoopCase(7006, 477, "sensor-geometry@a2x", &c));
  const LoopSummary summary = RunLoop(nominal, c.measurement, Options({}));
  std::cout << summary.HistoryTable();
  ASSERT_EQ(summary.effects_added.size(), 1u);
  EXPECT_EQ(summary.effects_added[0].rfind("sensor-geometry@a2x:", 0), 0u) << summary.effects_added[0];
  EXPECT_LE(summary.history.back().error, kDoneTimesFloor * summary.noise_floor.floor);
  const double rz = summary.final_model.effects.back().parameters.at("rz");
  EXPECT_NEAR(std::abs(rz) * 180 / M_PI, 16.0, 1.0);
  EXPECT_LT(DistanceToTruth(summary.final_model, c), 0.005);
  // Held where the data put the channel, for this refit and every later one: the turn at the estimate,
  // no offset, and none of its parameters among those a fit of the model with its effects frees.
  const model::Effect& correction = summary.final_model.effects.back();
  EXPECT_EQ(correction.held, (std::vector<std::string>{"dx", "dy", "dz", "rx", "ry", "rz"}));
  for (const char* p : {"dx", "dy", "dz"}) EXPECT_EQ(correction.parameters.at(p), 0.0) << p;
  for (const auto& p : model::MatchParameters(summary.final_model, model::WithEffectParameters({"*.k.*"}, summary.final_model))) {
    EXPECT_NE(p.name.rfind("sensor-geometry@", 0), 0u) << p.name;
  }
}

// A vertical sensor turned 17 degrees (seed 200055 of eval_loop: a3z, 600 Hz, 818 frequencies): the
// first fit bends the stiffnesses to absorb it (339x the floor). The correction refitted from there
// alone stayed in that basin (22.7x the floor); refitted from the model as given too, the better kept,
// it comes to where the noise-free truth is (1.08x the floor, the truth 1.07x). A round runs there
// (above 1.06x): impact h1's correction lowered the error by 12 %, most of it by re-weighing the
// measurement (its own floor 0.0301 against 0.0333), and was added, 0.020 off the truth; judged
// against its own floor (diagnose::JudgedError) it does not help, and the model stays at the truth.
// Tried again after the round (TryCandidateBesideAddedEffects), it replaces nothing, and a channel's
// correction does not count for reaching the floor (0.95x the floor of the measurement as given, 1.08x
// before): the loop goes back to the model before.
TEST(Loop, CorrectsATurnedChannelTheFirstFitBentTheStiffnessesFor) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectCase c;
  ASSERT_NO_FATAL_FAILURE(MakeEvalLoopCase(200055, 818, "sensor-geometry@a3z", &c));
  const LoopSummary summary = RunLoop(nominal, c.measurement, Options({}));
  std::cout << summary.HistoryTable();
  ASSERT_GE(summary.history.size(), 3u);  // as given, fit, the turned channel, ...
  EXPECT_GT(summary.history[1].error, 100 * summary.noise_floor.floor);
  EXPECT_NE(summary.history[2].action.find("channel a3z turned"), std::string::npos) << summary.history[2].action;
  EXPECT_LE(summary.history[2].error, kDoneTimesFloor * summary.noise_floor.floor);
  ASSERT_EQ(summary.effects_added.size(), 1u);
  EXPECT_EQ(summary.effects_added[0].rfind("sensor-geometry@a3z:", 0), 0u) << summary.effects_added[0];
  EXPECT_LT(DistanceToTruth(summary.final_model, c), 0.01);
}

// An accelerometer turned by 14 degrees (seed 15008 of eval_loop: a3x, 150 Hz, 835 frequencies): the
// stiffness fit absorbs it at 1.01x the floor, 0.012 off the noise-free truth. Its correction held at
// the estimated turn raises the error by 0.8 % (within the floor's spread) and is kept: the model comes
// within 0.01 of the truth (eval_loop's criterion; 0.0052). Kept only when the error did not rise, as
// before, it was not, and the model stays 0.012 off.
TEST(Loop, KeepsATurnedChannelsCorrectionThatRaisesTheErrorWithinTheNoise) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectCase c;
  ASSERT_NO_FATAL_FAILURE(MakeEvalLoopCase(15008, 835, "sensor-geometry@a3x", &c, 150));
  LoopOptions options = Options({});
  const LoopSummary summary = RunLoop(nominal, c.measurement, options);
  std::cout << summary.HistoryTable();
  ASSERT_EQ(summary.history.size(), 3u);  // as given, fit, the turned channel
  EXPECT_GT(summary.history[2].error, summary.history[1].error);
  EXPECT_LE(summary.history[2].error, (1 + options.turned_channel_max_rise) * summary.history[1].error);
  ASSERT_EQ(summary.effects_added.size(), 1u);
  EXPECT_EQ(summary.effects_added[0].rfind("sensor-geometry@a3x:", 0), 0u) << summary.effects_added[0];
  EXPECT_LT(DistanceToTruth(summary.final_model, c), 0.01);

  options.turned_channel_max_rise = 0;  // the rule before
  const LoopSummary strict = RunLoop(nominal, c.measurement, options);
  EXPECT_TRUE(strict.effects_added.empty());
  EXPECT_NE(strict.history.back().action.find("a3x looks turned"), std::string::npos) << strict.history.back().action;
  EXPECT_GT(DistanceToTruth(strict.final_model, c), 0.01);
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
  EXPECT_TRUE(summary.confirmed);
  EXPECT_NE(summary.conclusion.find("its parameters alone explain the measurement"), std::string::npos) << summary.conclusion;
  // Every raw channel is at the floor too: none is named.
  ASSERT_FALSE(summary.final_channels.empty());
  EXPECT_LT(summary.final_channels[0].times_median, kChannelStandsOut);
  EXPECT_EQ(summary.conclusion.find("raw space"), std::string::npos) << summary.conclusion;
}

// A bending mode of the top plate (outside the catalogue, seed 91000 of eval_loop: 80 Hz, the four
// vertical sensors in the saddle pattern) is a pattern no rigid motion takes: the compliance projection
// leaves it out, and the first fit ends at the floor there (1.02x). The raw channels do not: the
// vertical sensors and impacts are at 17x the floor, the others at it, and the conclusion names them.
TEST(Loop, NamesTheRawChannelsAPlateModeLeavesAboveTheFloor) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectOptions o = synthetic::EvalLoopCaseOptions(0, 150, 1074);
  o.min_visibility = 8.0;
  const auto c = synthetic::MakeOutsideCatalogueCase(nominal, 91000, "plate-bending", o);
  const LoopSummary summary = RunLoop(nominal, c.measurement, Options({}));
  std::cout << summary.HistoryTable() << summary.conclusion << std::endl;
  ASSERT_TRUE(summary.noise_floor.known);
  ASSERT_LE(summary.history.back().error, kDoneTimesFloor * summary.noise_floor.floor);
  EXPECT_TRUE(summary.effects_added.empty());
  ASSERT_GE(summary.final_channels.size(), 2u);
  std::string changed;
  for (const auto& name : c.outputs) changed += name + " ";
  for (const auto& name : c.inputs) changed += name + " ";
  for (size_t k = 0; k < 2; ++k) {
    const ChannelError& ch = summary.final_channels[k];
    EXPECT_NE(changed.find(ch.name + " "), std::string::npos) << ch.name << " is not among " << changed;
    EXPECT_GT(ch.times_floor, 5.0) << ch.name;
    EXPECT_GT(ch.times_median, 5.0) << ch.name;
    EXPECT_NE(summary.conclusion.find(ch.name + " ("), std::string::npos) << summary.conclusion;
  }
  EXPECT_NE(summary.conclusion.find("But in raw space not every channel is at the floor"), std::string::npos) << summary.conclusion;
}

// Seed 63012 of eval_loop: a 7.6 kg payload 61 mm above the hexapod's centre of mass and a 0.9 ms delay
// (150 Hz, 368 frequencies). The loop ends at the floor with two effects and names no raw channel. Where
// its final model's payload sat off-centre (the build machines before: a4y at 1.8x the floor in raw
// space, cleared by the raw refit) or its extra body held the mass (an AMD build, -march=native: no
// channel stands out), it depends on the last bits of the fits; the mechanism is tested on its own below.
// (The loop is resumed from the model its rounds left on this machine, LoopSummary::after_rounds written
// to tests/diagnose/data: the payload 23 mm off-centre, 1.00x the floor. The steps after the rounds and
// the raw refit are what is tested; the whole loop takes 90 s.)
TEST(Loop, NamesNoRawChannelTheModelFitsInRawSpace) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 63012, synthetic::EvalLoopCaseOptions(2, 150.0, 368));
  LoopOptions options = Options({"payload", "extra-body", "delay"});
  options.resume_from = StoredLoopState("loop_63012_after_rounds.toml");
  const LoopSummary summary = RunLoop(nominal, c.measurement, options);
  std::cout << summary.HistoryTable();
  ASSERT_TRUE(summary.confirmed);
  ASSERT_EQ(summary.effects_added.size(), 2u);
  ASSERT_FALSE(summary.final_channels.empty());
  EXPECT_LT(summary.final_channels[0].times_floor, kChannelStandsOut) << summary.final_channels[0].name;
  EXPECT_TRUE(ConclusionChannels(summary).empty());
  EXPECT_EQ(summary.conclusion.find("But in raw space"), std::string::npos) << summary.conclusion;
}

// The same data with a model at the floor in compliance space whose payload sits 20 mm off-centre in x
// (the truth's stiffnesses, the delay, the payload's mass and height right): the compliance space
// hardly sees the offset (1.00x the floor), the raw channels do (a2y about 2.0x the floor and the
// median channel). Refitted in raw space with its parameters and its effects', the model fits a2y too,
// and the conclusion names no channel; without the refit it would name a2y.
TEST(Loop, RawRefitClearsAChannelTheModelCanFit) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 63012, synthetic::EvalLoopCaseOptions(2, 150.0, 368));
  model::ModelSpec model = nominal;
  for (auto& joint : model.joints) {
    for (const auto& truth : c.truth.joints) {
      if (truth.name == joint.name) joint = truth;
    }
  }
  model::ApplyEffect(model, model::ParseEffect("delay@acquisition:tau=0.0009", model));
  model::ApplyEffect(model, model::ParseEffect("payload@hexapod:mass=7.6,z=0.061,x=0.02", model));
  const LoopOptions options = Options({"payload"});
  const auto comparison = compare::Comparison::Create(model, c.measurement, options.diagnose.comparison);
  const compare::NoiseFloor floor = comparison.CalcNoiseFloor();
  ASSERT_TRUE(floor.known);
  ASSERT_LE(comparison.Error(model), options.rounds_above_times_floor * floor.floor);  // no round would run

  const std::vector<ChannelError> before = WorstChannels(model, c.measurement, options.diagnose.comparison, 6);
  ASSERT_FALSE(before.empty());
  EXPECT_EQ(before[0].name, "a2y");
  EXPECT_GE(before[0].times_floor, kChannelStandsOut);
  EXPECT_GE(before[0].times_median, kChannelStandsOut);
  const std::vector<ChannelError> after = ChannelsAfterRawRefit(model, c.measurement, options, before);
  ASSERT_EQ(after.size(), before.size());
  EXPECT_LT(after[0].times_floor, kChannelStandsOut) << after[0].name;

  LoopSummary summary;
  summary.noise_floor = floor;
  summary.history.push_back({"as given", "", comparison.Error(model)});
  summary.confirmed = true;
  summary.final_channels = before;
  ASSERT_FALSE(ConclusionChannels(summary).empty());
  EXPECT_EQ(ConclusionChannels(summary)[0].name, "a2y");
  summary.final_channels = after;
  EXPECT_TRUE(ConclusionChannels(summary).empty());
}

// The diagnosis fits the model again before it tries any effect (its baseline, and its step 3 from the
// leader's parameters and from the model as given); when that model is better than the one the loop
// holds, the loop takes it. Here the loop's own first fit is cut to one iteration, so that it stops
// short of the floor on effect-free data; the diagnosis' baseline fit (50 iterations) reaches it, no
// effect is needed, and the loop ends there with the diagnosis' model.
TEST(Loop, TakesTheDiagnosisBaselineWhenItIsBetter) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectOptions hidden;
  hidden.num_effects = 0;
  hidden.num_frequencies = 300;
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 7, hidden);
  LoopOptions options = Options({"delay"});
  options.fit.max_iterations = 1;
  options.fit.max_probe_rounds = 0;
  options.max_rounds = 1;
  options.turned_channel_deg = 0;
  const LoopSummary summary = RunLoop(nominal, c.measurement, options);
  std::cout << summary.HistoryTable();
  ASSERT_TRUE(summary.noise_floor.known);
  ASSERT_GE(summary.history.size(), 3u);
  ASSERT_EQ(summary.history[1].action, "fit");
  ASSERT_GT(summary.history[1].error, kDoneTimesFloor * summary.noise_floor.floor);  // the cut fit stops short
  EXPECT_EQ(summary.history[2].action, "refit (the diagnosis' baseline)");
  EXPECT_LT(summary.history[2].error, 0.99 * summary.history[1].error);
  EXPECT_TRUE(summary.effects_added.empty());
  EXPECT_EQ(summary.stop_reason, "at the noise floor");
  EXPECT_TRUE(summary.confirmed);
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  EXPECT_EQ(comparison.Error(summary.final_model), summary.history.back().error);
}

// `fitted` holds an extra body on the hexapod (first) whose rocking is in the band: TakeRigidLimits takes
// it as its payload, of `mass_kg` within `share`, the error within kRigidLimitTolerance of the body's.
void ExpectTheRockingBodyTakenAsItsPayload(const model::ModelSpec& nominal, const compare::Comparison& comparison,
                                           const EffectsFit& fitted, double mass_kg, double share) {
  const auto modes = model::FindEffectDefinition("extra-body").local_modes_hz(fitted.effects[0]);
  const Eigen::VectorXd& f = comparison.frequency_hz();
  ASSERT_TRUE(modes[1] > f(0) && modes[1] < f(f.size() - 1)) << fitted.effects[0].ToString();  // the rocking
  model::ModelSpec current = fitted.spec;
  const double error = comparison.Error(current);
  std::vector<LoopStep> history = {{"fit", "", error}};
  const auto taken = TakeRigidLimits(nominal, comparison, LoopOptions{}, &current, &history);
  ASSERT_EQ(taken, std::vector<std::string>{"extra-body@hexapod -> payload@hexapod"}) << fitted.effects[0].ToString();
  EXPECT_EQ(current.effects[0].name, "payload");
  EXPECT_NEAR(current.effects[0].parameters.at("mass"), mass_kg, share * mass_kg);
  EXPECT_LE(history.back().error, (1 + kRigidLimitTolerance) * error);
}

// An extra body with its rocking in the band but not in the data is still tried as its rigid limit:
// seed 1028's 7.2 kg payload 141 mm above the hexapod, fitted as a body with a stiff translation and its
// rocking held at 30 Hz (its inertia m r^2 is small beside the payload's m z^2). The limit as it
// stands is within kLocalModeSeenRise of the error, and the payload is taken.
TEST(TakeRigidLimits, TriesTheLimitOfABodyWhoseRockingInTheBandTheDataDoNotSee) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 1028, {});
  ASSERT_EQ(c.effects.size(), 1u);
  const auto& body = c.truth.bodies[model::FindBody(c.truth, "hidden_payload")];
  const double r = model::kExtraBodyRadiusOfGyration, w = 2 * M_PI * 30.0;
  model::Effect start = ExtraBodyOnTheHexapod(c, "hidden_payload", 1e10, body.mass_kg * r * r * w * w);
  model::HoldEffectParameter(&start, "kr");  // unseen, it would drift out of the band (to 1 Hz)
  EffectFitOptions eo;
  eo.max_iterations = 50;
  eo.initial_trust_region_radius = 1.0;
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const EffectsFit fitted = FitEffects(nominal, comparison, {start}, {"*.k.*"}, eo);
  ExpectTheRockingBodyTakenAsItsPayload(nominal, comparison, fitted, body.mass_kg, 0.05);
}

// The same where the model's parameters lean on the unseen rocking: 82270 of eval_loop (a 6 kg payload
// 87 mm above the hexapod and a 0.37 ms delay, 600 Hz band, 336 points) ended its loop with the
// payload as a body rigid in translation rocking at 65 Hz, whose limit as it stands raised the error
// by 14.5 %. Fitted so from the truth's stiffnesses (the rocking held), the limit as it stands is still
// more than kLocalModeSeenRise above the error; a few iterations of refit bring it back, and the payload
// is taken.
TEST(TakeRigidLimits, TakesTheLimitWhereTheModelLeansOnAnUnseenRocking) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 82270, synthetic::EvalLoopCaseOptions(2, 600, 336));
  ASSERT_EQ(Keys(c.effects), (std::vector<std::string>{"delay@acquisition", "payload@hexapod"}));
  const auto& body = c.truth.bodies[model::FindBody(c.truth, "hidden_payload")];
  model::Effect start = ExtraBodyOnTheHexapod(c, "hidden_payload", 1e14, 2489);  // as the loop ended
  model::HoldEffectParameter(&start, "k");
  model::HoldEffectParameter(&start, "kr");
  const model::Effect delay{"delay", "acquisition", {{"tau", 0.37e-3}}, {}};
  EffectFitOptions eo;
  eo.max_iterations = 50;
  eo.initial_trust_region_radius = 1.0;
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const EffectsFit fitted = FitEffects(WithTruthStiffnesses(nominal, c), comparison, {start, delay}, {"*.k.*"}, eo);
  std::vector<model::Effect> with_limit = fitted.effects;
  with_limit[0] = model::FindEffectDefinition("extra-body").rigid_limit(with_limit[0]);
  model::ModelSpec as_it_stands = fitted.spec;
  model::SetEffects(as_it_stands, with_limit);
  ASSERT_GT(comparison.Error(as_it_stands), (1 + kLocalModeSeenRise) * comparison.Error(fitted.spec));
  ExpectTheRockingBodyTakenAsItsPayload(nominal, comparison, fitted, body.mass_kg, 0.02);
}

// At the floor, an added extra body whose joint the data do not show is replaced by its rigid limit:
// a 7.2 kg payload 141 mm above the hexapod (seed 1028, brute-force data) fitted as an extra body with
// a stiff joint (from 1e10 N/m, 1e8 Nm/rad) is taken as a payload with its mass and height, the error
// within 1 %. An extra body whose local mode is in the band (seed 1009, 288 Hz) keeps its place, with
// no refit: the data see the mode (model::EffectDefinition::local_modes_hz), the limit as it stands far
// above kLocalModeSeenRise.
TEST(TakeRigidLimits, TakesThePayloadAStiffExtraBodyIsAndKeepsALocalMode) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  EffectFitOptions eo;
  eo.max_iterations = 50;
  eo.probe_basins = true;
  eo.initial_trust_region_radius = 1.0;
  for (const uint64_t seed : {1028, 1009}) {
    const auto c = synthetic::MakeHiddenEffectCase(nominal, seed, {});
    ASSERT_EQ(c.effects.size(), 1u);
    const bool payload = seed == 1028;
    const std::string body_name = payload ? "hidden_payload" : "hidden_body";
    const auto& body = c.truth.bodies[model::FindBody(c.truth, body_name)];
    const auto& host = c.truth.bodies[model::FindBody(c.truth, "hexapod")];
    const auto& joint = c.truth.joints[model::FindJoint(c.truth, body_name)];
    const model::Effect start =
        ExtraBodyOnTheHexapod(c, body_name, payload ? 1e10 : joint.stiffness[0], payload ? 1e8 : joint.stiffness[3]);
    const auto comparison = compare::Comparison::Create(nominal, c.measurement);
    const EffectsFit fitted = FitEffects(nominal, comparison, {start}, {"*.k.*"}, eo);
    model::ModelSpec current = fitted.spec;
    const double error = comparison.Error(current);
    std::vector<LoopStep> history = {{"fit", "", error}};
    const auto taken = TakeRigidLimits(nominal, comparison, LoopOptions{}, &current, &history);
    if (payload) {
      ASSERT_EQ(taken, std::vector<std::string>{"extra-body@hexapod -> payload@hexapod"}) << fitted.effects[0].ToString();
      ASSERT_EQ(current.effects.size(), 1u);
      EXPECT_EQ(current.effects[0].name, "payload");
      EXPECT_NEAR(current.effects[0].parameters.at("mass"), body.mass_kg, 0.05 * body.mass_kg);
      EXPECT_NEAR(current.effects[0].parameters.at("z"), body.com_W.z() - host.com_W.z(), 0.01);
      ASSERT_EQ(history.size(), 2u);
      EXPECT_EQ(history[1].error, comparison.Error(current));
      EXPECT_LE(history[1].error, (1 + kRigidLimitTolerance) * error);
    } else {
      const auto modes = model::FindEffectDefinition("extra-body").local_modes_hz(fitted.effects[0]);
      const Eigen::VectorXd& f = comparison.frequency_hz();
      EXPECT_TRUE(modes[0] > f(0) && modes[0] < f(f.size() - 1)) << modes[0] << " Hz";
      EXPECT_TRUE(taken.empty()) << fitted.effects[0].ToString();
      EXPECT_EQ(current.effects[0].name, "extra-body");
      EXPECT_EQ(history.size(), 1u);
    }
  }
}

// The loop's last check: an effect it added whose refitted value sits at the bound of its range is
// listed (and the model not confirmed); a plausible one is not, nor an effect of the model as given,
// however absurd (the user's).
TEST(ImplausibleAddedEffects, ListsAnAddedEffectAtItsBoundOnly) {
  model::ModelSpec as_given = model::DefaultModelSpec();
  model::ApplyEffect(as_given, model::ParseEffect("sensor-geometry@a1x:dz=0.05", as_given));
  model::ModelSpec final = as_given;
  model::ApplyEffect(final, model::ParseEffect("sensor-geometry@h5:dz=0.05", final));
  model::ApplyEffect(final, model::ParseEffect("joint-offset@hexapod:dz=0.01", final));
  const std::vector<std::string> found = ImplausibleAddedEffects(as_given, final, 5.0);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].rfind("sensor-geometry@h5: dz = 0.05 m is at the bound", 0), 0u) << found[0];
  EXPECT_TRUE(ImplausibleAddedEffects(final, final, 5.0).empty());
}

// The loop's last check asks the channels too: an impact's turn the other impacts' rigid motion does not
// see (effect-free data of eval_loop's generator, seed 45014) is listed, checked under the model without
// it, and a sensor correction it does not contradict beside it is not; without the channels' directions
// nothing is checked.
TEST(ImplausibleAddedEffects, ListsATurnTheChannelsDoNotSee) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectOptions options = synthetic::EvalLoopCaseOptions(0, 600, 786);
  options.visibility_against_no_effect = true;
  const auto sound = synthetic::MakeHiddenEffectCase(nominal, 45014, options);
  const Eigen::Vector3d X = compare::Comparison::Create(nominal, sound.measurement).frame_origin_W();
  model::ModelSpec final = nominal;
  model::ApplyEffect(final, model::ParseEffect("sensor-geometry@h10:rz=20 deg", final));
  model::ApplyEffect(final, model::ParseEffect("sensor-geometry@a2y:dx=0.01", final));
  int calls = 0;
  const auto directions_under = [&](const model::ModelSpec& without) {
    ++calls;
    EXPECT_EQ(without.effects.size(), 1u);
    return ChannelDirectionsUnder(without.geometry_corrections, sound.measurement, X, 0.0, std::numeric_limits<double>::infinity());
  };
  const std::vector<std::string> found = ImplausibleAddedEffects(nominal, final, 5.0, directions_under);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].rfind("sensor-geometry@h10: it turns h10 by 20.0 deg", 0), 0u) << found[0];
  EXPECT_NE(found[0].find("the channels say it is not turned so"), std::string::npos) << found[0];
  EXPECT_EQ(calls, 2);
  EXPECT_TRUE(ImplausibleAddedEffects(nominal, final, 5.0).empty());
}

// A channel's correction with its offset at the bound of its range (a2x of seed 7006, truly turned 16
// degrees about z, given dy = 5 cm and no turn): the offset is held at none and the turn where the
// other channels' rigid motion sees the channel; the refit from both starts leaves every held value
// where it was put, and with the turn held right the model reaches the noise floor.
TEST(HoldParametersAtBounds, HoldsAnOffsetAtNoneAndAChannelsTurnAtItsEstimate) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectCase c;
  ASSERT_NO_FATAL_FAILURE(MakeEvalLoopCase(7006, 477, "sensor-geometry@a2x", &c));
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  model::ModelSpec current = nominal;
  model::ApplyEffect(current, model::ParseEffect("sensor-geometry@a2x:dy=0.05", current));
  ASSERT_FALSE(ImplausibleAddedEffects(nominal, current, 5.0).empty());
  std::vector<LoopStep> history = {{"as given", "", comparison.Error(current)}};
  const LoopOptions options = Options({});
  const std::vector<std::string> held = HoldParametersAtBounds(nominal, c.measurement, comparison, options, &current, &history);
  EXPECT_EQ(held, (std::vector<std::string>{"sensor-geometry@a2x.dy", "sensor-geometry@a2x.rx", "sensor-geometry@a2x.ry",
                                            "sensor-geometry@a2x.rz"}));
  ASSERT_EQ(current.effects.size(), 1u);
  const model::Effect& e = current.effects[0];
  EXPECT_EQ(e.held, (std::vector<std::string>{"dy", "rx", "ry", "rz"}));
  EXPECT_EQ(e.parameters.at("dy"), 0.0);
  EXPECT_NEAR(std::abs(e.parameters.at("rz")) * 180 / M_PI, 16.0, 1.0);
  // The held turn is the estimate itself, untouched by the refit.
  const auto directions = measurement::EstimateChannelDirections(c.measurement, comparison.frame_origin_W(), options.diagnose.comparison.fmin_hz,
                                                                  options.diagnose.comparison.fmax_hz);
  for (const auto& d : directions) {
    if (d.name != "a2x") continue;
    const auto euler = CalcChannelTurn(d);
    ASSERT_TRUE(euler.has_value());
    EXPECT_EQ(e.parameters.at("rx"), (*euler)(0));
    EXPECT_EQ(e.parameters.at("rz"), (*euler)(2));
  }
  ASSERT_EQ(history.size(), 2u);
  EXPECT_EQ(history[1].action.rfind("hold sensor-geometry@a2x.dy, ", 0), 0u) << history[1].action;
  EXPECT_EQ(history[1].error, comparison.Error(current));
  EXPECT_LE(history[1].error, kDoneTimesFloor * comparison.CalcNoiseFloor().floor);
  EXPECT_TRUE(ImplausibleAddedEffects(nominal, current, 5.0).empty());
  // Nothing at a bound: nothing held, nothing changed.
  const model::ModelSpec before = current;
  EXPECT_TRUE(HoldParametersAtBounds(nominal, c.measurement, comparison, options, &current, &history).empty());
  EXPECT_EQ(current.effects, before.effects);
  EXPECT_EQ(history.size(), 2u);
}

// The two corrections the loop had on seed 51007 of eval_loop (a3z turned 17 degrees): h1's, and
// a3z's with its turn held at the estimate and its offset dy at none.
std::pair<model::Effect, model::Effect> Corrections51007(const model::ModelSpec& nominal, const std::vector<std::string>& channels) {
  return {model::ParseEffect("sensor-geometry@h1:dx=-0.0333,dz=-0.0096,rx=0.0493,rz=-0.1148", nominal, channels),
          model::ParseEffect("sensor-geometry@a3z:dx=-0.0236,dy=0,rx=0.30066481015096985,ry=1.6245651733523114e-05,"
                             "rz=-2.4608138812394783e-06,held=dy,held=rx,held=ry,held=rz",
                             nominal, channels)};
}

// After the hold, the effects added before the held one earn their place again (RunLoop calls
// DropUnneededEffects with the held effect newest). Seed 51007 of eval_loop (a3z turned 17 degrees,
// 5-150 Hz, 774 frequencies): the loop added h1's correction first (1.75x -> 1.27x), then a3z's beside
// it, and held a3z's turn at its estimate and its offset dy at none; h1's correction, which had stood in
// for part of the turn, stayed at 1.00x, 0.016 off the noise-free truth, and the check after the hold
// dropped it (1.01x, 0.0037 off the truth). Here the two corrections as the loop had them are fitted
// with the stiffnesses from the truth's (a fit from the nominal stiffnesses stops at 1.05x in a basin
// where h1's correction keeps the model below 1.06x, and it is rightly kept there): h1's correction is
// not needed beside the held one, the held values stay where they were put, and the model without it
// is at the truth.
TEST(DropUnneededEffects, DropsAnEffectThatStoodInBesideACorrectionNowHeld) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectCase c;
  ASSERT_NO_FATAL_FAILURE(MakeEvalLoopCase(51007, 774, "sensor-geometry@a3z", &c, 150));
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const auto [h1, a3z] = Corrections51007(nominal, comparison.CorrectableChannels());
  const model::ModelSpec start = WithTruthStiffnesses(nominal, c);
  EffectFitOptions eo;
  eo.max_iterations = 50;
  const EffectsFit both = FitEffects(start, comparison, {h1, a3z}, {"*.k.*"}, eo);
  const compare::NoiseFloor floor = comparison.CalcNoiseFloor();
  const double both_error = comparison.Error(both.spec);
  ASSERT_LT(both_error, 1.02 * floor.floor);

  model::ModelSpec current = both.spec;
  std::vector<LoopStep> history = {{"both", "", both_error}};
  const auto dropped = DropUnneededEffects(nominal, comparison, Options({}), both.effects[1], &current, &history);
  ASSERT_EQ(dropped, std::vector<std::string>{"sensor-geometry@h1"});
  ASSERT_EQ(current.effects.size(), 1u);
  EXPECT_EQ(current.effects[0].held, (std::vector<std::string>{"dy", "rx", "ry", "rz"}));
  for (const char* p : {"dy", "rx", "ry", "rz"}) EXPECT_EQ(current.effects[0].parameters.at(p), a3z.parameters.at(p)) << p;
  EXPECT_EQ(history.back().error, comparison.Error(current));
  EXPECT_LT(history.back().error, 1.02 * floor.floor);
  EXPECT_LT(DistanceToTruth(current, c), 0.01);
}

// A channel's correction beside a later one is judged on the floor it leaves (seed 200055 of
// eval_loop: a3z turned 17 degrees, 600 Hz, 818 frequencies). The loop's round tried impact h4's
// correction beside a3z's held one: it lowers the error by 11 %, 1.07x -> 1.04x of each model's own
// floor, the rest by re-weighing the measurement (its floor 0.0306 against 0.0333). Put in the other
// order, a3z's the newest, the check of the effects added before drops h4's: judged by the raw errors
// it earned its place.
TEST(DropUnneededEffects, JudgesAChannelsCorrectionOnTheFloorItLeaves) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectCase c;
  ASSERT_NO_FATAL_FAILURE(MakeEvalLoopCase(200055, 818, "sensor-geometry@a3z", &c));
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const std::vector<std::string> channels = comparison.CorrectableChannels();
  const model::Effect h4 = model::ParseEffect(
      "sensor-geometry@h4:dx=-1.3734e-05,dy=-0.013969,dz=0,rx=-0.025987,ry=-0.028599,rz=3.0867e-09", nominal, channels);
  const model::Effect a3z = model::ParseEffect(
      "sensor-geometry@a3z:dx=0,dy=0,dz=0,rx=-0.29555,ry=-0.00029461,rz=-4.3856e-05,held=dx,held=dy,held=dz,held=rx,held=ry,"
      "held=rz",
      nominal, channels);
  const model::ModelSpec start = WithTruthStiffnesses(nominal, c);
  EffectFitOptions eo;
  eo.max_iterations = 50;
  const EffectsFit both = FitEffects(start, comparison, {h4, a3z}, {"*.k.*"}, eo);
  const EffectsFit alone = FitEffects(start, comparison, {a3z}, {"*.k.*"}, eo);
  const double both_error = comparison.Error(both.spec), alone_error = comparison.Error(alone.spec);
  const double both_floor = comparison.CalcNoiseFloor(both.spec).floor, alone_floor = comparison.CalcNoiseFloor(alone.spec).floor;
  std::cout << "with h4: " << both_error / both_floor << "x its floor " << both_floor << "; without: " << alone_error / alone_floor
            << "x its floor " << alone_floor << "\n";
  const LoopOptions options;
  // The premises: by the raw errors h4's correction lowers the error by the share a round asks; on each
  // model's own floor it does not.
  ASSERT_LT(both_error, (1 - options.diagnose.min_relative_improvement) * alone_error);
  ASSERT_GT(both_error / both_floor, (1 - options.diagnose.min_relative_improvement) * alone_error / alone_floor);
  ASSERT_LT(both_floor, 0.95 * alone_floor);

  model::ModelSpec current = both.spec;
  std::vector<LoopStep> history = {{"both", "", both_error}};
  const auto dropped = DropUnneededEffects(nominal, comparison, options, both.effects[1], &current, &history);
  ASSERT_EQ(dropped, std::vector<std::string>{"sensor-geometry@h4"});
  ASSERT_EQ(Keys(current.effects), std::vector<std::string>{"sensor-geometry@a3z"});
  // The step holds the model's own error, not the one put on the floor of the model with h4.
  EXPECT_EQ(history.back().error, comparison.Error(current));
  EXPECT_LT(DistanceToTruth(current, c), 0.01);
}

// An effect added beside one whose parameters are held (a channel's correction held at its turn, as
// after HoldParametersAtBounds): the refit from the model as given starts from the model's own
// effects, holds included, so the held parameters stay where they were put. (The loop's hold rounds
// once restarted from a copy of its effects taken before the hold, with the turn free and the offset
// at its bound.) Seed 51007 of eval_loop, as above: a3z's held correction fitted from the nominal
// stiffnesses stops at 2.9x the floor, and h1's correction beside it, fitted from there, stays in
// that basin; "the model as given" here has the truth's stiffnesses, so the restart from it is the
// better refit, and it reaches the floor with a3z's values as held.
TEST(AddEffectAndRefit, RestartsFromTheModelsEffectsWithTheirHolds) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectCase c;
  ASSERT_NO_FATAL_FAILURE(MakeEvalLoopCase(51007, 774, "sensor-geometry@a3z", &c, 150));
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const auto [h1, a3z] = Corrections51007(nominal, comparison.CorrectableChannels());
  EffectFitOptions eo;
  eo.max_iterations = 50;
  const EffectsFit alone = FitEffects(nominal, comparison, {a3z}, {"*.k.*"}, eo);
  model::ModelSpec bent = alone.spec;
  model::SetEffects(bent, {});
  const EffectsFit both = FitEffects(bent, comparison, {alone.effects[0], h1}, {"*.k.*"}, eo);
  const double floor = comparison.CalcNoiseFloor().floor;
  const double alone_error = comparison.Error(alone.spec);
  ASSERT_GT(alone_error, 2 * floor);
  ASSERT_LT(comparison.Error(both.spec), alone_error);

  model::ModelSpec current = alone.spec;
  std::vector<LoopStep> history = {{"a3z's correction, held", "", alone_error}};
  const model::ModelSpec as_given = WithTruthStiffnesses(nominal, c);
  ASSERT_TRUE(AddEffectAndRefit(as_given, comparison, Options({}), both.spec, both.effects[1], &current, &history));
  for (const LoopStep& step : history) std::cout << step.action << ": " << step.error / floor << " x the floor\n";
  ASSERT_EQ(history.size(), 3u);
  EXPECT_EQ(history[1].action, "add sensor-geometry@h1");
  EXPECT_EQ(history[2].action, "refit (effects and model from the model as given)");
  EXPECT_EQ(history[2].error, comparison.Error(current));
  EXPECT_LT(history[2].error, kDoneTimesFloor * floor);
  ASSERT_EQ(current.effects.size(), 2u);
  const model::Effect& held = current.effects[0];
  EXPECT_EQ(held.location, "a3z");
  EXPECT_EQ(held.held, (std::vector<std::string>{"dy", "rx", "ry", "rz"}));
  for (const char* p : {"dy", "rx", "ry", "rz"}) EXPECT_EQ(held.parameters.at(p), a3z.parameters.at(p)) << p;
  EXPECT_EQ(current.effects[1].location, "h1");
}

// Two couplings of one joint that its stiffness centre off its origin makes are merged into the offset.
// Seed 51012 of eval_loop (rz's stiffness centre 149 mm off and a 0.63 ms delay, 5-600 Hz, 392
// frequencies): the loop added the delay and then rz's Dy-Rx and Dx-Ry couplings (1.06x the floor, 0.011
// off the noise-free truth). The delay and the two couplings as the loop had them, fitted with the
// stiffnesses from the truth's: the offset started where the couplings put it takes their place, closer
// to the data and to the truth.
TEST(MergeMimickingEffects, TakesAJointOffsetForTwoCouplingsItMakes) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 51012, synthetic::EvalLoopCaseOptions(2, 600, 392));
  ASSERT_EQ(c.effects.size(), 2u);
  ASSERT_EQ(c.effects[0].name + "@" + c.effects[0].location, "joint-offset@rz");
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const double floor = comparison.CalcNoiseFloor().floor;
  const model::ModelSpec start = WithTruthStiffnesses(nominal, c);
  const model::Effect delay = model::ParseEffect("delay@acquisition:tau=0.000626", nominal);
  EffectFitOptions eo;
  eo.max_iterations = 50;
  const EffectsFit couplings = FitEffects(start, comparison, {delay, model::ParseEffect("coupled-stiffness@rz.Dy-Rx", nominal),
                                                              model::ParseEffect("coupled-stiffness@rz.Dx-Ry", nominal)},
                                          {"*.k.*"}, eo);
  const double couplings_error = comparison.Error(couplings.spec);
  ASSERT_LT(couplings_error, 1.06 * floor);

  model::ModelSpec current = couplings.spec;
  std::vector<LoopStep> history = {{"couplings", "", couplings_error}};
  const auto merged = MergeMimickingEffects(nominal, comparison, Options({}), &current, &history);
  ASSERT_EQ(merged, std::vector<std::string>{"coupled-stiffness@rz.Dy-Rx, coupled-stiffness@rz.Dx-Ry -> joint-offset@rz"});
  ASSERT_EQ(current.effects.size(), 2u);
  EXPECT_EQ(current.effects[0].name, "delay");
  const model::Effect& offset = current.effects[1];
  EXPECT_NEAR(std::hypot(offset.parameters.at("dx"), offset.parameters.at("dy"), offset.parameters.at("dz")), 0.149, 0.015);
  ASSERT_EQ(history.size(), 2u);
  EXPECT_EQ(history[1].error, comparison.Error(current));
  EXPECT_LT(history[1].error, couplings_error);
  EXPECT_LT(DistanceToTruth(current, c), DistanceToTruth(couplings.spec, c));
  EXPECT_LT(DistanceToTruth(current, c), 0.01);
  // Nothing to merge now.
  EXPECT_TRUE(MergeMimickingEffects(nominal, comparison, Options({}), &current, &history).empty());
  EXPECT_EQ(history.size(), 2u);
}

// Two couplings of a joint that are its offset beside a coupling of its own: seed 82755 of eval_loop
// (the hexapod's stiffness centre 109 mm below the model's and a Dx-Ry coupling of 2.52e6 N/rad there,
// 5-150 Hz, 626 frequencies). The loop's rounds added the hexapod's Dy-Rx and Dx-Ry couplings and stopped
// at 1.15x the floor, 0.0185 off the noise-free truth (LoopSummary::after_rounds of this case's loop,
// written to tests/diagnose/data). The offset alone cannot make both: their terms have one sign, an
// offset's opposite signs. Made from the Dy-Rx coupling, beside the Dx-Ry coupling less the offset's
// own term, it is the truth's.
TEST(MergeMimickingEffects, TakesAJointOffsetBesideWhatIsLeftOfTheCouplings) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 82755, synthetic::EvalLoopCaseOptions(2, 150, 626));
  ASSERT_EQ(Keys(c.effects), (std::vector<std::string>{"joint-offset@hexapod", "coupled-stiffness@hexapod.Dx-Ry"}));
  const model::JointSpec& hexapod = c.truth.joints[model::FindJoint(c.truth, "hexapod")];
  const double dz = hexapod.origin_W.z() - nominal.joints[model::FindJoint(nominal, "hexapod")].origin_W.z();
  const double k_truth = hexapod.couplings.at(0).stiffness;
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const double floor = comparison.CalcNoiseFloor().floor;
  model::ModelSpec current = StoredLoopState("loop_82755_after_rounds.toml");
  ASSERT_EQ(Keys(current.effects), (std::vector<std::string>{"coupled-stiffness@hexapod.Dy-Rx", "coupled-stiffness@hexapod.Dx-Ry"}));
  std::vector<LoopStep> history = {{"the loop's rounds", "", comparison.Error(current)}};
  ASSERT_GT(history[0].error, 1.1 * floor);
  ASSERT_GT(DistanceToTruth(current, c), 0.01);

  const LoopOptions options;
  const auto merged = MergeMimickingEffects(nominal, comparison, options, &current, &history);
  ASSERT_EQ(merged, std::vector<std::string>{"coupled-stiffness@hexapod.Dy-Rx, coupled-stiffness@hexapod.Dx-Ry -> "
                                             "joint-offset@hexapod, coupled-stiffness@hexapod.Dx-Ry"});
  ASSERT_EQ(history.size(), 2u);
  EXPECT_EQ(history[1].action,
            "merge coupled-stiffness@hexapod.Dy-Rx, coupled-stiffness@hexapod.Dx-Ry into joint-offset@hexapod and what is left of "
            "coupled-stiffness@hexapod.Dx-Ry");
  EXPECT_EQ(history[1].error, comparison.Error(current));
  ASSERT_EQ(Keys(current.effects), (std::vector<std::string>{"joint-offset@hexapod", "coupled-stiffness@hexapod.Dx-Ry"}));
  std::cout << "merged: " << history[1].error / floor << "x the floor, " << DistanceToTruth(current, c) << " off the truth, dz "
            << current.effects[0].parameters.at("dz") << " (truth " << dz << "), k " << current.effects[1].parameters.at("k")
            << " (truth " << k_truth << ")\n";
  EXPECT_LT(history[1].error, 1.05 * floor);
  EXPECT_LT(DistanceToTruth(current, c), 0.005);
  EXPECT_NEAR(current.effects[0].parameters.at("dz"), dz, 0.01);
  EXPECT_NEAR(current.effects[1].parameters.at("k"), k_truth, 0.03 * std::abs(k_truth));
  // One coupling left at the joint: nothing to merge now.
  EXPECT_TRUE(MergeMimickingEffects(nominal, comparison, options, &current, &history).empty());
  EXPECT_EQ(history.size(), 2u);
  // Not tried at the floor, where it would add parameters the loop does not look for:
  // Loop.MergesTheCouplingsAnOffsetMakesAgainAfterARigidLimit.
}

// The model the hold step ends with is kept at the floor, with every effect plausible, when its error is
// within 1 % of the model's before or as low as the loop looks for (rounds_above_times_floor, 1.06x).
TEST(KeepModelAfterHold, WithinOnePercentOrWhereTheLoopLooksNoFurther) {
  compare::NoiseFloor floor;
  floor.known = true;
  floor.floor = 0.04;
  const LoopOptions options;
  ASSERT_EQ(options.rounds_above_times_floor, 1.06);
  auto keep = [&](double before, double after, bool plausible = true) {
    return KeepModelAfterHold(before * floor.floor, after * floor.floor, plausible, floor, options);
  };
  EXPECT_TRUE(keep(0.97, 0.99));    // 51010: a rise of 2 %, at the floor
  EXPECT_TRUE(keep(0.98, 1.05));
  EXPECT_FALSE(keep(0.98, 1.07));   // a rise of 9 %, where the loop would look for more
  EXPECT_TRUE(keep(1.10, 1.11));    // within 1 %
  EXPECT_FALSE(keep(1.10, 1.12));
  EXPECT_TRUE(keep(1.04, 0.95));    // lower
  EXPECT_FALSE(keep(0.97, 0.99, false));  // an effect implausible
  EXPECT_FALSE(keep(1.19, 1.201));  // within 1 %, but above the floor's 1.2x
  floor.known = false;
  EXPECT_FALSE(keep(0.97, 0.97));
}

// An effect the loop added in an earlier round that a later one makes unnecessary is dropped: with the
// hexapod's stiffness centre 84 mm low (seed 1017), a model holding a coupling in ry (fitted with the
// offset, at the floor) is refitted without the coupling to within 5 % of its error, so the coupling
// goes and the offset stays; checked the other way round (the coupling the newest), the offset earns
// its place.
// Seed 1017 (the hexapod's stiffness centre 84 mm low) and a model with a coupling in ry and the offset,
// fitted together: the two tests below.
struct CouplingAndOffset {
  synthetic::HiddenEffectCase hidden;
  compare::Comparison comparison;
  EffectsFit both;  // effects[0] the coupling, effects[1] the offset
};

CouplingAndOffset FitCouplingAndOffset(const model::ModelSpec& nominal) {
  synthetic::HiddenEffectCase c = synthetic::MakeHiddenEffectCase(nominal, 1017, {});
  compare::Comparison comparison = compare::Comparison::Create(nominal, c.measurement);
  const model::Effect coupling = model::ParseEffect("coupled-stiffness@ry.Dx-Dy", nominal);
  const model::Effect offset = model::ParseEffect("joint-offset@hexapod:dz=-80 mm", nominal);
  EffectFitOptions eo;
  eo.max_iterations = 50;
  eo.probe_basins = true;
  eo.initial_trust_region_radius = 1.0;
  EffectsFit both = FitEffects(nominal, comparison, {coupling, offset}, {"*.k.*"}, eo);
  return {std::move(c), std::move(comparison), std::move(both)};
}

TEST(DropUnneededEffects, DropsAnEarlierEffectTheLaterOneMakesUnnecessary) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto [c, comparison, both] = FitCouplingAndOffset(nominal);
  ASSERT_EQ(c.effects.size(), 1u);
  ASSERT_EQ(c.effects[0].name + "@" + c.effects[0].location, "joint-offset@hexapod");
  const double floor = comparison.CalcNoiseFloor().floor;
  const double both_error = comparison.Error(both.spec);
  ASSERT_LT(both_error, kDoneTimesFloor * floor) << both.effects[0].ToString() << " " << both.effects[1].ToString();

  // The offset newest: the coupling is checked and dropped.
  model::ModelSpec current = both.spec;
  std::vector<LoopStep> history = {{"both", "", both_error}};
  const auto dropped = DropUnneededEffects(nominal, comparison, LoopOptions{}, both.effects[1], &current, &history);
  ASSERT_EQ(dropped, std::vector<std::string>{"coupled-stiffness@ry.Dx-Dy"});
  ASSERT_EQ(current.effects.size(), 1u);
  EXPECT_EQ(current.effects[0].name, "joint-offset");
  ASSERT_EQ(history.size(), 2u);
  EXPECT_EQ(history[1].error, comparison.Error(current));
  EXPECT_LT(history[1].error, kDoneTimesFloor * floor);

  // The coupling newest: the offset is checked and kept.
  model::ModelSpec kept = both.spec;
  std::vector<LoopStep> kept_history = {{"both", "", both_error}};
  EXPECT_TRUE(DropUnneededEffects(nominal, comparison, LoopOptions{}, both.effects[0], &kept, &kept_history).empty());
  EXPECT_EQ(kept.effects.size(), 2u);
  EXPECT_EQ(kept_history.size(), 1u);
}

// The refit on the search grid first (RefitRatioOnSearchGrid) on the case above, its 300 frequencies
// thinned to 150: the model without the offset (the coupling left) stays far above the model with
// both, more than kSearchGridMargin times what dropping the offset asks, so the offset earns its place
// without the refit on all frequencies; the model without the coupling does not rise by the 5 % share,
// and its ratio on the search grid is within 2 % of the one on all frequencies. DropUnneededEffects
// decides both as it does without the thinning.
TEST(DropUnneededEffects, RefitsOnTheSearchGridFirst) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto [c, comparison, both] = FitCouplingAndOffset(nominal);
  const double both_error = comparison.Error(both.spec);
  ASSERT_LT(both_error, kDoneTimesFloor * comparison.CalcNoiseFloor().floor);

  LoopOptions options;
  options.diagnose.max_search_frequencies = 150;
  const auto search = ThinnedComparison(comparison, options.diagnose.max_search_frequencies);
  ASSERT_TRUE(search);
  ASSERT_EQ(search->num_frequencies(), 150);
  const double asked = 1 / (1 - options.diagnose.min_relative_improvement);  // what dropping an effect asks
  const double without_offset = RefitRatioOnSearchGrid(nominal, *search, options, both.spec, {both.effects[0]});
  const double without_coupling = RefitRatioOnSearchGrid(nominal, *search, options, both.spec, {both.effects[1]});
  std::cout << "on the search grid, without the offset " << without_offset << ", without the coupling " << without_coupling
            << " times the model with both\n";
  EXPECT_GT(without_offset, kSearchGridMargin * asked);
  EXPECT_LT(without_coupling, asked);

  model::ModelSpec current = both.spec;
  std::vector<LoopStep> history = {{"both", "", both_error}};
  EXPECT_EQ(DropUnneededEffects(nominal, comparison, options, both.effects[1], &current, &history),
            std::vector<std::string>{"coupled-stiffness@ry.Dx-Dy"});
  ASSERT_EQ(history.size(), 2u);
  EXPECT_NEAR(without_coupling, history[1].error / both_error, 0.02 * history[1].error / both_error);
  model::ModelSpec kept = both.spec;
  std::vector<LoopStep> kept_history = {{"both", "", both_error}};
  EXPECT_TRUE(DropUnneededEffects(nominal, comparison, options, both.effects[0], &kept, &kept_history).empty());
  EXPECT_EQ(kept.effects.size(), 2u);
}

// Near the floor an effect cannot lower the error by the 5 % share: it is kept when the model is at the
// floor with it (within LoopOptions::rounds_above_times_floor) and would need another round without it.
// Seed 15011 of eval_loop (a ty.Dy servo of 1.28e9 N/m and a4y turned 20 degrees, 5-150 Hz, 700
// frequencies): the loop added the servo (1.08x -> 1.02x), then a4y's correction beside it, and
// dropped the servo for not lowering that model's error by 5 %; it ended at 1.07x, 0.019 off the truth.
// With the rule off (a round threshold below any model's error) the servo goes, as it went then.
TEST(DropUnneededEffects, KeepsAnEffectTheModelNeedsToBeAtTheFloor) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectOptions options = synthetic::EvalLoopCaseOptions(2, 150, 700);
  options.visibility_against_no_effect = true;  // the servo as first drawn (its own visibility is below 2)
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 15011, options);
  ASSERT_EQ(c.effects.size(), 2u);
  ASSERT_EQ(c.effects[0].name + "@" + c.effects[0].location, "sensor-geometry@a4y");
  ASSERT_EQ(c.effects[1].name + "@" + c.effects[1].location, "servo-stiffness@ty.Dy");
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const model::Effect servo = model::ParseEffect("servo-stiffness@ty.Dy:k=1.4e9,zeta=0.013", nominal);
  const model::Effect turn = model::ParseEffect("sensor-geometry@a4y:rx=0.346", nominal);
  EffectFitOptions eo;
  eo.initial_trust_region_radius = 1.0;
  const EffectsFit both = FitEffects(nominal, comparison, {servo, turn}, LoopOptions{}.diagnose.params, eo);
  const double floor = comparison.CalcNoiseFloor().floor;
  const double both_error = comparison.Error(both.spec);
  ASSERT_LE(both_error, LoopOptions{}.rounds_above_times_floor * floor);

  model::ModelSpec kept = both.spec;
  std::vector<LoopStep> kept_history = {{"both", "", both_error}};
  EXPECT_TRUE(DropUnneededEffects(nominal, comparison, LoopOptions{}, both.effects[1], &kept, &kept_history).empty());
  EXPECT_EQ(kept.effects.size(), 2u);

  LoopOptions rule_off;
  rule_off.rounds_above_times_floor = 1.0;
  model::ModelSpec current = both.spec;
  std::vector<LoopStep> history = {{"both", "", both_error}};
  EXPECT_EQ(DropUnneededEffects(nominal, comparison, rule_off, both.effects[1], &current, &history),
            std::vector<std::string>{"servo-stiffness@ty.Dy"});
  ASSERT_EQ(history.size(), 2u);
  EXPECT_GT(history[1].error, LoopOptions{}.rounds_above_times_floor * floor);  // another round's worth
  EXPECT_LT(both_error, history[1].error);
}

// The fit that puts a relocation test's effects where the loop's rounds left them: the effects and the
// stiffnesses, as the loop refits them.
// A diagnosis' candidate of the effect `text` (on the default model) with `delta_bic`, for the steps
// that take a round's candidates.
Candidate CandidateOf(const std::string& text, double delta_bic) {
  Candidate k;
  k.effect = model::ParseEffect(text, model::DefaultModelSpec());
  k.with = k.effect.ToString();
  k.delta_bic = delta_bic;
  return k;
}

EffectFitOptions RoundsFitOptions() {
  EffectFitOptions eo;
  eo.max_iterations = 100;
  eo.probe_basins = true;
  eo.initial_trust_region_radius = 1.0;
  return eo;
}

// The reverse of the merge: a joint offset and a coupling of its joint that cancels one of the two terms
// the offset makes are the one coupling left. Seed 82516 of eval_loop (a 6.2 kg payload 49 mm above the
// hexapod's centre of mass and a Dx-Ry coupling of 1.56e6 N/rad there, 5-600 Hz, 307 frequencies): the
// loop's rounds took the hexapod's stiffness centre 157 mm up for the coupling, then added the payload,
// the Dy-Rx coupling against the offset's other term, and a loss factor, and stopped at 1.17x the floor,
// 0.018 off the noise-free truth. Its effects as they were, refitted with the stiffnesses from the
// nominal ones: the offset and the Dy-Rx coupling give way to the Dx-Ry coupling they make together,
// the loss factor is then not needed, and the model is the truth's.
TEST(ReduceToTheMimicsLeft, TakesTheOneCouplingAnOffsetAndACouplingMake) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 82516, synthetic::EvalLoopCaseOptions(2, 600, 307));
  ASSERT_EQ(Keys(c.effects), (std::vector<std::string>{"payload@hexapod", "coupled-stiffness@hexapod.Dx-Ry"}));
  const model::JointSpec& hexapod = c.truth.joints[model::FindJoint(c.truth, "hexapod")];
  ASSERT_EQ(hexapod.couplings.size(), 1u);
  const double k_truth = hexapod.couplings[0].stiffness;
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const double floor = comparison.CalcNoiseFloor().floor;
  const std::vector<model::Effect> rounds = {
      model::ParseEffect("joint-offset@hexapod:dx=-0.00506,dy=-0.00242,dz=0.1572", nominal),
      model::ParseEffect("payload@hexapod:mass=6.19,x=-0.0110,y=-0.0103,z=0.0503", nominal),
      model::ParseEffect("coupled-stiffness@hexapod.Dy-Rx:k=1.714e6", nominal),
      model::ParseEffect("structural-damping@hexapod:eta=0.0416", nominal)};
  model::ModelSpec current = FitEffects(nominal, comparison, rounds, {"*.k.*"}, RoundsFitOptions()).spec;
  std::vector<LoopStep> history = {{"the rounds' effects", "", comparison.Error(current)}};
  std::cout << "the rounds' effects refitted: " << history[0].error / floor << "x the floor\n";
  ASSERT_GT(history[0].error, 1.1 * floor);
  ASSERT_GT(DistanceToTruth(current, c), 0.01);

  const LoopOptions options;
  const auto reduced = ReduceToTheMimicsLeft(nominal, comparison, options, &current, &history);
  ASSERT_EQ(reduced, std::vector<std::string>{"joint-offset@hexapod, coupled-stiffness@hexapod.Dy-Rx -> coupled-stiffness@hexapod.Dx-Ry"});
  ASSERT_EQ(history.size(), 2u);
  EXPECT_EQ(history[1].action,
            "reduce joint-offset@hexapod, coupled-stiffness@hexapod.Dy-Rx to coupled-stiffness@hexapod.Dx-Ry (what they make together)");
  EXPECT_EQ(history[1].error, comparison.Error(current));
  EXPECT_LE(history[1].error, (1 + kRigidLimitTolerance) * history[0].error);
  EXPECT_EQ(Keys(current.effects),
            (std::vector<std::string>{"payload@hexapod", "structural-damping@hexapod", "coupled-stiffness@hexapod.Dx-Ry"}));
  // Nothing left to reduce.
  EXPECT_TRUE(ReduceToTheMimicsLeft(nominal, comparison, options, &current, &history).empty());
  EXPECT_EQ(history.size(), 2u);

  const auto dropped = DropUnneededEffects(nominal, comparison, options, current.effects.back(), &current, &history);
  EXPECT_EQ(dropped, std::vector<std::string>{"structural-damping@hexapod"});
  ASSERT_EQ(Keys(current.effects), (std::vector<std::string>{"payload@hexapod", "coupled-stiffness@hexapod.Dx-Ry"}));
  std::cout << "reduced and dropped: " << history.back().error / floor << "x the floor, " << DistanceToTruth(current, c)
            << " off the truth, k " << current.effects[1].parameters.at("k") << " (truth " << k_truth << ")\n";
  EXPECT_LT(history.back().error, 1.05 * floor);
  EXPECT_LT(DistanceToTruth(current, c), 0.005);
  EXPECT_NEAR(current.effects[1].parameters.at("k"), k_truth, 0.03 * std::abs(k_truth));
}

// A loss factor in the wrong joint (seed 1 of eval_loop's kind of case, 5-150 Hz, here 150 frequencies:
// a loss factor of 0.062 in rz, put in ty and fitted there with the stiffnesses) is moved to rz, where
// the model comes to the error of the effect fitted in rz from the start; in rz it stays. (The
// catalogue's one loss factor for the six DoF leaves that at 1.7x the floor.)
TEST(RelocateEffects, MovesAnEffectToWhereTheDataPutIt) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 1, synthetic::EvalLoopCaseOptions(1, 150, 150));
  ASSERT_EQ(c.effects.size(), 1u);
  ASSERT_EQ(c.effects[0].name + "@" + c.effects[0].location, "structural-damping@rz");
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const double floor = comparison.CalcNoiseFloor().floor;
  const EffectFitOptions eo = RoundsFitOptions();
  LoopOptions options;
  options.diagnose.effects = {"payload"};  // replaced by the effect sought again
  options.diagnose.progress = [](const std::string& line) { std::cout << line << std::endl; };
  auto fitted_at = [&](const std::string& place) {
    return FitEffects(nominal, comparison, {model::ParseEffect("structural-damping@" + place, nominal)}, {"*.k.*"}, eo).spec;
  };
  // In rz: nothing moves.
  model::ModelSpec right = fitted_at("rz");
  const double right_error = comparison.Error(right);
  std::vector<LoopStep> right_history = {{"fitted", "", right_error}};
  EXPECT_TRUE(RelocateEffects(nominal, c.measurement, comparison, options, options.diagnose, &right, &right_history).empty());
  EXPECT_EQ(right_history.size(), 1u);
  // In ty: moved to rz; not sought again where only the mass effects are (the loop's step near the floor).
  model::ModelSpec current = fitted_at("ty");
  std::vector<LoopStep> history = {{"fitted", "", comparison.Error(current)}};
  const std::vector<model::Effect> in_ty = current.effects;
  EXPECT_TRUE(RelocateEffects(nominal, c.measurement, comparison, options, options.diagnose, &current, &history,
                              /*mass_effects_only=*/true)
                  .empty());
  EXPECT_EQ(history.size(), 1u);
  EXPECT_TRUE(current.effects == in_ty);
  EXPECT_EQ(comparison.Error(current), history.front().error);
  const auto moved = RelocateEffects(nominal, c.measurement, comparison, options, options.diagnose, &current, &history);
  std::cout << "in rz " << right_error / floor << "x the floor; in ty " << history.front().error / floor << "x, moved "
            << history.back().error / floor << "x\n";
  EXPECT_GT(history.front().error, 3 * right_error);
  ASSERT_EQ(moved, std::vector<std::string>{"structural-damping@ty -> structural-damping@rz"});
  ASSERT_EQ(current.effects.size(), 1u);
  EXPECT_EQ(current.effects[0].location, "rz");
  ASSERT_EQ(history.size(), 2u);
  EXPECT_EQ(history[1].action, "move structural-damping@ty to rz");
  EXPECT_EQ(history[1].error, comparison.Error(current));
  EXPECT_LT(history[1].error, 1.01 * right_error);
}

// A payload is sought as an extra body too (model::EffectDefinition::also_sought_as). Seed 81805 of
// eval_loop (150 Hz band, 708 points): a 3.9 kg body on the hexapod with its local mode at 158 Hz, just
// above the band, and a 52 kg payload on rz. The loop's rounds took the body for a payload of 8.7 kg,
// 97 and 87 mm off-axis, beside a joint offset of the hexapod, and stopped at 2.13x the floor; sought
// only as a payload at every body, it stayed. As an extra body it is the 3.9 kg body.
TEST(RelocateEffects, SeeksAPayloadAsAnExtraBodyToo) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 81805, synthetic::EvalLoopCaseOptions(2, 150, 708));
  ASSERT_EQ(c.effects.size(), 2u);
  ASSERT_EQ(c.effects[1].name + "@" + c.effects[1].location, "extra-body@hexapod");
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const double floor = comparison.CalcNoiseFloor().floor;
  const EffectFitOptions eo = RoundsFitOptions();
  // The loop's effects as it stopped, refitted with the stiffnesses.
  const std::vector<model::Effect> rounds = {
      model::ParseEffect("payload@hexapod:mass=8.71,x=0.0971,y=0.0870,z=0.0414", nominal),
      model::ParseEffect("joint-offset@hexapod:dx=0.0187,dy=0.0117,dz=0.0005", nominal)};
  model::ModelSpec current = FitEffects(nominal, comparison, rounds, {"*.k.*"}, eo).spec;
  std::vector<LoopStep> history = {{"fitted", "", comparison.Error(current)}};
  ASSERT_GT(history.front().error, 1.5 * floor);
  LoopOptions options;
  options.diagnose.progress = [](const std::string& line) { std::cout << line << std::endl; };
  const auto moved = RelocateEffects(nominal, c.measurement, comparison, options, options.diagnose, &current, &history);
  std::cout << "before " << history.front().error / floor << "x the floor, after " << history.back().error / floor << "x\n";
  ASSERT_NE(std::find(moved.begin(), moved.end(), "payload@hexapod -> extra-body@hexapod"), moved.end());
  const auto body = std::find_if(current.effects.begin(), current.effects.end(), [](const model::Effect& e) { return e.name == "extra-body"; });
  ASSERT_NE(body, current.effects.end());
  EXPECT_EQ(body->location, "hexapod");
  EXPECT_NEAR(body->parameters.at("mass"), 3.9, 0.4);
  EXPECT_NE(std::find_if(history.begin(), history.end(), [](const LoopStep& s) { return s.action == "move payload@hexapod to extra-body@hexapod"; }),
            history.end());
  EXPECT_LT(history.back().error, 0.6 * history.front().error);
}

// RelocateEffects with the options of the loop's diagnoses (LoopDiagnoseOptions), its progress and the
// error before and after it printed.
std::vector<std::string> RelocateAsTheLoopDoes(const model::ModelSpec& nominal, const synthetic::HiddenEffectCase& c,
                                               const compare::Comparison& comparison, model::ModelSpec* current,
                                               std::vector<LoopStep>* history) {
  LoopOptions options;
  options.progress = [](const std::string& line) { std::cout << line << std::endl; };
  const auto moved = RelocateEffects(nominal, c.measurement, comparison, options, LoopDiagnoseOptions(options, nominal), current, history);
  const double floor = comparison.CalcNoiseFloor().floor;
  std::cout << "before " << history->front().error / floor << "x the floor, after " << history->back().error / floor << "x\n";
  return moved;
}

// A payload is also refitted as an extra body in its own place, from its state
// (model::EffectDefinition::starts_in_place). Seed 82296 of eval_loop (150 Hz band, 669 points): a 3.3 kg
// body on the hexapod with its local mode at 215 Hz, above the band. The loop's rounds took it for a
// payload of 5.6 kg, 50 mm off-axis, at 1.13x the floor; the diagnosis of both kinds on the model
// without it named the payload again. Started from the payload's mass and height, the body is found.
TEST(RelocateEffects, RefitsAPayloadAsAnExtraBodyInItsPlace) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 82296, synthetic::EvalLoopCaseOptions(1, 150, 669));
  ASSERT_EQ(c.effects.size(), 1u);
  ASSERT_EQ(c.effects[0].name + "@" + c.effects[0].location, "extra-body@hexapod");
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const double floor = comparison.CalcNoiseFloor().floor;
  // The loop's state as it stopped (6 digits): its stiffnesses and the payload.
  model::ModelSpec current = nominal;
  const std::vector<std::pair<std::string, double>> stiffnesses = {
      {"granite.k.Dx", 3.60708e+09}, {"granite.k.Dy", 9.93891e+11}, {"granite.k.Dz", 4.45975e+09}, {"granite.k.Rx", 2.06223e+07},
      {"granite.k.Ry", 3.08053e+07}, {"granite.k.Rz", 1.10825e+07}, {"ty.k.Dx", 2.95821e+08},      {"ty.k.Dz", 1.75195e+08},
      {"ty.k.Rx", 4.8576e+07},       {"ty.k.Ry", 8.88748e+07},      {"ty.k.Rz", 2.89224e+06},      {"ry.k.Dx", 2.73045e+08},
      {"ry.k.Dy", 2.74813e+08},      {"ry.k.Dz", 3.34923e+08},      {"ry.k.Rx", 1.13476e+08},      {"ry.k.Rz", 1.52358e+10},
      {"rz.k.Dx", 3.09402e+09},      {"rz.k.Dy", 3.37736e+10},      {"rz.k.Dz", 2.16259e+09},      {"rz.k.Rx", 8.64686e+06},
      {"rz.k.Ry", 9.61924e+06},      {"hexapod.k.Dx", 1.26679e+07}, {"hexapod.k.Dy", 1.16379e+07}, {"hexapod.k.Dz", 8.8979e+07},
      {"hexapod.k.Rx", 1.81952e+06}, {"hexapod.k.Ry", 1.32431e+06}, {"hexapod.k.Rz", 254924}};
  for (const auto& [name, value] : stiffnesses) model::SetParameter(current, model::FindParameter(current, name), value);
  model::SetEffects(current, {model::ParseEffect("payload@hexapod:mass=5.55835,x=0.0296012,y=-0.0407305,z=0.0463481", nominal)});
  std::vector<LoopStep> history = {{"the loop's rounds", "", comparison.Error(current)}};
  ASSERT_GT(history.front().error, 1.1 * floor);
  const auto moved = RelocateAsTheLoopDoes(nominal, c, comparison, &current, &history);
  ASSERT_EQ(moved, std::vector<std::string>{"payload@hexapod -> extra-body@hexapod"});
  ASSERT_EQ(current.effects.size(), 1u);
  EXPECT_EQ(current.effects[0].name + "@" + current.effects[0].location, "extra-body@hexapod");
  EXPECT_NEAR(current.effects[0].parameters.at("mass"), 3.3, 0.2);
  // Its local mode where the body's is (215 Hz), not where the start put it (300 Hz).
  EXPECT_NEAR(model::FindEffectDefinition("extra-body").local_modes_hz(current.effects[0])[0], 215, 15);
  EXPECT_LT(history.back().error, 1.05 * floor);
}

// A payload is also refitted in its place from its mass at the host's centre of mass. Seed 82315 of
// eval_loop (600 Hz band, 591 points): a 7 kg payload 115 mm above the hexapod and a 0.52 ms delay. The
// rounds fitted the payload at 5.9 kg, 33-40 mm off-axis and 13 mm below, 4.9x the floor, and no
// diagnosis moved it; started again from 5.9 kg at the centre, it is the 7 kg payload at 115 mm.
TEST(RelocateEffects, StartsAPayloadAgainFromItsMassAtTheCentre) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 82315, synthetic::EvalLoopCaseOptions(2, 600, 591));
  ASSERT_EQ(c.effects.size(), 2u);
  ASSERT_EQ(c.effects[0].name + "@" + c.effects[0].location, "payload@hexapod");
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const double floor = comparison.CalcNoiseFloor().floor;
  // The rounds' effects, fitted with the stiffnesses from the model as given: the basin they stopped in.
  const std::vector<model::Effect> rounds = {model::ParseEffect("delay@acquisition:tau=0.00053", nominal),
                                             model::ParseEffect("payload@hexapod:mass=5.87,x=-0.0327,y=0.0395,z=-0.0136", nominal)};
  model::ModelSpec current = FitEffects(nominal, comparison, rounds, LoopOptions().diagnose.params, RoundsFitOptions()).spec;
  std::vector<LoopStep> history = {{"the loop's rounds", "", comparison.Error(current)}};
  ASSERT_GT(history.front().error, 3 * floor);
  const auto moved = RelocateAsTheLoopDoes(nominal, c, comparison, &current, &history);
  ASSERT_EQ(moved, std::vector<std::string>{"payload@hexapod -> payload@hexapod (started again)"});
  EXPECT_EQ(history.back().action, "refit payload@hexapod from another start in its place");
  const auto payload = std::find_if(current.effects.begin(), current.effects.end(), [](const model::Effect& e) { return e.name == "payload"; });
  ASSERT_NE(payload, current.effects.end());
  EXPECT_NEAR(payload->parameters.at("mass"), 7.0, 0.5);
  EXPECT_NEAR(payload->parameters.at("z"), 0.115, 0.01);
  EXPECT_LT(history.back().error, 1.15 * floor);
}

// An extra body is also refitted as its rigid limit in its place, above the floor too. Seed 82343 of
// eval_loop (three effects, 600 Hz band, 865 points): a 0.88 ms delay, a Dx-Ry coupling of the hexapod
// and a 9.7 kg payload 144 mm above it. The rounds took the payload for an extra body of 10.2 kg at
// 137 mm with a joint far stiffer than the band (its modes above 2 kHz), 2.4x the floor beside the right
// delay and coupling: the body's own rotary inertia is not in the data. As the payload, at the floor.
// (The delay and the coupling are given with the model here, so that only the body is relocated, for
// time.)
TEST(RelocateEffects, RefitsAStiffExtraBodyAsItsRigidLimitAboveTheFloor) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 82343, synthetic::EvalLoopCaseOptions(3, 600, 865));
  ASSERT_EQ(c.effects.size(), 3u);
  ASSERT_EQ(c.effects[2].name + "@" + c.effects[2].location, "payload@hexapod");
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const double floor = comparison.CalcNoiseFloor().floor;
  const std::vector<model::Effect> given = {model::ParseEffect("delay@acquisition:tau=0.00087079", nominal),
                                            model::ParseEffect("coupled-stiffness@hexapod.Dx-Ry:k=1602901", nominal)};
  model::ModelSpec as_given = nominal;
  model::SetEffects(as_given, given);
  std::vector<model::Effect> rounds = given;
  rounds.push_back(model::ParseEffect("extra-body@hexapod:mass=10.167,k=1783351824,kr=30604013125288,z=0.13696", nominal));
  model::ModelSpec current = FitEffects(nominal, comparison, rounds, LoopOptions().diagnose.params, RoundsFitOptions()).spec;
  std::vector<LoopStep> history = {{"the loop's rounds", "", comparison.Error(current)}};
  ASSERT_GT(history.front().error, 2 * floor);
  const auto moved = RelocateAsTheLoopDoes(as_given, c, comparison, &current, &history);
  ASSERT_NE(std::find(moved.begin(), moved.end(), "extra-body@hexapod -> payload@hexapod"), moved.end());
  const auto payload = std::find_if(current.effects.begin(), current.effects.end(), [](const model::Effect& e) { return e.name == "payload"; });
  ASSERT_NE(payload, current.effects.end());
  EXPECT_NEAR(payload->parameters.at("mass"), 9.7, 0.5);
  EXPECT_NEAR(payload->parameters.at("z"), 0.144, 0.01);
  EXPECT_LT(history.back().error, 1.1 * floor);
}

// An extra body's start in its place with its rocking modes at the centre of the worst band
// (model::EffectDefinition::starts_in_place, which the relocation step refits from). Seed 82614 of
// eval_loop (two effects, 600 Hz band, 916 points): the hexapod's stiffness centre 95 mm below the
// model's and a 3.7 kg body on it, its translation mode at 253 Hz and its rocking at 310 Hz. The rounds
// found both, but fitted the body's joint rigid in rocking (kr 1.8e11 Nm/rad): 4.77x the floor, 84 % of
// the error in 281-354 Hz, and no start of the relocation step came down from there. From the rocking
// start, the body is the truth's. (RelocateEffects on this state, 100 s, moves the body there: 1.03x.
// The start is refitted here from the nominal stiffnesses only, for time.)
TEST(RelocateEffects, StartsAnExtraBodysRockingAtTheWorstBand) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 82614, synthetic::EvalLoopCaseOptions(2, 600, 916));
  ASSERT_EQ(Keys(c.effects), (std::vector<std::string>{"joint-offset@hexapod", "extra-body@hexapod"}));
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const double floor = comparison.CalcNoiseFloor().floor;
  const model::Effect offset = model::ParseEffect("joint-offset@hexapod:dx=-0.00376,dy=0.00617,dz=-0.09928", nominal);
  const model::Effect rigid = model::ParseEffect("extra-body@hexapod:mass=3.658,k=9.2938e6,kr=1.8287e11,z=0.05535", nominal);
  const std::vector<std::string> params = LoopOptions().diagnose.params;
  const model::ModelSpec rounds = FitEffects(nominal, comparison, {offset, rigid}, params, RoundsFitOptions()).spec;
  ASSERT_GT(comparison.Error(rounds), 4 * floor);
  // Its worst band is where the body's rocking is missing.
  const model::PlaceBand band = PlaceBandOf(comparison, rounds);
  ASSERT_TRUE(band.worst_centre_hz);
  EXPECT_NEAR(*band.worst_centre_hz, 315, 10);
  const model::EffectDefinition& definition = model::FindEffectDefinition("extra-body");
  const std::vector<model::Effect> starts = definition.starts_in_place(rounds.effects[1], band);
  ASSERT_EQ(starts.size(), 3u);
  const model::ModelSpec rocking = FitEffects(nominal, comparison, {offset, starts[2]}, params, RoundsFitOptions()).spec;
  const model::Effect& body = rocking.effects[1];
  EXPECT_NEAR(body.parameters.at("mass"), 3.74, 0.2);
  const std::vector<double> modes_hz = definition.local_modes_hz(body);
  EXPECT_NEAR(modes_hz[0], 253, 10);
  EXPECT_NEAR(modes_hz[1], 310, 10);
  EXPECT_LT(comparison.Error(rocking), 1.1 * floor);
  EXPECT_LT(DistanceToTruth(rocking, c), 0.01);
}

// The right effects beside stiffnesses in the wrong basin come to the floor refitted in band stages from
// the model as given. Seed 82354 of eval_loop (two effects, 150 Hz band, 708 points): a Dy-Rx coupling
// of the hexapod (1.93e6 N/rad) and a 0.34 ms delay. Fitted with them on the whole band at once from the
// model as given, the stiffnesses stop at 1.8x the floor (the loop's rounds held them at 1.6x and added
// two more effects); in band stages, at the floor with the truth's values.
TEST(RefitInBandStages, TakesTheRightEffectsOutOfAStiffnessBasin) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 82354, synthetic::EvalLoopCaseOptions(2, 150, 708));
  ASSERT_EQ(c.effects.size(), 2u);
  ASSERT_EQ(c.effects[0].name + "@" + c.effects[0].location, "coupled-stiffness@hexapod.Dy-Rx");
  ASSERT_EQ(c.effects[1].name + "@" + c.effects[1].location, "delay@acquisition");
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const double floor = comparison.CalcNoiseFloor().floor;
  const std::vector<model::Effect> rounds = {model::ParseEffect("coupled-stiffness@hexapod.Dy-Rx:k=1988863", nominal),
                                             model::ParseEffect("delay@acquisition:tau=0.00034371", nominal)};
  model::ModelSpec current = FitEffects(nominal, comparison, rounds, LoopOptions().diagnose.params, RoundsFitOptions()).spec;
  std::vector<LoopStep> history = {{"the rounds' refit", "", comparison.Error(current)}};
  ASSERT_GT(history.front().error, 1.5 * floor);
  ASSERT_TRUE(RefitInBandStages(nominal, c.measurement, comparison, LoopOptions(), &current, &history));
  EXPECT_EQ(history.back().action, "refit in band stages from the model as given");
  EXPECT_LT(history.back().error, 1.06 * floor);
  ASSERT_EQ(current.effects.size(), 2u);
  EXPECT_NEAR(current.effects[0].parameters.at("k"), 1.93e6, 0.1e6);
  EXPECT_NEAR(current.effects[1].parameters.at("tau"), 0.34e-3, 0.02e-3);
  // At its own optimum it is not taken again: nothing changes.
  const model::ModelSpec before = current;
  EXPECT_FALSE(RefitInBandStages(nominal, c.measurement, comparison, LoopOptions(), &current, &history));
  EXPECT_EQ(history.size(), 2u);
  EXPECT_EQ(current.effects, before.effects);
}

// A first fit near the floor fitted again from several starts. Seed 82679 of eval_loop (one effect, 600 Hz
// band, 625 points): ty.Dy a spring of 1.14e8 N/m instead of a rigid drive, visibility 1.5. The first fit
// in band stages stops at 1.17x the floor with the granite's Dy spring 15x soft, standing in for the
// drive, and the servo fitted from there stays at 1.15x, so no round adds it; from random starts around
// the model as given the stiffnesses reach another basin (the granite's Dy at the truth's, ry's soft in
// its place), and the servo from there reaches the floor at the truth's k.
TEST(FitFromSeveralStarts, FindsTheBasinAWeakServoShowsIn) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 82679, synthetic::EvalLoopCaseOptions(1, 600, 625));
  ASSERT_EQ(Keys(c.effects), std::vector<std::string>{"servo-stiffness@ty.Dy"});
  const LoopOptions options;
  const auto comparison = compare::Comparison::Create(nominal, c.measurement, options.diagnose.comparison);
  const double floor = comparison.CalcNoiseFloor().floor;
  // The loop's first fit.
  model::ModelSpec current = nominal;
  fit::FitModelWithBandContinuation(current, c.measurement, options.diagnose.comparison, comparison,
                                    model::MatchParameters(current, options.diagnose.params), options.fit);
  std::vector<LoopStep> history = {{"fit", "", comparison.Error(current)}};
  ASSERT_GT(history.front().error, 1.1 * floor);
  ASSERT_LT(history.front().error, kBandStagesTimesFloor * floor);
  const model::Effect servo = model::ParseEffect("servo-stiffness@ty.Dy", nominal);
  const auto servo_from = [&](const model::ModelSpec& start) {
    return FitEffects(start, comparison, {servo}, options.diagnose.params, RoundsFitOptions()).spec;
  };
  EXPECT_GT(comparison.Error(servo_from(current)), 1.1 * floor);  // the basin the servo does not show in
  ASSERT_TRUE(FitFromSeveralStarts(nominal, comparison, options, &current, &history));
  EXPECT_EQ(history.back().action, "fit from several starts");
  EXPECT_LT(history.back().error, 0.97 * history.front().error);
  EXPECT_EQ(comparison.Error(current), history.back().error);
  const model::ModelSpec with_servo = servo_from(current);
  std::cout << "first fit " << history.front().error / floor << "x the floor, from several starts "
            << history.back().error / floor << "x, the servo from there " << comparison.Error(with_servo) / floor << "x\n";
  EXPECT_LT(comparison.Error(with_servo), 1.06 * floor);
  EXPECT_LT(DistanceToTruth(with_servo, c), 0.005);
  EXPECT_NEAR(with_servo.effects.at(0).parameters.at("k"), 1.14e8, 0.05e8);
  // Not taken again from where it ended (the same starts reach the same model), and not tried outside
  // its range: nothing changes.
  const model::ModelSpec before = current;
  EXPECT_FALSE(FitFromSeveralStarts(nominal, comparison, options, &current, &history));
  std::vector<LoopStep> far = {{"fit", "", 2.5 * floor}};
  EXPECT_FALSE(FitFromSeveralStarts(nominal, comparison, options, &current, &far));
  // Nor with one start (the step left out), where the starts would lower this history's error.
  LoopOptions one_start = options;
  one_start.first_fit_starts = 1;
  std::vector<LoopStep> near = {{"fit", "", history.front().error}};
  EXPECT_FALSE(FitFromSeveralStarts(nominal, comparison, one_start, &current, &near));
  EXPECT_EQ(history.size(), 2u);
  EXPECT_EQ(far.size(), 1u);
  EXPECT_EQ(near.size(), 1u);
  for (const auto& p : model::ListParameters(before)) {
    EXPECT_EQ(model::GetParameter(current, p), model::GetParameter(before, p)) << p.name;
  }
}

// A round's next candidate fitted beside its leader from the model as given. Seed 82314 of eval_loop (two
// effects, 150 Hz band, 851 points): a 6.2 kg payload 128 mm above the hexapod's centre of mass and a
// loss factor of 0.043 in rz. The first round ranks the payload first, an extra body of the hexapod
// second and the loss factor third (eta 0.078). Fitted beside the payload from the payload's model (its
// stiffnesses bent for the missing loss factor: rz's Dx 40x too soft), the loss factor stays far above
// the floor, and a loop went on to add three other effects; fitted together with the payload from the
// model as given, it is at the floor near the truth's eta.
TEST(TryRunnersUpFromAsGiven, FitsTheLossFactorTheBentStiffnessesHold) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 82314, synthetic::EvalLoopCaseOptions(2, 150, 851));
  ASSERT_EQ(Keys(c.effects), (std::vector<std::string>{"payload@hexapod", "structural-damping@rz"}));
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const double floor = comparison.CalcNoiseFloor().floor;
  DiagnoseSummary diagnosis;
  diagnosis.candidates = {CandidateOf("payload@hexapod:mass=6.1701,x=7.74e-06,y=-1.09e-06,z=0.28017", -42896),
                          CandidateOf("extra-body@hexapod:mass=6.19,k=9.9e13,kr=3.9e9,z=0.282", -42790),
                          CandidateOf("structural-damping@rz:eta=0.078", -33047)};
  // The loop's state after the round: the payload as the diagnosis fitted it (the refit kept it), beside
  // stiffnesses fitted for it.
  model::ModelSpec with_payload =
      FitEffects(nominal, comparison, {diagnosis.candidates[0].effect}, LoopOptions().diagnose.params, RoundsFitOptions()).spec;
  model::SetEffects(with_payload, {diagnosis.candidates[0].effect});
  const std::vector<LoopStep> history_with_payload = {{"add payload@hexapod", "", comparison.Error(with_payload)}};
  ASSERT_GT(history_with_payload.back().error, kBandStagesTimesFloor * floor);
  // From the payload's model, the loss factor stays in the bent stiffnesses' basin, above the floor
  // (2.0x until the weights took a raw SNR at 1 / cap at least; 1.36x since, docs/error-metric.md §3).
  const model::ModelSpec from_state = FitEffects(model::BaseOf(with_payload), comparison,
                                                 {with_payload.effects[0], diagnosis.candidates[2].effect},
                                                 LoopOptions().diagnose.params, RoundsFitOptions()).spec;
  EXPECT_GT(comparison.Error(from_state), kDoneTimesFloor * floor);

  model::ModelSpec current = with_payload;
  std::vector<LoopStep> history = history_with_payload;
  const auto added = TryRunnersUpFromAsGiven(nominal, comparison, LoopOptions(), diagnosis, {}, &current, &history);
  ASSERT_TRUE(added);
  EXPECT_EQ(added->name + "@" + added->location, "structural-damping@rz");
  ASSERT_EQ(history.size(), 3u);
  EXPECT_EQ(history[1].action, "add structural-damping@rz beside payload@hexapod (fitted together from the model as given)");
  EXPECT_EQ(history[2].action, "refit");
  EXPECT_LE(history[2].error, history[1].error);
  EXPECT_EQ(history[2].error, comparison.Error(current));
  EXPECT_LT(history.back().error, 1.06 * floor);
  EXPECT_EQ(Keys(current.effects), Keys(c.effects));
  // Fits of the two at the floor (from different starts and routes) put eta between 0.043 and 0.051.
  EXPECT_NEAR(added->parameters.at("eta"), 0.043, 0.01);
  EXPECT_LT(DistanceToTruth(current, c), 0.01);

  // Not tried: the leader's mimics at its place, a candidate that does not help, one dropped before.
  const auto nothing_changes = [&](const DiagnoseSummary& d, const std::set<std::string>& dropped) {
    model::ModelSpec unchanged = with_payload;
    std::vector<LoopStep> steps = history_with_payload;
    EXPECT_FALSE(TryRunnersUpFromAsGiven(nominal, comparison, LoopOptions(), d, dropped, &unchanged, &steps));
    EXPECT_EQ(steps.size(), 1u);
    EXPECT_EQ(unchanged.effects, with_payload.effects);
  };
  nothing_changes(diagnosis, {"structural-damping@rz"});
  diagnosis.candidates[2].delta_bic = 12;
  nothing_changes(diagnosis, {});
}

// A round's next candidate fitted beside its leader started again in its place. Seed 82536 of eval_loop
// (two effects, 150 Hz band, 538 points): a servo of ry.Ry (4.83e7 Nm/rad) and a 2.5 kg body 50 mm
// above the hexapod's centre of mass with its local mode at 213 Hz, above the band. The first round
// adds the body as 4.2 kg on a joint rigid in translation (k 8.8e13 N/m) with a rocking mode in the
// band (2.85x the floor). The servo fitted beside that body from the model as given stopped at 1.11x,
// above the round threshold, and the loop went on to add a correction of h7 and ended 0.0225 off the
// noise-free truth. From the body's other start of its kind, its modes above the band
// (model::EffectDefinition::starts_in_place), the pair reaches the floor, and refitted on all
// frequencies the truth.
TEST(TryRunnersUpFromAsGiven, StartsTheLeaderAgainWhereItsFitLeftNoSlope) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 82536, synthetic::EvalLoopCaseOptions(2, 150, 538));
  ASSERT_EQ(Keys(c.effects), (std::vector<std::string>{"servo-stiffness@ry.Ry", "extra-body@hexapod"}));
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const double floor = comparison.CalcNoiseFloor().floor;
  DiagnoseSummary diagnosis;
  diagnosis.candidates = {CandidateOf("extra-body@hexapod:mass=4.2432,k=8.8476e13,kr=13177,z=0.10964", -1000),
                          CandidateOf("servo-stiffness@ry.Ry:k=5e7,zeta=0.1", -1000)};
  model::ModelSpec current =
      FitEffects(nominal, comparison, {diagnosis.candidates[0].effect}, LoopOptions().diagnose.params, RoundsFitOptions()).spec;
  model::SetEffects(current, {diagnosis.candidates[0].effect});
  std::vector<LoopStep> history = {{"add extra-body@hexapod", "", comparison.Error(current)}};
  ASSERT_GT(history.back().error, kBandStagesTimesFloor * floor);  // the step runs

  const auto added = TryRunnersUpFromAsGiven(nominal, comparison, LoopOptions(), diagnosis, {}, &current, &history);
  for (const LoopStep& step : history) std::cout << step.action << ": " << step.error / floor << "x the floor\n";
  ASSERT_TRUE(added);
  EXPECT_EQ(Keys(current.effects), (std::vector<std::string>{"extra-body@hexapod", "servo-stiffness@ry.Ry"}));
  ASSERT_EQ(history.size(), 3u);
  EXPECT_LE(history[1].error, LoopOptions().rounds_above_times_floor * floor);
  EXPECT_LT(history.back().error, 1.02 * floor);
  // The body's mass and translation mode, and the servo, where the truth has them.
  EXPECT_NEAR(current.effects[0].parameters.at("mass"), 2.47, 0.15);
  EXPECT_NEAR(model::FindEffectDefinition("extra-body").local_modes_hz(current.effects[0])[0], 213, 10);
  EXPECT_NEAR(current.effects[1].parameters.at("k"), 4.83e7, 0.1 * 4.83e7);
  EXPECT_LT(DistanceToTruth(current, c), 0.005);
}

// A cable between the granite and the hexapod (outside the catalogue; eval_loop's seed 5023): a loss
// factor in the hexapod lowers the error, but the model stays clearly above the floor, so the loop
// does not confirm it and says where the error is. (Only loss factors are tried, in one round, for time;
// with the whole catalogue the loop ends at 1.67x the floor with the same effect.)
TEST(Loop, DoesNotConfirmAnEffectThatLeavesTheModelAboveTheFloor) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectOptions o = synthetic::EvalLoopCaseOptions(1, 150, 300);
  o.min_visibility = 8.0;
  const auto c = synthetic::MakeOutsideCatalogueCase(nominal, 5023, "cable", o);
  LoopOptions options = Options({"structural-damping"});
  options.max_rounds = 1;
  options.progress = [](const std::string& line) { std::cout << line << std::endl; };
  const LoopSummary summary = RunLoop(nominal, c.measurement, options);
  std::cout << summary.HistoryTable();
  ASSERT_TRUE(summary.noise_floor.known);
  ASSERT_GT(summary.history.back().error, 1.3 * summary.noise_floor.floor);
  ASSERT_FALSE(summary.effects_added.empty());
  EXPECT_FALSE(summary.confirmed);
  EXPECT_EQ(summary.conclusion.rfind("Not explained: the model ends at", 0), 0u) << summary.conclusion;
  EXPECT_NE(summary.conclusion.find("Hz ("), std::string::npos) << summary.conclusion;  // a band
  EXPECT_NE(summary.conclusion.find("are not confirmed"), std::string::npos) << summary.conclusion;
  EXPECT_EQ(summary.final_model.history.back().step, "loop: effects not confirmed (the model is not at the noise floor)");
  // Where the cable acts: the first fit's two worst bands, named after the effects that may stand in for
  // it; one of them is one of the bands that hold half of the cable's change.
  ASSERT_EQ(summary.missing_bands.size(), 2u);
  EXPECT_NE(summary.conclusion.find("Before them the error was largest in"), std::string::npos) << summary.conclusion;
  bool held = false;
  for (const auto& named : summary.missing_bands) {
    for (const auto& b : c.bands) held = held || std::abs(b.centre_hz() / named.band.centre_hz() - 1) < 1e-9;
  }
  EXPECT_TRUE(held) << summary.conclusion;
  // The raw channels: the cable acts on the whole hexapod, and no channel stands out from the others
  // (the worst, h1, at 2.0x the floor and within 1.5x of the median channel): none is named.
  ASSERT_FALSE(summary.final_channels.empty());
  EXPECT_GT(summary.final_channels[0].times_floor, 1.3);
  EXPECT_LT(summary.final_channels[0].times_median, kChannelStandsOut);
  EXPECT_EQ(summary.conclusion.find("; channels "), std::string::npos) << summary.conclusion;
}

// Two couplings of a joint that its offset makes are merged once more after a rigid limit is taken:
// seed 82164 of eval_loop (rz's stiffness centre 139 mm off and an 8.3 kg payload 67 mm above the
// hexapod's centre of mass, 5-150 Hz, 509 frequencies). The rounds add an extra body on the hexapod and
// rz's Dx-Ry and Dy-Rx couplings (1.06x the floor); the merge beside the extra body stays above that,
// and the body's rigid limit, a payload, is taken (1.05x, 0.0097 off the noise-free truth; since
// f845e42 by the relocation step near the floor, the merge following the move). Beside the
// payload the merge takes the offset for the couplings: the model is the truth's, at the floor. (At
// 1.059x, within the round threshold, the merge into the offset beside what is left of a coupling is not
// tried: there it took rz's offset and a Dx-Ry coupling the data do not hold, 2 % lower.)
// (Extra bodies and couplings tried in the rounds. The loop is resumed from the model its rounds left,
// LoopSummary::after_rounds of this case's loop written to tests/diagnose/data, for time: the steps
// after the rounds are what is tested; the whole loop takes 80 s alone.)
TEST(Loop, MergesTheCouplingsAnOffsetMakesAgainAfterARigidLimit) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 82164, synthetic::EvalLoopCaseOptions(2, 150, 509));
  ASSERT_EQ(Keys(c.effects), (std::vector<std::string>{"joint-offset@rz", "payload@hexapod"}));
  LoopOptions options = Options({"extra-body", "coupled-stiffness"});
  options.max_rounds = LoopOptions{}.max_rounds;
  LoopSummary summary;
  ASSERT_NO_FATAL_FAILURE(ResumeStoredLoop(
      c, options, "loop_82164_after_rounds.toml",
      {"extra-body@hexapod", "coupled-stiffness@rz.Dx-Ry", "coupled-stiffness@rz.Dy-Rx"}, &summary));
  const auto step = [&](const std::string& action) {
    return std::find_if(summary.history.begin(), summary.history.end(), [&](const LoopStep& s) { return s.action == action; });
  };
  // The body becomes its rigid limit in the relocation step near the floor (a move to the payload),
  // else in the rigid-limit step.
  auto limit = step("move extra-body@hexapod to payload@hexapod");
  if (limit == summary.history.end()) limit = step("take payload@hexapod for extra-body@hexapod (its rigid limit)");
  const auto merge = step("merge coupled-stiffness@rz.Dx-Ry, coupled-stiffness@rz.Dy-Rx into joint-offset@rz");
  ASSERT_EQ(summary.history[1].action, "resumed");
  ASSERT_NE(limit, summary.history.end());
  ASSERT_NE(merge, summary.history.end());
  EXPECT_LT(limit, merge);
  EXPECT_EQ(Keys(summary.final_model.effects), (std::vector<std::string>{"payload@hexapod", "joint-offset@rz"}));
  EXPECT_TRUE(summary.confirmed);
  EXPECT_LT(DistanceToTruth(summary.final_model, c), 0.005);
}

// A coupling the rounds find is also fitted as the joint offset that makes it: seed 82136 of eval_loop
// (rz's stiffness centre 100 mm above where the model puts it, beside a coupling of the hexapod's
// Dx-Ry, 5-150 Hz, 619 frequencies). The first round adds the hexapod's coupling (1.22x the floor). In
// the second, the offset's own starts (dz = 0 and +-0.1 m) ended at dz = 2 mm (0.0406), and rz's Dy-Rx
// coupling, which the offset makes, was added in its place: 1.05x the floor, 0.0079 off the noise-free
// truth. Fitted from what that coupling makes of it (dz = -k / k_Dy), the offset ranks first and the
// model is the truth's. (The whole catalogue: with effects left out, the offset's own starts reached it.
// The loop is resumed from the model its first round left, LoopSummary::after_rounds of this case's
// loop with one round, written to tests/diagnose/data, for time: the second round is what is tested.)
TEST(Loop, FitsTheJointOffsetACouplingStandsFor) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 82136, synthetic::EvalLoopCaseOptions(2, 150, 619));
  ASSERT_EQ(Keys(c.effects), (std::vector<std::string>{"coupled-stiffness@hexapod.Dx-Ry", "joint-offset@rz"}));
  LoopSummary summary;
  ASSERT_NO_FATAL_FAILURE(
      ResumeStoredLoop(c, LoopOptions{}, "loop_82136_after_round_1.toml", {"coupled-stiffness@hexapod.Dx-Ry"}, &summary));
  ASSERT_EQ(Keys(summary.final_model.effects), (std::vector<std::string>{"coupled-stiffness@hexapod.Dx-Ry", "joint-offset@rz"}));
  const double dz = c.truth.joints[model::FindJoint(c.truth, "rz")].origin_W.z() - nominal.joints[model::FindJoint(nominal, "rz")].origin_W.z();
  EXPECT_NEAR(summary.final_model.effects[1].parameters.at("dz"), dz, 0.01);
  EXPECT_TRUE(summary.confirmed);
  EXPECT_LT(DistanceToTruth(summary.final_model, c), 0.005);
}

// A weak servo beside a delay, near the floor (seed 83132 of eval_loop, two effects, 5-600 Hz, 720
// frequencies: ry.Ry a spring of 4.8e7, visibility 1.9; a 0.43 ms delay). The first round adds the
// delay (1.12x the floor), the second starts with the refit in band stages (1.09x). There the baseline's
// stiffnesses have absorbed the drive's mode: no start of the servo's free fits came below the
// baseline, a coupling of the hexapod led the diagnosis, did not earn its place, and the loop ended at
// 1.09x with the delay alone, 0.014 off the noise-free truth. From the minimum of the profile of the
// servo's k (ServoProfileStarts) the servo is refined and leads, and the model is the truth's. (Resumed
// from the model the first round left, LoopSummary::after_rounds of this case's loop with one round,
// in tests/diagnose/data; checked to fail with the profile's starts left out.)
TEST(Loop, NamesAWeakServoBesideADelayFromTheProfileOfItsStiffness) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 83132, synthetic::EvalLoopCaseOptions(2, 600, 720));
  ASSERT_EQ(Keys(c.effects), (std::vector<std::string>{"servo-stiffness@ry.Ry", "delay@acquisition"}));
  LoopSummary summary;
  ASSERT_NO_FATAL_FAILURE(ResumeStoredLoop(c, LoopOptions{}, "loop_83132_after_round_1.toml", {"delay@acquisition"}, &summary));
  ASSERT_EQ(Keys(summary.final_model.effects), (std::vector<std::string>{"delay@acquisition", "servo-stiffness@ry.Ry"}));
  const double truth_k = c.truth.joints[model::FindJoint(c.truth, "ry")].stiffness[4];
  EXPECT_NEAR(std::log(summary.final_model.effects[1].parameters.at("k") / truth_k), 0.0, std::log(1.2));
  EXPECT_TRUE(summary.confirmed);
  EXPECT_LT(DistanceToTruth(summary.final_model, c), 0.005);
}

// Between 1.1x and 1.2x the noise floor a round still runs (LoopOptions::rounds_above_times_floor):
// seed 9006 of eval_loop (a servo stiffness of ry.Ry, 5-150 Hz, 820 frequencies) is absorbed by the
// first stiffness fit at 1.16x the floor, 0.022 off the noise-free truth; the round adds the servo
// stiffness and the model ends within 0.01 of the truth. With rounds only above 1.2x (the confirmation
// threshold) the loop stops after the first fit, off the truth. (Servo stiffnesses and loss factors
// tried, for time.)
TEST(Loop, RunsARoundBetweenTheRoundAndTheConfirmationThresholds) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectCase c;
  ASSERT_NO_FATAL_FAILURE(MakeEvalLoopCase(9006, 820, "servo-stiffness@ry.Ry", &c, 150));
  LoopOptions options = Options({"servo-stiffness", "structural-damping"});
  options.max_rounds = 1;
  options.turned_channel_deg = 0;
  options.rounds_above_times_floor = kDoneTimesFloor;
  const LoopSummary stopped = RunLoop(nominal, c.measurement, options);
  std::cout << stopped.HistoryTable();
  ASSERT_TRUE(stopped.noise_floor.known);
  ASSERT_EQ(stopped.history.size(), 2u);  // as given, fit
  const double fit_times_floor = stopped.history.back().error / stopped.noise_floor.floor;
  ASSERT_GT(fit_times_floor, LoopOptions{}.rounds_above_times_floor);
  ASSERT_LE(fit_times_floor, kDoneTimesFloor);
  EXPECT_GT(DistanceToTruth(stopped.final_model, c), 0.015);

  options.rounds_above_times_floor = LoopOptions{}.rounds_above_times_floor;
  const LoopSummary summary = RunLoop(nominal, c.measurement, options);
  std::cout << summary.HistoryTable();
  ASSERT_EQ(summary.effects_added.size(), 1u);
  EXPECT_EQ(summary.effects_added[0].rfind("servo-stiffness@ry.Ry:", 0), 0u) << summary.effects_added[0];
  EXPECT_TRUE(summary.confirmed);
  EXPECT_LE(summary.history.back().error, 1.05 * summary.noise_floor.floor);
  EXPECT_LE(DistanceToTruth(summary.final_model, c), 0.01);
}

// A round whose candidates find no effect against the better model the diagnosis found without one
// (its baseline refitted from the leaders' parameters) is followed by a round from that model: seed
// 11002 of eval_loop (a payload on rz, 5-150 Hz, 395 frequencies): the first fit ends at 1.55x the
// floor, the diagnosis' baseline at 1.22x, where the payload fitted from the 1.55x model stays above
// it; from the 1.22x model the next round finds the payload and ends at the floor and the truth.
// (Payloads tried, for time; with extra bodies too the history is the same.)
TEST(Loop, TriesTheCandidatesAgainFromTheDiagnosisBaseline) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectCase c;
  ASSERT_NO_FATAL_FAILURE(MakeEvalLoopCase(11002, 395, "payload@rz", &c, 150));
  LoopOptions options = Options({"payload"});
  options.turned_channel_deg = 0;
  // The first fit's several starts (FitFromSeveralStarts) reach that 1.22x model on their own, and the
  // first round then adds the payload (1.04x): left out here, so that the round is tested.
  options.first_fit_starts = 1;
  options.progress = [](const std::string& line) { std::cout << line << std::endl; };
  const LoopSummary summary = RunLoop(nominal, c.measurement, options);
  std::cout << summary.HistoryTable();
  ASSERT_TRUE(summary.noise_floor.known);
  ASSERT_GE(summary.history.size(), 4u);
  EXPECT_EQ(summary.history[2].action, "refit (the diagnosis' baseline)");
  EXPECT_GT(summary.history[2].error, options.rounds_above_times_floor * summary.noise_floor.floor);
  ASSERT_EQ(summary.effects_added.size(), 1u);
  EXPECT_EQ(summary.effects_added[0].rfind("payload@rz:", 0), 0u) << summary.effects_added[0];
  EXPECT_TRUE(summary.confirmed);
  EXPECT_LE(DistanceToTruth(summary.final_model, c), 0.01);
}

// A tried candidate is kept when the error fell, its delta BIC against the model before (k: the
// parameters added less those removed) is negative, and it removed an effect or brought the error from
// above the round threshold to within it.
TEST(TriedCandidateEarnsPlace, AReplacementOrTheFloorReachedWithNegativeDeltaBic) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const model::Effect servo = model::ParseEffect("servo-stiffness@ry.Ry:k=3e7", nominal);  // 2 parameters
  const model::Effect h9 = model::ParseEffect("sensor-geometry@h9:ry=0.1", nominal);        // 6
  const model::Effect payload = model::ParseEffect("payload@hexapod:mass=5", nominal);      // 4
  const double n = 1000;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(TriedCandidateEarnsPlace(0.0374, 0.0336, servo, {h9}, n, nan));
  EXPECT_TRUE(TriedCandidateEarnsPlace(0.0374, 0.03739, servo, {h9}, n, nan));  // fewer parameters: any fall
  EXPECT_FALSE(TriedCandidateEarnsPlace(0.0374, 0.0374, servo, {h9}, n, nan));  // no fall
  EXPECT_FALSE(TriedCandidateEarnsPlace(0.0374, 0.0336, servo, {}, n, nan));    // nothing removed, no floor
  // Two parameters more (h9's six for the payload's four): ln(1000) = 6.9 each, 13.8 in all; a fall of
  // 1 % gives 1000 ln(0.99^2) = -20.1, one of 0.5 % -10.0.
  EXPECT_TRUE(TriedCandidateEarnsPlace(0.0400, 0.0400 * 0.99, h9, {payload}, n, nan));
  EXPECT_FALSE(TriedCandidateEarnsPlace(0.0400, 0.0400 * 0.995, h9, {payload}, n, nan));
  // Held parameters are not counted: h9 with its turn held adds three, one fewer than the payload removed.
  model::Effect held = h9;
  for (const char* p : {"rx", "ry", "rz"}) model::HoldEffectParameter(&held, p);
  EXPECT_TRUE(TriedCandidateEarnsPlace(0.0400, 0.0400 * 0.9999, held, {payload}, n, nan));
  // Nothing removed: kept where the error crosses the threshold (81706 of eval_loop: 1.062x -> 1.035x
  // the floor with a 1.06x threshold), with two parameters paid for (a fall of 0.5 % does not).
  const double floor = 0.03;
  EXPECT_TRUE(TriedCandidateEarnsPlace(1.062 * floor, 1.035 * floor, servo, {}, n, 1.06 * floor));
  EXPECT_FALSE(TriedCandidateEarnsPlace(1.10 * floor, 1.07 * floor, servo, {}, n, 1.06 * floor));  // still above
  EXPECT_FALSE(TriedCandidateEarnsPlace(1.059 * floor, 1.03 * floor, servo, {}, n, 1.06 * floor));  // within it before
  EXPECT_FALSE(TriedCandidateEarnsPlace(1.0620 * floor, 1.0620 * 0.995 * floor, servo, {}, n, 1.06 * floor));
}

// An effect that stood in for another is replaced by it: a weak servo of ry.Ry (seed 81502 of
// eval_loop: 2.96e7 N/m, 5-600 Hz, 371 frequencies) was taken in a first round for h9's correction
// (2.74x -> 1.17x the floor) in one run, and the servo's candidate beside it lowered the error by 3.2 %
// only, less than a new effect must (the loop stopped there, 0.020 off the noise-free truth). Here h9's
// correction as that round had it is fitted with the truth's stiffnesses (1.40x), and the servo is
// tried in its place from the two fitted together (1.06x): h9's correction is dropped, and the model
// is at the floor and the truth. With the servo in the model, a coupling of ty that lowers its error a
// little replaces nothing (the servo is needed beside it), the model was within the round threshold
// before, and the model is the one before.
TEST(TryCandidateBesideAddedEffects, ReplacesTheEffectAnEarlierOneStoodInFor) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectCase c;
  ASSERT_NO_FATAL_FAILURE(MakeEvalLoopCase(81502, 371, "servo-stiffness@ry.Ry", &c));
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  const auto channels = comparison.CorrectableChannels();
  const double floor = comparison.CalcNoiseFloor().floor;
  const model::Effect h9 = model::ParseEffect("sensor-geometry@h9:dy=-0.0077,dz=-0.0271,ry=-0.0491,rz=0.2903", nominal, channels);
  const model::Effect servo = model::ParseEffect("servo-stiffness@ry.Ry:k=3e7,zeta=0.13", nominal);
  const LoopOptions options = Options({});
  EffectFitOptions eo;
  eo.max_iterations = 50;
  // Fitted with the stiffnesses from the truth's, where the loop's rounds had brought them (from the
  // nominal ones the fit with h9's correction stops at 1.8x the floor).
  const model::ModelSpec start = WithTruthStiffnesses(nominal, c);
  const EffectsFit stood_in = FitEffects(start, comparison, {h9}, options.diagnose.params, eo);
  const EffectsFit both = FitEffects(start, comparison, {stood_in.effects[0], servo}, options.diagnose.params, eo);
  const double before = comparison.Error(stood_in.spec);
  ASSERT_GT(before, options.rounds_above_times_floor * floor);  // a round runs
  ASSERT_LT(comparison.Error(both.spec), before);

  model::ModelSpec current = stood_in.spec;
  std::vector<LoopStep> history = {{"h9's correction", "", before}};
  const auto replaced = TryCandidateBesideAddedEffects(nominal, comparison, options, both.spec, both.effects[1], &current, &history);
  for (const LoopStep& step : history) std::cout << step.action << ": " << step.error / floor << " x the floor\n";
  ASSERT_TRUE(replaced.has_value());
  ASSERT_EQ(*replaced, std::vector<std::string>{"sensor-geometry@h9"});
  ASSERT_EQ(current.effects.size(), 1u);
  EXPECT_EQ(current.effects[0].name + "@" + current.effects[0].location, "servo-stiffness@ry.Ry");
  EXPECT_EQ(history.back().action, "drop sensor-geometry@h9 (not needed)");
  EXPECT_EQ(history.back().error, comparison.Error(current));
  EXPECT_LE(history.back().error, options.rounds_above_times_floor * floor);
  EXPECT_LT(DistanceToTruth(current, c), 0.01);

  // The servo in the model (as the replacement left it), a coupling of ty tried in its place from the
  // two fitted together from there: the coupling lowers the error a little, the servo is still needed
  // beside it, and the model is the one before.
  model::ModelSpec kept = current;
  const double kept_error = comparison.Error(kept);
  std::vector<LoopStep> kept_history = {{"the servo", "", kept_error}};
  model::ModelSpec fitted_base = current;
  model::SetEffects(fitted_base, {});
  const model::Effect coupling = model::ParseEffect("coupled-stiffness@ty.Dx-Ry:k=1e5", nominal);
  const EffectsFit with_coupling = FitEffects(fitted_base, comparison, {current.effects[0], coupling}, options.diagnose.params, eo);
  ASSERT_LT(comparison.Error(with_coupling.spec), kept_error);
  EXPECT_FALSE(TryCandidateBesideAddedEffects(nominal, comparison, options, with_coupling.spec, with_coupling.effects[1], &kept,
                                              &kept_history));
  for (const LoopStep& step : kept_history) std::cout << step.action << ": " << step.error / floor << " x the floor\n";
  ASSERT_EQ(kept_history.size(), 4u);
  EXPECT_EQ(kept_history[1].action, "add coupled-stiffness@ty.Dx-Ry");
  ASSERT_EQ(kept.effects.size(), 1u);
  EXPECT_EQ(kept.effects[0].name, "servo-stiffness");
  EXPECT_EQ(comparison.Error(kept), kept_error);
  EXPECT_EQ(kept_history.back().action, "back to the model before (coupled-stiffness@ty.Dx-Ry neither replaces an effect nor reaches the floor)");
  EXPECT_EQ(kept_history.back().error, kept_error);
}

}  // namespace
}  // namespace stagefit::diagnose
