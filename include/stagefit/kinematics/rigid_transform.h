#pragma once
// Rotations, Euler angles and rigid transforms (seed section 1).
//
// Notation (docs/notation.md): X_AB is the pose of frame B in frame A; R_AB its rotation (the unit
// vectors of B written in A); p_ABo the position of B's origin in A. Compose only when the inner letters
// match: X_AC = X_AB * X_BC.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace stagefit::kinematics {

/// Rotation by `angle_rad` about x, y or z: the elementary matrices of seed eq. (1.3)-(1.5).
Eigen::Matrix3d RotX(double angle_rad);
Eigen::Matrix3d RotY(double angle_rad);
Eigen::Matrix3d RotZ(double angle_rad);

/// Euler angles of R = Rx(alpha) Ry(beta) Rz(gamma): successive rotations about the moving axes
/// (SPEC §1), all in rad.
struct EulerXyz {
  double alpha_rad = 0.0;
  double beta_rad = 0.0;
  double gamma_rad = 0.0;
};

/// R = Rx(alpha) Ry(beta) Rz(gamma).
Eigen::Matrix3d RotationFromEuler(const EulerXyz& angles);

/// Inverse of RotationFromEuler (seed eq. 1.6):
///   beta  = atan2(R13, sqrt(R11^2 + R12^2))       in [-pi/2, pi/2]
///   alpha = atan2(-R23 / cos(beta), R33 / cos(beta))
///   gamma = atan2(-R12 / cos(beta), R11 / cos(beta))
/// Gimbal lock: when |cos(beta)| < `gimbal_tolerance` only alpha + gamma (beta = +pi/2) or
/// gamma - alpha... is observable; we then set gamma = 0 and put the whole rotation about x into
/// alpha = atan2(R32, R22), which reproduces R exactly.
EulerXyz EulerFromRotation(const Eigen::Matrix3d& R, double gimbal_tolerance = 1e-9);

/// Rotation matrix of a small-angle rotation vector [Rx, Ry, Rz] taken as Euler XYZ angles.
/// Poses of stages and parasitic motions use this convention: a 6-vector Dx Dy Dz Rx Ry Rz is the
/// transform with translation (Dx, Dy, Dz) and rotation RotationFromEuler({Rx, Ry, Rz}).
using Vector6d = Eigen::Matrix<double, 6, 1>;

/// A rigid transform (homogeneous transform without the 4x4 storage): x_A = R_AB x_B + p_ABo.
class RigidTransform {
 public:
  RigidTransform() : R_(Eigen::Matrix3d::Identity()), p_(Eigen::Vector3d::Zero()) {}
  RigidTransform(const Eigen::Matrix3d& R, const Eigen::Vector3d& p) : R_(R), p_(p) {}

  static RigidTransform Identity() { return RigidTransform(); }
  static RigidTransform FromTranslation(const Eigen::Vector3d& p) {
    return RigidTransform(Eigen::Matrix3d::Identity(), p);
  }
  static RigidTransform FromRotation(const Eigen::Matrix3d& R) {
    return RigidTransform(R, Eigen::Vector3d::Zero());
  }
  /// From a pose 6-vector [Dx Dy Dz Rx Ry Rz] (m, rad): translation, then Euler XYZ rotation.
  static RigidTransform FromPose(const Vector6d& pose);

  const Eigen::Matrix3d& rotation() const { return R_; }
  const Eigen::Vector3d& translation() const { return p_; }

  /// Composition X_AC = X_AB * X_BC (seed eq. 1.9).
  RigidTransform operator*(const RigidTransform& other) const {
    return RigidTransform(R_ * other.R_, R_ * other.p_ + p_);
  }
  /// Maps a point: p_A = R_AB p_B + p_ABo.
  Eigen::Vector3d operator*(const Eigen::Vector3d& point) const { return R_ * point + p_; }

  /// Closed-form inverse (seed eq. 1.11): X_BA = [R', -R' p; 0 1].
  RigidTransform inverse() const {
    Eigen::Matrix3d Rt = R_.transpose();
    return RigidTransform(Rt, -Rt * p_);
  }

  /// The homogeneous 4x4 matrix, for printing and export only.
  Eigen::Matrix4d GetAsMatrix4() const;

  /// [Dx Dy Dz Rx Ry Rz]: translation and Euler XYZ angles (inverse of FromPose).
  Vector6d ToPose() const;

  bool IsNearlyEqualTo(const RigidTransform& other, double tolerance) const {
    return (R_ - other.R_).cwiseAbs().maxCoeff() <= tolerance &&
           (p_ - other.p_).cwiseAbs().maxCoeff() <= tolerance;
  }

 private:
  Eigen::Matrix3d R_;
  Eigen::Vector3d p_;
};

}  // namespace stagefit::kinematics
