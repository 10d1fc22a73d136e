#include "stagefit/model/model_file.h"

#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <set>
#include <sstream>

#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"
#include "stagefit/common/units.h"
#include "stagefit/kinematics/rigid_transform.h"
#include "stagefit/model/effects.h"
#include "stagefit/model/parameters.h"

namespace stagefit::model {

std::string_view EmbeddedMicroStationToml();  // generated from fitting/microstation.toml

namespace {

class Reader {
 public:
  explicit Reader(std::string source) : source_(std::move(source)) {}

  std::string Where(const toml::node* node) const {
    std::ostringstream out;
    out << source_;
    if (node && node->source().begin.line > 0) out << ":" << node->source().begin.line;
    return out.str();
  }

  void Error(const toml::node* node, const std::string& message) {
    errors_.push_back(Where(node) + ": " + message);
  }

  void CheckKeys(const toml::table& table, const std::string& item, std::initializer_list<std::string_view> allowed) {
    for (const auto& [key, value] : table) {
      bool ok = false;
      for (auto a : allowed) ok = ok || key.str() == a;
      if (!ok) {
        std::string list;
        for (auto a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
        Error(&value, item + ": unknown key '" + std::string(key.str()) + "' (a typo?), expected one of: " + list);
      }
    }
  }

  std::string String(const toml::table& t, std::string_view key, const std::string& item, bool required) {
    const toml::node* node = t.get(key);
    if (!node) {
      if (required) Error(&t, item + ": '" + std::string(key) + "' is missing");
      return {};
    }
    if (auto s = node->value<std::string>()) return *s;
    Error(node, item + ": '" + std::string(key) + "' must be a string");
    return {};
  }

  /// A number (SI) or a string with a unit.
  double Quantity(const toml::node* node, Dimension expected, const std::string& context) {
    if (node->is_integer()) return static_cast<double>(*node->value<int64_t>());
    if (node->is_floating_point()) {
      double v = *node->value<double>();
      if (!std::isfinite(v)) Error(node, context + " = " + std::to_string(v) + ", expected a finite number");
      return v;
    }
    if (auto s = node->value<std::string>()) {
      try {
        return ParseQuantity(*s, expected, context);
      } catch (const InputError& e) {
        Error(node, e.what());
        return 0.0;
      }
    }
    Error(node, context + " must be a number or a string with a unit, e.g. \"1 " + SiUnit(expected) + "\"");
    return 0.0;
  }

  double Quantity(const toml::table& t, std::string_view key, Dimension expected, const std::string& item,
                  bool required, double fallback = 0.0) {
    const toml::node* node = t.get(key);
    if (!node) {
      if (required) Error(&t, item + ": '" + std::string(key) + "' is missing, expected a " + DescribeDimension(expected));
      return fallback;
    }
    return Quantity(node, expected, item + ": " + std::string(key));
  }

  Eigen::Vector3d Vector3(const toml::table& t, std::string_view key, Dimension expected, const std::string& item,
                          bool required, const Eigen::Vector3d& fallback = Eigen::Vector3d::Zero()) {
    const toml::node* node = t.get(key);
    if (!node) {
      if (required) Error(&t, item + ": '" + std::string(key) + "' is missing, expected an array of 3 values");
      return fallback;
    }
    const toml::array* a = node->as_array();
    if (!a || a->size() != 3) {
      Error(node, item + ": '" + std::string(key) + "' must be an array of 3 values");
      return fallback;
    }
    Eigen::Vector3d v;
    for (int i = 0; i < 3; ++i) v(i) = Quantity(a->get(i), expected, item + ": " + std::string(key) + "[" + std::to_string(i) + "]");
    return v;
  }

  Eigen::Matrix3d Orientation(const toml::table& t, const std::string& item) {
    if (!t.get("orientation")) return Eigen::Matrix3d::Identity();
    Eigen::Vector3d e = Vector3(t, "orientation", dim::kAngle, item, false);
    return kinematics::RotationFromEuler({e(0), e(1), e(2)});
  }

  std::optional<Dof> DofName(const toml::node* node, const std::string& context) {
    auto s = node->value<std::string>();
    if (s) {
      if (auto d = ParseDof(*s)) return d;
    }
    Error(node, context + " = " + (s ? "'" + *s + "'" : std::string("a non-string")) +
                    ", expected one of Dx, Dy, Dz, Rx, Ry, Rz");
    return std::nullopt;
  }

  const toml::array* ArrayOfTables(const toml::table& root, std::string_view key) {
    const toml::node* node = root.get(key);
    if (!node) return nullptr;
    const toml::array* a = node->as_array();
    if (!a || !a->is_array_of_tables()) {
      Error(node, "'" + std::string(key) + "' must be an array of tables ([[" + std::string(key) + "]])");
      return nullptr;
    }
    return a;
  }

  const std::vector<std::string>& errors() const { return errors_; }
  const std::string& source() const { return source_; }

 private:
  std::string source_;
  std::vector<std::string> errors_;
};

BodySpec ReadBody(Reader& r, const toml::table& t, int number) {
  BodySpec b;
  b.name = r.String(t, "name", "body #" + std::to_string(number), true);
  const std::string item = "body '" + b.name + "'";
  r.CheckKeys(t, item, {"name", "mass", "com", "inertia", "note"});
  b.mass_kg = r.Quantity(t, "mass", dim::kMass, item, true);
  b.com_W = r.Vector3(t, "com", dim::kLength, item, true);
  b.note = r.String(t, "note", item, false);
  const toml::node* node = t.get("inertia");
  if (!node) {
    r.Error(&t, item + ": 'inertia' is missing, expected [Ixx, Iyy, Izz] or [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] in kg m^2");
    return b;
  }
  const toml::array* a = node->as_array();
  if (!a || (a->size() != 3 && a->size() != 6)) {
    r.Error(node, item + ": 'inertia' must be [Ixx, Iyy, Izz] or [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] (tensor elements, kg m^2)");
    return b;
  }
  std::vector<double> v;
  for (size_t i = 0; i < a->size(); ++i) v.push_back(r.Quantity(a->get(i), dim::kInertia, item + ": inertia[" + std::to_string(i) + "]"));
  b.inertia_com_W = Eigen::Matrix3d::Zero();
  b.inertia_com_W.diagonal() << v[0], v[1], v[2];
  if (v.size() == 6) {
    b.inertia_com_W(0, 1) = b.inertia_com_W(1, 0) = v[3];
    b.inertia_com_W(0, 2) = b.inertia_com_W(2, 0) = v[4];
    b.inertia_com_W(1, 2) = b.inertia_com_W(2, 1) = v[5];
  }
  return b;
}

void ReadDofTable(Reader& r, const toml::table& joint, std::string_view key, const std::string& item,
                  std::array<double, 6>& out, bool is_stiffness, bool is_loss, const std::array<bool, 6>& imposed) {
  const toml::node* node = joint.get(key);
  if (!node) {
    if (is_stiffness) {
      for (int i = 0; i < 6; ++i) {
        if (!imposed[i]) {
          r.Error(&joint, item + ": 'stiffness' is missing, expected a table { Dx = \"... N/m\", ... } for every free DoF");
          break;
        }
      }
    }
    return;
  }
  const toml::table* t = node->as_table();
  if (!t) {
    r.Error(node, item + ": '" + std::string(key) + "' must be a table such as { Dx = \"2e8 N/m\", Rx = \"6e7 Nm/rad\" }");
    return;
  }
  for (const auto& [k, v] : *t) {
    auto dof = ParseDof(k.str());
    if (!dof) {
      r.Error(&v, item + ": " + std::string(key) + "." + std::string(k.str()) + " is not a DoF, expected Dx, Dy, Dz, Rx, Ry or Rz");
      continue;
    }
    Dimension d = is_loss ? dim::kDimensionless
                          : (is_stiffness ? StiffnessDimension(*dof, *dof) : DampingDimension(*dof, *dof));
    out[index(*dof)] = r.Quantity(&v, d, item + ": " + std::string(key) + "." + std::string(k.str()));
  }
  if (is_stiffness) {
    for (int i = 0; i < 6; ++i) {
      if (!imposed[i] && !t->get(kDofNames[i])) {
        r.Error(node, item + ": stiffness." + std::string(kDofNames[i]) +
                          " is missing; give a value, or list " + std::string(kDofNames[i]) + " in 'imposed'");
      }
    }
  }
}

JointSpec ReadJoint(Reader& r, const toml::table& t, int number) {
  JointSpec j;
  j.name = r.String(t, "name", "joint #" + std::to_string(number), true);
  const std::string item = "joint '" + j.name + "'";
  r.CheckKeys(t, item, {"name", "parent", "child", "origin", "orientation", "stiffness", "damping", "loss_factor",
                        "imposed", "coupling", "spin_rate", "note"});
  j.parent = r.String(t, "parent", item, true);
  j.child = r.String(t, "child", item, true);
  j.origin_W = r.Vector3(t, "origin", dim::kLength, item, true);
  j.R_WJ = r.Orientation(t, item);
  j.note = r.String(t, "note", item, false);
  if (const toml::node* node = t.get("imposed")) {
    const toml::array* a = node->as_array();
    if (!a) {
      r.Error(node, item + ": 'imposed' must be an array of DoF names such as [\"Dy\"]");
    } else {
      for (const auto& e : *a) {
        if (auto d = r.DofName(&e, item + ": imposed")) j.imposed[index(*d)] = true;
      }
    }
  }
  ReadDofTable(r, t, "stiffness", item, j.stiffness, true, false, j.imposed);
  ReadDofTable(r, t, "damping", item, j.damping, false, false, j.imposed);
  ReadDofTable(r, t, "loss_factor", item, j.loss_factor, false, true, j.imposed);
  j.spin_rate_rad_s = r.Quantity(t, "spin_rate", dim::kAngularVelocity, item, false);
  if (const toml::array* couplings = r.ArrayOfTables(t, "coupling")) {
    for (const auto& e : *couplings) {
      const toml::table& c = *e.as_table();
      r.CheckKeys(c, item + ": coupling", {"dofs", "stiffness", "damping"});
      const toml::array* dofs = c.get("dofs") ? c.get("dofs")->as_array() : nullptr;
      if (!dofs || dofs->size() != 2) {
        r.Error(&c, item + ": coupling 'dofs' must be two DoF names such as [\"Dx\", \"Ry\"]");
        continue;
      }
      auto a = r.DofName(dofs->get(0), item + ": coupling dofs[0]");
      auto b = r.DofName(dofs->get(1), item + ": coupling dofs[1]");
      if (!a || !b) continue;
      CouplingSpec cs;
      cs.a = *a;
      cs.b = *b;
      const std::string citem = item + ": coupling " + std::string(name(*a)) + "-" + std::string(name(*b));
      cs.stiffness = r.Quantity(c, "stiffness", StiffnessDimension(*a, *b), citem, false);
      cs.damping = r.Quantity(c, "damping", DampingDimension(*a, *b), citem, false);
      j.couplings.push_back(cs);
    }
  }
  return j;
}

FrameSpec ReadFrame(Reader& r, const toml::table& t, int number) {
  FrameSpec f;
  f.name = r.String(t, "name", "frame #" + std::to_string(number), true);
  const std::string item = "frame '" + f.name + "'";
  r.CheckKeys(t, item, {"name", "body", "origin", "orientation"});
  f.body = r.String(t, "body", item, true);
  f.origin_W = r.Vector3(t, "origin", dim::kLength, item, true);
  f.R_WF = r.Orientation(t, item);
  return f;
}

PointSpec ReadPoint(Reader& r, const toml::table& t, const std::string& kind, int number) {
  PointSpec p;
  p.name = r.String(t, "name", kind + " #" + std::to_string(number), true);
  const std::string item = kind + " '" + p.name + "'";
  r.CheckKeys(t, item, {"name", "body", "position", "direction"});
  p.body = r.String(t, "body", item, true);
  p.position_W = r.Vector3(t, "position", dim::kLength, item, true);
  p.direction_W = r.Vector3(t, "direction", dim::kDimensionless, item, true, Eigen::Vector3d::UnitX());
  return p;
}

std::string Fmt(double v) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.17g", v);
  std::string s = buffer;
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
  return s;
}

std::string Quote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

std::string Vec(const Eigen::Vector3d& v) { return "[" + Fmt(v(0)) + ", " + Fmt(v(1)) + ", " + Fmt(v(2)) + "]"; }

void WriteOrientation(std::ostream& out, const Eigen::Matrix3d& R) {
  if (R.isIdentity(0.0)) return;
  auto e = kinematics::EulerFromRotation(R);
  out << "orientation = [" << Fmt(e.alpha_rad) << ", " << Fmt(e.beta_rad) << ", " << Fmt(e.gamma_rad) << "]  # rad, Euler XYZ\n";
}

}  // namespace

ModelSpec ParseModelToml(std::string_view text, const std::string& source) {
  toml::table root;
  try {
    root = toml::parse(text, source);
  } catch (const toml::parse_error& e) {
    std::ostringstream out;
    out << source << ":" << e.source().begin.line << ":" << e.source().begin.column << ": TOML syntax error: "
        << e.description();
    throw InputError(out.str());
  }
  Reader r(source);
  ModelSpec spec;
  r.CheckKeys(root, "model file", {"model", "ground", "acquisition", "body", "joint", "frame", "sensor", "excitation",
                                   "geometry_correction", "effect", "history"});
  if (const toml::table* m = root["model"].as_table()) {
    r.CheckKeys(*m, "[model]", {"name", "description", "compliance_frame", "effects"});
    spec.name = r.String(*m, "name", "[model]", false);
    spec.description = r.String(*m, "description", "[model]", false);
    if (m->get("compliance_frame")) spec.compliance_frame = r.String(*m, "compliance_frame", "[model]", false);
    if (const toml::node* e = m->get("effects")) {
      if (const toml::array* a = e->as_array()) {
        for (const auto& x : *a) {
          if (auto s = x.value<std::string>()) spec.baked_effects.push_back(*s);
          else r.Error(&x, "[model]: effects must be strings");
        }
      } else {
        r.Error(e, "[model]: effects must be an array of strings");
      }
    }
  } else {
    spec.compliance_frame.clear();
  }
  if (const toml::table* g = root["ground"].as_table()) {
    r.CheckKeys(*g, "[ground]", {"inputs"});
    if (const toml::node* node = g->get("inputs")) {
      spec.ground_inputs = {false, false, false};
      if (const toml::array* a = node->as_array()) {
        for (const auto& e : *a) {
          auto d = r.DofName(&e, "[ground]: inputs");
          if (d && is_rotation(*d)) r.Error(&e, "[ground]: inputs may only name translations Dx, Dy, Dz");
          else if (d) spec.ground_inputs[index(*d)] = true;
        }
      } else {
        r.Error(node, "[ground]: inputs must be an array such as [\"Dx\", \"Dy\", \"Dz\"]");
      }
    }
  }
  if (const toml::table* a = root["acquisition"].as_table()) {
    r.CheckKeys(*a, "[acquisition]", {"delay"});
    spec.acquisition_delay_s = r.Quantity(*a, "delay", dim::kTime, "[acquisition]", false);
  }
  int number = 0;
  if (auto* list = r.ArrayOfTables(root, "body")) {
    for (const auto& e : *list) spec.bodies.push_back(ReadBody(r, *e.as_table(), ++number));
  }
  number = 0;
  if (auto* list = r.ArrayOfTables(root, "joint")) {
    for (const auto& e : *list) spec.joints.push_back(ReadJoint(r, *e.as_table(), ++number));
  }
  number = 0;
  if (auto* list = r.ArrayOfTables(root, "frame")) {
    for (const auto& e : *list) spec.frames.push_back(ReadFrame(r, *e.as_table(), ++number));
  }
  number = 0;
  if (auto* list = r.ArrayOfTables(root, "sensor")) {
    for (const auto& e : *list) spec.sensors.push_back(ReadPoint(r, *e.as_table(), "sensor", ++number));
  }
  number = 0;
  if (auto* list = r.ArrayOfTables(root, "excitation")) {
    for (const auto& e : *list) spec.excitations.push_back(ReadPoint(r, *e.as_table(), "excitation", ++number));
  }
  if (auto* list = r.ArrayOfTables(root, "geometry_correction")) {
    for (const auto& e : *list) {
      const toml::table& t = *e.as_table();
      const std::string item = "[[geometry_correction]]";
      r.CheckKeys(t, item, {"channel", "kind", "offset", "rotation"});
      GeometryCorrection g;
      g.channel = r.String(t, "channel", item, true);
      std::string kind = r.String(t, "kind", item, false);
      if (kind == "impact") {
        g.is_impact = true;
      } else if (!kind.empty() && kind != "sensor") {
        r.Error(&t, item + ": kind = '" + kind + "', expected \"sensor\" or \"impact\"");
      }
      g.offset_W = r.Vector3(t, "offset", dim::kLength, item, false);
      g.rotation_rad = r.Vector3(t, "rotation", dim::kAngle, item, false);
      spec.geometry_corrections.push_back(g);
    }
  }
  if (auto* list = r.ArrayOfTables(root, "history")) {
    for (const auto& e : *list) {
      const toml::table& h = *e.as_table();
      r.CheckKeys(h, "[[history]]", {"step", "error", "detail"});
      HistoryEntry entry;
      entry.step = r.String(h, "step", "[[history]]", true);
      entry.error = r.Quantity(h, "error", dim::kDimensionless, "[[history]]", true);
      entry.detail = r.String(h, "detail", "[[history]]", false);
      spec.history.push_back(entry);
    }
  }
  // [[effect]]: name, location and the parameters of the catalogue entry (SI numbers or strings with
  // units); applied to the description above, in order, once it is valid.
  std::vector<std::pair<Effect, const toml::node*>> effects;
  if (auto* list = r.ArrayOfTables(root, "effect")) {
    int k = 0;
    for (const auto& node : *list) {
      const toml::table& t = *node.as_table();
      const std::string item = "[[effect]] #" + std::to_string(++k);
      Effect e;
      e.name = r.String(t, "name", item, true);
      e.location = r.String(t, "location", item, true);
      const EffectDefinition* def = nullptr;
      for (const auto& d : EffectCatalogue()) {
        if (d.name == e.name) def = &d;
      }
      if (!def) {
        if (!e.name.empty()) {
          std::string names;
          for (const auto& d : EffectCatalogue()) names += (names.empty() ? "" : ", ") + d.name;
          r.Error(t.get("name"), item + ": name = '" + e.name + "' is not an effect of the catalogue (" + names + ")");
        }
        continue;
      }
      std::vector<std::string_view> allowed = {"name", "location", "held"};
      for (const auto& p : def->parameters) allowed.push_back(p.name);
      for (const auto& [key, value] : t) {
        if (std::find(allowed.begin(), allowed.end(), key.str()) != allowed.end()) continue;
        std::string names;
        for (const auto& p : def->parameters) names += (names.empty() ? "" : ", ") + p.name;
        r.Error(&value, item + " (" + e.name + "): unknown key '" + std::string(key.str()) + "', expected name, location, held or " +
                            "a parameter of " + e.name + " (" + names + ")");
      }
      // held = ["dx", ...]: parameters every fit leaves at their value.
      if (const toml::node* h = t.get("held")) {
        std::string names;
        for (const auto& p : def->parameters) names += (names.empty() ? "" : ", ") + p.name;
        const std::string expected = item + " (" + e.name + "): held must be an array of parameter names of " + e.name + " (" + names + ")";
        if (const toml::array* list = h->as_array()) {
          for (const auto& x : *list) {
            const auto name = x.value<std::string>();
            try {
              if (!name) throw InputError("a value that is not a string");
              HoldEffectParameter(&e, *name);
            } catch (const InputError&) {
              r.Error(&x, expected + "; got " + (name ? "'" + *name + "'" : std::string("a value that is not a string")));
            }
          }
        } else {
          r.Error(h, expected);
        }
      }
      for (const auto& p : def->parameters) {
        const toml::node* v = t.get(p.name);
        if (!v) continue;  // the catalogue's default at the location, filled in below
        const std::string context = item + " (" + e.name + "): " + p.name;
        if (p.dimension == dim::kDimensionless && v->is_string()) {
          try {
            e.parameters[p.name] = ParseQuantity(*v->value<std::string>(), context).value;  // any stiffness unit
          } catch (const InputError& error) {
            r.Error(v, error.what());
          }
        } else {
          e.parameters[p.name] = r.Quantity(v, p.dimension, context);
        }
      }
      effects.emplace_back(e, &node);
    }
  }
  std::vector<std::string> errors = r.errors();
  if (errors.empty()) {
    for (const auto& e : ValidateModel(spec)) errors.push_back(source + ": " + e);
  }
  if (errors.empty()) {
    for (const auto& [e, node] : effects) {
      Effect effect = e;
      try {
        const auto defaults = DefaultEffectParameters(spec, effect.name, effect.location);
        for (const auto& [key, value] : defaults) effect.parameters.emplace(key, value);
        ApplyEffect(spec, effect);
      } catch (const InputError& error) {
        errors.push_back(r.Where(node) + ": [[effect]] " + effect.name + "@" + effect.location + ": " + error.what());
        break;
      }
    }
    if (errors.empty() && !spec.effects.empty()) {
      for (const auto& e : ValidateModel(spec)) errors.push_back(source + ": with its effects applied: " + e);
    }
  }
  if (!errors.empty()) {
    std::ostringstream out;
    out << source << ": " << errors.size() << (errors.size() == 1 ? " problem" : " problems") << " in the model file:";
    for (const auto& e : errors) out << "\n  " << e;
    throw InputError(out.str());
  }
  return spec;
}

ModelSpec ReadModelFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError("cannot open model file '" + path.string() + "'");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return ParseModelToml(buffer.str(), path.string());
}

std::string WriteModelToml(const ModelSpec& spec) {
  // With effects: the base description, then the effects that expand it ([[effect]]).
  const ModelSpec& d = BaseOf(spec);
  std::ostringstream out;
  out << "# stagefit model file (format: docs/model-file.md). SI units unless a unit string is given.\n\n";
  out << "[model]\nname = " << Quote(spec.name) << "\n";
  if (!spec.description.empty()) out << "description = " << Quote(spec.description) << "\n";
  out << "compliance_frame = " << Quote(spec.compliance_frame) << "\n";
  if (!spec.baked_effects.empty()) {
    out << "effects = [";
    for (size_t i = 0; i < spec.baked_effects.size(); ++i) out << (i ? ", " : "") << Quote(spec.baked_effects[i]);
    out << "]\n";
  }
  out << "\n[ground]\ninputs = [";
  bool first = true;
  for (int i = 0; i < 3; ++i) {
    if (d.ground_inputs[i]) {
      out << (first ? "" : ", ") << Quote(std::string(kDofNames[i]));
      first = false;
    }
  }
  out << "]\n\n[acquisition]\ndelay = " << Fmt(d.acquisition_delay_s) << "  # s\n";
  for (const auto& b : d.bodies) {
    out << "\n[[body]]\nname = " << Quote(b.name) << "\nmass = " << Fmt(b.mass_kg) << "  # kg\ncom = " << Vec(b.com_W)
        << "  # m\n";
    const Eigen::Matrix3d& I = b.inertia_com_W;
    out << "inertia = [" << Fmt(I(0, 0)) << ", " << Fmt(I(1, 1)) << ", " << Fmt(I(2, 2));
    if (!I.isDiagonal(0.0)) out << ", " << Fmt(I(0, 1)) << ", " << Fmt(I(0, 2)) << ", " << Fmt(I(1, 2));
    out << "]  # kg m^2\n";
    if (!b.note.empty()) out << "note = " << Quote(b.note) << "\n";
  }
  for (const auto& j : d.joints) {
    out << "\n[[joint]]\nname = " << Quote(j.name) << "\nparent = " << Quote(j.parent) << "\nchild = " << Quote(j.child)
        << "\norigin = " << Vec(j.origin_W) << "  # m\n";
    WriteOrientation(out, j.R_WJ);
    std::string imposed;
    for (int i = 0; i < 6; ++i) {
      if (j.imposed[i]) imposed += (imposed.empty() ? "" : ", ") + Quote(std::string(kDofNames[i]));
    }
    if (!imposed.empty()) out << "imposed = [" << imposed << "]\n";
    auto table = [&](const char* key, const std::array<double, 6>& values, bool skip_zero, const char* comment) {
      std::string body;
      for (int i = 0; i < 6; ++i) {
        if (j.imposed[i] || (skip_zero && values[i] == 0.0)) continue;
        body += (body.empty() ? "" : ", ") + std::string(kDofNames[i]) + " = " + Fmt(values[i]);
      }
      if (!body.empty()) out << key << " = { " << body << " }  # " << comment << "\n";
    };
    table("stiffness", j.stiffness, false, "N/m, Nm/rad");
    table("damping", j.damping, false, "N s/m, Nm s/rad");
    table("loss_factor", j.loss_factor, true, "dimensionless");
    if (j.spin_rate_rad_s != 0.0) out << "spin_rate = " << Fmt(j.spin_rate_rad_s) << "  # rad/s\n";
    if (!j.note.empty()) out << "note = " << Quote(j.note) << "\n";
    for (const auto& c : j.couplings) {
      out << "[[joint.coupling]]\ndofs = [" << Quote(std::string(name(c.a))) << ", " << Quote(std::string(name(c.b)))
          << "]\nstiffness = " << Fmt(c.stiffness) << "\ndamping = " << Fmt(c.damping) << "\n";
    }
  }
  for (const auto& f : d.frames) {
    out << "\n[[frame]]\nname = " << Quote(f.name) << "\nbody = " << Quote(f.body) << "\norigin = " << Vec(f.origin_W) << "  # m\n";
    WriteOrientation(out, f.R_WF);
  }
  for (const auto* list : {&d.sensors, &d.excitations}) {
    const char* kind = list == &d.sensors ? "sensor" : "excitation";
    for (const auto& p : *list) {
      out << "\n[[" << kind << "]]\nname = " << Quote(p.name) << "\nbody = " << Quote(p.body) << "\nposition = "
          << Vec(p.position_W) << "  # m\ndirection = " << Vec(p.direction_W) << "\n";
    }
  }
  for (const auto& g : d.geometry_corrections) {
    out << "\n[[geometry_correction]]\nchannel = " << Quote(g.channel) << "\nkind = " << (g.is_impact ? "\"impact\"" : "\"sensor\"")
        << "\noffset = " << Vec(g.offset_W) << "  # m\nrotation = " << Vec(g.rotation_rad) << "  # rad, Euler XYZ\n";
  }
  for (const Effect& e : spec.effects) {
    out << "\n[[effect]]\nname = " << Quote(e.name) << "\nlocation = " << Quote(e.location) << "\n";
    for (const auto& p : FindEffectDefinition(e.name).parameters) {
      auto it = e.parameters.find(p.name);
      if (it != e.parameters.end()) out << p.name << " = " << Fmt(it->second) << "  # " << p.doc << "\n";
    }
    if (!e.held.empty()) {
      out << "held = [";
      for (size_t i = 0; i < e.held.size(); ++i) out << (i ? ", " : "") << Quote(e.held[i]);
      out << "]  # left at their value by every fit\n";
    }
  }
  for (const auto& h : spec.history) {
    out << "\n[[history]]\nstep = " << Quote(h.step) << "\nerror = " << Fmt(h.error) << "\n";
    if (!h.detail.empty()) out << "detail = " << Quote(h.detail) << "\n";
  }
  return out.str();
}

void WriteModelFile(const std::filesystem::path& path, const ModelSpec& spec) {
  WriteFileAtomically(path, WriteModelToml(spec));
}

std::string_view DefaultModelToml() { return EmbeddedMicroStationToml(); }

ModelSpec DefaultModelSpec() {
  static const ModelSpec spec = ParseModelToml(EmbeddedMicroStationToml(), "<embedded micro-station>");
  return spec;
}

ModelSpec LoadModel(const std::string& path) {
  return path.empty() ? DefaultModelSpec() : ReadModelFile(path);
}

}  // namespace stagefit::model
