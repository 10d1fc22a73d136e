// The `model`, `pose` and `export` subcommands, run as a user would.

#include <gtest/gtest.h>

#include <fstream>

#include "cli_test_util.h"
#include "stagefit/measurement/mat_file.h"
#include "stagefit/model/model_file.h"

#include <map>

namespace stagefit {
namespace {

using testing::RunStagefit;
using testing::TempDir;

TEST(ModelCommand, DefaultModelPrintsItsModes) {
  auto r = RunStagefit("model");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Free DoF: 27    States: 54"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Modes (27"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("hexapod.Dz"), std::string::npos) << r.output;
}

TEST(ModelCommand, BadModelFileExitsTwoNamingFileAndField) {
  auto dir = TempDir("bad_model");
  std::string text(model::DefaultModelToml());
  text.replace(text.find("mass = \"15 kg\""), 14, "mass = \"-15 kg\"");
  std::ofstream(dir / "bad.toml") << text;
  auto r = RunStagefit("model --model " + (dir / "bad.toml").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("bad.toml:"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("body 'hexapod': mass = -15 kg"), std::string::npos) << r.output;
}

TEST(ModelCommand, MissingModelFileExitsTwo) {
  auto r = RunStagefit("model --model /nonexistent/model.toml");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("/nonexistent/model.toml"), std::string::npos);
}

TEST(ModelCommand, GarbageFileNeverCrashes) {
  auto dir = TempDir("garbage_model");
  std::ofstream(dir / "g.toml", std::ios::binary) << std::string("\x00\xff[[body]\n=\x01", 10);
  auto r = RunStagefit("model --model " + (dir / "g.toml").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
}

TEST(ModelCommand, UnknownOptionIsUsageError) {
  EXPECT_EQ(RunStagefit("model --no-such-option").exit_code, 1);
  EXPECT_EQ(RunStagefit("no-such-command").exit_code, 1);
}

TEST(ModelCommand, ReportHoldsTheModes) {
  auto dir = TempDir("model_report");
  auto r = RunStagefit("model --report " + (dir / "r.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(dir / "r.json");
  std::string json((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(json.find("\"num_states\": 54"), std::string::npos);
  EXPECT_NE(json.find("\"strain_energy_share\""), std::string::npos);
}

TEST(PoseCommand, PrintsTheComposedPose) {
  auto r = RunStagefit("pose --dy \"2 mm\" --rz \"90 deg\"");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Dy = 0.002 m"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Rz = 1.57079633 rad"), std::string::npos) << r.output;
  EXPECT_EQ(RunStagefit("pose --dy \"2 kg\"").exit_code, 2);
}

// Seed eq. 1.12: a parasitic x error of the spindle stays along x at Rz = 90 deg (fixed frame, the
// default); in the moved frame it appears along y. A bad convention name is a usage of bad input.
TEST(PoseCommand, ParasiticMotionInTheFixedOrTheMovedFrame) {
  auto fixed = RunStagefit("pose --rz \"90 deg\" --parasitic-rz 1e-6 0 0 0 0 0");
  ASSERT_EQ(fixed.exit_code, 0) << fixed.output;
  EXPECT_NE(fixed.output.find("Dx = 1e-06 m, Dy = 0 m"), std::string::npos) << fixed.output;
  auto moved = RunStagefit("pose --rz \"90 deg\" --parasitic-rz 1e-6 0 0 0 0 0 --parasitic-frame moved");
  ASSERT_EQ(moved.exit_code, 0) << moved.output;
  EXPECT_NE(moved.output.find("Dy = 1e-06 m"), std::string::npos) << moved.output;
  auto bad = RunStagefit("pose --parasitic-frame sideways");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("--parasitic-frame 'sideways'"), std::string::npos) << bad.output;
}

// The spindle error PSD and the point where it was measured, from the command line; bad values exit 2
// naming the option or the file and its missing column.
TEST(SimulateCommand, SpindleErrorPsdAndReference) {
  auto dir = TempDir("simulate-spindle");
  const std::string psd = std::string(STAGEFIT_SOURCE_DIR) + "/measurements/disturbance/spindle_target.csv";
  auto r = RunStagefit("simulate tomography --duration 1 --rate 1000 --spindle-psd " + psd +
                       " --spindle-reference 0 0 \"-400 mm\" --out-dir " + dir.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("radial"), std::string::npos) << r.output;
  std::ofstream(dir / "bad_psd.csv") << "frequency_hz,Dx,Dy,Dz,Rx\n0.1,1e-16,1e-16,1e-16,1e-14\n100,1e-19,1e-19,1e-19,1e-17\n";
  auto missing = RunStagefit("simulate tomography --duration 1 --rate 1000 --spindle-psd " + (dir / "bad_psd.csv").string() +
                             " --out-dir " + dir.string());
  EXPECT_EQ(missing.exit_code, 2) << missing.output;
  EXPECT_NE(missing.output.find("bad_psd.csv: no column 'Ry'"), std::string::npos) << missing.output;
  auto unit = RunStagefit("simulate tomography --duration 1 --rate 1000 --spindle-reference 0 0 \"1 kg\" --out-dir " +
                          dir.string());
  EXPECT_EQ(unit.exit_code, 2) << unit.output;
  EXPECT_NE(unit.output.find("--spindle-reference Z"), std::string::npos) << unit.output;
  auto absent = RunStagefit("simulate tomography --duration 1 --rate 1000 --spindle-psd " + (dir / "none.csv").string() +
                            " --out-dir " + dir.string());
  EXPECT_EQ(absent.exit_code, 2) << absent.output;
  EXPECT_NE(absent.output.find("none.csv"), std::string::npos) << absent.output;
}

TEST(ExportCommand, WritesNamedCsvMatrices) {
  auto dir = TempDir("export");
  auto r = RunStagefit("export --out " + (dir / "ss.csv").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(dir / "ss_A.csv");
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header.substr(0, 21), "name,granite.Dx,grani");
  int rows = 0;
  for (std::string line; std::getline(in, line);) ++rows;
  EXPECT_EQ(rows, 54);
  EXPECT_TRUE(std::filesystem::exists(dir / "ss_K.csv"));
}

TEST(ExportCommand, WritesMatFileWithNamedPlainArrays) {
  auto dir = TempDir("export_mat");
  auto r = RunStagefit("export --io raw --out " + (dir / "ss.mat").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto vars = measurement::ReadMatFile(dir / "ss.mat");
  std::map<std::string, const measurement::MatVariable*> by_name;
  for (const auto& v : vars) by_name[v.name] = &v;
  ASSERT_TRUE(by_name.count("A") && by_name.count("B") && by_name.count("output_names"));
  const auto& B = std::get<Eigen::MatrixXd>(by_name["B"]->value);
  EXPECT_EQ(B.rows(), 54);
  EXPECT_EQ(B.cols(), 10);
  const auto& names = std::get<std::vector<std::string>>(by_name["output_names"]->value);
  ASSERT_EQ(names.size(), 12u);
  EXPECT_EQ(names[0], "a1x");
}

}  // namespace
}  // namespace stagefit
