// `stagefit compare --measurement M`: the SPEC §4 error scalar between the model and a measurement, its
// breakdown by element and band, the mode pairing (MAC), CSV tables for plotting and a JSON report.

#include <cmath>
#include <cstdio>
#include <memory>

#include <nlohmann/json.hpp>

#include "command.h"
#include "report.h"
#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"
#include "stagefit/common/units.h"
#include "stagefit/compare/compare_model.h"
#include "stagefit/measurement/measurement_file.h"

namespace stagefit::cli {
namespace {

struct CompareFlags {
  CommonOptions common;
  std::string measurement;
  std::string space;
  std::string geometry;
  int averages = 0;
  std::string exclude_channels;
  std::string fmin;
  std::string fmax;
  std::string out_dir;
  double significance = compare::kDefaultSignificanceThreshold;
  double coherence_cap = compare::kDefaultCoherenceWeightCap;
  double min_mac = 0.6;
  bool no_coherence = false;
};

nlohmann::json NumberOrNull(double value) { return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(); }

nlohmann::json BreakdownJson(const compare::Comparison& comparison, const compare::ComparisonResult& result) {
  nlohmann::json elements = nlohmann::json::array();
  for (const auto& el : result.elements) {
    elements.push_back({{"element", el.name},
                        {"output", comparison.output_names()[el.index.output]},
                        {"input", comparison.input_names()[el.index.input]},
                        {"significance", el.significance},
                        {"points", el.num_points},
                        {"error", el.error},
                        {"share", el.share},
                        {"mean_ln_ratio", el.mean_log_magnitude},
                        {"mean_phase_rad", el.mean_phase_rad}});
  }
  nlohmann::json bands = nlohmann::json::array();
  for (const auto& b : result.bands) {
    bands.push_back({{"low_hz", b.band.low_hz},
                     {"high_hz", b.band.high_hz},
                     {"centre_hz", b.band.centre_hz()},
                     {"points", b.num_points},
                     {"error", b.error},
                     {"share", b.share}});
  }
  return {{"space", compare::ToString(comparison.space())},
          {"error", result.error},
          {"frequency_min_hz", comparison.frequency_hz()(0)},
          {"frequency_max_hz", comparison.frequency_hz()(comparison.num_frequencies() - 1)},
          {"num_frequencies", comparison.num_frequencies()},
          {"num_points", comparison.num_points()},
          {"elements", elements},
          {"bands", bands}};
}

nlohmann::json ModesJson(const compare::ModePairing& pairing) {
  nlohmann::json pairs = nlohmann::json::array();
  for (const auto& p : pairing.pairs) {
    const auto& a = pairing.measured[p.measured];
    const auto& b = pairing.model[p.model];
    pairs.push_back({{"measured_hz", a.frequency_hz},
                     {"model_hz", b.frequency_hz},
                     {"frequency_error", p.frequency_error},
                     {"measured_damping_ratio", NumberOrNull(a.damping_ratio)},
                     {"model_damping_ratio", NumberOrNull(b.damping_ratio)},
                     {"mac", p.mac},
                     {"model_mode", b.model_mode + 1},
                     {"model_mode_hz", b.model_frequency_hz},
                     {"dominant_dof", b.dominant_dof}});
  }
  nlohmann::json measured_only = nlohmann::json::array();
  for (int a : pairing.unpaired_measured) {
    measured_only.push_back({{"frequency_hz", pairing.measured[a].frequency_hz},
                             {"damping_ratio", NumberOrNull(pairing.measured[a].damping_ratio)}});
  }
  nlohmann::json model_only = nlohmann::json::array();
  for (int b : pairing.unpaired_model) {
    const auto& m = pairing.model[b];
    model_only.push_back({{"frequency_hz", m.frequency_hz},
                          {"damping_ratio", NumberOrNull(m.damping_ratio)},
                          {"model_mode", m.model_mode + 1},
                          {"dominant_dof", m.dominant_dof}});
  }
  return {{"pairs", pairs}, {"unpaired_measured", measured_only}, {"unpaired_model", model_only}};
}

void RunCompare(const CompareFlags& f) {
  if (f.measurement.empty()) throw UsageError("compare: --measurement FILE is required");
  if (!f.common.report_path.empty()) CheckNotAnInput(f.common.report_path, {f.measurement, f.common.model_path});

  compare::CompareOptions options;

  if (!f.fmin.empty()) options.comparison.fmin_hz = ParseQuantity(f.fmin, dim::kFrequency, "--fmin");
  if (!f.fmax.empty()) options.comparison.fmax_hz = ParseQuantity(f.fmax, dim::kFrequency, "--fmax");
  options.comparison.significance_threshold = f.significance;
  options.comparison.coherence_weight_cap = f.coherence_cap;
  options.comparison.use_coherence = !f.no_coherence;
  options.modes.min_mac = f.min_mac;

  const model::ModelSpec spec = LoadModelFromOptions(f.common);
  const measurement::FrfData data =
      ExcludeChannelsOption(ReadMeasurementFor(f.measurement, f.geometry, f.averages, spec), f.exclude_channels);
  options.comparison.space = ResolveComparisonSpace(f.space, data);
  const compare::CompareSummary summary = compare::CompareModel(spec, data, options);

  std::printf("Model: %s%s\nMeasurement: %s (%s, %d outputs x %d inputs)\n", spec.name.c_str(),
              f.common.model_path.empty() ? " (embedded default)" : "", f.measurement.c_str(),
              measurement::ToString(data.quantity).c_str(), data.num_outputs(), data.num_inputs());
  std::fputs(summary.BriefReport().c_str(), stdout);
  const compare::NoiseFloor floor = summary.comparison.CalcNoiseFloor();
  std::fputs(compare::NoiseFloorLine(summary.result.error, floor).c_str(), stdout);
  if (!summary.raw_skipped.empty() && options.comparison.space == compare::ComparisonSpace::kCompliance) {
    std::printf("raw channels not compared: %s\n", summary.raw_skipped.c_str());
  }

  const std::vector<std::filesystem::path> inputs = {f.measurement, f.common.model_path};
  if (!f.out_dir.empty()) {
    const auto written = compare::WriteCompareTables(f.out_dir, summary, inputs);
    std::printf("wrote %zu tables to %s\n", written.size(), f.out_dir.c_str());
  }
  if (!f.common.report_path.empty()) {
    nlohmann::json report = {{"command", "compare"},
                             {"model", spec.name},
                             {"measurement", f.measurement},
                             {"error", summary.result.error},
                             {"noise_floor", NoiseFloorJson(summary.result.error, floor)},
                             {"breakdown", BreakdownJson(summary.comparison, summary.result)},
                             {"modes", ModesJson(summary.modes)}};
    if (summary.raw && summary.raw_result) {
      report["raw"] = BreakdownJson(*summary.raw, *summary.raw_result);
    }
    WriteReport(f.common.report_path, report, {f.measurement, f.common.model_path});
  }
}

}  // namespace

void RegisterCompareCommand(CLI::App& app) {
  auto* command = app.add_subcommand(
      "compare", "model vs measurement: error scalar, errors by element and band, mode pairing (MAC), CSV for plots");
  auto flags = std::make_shared<CompareFlags>();
  AddCommonOptions(*command, flags->common);
  AddWithOption(*command, flags->common);
  command->add_option("--measurement", flags->measurement, "measurement file (.mat, .csv, .uff)")->required();
  command->add_option("--geometry", flags->geometry, kGeometryHelp);
  command->add_option("--averages", flags->averages, kAveragesHelp)->check(CLI::Range(2, 1000000000));
  command->add_option("--exclude-channels", flags->exclude_channels, kExcludeChannelsHelp);
  command->add_option("--space", flags->space, "comparison space: compliance (sensors on one body: the 6x6 compliance at {X}), bodies (sensors on several bodies: each body's 6 DoF at its centre of mass) or raw; default: as the measurement's geometry calls for")
      ->check(CLI::IsMember({"compliance", "bodies", "raw"}));
  command->add_option("--fmin", flags->fmin, "lower end of the comparison band (e.g. \"10 Hz\"; default: the data's)");
  command->add_option("--fmax", flags->fmax, "upper end of the comparison band (default: the data's)");
  command->add_option("--out-dir", flags->out_dir, "write CSV tables for plotting (scripts/plot_compare.sh) here");
  command->add_option("--significance", flags->significance,
                      "elements with coupling coefficient kappa below this are not used (default 0.1 = -20 dB; "
                      "docs/error-metric.md)");
  command->add_option("--coherence-cap", flags->coherence_cap,
                      "cap of the coherence-derived weight SNR = sqrt(g2 / (1 - g2)) (default 30)");
  command->add_flag("--no-coherence", flags->no_coherence, "ignore the measurement's coherence (w = 1)");
  command->add_option("--min-mac", flags->min_mac, "minimum MAC of a mode pair (default 0.6)");
  command->callback([flags] { RunCompare(*flags); });
}

}  // namespace stagefit::cli
