#pragma once
// Unit strings at the edge: "200 N/um", "1.5 Nm/urad", "25 kg", "150 mm", "60 rpm", "2 deg".
// Everything inside the code is SI; this is the one place where units are converted.
//
// Grammar: a number, optionally followed by a unit expression. A unit expression is a product of
// unit words (separated by spaces or '*'); the first '/' starts the denominator ("N s/m",
// "m/s^2", "m^2/Hz", "m/sqrt(Hz)"). A word is a run of unit symbols with an optional SI prefix on the
// first one only ("Nms" = N*m*s, "ms" = millisecond, "mm" = millimetre). Exponents: "^2", "^-1".
// Symbols: m g s N rad deg rev Hz rpm min h Pa; prefixes p n u µ m c k M G.
// Angles are their own dimension, so a rotational stiffness (Nm/rad) is not a torque (Nm).

#include <string>
#include <string_view>

namespace stagefit {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kDegreesPerRadian = 180.0 / kPi;

/// Physical dimension as exponents of kg, m, s and rad, stored doubled so that sqrt(Hz) is exact.
struct Dimension {
  int kg2 = 0, m2 = 0, s2 = 0, rad2 = 0;
  friend bool operator==(const Dimension& a, const Dimension& b) {
    return a.kg2 == b.kg2 && a.m2 == b.m2 && a.s2 == b.s2 && a.rad2 == b.rad2;
  }
  friend bool operator!=(const Dimension& a, const Dimension& b) { return !(a == b); }
};

namespace dim {
// Named dimensions used by the model and measurement files.
inline constexpr Dimension kDimensionless{};
inline constexpr Dimension kLength{0, 2, 0, 0};
inline constexpr Dimension kAngle{0, 0, 0, 2};
inline constexpr Dimension kMass{2, 0, 0, 0};
inline constexpr Dimension kInertia{2, 4, 0, 0};
inline constexpr Dimension kTime{0, 0, 2, 0};
inline constexpr Dimension kFrequency{0, 0, -2, 0};
inline constexpr Dimension kAngularVelocity{0, 0, -2, 2};
inline constexpr Dimension kForce{2, 2, -4, 0};
inline constexpr Dimension kTorque{2, 4, -4, 0};
inline constexpr Dimension kTranslationalStiffness{2, 0, -4, 0};
inline constexpr Dimension kRotationalStiffness{2, 4, -4, -2};
inline constexpr Dimension kTranslationalDamping{2, 0, -2, 0};
inline constexpr Dimension kRotationalDamping{2, 4, -2, -2};
inline constexpr Dimension kVelocity{0, 2, -2, 0};
inline constexpr Dimension kAcceleration{0, 2, -4, 0};
}  // namespace dim

/// A value in SI units with its dimension.
struct Quantity {
  double value = 0.0;
  Dimension dimension;
};

/// Parses "number [unit]" into SI. Throws InputError naming `context` (e.g. "model.toml: joint 'ty':
/// stiffness.Dx") and the offending text when the text is not a number followed by a known unit.
Quantity ParseQuantity(std::string_view text, std::string_view context);

/// Parses and checks the dimension; a bare number is taken as SI in the expected dimension.
/// Throws InputError: "<context> = '200 N' has the dimension of a force (N), expected a translational
/// stiffness (N/m)".
double ParseQuantity(std::string_view text, Dimension expected, std::string_view context);

/// Human name and SI unit of a dimension: "translational stiffness (N/m)"; generic ones are
/// written as kg^a m^b s^c rad^d.
std::string DescribeDimension(Dimension dimension);

/// The SI unit string of a dimension, e.g. "N/m", "Nm/rad", "kg m^2".
std::string SiUnit(Dimension dimension);

}  // namespace stagefit
