// `stagefit estimate RAW --out OUT`: FRFs (H1 or H2) with coherence from raw hammer time data
// (layout: measurements/README.md, "Raw hammer time data"), written as a measurement file.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <memory>

#include <nlohmann/json.hpp>

#include "command.h"
#include "report.h"
#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"
#include "stagefit/common/units.h"
#include "stagefit/measurement/hammer_estimation.h"
#include "stagefit/measurement/measurement_file.h"
#include "stagefit/measurement/raw_hammer_file.h"
#include "stagefit/measurement/uff_time.h"

namespace stagefit::cli {
namespace {

namespace sm = stagefit::measurement;

struct EstimateFlags {
  CommonOptions common;
  std::string raw;
  std::string out;
  std::string force_window;
  std::string exp_tau;
  std::string min_frequency;
  std::string max_frequency;
  std::string estimator = "h1";
  bool exclude_flagged = false;
  bool no_force_window = false;
  std::string force_channel;
  std::string responses;
};

nlohmann::json HitJson(const sm::HitDiagnostics& d, const sm::RawHammerData& data) {
  nlohmann::json outputs = nlohmann::json::array();
  for (int i : d.overloaded_outputs) outputs.push_back(data.outputs[i].name);
  return {{"input", data.inputs[d.input].name},
          {"input_number", d.input + 1},
          {"hit", d.hit + 1},
          {"peak_force_n", d.peak_force_n},
          {"impact_time_s", d.impact_time_s},
          {"pulse_width_s", d.pulse_width_s},
          {"double_hit", d.double_hit},
          {"second_peak_ratio", d.second_peak_ratio},
          {"force_overload", d.force_overload},
          {"overloaded_outputs", outputs},
          {"hit_coherence", d.hit_coherence},
          {"poor_coherence", d.poor_coherence},
          {"flagged", d.flagged()},
          {"rejected", d.rejected},
          {"messages", d.messages}};
}

void RunEstimate(const EstimateFlags& f) {
  CheckNotAnInput(f.out, {f.raw});
  if (!f.common.report_path.empty()) CheckNotAnInput(f.common.report_path, {f.raw, f.out});
  // Fail on a bad --out extension before the work.
  sm::MeasurementFormatOf(f.out);

  sm::EstimationOptions options;
  options.estimator = f.estimator == "h2" ? sm::FrfEstimator::kH2 : sm::FrfEstimator::kH1;
  options.apply_force_window = !f.no_force_window;
  if (!f.force_window.empty()) {
    options.force_window_s = ParseQuantity(f.force_window, dim::kTime, "--force-window");
  }
  if (!f.exp_tau.empty()) options.exp_tau_s = ParseQuantity(f.exp_tau, dim::kTime, "--exp-tau");
  if (!f.min_frequency.empty()) {
    options.min_frequency_hz = ParseQuantity(f.min_frequency, dim::kFrequency, "--min-frequency");
  }
  if (!f.max_frequency.empty()) {
    options.max_frequency_hz = ParseQuantity(f.max_frequency, dim::kFrequency, "--max-frequency");
  }
  options.exclude_flagged = f.exclude_flagged;

  sm::RawHammerData data;
  const std::string ext = std::filesystem::path(f.raw).extension().string();
  if (ext == ".uff" || ext == ".unv" || ext == ".UFF" || ext == ".UNV") {
    // UFF 58 time records (measurement/uff_time.h).
    sm::UffTimeOptions uff;
    uff.force_channel = f.force_channel;
    std::stringstream list(f.responses);
    for (std::string name; std::getline(list, name, ',');) {
      if (!name.empty()) uff.responses.push_back(name);
    }
    data = sm::ReadUffRawHammer(f.raw, uff);
  } else {
    if (!f.force_channel.empty() || !f.responses.empty()) {
      throw UsageError("--force and --responses name channels of a UFF time-record file; '" + f.raw + "' is not one");
    }
    data = sm::ReadRawHammerFile(f.raw);
  }
  const sm::EstimationSummary summary = sm::EstimateFrf(data, options);
  sm::WriteMeasurement(f.out, summary.frf);
  std::fputs(summary.BriefReport().c_str(), stdout);
  std::printf("wrote %s\n", f.out.c_str());
  if (options.estimator == sm::FrfEstimator::kH2 && summary.frf.has_coherence()) {
    std::printf("note: H2 is biased by noise on the responses, and the coherence does not show a bias: the noise floor "
                "of the commands that compare takes the estimate's error as noise alone, which holds for H1 and for H2 "
                "only where the noise is on the force (docs/error-metric.md §8)\n");
  }
  if (!summary.frf.averages.empty() && sm::MeasurementFormatOf(f.out) == sm::MeasurementFormat::kUff) {
    const auto [fewest, most] = std::minmax_element(summary.frf.averages.begin(), summary.frf.averages.end());
    std::printf("note: UFF 58 does not carry the number of hits averaged; give --averages %d to the commands that "
                "read %s (compare, fit, diagnose, loop)%s, or they take its coherence as the estimate's own and put "
                "the noise floor about %.1f times too high\n",
                *fewest, f.out.c_str(), *fewest == *most ? "" : " (the inputs had different numbers of hits; that is the fewest)",
                std::sqrt(*fewest - 1.0));
  }

  if (!f.common.report_path.empty()) {
    nlohmann::json hits = nlohmann::json::array();
    int flagged = 0;
    for (const sm::HitDiagnostics& d : summary.hits) {
      hits.push_back(HitJson(d, data));
      flagged += d.flagged() ? 1 : 0;
    }
    nlohmann::json report = {
        // No model is compared with the measurement here, so there is no error scalar.
        {"error", nullptr},
        {"raw", f.raw},
        {"out", f.out},
        {"estimator", f.estimator},
        {"quantity", sm::ToString(summary.frf.quantity)},
        {"num_outputs", summary.frf.num_outputs()},
        {"num_inputs", summary.frf.num_inputs()},
        {"num_frequencies", summary.frf.num_frequencies()},
        {"frequency_resolution_hz", summary.frequency_resolution_hz},
        {"exp_tau_s", options.exp_tau_s},
        {"added_decay_rate_1_s", summary.added_decay_rate_1_s},
        {"hits_used", summary.hits_used},
        {"num_flagged", flagged},
        {"num_rejected", summary.rejected_hits.size()},
        {"hits", hits},
        {"warnings", summary.warnings}};
    WriteReport(f.common.report_path, report, {f.raw, f.out});
  }
}

}  // namespace

void RegisterEstimateCommand(CLI::App& app) {
  auto* command = app.add_subcommand(
      "estimate",
      "FRFs (H1 or H2) with coherence from raw hammer time data (.mat, layout in "
      "measurements/README.md); flags double hits, overloads and incoherent hits");
  auto f = std::make_shared<EstimateFlags>();
  AddCommonOptions(*command, f->common);
  command->add_option("RAW", f->raw,
                      "raw hammer time data: .mat (layout in measurements/README.md) or .uff/.unv with UFF 58 time "
                      "records (one per channel and hit; docs/uff.md)")
      ->required();
  command->add_option("--force", f->force_channel,
                      "UFF: the force channel's name (e.g. 1001-Y); default: in each hit the record whose response "
                      "DOF is its reference DOF");
  command->add_option("--responses", f->responses, "UFF: the response channels to use, comma-separated (default: all)");
  command->add_option("--out", f->out, "measurement file to write: OUT.mat, OUT.csv or OUT.uff")
      ->required();
  command->add_option("--force-window", f->force_window,
                      "flat length of the force window after the impact (e.g. \"10 ms\"); default: "
                      "3 pulse widths");
  command->add_flag("--no-force-window", f->no_force_window, "do not window the force record");
  command->add_option("--exp-tau", f->exp_tau,
                      "time constant of the exponential response window (e.g. \"0.5 s\"); adds a "
                      "damping ratio 1/(tau omega_n), reported; default: none");
  command->add_option("--min-frequency", f->min_frequency, "lowest frequency written (default: df)");
  command->add_option("--max-frequency", f->max_frequency,
                      "highest frequency written (default: Nyquist)");
  command->add_option("--estimator", f->estimator, "h1 (default, noise on the response) or h2")
      ->check(CLI::IsMember({"h1", "h2"}));
  command->add_flag("--exclude-flagged", f->exclude_flagged,
                    "leave flagged hits (double hit, overload, poor coherence) out of the averages");
  command->callback([f] { RunEstimate(*f); });
}

}  // namespace stagefit::cli
