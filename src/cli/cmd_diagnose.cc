#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "command.h"
#include "report.h"
#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"
#include "stagefit/diagnose/diagnose.h"
#include "stagefit/measurement/channel_checks.h"
#include "stagefit/measurement/measurement_file.h"
#include "stagefit/model/model_file.h"

namespace stagefit::cli {

void RegisterDiagnoseCommand(CLI::App& app) {
  auto* command = app.add_subcommand(
      "diagnose",
      "where the model fails against a measurement, and which physical effect of the catalogue explains it, ranked");
  struct Options {
    CommonOptions common;
    std::string measurement;
    std::string space;
    std::string geometry;
    int averages = 0;
    std::string exclude_channels;
    bool no_channel_checks = false;
    std::string params = "*.k.*";
    std::string effects;
    double fmin = 0, fmax = 0;
    std::string out;
  };
  auto o = std::make_shared<Options>();
  AddCommonOptions(*command, o->common);
  AddWithOption(*command, o->common);
  command->add_option("--measurement", o->measurement, "measurement file (.mat, .csv, .uff)")->required();
  command->add_option("--geometry", o->geometry, kGeometryHelp);
  command->add_option("--averages", o->averages, kAveragesHelp)->check(CLI::Range(2, 1000000000));
  command->add_option("--exclude-channels", o->exclude_channels, kExcludeChannelsHelp);
  command->add_flag("--no-channel-checks", o->no_channel_checks,
                    "skip the checks of the test bench (reversed, swapped, dead, clipped, locally resonant channels)");
  command->add_option("--space", o->space, "comparison space: compliance (sensors on one body: the 6x6 compliance at {X}), bodies (sensors on several bodies: each body's 6 DoF at its centre of mass) or raw; default: as the measurement's geometry calls for")
      ->check(CLI::IsMember({"compliance", "bodies", "raw"}));
  command->add_option("--params", o->params, "model parameters fitted with every candidate (comma-separated patterns)")
      ->capture_default_str();
  command->add_option("--effects", o->effects, "only these catalogue effects (comma-separated); default all");
  command->add_option("--fmin", o->fmin, "lower end of the band, Hz");
  command->add_option("--fmax", o->fmax, "upper end of the band, Hz");
  command->add_option("--out", o->out, "write the baseline with the best effect applied (model file) here");
  command->callback([o] {
    const std::vector<std::string> inputs = {o->common.model_path, o->measurement};
    if (!o->out.empty()) CheckNotAnInput(o->out, {inputs.begin(), inputs.end()});
    if (!o->common.report_path.empty()) CheckNotAnInput(o->common.report_path, {inputs.begin(), inputs.end()});
    model::ModelSpec spec = LoadModelFromOptions(o->common);
    measurement::FrfData data =
        ExcludeChannelsOption(ReadMeasurementFor(o->measurement, o->geometry, o->averages, spec), o->exclude_channels);
    // Faults of the test bench first (docs/diagnose.md).
    nlohmann::json non_rigid = nullptr;
    const nlohmann::json channel_faults = o->no_channel_checks ? nlohmann::json(nullptr) : CheckTestBench(&data, &non_rigid);
    diagnose::DiagnoseOptions options;
    options.comparison.space = ResolveComparisonSpace(o->space, data);
    if (o->fmin > 0) options.comparison.fmin_hz = o->fmin;
    if (o->fmax > 0) options.comparison.fmax_hz = o->fmax;
    options.params = SplitCommaList(o->params);
    options.effects = SplitCommaList(o->effects);
    for (const auto& e : options.effects) model::FindEffectDefinition(e);
    if (StderrIsTerminal()) options.progress = [](const std::string& line) { std::cerr << "diagnose: " << line << std::endl; };
    diagnose::DiagnoseSummary summary = diagnose::Diagnose(spec, data, options);
    std::printf("%s", summary.BriefReport().c_str());
    std::printf("(%.1f s)\n", summary.time_s);
    if (!o->out.empty() && summary.effect_found) {
      model::ModelSpec with = diagnose::ApplyCandidate(summary, summary.candidates[0]);
      with.history.push_back({"diagnose --with " + summary.candidates[0].with, summary.candidates[0].error_after,
                              summary.candidates[0].explanation});
      model::WriteModelFile(o->out, with);
      std::printf("wrote %s (the fitted model with %s; refine it with stagefit fit)\n", o->out.c_str(),
                  summary.candidates[0].with.c_str());
    }
    if (!o->common.report_path.empty()) {
      nlohmann::json candidates = nlohmann::json::array();
      for (const auto& c : summary.candidates) {
        candidates.push_back({{"effect", c.effect.name}, {"location", c.effect.location}, {"with", c.with},
                              {"error_after", c.error_after}, {"delta_bic", c.delta_bic}, {"helps", c.helps},
                              {"parameters", c.effect.parameters}, {"explanation", c.explanation},
                              {"implausible", c.implausible.empty() ? nlohmann::json(nullptr) : nlohmann::json(c.implausible)}});
      }
      nlohmann::json bands = nlohmann::json::array(), elements = nlohmann::json::array(), modes = nlohmann::json::array();
      for (const auto& b : summary.worst_bands) {
        bands.push_back({{"low_hz", b.band.low_hz}, {"high_hz", b.band.high_hz}, {"error", b.error}, {"share", b.share}});
      }
      for (const auto& e : summary.worst_elements) elements.push_back({{"element", e.name}, {"error", e.error}, {"share", e.share}});
      for (const auto& m : summary.mispaired_modes) {
        modes.push_back({{"measured_hz", m.measured_hz}, {"model_hz", m.model_hz}, {"mac", m.mac}, {"dominant_dof", m.dominant_dof}});
      }
      nlohmann::json unpaired_model = nlohmann::json::array(), rigid = nullptr;
      for (const auto& [f, dof] : summary.unpaired_model) unpaired_model.push_back({{"model_hz", f}, {"dominant_dof", dof}});
      if (std::isfinite(summary.rigid_residual_share)) {
        nlohmann::json channels = nlohmann::json::array();
        for (const auto& c : summary.inconsistent_channels) {
          channels.push_back({{"channel", c.channel}, {"share", c.share}, {"band_hz", c.band_hz}});
        }
        nlohmann::json turned = nlohmann::json::array();
        for (const auto& t : summary.turned_channels) {
          turned.push_back({{"channel", t.channel}, {"angle_deg", t.angle_deg}, {"residual_share", t.residual_share}});
        }
        rigid = {{"max_share", summary.rigid_residual_share}, {"least_consistent", channels}, {"turned", turned}};
      }
      nlohmann::json report = {{"command", "diagnose"},
                               {"error", summary.error_initial},
                               {"error_baseline", summary.error_baseline},
                               {"noise_floor", NoiseFloorJson(summary.error_baseline, summary.noise_floor)},
                               {"channel_faults", channel_faults},
                               {"non_rigid", non_rigid},
                               {"effect_found", summary.effect_found},
                               {"verdict", summary.verdict},
                               {"candidates", candidates},
                               {"where", {{"bands", bands}, {"elements", elements}, {"channels", ChannelErrorsJson(summary.worst_channels)}, {"mispaired_modes", modes},
                                          {"unpaired_measured_hz", summary.unpaired_measured_hz},
                                          {"unpaired_model", unpaired_model}, {"rigid_consistency", rigid}}},
                               {"time_s", summary.time_s}};
      WriteReport(o->common.report_path, report, inputs);
    }
  });
}

}  // namespace stagefit::cli
