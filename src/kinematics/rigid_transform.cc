#include "stagefit/kinematics/rigid_transform.h"

#include <cmath>

namespace stagefit::kinematics {

Eigen::Matrix3d RotX(double a) {
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a);
  return R;
}

Eigen::Matrix3d RotY(double b) {
  Eigen::Matrix3d R;
  R << std::cos(b), 0, std::sin(b), 0, 1, 0, -std::sin(b), 0, std::cos(b);
  return R;
}

Eigen::Matrix3d RotZ(double c) {
  Eigen::Matrix3d R;
  R << std::cos(c), -std::sin(c), 0, std::sin(c), std::cos(c), 0, 0, 0, 1;
  return R;
}

Eigen::Matrix3d RotationFromEuler(const EulerXyz& e) {
  return RotX(e.alpha_rad) * RotY(e.beta_rad) * RotZ(e.gamma_rad);
}

EulerXyz EulerFromRotation(const Eigen::Matrix3d& R, double gimbal_tolerance) {
  EulerXyz e;
  double cos_beta = std::hypot(R(0, 0), R(0, 1));
  e.beta_rad = std::atan2(R(0, 2), cos_beta);
  if (cos_beta > gimbal_tolerance) {
    e.alpha_rad = std::atan2(-R(1, 2) / cos_beta, R(2, 2) / cos_beta);
    e.gamma_rad = std::atan2(-R(0, 1) / cos_beta, R(0, 0) / cos_beta);
  } else {
    // beta = +-pi/2: Rx(a) Ry(+-pi/2) Rz(c) depends on a +- c only. Take c = 0; then the lower-left
    // block of R is Rx(a) applied to the y axis: R(1,1) = cos a, R(2,1) = sin a.
    e.gamma_rad = 0.0;
    e.alpha_rad = std::atan2(R(2, 1), R(1, 1));
  }
  return e;
}

RigidTransform RigidTransform::FromPose(const Vector6d& pose) {
  return RigidTransform(RotationFromEuler({pose(3), pose(4), pose(5)}), pose.head<3>());
}

Eigen::Matrix4d RigidTransform::GetAsMatrix4() const {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = R_;
  T.topRightCorner<3, 1>() = p_;
  return T;
}

Vector6d RigidTransform::ToPose() const {
  EulerXyz e = EulerFromRotation(R_);
  Vector6d pose;
  pose << p_, e.alpha_rad, e.beta_rad, e.gamma_rad;
  return pose;
}

}  // namespace stagefit::kinematics
