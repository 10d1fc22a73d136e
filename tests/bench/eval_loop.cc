// Evaluates `stagefit loop` (diagnose::RunLoop) on synthetic hidden-effect measurements made by the
// brute-force generator (synthetic::MakeHiddenEffectCase: effects written as edits of bodies and joints,
// not through the catalogue), with the band, the number of frequencies and the noise drawn per case:
// fmax 150 or 600 Hz (fmin 5 Hz), 300-1200 log-spaced frequencies, noise 1-3 %, stiffness scatter 15 %.
// Per case: the effects the loop added against the truth's, the final error against the noise floor
// of the coherence, the distance of the final model to the noise-free truth on the same points and
// weights (||r_final - r_truth||, the error scalar of ln(H_final / H_truth)), and the time.
//
// Usage: eval_loop [--cases N] [--two-effects K] [--effect-free M] [--first-seed S] [--verbose 1]
//   Seeds: single-effect cases S .. S+N-1, two-effect cases S+N .., effect-free cases after them.

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "stagefit/common/memory.h"
#include "stagefit/compare/residuals.h"
#include "stagefit/diagnose/loop.h"
#include "stagefit/model/model_file.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace {

using namespace stagefit;

struct Outcome {
  bool named_all = false;    // every hidden effect added (name and location)
  bool extra = false;        // an effect added that is not hidden
  bool at_floor = false;     // final error <= 1.2 x the floor
  bool near_truth = false;   // distance to the noise-free truth <= 0.01
  double time_s = 0;
};

Outcome RunCase(const model::ModelSpec& nominal, uint64_t seed, int num_effects, bool verbose) {
  std::mt19937_64 rng(seed ^ 0x5eedULL);
  synthetic::HiddenEffectOptions options;
  options.num_effects = num_effects;
  options.fmin_hz = 5.0;
  options.fmax_hz = std::uniform_int_distribution<int>(0, 1)(rng) ? 600.0 : 150.0;
  options.num_frequencies = std::uniform_int_distribution<int>(300, 1200)(rng);
  options.noise_min = 0.01;
  options.noise_max = 0.03;
  const auto hidden = synthetic::MakeHiddenEffectCase(nominal, seed, options);
  diagnose::LoopOptions loop_options;
  if (verbose) loop_options.progress = [](const std::string& line) { std::printf("    %s\n", line.c_str()); };
  const diagnose::LoopSummary summary = diagnose::RunLoop(nominal, hidden.measurement, loop_options);

  const auto comparison = compare::Comparison::Create(nominal, hidden.measurement, loop_options.diagnose.comparison);
  Eigen::VectorXd r_final, r_truth;
  comparison.Residuals(summary.final_model, &r_final);
  comparison.Residuals(hidden.truth, &r_truth);
  const double distance = (r_final - r_truth).norm();

  std::set<std::string> truths, added;
  std::string truth_text, added_text;
  for (const auto& e : hidden.effects) {
    truths.insert(e.name + "@" + e.location);
    truth_text += (truth_text.empty() ? "" : " + ") + e.name + "@" + e.location;
  }
  for (const auto& w : summary.effects_added) {
    const std::string key = w.substr(0, w.find(':'));
    added.insert(key);
    added_text += (added_text.empty() ? "" : " + ") + key;
  }
  Outcome o;
  o.named_all = std::all_of(truths.begin(), truths.end(), [&](const std::string& t) { return added.count(t) > 0; });
  o.extra = std::any_of(added.begin(), added.end(), [&](const std::string& a) { return truths.count(a) == 0; });
  const double floor = summary.noise_floor.floor;
  o.at_floor = summary.history.back().error <= diagnose::kDoneTimesFloor * floor;
  o.near_truth = distance <= 0.01;
  o.time_s = summary.time_s;
  std::printf("seed %7llu  %4.0f Hz %4d pts  %-40s -> %-40s  error %.4f = %.2fx floor %.4f  |to truth| %.4f  %s%s%s %.1f s\n",
              static_cast<unsigned long long>(seed), options.fmax_hz, options.num_frequencies,
              truth_text.empty() ? "(none)" : truth_text.c_str(), added_text.empty() ? "(none)" : added_text.c_str(),
              summary.history.back().error, summary.history.back().error / floor, floor, distance,
              o.named_all ? "named " : "", o.at_floor ? "floor " : "", o.near_truth ? "truth " : "", summary.time_s);
  if (verbose) std::printf("%s", summary.HistoryTable().c_str());
  std::fflush(stdout);
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  KeepFreedMemory();  // as the stagefit program does
  int cases = 10, two_effects = 0, effect_free = 0, verbose = 0;
  uint64_t first_seed = 5000;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--cases")) cases = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--two-effects")) two_effects = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--effect-free")) effect_free = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--first-seed")) first_seed = std::strtoull(argv[i + 1], nullptr, 10);
    if (!std::strcmp(argv[i], "--verbose")) verbose = std::atoi(argv[i + 1]);
  }
  const model::ModelSpec nominal = model::DefaultModelSpec();
  struct Tally {
    int n = 0, named = 0, clean = 0, floor = 0, truth = 0, done = 0;
    double time = 0, max_time = 0;
  };
  auto run = [&](int count, int num_effects, uint64_t seed0, Tally* t) {
    for (int c = 0; c < count; ++c) {
      const Outcome o = RunCase(nominal, seed0 + c, num_effects, verbose);
      ++t->n;
      t->named += o.named_all;
      t->clean += !o.extra;
      t->floor += o.at_floor;
      t->truth += o.near_truth;
      t->done += o.named_all && !o.extra && o.at_floor;
      t->time += o.time_s;
      t->max_time = std::max(t->max_time, o.time_s);
    }
  };
  Tally one, two, none;
  run(cases, 1, first_seed, &one);
  run(two_effects, 2, first_seed + cases, &two);
  run(effect_free, 0, first_seed + cases + two_effects, &none);
  auto pct = [](int a, int n) { return n > 0 ? 100.0 * a / n : 0.0; };
  if (one.n) {
    std::printf("\nsingle effect (%d): named %d (%.0f %%), nothing else added %d, final within 1.2x the floor %d (%.0f %%), "
                "within 0.01 of the noise-free truth %d (%.0f %%); mean %.1f s, max %.1f s\n",
                one.n, one.named, pct(one.named, one.n), one.clean, one.floor, pct(one.floor, one.n), one.truth,
                pct(one.truth, one.n), one.time / one.n, one.max_time);
  }
  if (two.n) {
    std::printf("two effects (%d): both named %d (%.0f %%), both named and at the floor with nothing else %d (%.0f %%), "
                "within 0.01 of the truth %d; mean %.1f s, max %.1f s\n",
                two.n, two.named, pct(two.named, two.n), two.done, pct(two.done, two.n), two.truth, two.time / two.n,
                two.max_time);
  }
  if (none.n) {
    std::printf("effect-free (%d): nothing added %d (%.0f %%), final within 1.2x the floor %d; mean %.1f s\n", none.n,
                none.clean, pct(none.clean, none.n), none.floor, none.time / none.n);
  }
  return 0;
}
