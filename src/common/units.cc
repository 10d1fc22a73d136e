#include "stagefit/common/units.h"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <sstream>
#include <vector>

#include "stagefit/common/error.h"

namespace stagefit {
namespace {

struct UnitSymbol {
  std::string_view symbol;
  double factor;
  Dimension dimension;
};

const std::vector<UnitSymbol>& Symbols() {
  static const std::vector<UnitSymbol> symbols = {
      {"rpm", 2.0 * kPi / 60.0, dim::kAngularVelocity},
      {"rad", 1.0, dim::kAngle},
      {"deg", kPi / 180.0, dim::kAngle},
      {"rev", 2.0 * kPi, dim::kAngle},
      {"min", 60.0, dim::kTime},
      {"Hz", 1.0, dim::kFrequency},
      {"Pa", 1.0, Dimension{2, -2, -4, 0}},
      {"N", 1.0, dim::kForce},
      {"m", 1.0, dim::kLength},
      {"g", 1e-3, dim::kMass},
      {"s", 1.0, dim::kTime},
      {"h", 3600.0, dim::kTime},
  };
  return symbols;
}

struct Prefix {
  std::string_view text;
  double factor;
};

const std::vector<Prefix>& Prefixes() {
  static const std::vector<Prefix> prefixes = {
      {"\xC2\xB5", 1e-6}, {"\xCE\xBC", 1e-6}, {"p", 1e-12}, {"n", 1e-9}, {"u", 1e-6},
      {"m", 1e-3},        {"c", 1e-2},        {"k", 1e3},   {"M", 1e6},  {"G", 1e9},
  };
  return prefixes;
}

Dimension Scale(Dimension d, int numerator, int denominator) {
  // Multiplies every (doubled) exponent by numerator/denominator; callers keep results integral.
  return Dimension{d.kg2 * numerator / denominator, d.m2 * numerator / denominator,
                   d.s2 * numerator / denominator, d.rad2 * numerator / denominator};
}

Dimension Add(Dimension a, Dimension b) {
  return Dimension{a.kg2 + b.kg2, a.m2 + b.m2, a.s2 + b.s2, a.rad2 + b.rad2};
}

struct Factor {
  double value = 1.0;
  Dimension dimension;
};

// Splits a word of unit symbols; only the first symbol may carry a prefix.
std::optional<Factor> ParseUnsuffixedRun(std::string_view word) {
  Factor result;
  while (!word.empty()) {
    bool matched = false;
    for (const auto& s : Symbols()) {
      if (word.substr(0, s.symbol.size()) == s.symbol) {
        result.value *= s.factor;
        result.dimension = Add(result.dimension, s.dimension);
        word.remove_prefix(s.symbol.size());
        matched = true;
        break;
      }
    }
    if (!matched) return std::nullopt;
  }
  return result;
}

std::optional<Factor> ParseWord(std::string_view word) {
  for (const auto& p : Prefixes()) {
    if (word.size() > p.text.size() && word.substr(0, p.text.size()) == p.text) {
      std::string_view rest = word.substr(p.text.size());
      for (const auto& s : Symbols()) {
        if (rest.substr(0, s.symbol.size()) == s.symbol) {
          auto tail = ParseUnsuffixedRun(rest.substr(s.symbol.size()));
          if (tail) {
            Factor f;
            f.value = p.factor * s.factor * tail->value;
            f.dimension = Add(s.dimension, tail->dimension);
            return f;
          }
        }
      }
    }
  }
  return ParseUnsuffixedRun(word);
}

[[noreturn]] void BadUnit(std::string_view text, std::string_view context, const std::string& why) {
  std::ostringstream out;
  out << context << " = '" << text << "': " << why;
  throw InputError(out.str());
}

Factor ParseUnitExpression(std::string_view text, std::string_view full, std::string_view context) {
  Factor total;
  bool denominator = false;
  size_t i = 0;
  auto is_word_char = [](unsigned char c) { return std::isalpha(c) || c >= 0x80; };
  while (i < text.size()) {
    unsigned char c = static_cast<unsigned char>(text[i]);
    if (std::isspace(c) || c == '*' || c == '.') {
      ++i;
      continue;
    }
    if (c == '/') {
      if (denominator) BadUnit(full, context, "a unit may have only one '/'");
      denominator = true;
      ++i;
      continue;
    }
    Factor factor;
    int half_power = 2;  // doubled exponent of this factor
    if (text.substr(i, 5) == "sqrt(") {
      size_t close = text.find(')', i);
      if (close == std::string_view::npos) BadUnit(full, context, "unclosed 'sqrt('");
      Factor inner = ParseUnitExpression(text.substr(i + 5, close - i - 5), full, context);
      factor.value = std::sqrt(inner.value);
      factor.dimension = inner.dimension;
      half_power = 1;
      i = close + 1;
    } else if (c == '1' && (i + 1 == text.size() || !std::isdigit(static_cast<unsigned char>(text[i + 1])))) {
      ++i;  // the "1" of "1/s"
      continue;
    } else if (is_word_char(c)) {
      size_t start = i;
      while (i < text.size() && is_word_char(static_cast<unsigned char>(text[i]))) ++i;
      std::string_view word = text.substr(start, i - start);
      auto parsed = ParseWord(word);
      if (!parsed) {
        BadUnit(full, context,
                "unknown unit '" + std::string(word) +
                    "' (known: m g s N rad deg rev Hz rpm min h Pa with prefixes p n u m c k M G)");
      }
      factor = *parsed;
    } else {
      BadUnit(full, context, std::string("unexpected character '") + static_cast<char>(c) + "' in the unit");
    }
    int exponent = 1;
    if (i < text.size() && text[i] == '^') {
      ++i;
      size_t start = i;
      if (i < text.size() && (text[i] == '-' || text[i] == '+')) ++i;
      while (i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]))) ++i;
      std::string digits(text.substr(start, i - start));
      if (digits.empty() || digits == "-" || digits == "+") BadUnit(full, context, "'^' needs an integer exponent");
      exponent = std::atoi(digits.c_str());
    }
    int signed_half = (denominator ? -1 : 1) * exponent * half_power;
    total.value *= std::pow(factor.value, signed_half / 2.0);
    total.dimension = Add(total.dimension, Scale(factor.dimension, signed_half, 2));
  }
  return total;
}

struct NamedDimension {
  Dimension dimension;
  std::string_view name;
  std::string_view unit;
};

const std::vector<NamedDimension>& NamedDimensions() {
  static const std::vector<NamedDimension> named = {
      {dim::kDimensionless, "dimensionless number", "1"},
      {dim::kLength, "length", "m"},
      {dim::kAngle, "angle", "rad"},
      {dim::kMass, "mass", "kg"},
      {dim::kInertia, "moment of inertia", "kg m^2"},
      {dim::kTime, "time", "s"},
      {dim::kFrequency, "frequency", "Hz"},
      {dim::kAngularVelocity, "angular velocity", "rad/s"},
      {dim::kForce, "force", "N"},
      {dim::kTorque, "torque", "Nm"},
      {dim::kTranslationalStiffness, "translational stiffness", "N/m"},
      {dim::kRotationalStiffness, "rotational stiffness", "Nm/rad"},
      {dim::kTranslationalDamping, "translational damping", "N s/m"},
      {dim::kRotationalDamping, "rotational damping", "Nm s/rad"},
      {dim::kVelocity, "velocity", "m/s"},
      {dim::kAcceleration, "acceleration", "m/s^2"},
  };
  return named;
}

std::string GenericUnit(Dimension d) {
  std::ostringstream out;
  auto term = [&](const char* symbol, int doubled) {
    if (doubled == 0) return;
    if (out.tellp() > 0) out << ' ';
    out << symbol;
    if (doubled != 2) {
      if (doubled % 2 == 0) {
        out << '^' << doubled / 2;
      } else {
        out << '^' << doubled / 2.0;
      }
    }
  };
  term("kg", d.kg2);
  term("m", d.m2);
  term("s", d.s2);
  term("rad", d.rad2);
  std::string s = out.str();
  return s.empty() ? "1" : s;
}

}  // namespace

Quantity ParseQuantity(std::string_view text, std::string_view context) {
  std::string owned(text);
  const char* begin = owned.c_str();
  while (*begin == ' ' || *begin == '\t') ++begin;
  char* end = nullptr;
  double number = std::strtod(begin, &end);
  if (end == begin) BadUnit(text, context, "expected a number, optionally followed by a unit");
  if (!std::isfinite(number)) BadUnit(text, context, "expected a finite number");
  // strtod accepts "1e" prefixes of words like "1 e"; a unit must be separated or start with a letter.
  Factor unit = ParseUnitExpression(std::string_view(end), text, context);
  Quantity q;
  q.value = number * unit.value;
  q.dimension = unit.dimension;
  return q;
}

double ParseQuantity(std::string_view text, Dimension expected, std::string_view context) {
  Quantity q = ParseQuantity(text, context);
  bool bare = true;
  for (char c : text) {
    if (std::isalpha(static_cast<unsigned char>(c)) && c != 'e' && c != 'E') bare = false;
  }
  if (bare && q.dimension == dim::kDimensionless) return q.value;
  if (q.dimension != expected) {
    std::ostringstream out;
    out << context << " = '" << text << "' has the dimension of a " << DescribeDimension(q.dimension)
        << ", expected a " << DescribeDimension(expected);
    throw InputError(out.str());
  }
  return q.value;
}

std::string SiUnit(Dimension dimension) {
  for (const auto& n : NamedDimensions()) {
    if (n.dimension == dimension) return std::string(n.unit);
  }
  return GenericUnit(dimension);
}

std::string DescribeDimension(Dimension dimension) {
  for (const auto& n : NamedDimensions()) {
    if (n.dimension == dimension) return std::string(n.name) + " (" + std::string(n.unit) + ")";
  }
  return "quantity in " + GenericUnit(dimension);
}

}  // namespace stagefit
