#include "stagefit/model/model_file.h"

#include <gtest/gtest.h>

#include <regex>

#include "stagefit/common/error.h"

namespace stagefit::model {
namespace {

// A small valid model; each validation test edits one line of it.
const char* kValid = R"(
[model]
name = "two stages"
compliance_frame = "top"

[[body]]
name = "base"
mass = "100 kg"
com = [0, 0, -0.5]
inertia = [5, 6, 7]

[[body]]
name = "plate"
mass = "10 kg"
com = [0, 0, "-50 mm"]
inertia = [0.1, 0.1, 0.15]

[[joint]]
name = "base"
parent = "ground"
child = "base"
origin = [0, 0, -1]
stiffness = { Dx = "1e8 N/m", Dy = "1e8 N/m", Dz = "1e8 N/m", Rx = "1e6 Nm/rad", Ry = "1e6 Nm/rad", Rz = "1e6 Nm/rad" }

[[joint]]
name = "plate"
parent = "base"
child = "plate"
origin = [0, 0, 0]
imposed = ["Rz"]
stiffness = { Dx = "20 N/um", Dy = "2e7", Dz = "1e8 N/m", Rx = "1.5 Nm/urad", Ry = "1.5e6 Nm/rad" }
damping = { Dx = "500 N s/m" }

[[frame]]
name = "top"
body = "plate"
origin = [0, 0, -0.03]
)";

std::string Edit(const std::string& from, const std::string& to) {
  std::string text = kValid;
  size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

// Parses `text`, expects InputError, returns its message.
std::string ErrorOf(const std::string& text) {
  try {
    ParseModelToml(text, "test.toml");
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected an InputError";
  return "";
}

void ExpectMessage(const std::string& message, const std::vector<std::string>& fragments) {
  for (const auto& f : fragments) EXPECT_NE(message.find(f), std::string::npos) << "missing '" << f << "' in:\n" << message;
}

TEST(ModelFile, ValidModelParsesWithUnits) {
  ModelSpec spec = ParseModelToml(kValid, "test.toml");
  ASSERT_EQ(spec.bodies.size(), 2u);
  EXPECT_DOUBLE_EQ(spec.bodies[1].com_W.z(), -0.05);
  EXPECT_DOUBLE_EQ(spec.joints[1].stiffness[0], 2e7);
  EXPECT_DOUBLE_EQ(spec.joints[1].stiffness[3], 1.5e6);
  EXPECT_TRUE(spec.joints[1].imposed[5]);
  EXPECT_DOUBLE_EQ(spec.joints[1].damping[0], 500.0);
}

TEST(ModelFile, UnknownKeyIsReportedAsTypo) {
  ExpectMessage(ErrorOf(Edit("mass = \"10 kg\"", "mas = \"10 kg\"")),
                {"test.toml:", "body 'plate'", "unknown key 'mas'", "'mass' is missing"});
}

TEST(ModelFile, NegativeMassIsRejected) {
  ExpectMessage(ErrorOf(Edit("\"10 kg\"", "\"-10 kg\"")), {"body 'plate'", "mass = -10 kg", "expected a finite value > 0"});
}

TEST(ModelFile, InertiaNotPositiveDefiniteIsRejected) {
  ExpectMessage(ErrorOf(Edit("[0.1, 0.1, 0.15]", "[0.1, -0.1, 0.15]")), {"body 'plate'", "not positive definite"});
}

TEST(ModelFile, InertiaViolatingTriangleInequalityIsRejected) {
  ExpectMessage(ErrorOf(Edit("[0.1, 0.1, 0.15]", "[0.1, 0.1, 0.5]")), {"body 'plate'", "triangle inequality"});
}

TEST(ModelFile, NegativeStiffnessIsRejected) {
  ExpectMessage(ErrorOf(Edit("Rx = \"1.5 Nm/urad\"", "Rx = \"-1.5 Nm/urad\"")),
                {"joint 'plate'", "stiffness Rx = -1.5e+06 Nm/rad", "expected a finite value >= 0"});
}

TEST(ModelFile, UnknownBodyIsRejected) {
  ExpectMessage(ErrorOf(Edit("parent = \"base\"", "parent = \"bse\"")), {"joint 'plate'", "parent 'bse' is not a body"});
}

TEST(ModelFile, LoopIsRejected) {
  ExpectMessage(ErrorOf(Edit("parent = \"ground\"", "parent = \"plate\"")), {"loops back"});
}

TEST(ModelFile, DisconnectedBodyIsRejected) {
  std::string text = std::string(kValid) + "\n[[body]]\nname = \"loose\"\nmass = 1\ncom = [0, 0, 0]\ninertia = [1, 1, 1]\n";
  ExpectMessage(ErrorOf(text), {"body 'loose' is not connected to the ground"});
}

TEST(ModelFile, UnitOfWrongDimensionIsRejected) {
  ExpectMessage(ErrorOf(Edit("\"1e8 N/m\", Rx", "\"200 N\", Rx")),
                {"test.toml:", "stiffness.Dz", "force (N)", "expected a translational stiffness (N/m)"});
}

TEST(ModelFile, MissingStiffnessOfFreeDofIsRejected) {
  ExpectMessage(ErrorOf(Edit(", Ry = \"1.5e6 Nm/rad\"", "")), {"joint 'plate'", "stiffness.Ry is missing"});
}

TEST(ModelFile, ImposedDofWithStiffnessIsRejected) {
  ExpectMessage(ErrorOf(Edit("imposed = [\"Rz\"]", "imposed = [\"Rz\", \"Dx\"]")),
                {"joint 'plate'", "Dx is imposed and also has a stiffness"});
}

TEST(ModelFile, IndefiniteCouplingIsRejected) {
  std::string text = Edit("damping = { Dx = \"500 N s/m\" }",
                          "damping = { Dx = \"500 N s/m\" }\n[[joint.coupling]]\ndofs = [\"Dx\", \"Dy\"]\nstiffness = 5e7");
  ExpectMessage(ErrorOf(text), {"joint 'plate'", "indefinite"});
}

TEST(ModelFile, EveryProblemIsReportedAtOnce) {
  std::string text = Edit("\"10 kg\"", "\"-10 kg\"");
  text.replace(text.find("parent = \"base\""), 15, "parent = \"bse\"");
  std::string message = ErrorOf(text);
  ExpectMessage(message, {"2 problems", "mass = -10", "parent 'bse'"});
}

TEST(ModelFile, SyntaxErrorNamesLine) {
  ExpectMessage(ErrorOf(Edit("name = \"two stages\"", "name = \"two stages")), {"test.toml:3", "TOML syntax error"});
}

TEST(ModelFile, WrittenModelReadsBackIdentical) {
  ModelSpec spec = DefaultModelSpec();
  spec.joints[1].couplings.push_back({Dof::kDx, Dof::kRy, 1.2345678901234567e6, 3.25});
  spec.joints[2].loss_factor[0] = 0.015;
  spec.history.push_back({"fit", 0.0123, "all stiffnesses"});
  spec.baked_effects.push_back("payload@hexapod");
  ModelSpec back = ParseModelToml(WriteModelToml(spec), "roundtrip.toml");
  EXPECT_EQ(WriteModelToml(back), WriteModelToml(spec));
  ASSERT_EQ(back.joints.size(), spec.joints.size());
  for (size_t j = 0; j < spec.joints.size(); ++j) {
    EXPECT_EQ(back.joints[j].stiffness, spec.joints[j].stiffness);
    EXPECT_EQ(back.joints[j].damping, spec.joints[j].damping);
    EXPECT_EQ(back.joints[j].imposed, spec.joints[j].imposed);
  }
  EXPECT_EQ(back.joints[1].couplings[0].stiffness, 1.2345678901234567e6);
  EXPECT_EQ(back.sensors.size(), 12u);
  EXPECT_EQ(back.excitations.size(), 10u);
  EXPECT_EQ(back.history[0].error, 0.0123);
}

TEST(ModelFile, DefaultModelMatchesSpecTable) {
  ModelSpec spec = DefaultModelSpec();
  ASSERT_EQ(spec.bodies.size(), 5u);
  EXPECT_EQ(spec.bodies[0].mass_kg, 2500);
  EXPECT_EQ(spec.joints[4].stiffness[3], 1.5e6);  // hexapod Rx, read as Nm/urad (SPEC §2)
  EXPECT_EQ(spec.joints[4].stiffness[5], 2.7e5);
  EXPECT_EQ(spec.joints[0].damping[1], 1.1e5);
  EXPECT_TRUE(spec.joints[1].imposed[1]);
  EXPECT_TRUE(spec.joints[2].imposed[4]);
  EXPECT_TRUE(spec.joints[3].imposed[5]);
  EXPECT_EQ(spec.joints[3].origin_W.z(), -0.40);
}

}  // namespace
}  // namespace stagefit::model
