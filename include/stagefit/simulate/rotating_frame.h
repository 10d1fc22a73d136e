#pragma once
// The spindle turns the bodies above it through whole revolutions. Two exact time-invariant linear
// descriptions exist (docs/simulation.md derives both):
//
// 1. Inertial frame W. When the spinning subtree is axisymmetric about the spindle axis (every CoM
//    on the axis, inertias of the form a (I - e e') + c e e', the joints in the subtree and the
//    spindle joint itself with equal Dx/Dy and Rx/Ry stiffness and damping, no couplings, axes aligned
//    with the spindle axis), rotating the subtree by any angle leaves the linear model in W unchanged;
//    the only effect of the spin is the gyroscopic matrix G = -Omega (e' I e) [e]x on the rotations
//    of the spinning bodies, which model::AssembledModel adds when JointSpec::spin_rate_rad_s is set.
//    The micro-station is in this case; FindSpinAsymmetries() checks it.
// 2. Co-rotating frame. When the spinning subtree is NOT axisymmetric but its support co-rotates
//    (a rotating table: the spinning joint's parent is the ground), the equations are time-invariant
//    in axes turning with the spindle, with for each spinning body (mass m, inertia I about its CoM,
//    spin axis e, rate Omega, q = [CoM translation r; small rotation theta] in rotating axes):
//      m (r'' + 2 Omega [e]x r' + Omega^2 [e]x^2 r) = f                   (Coriolis, centrifugal)
//      I theta'' + Omega (I [e]x + [e]x I - [I e]x) theta'
//                + Omega^2 ([e]x I [e]x - [I e]x [e]x) theta = tau         (gyroscopic, centrifugal)
//    (linearised Euler equations about the steady spin; for I = diag(a, a, c) the rotation terms are
//    (2a - c) Omega [e]x and (c - a) Omega^2 on the tilts). AssembleCoRotatingModel() builds them.
//
// A stack whose rotating AND non-rotating parts are both anisotropic is periodically time-varying in
// every frame: the simulation refuses it (see docs/simulation.md for the frozen-angle alternative).

#include <Eigen/Core>

#include <string>
#include <vector>

#include "stagefit/model/assembled_model.h"
#include "stagefit/model/model_spec.h"

namespace stagefit::simulate {

/// Relative tolerance of the axisymmetry checks: two stiffnesses (or inertias) are "equal" when they
/// differ by less than this fraction of the larger; a CoM or joint origin is "on the axis" within this
/// fraction of 1 m. Data typed by hand agree exactly; 1e-9 only absorbs rounding of rotated inputs.
inline constexpr double kAxisymmetryTolerance = 1e-9;

/// Everything that makes the subtree of `spin_joint` (its child and the bodies above) plus the
/// spinning joint itself not axisymmetric about the spin axis (the joint's z axis through its
/// origin). Empty when the linear model in W does not depend on the spindle angle. Each entry names
/// the body or joint, the field and the values. Throws InputError when the joint does not exist.
std::vector<std::string> FindSpinAsymmetries(const model::ModelSpec& spec, const std::string& spin_joint,
                                             double tolerance = kAxisymmetryTolerance);

/// M, C, K of a model written in axes co-rotating with `spin_joint` at `omega_rad_s` (equations of
/// the header comment), n x n with n = model.num_dofs(). The model's own gyroscopic matrix (an
/// inertial-frame term) is not included: C = C_joints + C_frame, K = K_joints + K_frame.
struct CoRotatingModel {
  Eigen::MatrixXd M, C, K;
  double omega_rad_s = 0.0;
};

/// Builds the co-rotating model. Preconditions, each a thrown InputError naming body or joint: the
/// joint exists, its parent is the ground (everything spins), every CoM lies on the spin axis and the
/// spin axis is a principal axis of every body's inertia (otherwise the steady spin itself loads the
/// structure and the linearisation point is not the rest position).
CoRotatingModel AssembleCoRotatingModel(const model::AssembledModel& model, const std::string& spin_joint,
                                        double omega_rad_s);

/// Eigenvalues of [0 I; -M^-1 K, -M^-1 C] (rad/s), for checks against closed forms.
Eigen::VectorXcd CalcEigenvalues(const Eigen::MatrixXd& M, const Eigen::MatrixXd& C, const Eigen::MatrixXd& K);

}  // namespace stagefit::simulate
