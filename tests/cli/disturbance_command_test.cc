// The disturbance chain as a user runs it: model sensitivity -> force PSD -> synthesised signal, with
// the units carried from file to file and mismatches refused.

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "cli_test_util.h"
#include "stagefit/disturbance/record_io.h"

namespace stagefit {
namespace {

using testing::RunStagefit;
using testing::TempDir;

// A PSD table at the frequencies of `like` with one column `name` of constant `level` in `unit`.
void WriteFlatPsd(const std::filesystem::path& path, const disturbance::CsvTable& like, const std::string& name,
                  const std::string& unit, double level) {
  disturbance::CsvTable psd;
  psd.column_names = {"frequency_hz", name};
  psd.units = {"Hz", unit};
  psd.values.resize(like.values.rows(), 2);
  psd.values.col(0) = like.Column("frequency_hz");
  psd.values.col(1).setConstant(level);
  disturbance::WriteCsvTable(path, psd);
}

TEST(DisturbanceCommand, SensitivityFeedsTheForcePsdWithItsUnits) {
  const auto dir = TempDir("disturbance_force");
  auto r = RunStagefit("disturbance sensitivity --source ty.F.Dz --output X_rel.Dz --fmin 1 --fmax 100 --points 50 "
                       "--out " + (dir / "s.csv").string() + " --report " + (dir / "s.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const disturbance::CsvTable h = disturbance::ReadCsvTable(dir / "s.csv");
  EXPECT_EQ(h.units[h.FindColumn("abs")], "m/N");
  std::ifstream report_stream(dir / "s.json");
  const nlohmann::json report = nlohmann::json::parse(report_stream);
  EXPECT_EQ(report.at("source"), "ty.F.Dz");
  EXPECT_EQ(report.at("unit"), "m/N");
  EXPECT_EQ(report.at("frequencies"), 50);
  const double abs_max = h.Column("abs").maxCoeff();
  EXPECT_NEAR(report.at("abs_max").get<double>(), abs_max, 1e-8 * abs_max);  // the CSV's nine digits
  constexpr double kMotionPsd = 1e-18;  // m^2/Hz
  WriteFlatPsd(dir / "psd.csv", h, "motion", "m^2/Hz", kMotionPsd);

  r = RunStagefit("disturbance force --psd " + (dir / "psd.csv").string() + " --sensitivity " +
                  (dir / "s.csv").string() + " --out " + (dir / "f.csv").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const disturbance::CsvTable force = disturbance::ReadCsvTable(dir / "f.csv");
  ASSERT_GE(force.FindColumn("motion_force"), 0);
  EXPECT_EQ(force.units[force.FindColumn("motion_force")], "N^2/Hz");
  const Eigen::VectorXd s_f = force.Column("motion_force"), abs_h = h.Column("abs");
  constexpr double kCsvRoundOff = 1e-7;  // nine significant digits in the files, squared once
  for (Eigen::Index k = 0; k < s_f.size(); ++k) {
    const double expected = kMotionPsd / (abs_h[k] * abs_h[k]);
    EXPECT_NEAR(s_f[k], expected, kCsvRoundOff * expected) << "row " << k;
  }

  // A ground source gives a ground displacement PSD, m^2/Hz, named as a source rather than a force.
  r = RunStagefit("disturbance sensitivity --source ground.Dz --output X_rel.Dz --fmin 1 --fmax 100 --points 50 "
                  "--out " + (dir / "g.csv").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = RunStagefit("disturbance force --psd " + (dir / "psd.csv").string() + " --sensitivity " +
                  (dir / "g.csv").string() + " --out " + (dir / "fg.csv").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const disturbance::CsvTable ground = disturbance::ReadCsvTable(dir / "fg.csv");
  ASSERT_GE(ground.FindColumn("motion_source"), 0);
  EXPECT_EQ(ground.units[ground.FindColumn("motion_source")], "m^2/Hz");

  auto bad = RunStagefit("disturbance sensitivity --source spindle --out " + (dir / "x.csv").string());
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("ty.F.Dz"), std::string::npos) << bad.output;
}

TEST(DisturbanceCommand, ForceRefusesAMotionPsdInAnotherUnitThanTheSensitivity) {
  const auto dir = TempDir("disturbance_units");
  auto r = RunStagefit("disturbance sensitivity --source rz.F.Dz --output X_rel.Dz --fmin 1 --fmax 100 --points 20 "
                       "--out " + (dir / "s.csv").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  WriteFlatPsd(dir / "psd.csv", disturbance::ReadCsvTable(dir / "s.csv"), "Rx", "rad^2/Hz", 1e-20);
  r = RunStagefit("disturbance force --psd " + (dir / "psd.csv").string() + " --sensitivity " +
                  (dir / "s.csv").string() + " --out " + (dir / "f.csv").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  for (const char* fragment : {"psd.csv", "'Rx'", "rad^2/Hz", "m/N", "m^2/Hz"}) {
    EXPECT_NE(r.output.find(fragment), std::string::npos) << r.output << " lacks " << fragment;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "f.csv"));
}

TEST(DisturbanceCommand, SynthesisOfAForcePsdLeavesOutTheUnreliableBins) {
  const auto dir = TempDir("disturbance_synth");
  for (const double reliable : {1.0, 0.0}) {
    disturbance::CsvTable force;
    force.column_names = {"frequency_hz", "F", "reliable"};
    force.units = {"Hz", "N^2/Hz", ""};
    force.values.resize(50, 3);
    force.values.col(0) = Eigen::VectorXd::LinSpaced(50, 1.0, 50.0);
    force.values.col(1).setConstant(1e-2);
    force.values.col(2).setConstant(reliable);
    disturbance::WriteCsvTable(dir / "f.csv", force);
    std::filesystem::remove(dir / "signal.csv");
    auto r = RunStagefit("disturbance synth --psd " + (dir / "f.csv").string() + " --duration \"4 s\" --rate \"200 Hz\" "
                         "--out " + (dir / "signal.csv").string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const disturbance::CsvTable signal = disturbance::ReadCsvTable(dir / "signal.csv");
    ASSERT_EQ(signal.column_names, (std::vector<std::string>{"time_s", "F"}));
    EXPECT_EQ(signal.units[1], "N");
    // Mean square of the sum of cosines = integral of the PSD over 1..50 Hz when every bin is reliable,
    // nothing at all when none is.
    const double mean_square = signal.Column("F").squaredNorm() / static_cast<double>(signal.values.rows());
    constexpr double kBandEdgeShare = 0.05;  // half a bin (0.25 Hz of the 4 s record) at each edge
    const double expected = reliable * 1e-2 * 49.0;
    EXPECT_NEAR(mean_square, expected, kBandEdgeShare * 1e-2 * 49.0);
  }
}

}  // namespace
}  // namespace stagefit
