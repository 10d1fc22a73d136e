// Evaluates `stagefit loop` (diagnose::RunLoop) on synthetic hidden-effect measurements made by the
// brute-force generator (synthetic::MakeHiddenEffectCase: effects written as edits of bodies and joints,
// not through the catalogue), with the band, the number of frequencies and the noise drawn per case:
// fmax 150 or 600 Hz (fmin 5 Hz), 300-1200 log-spaced frequencies, noise 1-3 %, stiffness scatter 15 %.
// Per case: the effects the loop added against the truth's, the final error against the noise floor
// of the coherence, the distance of the final model to the noise-free truth on the same points and
// weights (||r_final - r_truth||, the error scalar of ln(H_final / H_truth)), and the time.
//
// Out-of-catalogue cases (--outside O, synthetic::MakeOutsideCatalogueCase: a flexible mode of the top
// plate, bending or in-plane, or a cable between the granite and the hexapod, kinds in turn, changing
// the data by 8-32 noise standard deviations): whether
// the loop adds nothing, and whether its conclusion localises what is missing. By band: one of the
// two bands it names as where what is missing acts (LoopSummary::missing_bands; the last diagnosis'
// worst bands when it names none) holds the frequency where the hidden part changes the data most ("peak"; or,
// counted apart, the worst element's own worst band, named with it when it holds a third of its
// error), or is one of the fewest bands that hold half the change ("half"). By channel: one of the
// three worst elements it names is one of the fewest elements of the top platform's accelerance that
// hold half the change ("element"), one of them or its least rigid channel is on a raw channel the
// hidden part changes most ("channel", for the raw space), or one of the raw channels it names as
// standing out is (diagnose::WorstChannels, ChannelWords; "raw"). The generator computes where the
// change is (synthetic::OutsideCatalogueCase) from its own projection, not the comparison's.
//
// Usage: eval_loop [--cases N] [--two-effects K] [--effect-free M] [--three-effects L] [--outside O]
//                  [--first-seed S] [--space compliance|raw] [--max-rounds R] [--effects a,b]
//                  [--outside-kinds k1,k2,..] [--rounds-above X] [--relocate-above X] [--hiding NAME]
//                  [--draws first|own] [--noise-per-channel 0|1] [--verbose 1|2]
//   --outside-kinds: the out-of-catalogue kinds taken in turn (default plate-bending,plate-breathing,cable);
//   --verbose 2 also prints the last diagnosis' best candidate of every effect and location (16 at most);
//   --effects a,b tries only these effects of the catalogue;
//   --hiding NAME runs and counts only the drawn catalogue cases that hide effect NAME (sensor-geometry, ...);
//   --draws first rebuilds the cases as the generator's first rule drew them (each effect's visibility
//   against the truth with no effect: synthetic::HiddenEffectOptions::visibility_against_no_effect),
//   to rerun the sets up to seed 82029; own (the default) takes it against the effects drawn before;
//   --noise-per-channel 1 gives the noise's absolute part a floor per sensor channel, the same for every
//   impact (synthetic::NoiseOptions::per_channel), in the measurement and in the visibility the hidden
//   parts are drawn to; 0 (the default, every set up to seed 83717) scales it per element.
//   Seeds: single-effect cases S .. S+N-1, two-effect cases S+N .., effect-free cases after them, then
//   three-effect cases, then out-of-catalogue cases.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "stagefit/common/memory.h"
#include "stagefit/compare/residuals.h"
#include "stagefit/diagnose/loop.h"
#include "stagefit/fit/least_squares.h"
#include "stagefit/measurement/channel_checks.h"
#include "stagefit/model/model_file.h"
#include "stagefit/synthetic/outside_catalogue.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace {

using namespace stagefit;

// The comparison space of every loop (--space; default compliance, as `stagefit loop` on a top-plate test).
compare::ComparisonSpace g_space = compare::ComparisonSpace::kCompliance;
// Rounds of diagnosis at most (--max-rounds; default LoopOptions').
int g_max_rounds = diagnose::LoopOptions{}.max_rounds;
// A round runs above this many times the floor (--rounds-above; default LoopOptions').
double g_rounds_above = diagnose::LoopOptions{}.rounds_above_times_floor;
// The relocation step runs above this many times the floor (--relocate-above; default LoopOptions').
double g_relocate_above = diagnose::LoopOptions{}.relocate_above_times_floor;
// Effects tried (--effects a,b; empty: the whole catalogue).
std::vector<std::string> g_effects;
// Only the drawn cases that hide this effect are run and counted (--hiding NAME; empty: every case).
std::string g_hiding;
// The generator's first rule of the draws (--draws first).
bool g_draws_as_first = false;
// The noise's absolute part per output channel (--noise-per-channel 1: HiddenEffectOptions::noise_per_channel).
bool g_noise_per_channel = false;

struct Outcome {
  bool named_all = false;    // every hidden effect added (name and location)
  bool extra = false;        // an effect added that is not hidden
  bool at_floor = false;     // final error <= 1.2 x the floor
  bool near_truth = false;   // distance to the noise-free truth <= 0.01
  bool raw_alarm = false;    // the conclusion at the floor says a raw channel stands out (none does here)
  bool non_rigid = false;    // the channel checks find channels not rigid together (ChannelCheckResult::non_rigid)
  double time_s = 0;
};

/// The channel checks the stagefit commands run before the loop (cli::CheckTestBench).
measurement::ChannelCheckResult CheckTestBench(const measurement::FrfData& data) {
  return measurement::CheckChannels(data, Eigen::Vector3d::Zero());
}

// The conclusion at the floor names raw channels that stand out (diagnose::ConclusionChannels).
bool RawChannelAlarm(const diagnose::LoopSummary& summary) {
  return summary.confirmed && !diagnose::ConclusionChannels(summary).empty();
}

synthetic::HiddenEffectOptions DrawOptions(uint64_t seed, int num_effects) {
  std::mt19937_64 rng(seed ^ 0x5eedULL);
  const double fmax_hz = std::uniform_int_distribution<int>(0, 1)(rng) ? 600.0 : 150.0;
  const int num_frequencies = std::uniform_int_distribution<int>(300, 1200)(rng);
  synthetic::HiddenEffectOptions options = synthetic::EvalLoopCaseOptions(num_effects, fmax_hz, num_frequencies);
  options.visibility_against_no_effect = g_draws_as_first;
  options.noise_per_channel = g_noise_per_channel;
  return options;
}

// The last diagnosis' leading candidates: what the loop chose from, or why it stopped.
void PrintLeaders(const diagnose::DiagnoseSummary& last) {
  for (size_t k = 0; k < last.candidates.size() && k < 4; ++k) {
    const diagnose::Candidate& c = last.candidates[k];
    std::printf("    last diagnosis #%zu: %-40s error %.4f  delta BIC %.0f  %s%s\n", k + 1,
                (c.effect.name + "@" + c.effect.location).c_str(), c.error_after, c.delta_bic, c.helps ? "helps " : "",
                c.implausible.empty() ? "" : ("(implausible: " + c.implausible + ")").c_str());
  }
}

std::optional<Outcome> RunCase(const model::ModelSpec& nominal, uint64_t seed, int num_effects, int verbose) {
  const synthetic::HiddenEffectOptions options = DrawOptions(seed, num_effects);
  const auto hidden = synthetic::MakeHiddenEffectCase(nominal, seed, options);
  if (!g_hiding.empty() && std::none_of(hidden.effects.begin(), hidden.effects.end(),
                                        [](const auto& e) { return e.name == g_hiding; })) {
    return std::nullopt;
  }
  diagnose::LoopOptions loop_options;
  loop_options.diagnose.comparison.space = g_space;
  loop_options.max_rounds = g_max_rounds;
  loop_options.rounds_above_times_floor = g_rounds_above;
  loop_options.relocate_above_times_floor = g_relocate_above;
  loop_options.diagnose.effects = g_effects;
  if (verbose) {
    // Each line with the seconds since the case started (the diagnosis' own lines count from its start).
    const auto t0 = std::chrono::steady_clock::now();
    loop_options.progress = [t0](const std::string& line) {
      std::printf("    %6.1f  %s\n", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), line.c_str());
      std::fflush(stdout);
    };
  }
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
  o.raw_alarm = RawChannelAlarm(summary);
  o.non_rigid = !CheckTestBench(hidden.measurement).non_rigid.empty();
  o.time_s = summary.time_s;
  std::printf("seed %7llu  %4.0f Hz %4d pts  %-40s -> %-40s  error %.4f = %.2fx floor %.4f  |to truth| %.4f  %s%s%s%s%s %.1f s\n",
              static_cast<unsigned long long>(seed), options.fmax_hz, options.num_frequencies,
              truth_text.empty() ? "(none)" : truth_text.c_str(), added_text.empty() ? "(none)" : added_text.c_str(),
              summary.history.back().error, summary.history.back().error / floor, floor, distance,
              o.named_all ? "named " : "", o.at_floor ? "floor " : "", o.near_truth ? "truth " : "",
              summary.confirmed || summary.effects_added.empty() ? "" : "(not confirmed) ", o.raw_alarm ? "RAW-CHANNEL-ALARM " : "",
              summary.time_s);
  if (o.raw_alarm) {
    // The noise-free truth's own raw channels on the same data: an alarm the truth raises too comes
    // from the data and their floor, not from what the loop fitted.
    std::string line;
    for (const auto& c : diagnose::WorstChannels(hidden.truth, hidden.measurement, loop_options.diagnose.comparison, 3)) {
      char word[96];
      std::snprintf(word, sizeof word, "%s%s %.2fx the floor (%.2fx the median)", line.empty() ? "" : ", ", c.name.c_str(),
                    c.times_floor, c.times_median);
      line += word;
    }
    std::printf("    raw channels of the truth: %s\n", line.empty() ? "(none)" : line.c_str());
  }
  if (verbose) {
    for (const auto& e : hidden.effects) std::printf("    hidden: %s (visibility %.1f)\n", e.description.c_str(), e.visibility);
    std::printf("%s", summary.HistoryTable().c_str());
    PrintLeaders(summary.last_diagnosis);
    if (verbose > 1) {
      // The best candidate of every effect and location (first in the ranking), with its fitted values.
      std::set<std::string> seen;
      for (const auto& c : summary.last_diagnosis.candidates) {
        if (!seen.insert(c.effect.name + "@" + c.effect.location).second || seen.size() > 16) continue;
        std::printf("    best %-18s %s  error %.4f%s\n", c.effect.name.c_str(), c.with.c_str(), c.error_after,
                    c.implausible.empty() ? "" : (" (implausible: " + c.implausible + ")").c_str());
      }
    }
  }
  std::fflush(stdout);
  return o;
}

constexpr double kOutsideVisibility = 8.0;

struct OutsideOutcome {
  bool added = false;    // an effect of the catalogue added on the way
  bool claimed = false;  // and confirmed: the loop ends at the floor with it (LoopSummary::confirmed)
  bool at_floor = false;  // the loop ended within 1.2x the floor: the hidden part is absorbed or unseen in this space
  bool band = false;     // a worst band named holds the peak of the change
  bool band_half = false;  // a worst band named is one of the bands holding half the change
  bool final_band_half = false;  // the same of the last diagnosis' worst bands (before missing_bands was named)
  bool element = false;  // a worst element named is one of the platform elements holding half the change
  bool element_band = false;  // the worst element's own worst band, named with it, holds it
  bool channel = false;  // a worst element named (or the least rigid channel) is on a changed channel
  bool raw_channel = false;  // one of the raw channels the conclusion names as standing out is
  bool checks_band = false;     // the channel checks' band of channels not rigid together is one holding half the change or the peak
  bool checks_channel = false;  // and a channel they name is one the hidden part changes most
  double time_s = 0;
};

OutsideOutcome RunOutsideCase(const model::ModelSpec& nominal, uint64_t seed, const std::string& kind, bool verbose) {
  synthetic::HiddenEffectOptions options = DrawOptions(seed, 0);
  // Visible enough that a stiffness fit cannot absorb it (at 2-8 noise standard deviations, the
  // catalogue cases' visibility, the first fit reached the floor in every case and there was nothing
  // to localise): 8-32.
  options.min_visibility = kOutsideVisibility;
  const auto hidden = synthetic::MakeOutsideCatalogueCase(nominal, seed, kind, options);
  diagnose::LoopOptions loop_options;
  loop_options.diagnose.comparison.space = g_space;
  if (verbose) {
    // Each line with the seconds since the case started (the diagnosis' own lines count from its start).
    const auto t0 = std::chrono::steady_clock::now();
    loop_options.progress = [t0](const std::string& line) {
      std::printf("    %6.1f  %s\n", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), line.c_str());
      std::fflush(stdout);
    };
  }
  const diagnose::LoopSummary summary = diagnose::RunLoop(nominal, hidden.measurement, loop_options);
  const diagnose::DiagnoseSummary& last = summary.last_diagnosis;
  OutsideOutcome o;
  o.added = !summary.effects_added.empty();
  o.claimed = o.added && summary.confirmed;
  // The bands the conclusion names as where what is missing acts (the first fit's worst, when the loop
  // added effects above the floor), else the last diagnosis' worst.
  const std::vector<compare::BandError>& named_bands = summary.missing_bands.empty() ? last.worst_bands : summary.missing_bands;
  auto holds_half = [&](const measurement::FrequencyBand& named) {
    for (const measurement::FrequencyBand& b : hidden.bands) {
      if (std::abs(b.centre_hz() / named.centre_hz() - 1) < 1e-9) return true;
    }
    return false;
  };
  for (size_t k = 0; k < named_bands.size() && k < 2; ++k) {
    o.band = o.band || (hidden.peak_hz >= named_bands[k].band.low_hz && hidden.peak_hz <= named_bands[k].band.high_hz);
    o.band_half = o.band_half || holds_half(named_bands[k].band);
  }
  for (size_t k = 0; k < last.worst_bands.size() && k < 2; ++k) o.final_band_half = o.final_band_half || holds_half(last.worst_bands[k].band);
  if (!last.worst_elements.empty() && last.worst_elements[0].worst_band_share > diagnose::kElementBandShareNamed) {
    const auto& b = last.worst_elements[0].worst_band;
    o.element_band = hidden.peak_hz >= b.low_hz && hidden.peak_hz <= b.high_hz;
  }
  auto changed = [&](const std::string& name) {
    return std::count(hidden.outputs.begin(), hidden.outputs.end(), name) + std::count(hidden.inputs.begin(), hidden.inputs.end(), name) > 0;
  };
  std::string where;
  for (size_t k = 0; k < last.worst_elements.size() && k < 3; ++k) {
    const std::string& name = last.worst_elements[k].name;  // "<output>/<input>"
    const size_t slash = name.find('/');
    o.channel = o.channel || changed(name.substr(0, slash)) || changed(name.substr(slash + 1));
    o.element = o.element || std::count(hidden.elements.begin(), hidden.elements.end(), name) > 0;
    where += (where.empty() ? "" : " ") + name;
  }
  if (!last.inconsistent_channels.empty()) o.channel = o.channel || changed(last.inconsistent_channels[0].channel);
  // The raw channels the loop's conclusion names (diagnose::ConclusionChannels).
  const double floor = summary.noise_floor.floor;
  o.at_floor = summary.history.back().error <= diagnose::kDoneTimesFloor * floor;
  for (const diagnose::ChannelError& c : diagnose::ConclusionChannels(summary)) {
    o.raw_channel = o.raw_channel || changed(c.name);
    char named[80];
    std::snprintf(named, sizeof named, " %s(%.1fx floor, %.1fx median)", c.name.c_str(), c.times_floor, c.times_median);
    where += named;
  }
  for (size_t k = 0; k < named_bands.size() && k < 2; ++k) {
    char band[64];
    std::snprintf(band, sizeof band, " %.0f-%.0f Hz", named_bands[k].band.low_hz, named_bands[k].band.high_hz);
    where += band;
  }
  const measurement::ChannelCheckResult checks = CheckTestBench(hidden.measurement);
  for (const measurement::NonRigidBand& n : checks.non_rigid) {
    const measurement::FrequencyBand band{n.low_hz, n.high_hz};
    o.checks_band = o.checks_band || (hidden.peak_hz >= n.low_hz && hidden.peak_hz <= n.high_hz) || holds_half(band);
    for (const std::string& c : n.channels) o.checks_channel = o.checks_channel || changed(c);
    char text[96];
    std::snprintf(text, sizeof text, " not-rigid %s %.0f-%.0f Hz", n.is_input ? "impacts" : "sensors", n.low_hz, n.high_hz);
    where += text;
    for (const std::string& c : n.channels) where += " " + c;
  }
  std::string truth;  // where the change is: its bands, its platform elements
  for (const measurement::FrequencyBand& b : hidden.bands) {
    char band[64];
    std::snprintf(band, sizeof band, "%s%.0f-%.0f", truth.empty() ? "" : ",", b.low_hz, b.high_hz);
    truth += band;
  }
  truth += " Hz";
  for (size_t k = 0; k < hidden.elements.size(); ++k) truth += (k ? "," : " ") + hidden.elements[k];
  std::string added;
  for (const auto& w : summary.effects_added) added += (added.empty() ? "" : " + ") + w.substr(0, w.find(':'));
  o.time_s = summary.time_s;
  std::printf("seed %7llu  %4.0f Hz %4d pts  %-16s peak %5.0f Hz on %s... (%s)  -> %-30s error %.2fx floor  where: %s  %s%s%s%s%s%s%s %.1f s\n",
              static_cast<unsigned long long>(seed), options.fmax_hz, options.num_frequencies, hidden.kind.c_str(), hidden.peak_hz,
              hidden.outputs.empty() ? "-" : hidden.outputs[0].c_str(), truth.c_str(), added.empty() ? "(nothing added)" : added.c_str(),
              summary.history.back().error / floor, where.c_str(), o.claimed ? "CLAIMED " : o.added ? "(not confirmed) " : "", o.band ? "band " : o.element_band ? "element-band " : "",
              o.band_half ? "band-half " : o.final_band_half ? "final-band-half " : "", o.element ? "element " : "", o.channel ? "channel " : "", o.raw_channel ? "raw-channel " : "",
              o.checks_band && o.checks_channel ? "checks-localised " : "", summary.time_s);
  if (verbose) {
    std::printf("    %s\n    %s\n%s    raw channels of the final model:", hidden.description.c_str(), summary.last_verdict.c_str(),
                summary.HistoryTable().c_str());
    for (const diagnose::ChannelError& c : summary.final_channels) {
      std::printf(" %s (%.1fx floor, %.1fx median)", c.name.c_str(), c.times_floor, c.times_median);
    }
    std::printf("\n");
  }
  std::fflush(stdout);
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  KeepFreedMemory();  // as the stagefit program does
  fit::SilenceSolverLog();
  int cases = 10, two_effects = 0, three_effects = 0, effect_free = 0, outside = 0, verbose = 0;
  uint64_t first_seed = 5000;
  std::vector<std::string> outside_kinds = {"plate-bending", "plate-breathing", "cable"};
  auto split = [](std::string list) {
    std::vector<std::string> items;
    while (!list.empty()) {
      const size_t comma = list.find(',');
      items.push_back(list.substr(0, comma));
      list = comma == std::string::npos ? "" : list.substr(comma + 1);
    }
    return items;
  };
  for (int i = 1; i < argc; i += 2) {
    const std::string option = argv[i];
    static const std::set<std::string> known = {"--cases",         "--two-effects", "--outside",    "--outside-kinds",
                                                "--three-effects", "--effect-free", "--first-seed", "--verbose",
                                                "--effects",       "--max-rounds",  "--space",      "--rounds-above",
                                                "--hiding",        "--draws",       "--relocate-above",
                                                "--noise-per-channel"};
    if (!known.count(option) || i + 1 >= argc) {
      std::fprintf(stderr, "eval_loop: %s '%s' (usage: see the head of tests/bench/eval_loop.cc)\n",
                   known.count(option) ? "no value after" : "unknown option", argv[i]);
      return 2;
    }
    const char* value = argv[i + 1];
    if (option == "--cases") cases = std::atoi(value);
    else if (option == "--two-effects") two_effects = std::atoi(value);
    else if (option == "--outside") outside = std::atoi(value);
    else if (option == "--outside-kinds") outside_kinds = split(value);
    else if (option == "--three-effects") three_effects = std::atoi(value);
    else if (option == "--effect-free") effect_free = std::atoi(value);
    else if (option == "--first-seed") first_seed = std::strtoull(value, nullptr, 10);
    else if (option == "--verbose") verbose = std::atoi(value);
    else if (option == "--effects") g_effects = split(value);
    else if (option == "--hiding") g_hiding = value;
    else if (option == "--draws") {
      if (std::strcmp(value, "first") != 0 && std::strcmp(value, "own") != 0) {
        std::fprintf(stderr, "eval_loop: --draws '%s': expected first or own\n", value);
        return 2;
      }
      g_draws_as_first = std::strcmp(value, "first") == 0;
    }
    else if (option == "--noise-per-channel") g_noise_per_channel = std::atoi(value) != 0;
    else if (option == "--max-rounds") g_max_rounds = std::atoi(value);
    else if (option == "--rounds-above") g_rounds_above = std::atof(value);
    else if (option == "--relocate-above") g_relocate_above = std::atof(value);
    else if (option == "--space") g_space = compare::ParseComparisonSpace(value, "--space");
  }
  if (outside > 0 && outside_kinds.empty()) {
    std::fprintf(stderr, "eval_loop: --outside-kinds is empty; expected plate-bending, plate-breathing or cable, comma-separated\n");
    return 2;
  }
  const model::ModelSpec nominal = model::DefaultModelSpec();
  struct Tally {
    // explained: at the floor, within 0.01 of the noise-free truth and no effect added that is not
    // hidden, whether or not every hidden one was named (an unnamed one then changes the data by less
    // than the noise lets the loop tell).
    int n = 0, named = 0, clean = 0, floor = 0, truth = 0, done = 0, explained = 0, named_explained = 0, raw_alarms = 0, non_rigid = 0;
    double time = 0, max_time = 0;
  };
  auto run = [&](int count, int num_effects, uint64_t seed0, Tally* t) {
    for (int c = 0; c < count; ++c) {
      const std::optional<Outcome> drawn = RunCase(nominal, seed0 + c, num_effects, verbose);
      if (!drawn) continue;
      const Outcome& o = *drawn;
      ++t->n;
      t->named += o.named_all;
      t->clean += !o.extra;
      t->floor += o.at_floor;
      t->truth += o.near_truth;
      t->done += o.named_all && !o.extra && o.at_floor;
      t->explained += !o.extra && o.at_floor && o.near_truth;
      t->named_explained += o.named_all && !o.extra && o.at_floor && o.near_truth;
      t->raw_alarms += o.raw_alarm;
      t->non_rigid += o.non_rigid;
      t->time += o.time_s;
      t->max_time = std::max(t->max_time, o.time_s);
    }
  };
  Tally one, two, three, none;
  run(cases, 1, first_seed, &one);
  run(two_effects, 2, first_seed + cases, &two);
  run(effect_free, 0, first_seed + cases + two_effects, &none);
  run(three_effects, 3, first_seed + cases + two_effects + effect_free, &three);
  int outside_clean = 0, outside_added = 0, outside_band = 0, outside_element_band = 0, outside_channel = 0, outside_raw_channel = 0, outside_floor_raw_channel = 0, outside_floor = 0;
  int outside_floor_checks = 0, outside_checks = 0;
  int outside_band_half = 0, outside_final_band_half = 0, outside_element = 0, outside_peak_and_raw = 0, outside_localised = 0;
  double outside_time = 0;
  for (int c = 0; c < outside; ++c) {
    const OutsideOutcome o = RunOutsideCase(nominal, first_seed + cases + two_effects + effect_free + three_effects + c,
                                            outside_kinds[c % outside_kinds.size()], verbose);
    outside_clean += !o.claimed;
    outside_added += o.added && !o.claimed;  // added, and not confirmed
    outside_floor += o.at_floor;
    outside_band += !o.at_floor && o.band;
    outside_element_band += !o.at_floor && o.element_band;
    outside_channel += !o.at_floor && o.channel;
    outside_raw_channel += !o.at_floor && o.raw_channel;
    outside_floor_raw_channel += o.at_floor && o.raw_channel;
    outside_band_half += !o.at_floor && o.band_half;
    outside_floor_checks += o.at_floor && o.checks_band && o.checks_channel;
    outside_checks += o.checks_band && o.checks_channel;
    outside_final_band_half += !o.at_floor && o.final_band_half;
    outside_element += !o.at_floor && o.element;
    outside_peak_and_raw += !o.at_floor && o.band && (o.channel || o.raw_channel);
    outside_localised += !o.at_floor && (o.band || o.band_half) && (o.element || o.channel || o.raw_channel);
    outside_time += o.time_s;
  }
  auto pct = [](int a, int n) { return n > 0 ? 100.0 * a / n : 0.0; };
  if (one.n) {
    std::printf("\nsingle effect (%d): named %d (%.0f %%), nothing else added %d, final within 1.2x the floor %d (%.0f %%), "
                "within 0.01 of the noise-free truth %d (%.0f %%), named and at the floor and within 0.01 of it %d; "
                "mean %.1f s, max %.1f s\n",
                one.n, one.named, pct(one.named, one.n), one.clean, one.floor, pct(one.floor, one.n), one.truth,
                pct(one.truth, one.n), one.named_explained, one.time / one.n,
                one.max_time);
  }
  if (two.n) {
    std::printf("two effects (%d): both named %d (%.0f %%), both named and at the floor with nothing else %d (%.0f %%), "
                "within 0.01 of the truth %d, explained (at the floor, within 0.01 of the truth, nothing wrong added) %d "
                "(%.0f %%); mean %.1f s, max %.1f s\n",
                two.n, two.named, pct(two.named, two.n), two.done, pct(two.done, two.n), two.truth, two.explained,
                pct(two.explained, two.n), two.time / two.n, two.max_time);
  }
  if (three.n) {
    std::printf("three effects (%d): all named %d (%.0f %%), all named and at the floor with nothing else %d (%.0f %%), "
                "within 0.01 of the truth %d, explained %d (%.0f %%); mean %.1f s, max %.1f s\n",
                three.n, three.named, pct(three.named, three.n), three.done, pct(three.done, three.n), three.truth,
                three.explained, pct(three.explained, three.n), three.time / three.n, three.max_time);
  }
  if (none.n) {
    std::printf("effect-free (%d): nothing added %d (%.0f %%), final within 1.2x the floor %d; mean %.1f s\n", none.n,
                none.clean, pct(none.clean, none.n), none.floor, none.time / none.n);
  }
  if (one.n + two.n + three.n + none.n) {
    std::printf("raw channels named as standing out at the floor on the catalogue and effect-free cases: %d of %d\n",
                one.raw_alarms + two.raw_alarms + three.raw_alarms + none.raw_alarms, one.n + two.n + three.n + none.n);
    std::printf("channels the checks find not rigid together: effect-free %d of %d, catalogue cases %d of %d\n", none.non_rigid, none.n,
                one.non_rigid + two.non_rigid + three.non_rigid, one.n + two.n + three.n);
  }
  if (outside) {
    std::printf("outside the catalogue (%d): no effect claimed %d (%.0f %%; added but not confirmed %d); ended at the floor %d "
                "(nothing to localise); of the %d above it, a band named holds the peak %d, worst element's own band named %d, worst channel "
                "named %d (by the raw channels that stand out %d); of those at the floor, a changed raw channel named %d; mean %.1f s\n",
                outside, outside_clean, pct(outside_clean, outside), outside_added, outside_floor, outside - outside_floor, outside_band,
                outside_element_band, outside_channel, outside_raw_channel, outside_floor_raw_channel, outside_time / outside);
    std::printf("  the channel checks' channels not rigid together, in a band holding the peak or half the change and on a changed "
                "channel: %d of the %d at the floor, %d of all %d\n",
                outside_floor_checks, outside_floor, outside_checks, outside);
    std::printf("  localised, of the %d above the floor: a band named is one of those holding half the change %d (of the last "
                "diagnosis' worst bands %d), an element named one of the platform's holding half of it %d; by the peak and a raw "
                "channel %d; by band (peak or half) and channel (element, channel or raw) %d\n",
                outside - outside_floor, outside_band_half, outside_final_band_half, outside_element, outside_peak_and_raw,
                outside_localised);
  }
  return 0;
}
