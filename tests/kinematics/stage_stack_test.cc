#include "stagefit/kinematics/stage_stack.h"

#include <gtest/gtest.h>

namespace stagefit::kinematics {
namespace {

TEST(StageStack, MicroStationPoseIsProductOfStageTransforms) {
  // T = T_Dy T_Ry T_Rz T_hexapod (seed eq. 1.13-1.14), written out by hand.
  const double dy = 2.5e-3, ry = 0.01, rz = 1.2;
  Vector6d hex;
  hex << 1e-4, -2e-4, 3e-4, 1e-3, -2e-3, 5e-3;
  std::vector<StageMotion> motions(4);
  motions[0].setpoint = dy;
  motions[1].setpoint = ry;
  motions[2].setpoint = rz;
  motions[3].pose_setpoint = hex;
  auto poses = CalcStackPoses(MicroStationStages(), motions);
  Eigen::Matrix4d Tdy = Eigen::Matrix4d::Identity(), Try = Eigen::Matrix4d::Identity(),
                  Trz = Eigen::Matrix4d::Identity(), Thex = Eigen::Matrix4d::Identity();
  Tdy(1, 3) = dy;
  Try.topLeftCorner<3, 3>() = RotY(ry);
  Trz.topLeftCorner<3, 3>() = RotZ(rz);
  Thex.topLeftCorner<3, 3>() = RotX(hex(3)) * RotY(hex(4)) * RotZ(hex(5));
  Thex.topRightCorner<3, 1>() = hex.head<3>();
  EXPECT_TRUE(poses.back().GetAsMatrix4().isApprox(Tdy * Try * Trz * Thex, 1e-14));
  EXPECT_EQ(poses.size(), 4u);
}

TEST(StageStack, ParasiticMotionActsInTheMovedFrame) {
  // A spindle turned by 90 deg with a parasitic x error of 1 um: the error appears along W's y.
  std::vector<Stage> stages = {{"rz", StageKind::kRotation, Dof::kRz}};
  StageMotion m;
  m.setpoint = M_PI / 2;
  m.parasitic(0) = 1e-6;
  auto pose = CalcStackPoses(stages, {m}).back();
  EXPECT_NEAR(pose.translation().x(), 0.0, 1e-20);
  EXPECT_NEAR(pose.translation().y(), 1e-6, 1e-20);
}

TEST(StageStack, MismatchedSizesAreAnInputError) {
  EXPECT_THROW(CalcStackPoses(MicroStationStages(), std::vector<StageMotion>(2)), std::runtime_error);
}

}  // namespace
}  // namespace stagefit::kinematics
