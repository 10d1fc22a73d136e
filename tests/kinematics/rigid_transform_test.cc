#include "stagefit/kinematics/rigid_transform.h"

#include <gtest/gtest.h>

#include <random>

namespace stagefit::kinematics {
namespace {

// Round trips go through sin/cos/atan2: errors of a few ulp of the angle.
constexpr double kAngleTol = 1e-12;

TEST(Euler, RandomRoundTripsRecoverAngles) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> any(-M_PI, M_PI), half(-M_PI / 2 + 1e-3, M_PI / 2 - 1e-3);
  for (int i = 0; i < 1000; ++i) {
    EulerXyz e{any(rng), half(rng), any(rng)};
    EulerXyz back = EulerFromRotation(RotationFromEuler(e));
    EXPECT_NEAR(back.alpha_rad, e.alpha_rad, kAngleTol);
    EXPECT_NEAR(back.beta_rad, e.beta_rad, kAngleTol);
    EXPECT_NEAR(back.gamma_rad, e.gamma_rad, kAngleTol);
  }
}

TEST(Euler, MatrixIsProductOfElementaryRotationsAboutMovingAxes) {
  EulerXyz e{0.3, -0.2, 1.1};
  Eigen::Matrix3d expected = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()).toRotationMatrix() *
                             Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitY()).toRotationMatrix() *
                             Eigen::AngleAxisd(1.1, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  EXPECT_TRUE(RotationFromEuler(e).isApprox(expected, 1e-15));
}

TEST(Euler, GimbalLockReproducesTheRotation) {
  for (double beta : {M_PI / 2, -M_PI / 2}) {
    Eigen::Matrix3d R = RotationFromEuler({0.7, beta, -0.4});
    EulerXyz back = EulerFromRotation(R);
    EXPECT_NEAR(std::abs(back.beta_rad), M_PI / 2, 1e-12);
    EXPECT_EQ(back.gamma_rad, 0.0);
    EXPECT_TRUE(RotationFromEuler(back).isApprox(R, 1e-12));
  }
}

TEST(RigidTransform, InverseComposesToIdentity) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 100; ++i) {
    Vector6d pose;
    for (int k = 0; k < 6; ++k) pose(k) = u(rng);
    RigidTransform X = RigidTransform::FromPose(pose);
    EXPECT_TRUE((X * X.inverse()).IsNearlyEqualTo(RigidTransform::Identity(), 1e-14));
    EXPECT_TRUE((X.inverse() * X).IsNearlyEqualTo(RigidTransform::Identity(), 1e-14));
    Eigen::Matrix4d T = X.GetAsMatrix4();
    EXPECT_TRUE(X.inverse().GetAsMatrix4().isApprox(T.inverse(), 1e-12));
    EXPECT_TRUE(X.ToPose().isApprox(pose, 1e-12));
  }
}

TEST(RigidTransform, CompositionMapsPointsLikeMatrixProduct) {
  RigidTransform A = RigidTransform::FromPose((Vector6d() << 1, 2, 3, 0.1, 0.2, 0.3).finished());
  RigidTransform B = RigidTransform::FromPose((Vector6d() << -1, 0.5, 0, -0.3, 0.1, 0.9).finished());
  Eigen::Vector3d p(0.3, -0.7, 1.9);
  EXPECT_TRUE(((A * B) * p).isApprox(A * (B * p), 1e-14));
  EXPECT_TRUE((A * B).GetAsMatrix4().isApprox(A.GetAsMatrix4() * B.GetAsMatrix4(), 1e-14));
}

}  // namespace
}  // namespace stagefit::kinematics
