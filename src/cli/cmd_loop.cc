// `stagefit loop --measurement M [--model F] --out final.toml`: fit, diagnose, add the best effect,
// refit, again until the model is at the noise floor or nothing in the catalogue helps
// (diagnose::RunLoop); prints the error history against the noise floor, writes the final model and,
// with --out-dir, the history and the before/after comparison tables for scripts/plot_loop.sh.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "command.h"
#include "report.h"
#include "stagefit/common/atomic_file.h"
#include "stagefit/common/csv_meta.h"
#include "stagefit/common/error.h"
#include "stagefit/compare/compare_model.h"
#include "stagefit/diagnose/loop.h"
#include "stagefit/measurement/measurement_file.h"
#include "stagefit/model/model_file.h"

namespace stagefit::cli {

void RegisterLoopCommand(CLI::App& app) {
  auto* command = app.add_subcommand(
      "loop", "fit, diagnose, add the best effect of the catalogue, refit, again until the model is at the noise "
              "floor or nothing helps; writes the final model");
  struct Options {
    CommonOptions common;
    std::string measurement, out, out_dir, resume;
    std::string space;
    std::string geometry;
    int averages = 0;
    std::string exclude_channels;
    bool no_channel_checks = false;
    std::string params = "*.k.*";
    std::string effects;
    double fmin = 0, fmax = 0;
    int max_rounds = 4;
  };
  auto o = std::make_shared<Options>();
  AddCommonOptions(*command, o->common);
  AddWithOption(*command, o->common);
  command->add_option("--measurement", o->measurement, "measurement file (.mat, .csv, .uff)")->required();
  command->add_option("--out", o->out, "write the final model file (TOML) here")->required();
  command->add_option("--out-dir", o->out_dir,
                      "write loop_history.csv, after_rounds.toml (the model as the rounds left it, to --resume) and the "
                      "comparison tables before/ and after/ (scripts/plot_loop.sh DIR)");
  command->add_option("--resume", o->resume,
                      "go on from a model this command wrote (--out) for the same --model and --with: its effects "
                      "beyond theirs are the loop's own (they are refitted, merged, moved or dropped as a round's); "
                      "the first fit is left out");
  command->add_option("--geometry", o->geometry, kGeometryHelp);
  command->add_option("--averages", o->averages, kAveragesHelp)->check(CLI::Range(2, 1000000000));
  command->add_option("--exclude-channels", o->exclude_channels, kExcludeChannelsHelp);
  command->add_flag("--no-channel-checks", o->no_channel_checks,
                    "skip the checks of the test bench (reversed, swapped, dead, clipped, locally resonant channels) "
                    "that run before the loop");
  command->add_option("--space", o->space, "comparison space: compliance (sensors on one body: the 6x6 compliance at {X}), bodies (sensors on several bodies: each body's 6 DoF at its centre of mass) or raw; default: as the measurement's geometry calls for")
      ->check(CLI::IsMember({"compliance", "bodies", "raw"}));
  command->add_option("--params", o->params, "model parameters fitted in every step (comma-separated patterns)")
      ->capture_default_str();
  command->add_option("--effects", o->effects, "only these catalogue effects (comma-separated); default all");
  command->add_option("--max-rounds", o->max_rounds, "rounds of diagnosis at most, each adding one effect at most (default 4)")->check(CLI::PositiveNumber);
  command->add_option("--fmin", o->fmin, "lower end of the band, Hz");
  command->add_option("--fmax", o->fmax, "upper end of the band, Hz");
  command->callback([o] {
    const std::vector<std::string> inputs = {o->common.model_path, o->measurement, o->resume};
    CheckNotAnInput(o->out, {inputs.begin(), inputs.end()});
    if (!o->out_dir.empty()) {
      CheckNotAnInput((std::filesystem::path(o->out_dir) / "after_rounds.toml").string(), {inputs.begin(), inputs.end()});
    }
    // The outputs' folders before the long run, not after it.
    if (!o->out_dir.empty()) std::filesystem::create_directories(o->out_dir);
    const std::filesystem::path out_parent = std::filesystem::absolute(o->out).parent_path();
    if (!std::filesystem::is_directory(out_parent)) {
      throw InputError("--out " + o->out + ": the folder " + out_parent.string() + " does not exist");
    }
    if (!o->common.report_path.empty()) CheckNotAnInput(o->common.report_path, {inputs.begin(), inputs.end()});
    const model::ModelSpec spec = LoadModelFromOptions(o->common);
    measurement::FrfData data =
        ExcludeChannelsOption(ReadMeasurementFor(o->measurement, o->geometry, o->averages, spec), o->exclude_channels);
    // Faults of the test bench before faults of the model (docs/diagnose.md, "Test bench first").
    nlohmann::json non_rigid = nullptr;
    const nlohmann::json channel_faults = o->no_channel_checks ? nlohmann::json(nullptr) : CheckTestBench(&data, &non_rigid);
    diagnose::LoopOptions options;
    options.diagnose.comparison.space = ResolveComparisonSpace(o->space, data);
    if (o->fmin > 0) options.diagnose.comparison.fmin_hz = o->fmin;
    if (o->fmax > 0) options.diagnose.comparison.fmax_hz = o->fmax;
    options.diagnose.params = SplitCommaList(o->params);
    options.diagnose.effects = SplitCommaList(o->effects);
    for (const auto& e : options.diagnose.effects) model::FindEffectDefinition(e);
    options.max_rounds = o->max_rounds;
    if (!o->resume.empty()) {
      options.resume_from = model::ReadModelFile(o->resume);
      try {
        diagnose::CheckResumedState(spec, *options.resume_from);
      } catch (const InputError& e) {
        throw InputError("--resume " + o->resume + ": " + e.what());
      }
    }
    if (StderrIsTerminal()) options.progress = [](const std::string& line) { std::cerr << "loop: " << line << std::endl; };

    const diagnose::LoopSummary summary = diagnose::RunLoop(spec, data, options);
    std::printf("Error history (%s space, %d rounds at most):\n%s",
                compare::ToString(options.diagnose.comparison.space).c_str(), o->max_rounds,
                summary.HistoryTable().c_str());
    if (!summary.last_verdict.empty()) std::printf("\nLast diagnosis: %s\n", summary.last_verdict.c_str());
    if (non_rigid.is_array() && !non_rigid.empty()) {
      std::printf("\nThe channel checks found channels that do not move as one rigid body (\"not rigid\" above): the model, "
                  "whatever its error in %s space, does not explain their readings there.\n",
                  compare::ToString(options.diagnose.comparison.space).c_str());
    }
    std::printf("(%.1f s)\n", summary.time_s);
    model::WriteModelFile(o->out, summary.final_model);
    std::printf("wrote %s\n", o->out.c_str());
    if (!o->out_dir.empty()) {
      const std::filesystem::path dir = o->out_dir;
      WriteFileAtomically(dir / "loop_history.csv", diagnose::FormatLoopHistory(summary));
      model::WriteModelFile(dir / "after_rounds.toml", summary.after_rounds);
      CsvMeta meta;
      meta.units = {{"step", ""}, {"action", ""}, {"effect", ""}, {"error", "1"}, {"noise_floor", "1"}, {"times_floor", "1"}};
      meta.notes = {"error: the SPEC §4 error scalar after each step of the loop; noise_floor: the error the "
                    "measurement's noise alone leaves (docs/error-metric.md §8)"};
      WriteCsvMeta(dir / "loop_history.csv", meta);
      compare::CompareOptions before_options;
      before_options.comparison = options.diagnose.comparison;
      const std::vector<std::filesystem::path> protect = {o->measurement, o->common.model_path, o->out};
      compare::WriteCompareTables(dir / "before", compare::CompareModel(summary.initial, data, before_options), protect);
      compare::WriteCompareTables(dir / "after", compare::CompareModel(summary.final_model, data, before_options), protect);
      std::printf("wrote %s/loop_history.csv, %s/after_rounds.toml, %s/before/, %s/after/ (plots: bash scripts/plot_loop.sh %s)\n",
                  o->out_dir.c_str(), o->out_dir.c_str(), o->out_dir.c_str(), o->out_dir.c_str(), o->out_dir.c_str());
    }
    if (!o->common.report_path.empty()) {
      nlohmann::json history = nlohmann::json::array();
      for (const auto& s : summary.history) {
        history.push_back({{"action", s.action}, {"effect", s.effect}, {"error", s.error}});
      }
      nlohmann::json missing_bands = nlohmann::json::array();
      for (const auto& b : summary.missing_bands) {
        missing_bands.push_back({{"low_hz", b.band.low_hz}, {"high_hz", b.band.high_hz}, {"error", b.error}, {"share", b.share}});
      }
      nlohmann::json report = {{"command", "loop"},
                               {"measurement", o->measurement},
                               {"error", summary.history.back().error},
                               {"error_before", summary.history.front().error},
                               {"noise_floor", NoiseFloorJson(summary.history.back().error, summary.noise_floor)},
                               {"history", history},
                               {"effects_added", summary.effects_added},
                               {"stop_reason", summary.stop_reason},
                               {"confirmed", summary.confirmed},
                               {"implausible_effects", summary.implausible_effects},
                               {"conclusion", summary.conclusion},
                               {"missing_bands", missing_bands},
                               {"channels", ChannelErrorsJson(summary.final_channels)},
                               {"channel_faults", channel_faults},
                               {"non_rigid", non_rigid},
                               {"last_verdict", summary.last_verdict},
                               {"final_model", o->out},
                               {"time_s", summary.time_s}};
      WriteReport(o->common.report_path, report, inputs);
    }
  });
}

}  // namespace stagefit::cli
