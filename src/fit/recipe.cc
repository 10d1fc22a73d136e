#include "stagefit/fit/recipe.h"

#include <toml++/toml.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include "stagefit/common/error.h"
#include "stagefit/common/units.h"

namespace stagefit::fit {
namespace {

class RecipeReader {
 public:
  explicit RecipeReader(std::string source) : source_(std::move(source)) {}

  void Error(const toml::node* node, const std::string& key, const std::string& message) {
    std::ostringstream out;
    out << source_;
    if (node != nullptr && node->source().begin.line > 0) out << ":" << node->source().begin.line;
    out << ": " << key << " " << message;
    errors_.push_back(out.str());
  }

  static std::string Show(const toml::node& node) {
    std::ostringstream out;
    node.visit([&](auto&& v) { out << v; });
    return out.str();
  }

  std::optional<std::string> String(const toml::table& t, std::string_view key) {
    const toml::node* node = t.get(key);
    if (node == nullptr) return std::nullopt;
    if (auto s = node->value<std::string>()) return *s;
    Error(node, std::string(key), "= " + Show(*node) + ", expected a string");
    return std::nullopt;
  }

  // An integer in [min, max]; max defaults to the largest int, the type of the counts it sets.
  std::optional<std::int64_t> Integer(const toml::table& t, std::string_view key, std::int64_t min,
                                      std::int64_t max = std::numeric_limits<int>::max()) {
    const toml::node* node = t.get(key);
    if (node == nullptr) return std::nullopt;
    if (node->is_integer()) {
      const std::int64_t v = *node->value<std::int64_t>();
      if (v >= min && v <= max) return v;
    }
    std::string expected = "an integer >= " + std::to_string(min);
    if (max < std::numeric_limits<std::int64_t>::max()) expected += " and <= " + std::to_string(max);
    Error(node, std::string(key), "= " + Show(*node) + ", expected " + expected);
    return std::nullopt;
  }

  std::optional<bool> Boolean(const toml::table& t, std::string_view key) {
    const toml::node* node = t.get(key);
    if (node == nullptr) return std::nullopt;
    if (auto b = node->value<bool>()) return *b;
    Error(node, std::string(key), "= " + Show(*node) + ", expected true or false");
    return std::nullopt;
  }

  // A plain number (no unit).
  std::optional<double> Number(const toml::node* node, const std::string& key, double min, double max,
                               const std::string& expected) {
    if (node == nullptr) return std::nullopt;
    if (node->is_number()) {
      const double v = *node->value<double>();
      if (std::isfinite(v) && v >= min && v <= max) return v;
    }
    Error(node, key, "= " + Show(*node) + ", expected " + expected);
    return std::nullopt;
  }

  // A number in SI (or in `bare_unit` when given, e.g. Hz) or a string with a unit; the dimension of a
  // string is returned in `dimension` when `expected` is not given.
  std::optional<double> Quantity(const toml::node* node, const std::string& key, std::optional<Dimension> expected,
                                 std::optional<Dimension>* dimension = nullptr) {
    if (node == nullptr) return std::nullopt;
    if (node->is_number()) {
      const double v = *node->value<double>();
      if (std::isfinite(v)) return v;
    } else if (auto s = node->value<std::string>()) {
      try {
        if (expected) return ParseQuantity(*s, *expected, source_ + ": " + key);
        const stagefit::Quantity q = ParseQuantity(*s, source_ + ": " + key);
        if (dimension != nullptr) *dimension = q.dimension;
        return q.value;
      } catch (const InputError& e) {
        Error(node, key, std::string("= '") + *s + "': " + e.what());
        return std::nullopt;
      }
    }
    Error(node, key, "= " + Show(*node) + ", expected a finite number or a string with a unit");
    return std::nullopt;
  }

  void CheckKeys(const toml::table& t, const std::string& item, std::initializer_list<std::string_view> allowed) {
    for (const auto& [key, value] : t) {
      bool known = false;
      for (auto a : allowed) known = known || key.str() == a;
      if (!known) {
        std::string list;
        for (auto a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
        Error(&value, item + std::string(key.str()), "is an unknown key (a typo?), expected one of: " + list);
      }
    }
  }

  void ThrowIfErrors() const {
    if (errors_.empty()) return;
    std::string message = errors_.size() == 1 ? errors_[0] : std::to_string(errors_.size()) + " problems:";
    if (errors_.size() > 1) {
      for (const auto& e : errors_) message += "\n  " + e;
    }
    throw InputError(message);
  }

  const std::string& source() const { return source_; }

 private:
  std::string source_;
  std::vector<std::string> errors_;
};

std::string Resolve(const std::string& path, const std::filesystem::path& base) {
  if (path.empty() || base.empty() || std::filesystem::path(path).is_absolute()) return path;
  return (base / path).lexically_normal().string();
}

}  // namespace

FitRecipe ParseFitRecipe(std::string_view text, const std::string& source, const std::filesystem::path& base_folder) {
  toml::table root;
  try {
    root = toml::parse(text, source);
  } catch (const toml::parse_error& e) {
    std::ostringstream out;
    out << source << ":" << e.source().begin.line << ":" << e.source().begin.column
        << ": TOML syntax error: " << e.description();
    throw InputError(out.str());
  }
  RecipeReader r(source);
  FitRecipe recipe;
  recipe.source = source;
  r.CheckKeys(root, "",
              {"measurement", "model", "space", "band", "significance", "params", "solver", "jacobian",
               "nlopt_algorithm", "nlopt_max_evaluations", "polish", "starts", "start_factor", "seed",
               "max_iterations", "probe_rounds", "bounds"});

  if (auto s = r.String(root, "measurement")) recipe.measurement = Resolve(*s, base_folder);
  if (auto s = r.String(root, "model")) recipe.model = Resolve(*s, base_folder);
  if (auto s = r.String(root, "space")) {
    try {
      recipe.comparison.space = compare::ParseComparisonSpace(*s, source + ": space");
      recipe.space_given = true;
    } catch (const InputError&) {
      r.Error(root.get("space"), "space", "= '" + *s + "', expected compliance, bodies or raw");
    }
  }
  if (const toml::node* node = root.get("band")) {
    const toml::array* a = node->as_array();
    if (a == nullptr || a->size() != 2) {
      r.Error(node, "band", "= " + RecipeReader::Show(*node) + ", expected [low, high] in Hz, e.g. [\"5 Hz\", \"700 Hz\"]");
    } else {
      auto lo = r.Quantity(a->get(0), "band[0]", dim::kFrequency);
      auto hi = r.Quantity(a->get(1), "band[1]", dim::kFrequency);
      if (lo && hi) {
        if (!(*lo >= 0.0 && *lo < *hi)) {
          r.Error(node, "band", "= " + RecipeReader::Show(*node) + ", expected 0 <= low < high");
        } else {
          recipe.comparison.fmin_hz = *lo;
          recipe.comparison.fmax_hz = *hi;
        }
      }
    }
  }
  if (auto v = r.Number(root.get("significance"), "significance", 0.0, 1.0, "a number in [0, 1]")) {
    recipe.comparison.significance_threshold = *v;
  }
  if (const toml::node* node = root.get("params")) {
    const toml::array* a = node->as_array();
    bool ok = a != nullptr && !a->empty();
    if (ok) {
      for (const auto& e : *a) {
        auto s = e.value<std::string>();
        ok = ok && s && !s->empty();
        if (s) recipe.params.push_back(*s);
      }
    }
    if (!ok) {
      recipe.params.clear();
      r.Error(node, "params", "= " + RecipeReader::Show(*node) +
                                  ", expected a non-empty array of name patterns, e.g. [\"*.k.*\"]");
    }
  }
  if (auto s = r.String(root, "solver")) {
    if (*s == "ceres" || *s == "nlopt") {
      recipe.options.solver = ParseSolverKind(*s, "solver");
    } else {
      r.Error(root.get("solver"), "solver", "= '" + *s + "', expected ceres or nlopt");
    }
  }
  if (auto s = r.String(root, "jacobian")) {
    if (*s == "analytic" || *s == "finite-difference") {
      recipe.options.jacobian = ParseJacobianKind(*s, "jacobian");
    } else {
      r.Error(root.get("jacobian"), "jacobian", "= '" + *s + "', expected analytic or finite-difference");
    }
  }
  if (auto s = r.String(root, "nlopt_algorithm")) {
    try {
      CheckNloptAlgorithm(*s, "nlopt_algorithm");
      recipe.options.nlopt_algorithm = *s;
    } catch (const InputError& e) {
      r.Error(root.get("nlopt_algorithm"), "nlopt_algorithm", std::string("is invalid: ") + e.what());
    }
  }
  if (auto v = r.Integer(root, "nlopt_max_evaluations", 1)) recipe.options.nlopt_max_evaluations = static_cast<int>(*v);
  if (auto v = r.Boolean(root, "polish")) recipe.options.nlopt_polish = *v;
  if (auto v = r.Integer(root, "starts", 1)) recipe.options.num_starts = static_cast<int>(*v);
  if (auto v = r.Number(root.get("start_factor"), "start_factor", 1.0, 1e6, "a number >= 1")) {
    recipe.options.start_factor = *v;
  }
  if (auto v = r.Integer(root, "seed", 0, std::numeric_limits<std::int64_t>::max())) recipe.options.seed = static_cast<std::uint64_t>(*v);
  if (auto v = r.Integer(root, "max_iterations", 1)) recipe.options.max_iterations = static_cast<int>(*v);
  if (auto v = r.Integer(root, "probe_rounds", 0)) recipe.options.max_probe_rounds = static_cast<int>(*v);

  if (const toml::node* node = root.get("bounds")) {
    const toml::array* a = node->as_array();
    if (a == nullptr || !a->is_array_of_tables()) {
      r.Error(node, "bounds", "must be an array of tables ([[bounds]] with pattern, lower, upper, factor)");
    } else {
      int number = 0;
      for (const auto& e : *a) {
        const toml::table& t = *e.as_table();
        const std::string item = "bounds[" + std::to_string(number++) + "].";
        r.CheckKeys(t, item, {"pattern", "lower", "upper", "factor"});
        BoundRule rule;
        rule.source = source + (t.source().begin.line > 0 ? ":" + std::to_string(t.source().begin.line) : "");
        if (auto s = r.String(t, "pattern"); s && !s->empty()) {
          rule.pattern = *s;
        } else {
          r.Error(&t, item + "pattern", "is missing, expected a parameter name pattern such as \"hexapod.k.*\"");
        }
        std::optional<Dimension> lower_dim, upper_dim;
        rule.lower = r.Quantity(t.get("lower"), item + "lower", std::nullopt, &lower_dim);
        rule.upper = r.Quantity(t.get("upper"), item + "upper", std::nullopt, &upper_dim);
        if (lower_dim && upper_dim && *lower_dim != *upper_dim) {
          r.Error(&t, item + "lower/upper", "have different units: " + DescribeDimension(*lower_dim) + " and " +
                                                DescribeDimension(*upper_dim));
        }
        rule.dimension = lower_dim ? lower_dim : upper_dim;
        rule.factor = r.Number(t.get("factor"), item + "factor", 1.0 + 1e-12, 1e12, "a number > 1");
        if (!rule.lower && !rule.upper && !rule.factor && t.get("lower") == nullptr && t.get("upper") == nullptr &&
            t.get("factor") == nullptr) {
          r.Error(&t, item.substr(0, item.size() - 1), "sets nothing, expected lower, upper or factor");
        }
        if (rule.lower && rule.upper && !(*rule.lower <= *rule.upper)) {
          r.Error(&t, item + "lower", "> upper, expected lower <= upper");
        }
        recipe.bounds.push_back(rule);
      }
    }
  }
  r.ThrowIfErrors();
  return recipe;
}

FitRecipe ReadFitRecipe(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string() + ": cannot read the fit recipe");
  std::ostringstream text;
  text << in.rdbuf();
  return ParseFitRecipe(text.str(), path.string(), path.parent_path());
}

}  // namespace stagefit::fit
