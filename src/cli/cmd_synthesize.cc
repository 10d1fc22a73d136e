#include <cstdio>

#include <nlohmann/json.hpp>

#include "command.h"
#include "report.h"
#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"
#include "stagefit/measurement/measurement_file.h"
#include "stagefit/measurement/raw_hammer_file.h"
#include "stagefit/model/model_file.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace stagefit::cli {

void RegisterSynthesizeCommand(CLI::App& app) {
  auto* command = app.add_subcommand(
      "synthesize",
      "make a synthetic 12x10 hammer-test measurement of the top plate (SPEC §2 geometry) with known truth, "
      "by an independent brute-force solver; for trying the tool and testing diagnose");
  struct Options {
    CommonOptions common;
    std::string out;
    double noise = 0.02;
    uint64_t seed = 1;
    double fmin = 10, fmax = 400;
    int points = 300;
    int hidden_effects = -1;
    double scatter = 0.15;
    std::string raw;
    std::string layout = "top-plate";
  };
  auto o = std::make_shared<Options>();
  AddCommonOptions(*command, o->common);
  AddWithOption(*command, o->common);
  command->add_option("--out", o->out, "measurement file to write (.mat, .csv or .uff)")->required();
  command->add_option("--noise", o->noise, "relative and absolute noise level (0.02 = 2 %)")->capture_default_str();
  command->add_option("--seed", o->seed, "random seed")->capture_default_str();
  command->add_option("--fmin", o->fmin, "lowest frequency, Hz")->capture_default_str();
  command->add_option("--fmax", o->fmax, "highest frequency, Hz")->capture_default_str();
  command->add_option("--points", o->points, "number of log-spaced frequencies")->capture_default_str();
  command->add_option("--hidden-effects", o->hidden_effects,
                      "draw this many (0-2) hidden effects and a stiffness scatter from --seed instead of using "
                      "the model as it is; the truth goes to --report");
  command->add_option("--raw", o->raw,
                      "also write raw hammer time data (force and accelerometer records, 3 hits per impact) of the "
                      "same truth to this .mat file (layout: measurements/README.md)");
  command->add_option("--layout", o->layout,
                      "top-plate (default: the 12x10 compliance test of the top plate) or whole-stack (three triaxial "
                      "accelerometers on every body, five hammer impacts on the translation stage, seed Figure 2.3)")
      ->check(CLI::IsMember({"top-plate", "whole-stack"}));
  command->add_option("--scatter", o->scatter, "log-normal sigma of the stiffness scatter with --hidden-effects")->capture_default_str();
  command->callback([o] {
    if (o->noise < 0 || o->noise > 1) throw UsageError("--noise must be in [0, 1]");
    if (!(o->fmin > 0 && o->fmax > o->fmin) || o->points < 2) throw UsageError("need 0 < --fmin < --fmax and --points >= 2");
    model::ModelSpec spec = LoadModelFromOptions(o->common);
    CheckNotAnInput(o->out, {o->common.model_path});
    if (!o->raw.empty()) CheckNotAnInput(o->raw, {o->common.model_path});
    if (!o->common.report_path.empty()) CheckNotAnInput(o->common.report_path, {o->common.model_path});
    const bool whole_stack = o->layout == "whole-stack";
    nlohmann::json report = {{"command", "synthesize"}, {"noise", o->noise}, {"seed", o->seed}, {"layout", o->layout}};
    measurement::FrfData data;
    if (o->hidden_effects >= 0) {
      synthetic::HiddenEffectOptions options;
      options.num_effects = o->hidden_effects;
      options.stiffness_scatter = o->scatter;
      options.noise_min = options.noise_max = o->noise;
      options.fmin_hz = o->fmin;
      options.fmax_hz = o->fmax;
      options.num_frequencies = o->points;
      if (whole_stack) options.layout = synthetic::TestLayout::kWholeStack;
      auto c = synthetic::MakeHiddenEffectCase(spec, o->seed, options);
      data = c.measurement;
      nlohmann::json effects = nlohmann::json::array();
      for (const auto& e : c.effects) {
        effects.push_back({{"effect", e.name}, {"location", e.location}, {"description", e.description}});
        std::printf("hidden effect: %s@%s: %s\n", e.name.c_str(), e.location.c_str(), e.description.c_str());
      }
      report["hidden_effects"] = effects;
      report["truth_model"] = model::WriteModelToml(c.truth);
    } else if (whole_stack) {
      data = synthetic::CalcBruteForceFrf(spec, synthetic::WholeStackSensors(spec), synthetic::WholeStackImpacts(spec),
                                          synthetic::LogFrequencies(o->fmin, o->fmax, o->points),
                                          measurement::FrfQuantity::kAccelerance);
      synthetic::AddNoise(data, {o->noise, o->noise, o->seed});
    } else {
      const int frame = model::FindFrame(spec, spec.compliance_frame);
      if (frame < 0) throw InputError("the model has no compliance frame for the test geometry");
      const auto& X = spec.frames[frame];
      data = synthetic::CalcBruteForceFrf(spec, synthetic::ComplianceTestSensors(X.body, X.origin_W),
                                          synthetic::ComplianceTestImpacts(X.body, X.origin_W),
                                          synthetic::LogFrequencies(o->fmin, o->fmax, o->points),
                                          measurement::FrfQuantity::kAccelerance);
      synthetic::AddNoise(data, {o->noise, o->noise, o->seed});
      data.frame_origin_W = X.origin_W;
    }
    measurement::WriteMeasurement(o->out, data);
    if (!o->raw.empty()) {
      if (o->hidden_effects >= 0) throw UsageError("--raw is made from the model as given; do not combine it with --hidden-effects");
      if (whole_stack) throw UsageError("--raw is made for the top-plate layout; do not combine it with --layout whole-stack");
      CheckNotAnInput(o->raw, {o->common.model_path, o->out});
      const auto& X = spec.frames[model::FindFrame(spec, spec.compliance_frame)];
      synthetic::RawHammerOptions raw_options;
      raw_options.noise = o->noise / 4;
      raw_options.seed = o->seed + 1;
      auto raw = synthetic::MakeRawHammerTest(spec, synthetic::ComplianceTestSensors(X.body, X.origin_W),
                                              synthetic::ComplianceTestImpacts(X.body, X.origin_W), raw_options);
      raw.frame_origin_W = X.origin_W;
      measurement::WriteRawHammerFile(o->raw, raw, measurement::MatVersion::kV5);
      std::printf("wrote %s: raw time data, %d impacts x %d hits, %d samples at %.0f Hz\n", o->raw.c_str(),
                  static_cast<int>(raw.inputs.size()), raw_options.hits_per_impact, raw_options.num_samples,
                  raw_options.sample_rate_hz);
    }
    std::printf("wrote %s: %d outputs x %d inputs x %d frequencies (%.4g-%.4g Hz), noise %.3g\n", o->out.c_str(),
                data.num_outputs(), data.num_inputs(), data.num_frequencies(), o->fmin, o->fmax, o->noise);
    if (!o->common.report_path.empty()) WriteReport(o->common.report_path, report, {o->common.model_path, o->out});
  });
}

}  // namespace stagefit::cli
