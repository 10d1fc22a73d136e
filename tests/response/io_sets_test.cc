#include "stagefit/response/io_sets.h"

#include <gtest/gtest.h>

#include "stagefit/common/error.h"
#include "stagefit/model/model_file.h"
#include "stagefit/response/frf_evaluator.h"

namespace stagefit::response {
namespace {

TEST(IoSets, StandardStudiesHaveTheDocumentedChannels) {
  const auto assembled = model::AssembledModel::Assemble(model::DefaultModelSpec());
  const auto compliance = BuildIoSetSystem(assembled, IoSet::kCompliance);
  EXPECT_EQ(compliance.num_outputs(), 6);
  EXPECT_EQ(compliance.num_inputs(), 6);
  const auto raw = BuildIoSetSystem(assembled, IoSet::kRaw);
  EXPECT_EQ(raw.num_outputs(), 12);
  EXPECT_EQ(raw.num_inputs(), 10);
  const auto stages = BuildIoSetSystem(assembled, IoSet::kStages);
  EXPECT_EQ(stages.num_outputs(), 30);
  ASSERT_EQ(stages.num_inputs(), 3);
  EXPECT_EQ(stages.input_names[2], "ty.hammer.Fz");
  EXPECT_EQ(stages.output_names[0], "granite.Dx");
  const auto disturbance = BuildIoSetSystem(assembled, IoSet::kDisturbance);
  EXPECT_EQ(disturbance.num_outputs(), 6);
  const std::vector<std::string> inputs = {"ground.Dx", "ground.Dy", "ground.Dz", "ty.F.Dz",
                                           "ty.F.Dx",   "rz.F.Dz",   "rz.F.Dx",   "rz.F.Dy"};
  EXPECT_EQ(disturbance.input_names, inputs);
}

TEST(IoSets, RelativeMotionIgnoresStaticGroundTranslation) {
  // A static ground displacement moves the whole stack rigidly: {X} does not move relative to the
  // granite (to rounding: 1e-12 of the compliance-scale response of the joint-force inputs).
  const auto assembled = model::AssembledModel::Assemble(model::DefaultModelSpec());
  auto ev = FrfEvaluator::Create(BuildDisturbanceSystem(assembled));
  const FrfArray h = ev.Evaluate(Eigen::VectorXd::Zero(1), ResponseQuantity::kReceptance);
  for (int i = 0; i < 3; ++i) {
    for (int o = 0; o < 6; ++o) EXPECT_LT(std::abs(h(0, o, i)), 1e-12) << o << " " << i;
  }
  // The joint force inside ty deforms only joints below {X}... and does move {X} relative to granite.
  EXPECT_GT(std::abs(h(0, 2, 3)), 0.0);
}

TEST(IoSets, ParsesTheSetNames) {
  EXPECT_EQ(ParseIoSet("stages", "--io"), IoSet::kStages);
  EXPECT_EQ(ToString(IoSet::kDisturbance), "disturbance");
  EXPECT_THROW(ParseIoSet("nonsense", "--io"), InputError);
}

}  // namespace
}  // namespace stagefit::response
