// The measurement workflow run as a user would: compare, fit, frf, estimate on the shipped example
// measurement, and bad inputs ending with exit code 2.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>

#include "cli_test_util.h"
#include "stagefit/measurement/uff_time.h"
#include "stagefit/measurement/uff58.h"
#include "stagefit/measurement/raw_hammer_file.h"
#include "stagefit/measurement/measurement_file.h"

namespace stagefit {
namespace {

using testing::RunStagefit;
using testing::TempDir;

const std::string kExample = std::string(STAGEFIT_SOURCE_DIR) + "/measurements/microstation-12x10/";

nlohmann::json ReadJson(const std::filesystem::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in);
}

TEST(CompareCommand, ReportsTheErrorOfTheShippedMeasurement) {
  auto dir = TempDir("compare");
  auto r = RunStagefit("compare --measurement " + kExample + "frf.mat --report " + (dir / "r.json").string() +
                       " --out-dir " + (dir / "tables").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto report = ReadJson(dir / "r.json");
  ASSERT_TRUE(report.contains("error"));
  EXPECT_GT(report["error"].get<double>(), 0.1);  // the example hides a 6 kg payload
  EXPECT_FALSE(std::filesystem::is_empty(dir / "tables"));
}

TEST(CompareCommand, WithThePayloadTheErrorFalls) {
  auto before = RunStagefit("compare --measurement " + kExample + "frf.mat");
  auto after = RunStagefit("compare --measurement " + kExample + "frf.mat --with \"payload@hexapod:mass=6,z=0.06\"");
  ASSERT_EQ(after.exit_code, 0) << after.output;
  auto error_of = [](const std::string& out) { return std::stod(out.substr(out.find("error = ") + 8)); };
  EXPECT_LT(error_of(after.output), 0.5 * error_of(before.output));
}

TEST(CompareCommand, BadMeasurementFilesExitTwoNamingTheFile) {
  auto dir = TempDir("compare_bad");
  EXPECT_EQ(RunStagefit("compare --measurement /nonexistent/m.mat").exit_code, 2);
  {
    std::ifstream in(kExample + "frf.mat", std::ios::binary);
    std::string bytes(2000, '\0');
    in.read(bytes.data(), bytes.size());
    std::ofstream(dir / "truncated.mat", std::ios::binary) << bytes;
  }
  auto r = RunStagefit("compare --measurement " + (dir / "truncated.mat").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("truncated.mat"), std::string::npos) << r.output;
  std::ofstream(dir / "bad.csv") << "freq_hz,output,input,re,im\n10,a,b,1,0\n5,a,b,1,0\n";
  r = RunStagefit("compare --space raw --measurement " + (dir / "bad.csv").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
}

// The diagnose report holds what SPEC §4 names (candidates with effect, location, error_after and the
// fitted parameters; where) and the rigid-body consistency of the channels. One cheap effect and the
// hexapod's stiffnesses keep it short.
TEST(DiagnoseCommand, ReportsCandidatesAndWhere) {
  auto dir = TempDir("diagnose");
  auto r = RunStagefit("diagnose --measurement " + kExample + "frf.mat --effects delay --params 'hexapod.k.*' --report " +
                       (dir / "d.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto report = ReadJson(dir / "d.json");
  ASSERT_TRUE(report["candidates"].is_array());
  ASSERT_EQ(report["candidates"].size(), 1u);
  const auto& c = report["candidates"][0];
  EXPECT_EQ(c["effect"], "delay");
  EXPECT_EQ(c["location"], "acquisition");
  EXPECT_TRUE(c["parameters"].contains("tau"));
  EXPECT_GT(c["error_after"].get<double>(), 0.0);
  EXPECT_TRUE(report["effect_found"].is_boolean());
  const auto& where = report["where"];
  EXPECT_FALSE(where["bands"].empty());
  EXPECT_FALSE(where["elements"].empty());
  ASSERT_TRUE(where["rigid_consistency"].is_object());
  EXPECT_EQ(where["rigid_consistency"]["least_consistent"].size(), 4u);
  EXPECT_NE(r.output.find("rigid-body consistency"), std::string::npos) << r.output;
  ASSERT_TRUE(report["noise_floor"].is_object());
  EXPECT_GT(report["noise_floor"]["floor"].get<double>(), 0.0);
  EXPECT_NE(r.output.find("noise floor"), std::string::npos) << r.output;
}

TEST(FitCommand, TunedFileReproducesTheReportedError) {
  auto dir = TempDir("fit");
  auto r = RunStagefit("fit --measurement " + kExample + "frf.mat --params \"hexapod.k.*\" --out " +
                       (dir / "tuned.toml").string() + " --report " + (dir / "fit.json").string());
  ASSERT_TRUE(r.exit_code == 0 || r.exit_code == 3) << r.output;
  auto report = ReadJson(dir / "fit.json");
  for (const char* key : {"error", "error_before", "parameters", "status"}) EXPECT_TRUE(report.contains(key)) << key;
  EXPECT_LT(report["error"].get<double>(), report["error_before"].get<double>());
  auto again = RunStagefit("compare --model " + (dir / "tuned.toml").string() + " --measurement " + kExample +
                           "frf.mat --report " + (dir / "again.json").string());
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_EQ(ReadJson(dir / "again.json")["error"].get<double>(), report["error"].get<double>());
}

// The next step diagnose prints, from the model as given: fit --with "<its with text>". The effect is a
// part of the model, so fit frees its parameters with the stiffnesses by default; the tuned file holds
// the base and an [[effect]] table and reproduces the error bit for bit. On the shipped example (6 kg,
// 60 mm) from diagnose's 5.5 kg, 64 mm the fit ends at the noise floor with the payload's truth.
TEST(FitCommand, TheEffectDiagnoseNamesIsRefittedWithTheStiffnesses) {
  auto dir = TempDir("fit-effect");
  auto r = RunStagefit("fit --measurement " + kExample + "frf.mat --with \"payload@hexapod:mass=5.5,z=0.064\" --out " +
                       (dir / "tuned.toml").string() + " --report " + (dir / "fit.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto report = ReadJson(dir / "fit.json");
  double mass = 0, z = 0;
  for (const auto& p : report["parameters"]) {
    if (p["name"] == "payload@hexapod.mass") mass = p["value"].get<double>();
    if (p["name"] == "payload@hexapod.z") z = p["value"].get<double>();
  }
  EXPECT_NEAR(mass, 6.0, 0.1) << r.output;
  EXPECT_NEAR(z, 0.060, 0.003) << r.output;
  EXPECT_LT(report["noise_floor"]["error_over_floor"].get<double>(), 1.1) << r.output;
  std::ifstream in(dir / "tuned.toml");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("[[effect]]\nname = \"payload\"\nlocation = \"hexapod\""), std::string::npos);
  auto again = RunStagefit("compare --model " + (dir / "tuned.toml").string() + " --measurement " + kExample +
                           "frf.mat --report " + (dir / "again.json").string());
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_EQ(ReadJson(dir / "again.json")["error"].get<double>(), report["error"].get<double>());
}

// A fit that stops at its iteration budget having lowered the error exits 0 (it wrote a better model)
// and says the budget ran out; the report says max_iterations. The shipped measurement is far from the
// nominal model: one iteration lowers the error without meeting a tolerance.
TEST(FitCommand, ABudgetThatRanOutAfterLoweringTheErrorIsNotAFailure) {
  auto dir = TempDir("fit-budget");
  auto r = RunStagefit("fit --measurement " + kExample + "frf.mat --params \"hexapod.k.*\" --max-iterations 1 "
                       "--probe-rounds 0 --report " + (dir / "fit.json").string());
  auto report = ReadJson(dir / "fit.json");
  ASSERT_EQ(report["status"].get<std::string>(), "max_iterations") << r.output;
  ASSERT_LT(report["error"].get<double>(), report["error_before"].get<double>());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("the iteration budget ran out"), std::string::npos) << r.output;
  ASSERT_TRUE(report["noise_floor"].is_object());
  EXPECT_GT(report["noise_floor"]["error_over_floor"].get<double>(), 1.0);
  EXPECT_NE(r.output.find("x floor"), std::string::npos) << r.output;
}

// The loop on the shipped example (a 6 kg payload 60 mm above the hexapod, 2 % noise): it adds the
// payload and ends at the noise floor; the final model reproduces the reported error; the history and
// the before/after tables are written.
TEST(LoopCommand, EndsAtTheNoiseFloorOfTheShippedExample) {
  auto dir = TempDir("loop");
  auto r = RunStagefit("loop --measurement " + kExample + "frf.mat --effects payload,extra-body --max-rounds 2 --out " +
                       (dir / "final.toml").string() + " --out-dir " + (dir / "plots").string() + " --report " +
                       (dir / "loop.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto report = ReadJson(dir / "loop.json");
  ASSERT_TRUE(report["noise_floor"].is_object());
  EXPECT_LT(report["noise_floor"]["error_over_floor"].get<double>(), 1.1) << r.output;
  ASSERT_EQ(report["effects_added"].size(), 1u) << r.output;
  EXPECT_EQ(report["effects_added"][0].get<std::string>().rfind("payload@hexapod:", 0), 0u);
  EXPECT_EQ(report["stop_reason"].get<std::string>(), "at the noise floor");
  EXPECT_TRUE(report["confirmed"].get<bool>());
  ASSERT_TRUE(report["missing_bands"].is_array());
  EXPECT_TRUE(report["missing_bands"].empty());  // at the floor nothing is missing
  EXPECT_NE(report["conclusion"].get<std::string>().find("with payload@hexapod: they explain the measurement"), std::string::npos)
      << report["conclusion"];
  EXPECT_NE(r.output.find("x floor"), std::string::npos) << r.output;
  for (const char* f : {"plots/loop_history.csv", "plots/after_rounds.toml", "plots/before/compare_frf.csv", "plots/after/compare_frf.csv"}) {
    EXPECT_TRUE(std::filesystem::exists(dir / f)) << f;
  }
  auto again = RunStagefit("compare --model " + (dir / "final.toml").string() + " --measurement " + kExample +
                           "frf.mat --report " + (dir / "again.json").string());
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_EQ(ReadJson(dir / "again.json")["error"].get<double>(), report["error"].get<double>());

  // Resumed from the model it wrote: the payload is the loop's own, at the floor nothing more is added,
  // and the error is the same to the bit.
  auto resumed = RunStagefit("loop --measurement " + kExample + "frf.mat --effects payload,extra-body --resume " +
                             (dir / "final.toml").string() + " --out " + (dir / "resumed.toml").string() + " --report " +
                             (dir / "resumed.json").string());
  ASSERT_EQ(resumed.exit_code, 0) << resumed.output;
  const auto r2 = ReadJson(dir / "resumed.json");
  EXPECT_EQ(r2["effects_added"], report["effects_added"]);
  EXPECT_EQ(r2["error"].get<double>(), report["error"].get<double>());
  EXPECT_TRUE(r2["confirmed"].get<bool>());
  EXPECT_NE(resumed.output.find("resumed"), std::string::npos) << resumed.output;
  // From a state without the given model's effects: refused, naming the file and what it expected.
  auto refused = RunStagefit("loop --measurement " + kExample + "frf.mat --with \"delay@acquisition:tau=1e-4\" --resume " +
                             (dir / "final.toml").string() + " --out " + (dir / "refused.toml").string());
  EXPECT_EQ(refused.exit_code, 2) << refused.output;
  EXPECT_NE(refused.output.find("--resume " + (dir / "final.toml").string()), std::string::npos) << refused.output;
  EXPECT_NE(refused.output.find("expected the given model's [delay@acquisition] first"), std::string::npos) << refused.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "refused.toml"));
}

TEST(LoopCommand, AMissingOutputFolderIsRefusedBeforeTheRun) {
  auto r = RunStagefit("loop --measurement " + kExample + "frf.mat --out /nonexistent-folder/final.toml");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("/nonexistent-folder"), std::string::npos) << r.output;
}

// The shipped whole-stack example: compare and fit choose the bodies space themselves and say so;
// fit lands near the noise floor's neighbourhood only once the payload is there, diagnose names it.
TEST(WholeStackExample, CompareFitAndDiagnoseWorkInTheBodiesSpace) {
  const std::string m = std::string(STAGEFIT_SOURCE_DIR) + "/measurements/whole-stack/frf.mat";
  auto dir = TempDir("whole-stack");
  auto compare = RunStagefit("compare --measurement " + m + " --out-dir " + (dir / "cmp").string() + " --report " +
                             (dir / "c.json").string());
  ASSERT_EQ(compare.exit_code, 0) << compare.output;
  EXPECT_NE(compare.output.find("comparison space: bodies (the sensors are on 5 bodies"), std::string::npos)
      << compare.output;
  {
    std::ifstream table(dir / "cmp" / "compare_elements.csv");
    const std::string text((std::istreambuf_iterator<char>(table)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("rz.Dx/h1"), std::string::npos) << text.substr(0, 400);
  }
  EXPECT_EQ(ReadJson(dir / "c.json")["breakdown"]["space"].get<std::string>(), "bodies");
  auto fit = RunStagefit("fit --measurement " + m + " --out " + (dir / "tuned.toml").string() + " --report " +
                         (dir / "f.json").string());
  ASSERT_EQ(fit.exit_code, 0) << fit.output;
  const auto f = ReadJson(dir / "f.json");
  EXPECT_EQ(f["space"].get<std::string>(), "bodies");
  EXPECT_LT(f["error"].get<double>(), 0.2 * f["error_before"].get<double>());
  auto diagnose = RunStagefit("diagnose --model " + (dir / "tuned.toml").string() + " --measurement " + m +
                              " --effects payload --report " + (dir / "d.json").string());
  ASSERT_EQ(diagnose.exit_code, 0) << diagnose.output;
  const auto d = ReadJson(dir / "d.json");
  ASSERT_TRUE(d["effect_found"].get<bool>()) << diagnose.output;
  EXPECT_EQ(d["candidates"][0]["with"].get<std::string>().rfind("payload@rz:", 0), 0u) << diagnose.output;
  EXPECT_TRUE(d["where"]["rigid_consistency"].is_object()) << diagnose.output;  // per body
  auto raw = RunStagefit("compare --measurement " + m + " --space compliance");
  EXPECT_EQ(raw.exit_code, 2) << raw.output;  // one frame cannot hold sensors on five bodies
}

// UFF files as acquisition systems write them: the shipped measurement as UFF 58b FRFs with its node
// coordinates in dataset 2411 (millimetres, dataset 164) compares exactly as the .mat; its raw time
// data as UFF 58 time records estimate the same FRFs as the raw .mat.
TEST(UffFiles, NodesFromDataset2411AndTimeRecordsRunThroughCompareAndEstimate) {
  auto dir = TempDir("uff-cli");
  const auto frf = measurement::ReadMeasurement(kExample + "frf.mat");
  std::string nodes = "    -1\n   164\n         2  mm (milli newton)   2\n"
                      "  1.00000000000000000D+03  1.00000000000000000D+00  1.00000000000000000D+00\n"
                      "  2.73150000000000000D+02\n    -1\n    -1\n  2411\n";
  char line[200];
  auto add = [&](int node, const Eigen::Vector3d& p) {
    std::snprintf(line, sizeof line, "%10d%10d%10d%10d\n%25.16E%25.16E%25.16E\n", node, 1, 1, 11, 1e3 * p.x(),
                  1e3 * p.y(), 1e3 * p.z());
    nodes += line;
  };
  for (int o = 0; o < frf.num_outputs(); ++o) add(1 + o, frf.outputs[o].position_W);
  for (int j = 0; j < frf.num_inputs(); ++j) add(1001 + j, frf.inputs[j].position_W);
  nodes += "    -1\n";
  std::ofstream(dir / "frf.uff", std::ios::binary)
      << nodes << measurement::FormatUff58(measurement::ConvertFrfDataToUff(frf), measurement::UffEncoding::kBinaryLittleEndian);
  auto mat = RunStagefit("compare --measurement " + kExample + "frf.mat --report " + (dir / "mat.json").string());
  auto uff = RunStagefit("compare --measurement " + (dir / "frf.uff").string() + " --report " + (dir / "uff.json").string());
  ASSERT_EQ(uff.exit_code, 0) << uff.output;
  EXPECT_NEAR(ReadJson(dir / "uff.json")["error"].get<double>(), ReadJson(dir / "mat.json")["error"].get<double>(), 1e-9);

  const auto raw = measurement::ReadRawHammerFile(kExample + "raw.mat");
  measurement::WriteUff58(dir / "raw.uff", measurement::ConvertRawHammerToUff(raw), measurement::UffEncoding::kBinaryLittleEndian);
  auto from_mat = RunStagefit("estimate " + kExample + "raw.mat --out " + (dir / "est_mat.mat").string());
  auto from_uff = RunStagefit("estimate " + (dir / "raw.uff").string() + " --out " + (dir / "est_uff.mat").string());
  ASSERT_EQ(from_uff.exit_code, 0) << from_uff.output;
  const auto a = measurement::ReadMeasurement(dir / "est_mat.mat"), b = measurement::ReadMeasurement(dir / "est_uff.mat");
  ASSERT_EQ(a.num_frequencies(), b.num_frequencies());
  for (int k = 0; k < a.num_frequencies(); ++k) EXPECT_LT((a.frf[k] - b.frf[k]).cwiseAbs().maxCoeff(), 1e-12 * a.frf[k].cwiseAbs().maxCoeff());
  auto bad = RunStagefit("estimate " + (dir / "raw.uff").string() + " --force 9999+X --out " + (dir / "x.mat").string());
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("no force record"), std::string::npos) << bad.output;
  auto missing = RunStagefit("compare --measurement " + (dir / "frf.uff").string() + " --geometry " +
                             (dir / "none.csv").string());
  EXPECT_EQ(missing.exit_code, 2) << missing.output;
  EXPECT_NE(missing.output.find("none.csv' does not exist"), std::string::npos) << missing.output;
}

// The FRFs estimated from the shipped raw data (3 hits per impact) carry their hit count, and the
// commands that compare set the noise floor with it: the truth of the example (the model with the
// 6 kg payload at 60 mm) is at about its floor, not 0.9 x as when the 3 hits' ordinary coherence was
// taken as the estimate's own. Written as UFF 58 the count is lost: estimate says so, and
// `--averages 3` gives the same floor back.
TEST(EstimateCommand, TheHitsAveragedSetTheNoiseFloorAndUffNeedsThemGiven) {
  auto dir = TempDir("estimate-averages");
  const std::string band = " --min-frequency \"10 Hz\" --max-frequency \"400 Hz\"";
  ASSERT_EQ(RunStagefit("estimate " + kExample + "raw.mat" + band + " --out " + (dir / "est.mat").string()).exit_code, 0);
  EXPECT_EQ(measurement::ReadMeasurement(dir / "est.mat").averages, std::vector<int>(10, 3));
  auto uff = RunStagefit("estimate " + kExample + "raw.mat" + band + " --out " + (dir / "est.uff").string());
  ASSERT_EQ(uff.exit_code, 0) << uff.output;
  EXPECT_NE(uff.output.find("give --averages 3 to the commands that read"), std::string::npos) << uff.output;
  // UFF 58 holds no sensor positions here: the channels' geometry beside it, as a user gives it.
  const auto est = measurement::ReadMeasurement(dir / "est.mat");
  std::ofstream geometry(dir / "est.geometry.csv");
  geometry.precision(17);
  geometry << "kind,name,body,x,y,z,nx,ny,nz\n";
  for (const auto* side : {&est.outputs, &est.inputs}) {
    for (const auto& c : *side) {
      geometry << (side == &est.outputs ? "sensor," : "impact,") << c.name << "," << c.body;
      for (int a = 0; a < 3; ++a) geometry << "," << c.position_W[a];
      for (int a = 0; a < 3; ++a) geometry << "," << c.direction_W[a];
      geometry << "\n";
    }
  }
  geometry.close();
  const std::string truth = "compare --with \"payload@hexapod:mass=6 kg,z=60 mm\" --measurement ";
  auto floor_of = [&](const std::string& args) {
    auto r = RunStagefit(truth + args + " --report " + (dir / "c.json").string());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return ReadJson(dir / "c.json")["noise_floor"];
  };
  const auto from_mat = floor_of((dir / "est.mat").string());
  EXPECT_GT(from_mat["error_over_floor"].get<double>(), 0.97);
  EXPECT_LT(from_mat["error_over_floor"].get<double>(), std::sqrt(2.0));  // 3 hits: sqrt((n - 1) / (n - 2)) at most
  const auto given = floor_of((dir / "est.uff").string() + " --averages 3");
  EXPECT_NEAR(given["floor"].get<double>(), from_mat["floor"].get<double>(), 1e-9);
  const auto without = floor_of((dir / "est.uff").string());
  EXPECT_LT(without["error_over_floor"].get<double>(), 0.92);
  auto one = RunStagefit(truth + (dir / "est.uff").string() + " --averages 1");
  EXPECT_EQ(one.exit_code, 1) << one.output;
}

TEST(FitCommand, RefusesToWriteOverItsInput) {
  auto r = RunStagefit("fit --measurement " + kExample + "frf.mat --out " + kExample + "frf.mat");
  EXPECT_EQ(r.exit_code, 2) << r.output;
}

TEST(FrfCommand, WritesTheModelAtTheMeasurementsFrequencies) {
  auto dir = TempDir("frf");
  auto r = RunStagefit("frf --measurement " + kExample + "frf.mat --out " + (dir / "model.csv").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(dir / "model.csv");
  int rows = 0;
  for (std::string line; std::getline(in, line);) rows += !line.empty() && line[0] != '#';
  EXPECT_EQ(rows, 1 + 300 * 12 * 10);  // header + one row per frequency, output and input
}

TEST(EstimateCommand, TurnsTheShippedRawDataIntoFrfs) {
  auto dir = TempDir("estimate");
  auto r = RunStagefit("estimate " + kExample + "raw.mat --exp-tau 0.25 --out " + (dir / "est.mat").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(dir / "est.mat"));
  auto bad = RunStagefit("estimate " + kExample + "frf.mat --out " + (dir / "x.mat").string());
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("frf.mat"), std::string::npos) << bad.output;
}

}  // namespace
}  // namespace stagefit
