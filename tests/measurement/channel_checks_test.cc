#include "stagefit/measurement/channel_checks.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <tuple>

#include "stagefit/common/error.h"
#include "stagefit/model/model_file.h"
#include "stagefit/synthetic/channel_faults.h"
#include "stagefit/synthetic/outside_catalogue.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace stagefit::measurement {
namespace {

// A sound 12x10 accelerance measurement of a scattered truth without hidden effect.
FrfData Sound(uint64_t seed, double noise, double fmax_hz = 400.0) {
  synthetic::HiddenEffectOptions o;
  o.num_effects = 0;
  o.noise_min = o.noise_max = noise;
  o.fmax_hz = fmax_hz;
  o.fmin_hz = fmax_hz / 40.0;
  return synthetic::MakeHiddenEffectCase(model::DefaultModelSpec(), seed, o).measurement;
}

std::string Describe(const ChannelCheckResult& r) { return r.Report(); }

TEST(CheckChannels, SoundDataGiveNoFinding) {
  for (uint64_t seed : {1, 2, 3, 4})
    for (double noise : {0.01, 0.02, 0.03}) {
      const auto r = CheckChannels(Sound(seed, noise), Eigen::Vector3d::Zero());
      EXPECT_TRUE(r.checked);
      EXPECT_TRUE(r.findings.empty()) << "seed " << seed << " noise " << noise << "\n" << Describe(r);
      EXPECT_TRUE(r.non_rigid.empty()) << "seed " << seed << " noise " << noise << "\n" << Describe(r);
    }
}

TEST(CheckChannels, ReversedSensorIsNamedAndRepaired) {
  const FrfData sound = Sound(5, 0.02);
  FrfData d = sound;
  synthetic::InjectReversed(d, "a2y", false);
  const auto r = CheckChannels(d, Eigen::Vector3d::Zero());
  ASSERT_EQ(r.findings.size(), 1u) << Describe(r);
  EXPECT_EQ(r.findings[0].kind, ChannelFaultKind::kReversed);
  EXPECT_FALSE(r.findings[0].is_input);
  EXPECT_EQ(r.findings[0].channels, std::vector<std::string>{"a2y"});
  const FrfData repaired = RepairChannels(d, r.findings);
  for (int k = 0; k < d.num_frequencies(); ++k) EXPECT_EQ(repaired.frf[k], sound.frf[k]);
  EXPECT_TRUE(CheckChannels(repaired, Eigen::Vector3d::Zero()).findings.empty());
}

TEST(CheckChannels, ReversedVerticalSensorAndImpactAreNamed) {
  for (const auto& [name, is_input] : std::vector<std::pair<std::string, bool>>{{"a3z", false}, {"h4", true}, {"h9", true}}) {
    FrfData d = Sound(6, 0.03);
    synthetic::InjectReversed(d, name, is_input);
    const auto r = CheckChannels(d, Eigen::Vector3d::Zero());
    ASSERT_EQ(r.findings.size(), 1u) << name << "\n" << Describe(r);
    EXPECT_EQ(r.findings[0].kind, ChannelFaultKind::kReversed) << name;
    EXPECT_EQ(r.findings[0].is_input, is_input);
    EXPECT_EQ(r.findings[0].channels, std::vector<std::string>{name});
  }
}

TEST(CheckChannels, SwappedPairIsNamedAndRepaired) {
  // The four vertical sensors have one parity relation, a1z + a3z = a2z + a4z (SPEC §2 layout): exchanging
  // a1z and a2z breaks it exactly as exchanging a3z and a4z would repair it, so that finding is ambiguous.
  for (const auto& [a, b, is_input, ambiguous] : std::vector<std::tuple<std::string, std::string, bool, bool>>{
           {"a1x", "a4y", false, false}, {"a1z", "a2z", false, true}, {"h1", "h3", true, false}}) {
    const FrfData sound = Sound(7, 0.02);
    FrfData d = sound;
    synthetic::InjectSwapped(d, a, b, is_input);
    const auto r = CheckChannels(d, Eigen::Vector3d::Zero());
    ASSERT_EQ(r.findings.size(), 1u) << a << " " << b << "\n" << Describe(r);
    const auto& f = r.findings[0];
    EXPECT_EQ(f.kind, ChannelFaultKind::kSwapped);
    EXPECT_EQ(f.is_input, is_input);
    auto sorted = [](std::vector<std::string> v) {
      std::sort(v.begin(), v.end());
      return v;
    };
    const std::vector<std::string> expected = sorted({a, b});
    bool named = sorted(f.channels) == expected;
    for (const auto& alt : f.alternatives) named = named || sorted(alt) == expected;
    EXPECT_TRUE(named) << Describe(r);
    EXPECT_EQ(!f.alternatives.empty(), ambiguous) << Describe(r);
    EXPECT_EQ(f.repairable, !ambiguous);
    if (ambiguous) continue;
    const FrfData repaired = RepairChannels(d, r.findings);
    for (int k = 0; k < d.num_frequencies(); ++k) EXPECT_EQ(repaired.frf[k], sound.frf[k]);
  }
}

TEST(CheckChannels, ReversalOfOneOfTwoCollinearImpactsIsAmbiguous) {
  // h1 (at +y, pushing -y) and h5 (at -y, pushing +y) act along the same line: for a rigid body h1 = -h5,
  // and reversing either one restores that. The check must say it cannot tell which.
  FrfData d = Sound(13, 0.02);
  synthetic::InjectReversed(d, "h5", true);
  const auto r = CheckChannels(d, Eigen::Vector3d::Zero());
  ASSERT_EQ(r.findings.size(), 1u) << Describe(r);
  EXPECT_EQ(r.findings[0].kind, ChannelFaultKind::kReversed);
  EXPECT_FALSE(r.findings[0].repairable);
  std::vector<std::string> all = r.findings[0].channels;
  for (const auto& a : r.findings[0].alternatives) all.insert(all.end(), a.begin(), a.end());
  std::sort(all.begin(), all.end());
  EXPECT_EQ(all, (std::vector<std::string>{"h1", "h5"}));
}

TEST(CheckChannels, DeadSensorIsNamed) {
  FrfData d = Sound(8, 0.01);
  synthetic::InjectDead(d, "a4x", 1e-3, 3);
  const auto r = CheckChannels(d, Eigen::Vector3d::Zero());
  ASSERT_EQ(r.findings.size(), 1u) << Describe(r);
  EXPECT_EQ(r.findings[0].kind, ChannelFaultKind::kDead);
  EXPECT_EQ(r.findings[0].channels, std::vector<std::string>{"a4x"});
  EXPECT_EQ(ChannelsToExclude(r.findings), std::vector<std::string>{"a4x"});
}

TEST(CheckChannels, ClippedSensorIsNamed) {
  FrfData d = Sound(9, 0.02);
  synthetic::InjectClipped(d, "a2x", 0.5);
  const auto r = CheckChannels(d, Eigen::Vector3d::Zero());
  ASSERT_EQ(r.findings.size(), 1u) << Describe(r);
  EXPECT_EQ(r.findings[0].kind, ChannelFaultKind::kClipped);
  EXPECT_EQ(r.findings[0].channels, std::vector<std::string>{"a2x"});
}

TEST(CheckChannels, LocalResonanceIsNamedWithItsBand) {
  for (const auto& [name, fn] : std::vector<std::pair<std::string, double>>{{"a1y", 60.0}, {"a4z", 150.0}}) {
    FrfData d = Sound(10, 0.02);
    synthetic::InjectLocalResonance(d, name, fn, 15.0);
    const auto r = CheckChannels(d, Eigen::Vector3d::Zero());
    ASSERT_EQ(r.findings.size(), 1u) << name << "\n" << Describe(r);
    const auto& f = r.findings[0];
    EXPECT_EQ(f.kind, ChannelFaultKind::kLocalResonance);
    EXPECT_EQ(f.channels, std::vector<std::string>{name});
    EXPECT_LE(f.low_hz, fn);
    EXPECT_GE(f.high_hz, fn);
    // The amplification 1/|x| of a base-excited mount peaks within a few per cent of fn for Q = 15.
    EXPECT_NEAR(f.peak_hz, fn, 0.05 * fn) << Describe(r);
    EXPECT_FALSE(f.repairable);
  }
}

// The top plate bending in a saddle (outside the catalogue): the four vertical sensors and the four
// vertical impacts do not move as one rigid body in the band of the mode, and no single channel explains
// it. Not a fault (nothing is left out); named as channels not rigid together, with the band and the
// channels, as nothing else names it: the projection to the platform removes it, and the loop ends at the
// floor in compliance space.
// The checks on a plate mode's case `c`: no fault, and the sensors and the impacts named not rigid
// together in a band holding the mode's peak, exactly `sensors` and `impacts` (sorted).
ChannelCheckResult ExpectNamedNotRigid(const synthetic::OutsideCatalogueCase& c, const std::vector<std::string>& sensors,
                                       const std::vector<std::string>& impacts) {
  const auto r = CheckChannels(c.measurement, Eigen::Vector3d::Zero());
  EXPECT_TRUE(r.findings.empty()) << Describe(r);
  EXPECT_EQ(r.non_rigid.size(), 2u) << c.description << "\n" << Describe(r);
  for (const NonRigidBand& n : r.non_rigid) {
    EXPECT_LE(n.low_hz, c.peak_hz) << n.Words();
    EXPECT_GE(n.high_hz, c.peak_hz) << n.Words();
    EXPECT_GT(n.excess, 4.0);
    std::vector<std::string> names = n.channels;
    std::sort(names.begin(), names.end());
    EXPECT_EQ(names, n.is_input ? impacts : sensors) << n.Words();
  }
  return r;
}

TEST(CheckChannels, APlateModeIsNamedNotRigidWithItsBandAndChannels) {
  synthetic::HiddenEffectOptions o = synthetic::EvalLoopCaseOptions(0, 150, 400);
  o.min_visibility = 8;
  const auto c = synthetic::MakeOutsideCatalogueCase(model::DefaultModelSpec(), 11, "plate-bending", o);
  const auto r = ExpectNamedNotRigid(c, {"a1z", "a2z", "a3z", "a4z"}, {"h2", "h4", "h6", "h8"});
  EXPECT_NE(r.Report().find("not rigid: the sensors in"), std::string::npos) << Describe(r);
}

// The top plate breathing in its plane (outside the catalogue): the radial sensors a1y, a3y (at y = +-d)
// and a2x, a4x (at x = +-d) move apart, which no rigid motion does (a rigid one moves a2x and a4x alike),
// and so do the radial impacts. Drawn with the noise per channel (a sensor's floor), the mode changes
// what the channels read and is named with its band and those channels. Drawn with the noise per element,
// the generator scales it to its visibility on elements the rigid model makes nearly zero, whose noise
// it scales down with them: the mode is then heavier and changes no channel by more than its noise, and
// nothing is named.
TEST(CheckChannels, ABreathingModeIsNamedNotRigidWithTheRadialChannels) {
  synthetic::HiddenEffectOptions o = synthetic::EvalLoopCaseOptions(0, 150, 400);
  o.min_visibility = 8;
  o.noise_per_channel = true;
  const auto c = synthetic::MakeOutsideCatalogueCase(model::DefaultModelSpec(), 12, "plate-breathing", o);
  ExpectNamedNotRigid(c, {"a1y", "a2x", "a3y", "a4x"}, {"h1", "h3", "h5", "h7"});

  o.noise_per_channel = false;
  const auto unseen = synthetic::MakeOutsideCatalogueCase(model::DefaultModelSpec(), 12, "plate-breathing", o);
  EXPECT_TRUE(CheckChannels(unseen.measurement, Eigen::Vector3d::Zero()).non_rigid.empty()) << unseen.description;
}

// A vertical sensor turned on its mount (its declared direction 15 degrees off the one it measures
// along): the sensors are not rigid as declared, but a turned channel's direction, as the others' rigid
// motion gives it, makes them rigid: a fault of the set-up the loop corrects, not channels that do not
// move as one. (The four vertical sensors observe three DoF with one redundancy, and the turn of one
// can be put on another: FindTurnedChannel names a2z here, which makes them rigid as well.)
TEST(CheckChannels, ATurnedSensorIsNotNamedNotRigid) {
  FrfData d = Sound(12, 0.02, 150.0);
  for (auto& c : d.outputs) {
    if (c.name == "a3z") c.direction_W = Eigen::AngleAxisd(15.0 * M_PI / 180.0, Eigen::Vector3d(1, 1, 0).normalized()) * c.direction_W;
  }
  const auto r = CheckChannels(d, Eigen::Vector3d::Zero());
  EXPECT_TRUE(r.non_rigid.empty()) << Describe(r);
  EXPECT_NE(r.skipped_reason.find("are not rigid in"), std::string::npos) << Describe(r);
  EXPECT_NE(r.skipped_reason.find("a channel turned on its mount, a"), std::string::npos) << Describe(r);
  EXPECT_NE(r.skipped_reason.find("z (15 degrees)"), std::string::npos) << Describe(r);
}

TEST(CheckChannels, SkipsDataWithoutGeometry) {
  FrfData d = Sound(11, 0.01);
  for (auto& c : d.outputs) c.body.clear();
  const auto r = CheckChannels(d, Eigen::Vector3d::Zero());
  EXPECT_FALSE(r.checked);
  EXPECT_NE(r.Report().find("skipped"), std::string::npos);
}

TEST(ExcludeChannels, DropsOutputsAndInputsAndRejectsUnknownNames) {
  FrfData d = Sound(12, 0.01);
  d.averages = {2, 3, 4, 5, 6, 7, 8, 9, 10, 11};  // the hits averaged follow their inputs
  const FrfData e = ExcludeChannels(d, {"a2z", "h3"});
  ASSERT_EQ(e.num_outputs(), 11);
  ASSERT_EQ(e.num_inputs(), 9);
  EXPECT_EQ(e.averages, (std::vector<int>{2, 3, 5, 6, 7, 8, 9, 10, 11}));
  EXPECT_EQ(e.outputs[4].name, "a2y");
  EXPECT_EQ(e.outputs[5].name, "a3x");
  EXPECT_EQ(e.inputs[2].name, "h4");
  for (int k = 0; k < d.num_frequencies(); k += 37) {
    EXPECT_EQ(e.frf[k](5, 2), d.frf[k](6, 3));  // a3x <- h4
    EXPECT_EQ(e.coherence[k](5, 2), d.coherence[k](6, 3));
  }
  try {
    ExcludeChannels(d, {"a9q"});
    FAIL() << "no error";
  } catch (const InputError& err) {
    EXPECT_NE(std::string(err.what()).find("'a9q'"), std::string::npos) << err.what();
    EXPECT_NE(std::string(err.what()).find("a1x"), std::string::npos) << err.what();
  }
}

}  // namespace
}  // namespace stagefit::measurement
