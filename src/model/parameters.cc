#include "stagefit/model/parameters.h"

#include <fnmatch.h>

#include "stagefit/common/error.h"

namespace stagefit::model {
namespace {

inline constexpr Dimension kMixedStiffness{2, 2, -4, -2};
inline constexpr Dimension kMixedDamping{2, 2, -2, -2};

Dimension StiffnessDim(Dof a, Dof b) {
  if (is_rotation(a) != is_rotation(b)) return kMixedStiffness;
  return is_rotation(a) ? dim::kRotationalStiffness : dim::kTranslationalStiffness;
}

Dimension DampingDim(Dof a, Dof b) {
  if (is_rotation(a) != is_rotation(b)) return kMixedDamping;
  return is_rotation(a) ? dim::kRotationalDamping : dim::kTranslationalDamping;
}

}  // namespace

std::vector<ParameterInfo> ListParameters(const ModelSpec& spec) {
  std::vector<ParameterInfo> list;
  for (size_t j = 0; j < spec.joints.size(); ++j) {
    const JointSpec& joint = spec.joints[j];
    struct Kind {
      ParameterKind kind;
      const char* tag;
    };
    for (Kind k : {Kind{ParameterKind::kStiffness, "k"}, Kind{ParameterKind::kDamping, "c"},
                   Kind{ParameterKind::kLossFactor, "eta"}}) {
      for (Dof d : kAllDofs) {
        if (joint.imposed[index(d)]) continue;
        ParameterInfo p;
        p.name = joint.name + "." + k.tag + "." + std::string(name(d));
        p.kind = k.kind;
        p.joint = static_cast<int>(j);
        p.a = p.b = d;
        p.dimension = k.kind == ParameterKind::kStiffness ? StiffnessDim(d, d)
                      : k.kind == ParameterKind::kDamping ? DampingDim(d, d)
                                                          : dim::kDimensionless;
        p.positive = k.kind == ParameterKind::kStiffness;
        list.push_back(p);
      }
    }
    for (size_t c = 0; c < joint.couplings.size(); ++c) {
      const CouplingSpec& cs = joint.couplings[c];
      const std::string pair = std::string(name(cs.a)) + "-" + std::string(name(cs.b));
      for (bool stiffness : {true, false}) {
        ParameterInfo p;
        p.name = joint.name + (stiffness ? ".k." : ".c.") + pair;
        p.kind = stiffness ? ParameterKind::kCouplingStiffness : ParameterKind::kCouplingDamping;
        p.joint = static_cast<int>(j);
        p.a = cs.a;
        p.b = cs.b;
        p.coupling = static_cast<int>(c);
        p.dimension = stiffness ? StiffnessDim(cs.a, cs.b) : DampingDim(cs.a, cs.b);
        p.positive = false;  // a coupling term may have either sign
        list.push_back(p);
      }
    }
  }
  for (size_t b = 0; b < spec.bodies.size(); ++b) {
    ParameterInfo p;
    p.name = spec.bodies[b].name + ".m";
    p.kind = ParameterKind::kMass;
    p.body = static_cast<int>(b);
    p.dimension = dim::kMass;
    list.push_back(p);
  }
  return list;
}

std::vector<ParameterInfo> MatchParameters(const ModelSpec& spec, const std::vector<std::string>& patterns) {
  std::vector<ParameterInfo> all = ListParameters(spec);
  std::vector<bool> chosen(all.size(), false);
  for (const auto& pattern : patterns) {
    bool any = false;
    for (size_t i = 0; i < all.size(); ++i) {
      if (::fnmatch(pattern.c_str(), all[i].name.c_str(), 0) == 0) {
        chosen[i] = true;
        any = true;
      }
    }
    if (!any) {
      throw InputError("--params: pattern '" + pattern +
                       "' matches no parameter of the model; names are <joint>.k.<Dof>, <joint>.c.<Dof>, "
                       "<joint>.eta.<Dof>, <joint>.k.<A>-<B> for free DoF, e.g. 'hexapod.k.Rx' or '*.k.*'");
    }
  }
  std::vector<ParameterInfo> result;
  for (size_t i = 0; i < all.size(); ++i) {
    if (chosen[i]) result.push_back(all[i]);
  }
  return result;
}

ParameterInfo FindParameter(const ModelSpec& spec, const std::string& name) {
  for (const auto& p : ListParameters(spec)) {
    if (p.name == name) return p;
  }
  throw InputError("parameter '" + name + "' is not a parameter of the model (names: <joint>.k.<Dof>, ...)");
}

double GetParameter(const ModelSpec& spec, const ParameterInfo& p) {
  if (p.kind == ParameterKind::kMass) return spec.bodies.at(p.body).mass_kg;
  const JointSpec& j = spec.joints.at(p.joint);
  switch (p.kind) {
    case ParameterKind::kStiffness: return j.stiffness[index(p.a)];
    case ParameterKind::kDamping: return j.damping[index(p.a)];
    case ParameterKind::kLossFactor: return j.loss_factor[index(p.a)];
    case ParameterKind::kCouplingStiffness: return j.couplings.at(p.coupling).stiffness;
    case ParameterKind::kCouplingDamping: return j.couplings.at(p.coupling).damping;
    case ParameterKind::kMass: break;
  }
  return 0.0;
}

void SetParameter(ModelSpec& spec, const ParameterInfo& p, double value) {
  if (p.kind == ParameterKind::kMass) {
    spec.bodies.at(p.body).mass_kg = value;
    return;
  }
  JointSpec& j = spec.joints.at(p.joint);
  switch (p.kind) {
    case ParameterKind::kStiffness: j.stiffness[index(p.a)] = value; break;
    case ParameterKind::kDamping: j.damping[index(p.a)] = value; break;
    case ParameterKind::kLossFactor: j.loss_factor[index(p.a)] = value; break;
    case ParameterKind::kCouplingStiffness: j.couplings.at(p.coupling).stiffness = value; break;
    case ParameterKind::kCouplingDamping: j.couplings.at(p.coupling).damping = value; break;
    case ParameterKind::kMass: break;
  }
}

SystemDerivative CalcSystemDerivative(const AssembledModel& model, const ParameterInfo& p) {
  const int n = model.num_dofs();
  SystemDerivative d;
  d.dM = Eigen::MatrixXd::Zero(n, n);
  d.dC = Eigen::MatrixXd::Zero(n, n);
  d.dK = Eigen::MatrixXd::Zero(n, n);
  d.dK_loss = Eigen::MatrixXd::Zero(n, n);
  if (p.kind == ParameterKind::kMass) {
    const auto translation = model.body_map(p.body).topRows<3>();
    d.dM = translation.transpose() * translation;
    return d;
  }
  const JointSpec& joint = model.spec().joints.at(p.joint);
  const Matrix6Xd& D = model.joint_map(p.joint);
  const int a = index(p.a), b = index(p.b);
  Matrix6d unit = Matrix6d::Zero();
  unit(a, b) = 1.0;
  unit(b, a) = 1.0;  // a == b for per-DoF parameters: a single 1 on the diagonal
  const Eigen::MatrixXd E = D.transpose() * unit * D;
  switch (p.kind) {
    case ParameterKind::kStiffness:
      d.dK = E;
      d.dK_loss = joint.loss_factor[a] * E;
      break;
    case ParameterKind::kDamping:
      d.dC = E;
      break;
    case ParameterKind::kLossFactor: {
      Matrix6d dL = Matrix6d::Zero();
      dL(a, a) = joint.stiffness[a];
      for (const auto& c : joint.couplings) {
        if (c.a == p.a || c.b == p.a) {
          dL(index(c.a), index(c.b)) += 0.5 * c.stiffness;
          dL(index(c.b), index(c.a)) += 0.5 * c.stiffness;
        }
      }
      d.dK_loss = D.transpose() * dL * D;
      break;
    }
    case ParameterKind::kCouplingStiffness:
      d.dK = E;
      d.dK_loss = 0.5 * (joint.loss_factor[a] + joint.loss_factor[b]) * E;
      break;
    case ParameterKind::kCouplingDamping:
      d.dC = E;
      break;
    case ParameterKind::kMass:
      break;
  }
  return d;
}

}  // namespace stagefit::model
