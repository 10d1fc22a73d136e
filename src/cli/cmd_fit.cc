#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <sstream>

#include "command.h"
#include "report.h"
#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"
#include "stagefit/compare/residuals.h"
#include "stagefit/fit/least_squares.h"
#include "stagefit/fit/model_fit.h"
#include "stagefit/fit/recipe.h"
#include "stagefit/measurement/measurement_file.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"

namespace stagefit::cli {
namespace {

std::vector<std::string> SplitPatterns(const std::string& list) {
  std::vector<std::string> patterns;
  std::stringstream in(list);
  std::string item;
  while (std::getline(in, item, ',')) {
    const auto b = item.find_first_not_of(" \t");
    const auto e = item.find_last_not_of(" \t");
    if (b == std::string::npos) throw UsageError("--params '" + list + "': empty pattern, expected e.g. \"*.k.*\"");
    patterns.push_back(item.substr(b, e - b + 1));
  }
  if (patterns.empty()) throw UsageError("--params is empty, expected comma-separated patterns such as \"*.k.*\"");
  return patterns;
}

// A JSON number, or null for infinity / NaN (undetermined standard deviations).
nlohmann::json JsonNumber(double value) { return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(); }

nlohmann::json MakeReport(const fit::FitSummary& summary, const compare::Comparison& comparison,
                          const std::string& measurement_path, const std::string& model_source,
                          const std::string& out_path) {
  nlohmann::json report;
  report["command"] = "fit";
  report["model"] = model_source;
  report["measurement"] = measurement_path;
  report["space"] = compare::ToString(comparison.space());
  report["band_hz"] = {comparison.frequency_hz()[0], comparison.frequency_hz()[comparison.num_frequencies() - 1]};
  report["error"] = JsonNumber(summary.final_error);
  report["error_before"] = JsonNumber(summary.initial_error);
  report["status"] = fit::ToString(summary.status);
  report["message"] = summary.message;
  report["solver"] = summary.solver;
  report["iterations"] = summary.iterations;
  report["evaluations"] = summary.num_evaluations;
  report["time_s"] = summary.time_s;
  report["num_residuals"] = summary.num_residuals;
  report["residual_variance"] = JsonNumber(summary.residual_variance);
  nlohmann::json parameters = nlohmann::json::array();
  std::vector<std::string> names;
  for (const auto& p : summary.parameters) {
    names.push_back(p.name);
    parameters.push_back({{"name", p.name},
                          {"initial", p.initial},
                          {"value", p.value},
                          {"std", JsonNumber(p.std_dev)},
                          {"unit", p.unit},
                          {"lower", JsonNumber(p.lower)},
                          {"upper", JsonNumber(p.upper)},
                          {"identifiable", p.identifiable},
                          {"at_bound", p.at_bound},
                          {"relative_sensitivity", JsonNumber(p.relative_sensitivity)}});
  }
  report["parameters"] = parameters;
  nlohmann::json matrix = nlohmann::json::array();
  for (int i = 0; i < summary.correlation.rows(); ++i) {
    nlohmann::json row = nlohmann::json::array();
    for (int j = 0; j < summary.correlation.cols(); ++j) row.push_back(JsonNumber(summary.correlation(i, j)));
    matrix.push_back(row);
  }
  report["correlation"] = {{"names", names}, {"matrix", matrix}};
  report["warnings"] = summary.warnings;
  nlohmann::json starts = nlohmann::json::array();
  for (const auto& s : summary.starts) {
    starts.push_back({{"error_before", JsonNumber(std::sqrt(2.0 * s.initial_cost))},
                      {"error", JsonNumber(std::sqrt(2.0 * s.final_cost))},
                      {"status", fit::ToString(s.status)},
                      {"iterations", s.iterations}});
  }
  report["starts"] = starts;
  report["best_start"] = summary.best_start;
  if (!out_path.empty()) report["tuned_model"] = out_path;
  return report;
}

}  // namespace

void RegisterFitCommand(CLI::App& app) {
  auto* command = app.add_subcommand(
      "fit", "tune model parameters (joint stiffnesses by default) against a measurement; Ceres by default, "
             "NLopt selectable; writes the tuned model file");
  struct Options {
    CommonOptions common;
    std::string measurement, params, recipe, solver, nlopt_algorithm, jacobian, space, out, geometry, exclude_channels;
    int averages = 0;
    int starts = 1, max_iterations = 100, probe_rounds = 4;
    std::uint64_t seed = 1;
    double fmin_hz = 0.0, fmax_hz = 0.0;
    bool direct = false;
  };
  auto o = std::make_shared<Options>();
  AddCommonOptions(*command, o->common);
  AddWithOption(*command, o->common);
  auto* measurement_option = command->add_option("--measurement", o->measurement, "measurement file (.mat, .csv, .uff)");
  auto* params_option = command->add_option(
      "--params", o->params, "free parameters: comma-separated name patterns (default \"*.k.*\" and every parameter of the model's "
      "effects, e.g. payload@hexapod.mass; \"*@*\" matches every effect parameter)");
  command->add_option("--recipe", o->recipe, "fit recipe (TOML, fitting/recipe-*.toml); options given here override it");
  auto* solver_option = command->add_option("--solver", o->solver, "ceres (default) or nlopt")
                            ->check(CLI::IsMember({"ceres", "nlopt"}));
  auto* algorithm_option = command->add_option(
      "--nlopt-algorithm", o->nlopt_algorithm,
      "NLopt algorithm: LN_BOBYQA (default), LN_SBPLX, GN_CRS2_LM, GN_DIRECT, ... (global ones are polished by Ceres)");
  auto* jacobian_option = command->add_option("--jacobian", o->jacobian, "analytic (default) or finite-difference")
                              ->check(CLI::IsMember({"analytic", "finite-difference"}));
  auto* starts_option = command->add_option("--starts", o->starts, "number of starts (multi-start; default 1)")
                            ->check(CLI::PositiveNumber);
  auto* seed_option = command->add_option("--seed", o->seed, "seed of the multi-start draws (default 1)");
  auto* iterations_option = command->add_option("--max-iterations", o->max_iterations,
                                                "iteration budget per start (default 100)")
                                ->check(CLI::PositiveNumber);
  auto* probe_option = command->add_option("--probe-rounds", o->probe_rounds,
                                           "after the fit, rounds of basin probes: each stiffness x 1/8 .. 8, "
                                           "restart from the best probe that lowers the error (default 4; 0: none)")
                           ->check(CLI::NonNegativeNumber);
  command->add_option("--geometry", o->geometry, kGeometryHelp);
  command->add_option("--averages", o->averages, kAveragesHelp)->check(CLI::Range(2, 1000000000));
  command->add_option("--exclude-channels", o->exclude_channels, kExcludeChannelsHelp);
  auto* space_option = command->add_option("--space", o->space, "comparison space: compliance (sensors on one body: the 6x6 compliance at {X}), bodies (sensors on several bodies: each body's 6 DoF at its centre of mass) or raw; default: as the measurement's geometry calls for")
                           ->check(CLI::IsMember({"compliance", "bodies", "raw"}));
  auto* fmin_option = command->add_option("--fmin", o->fmin_hz, "lower end of the comparison band, Hz");
  auto* fmax_option = command->add_option("--fmax", o->fmax_hz, "upper end of the comparison band, Hz");
  command->add_flag("--direct", o->direct,
                    "fit on the whole band at once only (default: also a continuation in band, 8x the lowest "
                    "frequency then x2.5 per stage, and keep the better; docs/fitting.md)");
  command->add_option("--out", o->out, "write the tuned model file (TOML) here");
  command->callback([=] {
    fit::FitRecipe recipe;
    if (!o->recipe.empty()) recipe = fit::ReadFitRecipe(o->recipe);
    if (measurement_option->count() > 0) recipe.measurement = o->measurement;
    if (!o->common.model_path.empty()) recipe.model = o->common.model_path;
    if (params_option->count() > 0) recipe.params = SplitPatterns(o->params);
    const bool default_params = recipe.params.empty();
    if (default_params) recipe.params = {"*.k.*"};
    if (solver_option->count() > 0) recipe.options.solver = fit::ParseSolverKind(o->solver, "--solver");
    if (algorithm_option->count() > 0) {
      fit::CheckNloptAlgorithm(o->nlopt_algorithm, "--nlopt-algorithm");
      recipe.options.nlopt_algorithm = o->nlopt_algorithm;
    }
    if (jacobian_option->count() > 0) recipe.options.jacobian = fit::ParseJacobianKind(o->jacobian, "--jacobian");
    if (starts_option->count() > 0) recipe.options.num_starts = o->starts;
    if (seed_option->count() > 0) recipe.options.seed = o->seed;
    if (iterations_option->count() > 0) recipe.options.max_iterations = o->max_iterations;
    if (probe_option->count() > 0) recipe.options.max_probe_rounds = o->probe_rounds;
    if (space_option->count() > 0) {
      recipe.comparison.space = compare::ParseComparisonSpace(o->space, "--space");
      recipe.space_given = true;
    }
    if (fmin_option->count() > 0) recipe.comparison.fmin_hz = o->fmin_hz;
    if (fmax_option->count() > 0) recipe.comparison.fmax_hz = o->fmax_hz;
    if (recipe.measurement.empty()) {
      throw UsageError("fit: --measurement FILE is required (or a recipe with measurement = \"...\")");
    }

    CommonOptions model_options = o->common;
    model_options.model_path = recipe.model;
    std::vector<std::string> inputs = {recipe.measurement};
    if (!recipe.model.empty()) inputs.push_back(recipe.model);
    if (!o->recipe.empty()) inputs.push_back(o->recipe);
    if (!o->out.empty()) CheckNotAnInput(o->out, {inputs.begin(), inputs.end()});
    if (!o->common.report_path.empty()) CheckNotAnInput(o->common.report_path, {inputs.begin(), inputs.end()});

    model::ModelSpec spec = LoadModelFromOptions(model_options);
    // By default the stiffnesses and every parameter of the model's effects (model/parameters.h).
    if (default_params) recipe.params = model::WithEffectParameters(recipe.params, spec);
    const measurement::FrfData data =
        ExcludeChannelsOption(ReadMeasurementFor(recipe.measurement, o->geometry, o->averages, spec), o->exclude_channels);
    if (!recipe.space_given) recipe.comparison.space = ResolveComparisonSpace("", data);
    const compare::Comparison comparison = compare::Comparison::Create(spec, data, recipe.comparison);
    const std::vector<model::ParameterInfo> params = model::MatchParameters(spec, recipe.params);

    const bool show_progress = StderrIsTerminal();
    bool progress_shown = false;
    if (show_progress) {
      recipe.options.progress = [&progress_shown](const fit::FitProgress& p) {
        if (p.elapsed_s < 1.0) return;
        progress_shown = true;
        std::fprintf(stderr, "\rfit: start %d/%d, %s iteration %d, error %.6g   ", p.start + 1, p.num_starts,
                     p.stage.c_str(), p.iteration, std::sqrt(2.0 * p.cost));
        std::fflush(stderr);
      };
    }
    const fit::FitSummary summary =
        o->direct ? fit::FitModel(spec, comparison, params, recipe.options, recipe.bounds)
                  : fit::FitModelWithBandContinuation(spec, data, recipe.comparison, comparison, params, recipe.options,
                                                      recipe.bounds);
    if (progress_shown) std::fprintf(stderr, "\n");

    std::printf("%s\n%s", summary.BriefReport().c_str(), summary.FullReport().c_str());
    const compare::NoiseFloor floor = comparison.CalcNoiseFloor();
    std::fputs(compare::NoiseFloorLine(summary.final_error, floor).c_str(), stdout);
    if (!o->out.empty()) {
      model::WriteModelFile(o->out, spec);
      std::printf("wrote %s\n", o->out.c_str());
    }
    if (!o->common.report_path.empty()) {
      nlohmann::json report = MakeReport(summary, comparison, recipe.measurement, ModelSource(model_options), o->out);
      report["noise_floor"] = NoiseFloorJson(summary.final_error, floor);
      WriteReport(o->common.report_path, report, inputs);
    }
    // Exit 3 only when the numerics failed: a failed solver, or a budget that ran out without
    // lowering the error. A fit that stopped at its budget having lowered it wrote a better model.
    const bool lowered = summary.final_error < summary.initial_error;
    const bool failed = summary.status == fit::FitStatus::kFailed ||
                        (summary.status == fit::FitStatus::kMaxIterations && !lowered);
    if (summary.status == fit::FitStatus::kMaxIterations && lowered) {
      std::printf("note: the iteration budget ran out before a tolerance was met; the error fell from %.6g to %.6g "
                  "(more --max-iterations may lower it further)\n",
                  summary.initial_error, summary.final_error);
    }
    ExitCode() = failed ? kExitNumerics : kExitOk;
  });
}

}  // namespace stagefit::cli
