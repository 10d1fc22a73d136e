#include "stagefit/model/model_spec.h"

#include <Eigen/Eigenvalues>

#include <cmath>
#include <map>
#include <set>
#include <sstream>

#include "stagefit/common/error.h"

namespace stagefit::model {
namespace {

std::string SixDigits(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

bool IsRotation(const Eigen::Matrix3d& R) {
  return R.allFinite() && (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-9 &&
         R.determinant() > 0;
}

bool IsUnit(const Eigen::Vector3d& v) { return v.allFinite() && std::abs(v.norm() - 1.0) < 1e-6; }

void CheckBody(const BodySpec& b, std::vector<std::string>& errors) {
  const std::string where = "body '" + b.name + "'";
  if (!(std::isfinite(b.mass_kg) && b.mass_kg > 0)) {
    errors.push_back(where + ": mass = " + SixDigits(b.mass_kg) + " kg, expected a finite value > 0");
  }
  if (!b.com_W.allFinite()) errors.push_back(where + ": com has a non-finite coordinate");
  const Eigen::Matrix3d& I = b.inertia_com_W;
  if (!I.allFinite()) {
    errors.push_back(where + ": inertia has a non-finite element");
    return;
  }
  if ((I - I.transpose()).cwiseAbs().maxCoeff() > 1e-9 * (1.0 + I.cwiseAbs().maxCoeff())) {
    errors.push_back(where + ": inertia is not symmetric");
    return;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(I);
  Eigen::Vector3d l = eig.eigenvalues();
  if (l.minCoeff() <= 0) {
    errors.push_back(where + ": inertia is not positive definite (principal moments " + SixDigits(l(0)) + ", " +
                     SixDigits(l(1)) + ", " + SixDigits(l(2)) + " kg m^2), expected all > 0");
    return;
  }
  const double tol = 1e-9 * l.sum();
  if (l(0) + l(1) < l(2) - tol) {
    errors.push_back(where + ": principal moments " + SixDigits(l(0)) + ", " + SixDigits(l(1)) + ", " + SixDigits(l(2)) +
                     " kg m^2 violate the triangle inequality (I1 + I2 >= I3); no rigid body has them");
  }
}

void CheckJoint(const JointSpec& j, std::vector<std::string>& errors) {
  const std::string where = "joint '" + j.name + "'";
  if (!j.origin_W.allFinite()) errors.push_back(where + ": origin has a non-finite coordinate");
  if (!IsRotation(j.R_WJ)) errors.push_back(where + ": orientation is not a rotation matrix");
  for (int i = 0; i < 6; ++i) {
    const std::string dof(kDofNames[i]);
    const char* kunit = i < 3 ? " N/m" : " Nm/rad";
    const char* cunit = i < 3 ? " N s/m" : " Nm s/rad";
    if (!(std::isfinite(j.stiffness[i]) && j.stiffness[i] >= 0)) {
      errors.push_back(where + ": stiffness " + dof + " = " + SixDigits(j.stiffness[i]) + kunit +
                       ", expected a finite value >= 0");
    }
    if (!(std::isfinite(j.damping[i]) && j.damping[i] >= 0)) {
      errors.push_back(where + ": damping " + dof + " = " + SixDigits(j.damping[i]) + cunit +
                       ", expected a finite value >= 0");
    }
    if (!(std::isfinite(j.loss_factor[i]) && j.loss_factor[i] >= 0 && j.loss_factor[i] < 10)) {
      errors.push_back(where + ": loss_factor " + dof + " = " + SixDigits(j.loss_factor[i]) +
                       ", expected a value in [0, 10)");
    }
    if (j.imposed[i] && (j.stiffness[i] != 0 || j.damping[i] != 0)) {
      errors.push_back(where + ": " + dof +
                       " is imposed and also has a stiffness or damping; an imposed DoF is a constraint "
                       "(use the servo-stiffness effect to make it a finite spring)");
    }
  }
  if (!std::isfinite(j.spin_rate_rad_s)) errors.push_back(where + ": spin_rate is not finite");
  Eigen::Matrix<double, 6, 6> K = Eigen::Matrix<double, 6, 6>::Zero();
  for (int i = 0; i < 6; ++i) K(i, i) = j.imposed[i] ? 0.0 : j.stiffness[i];
  std::set<std::pair<int, int>> seen;
  for (const auto& c : j.couplings) {
    int a = index(c.a), b = index(c.b);
    std::string pair = std::string(name(c.a)) + "-" + std::string(name(c.b));
    if (a == b) {
      errors.push_back(where + ": coupling " + pair + " couples a DoF with itself, expected two distinct DoF");
      continue;
    }
    if (j.imposed[a] || j.imposed[b]) {
      errors.push_back(where + ": coupling " + pair + " involves an imposed DoF, expected two free DoF");
      continue;
    }
    if (!seen.insert({std::min(a, b), std::max(a, b)}).second) {
      errors.push_back(where + ": coupling " + pair + " is given twice");
    }
    if (!std::isfinite(c.stiffness) || !std::isfinite(c.damping)) {
      errors.push_back(where + ": coupling " + pair + " has a non-finite stiffness or damping");
      continue;
    }
    K(a, b) += c.stiffness;
    K(b, a) += c.stiffness;
  }
  if (K.allFinite() && !j.couplings.empty()) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(K);
    if (eig.eigenvalues().minCoeff() < -1e-12 * K.cwiseAbs().maxCoeff()) {
      errors.push_back(where + ": the coupling terms make the joint stiffness indefinite (smallest eigenvalue " +
                       SixDigits(eig.eigenvalues().minCoeff()) +
                       "); expected |k_ab| <= sqrt(k_aa k_bb) for each coupling");
    }
  }
}

}  // namespace

std::vector<std::string> ValidateModel(const ModelSpec& spec) {
  std::vector<std::string> errors;
  std::map<std::string, int> body_index;
  if (spec.bodies.empty()) errors.push_back("model has no body, expected at least one [[body]]");
  for (size_t i = 0; i < spec.bodies.size(); ++i) {
    const auto& b = spec.bodies[i];
    if (b.name.empty()) errors.push_back("body #" + std::to_string(i + 1) + ": name is empty");
    if (b.name == kGroundName) errors.push_back("body 'ground': the name is reserved for the ground");
    if (!body_index.emplace(b.name, static_cast<int>(i)).second) {
      errors.push_back("body '" + b.name + "': name is used twice");
    }
    CheckBody(b, errors);
  }
  auto known_body = [&](const std::string& n) { return n == kGroundName || body_index.count(n) > 0; };

  std::map<std::string, int> parent_joint_of;  // child body -> joint
  std::set<std::string> joint_names;
  for (size_t i = 0; i < spec.joints.size(); ++i) {
    const auto& j = spec.joints[i];
    const std::string where = "joint '" + j.name + "'";
    if (j.name.empty()) errors.push_back("joint #" + std::to_string(i + 1) + ": name is empty");
    if (!joint_names.insert(j.name).second) errors.push_back(where + ": name is used twice");
    if (!known_body(j.parent)) errors.push_back(where + ": parent '" + j.parent + "' is not a body of the model");
    if (!known_body(j.child)) errors.push_back(where + ": child '" + j.child + "' is not a body of the model");
    if (j.child == kGroundName) errors.push_back(where + ": child is the ground, expected a body");
    if (j.parent == j.child) errors.push_back(where + ": parent and child are the same body '" + j.child + "'");
    if (body_index.count(j.child) && !parent_joint_of.emplace(j.child, static_cast<int>(i)).second) {
      errors.push_back(where + ": body '" + j.child + "' is already the child of joint '" +
                       spec.joints[parent_joint_of[j.child]].name +
                       "'; each body hangs from exactly one joint (the stack is a tree)");
    }
    CheckJoint(j, errors);
  }
  // Every body must reach the ground through its parent joints, without a loop.
  for (const auto& b : spec.bodies) {
    std::set<std::string> visited;
    std::string current = b.name;
    while (true) {
      if (current == kGroundName) break;
      if (!visited.insert(current).second) {
        errors.push_back("body '" + b.name + "': its chain of parent joints loops back to '" + current +
                         "', expected a chain down to the ground");
        break;
      }
      auto it = parent_joint_of.find(current);
      if (it == parent_joint_of.end()) {
        errors.push_back("body '" + b.name + "' is not connected to the ground (body '" + current +
                         "' is the child of no joint)");
        break;
      }
      current = spec.joints[it->second].parent;
      if (!known_body(current)) break;  // already reported
    }
  }
  std::set<std::string> frame_names;
  for (const auto& f : spec.frames) {
    const std::string where = "frame '" + f.name + "'";
    if (!frame_names.insert(f.name).second) errors.push_back(where + ": name is used twice");
    if (!body_index.count(f.body)) errors.push_back(where + ": body '" + f.body + "' is not a body of the model");
    if (!f.origin_W.allFinite()) errors.push_back(where + ": origin has a non-finite coordinate");
    if (!IsRotation(f.R_WF)) errors.push_back(where + ": orientation is not a rotation matrix");
  }
  for (const auto* list : {&spec.sensors, &spec.excitations}) {
    const char* kind = list == &spec.sensors ? "sensor" : "excitation";
    std::set<std::string> names;
    for (const auto& p : *list) {
      const std::string where = std::string(kind) + " '" + p.name + "'";
      if (!names.insert(p.name).second) errors.push_back(where + ": name is used twice");
      if (!body_index.count(p.body)) errors.push_back(where + ": body '" + p.body + "' is not a body of the model");
      if (!p.position_W.allFinite()) errors.push_back(where + ": position has a non-finite coordinate");
      if (!IsUnit(p.direction_W)) {
        errors.push_back(where + ": direction has length " + SixDigits(p.direction_W.norm()) + ", expected a unit vector");
      }
    }
  }
  if (!spec.compliance_frame.empty() && !frame_names.count(spec.compliance_frame)) {
    errors.push_back("model: compliance_frame '" + spec.compliance_frame + "' is not a [[frame]] of the model");
  }
  if (!(std::isfinite(spec.acquisition_delay_s) && spec.acquisition_delay_s >= 0)) {
    errors.push_back("acquisition: delay = " + SixDigits(spec.acquisition_delay_s) + " s, expected a finite value >= 0");
  }
  return errors;
}

void CheckModel(const ModelSpec& spec, const std::string& source) {
  auto errors = ValidateModel(spec);
  if (errors.empty()) return;
  std::ostringstream out;
  out << source << ": " << errors.size() << (errors.size() == 1 ? " problem" : " problems") << ":";
  for (const auto& e : errors) out << "\n  " << source << ": " << e;
  throw InputError(out.str());
}

int FindBody(const ModelSpec& spec, const std::string& name) {
  for (size_t i = 0; i < spec.bodies.size(); ++i) {
    if (spec.bodies[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

int FindJoint(const ModelSpec& spec, const std::string& name) {
  for (size_t i = 0; i < spec.joints.size(); ++i) {
    if (spec.joints[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

int FindFrame(const ModelSpec& spec, const std::string& name) {
  for (size_t i = 0; i < spec.frames.size(); ++i) {
    if (spec.frames[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

}  // namespace stagefit::model
