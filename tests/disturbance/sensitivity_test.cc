#include "stagefit/disturbance/sensitivity.h"

#include <gtest/gtest.h>

#include "stagefit/common/error.h"
#include "stagefit/model/model_file.h"

namespace stagefit::disturbance {
namespace {

TEST(ModelSensitivity, TranslationStageForceStaticallyDeformsOnlyItsJoint) {
  // A force pair inside ty's Dz, far below every mode, deforms that joint alone: everything above ty
  // moves rigidly, so {X} moves relative to the granite by F / k_ty,Dz (2e8 N/m).
  const model::ModelSpec spec = model::DefaultModelSpec();
  const auto channels = ListDisturbanceChannels(spec);
  std::string output;
  for (const auto& o : channels.outputs) {
    if (o.size() >= 3 && o.substr(o.size() - 3) == ".Dz") output = o;
  }
  ASSERT_FALSE(output.empty());
  Eigen::VectorXd f(1);
  f << 0.01;
  const Eigen::VectorXcd h = CalcModelSensitivity(spec, "ty.F.Dz", output, f);
  // At 0.01 Hz the inertia terms are (f / f_1)^2 ~ 1e-7 of the static value.
  EXPECT_NEAR(h(0).real(), 1.0 / 2e8, 1e-6 / 2e8);
  EXPECT_NEAR(h(0).imag(), 0.0, 1e-4 / 2e8);
}

TEST(ModelSensitivity, GroundMotionDoesNotDeformTheStackStatically) {
  const model::ModelSpec spec = model::DefaultModelSpec();
  const auto channels = ListDisturbanceChannels(spec);
  Eigen::VectorXd f(2);
  f << 0.01, 100.0;
  const Eigen::VectorXcd h = CalcModelSensitivity(spec, "ground.Dz", channels.outputs[2], f);
  EXPECT_LT(std::abs(h(0)), 1e-6);   // a rigid translation with the ground
  EXPECT_GT(std::abs(h(1)), 1e-4);   // near the stack's modes the top moves against the granite
}

TEST(ModelSensitivity, UnknownNamesListTheValidOnes) {
  const model::ModelSpec spec = model::DefaultModelSpec();
  try {
    CalcModelSensitivity(spec, "spindle", "X_rel.Dz", Eigen::VectorXd::Ones(1));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("ground.Dx"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace stagefit::disturbance
