#include "stagefit/simulate/rotating_frame.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <cmath>
#include <sstream>

#include "stagefit/common/eigen_decomposition.h"
#include "stagefit/common/error.h"

namespace stagefit::simulate {
namespace {

bool Same(double a, double b, double tolerance) {
  return std::abs(a - b) <= tolerance * std::max({std::abs(a), std::abs(b), 1e-300});
}

std::string Describe(double a, double b) {
  std::ostringstream out;
  out << a << " vs " << b;
  return out.str();
}

// Distance of point p from the axis through o along e, m.
double DistanceFromAxis(const Eigen::Vector3d& p, const Eigen::Vector3d& o, const Eigen::Vector3d& e) {
  return (p - o).cross(e).norm();
}

int RequireJoint(const model::ModelSpec& spec, const std::string& name) {
  const int j = model::FindJoint(spec, name);
  if (j < 0) throw InputError("spinning joint '" + name + "' is not a joint of the model");
  return j;
}

}  // namespace

std::vector<std::string> FindSpinAsymmetries(const model::ModelSpec& spec, const std::string& spin_joint,
                                             double tolerance) {
  const int j = RequireJoint(spec, spin_joint);
  const model::JointSpec& spin = spec.joints[j];
  const Eigen::Vector3d e = spin.R_WJ.col(2);
  const Eigen::Vector3d o = spin.origin_W;
  std::vector<std::string> problems;

  // Bodies above the joint (child first), found from the description alone.
  std::vector<std::string> bodies = {spin.child};
  for (size_t i = 0; i < bodies.size(); ++i) {
    for (const auto& joint : spec.joints) {
      if (joint.parent == bodies[i]) bodies.push_back(joint.child);
    }
  }
  for (const auto& name : bodies) {
    const model::BodySpec& b = spec.bodies[model::FindBody(spec, name)];
    const double d = DistanceFromAxis(b.com_W, o, e);
    if (d > tolerance) {
      problems.push_back("body '" + name + "': centre of mass " + std::to_string(d) + " m off the spin axis");
    }
    // Axisymmetric inertia: I = a (I3 - e e') + c e e'.
    const double c = e.dot(b.inertia_com_W * e);
    const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - e * e.transpose();
    const double a = 0.5 * (b.inertia_com_W * P).trace();
    const Eigen::Matrix3d ideal = a * P + c * e * e.transpose();
    if ((b.inertia_com_W - ideal).norm() > tolerance * b.inertia_com_W.norm()) {
      problems.push_back("body '" + name + "': inertia is not axisymmetric about the spin axis");
    }
  }
  // The spinning joint and every joint inside the subtree.
  std::vector<const model::JointSpec*> joints = {&spin};
  for (const auto& joint : spec.joints) {
    for (size_t i = 0; i < bodies.size(); ++i) {
      if (joint.parent == bodies[i]) joints.push_back(&joint);
    }
  }
  for (const model::JointSpec* joint : joints) {
    const std::string what = "joint '" + joint->name + "'";
    if (DistanceFromAxis(joint->origin_W, o, e) > tolerance) {
      problems.push_back(what + ": origin off the spin axis");
    }
    if ((joint->R_WJ.col(2) - e).norm() > tolerance) {
      problems.push_back(what + ": z axis not along the spin axis");
    }
    for (int pair = 0; pair < 2; ++pair) {
      const int x = 3 * pair, y = 3 * pair + 1;
      const std::string dofs = pair == 0 ? "Dx/Dy" : "Rx/Ry";
      if (joint->imposed[x] != joint->imposed[y]) {
        problems.push_back(what + ": " + dofs + " not both free or both imposed");
        continue;
      }
      if (!Same(joint->stiffness[x], joint->stiffness[y], tolerance)) {
        problems.push_back(what + ": stiffness " + dofs + " differ (" +
                           Describe(joint->stiffness[x], joint->stiffness[y]) + ")");
      }
      if (!Same(joint->damping[x], joint->damping[y], tolerance)) {
        problems.push_back(what + ": damping " + dofs + " differ (" + Describe(joint->damping[x], joint->damping[y]) +
                           ")");
      }
      if (!Same(joint->loss_factor[x], joint->loss_factor[y], tolerance)) {
        problems.push_back(what + ": loss factor " + dofs + " differ");
      }
    }
    if (!joint->couplings.empty()) problems.push_back(what + ": has stiffness couplings");
  }
  return problems;
}

CoRotatingModel AssembleCoRotatingModel(const model::AssembledModel& model, const std::string& spin_joint,
                                        double omega_rad_s) {
  const model::ModelSpec& spec = model.spec();
  const int j = RequireJoint(spec, spin_joint);
  const model::JointSpec& spin = spec.joints[j];
  if (spin.parent != model::kGroundName) {
    throw InputError("joint '" + spin_joint + "': the co-rotating model needs the whole model to spin (parent '" +
                     model::kGroundName + "'), got parent '" + spin.parent + "'");
  }
  if (!std::isfinite(omega_rad_s)) throw InputError("co-rotating model: spin rate is not finite");
  const Eigen::Vector3d e = spin.R_WJ.col(2);
  const Eigen::Matrix3d E = model::Skew(e);
  CoRotatingModel out;
  out.omega_rad_s = omega_rad_s;
  out.M = model.M();
  out.C = model.C() - model.G();
  out.K = model.K();
  const double w = omega_rad_s;
  for (int b : model.Subtree(j)) {
    const model::BodySpec& body = spec.bodies[b];
    if (DistanceFromAxis(body.com_W, spin.origin_W, e) > kAxisymmetryTolerance) {
      throw InputError("body '" + body.name + "': centre of mass off the spin axis of joint '" + spin_joint +
                       "' (the steady spin would preload it)");
    }
    const Eigen::Matrix3d& I = body.inertia_com_W;
    const Eigen::Vector3d Ie = I * e;
    if ((Ie - e.dot(Ie) * e).norm() > kAxisymmetryTolerance * I.norm()) {
      throw InputError("body '" + body.name + "': the spin axis is not a principal axis of its inertia");
    }
    model::Matrix6d C_b = model::Matrix6d::Zero(), K_b = model::Matrix6d::Zero();
    C_b.topLeftCorner<3, 3>() = 2 * body.mass_kg * w * E;
    K_b.topLeftCorner<3, 3>() = body.mass_kg * w * w * E * E;
    C_b.bottomRightCorner<3, 3>() = w * (I * E + E * I - model::Skew(Ie));
    K_b.bottomRightCorner<3, 3>() = w * w * (E * I * E - model::Skew(Ie) * E);
    const model::Matrix6Xd& Phi = model.body_map(b);
    out.C.noalias() += Phi.transpose() * C_b * Phi;
    out.K.noalias() += Phi.transpose() * K_b * Phi;
  }
  return out;
}

Eigen::VectorXcd CalcEigenvalues(const Eigen::MatrixXd& M, const Eigen::MatrixXd& C, const Eigen::MatrixXd& K) {
  const Eigen::Index n = M.rows();
  Eigen::LLT<Eigen::MatrixXd> llt(M);
  if (llt.info() != Eigen::Success) throw NumericalError("the mass matrix is not positive definite");
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  A.topRightCorner(n, n).setIdentity();
  A.bottomLeftCorner(n, n) = -llt.solve(K);
  A.bottomRightCorner(n, n) = -llt.solve(C);
  const auto eig = CalcEigenPairs(A, /*with_vectors=*/false);
  if (!eig) throw NumericalError("eigen-decomposition of the state matrix failed");
  return eig->values;
}

}  // namespace stagefit::simulate
