#pragma once
// The immutable linearised model assembled from a validated ModelSpec.
//
// Generalised coordinates (docs/model.md): z holds the FREE relative DoF of every joint, joint by
// joint in file order, each joint's free DoF in the order Dx..Rz, named "<joint>.<Dof>". Imposed
// DoF are removed exactly (they are not coordinates). A body's motion q_b = [translation of its CoM;
// small rotation], in W, is linear in z and in the ground translations u_g:
//     q_b = Phi_b z + Psi u_g,
// built down the tree: q_child = S(o - c_child)^-1 (S(o - c_parent) q_parent + A_J delta_J), where
// S(r) = [I, -[r]x; 0, I] moves CoM motion to the motion of a point at offset r and A_J =
// blockdiag(R_WJ, R_WJ) turns joint axes into W. Psi = [E; 0] is a rigid translation of everything
// with the ground, so the joint deformations delta_J depend on z only.
//
// Equations of motion (Lagrange):
//     M z'' + (C + G) z' + (K + j K_loss) z = f_z - M_zg u_g''
// M = sum_b Phi_b' M_b Phi_b, K = sum_J D_J' K_J D_J (D_J: z -> delta_J), C likewise, K_loss the
// hysteretic part (loss factors; frequency domain only), G the gyroscopic matrix of spinning subtrees
// (G_b = -Omega (e' I_b e) [e]x on the rotations of each spinning body; axisymmetric average),
// M_zg = sum_b Phi_b' M_b Psi.

#include <Eigen/Core>

#include <string>
#include <vector>

#include "stagefit/model/model_spec.h"

namespace stagefit::model {

using Matrix6Xd = Eigen::Matrix<double, 6, Eigen::Dynamic>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

/// S(r) = [I, -[r]x; 0, I]: maps the motion [u; theta] of a body at a point A to the motion of the
/// point A + r of the same body (small rotations).
Matrix6d PointTransport(const Eigen::Vector3d& r);

/// [r]x, the cross-product matrix.
Eigen::Matrix3d Skew(const Eigen::Vector3d& r);

class AssembledModel {
 public:
  /// Validates `spec` (CheckModel with `source` in messages) and assembles it.
  static AssembledModel Assemble(const ModelSpec& spec, const std::string& source = "model");

  const ModelSpec& spec() const { return spec_; }
  int num_dofs() const { return static_cast<int>(dof_names_.size()); }
  int num_states() const { return 2 * num_dofs(); }
  /// "<joint>.<Dof>" for every generalised coordinate.
  const std::vector<std::string>& dof_names() const { return dof_names_; }
  /// Names of the ground inputs, "ground.Dx" ...
  const std::vector<std::string>& ground_input_names() const { return ground_input_names_; }
  int num_ground_inputs() const { return static_cast<int>(ground_input_names_.size()); }

  const Eigen::MatrixXd& M() const { return M_; }
  /// Viscous damping including the gyroscopic matrix (C + G; not symmetric when something spins).
  const Eigen::MatrixXd& C() const { return C_; }
  const Eigen::MatrixXd& K() const { return K_; }
  /// Hysteretic (loss-factor) stiffness: the dynamic stiffness is K + j K_loss.
  const Eigen::MatrixXd& K_loss() const { return K_loss_; }
  /// The gyroscopic part of C() alone.
  const Eigen::MatrixXd& G() const { return G_; }
  bool has_loss() const { return has_loss_; }
  /// M_zg: coupling of the ground accelerations into the equations (num_dofs x num_ground_inputs).
  const Eigen::MatrixXd& M_zg() const { return M_zg_; }

  /// Phi_b: z -> [CoM translation; rotation] of body `body_index`, in W (6 x num_dofs).
  const Matrix6Xd& body_map(int body_index) const { return body_maps_[body_index]; }
  /// Psi restricted to translations: u_g -> translation of any point (3 x num_ground_inputs).
  const Eigen::MatrixXd& ground_translation_map() const { return ground_translation_; }
  /// D_J: z -> delta_J, the relative motion of joint `joint_index` in joint axes (6 x num_dofs).
  const Matrix6Xd& joint_map(int joint_index) const { return joint_maps_[joint_index]; }
  /// Index in z of a joint's free DoF, or -1 when that DoF is imposed.
  int dof_index(int joint_index, Dof dof) const { return dof_index_[joint_index][stagefit::index(dof)]; }

  /// z -> [translation of the body point at position_W; rotation], in W (6 x num_dofs).
  Matrix6Xd CalcPointMap(int body_index, const Eigen::Vector3d& position_W) const;

  /// The joint's 6x6 stiffness K_J, damping C_J and hysteretic K_loss_J in joint axes, imposed DoF zero.
  Matrix6d JointStiffness(int joint_index) const;
  Matrix6d JointDamping(int joint_index) const;
  Matrix6d JointLossStiffness(int joint_index) const;

  /// Indices of the bodies that spin with joint `joint_index` (its child and everything above).
  std::vector<int> Subtree(int joint_index) const;

 private:
  AssembledModel() = default;

  ModelSpec spec_;
  std::vector<std::string> dof_names_;
  std::vector<std::string> ground_input_names_;
  std::vector<std::array<int, 6>> dof_index_;
  std::vector<Matrix6Xd> body_maps_;
  std::vector<Matrix6Xd> joint_maps_;
  Eigen::MatrixXd ground_translation_;
  Eigen::MatrixXd M_, C_, K_, K_loss_, G_, M_zg_;
  bool has_loss_ = false;
};

}  // namespace stagefit::model
