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

TEST(StageStack, ParasiticTranslationStaysInTheFixedFrameByDefault) {
  // Seed eq. 1.12: a spindle turned by 90 deg with a parasitic x error of 1 um: the error stays along W's
  // x (the fixed frame); in the moved-frame convention it appears along y.
  std::vector<Stage> stages = {{"rz", StageKind::kRotation, Dof::kRz}};
  StageMotion m;
  m.setpoint = M_PI / 2;
  m.parasitic(0) = 1e-6;
  const auto fixed = CalcStackPoses(stages, {m}).back();
  EXPECT_NEAR(fixed.translation().x(), 1e-6, 1e-20);
  EXPECT_NEAR(fixed.translation().y(), 0.0, 1e-20);
  const auto moved = CalcStackPoses(stages, {m}, ParasiticFrame::kMoved).back();
  EXPECT_NEAR(moved.translation().x(), 0.0, 1e-20);
  EXPECT_NEAR(moved.translation().y(), 1e-6, 1e-20);
  // The rotation is the same in both: R_nom R_err.
  EXPECT_TRUE(fixed.rotation().isApprox(moved.rotation(), 1e-15));
}

TEST(StageStack, MicroStationPoseWithParasiticMotionsMatchesAHandComputation) {
  // Eq. 1.12 for every stage, written out as 4x4 matrices: T_i = [R_nom R_err, p_nom + D_err; 0 1], with
  // R_err = Rx(a) Ry(b) Rz(c) of the parasitic angles; the stack is the product T_Dy T_Ry T_Rz T_hex.
  const double dy = 2e-3, ry = 0.02, rz = 0.7;
  Vector6d hex, e_dy, e_ry, e_rz, e_hex;
  hex << 1e-4, 2e-4, -1e-4, 2e-3, -1e-3, 3e-3;
  e_dy << 0, 0, 3e-7, 2e-6, 0, -1e-6;
  e_ry << 1e-7, 0, 0, 0, 5e-6, 0;
  e_rz << 2e-7, -1e-7, 5e-8, 1e-6, -2e-6, 0;
  e_hex << 1e-8, 1e-8, 0, 0, 0, 4e-6;
  std::vector<StageMotion> motions(4);
  motions[0].setpoint = dy;
  motions[1].setpoint = ry;
  motions[2].setpoint = rz;
  motions[3].pose_setpoint = hex;
  motions[0].parasitic = e_dy;
  motions[1].parasitic = e_ry;
  motions[2].parasitic = e_rz;
  motions[3].parasitic = e_hex;
  auto hand = [](const Eigen::Matrix3d& R_nom, const Eigen::Vector3d& p_nom, const Vector6d& e) {
    Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
    T.topLeftCorner<3, 3>() = R_nom * RotX(e(3)) * RotY(e(4)) * RotZ(e(5));
    T.topRightCorner<3, 1>() = p_nom + e.head<3>();
    return T;
  };
  const Eigen::Matrix4d expected =
      hand(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0, dy, 0), e_dy) * hand(RotY(ry), Eigen::Vector3d::Zero(), e_ry) *
      hand(RotZ(rz), Eigen::Vector3d::Zero(), e_rz) * hand(RotX(hex(3)) * RotY(hex(4)) * RotZ(hex(5)), hex.head<3>(), e_hex);
  const auto poses = CalcStackPoses(MicroStationStages(), motions);
  EXPECT_TRUE(poses.back().GetAsMatrix4().isApprox(expected, 1e-14)) << poses.back().GetAsMatrix4() << "\n" << expected;
  // A translation stage does not rotate: both conventions agree for it alone.
  const auto dy_fixed = CalcStageTransform(MicroStationStages()[0], motions[0], ParasiticFrame::kFixed);
  const auto dy_moved = CalcStageTransform(MicroStationStages()[0], motions[0], ParasiticFrame::kMoved);
  EXPECT_TRUE(dy_fixed.GetAsMatrix4().isApprox(dy_moved.GetAsMatrix4(), 1e-15));
}

TEST(StageStack, ParasiticFrameNamesAreParsed) {
  EXPECT_EQ(ParseParasiticFrame("fixed", "--parasitic-frame"), ParasiticFrame::kFixed);
  EXPECT_EQ(ParseParasiticFrame("moved", "--parasitic-frame"), ParasiticFrame::kMoved);
  EXPECT_THROW(ParseParasiticFrame("body", "--parasitic-frame"), std::runtime_error);
}

TEST(StageStack, MismatchedSizesAreAnInputError) {
  EXPECT_THROW(CalcStackPoses(MicroStationStages(), std::vector<StageMotion>(2)), std::runtime_error);
}

}  // namespace
}  // namespace stagefit::kinematics
