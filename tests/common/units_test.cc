#include "stagefit/common/units.h"

#include <gtest/gtest.h>

#include <cmath>

#include "stagefit/common/error.h"

namespace stagefit {
namespace {

constexpr double kRelTol = 1e-14;  // unit factors are exact decimal scalings

TEST(ParseQuantity, ConvertsSpecExamplesToSi) {
  EXPECT_NEAR(ParseQuantity("200 N/um", dim::kTranslationalStiffness, "t"), 2e8, 2e8 * kRelTol);
  EXPECT_NEAR(ParseQuantity("1.5 Nm/urad", dim::kRotationalStiffness, "t"), 1.5e6, 1.5e6 * kRelTol);
  EXPECT_DOUBLE_EQ(ParseQuantity("25 kg", dim::kMass, "t"), 25.0);
  EXPECT_NEAR(ParseQuantity("150 mm", dim::kLength, "t"), 0.15, 0.15 * kRelTol);
  EXPECT_NEAR(ParseQuantity("60 rpm", dim::kAngularVelocity, "t"), 2 * M_PI, 1e-12);
  EXPECT_NEAR(ParseQuantity("2 deg", dim::kAngle, "t"), 2 * M_PI / 180, 1e-15);
}

TEST(ParseQuantity, BareNumbersAreSi) {
  EXPECT_DOUBLE_EQ(ParseQuantity("5e9", dim::kTranslationalStiffness, "t"), 5e9);
  EXPECT_DOUBLE_EQ(ParseQuantity("-0.9", dim::kLength, "t"), -0.9);
}

TEST(ParseQuantity, CompoundUnits) {
  EXPECT_NEAR(ParseQuantity("8e4 N s/m", dim::kTranslationalDamping, "t"), 8e4, 1e-9);
  EXPECT_NEAR(ParseQuantity("3e4 Nms/rad", dim::kRotationalDamping, "t"), 3e4, 1e-9);
  EXPECT_NEAR(ParseQuantity("3e4 Nm s/rad", dim::kRotationalDamping, "t"), 3e4, 1e-9);
  EXPECT_NEAR(ParseQuantity("380 kg m^2", dim::kInertia, "t"), 380, 1e-12);
  EXPECT_NEAR(ParseQuantity("9.81 m/s^2", dim::kAcceleration, "t"), 9.81, 1e-12);
  EXPECT_NEAR(ParseQuantity("2 ms", dim::kTime, "t"), 2e-3, 1e-18);
  EXPECT_NEAR(ParseQuantity("1 kHz", dim::kFrequency, "t"), 1e3, 1e-12);
  Quantity asd = ParseQuantity("1e-8 m/sqrt(Hz)", "t");
  EXPECT_EQ(asd.dimension, (Dimension{0, 2, 1, 0}));
  EXPECT_DOUBLE_EQ(asd.value, 1e-8);
}

TEST(ParseQuantity, RejectsWrongDimensionNamingBoth) {
  try {
    ParseQuantity("200 N", dim::kTranslationalStiffness, "joint 'ty': stiffness.Dx");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    std::string message = e.what();
    EXPECT_NE(message.find("joint 'ty': stiffness.Dx"), std::string::npos) << message;
    EXPECT_NE(message.find("force (N)"), std::string::npos) << message;
    EXPECT_NE(message.find("translational stiffness (N/m)"), std::string::npos) << message;
  }
}

TEST(ParseQuantity, RotationalStiffnessIsNotTorque) {
  EXPECT_THROW(ParseQuantity("1.5 Nm", dim::kRotationalStiffness, "t"), InputError);
}

TEST(ParseQuantity, RejectsGarbage) {
  EXPECT_THROW(ParseQuantity("abc", dim::kLength, "t"), InputError);
  EXPECT_THROW(ParseQuantity("3 furlongs", dim::kLength, "t"), InputError);
  EXPECT_THROW(ParseQuantity("nan m", dim::kLength, "t"), InputError);
  EXPECT_THROW(ParseQuantity("1 m/s/s", dim::kAcceleration, "t"), InputError);
  EXPECT_THROW(ParseQuantity("1 m^", dim::kLength, "t"), InputError);
}

}  // namespace
}  // namespace stagefit
