#include "stagefit/diagnose/diagnose.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "stagefit/common/error.h"
#include "stagefit/compare/residuals.h"
#include "stagefit/fit/least_squares.h"
#include "stagefit/fit/model_fit.h"
#include "stagefit/model/effects.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/model_spec.h"
#include "stagefit/model/parameters.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace stagefit::diagnose {
namespace {

DiagnoseOptions QuietOptions() {
  DiagnoseOptions options;
  options.progress = [](const std::string& line) { std::cout << line << std::endl; };
  return options;
}

// Case `seed` of eval_loop (`num_effects` hidden effects; its band's top and number of frequencies as
// eval_loop draws them), checked to hold `expected` ("effect@location") as its effect `index`.
void MakeEvalLoopCase(uint64_t seed, size_t num_effects, double fmax_hz, int num_frequencies, size_t index,
                      const std::string& expected, synthetic::HiddenEffectCase* c) {
  *c = synthetic::MakeHiddenEffectCase(model::DefaultModelSpec(), seed,
                                       synthetic::EvalLoopCaseOptions(static_cast<int>(num_effects), fmax_hz, num_frequencies));
  ASSERT_EQ(c->effects.size(), num_effects);
  ASSERT_EQ(c->effects[index].name + "@" + c->effects[index].location, expected);
}

// Prints `summary`'s report, and checks that it found an effect and names `expected`
// ("effect@location") first with an error below `max_error`.
void ExpectLeader(const DiagnoseSummary& summary, const std::string& expected, double max_error) {
  std::cout << summary.BriefReport() << "time " << summary.time_s << " s\n";
  ASSERT_TRUE(summary.effect_found);
  const Candidate& best = summary.candidates[0];
  EXPECT_EQ(best.effect.name + "@" + best.effect.location, expected);
  EXPECT_LT(best.error_after, max_error);
}

// `options` with the stages after the screening cut to refining its best `num_refined` (time): what
// the screening ranks decides what is found.
void CutToScreening(DiagnoseOptions* options, int num_refined) {
  options->num_refined = num_refined;
  options->num_second_starts = 0;
  options->num_polished = 0;
  options->refit_starts = 1;
  options->num_finished = 0;
}

// eval_loop's case `seed` (MakeEvalLoopCase, its first effect `expected`) diagnosed with `effects` from
// the loop's first fit (band continuation), the stages after the screening cut to its best two
// (CutToScreening); `truth_error` is the noise-free truth's error. The case hides `num_effects`.
struct FirstFitDiagnosis {
  synthetic::HiddenEffectCase c;
  DiagnoseSummary summary;
  double truth_error = 0;
};
void DiagnoseFromFirstFit(uint64_t seed, double fmax_hz, int num_frequencies, const std::string& expected,
                          const std::vector<std::string>& effects, FirstFitDiagnosis* run, size_t num_effects = 1) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  ASSERT_NO_FATAL_FAILURE(MakeEvalLoopCase(seed, num_effects, fmax_hz, num_frequencies, 0, expected, &run->c));
  DiagnoseOptions options = QuietOptions();
  const compare::Comparison comparison = compare::Comparison::Create(nominal, run->c.measurement, options.comparison);
  model::ModelSpec first_fit = nominal;
  fit::FitModelWithBandContinuation(first_fit, run->c.measurement, options.comparison, comparison,
                                    model::MatchParameters(first_fit, options.params), fit::FitOptions{});
  options.effects = effects;
  CutToScreening(&options, 2);
  run->summary = Diagnose(first_fit, run->c.measurement, options);
  run->truth_error = comparison.Error(run->c.truth);
}

// One drawn effect (seed: synthetic::MakeHiddenEffectCase with default options), checked to be the
// expected one, diagnosed with `effects` (empty: the whole catalogue); `floor` is the truth's error.
struct HiddenCaseRun {
  synthetic::HiddenEffectCase c;
  DiagnoseSummary summary;
  double floor = 0;
};
void DiagnoseHiddenCase(uint64_t seed, const std::string& effect, const std::string& location,
                        const std::vector<std::string>& effects, HiddenCaseRun* run) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  run->c = synthetic::MakeHiddenEffectCase(nominal, seed, {});
  ASSERT_EQ(run->c.effects.size(), 1u);
  ASSERT_EQ(run->c.effects[0].name, effect);
  ASSERT_EQ(run->c.effects[0].location, location);
  DiagnoseOptions options = QuietOptions();
  options.effects = effects;
  run->summary = Diagnose(nominal, run->c.measurement, options);
  std::cout << run->summary.BriefReport() << "time " << run->summary.time_s << " s\n";
  run->floor = compare::Comparison::Create(nominal, run->c.measurement).Error(run->c.truth);
}

// Effect-free data (stiffness scatter and noise only): the baseline fit reaches the noise floor and
// no candidate of the catalogue is claimed.
TEST(Diagnose, ClaimsNothingWithoutAnEffect) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectOptions options;
  options.num_effects = 0;
  auto c = synthetic::MakeHiddenEffectCase(nominal, 7, options);
  DiagnoseOptions quiet = QuietOptions();
  std::vector<std::string> lines;
  quiet.progress = [&](const std::string& line) {
    std::cout << line << std::endl;
    lines.push_back(line);
  };
  auto summary = Diagnose(nominal, c.measurement, quiet);
  std::cout << summary.BriefReport() << "time " << summary.time_s << " s\n";
  const double floor = compare::Comparison::Create(nominal, c.measurement).Error(c.truth);
  EXPECT_LT(summary.error_baseline, 1.05 * floor);
  EXPECT_FALSE(summary.effect_found);
  // The coherence's noise floor is the truth's error, and the verdict says the model is done.
  ASSERT_TRUE(summary.noise_floor.known);
  EXPECT_NEAR(summary.noise_floor.floor / floor, 1.0, 0.05);
  EXPECT_EQ(summary.verdict.rfind("Done:", 0), 0u) << summary.verdict;
  // The leaders are at the floor already: none gets a second start (kSecondStartSkipTimesFloor).
  EXPECT_EQ(std::count_if(lines.begin(), lines.end(),
                          [](const std::string& l) { return l.find("second start for the best 0 (3 at the noise floor go without)") != std::string::npos; }),
            1);
}

// DiagnoseOptions::stop_at_times_floor: effect-free data, the baseline fit cut to 2 iterations from the
// nominal model. Refitted from where a screening's fit with a candidate (4 iterations more) left the
// model's parameters, the model without an effect gets lower. With the threshold just below the
// baseline's error, the diagnosis stops there, claims nothing and scores every candidate on all
// frequencies; with it at half the floor, which no model reaches, the search runs on, as without it.
TEST(Diagnose, StopsWhenTheModelRefittedFromTheLeadersReachesTheThreshold) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectOptions hidden;
  hidden.num_effects = 0;
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 7, hidden);
  DiagnoseOptions options = QuietOptions();
  options.effects = {"payload", "structural-damping"};
  options.baseline_iterations = 2;
  CutToScreening(&options, 2);
  std::vector<std::string> lines;
  options.progress = [&](const std::string& line) {
    std::cout << line << std::endl;
    lines.push_back(line);
  };
  auto said = [&](const std::string& text) {
    return std::any_of(lines.begin(), lines.end(), [&](const std::string& l) { return l.find(text) != std::string::npos; });
  };
  const DiagnoseSummary searched = Diagnose(nominal, c.measurement, options);
  std::cout << searched.BriefReport() << "time " << searched.time_s << " s\n";
  ASSERT_TRUE(searched.noise_floor.known);
  const double floor = searched.noise_floor.floor;
  EXPECT_TRUE(searched.stopped_at_floor.empty());
  EXPECT_TRUE(said("refining the best"));

  lines.clear();
  options.stop_at_times_floor = 0.5;
  const DiagnoseSummary unreachable = Diagnose(nominal, c.measurement, options);
  EXPECT_TRUE(unreachable.stopped_at_floor.empty());
  EXPECT_TRUE(said("refining the best"));
  EXPECT_EQ(unreachable.error_baseline, searched.error_baseline);

  lines.clear();
  options.stop_at_times_floor = 0.999 * searched.error_baseline / floor;
  const DiagnoseSummary stopped = Diagnose(nominal, c.measurement, options);
  std::cout << stopped.BriefReport() << "time " << stopped.time_s << " s\n";
  EXPECT_EQ(stopped.stopped_at_floor, "screening");
  EXPECT_FALSE(said("refining the best"));
  EXPECT_LE(stopped.error_baseline, options.stop_at_times_floor * floor);
  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  EXPECT_DOUBLE_EQ(stopped.error_baseline, comparison.Error(stopped.baseline));
  EXPECT_FALSE(stopped.effect_found);
  ASSERT_FALSE(stopped.candidates.empty());
  for (const Candidate& candidate : stopped.candidates) {
    EXPECT_FALSE(candidate.helps) << candidate.with;
    EXPECT_NEAR(candidate.error_after, comparison.Error(ApplyCandidate(stopped, candidate)), 1e-12 * candidate.error_after)
        << candidate.with;
  }
  EXPECT_EQ(stopped.verdict.rfind("Done:", 0), 0u) << stopped.verdict;
}

// Physically absurd fits are named as such: a payload heavier than the whole stack, an offset at the
// bound of its search range; ordinary values are not.
TEST(ImplausibleBecause, HeavierThanTheStackOrAtABound) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  double stack_kg = 0;
  for (const auto& b : nominal.bodies) stack_kg += b.mass_kg;
  model::Effect payload{"payload", "hexapod", model::DefaultEffectParameters(nominal, "payload", "hexapod")};
  EXPECT_EQ(ImplausibleBecause(nominal, payload), "");
  payload.parameters["mass"] = 1.5 * stack_kg;
  EXPECT_NE(ImplausibleBecause(nominal, payload).find("more than the whole stack"), std::string::npos);
  payload.parameters["mass"] = 5.0;
  payload.parameters["z"] = 0.3;  // the bound of a payload's offset (diagnose::EffectParameterSpecs)
  EXPECT_NE(ImplausibleBecause(nominal, payload).find("z = 0.3 m is at the bound"), std::string::npos)
      << ImplausibleBecause(nominal, payload);
  model::Effect offset{"joint-offset", "ty", model::DefaultEffectParameters(nominal, "joint-offset", "ty")};
  offset.parameters["dz"] = 0.05;
  EXPECT_EQ(ImplausibleBecause(nominal, offset), "");
  offset.parameters["dx"] = -0.2995;
  EXPECT_NE(ImplausibleBecause(nominal, offset).find("dx"), std::string::npos);
  // A channel's turn at the bound of its range (model::kMaxCorrectionTurn), not within it.
  model::Effect turn{"sensor-geometry", "a1x", model::DefaultEffectParameters(nominal, "sensor-geometry", "a1x")};
  turn.parameters["rz"] = 0.35;  // 20 degrees
  EXPECT_EQ(ImplausibleBecause(nominal, turn), "");
  // A turn about the channel's own axis changes nothing it reads (model::RedundantEffectParameters): no
  // fit moves it, and at the bound it is not a reason.
  turn.parameters["rx"] = -0.999 * model::kMaxCorrectionTurn;
  EXPECT_EQ(ImplausibleBecause(nominal, turn), "");
  turn.parameters["ry"] = -0.999 * model::kMaxCorrectionTurn;
  EXPECT_NE(ImplausibleBecause(nominal, turn).find("ry = -0.5994 rad is at the bound"), std::string::npos)
      << ImplausibleBecause(nominal, turn);
}

// A loss factor below the material loss of steel leaves its joint undamped, which no joint is (seed 83188
// of eval_loop: rz's loss factor at 1.5e-8 taken for a payload and an offset of the hexapod); the loss
// factors of the catalogue's draws and of every other fit in the kept logs of eval_loop's sets 82853-83266
// (0.025 and above) are not absurd.
TEST(ImplausibleBecause, ALossFactorThatLeavesItsJointUndamped) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  model::Effect loss{"structural-damping", "rz", model::DefaultEffectParameters(nominal, "structural-damping", "rz")};
  EXPECT_EQ(ImplausibleBecause(nominal, loss), "");
  for (double eta : {0.043, 0.087, 0.24, 1.01 * model::kMinPlausibleLossFactor}) {
    loss.parameters["eta"] = eta;
    EXPECT_EQ(ImplausibleBecause(nominal, loss), "") << eta;
  }
  loss.parameters["eta"] = 1.4649087504965017e-08;  // 83188's
  const std::string why = ImplausibleBecause(nominal, loss);
  EXPECT_NE(why.find("its loss factor 1.5e-08 leaves joint rz undamped"), std::string::npos) << why;
  loss.parameters["eta"] = 0.99 * model::kMinPlausibleLossFactor;
  EXPECT_NE(ImplausibleBecause(nominal, loss).find("undamped"), std::string::npos);
}

// A body whose local mode lies below the compared band stands still in it: its mass is not determined
// and its joint acts as a spring to the ground. Such a fit is not claimed; a body that resonates in or
// above the band is.
TEST(ImplausibleBecause, ABodyThatStandsStillInTheBand) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  model::Effect body{"extra-body", "hexapod", model::DefaultEffectParameters(nominal, "extra-body", "hexapod")};
  auto set_local_mode = [&](double mass, double hz) {
    body.parameters["mass"] = mass;
    body.parameters["k"] = mass * std::pow(2 * M_PI * hz, 2);
  };
  set_local_mode(1078.0, 1.34);  // the cable of docs/diagnose.md, fitted as a body
  const std::string why = ImplausibleBecause(nominal, body, 5.0);
  EXPECT_NE(why.find("local mode at 1.34 Hz is below the compared band (from 5 Hz)"), std::string::npos) << why;
  EXPECT_EQ(ImplausibleBecause(nominal, body), "");  // no band given: not checked
  set_local_mode(1078.0, 5.5);
  EXPECT_EQ(ImplausibleBecause(nominal, body, 5.0), "");
  set_local_mode(3.0, 278.0);  // above a 150 Hz band: it still acts in the band as a mass on a spring
  EXPECT_EQ(ImplausibleBecause(nominal, body, 5.0), "");
}

// A channel's correction against what the channels themselves say (no model involved): on effect-free
// data of eval_loop's generator (seed 45014, 600 Hz, 786 points, 1-3 % noise) an impact or a sensor
// turned 20 degrees leaves many times the residual of its declared direction against the other
// channels' rigid motion, and is not claimed; a move without a turn, an effect of the model, or no
// raw data leave nothing to check. On 60040 (a3z turned 12 degrees beside two effects, 150 Hz) the
// correction by the true turn is what the channels say, and under it a3z is no longer off.
TEST(TurnAgainstTheChannels, ATurnTheOtherChannelsDoNotSee) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  auto make = [&](uint64_t seed, int num_effects, double fmax_hz, int num_frequencies) {
    synthetic::HiddenEffectOptions options = synthetic::EvalLoopCaseOptions(num_effects, fmax_hz, num_frequencies);
    options.visibility_against_no_effect = true;  // the cases as first drawn, as FindTurnedChannel's tests take them
    return synthetic::MakeHiddenEffectCase(nominal, seed, options);
  };
  const auto sound = make(45014, 0, 600, 786);
  ASSERT_TRUE(sound.effects.empty());
  const Eigen::Vector3d X = compare::Comparison::Create(nominal, sound.measurement).frame_origin_W();
  const double all = std::numeric_limits<double>::infinity();
  const auto directions = ChannelDirectionsUnder(nominal.geometry_corrections, sound.measurement, X, 0.0, all);
  ASSERT_EQ(directions.size(), sound.measurement.outputs.size() + sound.measurement.inputs.size());
  for (const char* text : {"sensor-geometry@h10:rz=20 deg", "sensor-geometry@a2z:ry=20 deg", "sensor-geometry@a1x:rz=-20 deg"}) {
    SCOPED_TRACE(text);
    const model::Effect turn = model::ParseEffect(text, nominal);
    const std::string why = TurnAgainstTheChannels(nominal, turn, directions);
    EXPECT_NE(why.find("the channels say it is not turned so"), std::string::npos) << why;
    EXPECT_EQ(ImplausibleBecause(nominal, turn, 5.0, directions), why);
    EXPECT_EQ(ImplausibleBecause(nominal, turn, 5.0), "");  // without the channels' directions: not checked
  }
  for (const char* text : {"sensor-geometry@h10:dx=0.01,dz=-0.02", "payload@hexapod:mass=5,z=0.1"}) {
    EXPECT_EQ(TurnAgainstTheChannels(nominal, model::ParseEffect(text, nominal), directions), "") << text;
  }
  measurement::FrfData projected = sound.measurement;
  for (auto& c : projected.outputs) c = measurement::ChannelGeometry{c.name};
  EXPECT_TRUE(ChannelDirectionsUnder(nominal.geometry_corrections, projected, X, 0.0, all).empty());

  const auto turned = make(60040, 3, 150, 323);
  ASSERT_EQ(turned.truth.geometry_corrections.size(), 1u);
  const model::GeometryCorrection& g = turned.truth.geometry_corrections[0];
  ASSERT_EQ(g.channel, "a3z");
  char text[256];
  std::snprintf(text, sizeof text, "sensor-geometry@a3z:rx=%.17g,ry=%.17g,rz=%.17g", g.rotation_rad(0), g.rotation_rad(1),
                g.rotation_rad(2));
  const model::Effect right = model::ParseEffect(text, nominal);
  const auto as_declared = ChannelDirectionsUnder(nominal.geometry_corrections, turned.measurement, X, 0.0, all);
  EXPECT_EQ(TurnAgainstTheChannels(nominal, right, as_declared), "");
  model::ModelSpec corrected = nominal;
  model::ApplyEffect(corrected, right);
  const auto under = ChannelDirectionsUnder(corrected.geometry_corrections, turned.measurement, X, 0.0, all);
  const auto a3z = std::find_if(under.begin(), under.end(), [](const auto& d) { return d.name == "a3z"; });
  ASSERT_NE(a3z, under.end());
  EXPECT_LT(a3z->angle_rad, 2 * M_PI / 180);
}

// A search on a thinned grid, and a screening on a coarser one still: every candidate is scored on
// all frequencies, and the results agree with a search on all of them.
TEST(Diagnose, SearchesOnAThinnedGridAndScoresOnAllFrequencies) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectOptions hidden;
  hidden.num_frequencies = 400;
  auto c = synthetic::MakeHiddenEffectCase(nominal, 1004, hidden);
  ASSERT_EQ(c.effects.size(), 1u);
  ASSERT_EQ(c.effects[0].name, "delay");
  DiagnoseOptions options = QuietOptions();
  options.effects = {"delay", "structural-damping"};
  options.max_search_frequencies = 150;
  options.max_screening_frequencies = 0;
  const auto thinned = Diagnose(nominal, c.measurement, options);
  std::cout << thinned.BriefReport() << "time " << thinned.time_s << " s\n";
  options.max_screening_frequencies = 60;
  const auto coarse = Diagnose(nominal, c.measurement, options);
  std::cout << coarse.BriefReport() << "time " << coarse.time_s << " s\n";
  options.max_search_frequencies = 0;
  options.max_screening_frequencies = 0;
  const auto full = Diagnose(nominal, c.measurement, options);
  std::cout << full.BriefReport() << "time " << full.time_s << " s\n";

  const auto comparison = compare::Comparison::Create(nominal, c.measurement);
  ASSERT_EQ(comparison.num_frequencies(), 400);
  const double floor = comparison.Error(c.truth);
  ASSERT_TRUE(full.effect_found);
  EXPECT_EQ(full.candidates[0].effect.name, "delay");
  for (const DiagnoseSummary* searched : {&thinned, &coarse}) {
    for (const Candidate& candidate : searched->candidates) {
      EXPECT_NEAR(candidate.error_after, comparison.Error(ApplyCandidate(*searched, candidate)), 1e-12 * candidate.error_after)
          << candidate.with;
    }
    ASSERT_TRUE(searched->effect_found);
    EXPECT_EQ(searched->candidates[0].effect.name, "delay");
    EXPECT_LT(searched->candidates[0].error_after, 1.5 * floor);
    EXPECT_NEAR(searched->candidates[0].error_after, full.candidates[0].error_after, 0.02 * full.candidates[0].error_after);
    EXPECT_NEAR(searched->candidates[0].effect.parameters.at("tau"), full.candidates[0].effect.parameters.at("tau"),
                0.01 * full.candidates[0].effect.parameters.at("tau"));
  }
}

// The effects already in the model are fitted again with every candidate from the refinement on
// (DiagnoseOptions::refit_effects), but held where the baseline fitted them in the screening
// (DiagnoseOptions::hold_effects_in_screening): a candidate only screened carries no fitted value of
// them, a refined one does; with the option off, every candidate does.
TEST(Diagnose, HoldsTheModelsEffectsInTheScreeningAndFitsThemFromTheRefinementOn) {
  model::ModelSpec with_payload = model::DefaultModelSpec();
  model::ApplyEffect(with_payload, model::ParseEffect("payload@hexapod:mass=2 kg,z=50 mm", with_payload));
  synthetic::HiddenEffectOptions hidden;
  hidden.num_effects = 0;
  hidden.num_frequencies = 150;
  const auto c = synthetic::MakeHiddenEffectCase(model::DefaultModelSpec(), 7, hidden);
  DiagnoseOptions options;
  options.effects = {"delay", "structural-damping"};
  options.num_refined = 1;
  options.num_second_starts = 0;
  options.num_polished = 0;
  options.refit_starts = 1;
  const std::string mass = "payload@hexapod.mass";
  for (const bool hold : {true, false}) {
    options.hold_effects_in_screening = hold;
    const DiagnoseSummary summary = Diagnose(with_payload, c.measurement, options);
    int screened = 0, refined = 0;
    for (const Candidate& candidate : summary.candidates) {
      const bool fitted = candidate.model_parameters.count(mass) > 0;
      if (candidate.refined) {
        ++refined;
        EXPECT_TRUE(fitted) << candidate.with;
      } else {
        ++screened;
        EXPECT_EQ(fitted, !hold) << candidate.with << (hold ? " (held)" : " (free)");
      }
    }
    EXPECT_EQ(refined, 1);
    EXPECT_GT(screened, 0);
  }
}

// An extra body whose mass the baseline's stiffnesses have absorbed (softened hexapod joint): added to
// the baseline it overshoots and its fit sheds the mass; started from the model as given, 0.1 m above
// the host, it is found at its body with its mass and height, and the error falls by more than a
// factor 4. Not yet to the floor: the body's rotational stiffness kr (its rocking mode at 351 Hz) was
// left 12x too stiff here (error 0.138, floor 0.041; docs/diagnose.md); since the leaders' rocking start
// (kr at the centre of the leader's worst band) kr is within 1 % of its value and the error 0.071.
TEST(Diagnose, FindsAnExtraBodyTheBaselineStiffnessesHid) {
  HiddenCaseRun run;
  ASSERT_NO_FATAL_FAILURE(DiagnoseHiddenCase(1009, "extra-body", "hexapod", {"extra-body"}, &run));
  const auto& body = run.c.truth.bodies[model::FindBody(run.c.truth, "hidden_body")];
  const auto& host = run.c.truth.bodies[model::FindBody(run.c.truth, "hexapod")];
  ASSERT_TRUE(run.summary.effect_found);
  const Candidate& best = run.summary.candidates[0];
  EXPECT_EQ(best.effect.location, "hexapod");
  EXPECT_LT(best.error_after, 0.25 * run.summary.error_baseline);
  EXPECT_GT(run.summary.error_baseline, 10 * run.floor);
  EXPECT_NEAR(best.effect.parameters.at("mass"), body.mass_kg, 0.1 * body.mass_kg);
  EXPECT_NEAR(best.effect.parameters.at("z"), body.com_W.z() - host.com_W.z(), 0.01);
}

// A band scan starts from its lowest error, unless that is at an end of the band (the mode has left it):
// then from the deepest dip inside, by prominence, not the lowest local minimum. The first vector holds
// points of 82366's scan of a 1.5 kg body on the hexapod (times the floor, from 5 Hz up, some points
// left out; BandScanPick's comment): lowest at 5 Hz, a shallow dip near 30 Hz, the deep one at 93 Hz.
TEST(BandScanPick, TakesTheDeepestDipInsideTheBandWhenTheLowestIsAtItsEnd) {
  const std::vector<double> scan = {7.196, 7.197, 7.206, 7.395, 7.478, 7.297, 7.280, 7.383, 7.854,
                                    10.436, 11.629, 9.122, 8.768, 12.407, 17.537, 18.455, 21.124, 28.595};
  EXPECT_EQ(BandScanPick(scan), std::optional<size_t>(12));  // 8.768, not 7.280 (prominence 0.20 against 2.86)
  EXPECT_EQ(BandScanPick({5.0, 3.0, 4.0, 3.5, 6.0}), std::optional<size_t>(1));  // the lowest, inside: as before
  EXPECT_EQ(BandScanPick({9.0, 5.0, 8.0, 4.0}), std::optional<size_t>(1));       // the lowest at the top end: the dip
  EXPECT_EQ(BandScanPick({1.0, 2.0, 3.0}), std::optional<size_t>(0));             // no dip: the lowest
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(BandScanPick({inf, 6.0, inf, 2.0}), std::optional<size_t>(3));        // unbuildable points are no dip
  EXPECT_EQ(BandScanPick({inf, inf}), std::nullopt);
  EXPECT_EQ(BandScanPick({}), std::nullopt);
}

// A servo's profile (ServoProfileStarts) gives its lowest local minima, the lowest first, when that one
// lies kServoScanMinDrop below the baseline. The profile is 83129's of ty.Dy (errors over the baseline's,
// k from 1/16 to 4 times the catalogue's): the lowest minimum at 4e8 (index 5), the next at 1e8 (3).
TEST(ServoProfileStarts, TakesTheLowestMinimaWhenTheLowestIsBelowTheBaseline) {
  const std::vector<double> profile = {2.149, 1.773, 1.415, 0.971, 0.978, 0.943, 0.967};
  EXPECT_EQ(ServoProfileStarts(profile, 1.0, 2), (std::vector<size_t>{5, 3}));
  EXPECT_EQ(ServoProfileStarts(profile, 1.0, 1), (std::vector<size_t>{5}));
  EXPECT_EQ(ServoProfileStarts(profile, 0.96, 2), (std::vector<size_t>{}));  // 0.943 is not 3 % below 0.96
  EXPECT_EQ(ServoProfileStarts({3.0, 2.0, 1.0}, 2.0, 2), (std::vector<size_t>{2}));  // a minimum at the grid's end
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(ServoProfileStarts({inf, 0.9, inf, 0.8}, 1.0, 2), (std::vector<size_t>{3, 1}));  // failed fits are no minima
  EXPECT_EQ(ServoProfileStarts({inf, inf}, 1.0, 2), (std::vector<size_t>{}));
  EXPECT_EQ(ServoProfileStarts({}, 1.0, 2), (std::vector<size_t>{}));
}

// An extra body whose band scan is lowest at the band's end is started at the scan's dip (BandScanPick).
// Seed 82366 of eval_loop (a 2.9 kg body on the hexapod with its local mode at 91 Hz, and a weak servo
// of ty.Dy; 600 Hz band, 444 points): from the first fit (7.15x the floor) the loop's first round added
// a loss factor of ry (5.05x), the body's starts all above the baseline after the screening, and it
// ended at 4.4x. Started at the dip, the body leads.
TEST(Diagnose, StartsABodyAtTheScansDipWhenItsLowestIsAtTheBandsEnd) {
  FirstFitDiagnosis run;
  ASSERT_NO_FATAL_FAILURE(
      DiagnoseFromFirstFit(82366, 600, 444, "extra-body@hexapod", {"extra-body", "structural-damping"}, &run, 2));
  ExpectLeader(run.summary, "extra-body@hexapod", 0.5 * run.summary.error_baseline);
  EXPECT_NEAR(run.summary.candidates[0].effect.parameters.at("mass"), 2.9, 0.4);
}

// The rocking scan of an extra-body candidate (ScanRockingHz) finds the rocking frequency of a body the
// independent generator hid (seed 1009: its rocking stiffness 1.5x its translation's, per inertia),
// from a candidate whose rocking is 40 % below it and whose other parameters and the model's are the
// truth's; a candidate already there gets no other start, and another effect is not scanned.
TEST(ScanRockingHz, FindsTheRockingFrequencyOfAHiddenBody) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const synthetic::HiddenEffectCase c = synthetic::MakeHiddenEffectCase(nominal, 1009, {});
  ASSERT_EQ(c.effects.size(), 1u);
  ASSERT_EQ(c.effects[0].name, "extra-body");
  const auto& body = c.truth.bodies[model::FindBody(c.truth, "hidden_body")];
  const auto& host = c.truth.bodies[model::FindBody(c.truth, c.effects[0].location)];
  const auto& joint = c.truth.joints[model::FindJoint(c.truth, "hidden_body")];
  const double inertia = body.mass_kg * std::pow(model::kExtraBodyRadiusOfGyration, 2);
  ASSERT_NEAR(body.inertia_com_W(0, 0), inertia, 1e-12 * inertia);  // the catalogue's body, as the generator's
  const double rocking_hz = std::sqrt(joint.stiffness[3] / inertia) / (2 * M_PI);

  DiagnoseSummary summary;
  summary.baseline = nominal;
  Candidate candidate;
  for (const auto& p : model::ListParameters(nominal)) candidate.model_parameters[p.name] = model::GetParameter(c.truth, p);
  candidate.effect = {"extra-body", c.effects[0].location,
                      {{"mass", body.mass_kg},
                       {"k", joint.stiffness[0]},
                       {"kr", inertia * std::pow(2 * M_PI * 0.6 * rocking_hz, 2)},
                       {"z", body.com_W.z() - host.com_W.z()}}};
  const compare::Comparison comparison = compare::Comparison::Create(nominal, c.measurement);
  const std::optional<double> hz = ScanRockingHz(comparison, summary, candidate);
  ASSERT_TRUE(hz.has_value());
  EXPECT_NEAR(*hz / rocking_hz, 1.0, 2 * kModeScanStep) << *hz << " Hz for " << rocking_hz << " Hz";

  candidate.effect.parameters["kr"] = inertia * std::pow(2 * M_PI * *hz, 2);
  EXPECT_FALSE(ScanRockingHz(comparison, summary, candidate).has_value());
  candidate.effect = {"payload", c.effects[0].location, {{"mass", body.mass_kg}, {"x", 0.0}, {"y", 0.0}, {"z", 0.05}}};
  EXPECT_FALSE(ScanRockingHz(comparison, summary, candidate).has_value());
}

// A servo stiffness that puts the translation stage's mode in the 150 Hz band (the independent
// generator's seed 29009, drawn as eval_loop draws it: ty.Dy a spring of 3.21e8 N/m, 447 frequencies).
// The scan of its k on a model without it finds it: on the generator's truth with ty.Dy rigid again,
// within one grid step (2 %); on the model as given (stiffnesses scattered 30 %), within 5 %. The fit
// started there reaches the noise floor; started from the catalogue's default k it does not.
synthetic::HiddenEffectCase ServoCase29009() {
  return synthetic::MakeHiddenEffectCase(model::DefaultModelSpec(), 29009, synthetic::EvalLoopCaseOptions(1, 150, 447));
}

TEST(ScanServoStiffness, FindsTheStiffnessOfAHiddenServo) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const synthetic::HiddenEffectCase c = ServoCase29009();
  ASSERT_EQ(c.effects.size(), 1u);
  ASSERT_EQ(c.effects[0].name, "servo-stiffness");
  ASSERT_EQ(c.effects[0].location, "ty.Dy");
  const int ty = model::FindJoint(c.truth, "ty");
  ASSERT_FALSE(c.truth.joints[ty].imposed[1]);
  const double truth_k = c.truth.joints[ty].stiffness[1];
  model::ModelSpec rigid = c.truth;
  rigid.joints[ty].imposed[1] = true;
  rigid.joints[ty].stiffness[1] = rigid.joints[ty].damping[1] = 0.0;
  const compare::Comparison comparison = compare::Comparison::Create(nominal, c.measurement);
  const model::Effect servo = model::ParseEffect("servo-stiffness@ty.Dy", nominal);
  ASSERT_GT(std::abs(std::log(servo.parameters.at("k") / truth_k)), std::log(1.3));  // the default is not near

  const std::optional<double> on_truth = ScanServoStiffness(comparison, rigid, servo);
  ASSERT_TRUE(on_truth.has_value());
  EXPECT_NEAR(*on_truth / truth_k, 1.0, 2 * kModeScanStep) << *on_truth << " for " << truth_k;
  const std::optional<double> on_nominal = ScanServoStiffness(comparison, nominal, servo);
  ASSERT_TRUE(on_nominal.has_value());
  EXPECT_NEAR(*on_nominal / truth_k, 1.0, 0.05) << *on_nominal << " for " << truth_k;
  EXPECT_FALSE(ScanServoStiffness(comparison, nominal, model::ParseEffect("payload@hexapod", nominal)).has_value());

  const double floor = comparison.Error(c.truth);
  model::Effect scanned = servo;
  scanned.parameters["k"] = *on_nominal;
  const EffectFit from_scan = FitEffect(nominal, comparison, scanned, {"*.k.*"});
  EXPECT_LT(from_scan.summary.final_error, 1.02 * floor);
  EXPECT_NEAR(from_scan.effect.parameters.at("k") / truth_k, 1.0, 0.05);
  const EffectFit from_default = FitEffect(nominal, comparison, servo, {"*.k.*"});
  EXPECT_GT(from_default.summary.final_error, 2 * floor);
}

// Seed 33013 of eval_loop (two effects, 150 Hz, 737 frequencies): a coupling of 2.5e6 N/rad between
// the hexapod's Dx and Ry (correlation 0.76) and a3z turned by -23 degrees, with a3z's correction as
// the loop's first round fitted it.
synthetic::HiddenEffectCase CouplingCase33013(model::ModelSpec* with_a3z) {
  *with_a3z = model::DefaultModelSpec();
  model::ApplyEffect(*with_a3z, model::ParseEffect("sensor-geometry@a3z:dx=0.0143,dy=0.00165,ry=-0.3378", *with_a3z));
  return synthetic::MakeHiddenEffectCase(model::DefaultModelSpec(), 33013, synthetic::EvalLoopCaseOptions(2, 150, 737));
}

// On the model as given with a3z corrected, the scan of every coupling of the stack puts the hexapod's
// Dx-Ry first, near the drawn coupling, far below the next location's; the fit from there (the
// stiffnesses with it, 30 iterations) ends below half the fit's from no coupling (0.268 against 0.579).
TEST(ScanCouplingStiffness, FindsAStrongCouplingBesideATurnedChannel) {
  model::ModelSpec with_a3z;
  const synthetic::HiddenEffectCase c = CouplingCase33013(&with_a3z);
  ASSERT_EQ(c.effects.size(), 2u);
  ASSERT_EQ(c.effects[0].name + "@" + c.effects[0].location, "coupled-stiffness@hexapod.Dx-Ry");
  const compare::Comparison comparison = compare::Comparison::Create(with_a3z, c.measurement);
  std::vector<std::pair<double, std::string>> minima;
  std::optional<ScanMinimum> dx_ry;
  for (const auto& location : model::EffectLocations(with_a3z, "coupled-stiffness")) {
    const model::Effect coupling = model::ParseEffect("coupled-stiffness@" + location, with_a3z);
    const auto scan = ScanCouplingStiffness(comparison, with_a3z, coupling);
    ASSERT_TRUE(scan.has_value()) << location;
    minima.push_back({scan->error, location});
    if (location == "hexapod.Dx-Ry") dx_ry = scan;
  }
  std::sort(minima.begin(), minima.end());
  EXPECT_EQ(minima[0].second, "hexapod.Dx-Ry");
  EXPECT_LT(minima[0].first, 0.5 * minima[1].first);
  const int hexapod = model::FindJoint(c.truth, "hexapod");
  const double truth_k = c.truth.joints[hexapod].couplings.at(0).stiffness;
  ASSERT_TRUE(dx_ry.has_value());
  // A start, on the model as given (its stiffnesses 15 % off the truth's): 2.94e6 for 2.50e6.
  EXPECT_NEAR(dx_ry->at / truth_k, 1.0, 0.25) << dx_ry->at << " for " << truth_k;
  EXPECT_FALSE(ScanCouplingStiffness(comparison, with_a3z, model::ParseEffect("payload@hexapod", with_a3z)).has_value());

  model::Effect scanned = model::ParseEffect("coupled-stiffness@hexapod.Dx-Ry", with_a3z);
  const EffectFit from_default = FitEffect(with_a3z, comparison, scanned, {"*.k.*"});
  scanned.parameters["k"] = dx_ry->at;
  const EffectFit from_scan = FitEffect(with_a3z, comparison, scanned, {"*.k.*"});
  EXPECT_LT(from_scan.summary.final_error, from_default.summary.final_error / 2)
      << from_scan.summary.final_error << " against " << from_default.summary.final_error;
}

// The model as given with the effects already in it, as fitted, need not be a model: a coupling fitted
// beside the fitted stiffnesses can exceed sqrt(k_a k_b) of the stiffnesses given (seed 35023 of
// eval_loop, a cable, round 2: the loop stopped with the joint indefinite). The scans on it then have
// no minimum, and the diagnosis goes on.
TEST(Diagnose, GoesOnWhenTheModelAsGivenWithItsEffectsIsNoModel) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 7, synthetic::EvalLoopCaseOptions(0, 150, 300));
  model::ModelSpec spec = nominal;
  const model::Effect coupling = model::ParseEffect("coupled-stiffness@hexapod.Dx-Ry", spec);
  const double limit = model::EffectRange(spec, coupling, "k").upper;
  model::ApplyEffect(spec, model::ParseEffect("coupled-stiffness@hexapod.Dx-Ry:k=" + std::to_string(0.9 * limit), spec));
  DiagnoseOptions options = QuietOptions();
  options.effects = {"coupled-stiffness", "servo-stiffness"};
  const model::ParameterInfo kx = model::FindParameter(spec, "hexapod.k.Dx");
  options.as_given["hexapod.k.Dx"] = 0.5 * model::GetParameter(spec, kx);
  model::ModelSpec as_given = spec;
  model::SetParameter(as_given, kx, options.as_given["hexapod.k.Dx"]);
  ASSERT_THROW(compare::Comparison::Create(nominal, c.measurement).Error(as_given), InputError);
  DiagnoseSummary summary;
  ASSERT_NO_THROW(summary = Diagnose(spec, c.measurement, options));
  EXPECT_FALSE(summary.candidates.empty());
}

// The whole diagnosis of that case names the servo first, at the floor. Before the scan the servo's
// screening fit from the default k ended at 0.213 (baseline 0.058, floor 0.039), it was never refined,
// and a joint offset of ry at its bound won at 1.04x.
TEST(Diagnose, FindsAServoStiffnessFromItsScan) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const synthetic::HiddenEffectCase c = ServoCase29009();
  const DiagnoseSummary summary = Diagnose(nominal, c.measurement, QuietOptions());
  const double floor = compare::Comparison::Create(nominal, c.measurement).Error(c.truth);
  ExpectLeader(summary, "servo-stiffness@ty.Dy", 1.02 * floor);
}

// ty.Dy a spring of 4.0e8 N/m, 150 Hz band (seed 35008 of eval_loop). The scan on the model as given
// has no dip there (its minimum at 100 times the default, no lower than the model's error), so the
// servo is refined only when its screening ranks it: from the default 2e8 N/m the four short iterations
// throw k away (0.26 against a baseline of 0.055), from ten times the default they reach 0.046. With
// four refined places and the joint offsets that took its place on three such cases (ry, at 1.07-1.10x
// the floor) beside it, the servo must be refined and win at the floor; without the stiff start it
// stays at 0.26 and the offset of ry at its bound ranks first.
TEST(Diagnose, ScreensAServoFromNearlyRigidToo) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectCase c;
  ASSERT_NO_FATAL_FAILURE(MakeEvalLoopCase(35008, 1, 150, 932, 0, "servo-stiffness@ty.Dy", &c));
  DiagnoseOptions options = QuietOptions();
  options.effects = {"servo-stiffness", "joint-offset"};
  options.num_refined = 4;
  const DiagnoseSummary summary = Diagnose(nominal, c.measurement, options);
  const double floor = compare::Comparison::Create(nominal, c.measurement).Error(c.truth);
  ExpectLeader(summary, "servo-stiffness@ty.Dy", 1.02 * floor);
}

// ty.Dy a spring of 6.4e8 N/m, 150 Hz band (seed 37001 of eval_loop, visibility 3.8 noise standard
// deviations), diagnosed from the loop's first fit (1.34x the floor). From ten times the default k the
// screening's long first steps threw the damping ratio to its bound and ended above the baseline
// (0.048 against 0.045): the servo was never refined, and a joint offset of ry at its bound or a 50 kg
// body on rz was taken at 1.08-1.09x. It is also screened from there with short first steps, which
// keep it near its value; refined first, it reaches the floor.
TEST(Diagnose, ScreensAServoWithShortStepsToo) {
  FirstFitDiagnosis run;
  ASSERT_NO_FATAL_FAILURE(
      DiagnoseFromFirstFit(37001, 150, 1001, "servo-stiffness@ty.Dy", {"servo-stiffness", "joint-offset", "payload"}, &run));
  ASSERT_NO_FATAL_FAILURE(ExpectLeader(run.summary, "servo-stiffness@ty.Dy", 1.05 * run.truth_error));
  const double truth_k = run.c.truth.joints[model::FindJoint(run.c.truth, "ty")].stiffness[1];
  EXPECT_LT(std::abs(std::log(run.summary.candidates[0].effect.parameters.at("k") / truth_k)), std::log(1.2));
}

// A 2.3 kg body at 270 Hz on the hexapod beside an 8.4 kg payload (seed 37011 of eval_loop, the
// independent generator), diagnosed from a state like the one the loop's first round leaves: the
// payload added and fitted with the stiffnesses from the model as given (0.32, 10x the floor; the
// worst band 223-281 Hz), the model as given for the second starts. The extra body's start from that
// band's centre is screened with short first steps and keeps its mass and mode; the refinement from it
// reaches the floor (0.0335). With long steps there, as for the five fixed starts, this test's body
// ended at 1.8x (0.0579); in the loop's own state the long steps threw the mass to 0.46 kg in four
// iterations (0.345, above the baseline), a 2.5 t body on a 7 Hz spring was refined in its place, and
// a 420 kg body on ry ranked first at 9.5x the floor.
TEST(Diagnose, ScreensAnExtraBodyFromItsWorstBandWithShortSteps) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectCase c;
  ASSERT_NO_FATAL_FAILURE(MakeEvalLoopCase(37011, 2, 600, 1026, 1, "extra-body@hexapod", &c));
  DiagnoseOptions options = QuietOptions();
  const compare::Comparison comparison = compare::Comparison::Create(nominal, c.measurement, options.comparison);
  EffectFitOptions refit;  // the loop's refit from the model as given, without its basin probes (time)
  refit.max_iterations = fit::FitOptions{}.max_iterations;
  refit.initial_trust_region_radius = 1.0;
  const EffectsFit round1 = FitEffects(
      nominal, comparison, {model::ParseEffect("payload@hexapod:mass=9.62,x=-0.0103,y=-0.0162,z=0.110", nominal)},
      options.params, refit);
  for (const auto& p : model::ListParameters(nominal)) options.as_given[p.name] = model::GetParameter(nominal, p);
  options.effects = {"extra-body"};
  CutToScreening(&options, 1);
  const DiagnoseSummary summary = Diagnose(round1.spec, c.measurement, options);
  ASSERT_NO_FATAL_FAILURE(ExpectLeader(summary, "extra-body@hexapod", 1.2 * comparison.Error(c.truth)));
  const Candidate& best = summary.candidates[0];
  const auto& body = c.truth.bodies[model::FindBody(c.truth, "hidden_body")];
  EXPECT_NEAR(best.effect.parameters.at("mass"), body.mass_kg, 0.1 * body.mass_kg);
}

// A 4.3 kg payload 54 mm above the hexapod's centre of mass (seed 41000 of eval_loop, the independent
// generator), diagnosed from the loop's first fit (band continuation, 9.0x the floor) with payloads and
// couplings. A payload is also screened with short first steps: with long ones its four iterations
// ended above the baseline (0.283 against 0.270 from the baseline, 0.520 from the model as given), it
// was never refined, and in the loop nothing was found (9.0x); with short ones it screens at 0.10-0.12,
// is refined first and reaches the floor with its mass and height.
TEST(Diagnose, ScreensAPayloadWithShortStepsToo) {
  FirstFitDiagnosis run;
  ASSERT_NO_FATAL_FAILURE(DiagnoseFromFirstFit(41000, 600, 924, "payload@hexapod", {"payload", "coupled-stiffness"}, &run));
  ASSERT_NO_FATAL_FAILURE(ExpectLeader(run.summary, "payload@hexapod", 1.2 * run.truth_error));
  const Candidate& best = run.summary.candidates[0];
  const auto& payload = run.c.truth.bodies[model::FindBody(run.c.truth, "hidden_payload")];
  const auto& host = run.c.truth.bodies[model::FindBody(run.c.truth, "hexapod")];
  EXPECT_NEAR(best.effect.parameters.at("mass"), payload.mass_kg, 0.05 * payload.mass_kg);
  EXPECT_NEAR(best.effect.parameters.at("z"), payload.com_W.z() - host.com_W.z(), 0.005);
}

// A vertical accelerometer turned by 17 degrees (seed 1023, visibility 18.5 noise standard deviations),
// compared in compliance space. Its direction as the other channels see it is listed first among the
// turned channels, and the correction held there ranks first, at the noise floor. Before the
// element rule of residuals.h and the estimated turns, a joint offset in rz won (0.49 for a floor of
// 0.036): the right correction left the model's exact zeros against noise, and a fitted correction
// stopped in a local minimum. The effects are the channels' and the joint offsets, the one that won
// then (the whole catalogue: eval_diagnose).
TEST(Diagnose, FindsATurnedSensorInComplianceSpace) {
  HiddenCaseRun run;
  ASSERT_NO_FATAL_FAILURE(DiagnoseHiddenCase(1023, "sensor-geometry", "a2z", {"sensor-geometry", "joint-offset"}, &run));
  const DiagnoseSummary& summary = run.summary;
  ASSERT_FALSE(summary.turned_channels.empty());
  EXPECT_EQ(summary.turned_channels[0].channel, "a2z");
  EXPECT_NEAR(summary.turned_channels[0].angle_deg, 17.0, 1.0);
  ASSERT_TRUE(summary.effect_found);
  const Candidate& best = summary.candidates[0];
  EXPECT_EQ(best.effect.name, "sensor-geometry");
  EXPECT_EQ(best.effect.location, "a2z");
  EXPECT_LT(best.error_after, 1.1 * run.floor);
}

// The stiffness centre of the hexapod 84 mm below where the model puts it (seed 1017). It makes both
// couplings Dx-Ry and Dy-Rx, and the baseline's rotational stiffnesses absorb the k dz^2 it adds:
// from the baseline the offset's fit hardly moved (0.66 for a floor of 0.038) and a coupling won
// (0.45). Started from the model as given, 0.1 m below, the offset is found to a few mm, at the floor.
TEST(Diagnose, FindsAStiffnessCentreTheCouplingsMimic) {
  HiddenCaseRun run;
  ASSERT_NO_FATAL_FAILURE(DiagnoseHiddenCase(1017, "joint-offset", "hexapod", {"joint-offset", "coupled-stiffness"}, &run));
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const double dz = run.c.truth.joints[model::FindJoint(run.c.truth, "hexapod")].origin_W.z() -
                    nominal.joints[model::FindJoint(nominal, "hexapod")].origin_W.z();
  ASSERT_TRUE(run.summary.effect_found);
  const Candidate& best = run.summary.candidates[0];
  EXPECT_EQ(best.effect.name, "joint-offset");
  EXPECT_EQ(best.effect.location, "hexapod");
  EXPECT_NEAR(best.effect.parameters.at("dz"), dz, 0.005);
  EXPECT_LT(best.error_after, 1.1 * run.floor);
}

// A 7.2 kg payload 141 mm above the hexapod's centre of mass (seed 1028), in data made by the
// independent brute-force path, payloads and extra bodies searched (the whole catalogue: eval_diagnose,
// and this test until it was cut for time; the result was the same): it is found at its body, with its
// mass and height, at the floor. An extra body rigid in translation came close (1.16x the floor) while
// the payload's own fits, from 1.5 kg at the centre of mass, stopped at 7x; the payload fitted from the
// extra body's mass and height reaches the floor.
TEST(Diagnose, FindsAHiddenPayloadAnExtraBodyApproximates) {
  HiddenCaseRun run;
  ASSERT_NO_FATAL_FAILURE(DiagnoseHiddenCase(1028, "payload", "hexapod", {"payload", "extra-body"}, &run));
  const auto& payload = run.c.truth.bodies[model::FindBody(run.c.truth, "hidden_payload")];
  const auto& host = run.c.truth.bodies[model::FindBody(run.c.truth, "hexapod")];
  ASSERT_TRUE(run.summary.effect_found);
  const Candidate& best = run.summary.candidates[0];
  EXPECT_EQ(best.effect.name, "payload");
  EXPECT_EQ(best.effect.location, "hexapod");
  EXPECT_NEAR(best.effect.parameters.at("mass"), payload.mass_kg, 0.05 * payload.mass_kg);
  EXPECT_NEAR(best.effect.parameters.at("z"), payload.com_W.z() - host.com_W.z(), 0.01);
  EXPECT_LT(best.error_after, 1.1 * run.floor);
}

// The rigid-limit rule on hand-made rankings: a payload within 1 % of an extra body at the same body is
// named first; one further off, at another body, or one that does not help is not; an effect without a
// rigid limit keeps its place.
TEST(NameRigidLimitFirst, NamesThePayloadAnExtraBodyCannotBeToldFrom) {
  auto candidate = [](const std::string& name, const std::string& location, double error, bool helps = true) {
    Candidate c;
    c.effect.name = name;
    c.effect.location = location;
    c.effect.parameters = name == "extra-body" ? std::map<std::string, double>{{"mass", 7.3}, {"k", 1e9}, {"kr", 500}, {"z", 0.075}}
                                               : std::map<std::string, double>{{"mass", 7.4}, {"x", 0}, {"y", 0}, {"z", 0.075}};
    c.error_after = error;
    c.helps = helps;
    return c;
  };
  auto names = [](const std::vector<Candidate>& list) {
    std::string out;
    for (const auto& c : list) out += c.effect.name + "@" + c.effect.location + " ";
    return out;
  };
  std::vector<Candidate> list = {candidate("extra-body", "hexapod", 0.03740), candidate("coupled-stiffness", "rz.Dx-Ry", 0.1),
                                 candidate("payload", "hexapod", 0.03744)};
  NameRigidLimitFirst(&list);
  EXPECT_EQ(names(list), "payload@hexapod extra-body@hexapod coupled-stiffness@rz.Dx-Ry ");
  list = {candidate("extra-body", "hexapod", 0.03740), candidate("payload", "hexapod", 0.0380)};  // 1.6 % above
  NameRigidLimitFirst(&list);
  EXPECT_EQ(names(list), "extra-body@hexapod payload@hexapod ");
  list = {candidate("extra-body", "hexapod", 0.03740), candidate("payload", "rz", 0.03741)};
  NameRigidLimitFirst(&list);
  EXPECT_EQ(names(list), "extra-body@hexapod payload@rz ");
  list = {candidate("extra-body", "hexapod", 0.03740), candidate("payload", "hexapod", 0.03741, false)};
  NameRigidLimitFirst(&list);
  EXPECT_EQ(names(list), "extra-body@hexapod payload@hexapod ");
  list = {candidate("coupled-stiffness", "hexapod.Dy-Rx", 0.03740), candidate("payload", "hexapod", 0.03740)};
  NameRigidLimitFirst(&list);
  EXPECT_EQ(names(list), "coupled-stiffness@hexapod.Dy-Rx payload@hexapod ");
}

}  // namespace
}  // namespace stagefit::diagnose
