#include "stagefit/synthetic/outside_catalogue.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "stagefit/common/error.h"
#include "stagefit/model/model_file.h"

namespace stagefit::synthetic {
namespace {

HiddenEffectOptions Options() {
  HiddenEffectOptions o;
  o.fmin_hz = 5;
  o.fmax_hz = 600;
  o.num_frequencies = 300;
  return o;
}

std::vector<std::string> Sorted(std::vector<std::string> v) {
  std::sort(v.begin(), v.end());
  return v;
}

// The saddle mode moves only the vertical channels, all four by the same amount (|phi| = 1): the
// change sits on exactly the four vertical accelerometers and the four vertical impacts.
TEST(OutsideCatalogue, PlateBendingChangesTheVerticalChannelsOnly) {
  const auto c = MakeOutsideCatalogueCase(model::DefaultModelSpec(), 11, "plate-bending", Options());
  EXPECT_EQ(Sorted(c.outputs), (std::vector<std::string>{"a1z", "a2z", "a3z", "a4z"}));
  EXPECT_EQ(Sorted(c.inputs), (std::vector<std::string>{"h2", "h4", "h6", "h8"}));
  EXPECT_GE(c.visibility, Options().min_visibility * (1 - 1e-9));
  EXPECT_LE(c.visibility, 4 * Options().min_visibility * (1 + 1e-9));
  EXPECT_GE(c.peak_hz, 0.3 * 600 * 0.97);
  EXPECT_LE(c.peak_hz, 0.9 * 600 * 1.03);
}

// The breathing mode moves the in-plane channels that point radially: a1y, a3y at y = +-d and a2x,
// a4x at x = +-d; the tangential ones (a1x, a3x, a2y, a4y) and the off-centre x hits h9, h10 not at all.
TEST(OutsideCatalogue, PlateBreathingChangesTheRadialChannelsOnly) {
  const auto c = MakeOutsideCatalogueCase(model::DefaultModelSpec(), 12, "plate-breathing", Options());
  EXPECT_EQ(Sorted(c.outputs), (std::vector<std::string>{"a1y", "a2x", "a3y", "a4x"}));
  EXPECT_EQ(Sorted(c.inputs), (std::vector<std::string>{"h1", "h3", "h5", "h7"}));
}

TEST(OutsideCatalogue, CableIsScaledToTheDrawnVisibilityAndTheCaseIsReproducible) {
  const auto a = MakeOutsideCatalogueCase(model::DefaultModelSpec(), 13, "cable", Options());
  const auto b = MakeOutsideCatalogueCase(model::DefaultModelSpec(), 13, "cable", Options());
  EXPECT_GE(a.visibility, 0.99 * Options().min_visibility);
  EXPECT_LE(a.visibility, 1.01 * 4 * Options().min_visibility);
  EXPECT_NE(a.description.find("cable between the granite and the hexapod"), std::string::npos);
  ASSERT_EQ(a.measurement.num_frequencies(), b.measurement.num_frequencies());
  for (int k = 0; k < a.measurement.num_frequencies(); ++k) EXPECT_EQ(a.measurement.frf[k], b.measurement.frf[k]);
}

// A lightly damped mode changes the data most in the band that holds it: the first of the bands
// holding half the change is the peak's.
TEST(OutsideCatalogue, TheBandsHoldingHalfTheChangeStartWithThePeaksForAPlateMode) {
  const auto c = MakeOutsideCatalogueCase(model::DefaultModelSpec(), 11, "plate-bending", Options());
  ASSERT_FALSE(c.bands.empty());
  EXPECT_GE(c.peak_hz, c.bands[0].low_hz);
  EXPECT_LT(c.peak_hz, c.bands[0].high_hz);
  for (const auto& b : c.bands) EXPECT_NEAR(b.high_hz / b.low_hz, std::pow(2.0, 1.0 / 3), 1e-9);  // third octaves
}

// A cable along x (y) pulls the hexapod, and the platform above it, along x (y): the platform's
// accelerance changes most in its own direct element, Dx/Fx (Dy/Fy); along both, in one of them.
TEST(OutsideCatalogue, ACableChangesThePlatformsElementAlongIt) {
  std::set<std::string> axes;
  for (uint64_t seed = 20; seed < 29; ++seed) {
    const auto c = MakeOutsideCatalogueCase(model::DefaultModelSpec(), seed, "cable", Options());
    ASSERT_FALSE(c.elements.empty()) << seed;
    const bool x = c.description.find("along x,") != std::string::npos, y = c.description.find("along y,") != std::string::npos;
    if (x) EXPECT_EQ(c.elements[0], "Dx/Fx") << c.description;
    if (y) EXPECT_EQ(c.elements[0], "Dy/Fy") << c.description;
    if (!x && !y) {  // along both: the direct element of one of them first (the stack is stiffer along one)
      EXPECT_TRUE(c.elements[0] == "Dx/Fx" || c.elements[0] == "Dy/Fy") << c.description << ": " << c.elements[0];
    }
    axes.insert(x ? "x" : y ? "y" : "x and y");
  }
  EXPECT_EQ(axes.size(), 3u) << "the seeds no longer draw a cable of each kind";
}

TEST(OutsideCatalogue, DrawsAKindWhenNoneIsGivenAndRejectsAnUnknownOne) {
  const auto c = MakeOutsideCatalogueCase(model::DefaultModelSpec(), 14, "", Options());
  EXPECT_TRUE(c.kind == "plate-bending" || c.kind == "plate-breathing" || c.kind == "cable") << c.kind;
  try {
    MakeOutsideCatalogueCase(model::DefaultModelSpec(), 14, "gravity-wave", Options());
    FAIL() << "no error for an unknown kind";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'gravity-wave'"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace stagefit::synthetic
