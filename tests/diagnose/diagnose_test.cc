#include "stagefit/diagnose/diagnose.h"

#include <gtest/gtest.h>

#include <iostream>

#include "stagefit/compare/residuals.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/model_spec.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace stagefit::diagnose {
namespace {

DiagnoseOptions QuietOptions() {
  DiagnoseOptions options;
  options.progress = [](const std::string& line) { std::cout << line << std::endl; };
  return options;
}

// A payload hidden in data made by the independent brute-force path is found, at its body, with a
// mass close to the truth, and the error falls to the noise floor.
TEST(Diagnose, FindsAHiddenPayload) {
  model::ModelSpec nominal = model::DefaultModelSpec();
  model::ModelSpec truth = nominal;
  synthetic::HiddenEffectOptions options;
  options.num_effects = 0;
  auto c = synthetic::MakeHiddenEffectCase(nominal, 101, options);
  // Add a known payload to the truth and remake the measurement.
  model::BodySpec b;
  b.name = "mass";
  b.mass_kg = 6.0;
  b.com_W = Eigen::Vector3d(0, 0, 0.05);
  b.inertia_com_W = Eigen::Matrix3d::Identity() * 1e-6;
  c.truth.bodies.push_back(b);
  model::JointSpec j;
  j.name = "mass";
  j.parent = "hexapod";
  j.child = "mass";
  j.origin_W = b.com_W;
  j.imposed = {true, true, true, true, true, true};
  c.truth.joints.push_back(j);
  const Eigen::Vector3d X(0, 0, -0.03);
  auto data = synthetic::CalcBruteForceFrf(c.truth, synthetic::ComplianceTestSensors("hexapod", X),
                                           synthetic::ComplianceTestImpacts("hexapod", X),
                                           c.measurement.frequency_hz, measurement::FrfQuantity::kAccelerance);
  synthetic::AddNoise(data, {0.02, 0.02, 3});
  auto summary = Diagnose(nominal, data, QuietOptions());
  std::cout << summary.BriefReport() << "time " << summary.time_s << " s\n";
  ASSERT_FALSE(summary.candidates.empty());
  EXPECT_TRUE(summary.effect_found);
  EXPECT_EQ(summary.candidates[0].effect.name, "payload");
  EXPECT_EQ(summary.candidates[0].effect.location, "hexapod");
  EXPECT_NEAR(summary.candidates[0].effect.parameters.at("mass"), 6.0, 1.0);
}

// Effect-free data (stiffness scatter and noise only): the baseline fit reaches the noise floor and
// no candidate of the catalogue is claimed.
TEST(Diagnose, ClaimsNothingWithoutAnEffect) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectOptions options;
  options.num_effects = 0;
  auto c = synthetic::MakeHiddenEffectCase(nominal, 7, options);
  auto summary = Diagnose(nominal, c.measurement, QuietOptions());
  std::cout << summary.BriefReport() << "time " << summary.time_s << " s\n";
  const double floor = compare::Comparison::Create(nominal, c.measurement).Error(c.truth);
  EXPECT_LT(summary.error_baseline, 1.05 * floor);
  EXPECT_FALSE(summary.effect_found);
}

// A search on a thinned grid: every candidate is scored on all frequencies, and the result agrees
// with a search on all of them.
TEST(Diagnose, SearchesOnAThinnedGridAndScoresOnAllFrequencies) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectOptions hidden;
  hidden.num_frequencies = 400;
  auto c = synthetic::MakeHiddenEffectCase(nominal, 1004, hidden);
  ASSERT_EQ(c.effects.size(), 1u);
  ASSERT_EQ(c.effects[0].name, "delay");
  DiagnoseOptions options = QuietOptions();
  options.effects = {"delay", "structural-damping"};
  options.max_search_frequencies = 150;
  const auto thinned = Diagnose(nominal, c.measurement, options);
  std::cout << thinned.BriefReport() << "time " << thinned.time_s << " s\n";
  options.max_search_frequencies = 0;
  const auto full = Diagnose(nominal, c.measurement, options);
  std::cout << full.BriefReport() << "time " << full.time_s << " s\n";

  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  ASSERT_EQ(comparison.num_frequencies(), 400);
  for (const Candidate& candidate : thinned.candidates) {
    EXPECT_NEAR(candidate.error_after, comparison.Error(ApplyCandidate(thinned, candidate)), 1e-12 * candidate.error_after)
        << candidate.with;
  }
  const double floor = comparison.Error(c.truth);
  ASSERT_TRUE(thinned.effect_found);
  ASSERT_TRUE(full.effect_found);
  EXPECT_EQ(thinned.candidates[0].effect.name, "delay");
  EXPECT_EQ(full.candidates[0].effect.name, "delay");
  EXPECT_LT(thinned.candidates[0].error_after, 1.5 * floor);
  EXPECT_NEAR(thinned.candidates[0].error_after, full.candidates[0].error_after, 0.02 * full.candidates[0].error_after);
  EXPECT_NEAR(thinned.candidates[0].effect.parameters.at("tau"), full.candidates[0].effect.parameters.at("tau"),
              0.01 * full.candidates[0].effect.parameters.at("tau"));
}

// An extra body whose mass the baseline's stiffnesses have absorbed (softened hexapod joint): added to
// the baseline it overshoots and its fit sheds the mass; started from the model as given, 0.1 m above
// the host, it is found at its body with its mass and height, and the error falls by more than a
// factor 4. Not yet to the floor: the body's rotational stiffness kr (its rocking mode at 351 Hz) is
// left 12x too stiff here (error 0.138, floor 0.041; docs/diagnose.md).
TEST(Diagnose, FindsAnExtraBodyTheBaselineStiffnessesHid) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  auto c = synthetic::MakeHiddenEffectCase(nominal, 1009, {});
  ASSERT_EQ(c.effects.size(), 1u);
  ASSERT_EQ(c.effects[0].name, "extra-body");
  ASSERT_EQ(c.effects[0].location, "hexapod");
  const auto& body = c.truth.bodies[model::FindBody(c.truth, "hidden_body")];
  const auto& host = c.truth.bodies[model::FindBody(c.truth, "hexapod")];
  DiagnoseOptions options = QuietOptions();
  options.effects = {"extra-body"};
  const auto summary = Diagnose(nominal, c.measurement, options);
  std::cout << summary.BriefReport() << "time " << summary.time_s << " s\n";
  const double floor = compare::Comparison::Create(nominal, c.measurement).Error(c.truth);
  ASSERT_TRUE(summary.effect_found);
  const Candidate& best = summary.candidates[0];
  EXPECT_EQ(best.effect.location, "hexapod");
  EXPECT_LT(best.error_after, 0.25 * summary.error_baseline);
  EXPECT_GT(summary.error_baseline, 10 * floor);
  EXPECT_NEAR(best.effect.parameters.at("mass"), body.mass_kg, 0.1 * body.mass_kg);
  EXPECT_NEAR(best.effect.parameters.at("z"), body.com_W.z() - host.com_W.z(), 0.01);
}

// A vertical accelerometer turned by 17 degrees (seed 1023, visibility 18.5 noise standard deviations),
// compared in compliance space. Its direction as the other channels see it is listed first among the
// turned channels, and the correction held there ranks first, at the noise floor. Before the
// element rule of residuals.h and the estimated turns, a joint offset in rz won (0.49 for a floor of
// 0.036): the right correction left the model's exact zeros against noise, and a fitted correction
// stopped in a local minimum. The effects are the channels' and the joint offsets, the one that won
// then (the whole catalogue: eval_diagnose).
TEST(Diagnose, FindsATurnedSensorInComplianceSpace) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  auto c = synthetic::MakeHiddenEffectCase(nominal, 1023, {});
  ASSERT_EQ(c.effects.size(), 1u);
  ASSERT_EQ(c.effects[0].name, "sensor-geometry");
  ASSERT_EQ(c.effects[0].location, "a2z");
  DiagnoseOptions options = QuietOptions();
  options.effects = {"sensor-geometry", "joint-offset"};
  const auto summary = Diagnose(nominal, c.measurement, options);
  std::cout << summary.BriefReport() << "time " << summary.time_s << " s\n";
  const double floor = compare::Comparison::Create(nominal, c.measurement).Error(c.truth);
  ASSERT_FALSE(summary.turned_channels.empty());
  EXPECT_EQ(summary.turned_channels[0].channel, "a2z");
  EXPECT_NEAR(summary.turned_channels[0].angle_deg, 17.0, 1.0);
  ASSERT_TRUE(summary.effect_found);
  const Candidate& best = summary.candidates[0];
  EXPECT_EQ(best.effect.name, "sensor-geometry");
  EXPECT_EQ(best.effect.location, "a2z");
  EXPECT_LT(best.error_after, 1.1 * floor);
}

}  // namespace
}  // namespace stagefit::diagnose
