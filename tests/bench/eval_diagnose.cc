// Evaluates diagnose on synthetic measurements with hidden effects (synthetic::MakeHiddenEffectCase):
// the share of cases whose hidden effect and location rank first, the share whose error after adding
// the best effect comes within 1.5x of the noise floor (the truth model's own error), and the share of
// effect-free cases where diagnose wrongly claims an effect. With --two-effects K, K further cases hide
// two effects each and follow the README's loop: diagnose, add the best effect, diagnose the model with it
// again, ..., until nothing helps (at most 4 rounds); counted are the cases whose first round names one
// of the two, whose rounds name both, and whose error at the loop's end comes within 1.5x of the floor.
//
// Usage: eval_diagnose [--cases N] [--effect-free M] [--two-effects K] [--first-seed S] [--points F] [--verbose 1|2]
//   --points: frequencies per measurement (default 300); --verbose 2 lists the truth's effects and the top candidates too.

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <set>
#include <string>
#include <vector>

#include "stagefit/common/memory.h"
#include "stagefit/compare/residuals.h"
#include "stagefit/diagnose/diagnose.h"
#include "stagefit/fit/least_squares.h"
#include "stagefit/model/model_file.h"
#include "stagefit/synthetic/synthetic_measurement.h"

int main(int argc, char** argv) {
  using namespace stagefit;
  KeepFreedMemory();  // as the stagefit program does
  fit::SilenceSolverLog();
  int cases = 30, effect_free = 10, two_effects = 0, verbose = 0, points = 300;
  uint64_t first_seed = 1000;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--cases")) cases = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--effect-free")) effect_free = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--two-effects")) two_effects = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--first-seed")) first_seed = std::strtoull(argv[i + 1], nullptr, 10);
    if (!std::strcmp(argv[i], "--verbose")) verbose = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--points")) points = std::atoi(argv[i + 1]);
  }
  const model::ModelSpec nominal = model::DefaultModelSpec();
  int ranked_first = 0, near_floor = 0, false_claims = 0;
  double total_time = 0;
  for (int c = 0; c < cases + effect_free; ++c) {
    const bool with_effect = c < cases;
    synthetic::HiddenEffectOptions options;
    options.num_effects = with_effect ? 1 : 0;
    options.num_frequencies = points;
    auto hidden = synthetic::MakeHiddenEffectCase(nominal, first_seed + c, options);
    diagnose::DiagnoseOptions diagnose_options;
    if (verbose) diagnose_options.progress = [](const std::string& line) { std::printf("    %s\n", line.c_str()); };
    auto summary = diagnose::Diagnose(nominal, hidden.measurement, diagnose_options);
    auto comparison = compare::Comparison::Create(nominal, hidden.measurement, diagnose_options.comparison);
    const double floor = comparison.Error(hidden.truth);
    total_time += summary.time_s;
    const auto& best = summary.candidates.front();
    if (with_effect) {
      const auto& truth = hidden.effects.front();
      const bool first = summary.effect_found && best.effect.name == truth.name && best.effect.location == truth.location;
      const bool close = best.error_after <= 1.5 * floor;
      ranked_first += first;
      near_floor += close;
      std::printf("case %3d  %-28s (vis %5.1f) -> %-28s first=%d  error %.4f -> %.4f (floor %.4f) %s  %.1f s\n", c,
                  (truth.name + "@" + truth.location).c_str(), truth.visibility,
                  (best.effect.name + "@" + best.effect.location).c_str(), first, summary.error_baseline,
                  best.error_after, floor, close ? "near-floor" : "", summary.time_s);
    } else {
      false_claims += summary.effect_found;
      std::printf("case %3d  (no effect)  claimed=%d (%s)  error %.4f, floor %.4f  %.1f s\n", c, summary.effect_found,
                  (best.effect.name + "@" + best.effect.location).c_str(), summary.error_baseline, floor, summary.time_s);
    }
    if (verbose > 1) {
      for (const auto& e : hidden.effects) std::printf("      truth: %s\n", e.description.c_str());
      for (size_t k = 0; k < summary.candidates.size() && k < 5; ++k) {
        const auto& cand = summary.candidates[k];
        std::printf("      %zu. %s  error %.4f  dBIC %.1f%s\n", k + 1, cand.with.c_str(), cand.error_after, cand.delta_bic,
                    cand.helps ? "  helps" : "");
      }
    }
    std::fflush(stdout);
  }
  std::printf("\nright effect and location first: %d/%d (%.0f %%)\n", ranked_first, cases, 100.0 * ranked_first / std::max(1, cases));
  std::printf("error within 1.5x of the noise floor: %d/%d (%.0f %%)\n", near_floor, cases, 100.0 * near_floor / std::max(1, cases));
  std::printf("effect-free cases with a wrongly claimed effect: %d/%d (%.0f %%)\n", false_claims, effect_free,
              100.0 * false_claims / std::max(1, effect_free));
  std::printf("mean diagnosis time: %.1f s\n", total_time / std::max(1, cases + effect_free));
  if (two_effects <= 0) return 0;

  // Two hidden effects: the loop, until nothing helps (at most kMaxRounds rounds).
  constexpr int kMaxRounds = 4;
  std::printf("\n");
  int one_first = 0, both_named = 0, loop_near_floor = 0;
  for (int c = 0; c < two_effects; ++c) {
    const uint64_t seed = first_seed + cases + effect_free + c;
    synthetic::HiddenEffectOptions options;
    options.num_effects = 2;
    options.num_frequencies = points;
    auto hidden = synthetic::MakeHiddenEffectCase(nominal, seed, options);
    diagnose::DiagnoseOptions diagnose_options;
    if (verbose) diagnose_options.progress = [](const std::string& line) { std::printf("    %s\n", line.c_str()); };
    const double floor = compare::Comparison::Create(nominal, hidden.measurement, diagnose_options.comparison).Error(hidden.truth);
    std::set<std::string> truths;
    std::string truth_text;
    for (const auto& e : hidden.effects) {
      truths.insert(e.name + "@" + e.location);
      truth_text += (truth_text.empty() ? "" : " + ") + e.name + "@" + e.location;
    }
    model::ModelSpec model = nominal;
    std::vector<std::string> named;
    std::vector<double> errors;
    double time = 0;
    for (int round = 0; round < kMaxRounds; ++round) {
      const auto summary = diagnose::Diagnose(model, hidden.measurement, diagnose_options);
      time += summary.time_s;
      if (round == 0) errors.push_back(summary.error_baseline);
      if (!summary.effect_found) break;
      const auto& best = summary.candidates.front();
      named.push_back(best.effect.name + "@" + best.effect.location);
      errors.push_back(best.error_after);
      model = diagnose::ApplyCandidate(summary, best);
    }
    const bool first = !named.empty() && truths.count(named[0]);
    std::set<std::string> named_truths;
    for (const auto& n : named) {
      if (truths.count(n)) named_truths.insert(n);
    }
    const bool both = named_truths.size() == 2;
    const bool close = errors.back() <= 1.5 * floor;
    one_first += first;
    both_named += both;
    loop_near_floor += close;
    std::string named_text, error_text = "error";
    for (const auto& n : named) named_text += (named_text.empty() ? "" : " + ") + n;
    for (double e : errors) {
      char value[32];
      std::snprintf(value, sizeof value, "%.4f", e);
      error_text += (error_text == "error" ? " " : " -> ") + std::string(value);
    }
    std::printf("two-effect case %3d  %s -> %s  first=%d both=%d  %s (floor %.4f) %s  %.1f s\n", c, truth_text.c_str(),
                named.empty() ? "(none)" : named_text.c_str(), first, both, error_text.c_str(), floor, close ? "near-floor" : "", time);
    std::fflush(stdout);
  }
  std::printf("\ntwo-effect cases, first round names one of the two: %d/%d (%.0f %%)\n", one_first, two_effects,
              100.0 * one_first / two_effects);
  std::printf("two-effect cases, the loop names both: %d/%d (%.0f %%)\n", both_named, two_effects, 100.0 * both_named / two_effects);
  std::printf("two-effect cases, error at the loop's end within 1.5x of the noise floor: %d/%d (%.0f %%)\n", loop_near_floor,
              two_effects, 100.0 * loop_near_floor / two_effects);
  return 0;
}
