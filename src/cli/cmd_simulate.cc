// `stagefit simulate tomography|raster`: time-domain experiments (docs/simulation.md).

#include <cstdio>
#include <filesystem>
#include <memory>

#include <nlohmann/json.hpp>

#include "command.h"
#include "report.h"
#include "stagefit/common/atomic_file.h"
#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"
#include "stagefit/common/units.h"
#include "stagefit/disturbance/record_io.h"
#include "stagefit/simulate/experiments.h"

namespace stagefit::cli {
namespace {

namespace sim = stagefit::simulate;
namespace sd = stagefit::disturbance;

struct SimulateFlags {
  CommonOptions common;
  std::string duration = "10 s", rate = "10 kHz", speed = "60 rpm", offset;
  std::string amplitude = "4.5 mm", period = "1 s";
  std::uint64_t seed = 1;
  std::string out_dir = ".";
  std::string compare;
  std::string ground_psd;
  std::string straightness;
  std::string spindle_psd;
  std::vector<std::string> spindle_reference;
  bool no_ground = false, no_stage_error = false;
};

void AddFlags(CLI::App* command, SimulateFlags& f, bool tomography) {
  AddCommonOptions(*command, f.common);
  command->add_option("--duration", f.duration, "length of the run (default \"10 s\")");
  command->add_option("--rate", f.rate, "sample rate and integration step (default \"10 kHz\")");
  command->add_option("--offset", f.offset,
                      tomography ? "radial offset of the PoI from the rotation axis (default \"1 um\")"
                                 : "offset of the PoI along x (default 0)");
  command->add_option("--seed", f.seed, "seed of the synthesised disturbances (std::mt19937_64; default 1)");
  command->add_option("--out-dir", f.out_dir, "folder for <experiment>.csv and <experiment>_psd.csv (default .)");
  command->add_option("--compare", f.compare,
                      "measured time series (CSV: time_s and error columns named as in the output) to compare");
  command->add_option("--ground-psd", f.ground_psd,
                      "ground displacement PSD table (CSV frequency_hz + one column, m^2/Hz; default: quiet hall)");
  command->add_flag("--no-ground", f.no_ground, "no ground motion");
  command->add_flag("--no-stage-error", f.no_stage_error,
                    tomography ? "no spindle error motion" : "no translation-stage straightness error");
  if (tomography) {
    command->add_option("--speed", f.speed, "spindle speed (default \"60 rpm\")");
    command->add_option("--spindle-psd", f.spindle_psd,
                        "spindle error PSD table (CSV frequency_hz, Dx, Dy, Dz in m^2/Hz, Rx, Ry in rad^2/Hz; default: "
                        "the target of measurements/disturbance/spindle_target.csv)");
    command->add_option("--spindle-reference", f.spindle_reference,
                        "X Y Z: where the spindle error is measured (the analyser's sphere), in W, lengths with units "
                        "or in m (default: the PoI, 0 0 0); moved to the spindle joint by the rigid lever arm")
        ->expected(3);
  } else {
    command->add_option("--amplitude", f.amplitude, "triangle setpoint amplitude (default \"4.5 mm\")");
    command->add_option("--period", f.period, "triangle period, one back-and-forth (default \"1 s\")");
    command->add_option("--straightness", f.straightness,
                        "measured straightness record (CSV position_m, vertical_m, lateral_m) instead of the "
                        "synthesised one");
  }
}

sd::PsdTable ReadPsdTable(const std::string& path) {
  const sd::CsvTable t = sd::ReadCsvTable(path);
  if (t.column_names.size() < 2 || t.column_names[0] != "frequency_hz") {
    throw InputError(path + ": expected a PSD table with columns frequency_hz and one PSD column (m^2/Hz)");
  }
  sd::PsdTable table;
  table.name = path;
  table.frequency_hz = t.values.col(0);
  table.psd = t.values.col(1);
  sd::ValidatePsdTable(table);
  return table;
}

void WriteOutputs(const sim::SimulationSummary& s, const SimulateFlags& f, const std::vector<std::string>& inputs,
                  nlohmann::json& report) {
  const std::filesystem::path dir(f.out_dir);
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (!std::filesystem::is_directory(dir)) {
    throw InputError("--out-dir " + f.out_dir + ": not a folder and cannot be created (" + ec.message() + ")");
  }
  std::vector<std::filesystem::path> input_paths(inputs.begin(), inputs.end());

  sd::CsvTable series;
  series.comments = {"stagefit simulate " + s.experiment + ": PoI relative to the granite (large motion + vibration)",
                     "Dx..Rz: pose of the PoI; vib_*: the linear model's part; errors in m"};
  series.column_names = {"time_s", s.experiment == "tomography" ? "angle_rad" : "setpoint_m",
                         "Dx", "Dy", "Dz", "Rx", "Ry", "Rz",
                         "vib_Dx", "vib_Dy", "vib_Dz", "vib_Rx", "vib_Ry", "vib_Rz"};
  series.units = {"s", s.experiment == "tomography" ? "rad" : "m", "m", "m", "m", "rad", "rad", "rad",
                  "m", "m", "m", "rad", "rad", "rad"};
  for (const auto& name : s.error_names) {
    series.column_names.push_back(name);
    series.units.push_back("m");
  }
  const Eigen::Index n = s.time_s.size();
  series.values.resize(n, static_cast<Eigen::Index>(series.column_names.size()));
  series.values.col(0) = s.time_s;
  series.values.col(1) = s.setpoint;
  series.values.middleCols(2, 6) = s.poi_pose;
  series.values.middleCols(8, 6) = s.vibration;
  series.values.rightCols(s.errors.cols()) = s.errors;
  const std::filesystem::path series_path = dir / (s.experiment + ".csv");
  CheckNotAnInput(series_path, input_paths);
  sd::WriteCsvTable(series_path, series);

  sd::CsvTable spectra;
  spectra.comments = {"Welch PSDs of the errors of stagefit simulate " + s.experiment + ", m^2/Hz"};
  spectra.column_names = {"frequency_hz"};
  spectra.units = {"Hz"};
  const Eigen::Index bins = s.spectra.front().frequency_hz.size();
  spectra.values.resize(bins, static_cast<Eigen::Index>(s.spectra.size() + 1));
  spectra.values.col(0) = s.spectra.front().frequency_hz;
  for (size_t c = 0; c < s.spectra.size(); ++c) {
    spectra.column_names.push_back(s.error_names[c]);
    spectra.units.push_back("m^2/Hz");
    spectra.values.col(static_cast<Eigen::Index>(c + 1)) = s.spectra[c].psd;
  }
  const std::filesystem::path psd_path = dir / (s.experiment + "_psd.csv");
  CheckNotAnInput(psd_path, input_paths);
  sd::WriteCsvTable(psd_path, spectra);
  report["files"] = {series_path.string(), psd_path.string()};

  if (!f.compare.empty()) {
    const sd::CsvTable measured = sd::ReadCsvTable(f.compare);
    const sim::ComparisonSummary c = sim::CompareWithMeasured(s, measured, {});
    std::printf("%s", c.BriefReport().c_str());
    sd::CsvTable side;
    side.comments = {"simulated and measured error PSDs side by side, m^2/Hz (measured: " + f.compare + ")"};
    side.column_names = {"frequency_hz"};
    side.units = {"Hz"};
    Eigen::Index rows = c.channels.front().simulated_psd.psd.size();
    for (const auto& ch : c.channels) {
      rows = std::min({rows, ch.simulated_psd.psd.size(), ch.measured_psd.psd.size()});
    }
    side.values.resize(rows, static_cast<Eigen::Index>(1 + 2 * c.channels.size()));
    side.values.col(0) = c.channels.front().simulated_psd.frequency_hz.head(rows);
    nlohmann::json channels = nlohmann::json::array();
    for (size_t i = 0; i < c.channels.size(); ++i) {
      const auto& ch = c.channels[i];
      side.column_names.push_back("sim_" + ch.name);
      side.column_names.push_back("meas_" + ch.name);
      side.units.push_back("m^2/Hz");
      side.units.push_back("m^2/Hz");
      side.values.col(static_cast<Eigen::Index>(1 + 2 * i)) = ch.simulated_psd.psd.head(rows);
      side.values.col(static_cast<Eigen::Index>(2 + 2 * i)) = ch.measured_psd.psd.head(rows);
      channels.push_back({{"name", ch.name},
                          {"simulated", {{"rms_m", ch.simulated.rms}, {"peak_to_peak_m", ch.simulated.peak_to_peak}}},
                          {"measured", {{"rms_m", ch.measured.rms}, {"peak_to_peak_m", ch.measured.peak_to_peak}}}});
    }
    const std::filesystem::path compare_path = dir / (s.experiment + "_compare_psd.csv");
    CheckNotAnInput(compare_path, input_paths);
    sd::WriteCsvTable(compare_path, side);
    report["comparison"] = {{"measured", f.compare}, {"channels", channels}, {"psd_file", compare_path.string()}};
  }
}

void Finish(const sim::SimulationSummary& s, const SimulateFlags& f) {
  std::printf("%s", s.BriefReport().c_str());
  std::vector<std::string> inputs;
  for (const auto& p : {f.common.model_path, f.compare, f.ground_psd, f.straightness, f.spindle_psd}) {
    if (!p.empty()) inputs.push_back(p);
  }
  nlohmann::json report = {{"command", "simulate " + s.experiment}, {"model", ModelSource(f.common)}, {"seed", f.seed}};
  nlohmann::json stats = nlohmann::json::array();
  for (const auto& st : s.statistics) {
    stats.push_back({{"name", st.name}, {"rms_m", st.rms}, {"peak_to_peak_m", st.peak_to_peak}});
  }
  report["errors"] = stats;
  report["inputs"] = s.input_names;
  report["notes"] = s.notes;
  report["integration"] = {{"modal", s.modal_integration}, {"wall_time_s", s.integration_wall_time_s}};
  if (s.experiment == "tomography") {
    report["circle"] = {{"eccentricity_m", s.eccentricity_m},
                        {"phase_rad", s.eccentricity_phase_rad},
                        {"centre_x_m", s.circle_centre_x_m},
                        {"centre_y_m", s.circle_centre_y_m}};
  }
  WriteOutputs(s, f, inputs, report);
  if (!f.common.report_path.empty()) WriteReport(f.common.report_path, report, inputs);
  ExitCode() = kExitOk;
}

}  // namespace

void RegisterSimulateCommand(CLI::App& app) {
  auto* command = app.add_subcommand("simulate", "time-domain experiments: tomography, raster scan");
  command->require_subcommand(1);

  auto tf = std::make_shared<SimulateFlags>();
  tf->offset = "1 um";
  auto* tomography = command->add_subcommand(
      "tomography", "spindle turning at --speed with ground motion and spindle error; radial/axial errors of the PoI");
  AddFlags(tomography, *tf, true);
  tomography->callback([tf] {
    sim::TomographyOptions o;
    o.duration_s = ParseQuantity(tf->duration, dim::kTime, "--duration");
    o.sample_rate_hz = ParseQuantity(tf->rate, dim::kFrequency, "--rate");
    o.speed_rad_s = ParseQuantity(tf->speed, dim::kAngularVelocity, "--speed");
    o.offset_m = ParseQuantity(tf->offset, dim::kLength, "--offset");
    o.seed = tf->seed;
    o.ground_motion = !tf->no_ground;
    o.spindle_error = !tf->no_stage_error;
    if (!tf->ground_psd.empty()) o.ground_psd = ReadPsdTable(tf->ground_psd);
    if (!tf->spindle_psd.empty()) o.spindle_error_psd = sim::SpindleErrorPsdFromTable(sd::ReadCsvTable(tf->spindle_psd));
    if (!tf->spindle_reference.empty()) {
      for (int k = 0; k < 3; ++k) {
        o.spindle_error_reference_W(k) =
            ParseQuantity(tf->spindle_reference[k], dim::kLength, std::string("--spindle-reference ") + "XYZ"[k]);
      }
    }
    Finish(sim::RunTomography(LoadModelFromOptions(tf->common), o), *tf);
  });

  auto rf = std::make_shared<SimulateFlags>();
  rf->offset = "0";
  auto* raster = command->add_subcommand(
      "raster", "translation stage triangle scan with ground motion and straightness error; vertical/lateral errors");
  AddFlags(raster, *rf, false);
  raster->callback([rf] {
    sim::RasterOptions o;
    o.duration_s = ParseQuantity(rf->duration, dim::kTime, "--duration");
    o.sample_rate_hz = ParseQuantity(rf->rate, dim::kFrequency, "--rate");
    o.amplitude_m = ParseQuantity(rf->amplitude, dim::kLength, "--amplitude");
    o.period_s = ParseQuantity(rf->period, dim::kTime, "--period");
    o.offset_m = ParseQuantity(rf->offset, dim::kLength, "--offset");
    o.seed = rf->seed;
    o.ground_motion = !rf->no_ground;
    o.straightness_error = !rf->no_stage_error;
    if (!rf->ground_psd.empty()) o.ground_psd = ReadPsdTable(rf->ground_psd);
    if (!rf->straightness.empty()) {
      const sd::CsvTable t = sd::ReadCsvTable(rf->straightness);
      o.straightness_position_m = t.Column("position_m");
      o.straightness_vertical_m = t.Column("vertical_m");
      o.straightness_lateral_m = t.Column("lateral_m");
    }
    Finish(sim::RunRaster(LoadModelFromOptions(rf->common), o), *rf);
  });
}

}  // namespace stagefit::cli
