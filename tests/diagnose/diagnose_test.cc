#include "stagefit/diagnose/diagnose.h"

#include <gtest/gtest.h>

#include <iostream>

#include "stagefit/model/model_file.h"
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

}  // namespace
}  // namespace stagefit::diagnose
