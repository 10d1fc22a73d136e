#include "stagefit/model/effects.h"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "stagefit/common/error.h"
#include "stagefit/kinematics/rigid_transform.h"

namespace stagefit::model {
namespace {

constexpr double kDefaultZeta = 0.02;  // damping ratio given to new springs (extra body, servo)

const EffectParameterSpec P(const std::string& n, Dimension d, bool positive, const std::string& doc) {
  return EffectParameterSpec{n, d, positive, doc};
}

std::string Num(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

/// "joint.Dof" -> (joint index, dof); "joint.A-B" -> (joint, A, B).
struct JointDofLocation {
  int joint = -1;
  Dof a = Dof::kDx, b = Dof::kDx;
  bool pair = false;
};

JointDofLocation ParseJointDof(const ModelSpec& spec, const std::string& location, const std::string& effect) {
  size_t dot = location.rfind('.');
  if (dot == std::string::npos) {
    throw InputError("effect " + effect + ": location '" + location + "' must be <joint>.<Dof> or <joint>.<A>-<B>");
  }
  JointDofLocation l;
  l.joint = FindJoint(spec, location.substr(0, dot));
  if (l.joint < 0) throw InputError("effect " + effect + ": joint '" + location.substr(0, dot) + "' is not a joint of the model");
  std::string dofs = location.substr(dot + 1);
  size_t dash = dofs.find('-');
  auto a = ParseDof(dofs.substr(0, dash));
  if (!a) throw InputError("effect " + effect + ": '" + dofs + "' in location '" + location + "' is not a DoF (Dx..Rz)");
  l.a = l.b = *a;
  if (dash != std::string::npos) {
    auto b = ParseDof(dofs.substr(dash + 1));
    if (!b) throw InputError("effect " + effect + ": '" + dofs + "' in location '" + location + "' is not a DoF pair such as Dx-Ry");
    l.b = *b;
    l.pair = true;
  }
  return l;
}

int RequireBody(const ModelSpec& spec, const std::string& body, const std::string& effect) {
  int b = FindBody(spec, body);
  if (b < 0) throw InputError("effect " + effect + ": location '" + body + "' is not a body of the model");
  return b;
}

int RequireJoint(const ModelSpec& spec, const std::string& joint, const std::string& effect) {
  int j = FindJoint(spec, joint);
  if (j < 0) throw InputError("effect " + effect + ": location '" + joint + "' is not a joint of the model");
  return j;
}

double TypicalStiffness(const JointSpec& j, bool rotation) {
  double log_sum = 0;
  int count = 0;
  for (int i = rotation ? 3 : 0; i < (rotation ? 6 : 3); ++i) {
    if (!j.imposed[i] && j.stiffness[i] > 0) {
      log_sum += std::log(j.stiffness[i]);
      ++count;
    }
  }
  if (count == 0) return rotation ? 1e7 : 1e8;
  return std::exp(log_sum / count);
}

/// Adds a point mass at p_W (and isotropic inertia i_p about it) to body b, keeping the combined
/// body's mass properties exact (parallel-axis theorem).
void AddMass(BodySpec& b, double m, const Eigen::Vector3d& p_W, double i_p) {
  const double total = b.mass_kg + m;
  const Eigen::Vector3d c = (b.mass_kg * b.com_W + m * p_W) / total;
  auto shift = [](double mass, const Eigen::Vector3d& d) {
    return mass * (d.squaredNorm() * Eigen::Matrix3d::Identity() - d * d.transpose());
  };
  b.inertia_com_W = b.inertia_com_W + shift(b.mass_kg, b.com_W - c) + shift(m, p_W - c) +
                    i_p * Eigen::Matrix3d::Identity();
  b.mass_kg = total;
  b.com_W = c;
}

std::string UniqueName(const ModelSpec& spec, const std::string& base) {
  std::string name = base;
  for (int k = 2; FindBody(spec, name) >= 0 || FindJoint(spec, name) >= 0; ++k) name = base + "_" + std::to_string(k);
  return name;
}

void CheckRange(const std::string& effect, const std::string& param, double v, double lo, double hi) {
  if (!(std::isfinite(v) && v >= lo && v <= hi)) {
    throw InputError("effect " + effect + ": " + param + " = " + Num(v) + ", expected a value in [" + Num(lo) + ", " +
                     Num(hi) + "]");
  }
}

}  // namespace

std::string Effect::ToString() const {
  std::string text = name + "@" + location;
  const EffectDefinition& def = FindEffectDefinition(name);
  bool first = true;
  for (const auto& p : def.parameters) {
    auto it = parameters.find(p.name);
    if (it == parameters.end()) continue;
    text += (first ? ":" : ",") + p.name + "=" + Num(it->second);
    first = false;
  }
  return text;
}

const std::vector<EffectDefinition>& EffectCatalogue() {
  static const std::vector<EffectDefinition> catalogue = {
      {"payload", "a rigid mass fixed to a body (its mass, CoM and inertia change)", "body",
       {P("mass", dim::kMass, true, "added mass, kg"), P("x", dim::kLength, false, "CoM offset from the body's CoM, m"),
        P("y", dim::kLength, false, "m"), P("z", dim::kLength, false, "m")}},
      {"extra-body", "a new body joined to an existing one by a compliant 6-DoF joint (a local mode)", "body",
       {P("mass", dim::kMass, true, "mass of the new body, kg"),
        P("k", dim::kTranslationalStiffness, true, "stiffness of the new joint in Dx, Dy, Dz, N/m"),
        P("kr", dim::kRotationalStiffness, true, "stiffness in Rx, Ry, Rz, Nm/rad"),
        P("z", dim::kLength, false, "height of the new body above the host's CoM, m")}},
      {"servo-stiffness", "an imposed DoF becomes a finite spring/damper (drive or servo compliance)",
       "joint.DoF (imposed)",
       {P("k", dim::kDimensionless, true, "stiffness, N/m or Nm/rad"),
        P("zeta", dim::kDimensionless, true, "damping ratio of the spring with the child's mass")}},
      {"joint-offset", "a joint's origin moved (its stiffness centre is not where assumed)", "joint",
       {P("dx", dim::kLength, false, "m"), P("dy", dim::kLength, false, "m"), P("dz", dim::kLength, false, "m")}},
      {"coupled-stiffness", "an off-diagonal stiffness term between two free DoF of a joint", "joint.A-B",
       {P("k", dim::kDimensionless, false, "coupling stiffness, N/m, Nm/rad or N/rad")}},
      {"structural-damping", "frequency-independent (hysteretic) loss in a joint instead of viscous damping",
       "joint", {P("eta", dim::kDimensionless, true, "loss factor")}},
      {"sensor-geometry", "a sensor or impact position/orientation error", "channel",
       {P("dx", dim::kLength, false, "m"), P("dy", dim::kLength, false, "m"), P("dz", dim::kLength, false, "m"),
        P("rx", dim::kAngle, false, "rad"), P("ry", dim::kAngle, false, "rad"), P("rz", dim::kAngle, false, "rad")}},
      {"delay", "a pure time delay in the acquisition chain", "acquisition",
       {P("tau", dim::kTime, true, "delay, s")}},
      {"gyroscopic", "spindle rotation at a given speed (gyroscopic terms of the spinning subtree)", "joint",
       {P("spin", dim::kAngularVelocity, false, "spin rate about the joint's z axis, rad/s")}},
  };
  return catalogue;
}

const EffectDefinition& FindEffectDefinition(const std::string& name) {
  for (const auto& d : EffectCatalogue()) {
    if (d.name == name) return d;
  }
  std::string names;
  for (const auto& d : EffectCatalogue()) names += (names.empty() ? "" : ", ") + d.name;
  throw InputError("effect '" + name + "' is not in the catalogue (" + names + ")");
}

std::vector<std::string> EffectLocations(const ModelSpec& spec, const std::string& name,
                                         const std::vector<std::string>& channels) {
  const EffectDefinition& def = FindEffectDefinition(name);
  std::vector<std::string> locations;
  if (def.location_kind == "body") {
    for (const auto& b : spec.bodies) locations.push_back(b.name);
  } else if (def.location_kind == "joint") {
    for (const auto& j : spec.joints) locations.push_back(j.name);
  } else if (def.location_kind == "joint.DoF (imposed)") {
    for (const auto& j : spec.joints) {
      for (Dof d : kAllDofs) {
        if (j.imposed[index(d)]) locations.push_back(j.name + "." + std::string(stagefit::name(d)));
      }
    }
  } else if (def.location_kind == "joint.A-B") {
    for (const auto& j : spec.joints) {
      for (int a = 0; a < 6; ++a) {
        for (int b = a + 1; b < 6; ++b) {
          if (!j.imposed[a] && !j.imposed[b]) {
            locations.push_back(j.name + "." + std::string(kDofNames[a]) + "-" + std::string(kDofNames[b]));
          }
        }
      }
    }
  } else if (def.location_kind == "channel") {
    locations = channels;
  } else {
    locations.push_back("acquisition");
  }
  return locations;
}

std::map<std::string, double> DefaultEffectParameters(const ModelSpec& spec, const std::string& name,
                                                      const std::string& location) {
  std::map<std::string, double> p;
  if (name == "payload") {
    const BodySpec& b = spec.bodies[RequireBody(spec, location, name)];
    p = {{"mass", 0.1 * b.mass_kg}, {"x", 0.0}, {"y", 0.0}, {"z", 0.0}};
  } else if (name == "extra-body") {
    const BodySpec& b = spec.bodies[RequireBody(spec, location, name)];
    const double m = 0.1 * b.mass_kg;
    const double w = 2 * M_PI * 100.0;  // a local mode near 100 Hz to start from
    p = {{"mass", m}, {"k", m * w * w}, {"kr", m * 0.01 * w * w}, {"z", 0.0}};
  } else if (name == "servo-stiffness") {
    JointDofLocation l = ParseJointDof(spec, location, name);
    p = {{"k", TypicalStiffness(spec.joints[l.joint], is_rotation(l.a))}, {"zeta", kDefaultZeta}};
  } else if (name == "joint-offset") {
    p = {{"dx", 0.0}, {"dy", 0.0}, {"dz", 0.0}};
  } else if (name == "coupled-stiffness") {
    p = {{"k", 0.0}};
  } else if (name == "structural-damping") {
    p = {{"eta", 0.02}};
  } else if (name == "sensor-geometry") {
    p = {{"dx", 0.0}, {"dy", 0.0}, {"dz", 0.0}, {"rx", 0.0}, {"ry", 0.0}, {"rz", 0.0}};
  } else if (name == "delay") {
    p = {{"tau", 1e-4}};
  } else if (name == "gyroscopic") {
    p = {{"spin", 2 * M_PI}};
  } else {
    FindEffectDefinition(name);
  }
  return p;
}

Effect ParseEffect(const std::string& text, const ModelSpec& spec, const std::vector<std::string>& channels) {
  const std::string what = "--with '" + text + "'";
  size_t at = text.find('@');
  if (at == std::string::npos || at == 0 || at + 1 == text.size()) {
    throw InputError(what + ": expected EFFECT@LOCATION[:name=value,...], e.g. payload@hexapod:mass=5 kg");
  }
  Effect e;
  e.name = text.substr(0, at);
  const EffectDefinition& def = FindEffectDefinition(e.name);
  size_t colon = text.find(':', at);
  e.location = text.substr(at + 1, colon == std::string::npos ? std::string::npos : colon - at - 1);
  auto locations = EffectLocations(spec, e.name, channels);
  bool known = def.location_kind == "channel";  // channels may come from a measurement not yet loaded
  for (const auto& l : locations) known = known || l == e.location;
  if (!known) {
    std::string list;
    for (size_t i = 0; i < locations.size() && i < 12; ++i) list += (i ? ", " : "") + locations[i];
    throw InputError(what + ": '" + e.location + "' is not a location of " + e.name + " (a " + def.location_kind +
                     "; e.g. " + list + ")");
  }
  e.parameters = DefaultEffectParameters(spec, e.name, e.location);
  if (colon != std::string::npos) {
    std::stringstream list(text.substr(colon + 1));
    std::string item;
    while (std::getline(list, item, ',')) {
      size_t eq = item.find('=');
      if (eq == std::string::npos) throw InputError(what + ": '" + item + "' should be name=value");
      std::string key = item.substr(0, eq);
      while (!key.empty() && key.front() == ' ') key.erase(key.begin());
      while (!key.empty() && key.back() == ' ') key.pop_back();
      const EffectParameterSpec* ps = nullptr;
      for (const auto& p : def.parameters) {
        if (p.name == key) ps = &p;
      }
      if (!ps) {
        std::string names;
        for (const auto& p : def.parameters) names += (names.empty() ? "" : ", ") + p.name;
        throw InputError(what + ": " + e.name + " has no parameter '" + key + "' (it has " + names + ")");
      }
      double value;
      if (ps->dimension == dim::kDimensionless) {
        value = ParseQuantity(item.substr(eq + 1), what + " " + key).value;  // k of servo/coupling: any stiffness unit
      } else {
        value = ParseQuantity(item.substr(eq + 1), ps->dimension, what + " " + key);
      }
      e.parameters[key] = value;
    }
  }
  return e;
}

void ApplyEffect(ModelSpec& spec, const Effect& e) {
  auto get = [&](const std::string& key) {
    auto it = e.parameters.find(key);
    if (it == e.parameters.end()) throw InputError("effect " + e.name + ": parameter '" + key + "' is missing");
    if (!std::isfinite(it->second)) throw InputError("effect " + e.name + ": parameter '" + key + "' is not finite");
    return it->second;
  };
  if (e.name == "payload") {
    BodySpec& b = spec.bodies[RequireBody(spec, e.location, e.name)];
    const double m = get("mass");
    CheckRange(e.name, "mass", m, 0.0, 1e6);
    AddMass(b, m, b.com_W + Eigen::Vector3d(get("x"), get("y"), get("z")), 0.0);
  } else if (e.name == "extra-body") {
    const int host = RequireBody(spec, e.location, e.name);
    const double m = get("mass"), k = get("k"), kr = get("kr");
    CheckRange(e.name, "mass", m, 1e-9, 1e6);
    CheckRange(e.name, "k", k, 0.0, 1e14);
    CheckRange(e.name, "kr", kr, 0.0, 1e14);
    BodySpec body;
    body.name = UniqueName(spec, e.location + "_extra");
    body.mass_kg = m;
    body.com_W = spec.bodies[host].com_W + Eigen::Vector3d(0, 0, get("z"));
    const double radius = 0.05;  // radius of gyration of the new body, m
    body.inertia_com_W = m * radius * radius * Eigen::Matrix3d::Identity();
    body.note = "added by effect " + e.ToString();
    JointSpec joint;
    joint.name = body.name;
    joint.parent = e.location;
    joint.child = body.name;
    joint.origin_W = body.com_W;
    for (int i = 0; i < 6; ++i) {
      const double stiffness = i < 3 ? k : kr;
      const double inertia = i < 3 ? m : m * radius * radius;
      joint.stiffness[i] = stiffness;
      joint.damping[i] = 2 * kDefaultZeta * std::sqrt(stiffness * inertia);
    }
    joint.note = body.note;
    spec.bodies.push_back(body);
    spec.joints.push_back(joint);
  } else if (e.name == "servo-stiffness") {
    JointDofLocation l = ParseJointDof(spec, e.location, e.name);
    JointSpec& j = spec.joints[l.joint];
    if (!j.imposed[index(l.a)]) {
      throw InputError("effect servo-stiffness: " + e.location + " is not an imposed DoF");
    }
    const double k = get("k"), zeta = get("zeta");
    CheckRange(e.name, "k", k, 0.0, 1e14);
    CheckRange(e.name, "zeta", zeta, 0.0, 10.0);
    const BodySpec& child = spec.bodies[FindBody(spec, j.child)];
    const Eigen::Vector3d axis = j.R_WJ.col(index(l.a) % 3);
    const double inertia = is_rotation(l.a) ? axis.dot(child.inertia_com_W * axis) : child.mass_kg;
    j.imposed[index(l.a)] = false;
    j.stiffness[index(l.a)] = k;
    j.damping[index(l.a)] = 2 * zeta * std::sqrt(k * inertia);
  } else if (e.name == "joint-offset") {
    JointSpec& j = spec.joints[RequireJoint(spec, e.location, e.name)];
    j.origin_W += Eigen::Vector3d(get("dx"), get("dy"), get("dz"));
  } else if (e.name == "coupled-stiffness") {
    JointDofLocation l = ParseJointDof(spec, e.location, e.name);
    if (!l.pair || l.a == l.b) throw InputError("effect coupled-stiffness: location '" + e.location + "' must be <joint>.<A>-<B>");
    JointSpec& j = spec.joints[l.joint];
    bool found = false;
    for (auto& c : j.couplings) {
      if ((c.a == l.a && c.b == l.b) || (c.a == l.b && c.b == l.a)) {
        c.stiffness += get("k");
        found = true;
      }
    }
    if (!found) j.couplings.push_back({l.a, l.b, get("k"), 0.0});
  } else if (e.name == "structural-damping") {
    JointSpec& j = spec.joints[RequireJoint(spec, e.location, e.name)];
    const double eta = get("eta");
    CheckRange(e.name, "eta", eta, 0.0, 10.0);
    for (int i = 0; i < 6; ++i) {
      if (j.imposed[i]) continue;
      j.loss_factor[i] = eta;
      j.damping[i] = 0.0;
    }
    for (auto& c : j.couplings) c.damping = 0.0;
  } else if (e.name == "sensor-geometry") {
    GeometryCorrection g;
    g.channel = e.location;
    g.is_impact = false;
    for (const auto& x : spec.excitations) g.is_impact = g.is_impact || x.name == e.location;
    g.offset_W = Eigen::Vector3d(get("dx"), get("dy"), get("dz"));
    g.rotation_rad = Eigen::Vector3d(get("rx"), get("ry"), get("rz"));
    bool merged = false;
    for (auto& existing : spec.geometry_corrections) {
      if (existing.channel == g.channel) {
        existing.offset_W += g.offset_W;
        existing.rotation_rad += g.rotation_rad;
        merged = true;
      }
    }
    if (!merged) spec.geometry_corrections.push_back(g);
    for (auto* list : {&spec.sensors, &spec.excitations}) {
      for (auto& p : *list) {
        if (p.name != e.location) continue;
        p.position_W += g.offset_W;
        p.direction_W = kinematics::RotationFromEuler({g.rotation_rad(0), g.rotation_rad(1), g.rotation_rad(2)}) * p.direction_W;
      }
    }
  } else if (e.name == "delay") {
    const double tau = get("tau");
    CheckRange(e.name, "tau", tau, 0.0, 1.0);
    spec.acquisition_delay_s += tau;
  } else if (e.name == "gyroscopic") {
    spec.joints[RequireJoint(spec, e.location, e.name)].spin_rate_rad_s = get("spin");
  } else {
    FindEffectDefinition(e.name);
  }
  spec.effects.push_back(e.ToString());
}

std::vector<Effect> EnumerateEffects(const ModelSpec& spec, const std::vector<std::string>& channels) {
  std::vector<Effect> all;
  for (const auto& def : EffectCatalogue()) {
    for (const auto& location : EffectLocations(spec, def.name, channels)) {
      all.push_back({def.name, location, DefaultEffectParameters(spec, def.name, location)});
    }
  }
  return all;
}

}  // namespace stagefit::model
