#include "stagefit/model/assembled_model.h"

#include <functional>

#include "stagefit/common/error.h"

namespace stagefit::model {

Eigen::Matrix3d Skew(const Eigen::Vector3d& r) {
  Eigen::Matrix3d S;
  S << 0, -r.z(), r.y(), r.z(), 0, -r.x(), -r.y(), r.x(), 0;
  return S;
}

Matrix6d PointTransport(const Eigen::Vector3d& r) {
  Matrix6d S = Matrix6d::Identity();
  S.topRightCorner<3, 3>() = -Skew(r);
  return S;
}

namespace {

Matrix6d AxesToWorld(const Eigen::Matrix3d& R_WJ) {
  Matrix6d A = Matrix6d::Zero();
  A.topLeftCorner<3, 3>() = R_WJ;
  A.bottomRightCorner<3, 3>() = R_WJ;
  return A;
}

Matrix6d BodyMass(const BodySpec& b) {
  Matrix6d Mb = Matrix6d::Zero();
  Mb.topLeftCorner<3, 3>() = b.mass_kg * Eigen::Matrix3d::Identity();
  Mb.bottomRightCorner<3, 3>() = b.inertia_com_W;
  return Mb;
}

}  // namespace

AssembledModel AssembledModel::Assemble(const ModelSpec& spec, const std::string& source) {
  CheckModel(spec, source);
  AssembledModel m;
  m.spec_ = spec;
  const int num_bodies = static_cast<int>(spec.bodies.size());
  const int num_joints = static_cast<int>(spec.joints.size());

  // Generalised coordinates: the free DoF of each joint, in file order.
  m.dof_index_.assign(num_joints, {-1, -1, -1, -1, -1, -1});
  for (int j = 0; j < num_joints; ++j) {
    for (int i = 0; i < 6; ++i) {
      if (spec.joints[j].imposed[i]) continue;
      m.dof_index_[j][i] = static_cast<int>(m.dof_names_.size());
      m.dof_names_.push_back(spec.joints[j].name + "." + std::string(kDofNames[i]));
    }
  }
  const int n = m.num_dofs();
  for (int i = 0; i < 3; ++i) {
    if (spec.ground_inputs[i]) m.ground_input_names_.push_back(std::string(kGroundName) + "." + std::string(kDofNames[i]));
  }
  const int ng = m.num_ground_inputs();
  m.ground_translation_ = Eigen::MatrixXd::Zero(3, ng);
  for (int i = 0, c = 0; i < 3; ++i) {
    if (spec.ground_inputs[i]) m.ground_translation_(i, c++) = 1.0;
  }

  // Joint maps D_J: selections of the joint's own coordinates.
  m.joint_maps_.assign(num_joints, Matrix6Xd::Zero(6, n));
  for (int j = 0; j < num_joints; ++j) {
    for (int i = 0; i < 6; ++i) {
      if (m.dof_index_[j][i] >= 0) m.joint_maps_[j](i, m.dof_index_[j][i]) = 1.0;
    }
  }

  // Body maps Phi_b, down the tree.
  std::vector<int> parent_joint(num_bodies, -1);
  for (int j = 0; j < num_joints; ++j) parent_joint[FindBody(spec, spec.joints[j].child)] = j;
  m.body_maps_.assign(num_bodies, Matrix6Xd::Zero(6, n));
  std::vector<bool> done(num_bodies, false);
  std::function<void(int)> build = [&](int b) {
    if (done[b]) return;
    const JointSpec& joint = spec.joints[parent_joint[b]];
    const int parent = FindBody(spec, joint.parent);
    Matrix6Xd parent_at_origin = Matrix6Xd::Zero(6, n);
    if (parent >= 0) {
      build(parent);
      parent_at_origin = PointTransport(joint.origin_W - spec.bodies[parent].com_W) * m.body_maps_[parent];
    }
    Matrix6Xd child_at_origin = parent_at_origin + AxesToWorld(joint.R_WJ) * m.joint_maps_[parent_joint[b]];
    m.body_maps_[b] = PointTransport(spec.bodies[b].com_W - joint.origin_W) * child_at_origin;
    done[b] = true;
  };
  for (int b = 0; b < num_bodies; ++b) build(b);

  // Mass, ground coupling and gyroscopic matrices.
  m.M_ = Eigen::MatrixXd::Zero(n, n);
  m.M_zg_ = Eigen::MatrixXd::Zero(n, ng);
  m.G_ = Eigen::MatrixXd::Zero(n, n);
  Eigen::MatrixXd Psi = Eigen::MatrixXd::Zero(6, ng);
  Psi.topRows<3>() = m.ground_translation_;
  for (int b = 0; b < num_bodies; ++b) {
    const Matrix6d Mb = BodyMass(spec.bodies[b]);
    m.M_.noalias() += m.body_maps_[b].transpose() * Mb * m.body_maps_[b];
    m.M_zg_.noalias() += m.body_maps_[b].transpose() * Mb * Psi;
  }
  for (int j = 0; j < num_joints; ++j) {
    const double omega = spec.joints[j].spin_rate_rad_s;
    if (omega == 0.0) continue;
    const Eigen::Vector3d e = spec.joints[j].R_WJ.col(2);
    for (int b : m.Subtree(j)) {
      const double polar = e.dot(spec.bodies[b].inertia_com_W * e);
      const Eigen::Matrix3d Gb = -omega * polar * Skew(e);
      const auto rot = m.body_maps_[b].bottomRows<3>();
      m.G_.noalias() += rot.transpose() * Gb * rot;
    }
  }
  m.M_ = 0.5 * (m.M_ + m.M_.transpose());

  // Stiffness, damping, loss.
  m.K_ = Eigen::MatrixXd::Zero(n, n);
  m.C_ = Eigen::MatrixXd::Zero(n, n);
  m.K_loss_ = Eigen::MatrixXd::Zero(n, n);
  for (int j = 0; j < num_joints; ++j) {
    const Matrix6Xd& D = m.joint_maps_[j];
    m.K_.noalias() += D.transpose() * m.JointStiffness(j) * D;
    m.C_.noalias() += D.transpose() * m.JointDamping(j) * D;
    Matrix6d Kl = m.JointLossStiffness(j);
    if (!Kl.isZero(0.0)) m.has_loss_ = true;
    m.K_loss_.noalias() += D.transpose() * Kl * D;
  }
  m.C_ += m.G_;
  return m;
}

Matrix6Xd AssembledModel::CalcPointMap(int body_index, const Eigen::Vector3d& position_W) const {
  STAGEFIT_ASSERT(body_index >= 0 && body_index < static_cast<int>(body_maps_.size()), "bad body index");
  return PointTransport(position_W - spec_.bodies[body_index].com_W) * body_maps_[body_index];
}

Matrix6d AssembledModel::JointStiffness(int j) const {
  const JointSpec& joint = spec_.joints[j];
  Matrix6d K = Matrix6d::Zero();
  for (int i = 0; i < 6; ++i) K(i, i) = joint.imposed[i] ? 0.0 : joint.stiffness[i];
  for (const auto& c : joint.couplings) {
    K(index(c.a), index(c.b)) += c.stiffness;
    K(index(c.b), index(c.a)) += c.stiffness;
  }
  return K;
}

Matrix6d AssembledModel::JointDamping(int j) const {
  const JointSpec& joint = spec_.joints[j];
  Matrix6d C = Matrix6d::Zero();
  for (int i = 0; i < 6; ++i) C(i, i) = joint.imposed[i] ? 0.0 : joint.damping[i];
  for (const auto& c : joint.couplings) {
    C(index(c.a), index(c.b)) += c.damping;
    C(index(c.b), index(c.a)) += c.damping;
  }
  return C;
}

Matrix6d AssembledModel::JointLossStiffness(int j) const {
  // Each DoF's own term is eta_i k_i; a coupling term k_ab gets the mean loss factor (eta_a + eta_b) / 2.
  const JointSpec& joint = spec_.joints[j];
  Matrix6d K = Matrix6d::Zero();
  for (int i = 0; i < 6; ++i) K(i, i) = joint.imposed[i] ? 0.0 : joint.loss_factor[i] * joint.stiffness[i];
  for (const auto& c : joint.couplings) {
    const double eta = 0.5 * (joint.loss_factor[index(c.a)] + joint.loss_factor[index(c.b)]);
    K(index(c.a), index(c.b)) += eta * c.stiffness;
    K(index(c.b), index(c.a)) += eta * c.stiffness;
  }
  return K;
}

std::vector<int> AssembledModel::Subtree(int joint_index) const {
  std::vector<int> bodies;
  std::vector<std::string> frontier = {spec_.joints[joint_index].child};
  while (!frontier.empty()) {
    std::string current = frontier.back();
    frontier.pop_back();
    bodies.push_back(FindBody(spec_, current));
    for (const auto& j : spec_.joints) {
      if (j.parent == current) frontier.push_back(j.child);
    }
  }
  return bodies;
}

}  // namespace stagefit::model
