// diagnose's checks of the test bench and --exclude-channels on compare, fit and diagnose.

#include <gtest/gtest.h>

#include <fstream>

#include <nlohmann/json.hpp>

#include "cli_test_util.h"
#include "stagefit/measurement/measurement_file.h"
#include "stagefit/model/model_file.h"
#include "stagefit/synthetic/outside_catalogue.h"

namespace stagefit::cli {
using testing::RunStagefit;
using testing::TempDir;
namespace {

const std::string kExample = std::string(STAGEFIT_SOURCE_DIR) + "/measurements/microstation-12x10/frf.mat";

TEST(ChannelChecksCli, ReversedSensorIsReportedAsAFaultNotAsAnEffect) {
  auto dir = TempDir("channel-reversed");
  measurement::FrfData data = measurement::ReadMeasurement(kExample);
  for (auto& h : data.frf) h.row(4) *= -1.0;  // a2y wired with reversed sign
  ASSERT_EQ(data.outputs[4].name, "a2y");
  measurement::WriteMeasurement(dir / "rev.mat", data);
  const auto r = RunStagefit("diagnose --measurement " + (dir / "rev.mat").string() +
                             " --effects delay,payload --params 'hexapod.k.*' --report " + (dir / "r.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("channel fault: reversed sensor a2y"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("repaired a2y"), std::string::npos) << r.output;
  std::ifstream in(dir / "r.json");
  const auto report = nlohmann::json::parse(in);
  ASSERT_EQ(report["channel_faults"].size(), 1u) << report.dump(2);
  EXPECT_EQ(report["channel_faults"][0]["kind"], "reversed");
  EXPECT_EQ(report["channel_faults"][0]["channels"][0], "a2y");

  // The shipped example itself is sound: no finding, an empty list in the report.
  const auto s = RunStagefit("diagnose --measurement " + kExample + " --effects delay,payload --params 'hexapod.k.*' --report " +
                             (dir / "s.json").string());
  ASSERT_EQ(s.exit_code, 0) << s.output;
  EXPECT_NE(s.output.find("channels: no fault of the test bench found"), std::string::npos) << s.output;
  std::ifstream in2(dir / "s.json");
  const auto sound = nlohmann::json::parse(in2);
  EXPECT_TRUE(sound["channel_faults"].empty());
  // The repair is an exact negation, so the model search sees the sound data: the example's own hidden
  // payload is found with the same error, not a catalogue effect made up for the reversed channel.
  EXPECT_EQ(report["candidates"][0]["with"], sound["candidates"][0]["with"]);
  EXPECT_EQ(report["candidates"][0]["error_after"], sound["candidates"][0]["error_after"]);
  EXPECT_EQ(report["effect_found"], sound["effect_found"]);

  // --no-channel-checks: no check, null in the report.
  const auto n = RunStagefit("diagnose --measurement " + (dir / "rev.mat").string() +
                             " --effects delay --params 'hexapod.k.*' --no-channel-checks --report " + (dir / "n.json").string());
  ASSERT_EQ(n.exit_code, 0) << n.output;
  EXPECT_EQ(n.output.find("channel fault"), std::string::npos) << n.output;
  std::ifstream in3(dir / "n.json");
  EXPECT_TRUE(nlohmann::json::parse(in3)["channel_faults"].is_null());
}

// The loop checks the test bench first too: a reversed a2y on the shipped example is repaired, and the
// loop ends at the noise floor with the example's payload as on the sound data.
TEST(ChannelChecksCli, TheLoopRepairsAReversedChannelFirst) {
  auto dir = TempDir("channel-loop");
  measurement::FrfData data = measurement::ReadMeasurement(kExample);
  for (auto& h : data.frf) h.row(4) *= -1.0;
  measurement::WriteMeasurement(dir / "rev.mat", data);
  const auto r = RunStagefit("loop --measurement " + (dir / "rev.mat").string() + " --effects payload --max-rounds 1 --out " +
                             (dir / "final.toml").string() + " --report " + (dir / "loop.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("channel fault: reversed sensor a2y"), std::string::npos) << r.output;
  std::ifstream in(dir / "loop.json");
  const auto report = nlohmann::json::parse(in);
  ASSERT_EQ(report["channel_faults"].size(), 1u) << report.dump(2);
  EXPECT_EQ(report["channel_faults"][0]["channels"][0], "a2y");
  EXPECT_LT(report["noise_floor"]["error_over_floor"].get<double>(), 1.1) << r.output;
  ASSERT_EQ(report["effects_added"].size(), 1u);
  EXPECT_EQ(report["effects_added"][0].get<std::string>().rfind("payload@hexapod:", 0), 0u);
}

// The top plate bending (outside the catalogue): the loop ends at the floor in compliance space, which the
// projection to the platform leaves blind to it; the channel checks name the band and the channels that
// do not move as one, leave none out, and the loop says its model does not explain their readings.
TEST(ChannelChecksCli, TheLoopNamesChannelsNotRigidTogether) {
  auto dir = TempDir("channel-non-rigid");
  synthetic::HiddenEffectOptions o = synthetic::EvalLoopCaseOptions(0, 150, 400);
  o.min_visibility = 8;
  const auto c = synthetic::MakeOutsideCatalogueCase(model::DefaultModelSpec(), 11, "plate-bending", o);
  measurement::WriteMeasurement(dir / "plate.mat", c.measurement);
  const auto r = RunStagefit("loop --measurement " + (dir / "plate.mat").string() + " --effects payload --max-rounds 1 --out " +
                             (dir / "final.toml").string() + " --report " + (dir / "loop.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("not rigid: the sensors in"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("does not explain their readings there"), std::string::npos) << r.output;
  std::ifstream in(dir / "loop.json");
  const auto report = nlohmann::json::parse(in);
  EXPECT_TRUE(report["channel_faults"].empty()) << report.dump(2);
  ASSERT_EQ(report["non_rigid"].size(), 2u) << report.dump(2);
  for (const auto& n : report["non_rigid"]) {
    EXPECT_LE(n["low_hz"].get<double>(), c.peak_hz);
    EXPECT_GE(n["high_hz"].get<double>(), c.peak_hz);
    EXPECT_EQ(n["channels"].size(), 4u) << n.dump();
  }
}

TEST(ChannelChecksCli, ExcludeChannelsOnCompareFitDiagnose) {
  const auto c = RunStagefit("compare --measurement " + kExample + " --exclude-channels a2z,h3");
  ASSERT_EQ(c.exit_code, 0) << c.output;
  EXPECT_NE(c.output.find("11 outputs x 9 inputs"), std::string::npos) << c.output;
  for (const std::string command : {"compare", "fit", "diagnose"}) {
    const auto r = RunStagefit(command + " --measurement " + kExample + " --exclude-channels a2z,a9q");
    EXPECT_EQ(r.exit_code, 2) << command << "\n" << r.output;
    EXPECT_NE(r.output.find("'a9q'"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("not a channel of the data"), std::string::npos) << r.output;
  }
}

}  // namespace
}  // namespace stagefit::cli
