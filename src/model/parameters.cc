#include "stagefit/model/parameters.h"

#include <fnmatch.h>

#include <algorithm>

#include "stagefit/common/error.h"
#include "stagefit/model/effects.h"

namespace stagefit::model {

Dimension StiffnessDimension(Dof a, Dof b) {
  constexpr Dimension kMixed{2, 2, -4, -2};  // N/rad
  if (is_rotation(a) != is_rotation(b)) return kMixed;
  return is_rotation(a) ? dim::kRotationalStiffness : dim::kTranslationalStiffness;
}

Dimension DampingDimension(Dof a, Dof b) {
  constexpr Dimension kMixed{2, 2, -2, -2};  // N s/rad
  if (is_rotation(a) != is_rotation(b)) return kMixed;
  return is_rotation(a) ? dim::kRotationalDamping : dim::kTranslationalDamping;
}

std::vector<ParameterInfo> ListParameters(const ModelSpec& model) {
  const ModelSpec& spec = BaseOf(model);
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
        p.dimension = k.kind == ParameterKind::kStiffness ? StiffnessDimension(d, d)
                      : k.kind == ParameterKind::kDamping ? DampingDimension(d, d)
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
        p.dimension = stiffness ? StiffnessDimension(cs.a, cs.b) : DampingDimension(cs.a, cs.b);
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
  for (size_t e = 0; e < model.effects.size(); ++e) {
    const Effect& effect = model.effects[e];
    const EffectDefinition& def = FindEffectDefinition(effect.name);
    for (const auto& ps : def.parameters) {
      if (!effect.parameters.count(ps.name)) continue;
      ParameterInfo p;
      p.name = effect.name + "@" + effect.location + "." + ps.name;
      p.kind = ParameterKind::kEffect;
      p.effect = static_cast<int>(e);
      p.effect_parameter = ps.name;
      p.dimension = ps.dimension;
      p.positive = ps.positive;
      list.push_back(p);
    }
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
                       "<joint>.eta.<Dof>, <joint>.k.<A>-<B> for free DoF, <body>.m, <effect>@<location>.<parameter> "
                       "for the model's effects, e.g. 'hexapod.k.Rx', '*.k.*' or '*@*'");
    }
  }
  std::vector<ParameterInfo> result;
  for (size_t i = 0; i < all.size(); ++i) {
    if (chosen[i]) result.push_back(all[i]);
  }
  return result;
}

std::vector<std::string> EffectParameterPatterns(const ModelSpec& spec) {
  std::vector<std::string> patterns;
  auto add = [&](const std::string& pattern) {
    if (std::find(patterns.begin(), patterns.end(), pattern) == patterns.end()) patterns.push_back(pattern);
  };
  for (size_t k = 0; k < spec.effects.size(); ++k) {
    const Effect& e = spec.effects[k];
    const EffectDefinition& def = FindEffectDefinition(e.name);
    if (def.set_by_experiment) continue;
    // fnmatch: a location's own brackets or stars would be patterns; catalogue locations have none.
    const std::string prefix = e.name + "@" + e.location + ".";
    // Redundant and held parameters are left out (FixedEffectParameters).
    const std::vector<std::string> fixed =
        def.redundant || !e.held.empty() ? FixedEffectParameters(ExpandedBefore(spec, k), e) : std::vector<std::string>{};
    if (fixed.empty()) {
      add(prefix + "*");
      continue;
    }
    for (const auto& p : def.parameters) {
      if (e.parameters.count(p.name) && std::find(fixed.begin(), fixed.end(), p.name) == fixed.end()) {
        add(prefix + p.name);
      }
    }
  }
  return patterns;
}

std::vector<std::string> WithEffectParameters(std::vector<std::string> patterns, const ModelSpec& spec) {
  for (const auto& p : EffectParameterPatterns(spec)) {
    if (std::find(patterns.begin(), patterns.end(), p) == patterns.end()) patterns.push_back(p);
  }
  return patterns;
}

ParameterInfo FindParameter(const ModelSpec& spec, const std::string& name) {
  for (const auto& p : ListParameters(spec)) {
    if (p.name == name) return p;
  }
  throw InputError("parameter '" + name + "' is not a parameter of the model (names: <joint>.k.<Dof>, <body>.m, "
                   "<effect>@<location>.<parameter>, ...)");
}

namespace {

double GetDirect(const ModelSpec& spec, const ParameterInfo& p) {
  if (p.kind == ParameterKind::kMass) return spec.bodies.at(p.body).mass_kg;
  const JointSpec& j = spec.joints.at(p.joint);
  switch (p.kind) {
    case ParameterKind::kStiffness: return j.stiffness[index(p.a)];
    case ParameterKind::kDamping: return j.damping[index(p.a)];
    case ParameterKind::kLossFactor: return j.loss_factor[index(p.a)];
    case ParameterKind::kCouplingStiffness: return j.couplings.at(p.coupling).stiffness;
    case ParameterKind::kCouplingDamping: return j.couplings.at(p.coupling).damping;
    case ParameterKind::kMass:
    case ParameterKind::kEffect: break;
  }
  return 0.0;
}

void SetDirect(ModelSpec& spec, const ParameterInfo& p, double value) {
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
    case ParameterKind::kMass:
    case ParameterKind::kEffect: break;
  }
}

/// An effect of `spec` at joint `joint` (or at one of its DoF) with the name `effect`.
bool JointHasEffect(const ModelSpec& spec, int joint, const std::string& effect) {
  const std::string& name = BaseOf(spec).joints.at(joint).name;
  for (const Effect& e : spec.effects) {
    if (e.name == effect && (e.location == name || e.location.rfind(name + ".", 0) == 0)) return true;
  }
  return false;
}

/// The effects leave the parameter's value in the expanded description as in the base (header).
bool SameInBaseAndExpanded(const ModelSpec& spec, const ParameterInfo& p) {
  if (spec.effects.empty()) return true;
  switch (p.kind) {
    case ParameterKind::kStiffness: return true;
    case ParameterKind::kDamping:
    case ParameterKind::kLossFactor:
    case ParameterKind::kCouplingDamping: return !JointHasEffect(spec, p.joint, "structural-damping");
    case ParameterKind::kCouplingStiffness: return !JointHasEffect(spec, p.joint, "coupled-stiffness");
    case ParameterKind::kMass:
    case ParameterKind::kEffect: return false;
  }
  return false;
}

}  // namespace

double GetParameter(const ModelSpec& spec, const ParameterInfo& p) {
  if (p.kind == ParameterKind::kEffect) return spec.effects.at(p.effect).parameters.at(p.effect_parameter);
  return GetDirect(BaseOf(spec), p);
}

void SetParameter(ModelSpec& spec, const ParameterInfo& p, double value) {
  if (p.kind == ParameterKind::kEffect) {
    std::vector<Effect> effects = spec.effects;
    effects.at(p.effect).parameters[p.effect_parameter] = value;
    SetEffects(spec, std::move(effects));
    return;
  }
  if (!spec.base) {
    SetDirect(spec, p, value);
    return;
  }
  // The base is shared between copies of the spec: copied before it changes unless this spec holds
  // the only reference.
  if (spec.base.use_count() > 1) spec.base = std::make_shared<ModelSpec>(*spec.base);
  const double previous = GetDirect(*spec.base, p);
  SetDirect(*spec.base, p, value);
  if (SameInBaseAndExpanded(spec, p)) {
    SetDirect(spec, p, value);
    return;
  }
  try {
    SetEffects(spec, spec.effects);
  } catch (const InputError&) {
    SetDirect(*spec.base, p, previous);
    throw;
  }
}

bool HasAnalyticDerivative(const ModelSpec& spec, const ParameterInfo& p) {
  if (p.kind == ParameterKind::kEffect) return false;
  if (spec.effects.empty()) return true;
  switch (p.kind) {
    case ParameterKind::kStiffness:
    case ParameterKind::kCouplingStiffness: return true;
    case ParameterKind::kDamping:
    case ParameterKind::kLossFactor:
    case ParameterKind::kCouplingDamping: return !JointHasEffect(spec, p.joint, "structural-damping");
    case ParameterKind::kMass:
    case ParameterKind::kEffect: return false;
  }
  return false;
}

SystemDerivative CalcSystemDerivative(const AssembledModel& model, const ParameterInfo& p) {
  const int n = model.num_dofs();
  SystemDerivative d;
  d.dM = Eigen::MatrixXd::Zero(n, n);
  d.dC = Eigen::MatrixXd::Zero(n, n);
  d.dK = Eigen::MatrixXd::Zero(n, n);
  d.dK_loss = Eigen::MatrixXd::Zero(n, n);
  STAGEFIT_ASSERT(p.kind != ParameterKind::kEffect, "an effect parameter has no analytic system derivative");
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
    case ParameterKind::kEffect:
      break;
  }
  return d;
}

}  // namespace stagefit::model
