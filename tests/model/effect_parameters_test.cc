// Effects as parameterised parts of a model: the base and the ordered effects, re-expanded when a
// parameter changes, kept in model files as [[effect]] tables.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "stagefit/common/error.h"
#include "stagefit/kinematics/rigid_transform.h"
#include "stagefit/model/assembled_model.h"
#include "stagefit/model/effects.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"

namespace stagefit::model {
namespace {

ModelSpec WithEffects() {
  ModelSpec spec = DefaultModelSpec();
  for (const char* text : {"payload@hexapod:mass=3,z=0.05", "joint-offset@ty:dz=0.02", "coupled-stiffness@hexapod.Dx-Ry:k=1e5",
                           "sensor-geometry@a2x:dx=2 mm,rz=0.1", "extra-body@rz:mass=4,k=1e7,kr=1e5",
                           "structural-damping@ry:eta=0.03", "delay@acquisition:tau=1e-4"}) {
    ApplyEffect(spec, ParseEffect(text, spec));
  }
  return spec;
}

bool SameMatrices(const ModelSpec& a, const ModelSpec& b) {
  const auto x = AssembledModel::Assemble(a), y = AssembledModel::Assemble(b);
  return x.M() == y.M() && x.K() == y.K() && x.C() == y.C() && x.K_loss() == y.K_loss();
}

TEST(EffectParameters, TheBaseIsTheDescriptionBeforeTheFirstEffect) {
  const ModelSpec nominal = DefaultModelSpec();
  const ModelSpec spec = WithEffects();
  ASSERT_TRUE(spec.base);
  EXPECT_EQ(WriteModelToml(*spec.base), WriteModelToml(nominal));
  EXPECT_EQ(spec.effects.size(), 7u);
  EXPECT_EQ(spec.bodies.size(), nominal.bodies.size() + 1);  // the extra body
  // The expansion from the base is the description the effects were applied to one by one.
  const ModelSpec expanded = ExpandEffects(*spec.base, spec.effects);
  EXPECT_EQ(WriteModelToml(expanded), WriteModelToml(spec));
  EXPECT_TRUE(SameMatrices(expanded, spec));
}

TEST(EffectParameters, EveryEffectParameterIsListedByName) {
  const ModelSpec spec = WithEffects();
  const auto all = ListParameters(spec);
  auto has = [&](const std::string& name) {
    for (const auto& p : all) {
      if (p.name == name) return true;
    }
    return false;
  };
  EXPECT_TRUE(has("payload@hexapod.mass"));
  EXPECT_TRUE(has("payload@hexapod.z"));
  EXPECT_TRUE(has("sensor-geometry@a2x.rz"));
  EXPECT_TRUE(has("coupled-stiffness@hexapod.Dx-Ry.k"));
  EXPECT_TRUE(has("delay@acquisition.tau"));
  EXPECT_TRUE(has("hexapod.k.Dz"));
  // The extra body's joint and the effect's coupling are the effects' parameters, not the model's.
  EXPECT_FALSE(has("rz_extra.k.Dx"));
  EXPECT_FALSE(has("hexapod.k.Dx-Ry"));
  EXPECT_EQ(MatchParameters(spec, {"*@*"}).size(), 4u + 3u + 1u + 6u + 4u + 1u + 1u);
  // By default every effect parameter is fitted but a2x's offset along x and turn about x, which
  // change nothing a2x reads (EffectDefinition::redundant).
  EXPECT_EQ(MatchParameters(spec, WithEffectParameters({"*.k.*"}, spec)).size(),
            MatchParameters(spec, {"*.k.*"}).size() + 18u);
}

TEST(EffectParameters, SettingAnEffectParameterReexpandsFromTheBase) {
  ModelSpec spec = WithEffects();
  const ModelSpec before = spec;
  SetParameter(spec, FindParameter(spec, "payload@hexapod.mass"), 7.5);
  SetParameter(spec, FindParameter(spec, "joint-offset@ty.dz"), -0.04);
  EXPECT_EQ(GetParameter(spec, FindParameter(spec, "payload@hexapod.mass")), 7.5);
  std::vector<Effect> effects = before.effects;
  effects[0].parameters["mass"] = 7.5;
  effects[1].parameters["dz"] = -0.04;
  const ModelSpec direct = ExpandEffects(*before.base, effects);
  EXPECT_EQ(WriteModelToml(spec), WriteModelToml(direct));
  EXPECT_TRUE(SameMatrices(spec, direct));
  EXPECT_EQ(spec.bodies[4].mass_kg, before.base->bodies[4].mass_kg + 7.5);
  // The copy it was made from is untouched (the base is copied on write).
  EXPECT_EQ(before.effects[0].parameters.at("mass"), 3.0);
  EXPECT_EQ(before.bodies[4].mass_kg, before.base->bodies[4].mass_kg + 3.0);
}

TEST(EffectParameters, AStiffnessIsSetInTheBaseAndTheExpandedDescription) {
  ModelSpec spec = WithEffects();
  const ModelSpec copy = spec;
  SetParameter(spec, FindParameter(spec, "hexapod.k.Dz"), 3.5e8);
  EXPECT_EQ(spec.base->joints[4].stiffness[2], 3.5e8);
  EXPECT_EQ(spec.joints[4].stiffness[2], 3.5e8);
  EXPECT_EQ(copy.base->joints[4].stiffness[2], DefaultModelSpec().joints[4].stiffness[2]);
  EXPECT_TRUE(SameMatrices(spec, ExpandEffects(*spec.base, spec.effects)));
  // A damping the structural damping replaces, and a mass a payload builds on: re-expanded.
  SetParameter(spec, FindParameter(spec, "ry.c.Dx"), 123.0);
  EXPECT_EQ(spec.base->joints[2].damping[0], 123.0);
  EXPECT_EQ(spec.joints[2].damping[0], 0.0);
  SetParameter(spec, FindParameter(spec, "hexapod.m"), 20.0);
  EXPECT_EQ(GetParameter(spec, FindParameter(spec, "hexapod.m")), 20.0);
  EXPECT_DOUBLE_EQ(spec.bodies[4].mass_kg, 23.0);
  EXPECT_TRUE(SameMatrices(spec, ExpandEffects(*spec.base, spec.effects)));
  EXPECT_FALSE(HasAnalyticDerivative(spec, FindParameter(spec, "hexapod.m")));
  EXPECT_FALSE(HasAnalyticDerivative(spec, FindParameter(spec, "ry.c.Dx")));
  EXPECT_TRUE(HasAnalyticDerivative(spec, FindParameter(spec, "ry.k.Dx")));
  EXPECT_TRUE(HasAnalyticDerivative(DefaultModelSpec(), FindParameter(DefaultModelSpec(), "hexapod.m")));
}

TEST(EffectParameters, AValueTheEditRejectsLeavesTheSpecUnchanged) {
  ModelSpec spec = WithEffects();
  const std::string before = WriteModelToml(spec);
  EXPECT_THROW(SetParameter(spec, FindParameter(spec, "payload@hexapod.mass"), -1.0), InputError);
  EXPECT_EQ(WriteModelToml(spec), before);
  EXPECT_THROW(SetParameter(spec, FindParameter(spec, "extra-body@rz.k"), -1e7), InputError);
  EXPECT_EQ(WriteModelToml(spec), before);
}

TEST(EffectParameters, AModelFileKeepsTheEffectsAsTablesAndReproducesTheModelBitForBit) {
  ModelSpec spec = WithEffects();
  SetParameter(spec, FindParameter(spec, "hexapod.k.Rx"), 1.2345678901234567e6);
  SetParameter(spec, FindParameter(spec, "payload@hexapod.mass"), 2.718281828459045);
  const std::string text = WriteModelToml(spec);
  EXPECT_NE(text.find("[[effect]]\nname = \"payload\"\nlocation = \"hexapod\"\nmass = 2.718281828459045"), std::string::npos);
  const ModelSpec back = ParseModelToml(text, "effects.toml");
  EXPECT_EQ(back.effects, spec.effects);
  EXPECT_EQ(WriteModelToml(back), text);
  EXPECT_TRUE(SameMatrices(back, spec));
  EXPECT_EQ(back.geometry_corrections.size(), 1u);
  EXPECT_EQ(back.acquisition_delay_s, 1e-4);
  // The body of the file is the base: the payload is not counted twice.
  EXPECT_EQ(back.bodies[4].mass_kg, spec.bodies[4].mass_kg);
}

TEST(EffectParameters, EffectTablesTakeUnitsAndDefaults) {
  std::string text = WriteModelToml(DefaultModelSpec());
  text += "\n[[effect]]\nname = \"payload\"\nlocation = \"hexapod\"\nmass = \"5 kg\"\nz = \"100 mm\"\n";
  text += "\n[[effect]]\nname = \"servo-stiffness\"\nlocation = \"ty.Dy\"\nk = \"2e8 N/m\"\n";
  const ModelSpec spec = ParseModelToml(text, "units.toml");
  ASSERT_EQ(spec.effects.size(), 2u);
  EXPECT_EQ(spec.effects[0].parameters.at("mass"), 5.0);
  EXPECT_DOUBLE_EQ(spec.effects[0].parameters.at("z"), 0.1);
  EXPECT_EQ(spec.effects[0].parameters.at("x"), 0.0);  // the catalogue's default
  EXPECT_EQ(spec.effects[1].parameters.at("k"), 2e8);
  EXPECT_FALSE(spec.joints[1].imposed[1]);
}

TEST(EffectParameters, BadEffectTablesAreNamed) {
  const std::string base = WriteModelToml(DefaultModelSpec());
  auto error_of = [&](const std::string& extra) {
    try {
      ParseModelToml(base + extra, "bad.toml");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  std::string e = error_of("\n[[effect]]\nname = \"paylaod\"\nlocation = \"hexapod\"\n");
  EXPECT_NE(e.find("bad.toml"), std::string::npos) << e;
  EXPECT_NE(e.find("'paylaod' is not an effect of the catalogue"), std::string::npos) << e;
  e = error_of("\n[[effect]]\nname = \"payload\"\nlocation = \"hexapod\"\nmas = 5\n");
  EXPECT_NE(e.find("unknown key 'mas'"), std::string::npos) << e;
  EXPECT_NE(e.find("mass, x, y, z"), std::string::npos) << e;
  e = error_of("\n[[effect]]\nname = \"payload\"\nlocation = \"hexapod\"\nmass = -5\n");
  EXPECT_NE(e.find("payload@hexapod"), std::string::npos) << e;
  EXPECT_NE(e.find("mass = -5"), std::string::npos) << e;
  e = error_of("\n[[effect]]\nname = \"payload\"\nlocation = \"nowhere\"\n");
  EXPECT_NE(e.find("'nowhere' is not a body"), std::string::npos) << e;
  e = error_of("\n[[effect]]\nname = \"payload\"\nlocation = \"hexapod\"\nz = \"5 kg\"\n");
  EXPECT_NE(e.find("z"), std::string::npos) << e;
  EXPECT_NE(e.find("length"), std::string::npos) << e;
}

// A held parameter keeps its value through every fit: it is in the text form and the model file, and
// left out of the effect parameters a fit frees by default (an explicit name still matches it).
TEST(EffectParameters, AHeldParameterIsKeptInTextAndFileAndLeftOutOfTheFit) {
  ModelSpec spec = DefaultModelSpec();
  const Effect e = ParseEffect("sensor-geometry@a2x:dy=0,rz=0.1,held=dy,held=rz", spec);
  EXPECT_EQ(e.held, (std::vector<std::string>{"dy", "rz"}));
  EXPECT_EQ(ParseEffect(e.ToString(), spec), e);
  EXPECT_NE(e.ToString().find(",held=dy,held=rz"), std::string::npos) << e.ToString();
  // Kept in catalogue order, once, whatever the order given.
  EXPECT_EQ(ParseEffect("sensor-geometry@a2x:held=rz,held=dy,held=rz", spec).held, e.held);
  ApplyEffect(spec, e);
  ApplyEffect(spec, ParseEffect("payload@hexapod:mass=3", spec));
  const std::string text = WriteModelToml(spec);
  EXPECT_NE(text.find("held = [\"dy\", \"rz\"]"), std::string::npos) << text;
  const ModelSpec back = ParseModelToml(text, "held.toml");
  EXPECT_EQ(back.effects, spec.effects);
  EXPECT_EQ(WriteModelToml(back), text);
  const std::vector<std::string> patterns = EffectParameterPatterns(spec);
  auto has = [&](const std::string& p) { return std::find(patterns.begin(), patterns.end(), p) != patterns.end(); };
  EXPECT_TRUE(has("payload@hexapod.*"));
  // a2x's own axis (dx, rx) is redundant; dy and rz are held.
  EXPECT_TRUE(has("sensor-geometry@a2x.dz"));
  EXPECT_TRUE(has("sensor-geometry@a2x.ry"));
  EXPECT_FALSE(has("sensor-geometry@a2x.dy"));
  EXPECT_FALSE(has("sensor-geometry@a2x.rz"));
  EXPECT_EQ(MatchParameters(spec, {"sensor-geometry@a2x.rz"}).size(), 1u);
}

TEST(EffectParameters, ABadHeldParameterIsNamed) {
  const ModelSpec spec = DefaultModelSpec();
  try {
    ParseEffect("payload@hexapod:held=mas", spec);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("held = 'mas' is not a parameter of payload (it has mass, x, y, z)"), std::string::npos)
        << e.what();
  }
  const std::string base = WriteModelToml(spec);
  for (const char* held : {"[\"mas\"]", "\"mass\"", "[3]"}) {
    try {
      ParseModelToml(base + "\n[[effect]]\nname = \"payload\"\nlocation = \"hexapod\"\nheld = " + held + "\n", "bad.toml");
      ADD_FAILURE() << "no error for held = " << held;
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("bad.toml"), std::string::npos) << what;
      EXPECT_NE(what.find("held must be an array of parameter names of payload (mass, x, y, z)"), std::string::npos) << what;
    }
  }
}

TEST(EffectParameters, OldFilesWithEffectTextStillLoad) {
  // Before effects were kept as parameters, a file held the edited bodies and the effects as text.
  ModelSpec nominal = DefaultModelSpec();
  std::string text = WriteModelToml(nominal);
  const std::string key = "compliance_frame = \"X\"\n";
  text.replace(text.find(key), key.size(), key + "effects = [\"payload@hexapod:mass=5,x=0,y=0,z=0\"]\n");
  const ModelSpec old = ParseModelToml(text, "old.toml");
  EXPECT_TRUE(old.effects.empty());
  EXPECT_FALSE(old.base);
  ASSERT_EQ(old.baked_effects.size(), 1u);
  EXPECT_EQ(old.bodies[4].mass_kg, nominal.bodies[4].mass_kg);  // nothing applied twice
  EXPECT_EQ(WriteModelToml(old), text);
}

TEST(EffectParameters, ChannelTurnsComposeAsRotations) {
  ModelSpec spec = DefaultModelSpec();
  const int s = [&] {
    for (size_t k = 0; k < spec.sensors.size(); ++k) {
      if (spec.sensors[k].name == "a2x") return static_cast<int>(k);
    }
    return -1;
  }();
  ASSERT_GE(s, 0);
  const Eigen::Vector3d d0 = spec.sensors[s].direction_W;
  ApplyEffect(spec, ParseEffect("sensor-geometry@a2x:rx=0.2", spec));
  ApplyEffect(spec, ParseEffect("sensor-geometry@a2x:rz=0.3", spec));
  const Eigen::Matrix3d expected = kinematics::RotationFromEuler({0, 0, 0.3}) * kinematics::RotationFromEuler({0.2, 0, 0});
  ASSERT_EQ(spec.geometry_corrections.size(), 1u);
  const Eigen::Vector3d r = spec.geometry_corrections[0].rotation_rad;
  EXPECT_TRUE(kinematics::RotationFromEuler({r(0), r(1), r(2)}).isApprox(expected, 1e-14));
  EXPECT_TRUE(spec.sensors[s].direction_W.isApprox(expected * d0, 1e-14));
  // Not the sum of the angles: Rz(0.3) Rx(0.2) differs from the Euler XYZ rotation (0.2, 0, 0.3).
  EXPECT_FALSE(expected.isApprox(kinematics::RotationFromEuler({0.2, 0, 0.3}), 1e-3));
}

TEST(EffectParameters, EveryCatalogueEntryCarriesItsOwnRules) {
  const ModelSpec spec = DefaultModelSpec();
  for (const auto& def : EffectCatalogue()) {
    EXPECT_TRUE(def.defaults && def.apply && def.range && def.explain) << def.name;
    const auto locations = EffectLocations(spec, def.name, {"a2x"});
    ASSERT_FALSE(locations.empty()) << def.name;
    Effect e{def.name, locations.front(), DefaultEffectParameters(spec, def.name, locations.front())};
    EXPECT_FALSE(ExplainEffect(e).empty()) << def.name;
    for (const auto& p : def.parameters) {
      const EffectParameterRange r = EffectRange(spec, e, p.name);
      EXPECT_LE(r.lower, e.parameters.at(p.name)) << def.name << "." << p.name;
      EXPECT_GE(r.upper, e.parameters.at(p.name)) << def.name << "." << p.name;
    }
  }
}

}  // namespace
}  // namespace stagefit::model
