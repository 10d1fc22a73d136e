#include "stagefit/diagnose/diagnose.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <optional>
#include <sstream>

#include "stagefit/common/error.h"
#include "stagefit/common/parallel.h"
#include "stagefit/common/units.h"
#include "stagefit/compare/parameter_probes.h"
#include "stagefit/diagnose/effect_problem.h"
#include "stagefit/fit/model_fit.h"
#include "stagefit/kinematics/rigid_transform.h"
#include "stagefit/measurement/projection.h"
#include "stagefit/model/assembled_model.h"
#include "stagefit/model/modes.h"
#include "stagefit/model/parameters.h"

namespace stagefit::diagnose {
namespace {

double Clock() {
  using namespace std::chrono;
  return duration<double>(steady_clock::now().time_since_epoch()).count();
}

std::string Format(const char* format, double a = 0, double b = 0, double c = 0) {
  char buffer[256];
  std::snprintf(buffer, sizeof buffer, format, a, b, c);
  return buffer;
}

/// printf-style text of any arguments (Format() takes doubles only).
template <typename... Args>
std::string FormatText(const char* format, Args... args) {
  char buffer[512];
  std::snprintf(buffer, sizeof buffer, format, args...);
  return buffer;
}

/// Places in the refinement one effect can take at most (at its several locations).
constexpr int kMaxRefinedPerEffect = 4;

/// A channel's direction estimated from the other channels (measurement::EstimateChannelDirections)
/// counts as turned above this angle: at 1-3 % noise right channels came out up to 1.3 degrees off.
constexpr double kMinEstimatedTurn = 2.0 / kDegreesPerRadian;

std::vector<model::ParameterInfo> MatchQuiet(const model::ModelSpec& spec, const std::vector<std::string>& patterns) {
  if (patterns.empty()) return {};
  return model::MatchParameters(spec, patterns);
}

std::string Explain(const Candidate& c) { return model::ExplainEffect(c.effect); }


/// "explains why the model's mode at X Hz is measured at Y Hz": the measured mode whose pairing
/// improves most when the effect is added.
/// `before` is the baseline's pairing.
std::string ModeSentence(const compare::Comparison& comparison, const compare::ModePairing& before, const model::ModelSpec& with) {
  try {
    auto after = compare::PairModes(comparison, comparison.EvaluateModel(with), with);
    double best_gain = 0.0;
    std::string sentence;
    for (const auto& pb : before.pairs) {
      const double fm = before.measured[pb.measured].frequency_hz;
      for (const auto& pa : after.pairs) {
        if (std::abs(after.measured[pa.measured].frequency_hz - fm) > 1e-9 * fm) continue;
        const double gain = std::abs(pb.frequency_error) - std::abs(pa.frequency_error);
        if (gain > best_gain && std::abs(pb.frequency_error) > 0.01) {
          best_gain = gain;
          sentence = Format("; it explains why the model's mode at %.1f Hz is measured at %.1f Hz (with it: %.1f Hz)",
                            before.model[pb.model].frequency_hz, fm, after.model[pa.model].frequency_hz);
        }
      }
    }
    if (sentence.empty() && !before.unpaired_measured.empty()) {
      for (int m : before.unpaired_measured) {
        const double fm = before.measured[m].frequency_hz;
        for (const auto& pa : after.pairs) {
          if (std::abs(after.measured[pa.measured].frequency_hz - fm) <= 1e-9 * fm) {
            return Format("; it explains the measured mode at %.1f Hz that the model lacked (with it: %.1f Hz)", fm,
                          after.model[pa.model].frequency_hz);
          }
        }
      }
    }
    return sentence;
  } catch (const std::exception&) {
    return "";
  }
}

// Candidates keep Ceres' own long first steps (EffectFitOptions): they are screened with a few
// iterations each, and long first steps get an effect's mass or stiffness near its value within that
// budget. With the stiffness fit's short first steps the hidden-payload test found 3-4 kg for 6 kg.
// The leaders are fitted to convergence with short ones.
constexpr double kPolishTrustRegionRadius = 1.0;

/// A leader this close to the noise floor of the grid it is fitted on gets no second start: a
/// correct model's error lies within 1.05x of the floor (its standard deviation is about 1 % of it).
constexpr double kSecondStartSkipTimesFloor = 1.05;

/// `body` (an extra-body effect) with the joint stiffnesses that put its translation modes,
/// sqrt(k / mass), at `translation_hz` and its rocking modes at `rocking_hz`
/// (model::SetExtraBodyRockingHz); its mass as it is.
void SetExtraBodyModesHz(model::Effect* body, double translation_hz, double rocking_hz) {
  body->parameters["k"] = body->parameters.at("mass") * std::pow(2 * M_PI * translation_hz, 2);
  model::SetExtraBodyRockingHz(body, rocking_hz);
}

/// The rigid-body consistency of the measurement's raw channels (summary fields), when it has them.
void AddRigidConsistency(const measurement::FrfData& data, const compare::Comparison& comparison,
                         const model::ModelSpec& spec, DiagnoseSummary* summary) {
  measurement::RigidConsistency rc;
  try {
    if (comparison.space() == compare::ComparisonSpace::kBodies) {
      // Each sensor against the rigid motion of its own body.
      std::map<std::string, Eigen::Vector3d> p_WBcm;
      for (const auto& b : spec.bodies) p_WBcm[b.name] = b.com_W;
      rc = measurement::CalcRigidConsistencyPerBody(data, p_WBcm);
    } else {
      if (comparison.CorrectableChannels().empty()) return;
      rc = measurement::CalcRigidConsistency(data, comparison.frame_origin_W());
    }
  } catch (const InputError&) {
    return;  // sensors on several bodies or too few channels: no single rigid body to check against
  }
  if (rc.bands.empty()) return;
  summary->rigid_residual_share = std::max(rc.output_overall.maxCoeff(), rc.input_overall.maxCoeff());
  std::vector<DiagnoseSummary::ChannelConsistency> channels;
  // A channel's share is its median over the bands: a turned or misplaced channel is off in every
  // band, while the bands where noise dominates (low frequencies of an accelerance) are off for all.
  auto add = [&](const std::vector<std::string>& names, const Eigen::MatrixXd& share) {
    for (int i = 0; i < share.rows(); ++i) {
      std::vector<double> row;
      for (int b = 0; b < share.cols(); ++b) row.push_back(share(i, b));
      std::nth_element(row.begin(), row.begin() + row.size() / 2, row.end());
      int worst = 0;
      share.row(i).maxCoeff(&worst);
      channels.push_back({names[i], row[row.size() / 2], rc.bands[worst].centre_hz()});
    }
  };
  add(rc.output_names, rc.output_residual_share);
  add(rc.input_names, rc.input_residual_share);
  std::sort(channels.begin(), channels.end(), [](const auto& a, const auto& b) { return a.share > b.share; });
  if (channels.size() > 4) channels.resize(4);
  summary->inconsistent_channels = channels;
}

/// A candidate to fit: the effect with its starting values, the model parameters to start from (the
/// baseline's where it names none) and the effect parameters held at their value.
struct Try {
  model::Effect effect;
  std::map<std::string, double> start;
  std::vector<std::string> held;
  /// Short first steps (kPolishTrustRegionRadius) whatever the round's: a start from the model as given
  /// far from the data, where long first steps throw the stiffnesses across modes as they do in a
  /// stiffness fit (a hexapod coupling from the model as given, 4 iterations: 0.83 with short first
  /// steps, 1.18 with long ones, against a baseline at 1.07).
  bool short_steps = false;
};

bool SameCandidate(const Candidate& a, const Candidate& b) {
  return a.effect.name == b.effect.name && a.effect.location == b.effect.location && a.held_parameters == b.held_parameters;
}

}  // namespace

std::optional<Eigen::Vector3d> CalcChannelTurn(const measurement::ChannelDirectionEstimate& estimate) {
  const Eigen::Vector3d axis = estimate.declared_W.cross(estimate.estimated_W);
  if (!estimate.estimable || axis.norm() < 1e-12) return std::nullopt;
  const auto euler =
      kinematics::EulerFromRotation(Eigen::AngleAxisd(estimate.angle_rad, axis.normalized()).toRotationMatrix());
  return Eigen::Vector3d(euler.alpha_rad, euler.beta_rad, euler.gamma_rad);
}

void SortWorst(const compare::ComparisonResult& result, size_t max_bands, size_t max_elements,
               std::vector<compare::BandError>* bands, std::vector<compare::ElementError>* elements) {
  auto by_share = [](const auto& a, const auto& b) { return a.share > b.share; };
  *bands = result.bands;
  std::sort(bands->begin(), bands->end(), by_share);
  if (bands->size() > max_bands) bands->resize(max_bands);
  *elements = result.elements;
  std::sort(elements->begin(), elements->end(), by_share);
  if (elements->size() > max_elements) elements->resize(max_elements);
}

std::string WhereWords(const std::vector<compare::BandError>& bands, const std::vector<compare::ElementError>& elements,
                       const std::vector<ChannelError>& channels) {
  std::string text;
  for (size_t k = 0; k < bands.size() && k < 2; ++k) {
    text += (text.empty() ? "" : ", ") + Format("%.0f-%.0f Hz", bands[k].band.low_hz, bands[k].band.high_hz) +
            Format(" (%.0f %%)", 100 * bands[k].share);
  }
  std::string named;
  for (size_t k = 0; k < elements.size() && k < 3; ++k) {
    named += (named.empty() ? "" : ", ") + elements[k].name + Format(" (%.0f %%", 100 * elements[k].share);
    // The first element's own worst band, when it holds a part of it that its bands would not by
    // chance (kElementBandShareNamed).
    if (k == 0 && elements[k].worst_band_share > kElementBandShareNamed) {
      named += Format(", %.0f %% of it in %.0f-", 100 * elements[k].worst_band_share, elements[k].worst_band.low_hz) +
               Format("%.0f Hz", elements[k].worst_band.high_hz);
    }
    named += ")";
  }
  if (!named.empty()) text += (text.empty() ? "" : "; elements ") + named;
  const std::string channel_words = ChannelWords(channels);
  if (!channel_words.empty()) text += "; channels " + channel_words;
  return text;
}

namespace {

/// The median of `values` (sorted in place); 0 for none.
double Median(std::vector<double>* values) {
  if (values->empty()) return 0.0;
  std::sort(values->begin(), values->end());
  const size_t n = values->size();
  return n % 2 ? (*values)[n / 2] : 0.5 * ((*values)[n / 2 - 1] + (*values)[n / 2]);
}

}  // namespace

std::vector<ChannelError> WorstChannels(const model::ModelSpec& spec, const measurement::FrfData& measurement,
                                        const compare::ComparisonOptions& options, size_t max_channels) {
  if (measurement.outputs.empty() || measurement.inputs.empty()) return {};
  compare::ComparisonOptions raw = options;
  raw.space = compare::ComparisonSpace::kRaw;
  std::optional<compare::Comparison> comparison;
  compare::ComparisonResult result;
  try {
    comparison.emplace(compare::Comparison::Create(spec, measurement, raw));
    result = comparison->Evaluate(spec);
  } catch (const std::exception&) {
    return {};  // a measurement given already projected, or one the raw space cannot take (header)
  }
  // The median of the channel's elements' errors, not the error over all its points: a part missing
  // at one sensor raises every element of its row and one element of each impact's column; over all
  // points that one element put every impact at 19x the floor beside the sensor's 47x
  // (WorstChannels.ALocalResonanceUnderOneSensorPutsItFirst), the median leaves them at the floor.
  std::vector<std::vector<double>> out(static_cast<size_t>(comparison->num_outputs())), in(static_cast<size_t>(comparison->num_inputs()));
  for (const auto& e : result.elements) {
    out[static_cast<size_t>(e.index.output)].push_back(e.error);
    in[static_cast<size_t>(e.index.input)].push_back(e.error);
  }
  const compare::NoiseFloor floor = comparison->CalcNoiseFloor();
  std::vector<ChannelError> channels;
  auto add = [&](std::vector<std::vector<double>>& errors, const std::vector<std::string>& names, bool is_input) {
    for (size_t c = 0; c < errors.size(); ++c) {
      if (errors[c].empty()) continue;
      ChannelError ce;
      ce.name = names[c];
      ce.is_input = is_input;
      ce.num_elements = static_cast<int>(errors[c].size());
      ce.error = Median(&errors[c]);
      if (floor.known && floor.floor > 0) ce.times_floor = ce.error / floor.floor;
      channels.push_back(ce);
    }
  };
  add(out, comparison->output_names(), false);
  add(in, comparison->input_names(), true);
  std::stable_sort(channels.begin(), channels.end(), [](const ChannelError& a, const ChannelError& b) { return a.error > b.error; });
  std::vector<double> errors;
  for (const auto& c : channels) errors.push_back(c.error);
  const double median = Median(&errors);
  for (auto& c : channels) c.times_median = median > 0 ? c.error / median : 0.0;
  if (channels.size() > max_channels) channels.resize(max_channels);
  return channels;
}

std::vector<ChannelError> StandingOut(const std::vector<ChannelError>& channels) {
  std::vector<ChannelError> out;
  for (size_t k = 0; k < channels.size() && k < 2 && channels[k].times_median >= kChannelStandsOut; ++k) out.push_back(channels[k]);
  return out;
}

std::string ChannelWords(const std::vector<ChannelError>& channels) {
  std::string text;
  for (const ChannelError& c : StandingOut(channels)) {
    const bool first = text.empty();
    text += (first ? "" : ", ") + c.name +
            (std::isfinite(c.times_floor) ? Format(first ? " (%.1f x the floor)" : " (%.1f x)", c.times_floor) : Format(" (error %.4f)", c.error));
  }
  return text;
}

std::vector<measurement::ChannelDirectionEstimate> ChannelDirectionsUnder(
    const std::vector<model::GeometryCorrection>& corrections, const measurement::FrfData& measurement,
    const Eigen::Vector3d& p_WXo, double fmin_hz, double fmax_hz) {
  try {
    return measurement::EstimateChannelDirections(compare::WithGeometryCorrections(measurement, corrections), p_WXo,
                                                  fmin_hz, fmax_hz);
  } catch (const InputError&) {
    return {};  // no raw channels with geometry: nothing to say
  }
}

std::string TurnAgainstTheChannels(const model::ModelSpec& baseline, const model::Effect& effect,
                                   const std::vector<measurement::ChannelDirectionEstimate>& directions) {
  if (!model::FindEffectDefinition(effect.name).measured_side_only) return {};
  const auto estimate = std::find_if(directions.begin(), directions.end(),
                                     [&](const measurement::ChannelDirectionEstimate& d) { return d.name == effect.location; });
  if (estimate == directions.end() || !estimate->estimable) return {};
  // The turn the effect gives its channel in the model, applied to the direction the data declare.
  const auto direction_of = [&](const model::ModelSpec& spec) -> std::optional<Eigen::Vector3d> {
    for (const auto* list : {&spec.sensors, &spec.excitations}) {
      for (const auto& p : *list) {
        if (p.name == effect.location) return p.direction_W.normalized();
      }
    }
    return std::nullopt;
  };
  model::ModelSpec with = baseline;
  try {
    model::ApplyEffect(with, effect);
  } catch (const InputError&) {
    return {};
  }
  const std::optional<Eigen::Vector3d> before = direction_of(baseline), after = direction_of(with);
  if (!before || !after || !(before->cross(*after).norm() > 0.0)) return {};
  const Eigen::Vector3d turned = Eigen::Quaterniond::FromTwoVectors(*before, *after) * estimate->declared_W;
  const double declared = estimate->declared_residual_share, along = estimate->ResidualShareAlong(turned);
  if (!(along > kTurnAgainstChannelsRatio * declared)) return {};
  const double angle = std::atan2(before->cross(*after).norm(), before->dot(*after));
  return FormatText("it turns %s by %.1f deg, which leaves %.3g of its readings unexplained by the other %s' rigid motion against "
                    "%.3g as declared (%.3g with the direction they give it, %.1f deg from the declared): the channels say it is not "
                    "turned so",
                    effect.location.c_str(), angle * kDegreesPerRadian, along, estimate->is_impact ? "impacts" : "sensors", declared,
                    estimate->residual_share, estimate->angle_rad * kDegreesPerRadian);
}

std::string ImplausibleBecause(const model::ModelSpec& baseline, const model::Effect& effect, double band_low_hz,
                               const std::vector<measurement::ChannelDirectionEstimate>& directions) {
  double stack_kg = 0.0;
  for (const auto& b : baseline.bodies) stack_kg += b.mass_kg;
  const model::EffectDefinition& definition = model::FindEffectDefinition(effect.name);
  const auto mass = effect.parameters.find("mass");
  if (definition.adds_mass && mass != effect.parameters.end() && mass->second > stack_kg) {
    return Format("its fitted mass %.4g kg is more than the whole stack's %.4g kg", mass->second, stack_kg);
  }
  const auto k = effect.parameters.find("k");
  if (definition.adds_mass && mass != effect.parameters.end() && k != effect.parameters.end() &&
      band_low_hz > 0 && mass->second > 0) {
    const double local_hz = std::sqrt(std::max(k->second, 0.0) / mass->second) / (2 * M_PI);
    if (local_hz < band_low_hz) {
      return Format("its local mode at %.3g Hz is below the compared band (from %.3g Hz): in the band the body stands still "
                    "and its joint acts as a spring from the stage to the ground, which is no body; something ties the "
                    "stage to the ground (a cable, a hose)",
                    local_hz, band_low_hz);
    }
  }
  if (definition.implausible) {
    if (std::string why = definition.implausible(effect); !why.empty()) return why;
  }
  if (std::string why = TurnAgainstTheChannels(baseline, effect, directions); !why.empty()) return why;
  const std::vector<ParameterAtBound> at_bounds = ParametersAtBounds(baseline, effect);
  if (at_bounds.empty()) return {};
  const ParameterAtBound& p = at_bounds[0];
  return FormatText("%s = %.4g %s is at the bound of its search range [%.3g, %.3g] %s", p.name.c_str(), p.value, p.unit,
                    p.lower, p.upper, p.unit);
}

std::vector<ParameterAtBound> ParametersAtBounds(const model::ModelSpec& baseline, const model::Effect& effect) {
  const model::EffectDefinition& def = model::FindEffectDefinition(effect.name);
  model::Effect nominal = effect;
  nominal.parameters = model::DefaultEffectParameters(baseline, effect.name, effect.location);
  // The parameters a fit sets (not the redundant or held ones, which stay where they were started).
  std::vector<int> positions;
  const std::vector<fit::ParameterSpec> specs = EffectParameterSpecs(baseline, nominal, {}, &positions);
  std::vector<ParameterAtBound> found;
  for (size_t i = 0; i < specs.size(); ++i) {
    const size_t k = static_cast<size_t>(positions[i]);
    const bool length = def.parameters[k].dimension == dim::kLength;
    if (!length && def.parameters[k].dimension != dim::kAngle) continue;
    const fit::ParameterSpec& b = specs[i];
    const double value = effect.parameters.at(def.parameters[k].name);
    if (!std::isfinite(b.upper - b.lower)) continue;
    const double margin = 0.01 * (b.upper - b.lower);
    if (value <= b.lower + margin || value >= b.upper - margin) {
      found.push_back({def.parameters[k].name, value, b.lower, b.upper, length ? "m" : "rad"});
    }
  }
  return found;
}

namespace {

/// Candidate::floor_ratio of `effect` fitted as `with` against `baseline` on `comparison`: 1 for an
/// effect of the model's side, or when a floor is unknown.
double FloorRatio(const compare::Comparison& comparison, const model::ModelSpec& baseline, const model::ModelSpec& with,
                  const model::Effect& effect) {
  if (!model::FindEffectDefinition(effect.name).measured_side_only) return 1.0;
  const compare::NoiseFloor base = comparison.CalcNoiseFloor(baseline), own = comparison.CalcNoiseFloor(with);
  return base.known && own.known && base.floor > 0 && own.floor > 0 ? own.floor / base.floor : 1.0;
}

void SortByBic(std::vector<Candidate>* candidates) {
  std::sort(candidates->begin(), candidates->end(), [](const Candidate& a, const Candidate& b) { return a.delta_bic < b.delta_bic; });
}

void SortByJudgedError(std::vector<Candidate>* candidates) {
  std::sort(candidates->begin(), candidates->end(),
            [](const Candidate& a, const Candidate& b) { return JudgedError(a) < JudgedError(b); });
}

/// Each of `fitted` replaces the same candidate of `ranked` unless its error is higher; re-ranked.
void MergeBetter(const std::vector<Candidate>& fitted, std::vector<Candidate>* ranked) {
  for (const auto& r : fitted) {
    for (auto& c : *ranked) {
      if (SameCandidate(r, c) && JudgedError(r) <= JudgedError(c)) c = r;
    }
  }
  SortByBic(ranked);
}

/// The first `count` of `ranked` as fits that continue from where they stopped; with `max_per_effect`
/// > 0, at most that many of one effect (the next best of the others take their places).
std::vector<Try> Continue(const std::vector<Candidate>& ranked, int count, int max_per_effect = 0) {
  std::vector<Try> tries;
  std::map<std::string, int> per_effect;
  for (size_t i = 0; i < ranked.size() && static_cast<int>(tries.size()) < count; ++i) {
    if (max_per_effect > 0 && per_effect[ranked[i].effect.name]++ >= max_per_effect) continue;
    tries.push_back({ranked[i].effect, ranked[i].model_parameters, ranked[i].held_parameters});
  }
  return tries;
}

/// Whether `channel` is an impact (an input) of the measurement, else a sensor.
bool IsImpact(const measurement::FrfData& data, const std::string& channel) {
  for (const auto& x : data.inputs) {
    if (x.name == channel) return true;
  }
  return false;
}

/// The turn of each channel (Euler XYZ angles, as a sensor-geometry correction holds them) that takes
/// its declared direction to the one the other channels' rigid-body motion gives it (`estimates`,
/// measurement::EstimateChannelDirections); empty when the data carry no channel geometry.
struct ChannelTurn {
  Eigen::Vector3d euler_rad;
  double angle_rad = 0;
  double residual_share = 0;  ///< ChannelDirectionEstimate::residual_share
};
std::map<std::string, ChannelTurn> EstimateChannelTurns(const std::vector<measurement::ChannelDirectionEstimate>& estimates,
                                                        const compare::Comparison& comparison) {
  std::map<std::string, ChannelTurn> turns;
  if (comparison.CorrectableChannels().empty()) return turns;
  for (const auto& e : estimates) {
    if (const auto euler = CalcChannelTurn(e)) turns[e.name] = {*euler, e.angle_rad, e.residual_share};
  }
  return turns;
}

/// Every k-th of `count` frequencies, k the smallest step that leaves at most `max_frequencies` of
/// them; nullopt when there are no more than that (or max_frequencies <= 0).
std::optional<std::vector<int>> ThinnedFrequencies(int count, int max_frequencies) {
  if (max_frequencies <= 0 || count <= max_frequencies) return std::nullopt;
  const int step = (count + max_frequencies - 1) / max_frequencies;
  std::vector<int> kept;
  for (int k = 0; k < count; k += step) kept.push_back(k);
  return kept;
}

}  // namespace

std::optional<double> WorstBandCentreHz(const compare::Comparison& comparison, const model::ModelSpec& model) {
  std::vector<compare::BandError> bands;
  std::vector<compare::ElementError> elements;
  SortWorst(comparison.Evaluate(model), 1, 0, &bands, &elements);
  if (bands.empty() || !(bands[0].band.low_hz > 0)) return std::nullopt;
  return std::sqrt(bands[0].band.low_hz * bands[0].band.high_hz);
}

std::optional<compare::Comparison> ThinnedComparison(const compare::Comparison& comparison, int max_frequencies) {
  const auto kept = ThinnedFrequencies(comparison.num_frequencies(), max_frequencies);
  if (!kept) return std::nullopt;
  try {
    return comparison.OnFrequencies(*kept);
  } catch (const InputError&) {
    return std::nullopt;  // no compared point left on the thinned grid
  }
}

EffectFit FitEffect(const model::ModelSpec& base, const compare::Comparison& comparison, const model::Effect& effect,
                    const std::vector<std::string>& params, const EffectFitOptions& effect_options) {
  std::vector<int> effect_index;
  std::vector<fit::ParameterSpec> effect_specs = EffectParameterSpecs(base, effect, effect_options.held, &effect_index);
  std::vector<model::ParameterInfo> model_params = MatchQuiet(base, params);
  std::vector<fit::ParameterSpec> specs = effect_specs;
  for (const auto& s : fit::MakeParameterSpecs(base, model_params)) specs.push_back(s);
  EffectProblem problem(base, comparison, effect, effect_specs, effect_index, model_params);
  fit::FitOptions options;
  options.max_iterations = effect_options.max_iterations;
  options.function_tolerance = 1e-8;
  options.initial_trust_region_radius = effect_options.initial_trust_region_radius;
  options.stall_iterations = effect_options.stall_iterations;
  options.projected_line_search = true;  // a screening fit has 4 iterations
  options.analyse_optimum = false;        // candidates are ranked by their error alone
  EffectFit result;
  result.summary =
      effect_options.probe_basins ? fit::SolveWithProbes(problem, specs, options) : fit::Solve(problem, specs, options);
  Eigen::VectorXd p = result.summary.values();
  result.effect = problem.EffectAt(p);
  if (!problem.SpecAt(p, &result.spec)) result.spec = base;
  return result;
}

EffectsFit FitEffects(const model::ModelSpec& base, const compare::Comparison& comparison,
                      const std::vector<model::Effect>& effects, const std::vector<std::string>& params,
                      const EffectFitOptions& effect_options) {
  // Each effect's search range is taken on the model it is applied to (the base with the effects before it).
  std::vector<fit::ParameterSpec> effect_specs;
  std::vector<int> effect_of, effect_index;
  model::ModelSpec applied = base;
  for (size_t k = 0; k < effects.size(); ++k) {
    std::vector<int> index;
    for (const auto& s : EffectParameterSpecs(applied, effects[k], effect_options.held, &index)) effect_specs.push_back(s);
    for (int i : index) {
      effect_index.push_back(i);
      effect_of.push_back(static_cast<int>(k));
    }
    model::ApplyEffect(applied, effects[k]);
  }
  std::vector<model::ParameterInfo> model_params = MatchQuiet(base, params);
  std::vector<fit::ParameterSpec> specs = effect_specs;
  for (const auto& s : fit::MakeParameterSpecs(base, model_params)) specs.push_back(s);
  EffectProblem problem(base, comparison, effects, effect_specs, effect_of, effect_index, model_params);
  fit::FitOptions options;
  options.max_iterations = effect_options.max_iterations;
  options.function_tolerance = 1e-8;
  options.initial_trust_region_radius = effect_options.initial_trust_region_radius;
  options.stall_iterations = effect_options.stall_iterations;
  options.projected_line_search = true;
  options.analyse_optimum = false;
  EffectsFit result;
  result.summary =
      effect_options.probe_basins ? fit::SolveWithProbes(problem, specs, options) : fit::Solve(problem, specs, options);
  const Eigen::VectorXd p = result.summary.values();
  result.effects = problem.EffectsAt(p);
  if (!problem.SpecAt(p, &result.spec)) {
    result.spec = base;
    for (const auto& e : effects) model::ApplyEffect(result.spec, e);
  }
  return result;
}

DiagnoseSummary Diagnose(const model::ModelSpec& spec, const measurement::FrfData& measurement,
                         const DiagnoseOptions& options) {
  const double start = Clock();
  auto say = [&](const std::string& line) {
    if (options.progress) options.progress(Format("[%5.1f s] ", Clock() - start) + line);
  };
  DiagnoseSummary summary;
  compare::Comparison comparison = compare::Comparison::Create(spec, measurement, options.comparison);
  summary.num_residuals = comparison.num_residuals();
  summary.error_initial = comparison.Error(spec);

  // 1. Baseline.
  summary.baseline = spec;
  // The model's own parameters, and those of the effects already in it (DiagnoseOptions::refit_effects):
  // fitted in the baseline and again with every candidate.
  const std::vector<std::string> params =
      options.refit_effects ? model::WithEffectParameters(options.params, spec) : options.params;
  std::vector<model::ParameterInfo> model_params = MatchQuiet(spec, params);
  if (!model_params.empty()) {
    fit::FitOptions fo;
    fo.max_iterations = options.baseline_iterations;
    fit::FitModel(summary.baseline, comparison, model_params, fo);
  }
  summary.error_baseline = comparison.Error(summary.baseline);
  say(Format("baseline: error %.4f -> %.4f after fitting the model's own parameters", summary.error_initial,
             summary.error_baseline));

  // The grid the candidates are searched on (DiagnoseOptions::max_search_frequencies): a thinned one
  // ranks them as well at a fraction of the cost; the leaders are finished and every candidate is scored
  // on all frequencies.
  const std::optional<compare::Comparison> thinned_comparison = ThinnedComparison(comparison, options.max_search_frequencies);
  const compare::Comparison& search = thinned_comparison ? *thinned_comparison : comparison;
  // The screening and its scans on a coarser grid still (DiagnoseOptions::max_screening_frequencies):
  // four iterations from far only need to tell the promising candidates from the others.
  std::optional<compare::Comparison> screening_comparison;
  if (options.max_screening_frequencies > 0 && search.num_frequencies() > options.max_screening_frequencies) {
    screening_comparison = ThinnedComparison(comparison, options.max_screening_frequencies);
  }
  const compare::Comparison& screen = screening_comparison ? *screening_comparison : search;

  // 2. Candidates: every effect at every location (extra bodies from five starting local modes,
  // sensor-geometry at every channel, started from its direction as the other channels see it).
  AddRigidConsistency(measurement, comparison, spec, &summary);
  const std::vector<std::string> channels = comparison.CorrectableChannels();
  // The channels' directions as the data declare them (no model involved): the candidates' starting
  // turns here, and the check of the leaders' turns at the end (TurnAgainstTheChannels) unless the model
  // corrects some channels already.
  const std::vector<measurement::ChannelDirectionEstimate> declared_directions =
      ChannelDirectionsUnder({}, measurement, comparison.frame_origin_W(), options.comparison.fmin_hz,
                             options.comparison.fmax_hz);
  const auto turns = EstimateChannelTurns(declared_directions, comparison);
  for (const auto& [channel, turn] : turns) {
    if (turn.angle_rad > kMinEstimatedTurn) {
      summary.turned_channels.push_back({channel, turn.angle_rad * kDegreesPerRadian, turn.residual_share});
    }
  }
  std::sort(summary.turned_channels.begin(), summary.turned_channels.end(),
            [](const auto& a, const auto& b) { return a.residual_share < b.residual_share; });
  // An effect that adds mass (payload, extra body) is also started from the model's parameters as
  // given: the baseline's stiffnesses have softened to mimic the missing mass, so that the effect
  // added to them overshoots (the error rises above the baseline's) and its fit sheds the mass again.
  // An extra body starts 0.1 m above its host's centre of mass: at the same height the body's
  // coupling to the host's rocking is stationary in z, and the fit did not move z away from there.
  std::map<std::string, double> as_given;
  for (const auto& p : model::ListParameters(spec)) {
    const auto it = options.as_given.find(p.name);
    as_given[p.name] = it != options.as_given.end() ? it->second : model::GetParameter(spec, p);
  }
  model::ModelSpec spec_as_given = spec;
  for (const auto& p : model::ListParameters(spec_as_given)) model::SetParameter(spec_as_given, p, as_given.at(p.name));
  summary.noise_floor = comparison.CalcNoiseFloor();
  // A baseline far above the noise floor has bent its parameters to mimic what is missing: every
  // candidate is then also started from the model as given (DiagnoseOptions::far_times_floor).
  const bool far_from_floor = options.far_times_floor > 0 && summary.noise_floor.known && summary.noise_floor.floor > 0 &&
                              summary.error_baseline > options.far_times_floor * summary.noise_floor.floor;
  // An extra body starts from five local modes across the band, and from the centre of the band where
  // the baseline's error is largest: a missing lightly damped local mode leaves its error around its
  // frequency, and a fit started a factor 1.3 or more away from it does not reach it (its peak and the
  // measured one do not overlap): a 1.8 kg body on the hexapod at 246 Hz, with its error 78 % in
  // 223-281 Hz, was fitted from 200 and 320 Hz down to 1.5 g and lost to a turned channel (seed 13008).
  const std::vector<double> extra_body_fixed_start_hz = {40.0, 70.0, 120.0, 200.0, 320.0};
  std::vector<double> extra_body_data_start_hz;  // where the data put the body's mode
  if (const auto hz = WorstBandCentreHz(comparison, summary.baseline)) extra_body_data_start_hz.push_back(*hz);
  std::vector<Try> tries;
  std::vector<Try> scan_starts;  // refined without screening (ScanServoStiffness, ScanCouplingStiffness)
  std::vector<model::Effect> couplings;  // scanned after the loop below
  std::vector<model::Effect> servos;     // profiled near the floor (ServoProfileStarts)
  auto add_try = [&](const model::Effect& e, bool short_steps = false) {
    tries.push_back({e, {}, {}, short_steps});
    if (model::FindEffectDefinition(e.name).adds_mass) {
      tries.push_back({e, as_given, {}, short_steps});
    } else if (far_from_floor) {
      tries.push_back({e, as_given, {}, true});
    }
    // A channel whose direction, as the other channels see it, is off by more than kMinEstimatedTurn is
    // also tried turned as they see it, held there: only the model's parameters are fitted. In
    // compliance space a fitted correction is poorly determined. It drifted from the estimate (a
    // 15-degree turn to 28 degrees, at 1.2x the floor), and the correction of a right channel mimicked
    // a turned one (a3y's for a1y's, at the floor). Held at the estimate, a right channel's correction
    // is nearly nothing and cannot mimic.
    // Like an effect that adds mass, it is started from the model as given too: the baseline's
    // stiffnesses have bent to absorb the turn (a1x turned 15 degrees, held right: 0.176 from the
    // baseline's stiffnesses, the floor from the model's as given).
    if (e.name == "sensor-geometry" && turns.count(e.location) && turns.at(e.location).angle_rad > kMinEstimatedTurn) {
      tries.push_back({e, {}, {"dx", "dy", "dz", "rx", "ry", "rz"}});
      tries.push_back({e, as_given, {"dx", "dy", "dz", "rx", "ry", "rz"}});
    }
  };
  for (auto e : model::EnumerateEffects(summary.baseline, channels)) {
    if (!options.effects.empty() &&
        std::find(options.effects.begin(), options.effects.end(), e.name) == options.effects.end()) {
      continue;
    }
    if (model::FindEffectDefinition(e.name).set_by_experiment) continue;  // a spin rate: not from hammer data
    if (e.name == "sensor-geometry" && turns.count(e.location) && turns.at(e.location).angle_rad <= kMinEstimatedTurn &&
        !IsImpact(measurement, e.location)) {
      // An accelerometer whose direction the other channels confirm is not tried: its offsets alone
      // (within 5 cm) change its readings only by the lever arm of a rotation, and in compliance space
      // such corrections of right channels came within a few % of each other and filled the refinement
      // (each 6 parameters by central differences: 30 % of a diagnosis). An impact is still tried: a
      // hammer hits off its mark, and its direction estimate says nothing of that.
      continue;
    }
    if (e.name == "sensor-geometry" && turns.count(e.location)) {
      // Started turned as the other channels see it: from no turn, the fit of a channel turned by
      // 15 degrees stopped in a local minimum (0.198 for a floor of 0.036) and another channel won.
      const Eigen::Vector3d& t = turns.at(e.location).euler_rad;
      e.parameters["rx"] = std::clamp(t(0), -kMaxCorrectionTurn, kMaxCorrectionTurn);
      e.parameters["ry"] = std::clamp(t(1), -kMaxCorrectionTurn, kMaxCorrectionTurn);
      e.parameters["rz"] = std::clamp(t(2), -kMaxCorrectionTurn, kMaxCorrectionTurn);
    }
    if (e.name == "joint-offset") {
      // A moved stiffness centre adds k dz^2 to the joint's rotational stiffnesses, which the baseline's
      // have already absorbed: from the baseline the fit hardly moves the centre (seeds 1002, 1017,
      // 1022: 0.33, 0.66 and 0.31 after the screening's 4 iterations, floors 0.030-0.038). From the
      // model as given, started 0.1 m above or below, the side of the truth reached 0.037-0.28.
      // Far from the floor also with short first steps (Try::short_steps): a hexapod offset of 75 mm
      // (seed 5005, baseline at 9.4x) reached 0.18 in 4 iterations with them, 0.34 with long ones.
      tries.push_back({e, {}, {}});
      for (double dz : {-0.1, 0.1}) {
        e.parameters["dz"] = dz;
        tries.push_back({e, as_given, {}});
        if (far_from_floor) tries.push_back({e, as_given, {}, true});
      }
      continue;
    }
    if (e.name == "extra-body") {
      e.parameters["z"] = 0.1;
      // Also from the local mode (translation and rocking together) of a scan across the band, the
      // body's default mass on the baseline: 23005 (a 3.1 kg body at 95 Hz on the hexapod, 150 Hz band)
      // was started at 70, 120 Hz and its worst band and not found (6.0x the floor); the scan with a
      // 1 kg body has its minimum at 92 Hz, and fits from there reach the body's mass and local mode.
      std::vector<double> data_starts_hz = extra_body_data_start_hz;
      const model::Effect at_default = e;
      if (const auto hz = ScanBandHz(screen, [&](double hz) {
            model::Effect body = at_default;
            SetExtraBodyModesHz(&body, hz, hz);
            model::ModelSpec with = summary.baseline;
            model::ApplyEffect(with, body);
            return with;
          })) {
        data_starts_hz.push_back(*hz);
      }
      // The starts the data put near the body's mode (the worst band's centre, the scan's minimum) are
      // screened with short first steps, which keep them there; the five fixed ones with long steps, to
      // travel. 37011 of eval_loop (a 2.3 kg body at 270 Hz on the hexapod beside a payload, the worst
      // band 223-281 Hz): from 250 Hz the long steps threw the mass to 0.46 kg in 4 iterations (0.345,
      // above the baseline's 0.322) and a 2.5 t body on a 7 Hz spring was refined instead (0.321); with
      // short ones the start kept 2.2 kg at 265 Hz (0.233) and its refinement reached 1.09x the floor.
      auto add_starts = [&](const std::vector<double>& starts_hz, bool short_steps) {
        for (double hz : starts_hz) {
          SetExtraBodyModesHz(&e, hz, hz);  // its rocking modes at the same frequency
          add_try(e, short_steps);
        }
      };
      add_starts(extra_body_fixed_start_hz, false);
      add_starts(data_starts_hz, true);
    } else if (e.name == "servo-stiffness") {
      add_try(e);
      // Also from kServoStiffStart times the default k, the drive nearly rigid: from the default the
      // screening's long first steps throw k away (35008 of eval_loop, ty.Dy a spring of 4.0e8 N/m,
      // 150 Hz band: 0.252 after 4 iterations from 2e8, 0.046 from 2e9, the next candidate 0.049).
      model::Effect stiff = e;
      stiff.parameters["k"] = kServoStiffStart * e.parameters.at("k");
      add_try(stiff);
      // And from there with short first steps: the long ones threw the damping ratio to its bound and
      // the screening ended above the baseline (37001 of eval_loop, ty.Dy a spring of 6.4e8 N/m, 150 Hz
      // band, the baseline at 0.0451: from 2e9 0.0480 in 4 iterations with long steps, 0.0374 with
      // short ones; 30 iterations on from either reach the floor, 0.0338).
      add_try(stiff, true);
      // Also from the k of a scan on the model as given, refined whatever its screening: 29009 (ty.Dy
      // a spring of 3.2e8 N/m, 150 Hz band) was screened from the default 2.0e8 at 0.213 against the
      // baseline's 0.058 (four iterations, its mode in the band) and never refined; its 30-iteration
      // fit from there stops at 5.6e7 (0.111). The scan's minimum is at 3.1e8, and the fit from there
      // reaches the noise floor (0.0387, floor 0.0387).
      if (const auto k = ScanServoStiffness(screen, spec_as_given, e)) {
        model::Effect scanned = e;
        scanned.parameters["k"] = *k;
        scan_starts.push_back({scanned, as_given, {}});
      }
      // The profile's grid about the catalogue's k on the model as given: on the fitted baseline the
      // joint's typical stiffness moves with the round (83132's ry, 1.2e8 as given, 7.8e8 in round 2).
      model::Effect profiled = e;
      profiled.parameters["k"] = model::FindEffectDefinition(e.name).defaults(spec_as_given, e.location).at("k");
      servos.push_back(profiled);
    } else {
      add_try(e);
      // A rigid mass also with short first steps: the long ones threw 41000's payload (4.3 kg, 54 mm
      // above the hexapod's centre of mass; the first fit at 9.0x the floor) off its course in the four
      // iterations, from the baseline 0.283 against the baseline's own 0.270 and from the model as given
      // 0.520, so it was never refined and nothing was found; with short steps 0.122 and 0.097, and 30
      // iterations on from any of the four reach the floor.
      if (model::FindEffectDefinition(e.name).adds_mass) add_try(e, true);
      if (e.name == "coupled-stiffness") couplings.push_back(e);
    }
  }
  // The couplings scanned on the model as given (ScanCouplingStiffness); the best one refined from its
  // minimum whatever its screening when it stands out (kCouplingScanLead).
  {
    std::vector<std::pair<double, size_t>> minima;  // (error, index into couplings)
    std::vector<std::optional<ScanMinimum>> scans(couplings.size());
    for (size_t i = 0; i < couplings.size(); ++i) {
      scans[i] = ScanCouplingStiffness(screen, spec_as_given, couplings[i]);
      if (scans[i]) minima.push_back({scans[i]->error, i});
    }
    std::sort(minima.begin(), minima.end());
    // The model as given with the effects added so far as fitted (their parameters on the fitted
    // stiffnesses) may be no model: a coupling fitted beside stiffer joints than given makes the joint
    // indefinite (seed 35023 of eval_loop). Its scans then have no minimum either.
    double error_as_given = std::numeric_limits<double>::infinity();
    try {
      error_as_given = screen.Error(spec_as_given);
    } catch (const InputError&) {
    }
    if (!minima.empty() && std::isfinite(error_as_given) && minima[0].first <= (1 - kServoScanMinDrop) * error_as_given &&
        (minima.size() < 2 || minima[0].first <= kCouplingScanLead * minima[1].first)) {
      model::Effect scanned = couplings[minima[0].second];
      scanned.parameters["k"] = scans[minima[0].second]->at;
      scan_starts.push_back({scanned, as_given, {}});
    }
  }
  // The criterion against the baseline (header): delta BIC, and a fall of the error that counts. A
  // candidate's error is compared with the baseline's on the same grid: `scale` holds that grid's
  // number of residuals and baseline error.
  struct Scale {
    double n = 0;
    double error_baseline = 0;
  };
  const Scale search_scale{static_cast<double>(search.num_residuals()), search.Error(summary.baseline)};
  auto rescore = [&](Candidate* c, const Scale& scale) {
    const double n = scale.n;
    const double error = JudgedError(*c);
    c->delta_bic = n * std::log(std::pow(error, 2) / std::pow(scale.error_baseline, 2)) + c->num_parameters * std::log(n);
    c->helps = c->delta_bic < 0 && error < (1 - options.min_relative_improvement) * scale.error_baseline;
  };
  auto full_scale = [&] { return Scale{static_cast<double>(comparison.num_residuals()), summary.error_baseline}; };
  auto score = [&](const EffectFit& f, Candidate* c, bool refined, const compare::Comparison& on, const Scale& scale) {
    c->effect = f.effect;
    c->with = f.effect.ToString();
    c->error_after = f.summary.final_error;
    c->floor_ratio = FloorRatio(on, summary.baseline, f.spec, f.effect);
    // Fitted parameters, and held ones set from the data (an estimated turn); held zeros add nothing.
    c->num_parameters = 0;
    for (const auto& p : model::FindEffectDefinition(f.effect.name).parameters) {
      const bool held = std::find(c->held_parameters.begin(), c->held_parameters.end(), p.name) != c->held_parameters.end();
      c->num_parameters += !held || f.effect.parameters.at(p.name) != 0.0;
    }
    rescore(c, scale);
    c->refined = refined;
    c->model_parameters.clear();
    for (const auto& p : f.summary.parameters) c->model_parameters[p.name] = p.value;
  };
  // task(i) for i in [0, count) on the common pool: each worker takes the next index when it is done
  // with one (candidates' costs differ by 10x); on the pool's threads, the FRF evaluations inside run
  // on their caller's thread.
  auto for_each_candidate = [&](size_t count, const std::function<void(size_t)>& task) {
    std::atomic<size_t> next{0};
    const int threads = options.num_threads > 0 ? options.num_threads : MaxThreads();
    ParallelFor(std::min<int>(threads, static_cast<int>(count)), [&](int, int) {
      for (size_t i = next++; i < count; i = next++) task(i);
    });
  };
  // Fits every effect of `list` with the model's parameters against `on`, each from its start (the
  // baseline's parameters where it names none).
  // The screening holds the parameters of the effects already in the model where the baseline fitted
  // them (DiagnoseOptions::refit_effects frees them from the refinement on): their columns are
  // differenced, and with a joint offset in the model a second round's screening took twice the first's.
  const std::vector<std::string>& screening_params = options.hold_effects_in_screening ? options.params : params;
  auto run = [&](const std::vector<Try>& list, int iterations, bool refined, bool probe_basins,
                 const compare::Comparison& on, const Scale& scale, double trust_region_radius = EffectFitOptions{}.initial_trust_region_radius,
                 int stall_iterations = 0) {
    const std::vector<std::string>& fitted = refined ? params : screening_params;
    std::vector<Candidate> out(list.size());
    std::vector<char> ok(list.size(), 0);  // not vector<bool>: its elements share words, written from several threads
    for_each_candidate(list.size(), [&](size_t i) {
      try {
        model::ModelSpec base = summary.baseline;
        for (const auto& p : model::ListParameters(base)) {
          auto it = list[i].start.find(p.name);
          if (it != list[i].start.end()) model::SetParameter(base, p, it->second);
        }
        EffectFitOptions fit_options;
        fit_options.max_iterations = iterations;
        fit_options.probe_basins = probe_basins;
        fit_options.stall_iterations = stall_iterations;
        fit_options.held = list[i].held;
        // A sensor-geometry correction starts from the turn the other channels see (EstimateChannelTurns),
        // near its value: on one case a 15-degree turn's fit ended at 5x the floor with long first steps,
        // at 1.2x with short ones.
        fit_options.initial_trust_region_radius = list[i].effect.name == "sensor-geometry" || list[i].short_steps
                                                      ? std::min(trust_region_radius, kPolishTrustRegionRadius)
                                                      : trust_region_radius;
        EffectFit f = FitEffect(base, on, list[i].effect, fitted, fit_options);
        if (f.summary.status == fit::FitStatus::kFailed || !std::isfinite(f.summary.final_error)) return;
        out[i].held_parameters = list[i].held;
        score(f, &out[i], refined, on, scale);
        ok[i] = true;
      } catch (const std::exception&) {
      }
    });
    std::vector<Candidate> kept;
    for (size_t i = 0; i < out.size(); ++i) {
      if (ok[i]) kept.push_back(out[i]);
    }
    return kept;
  };
  // Every candidate of `list` scored on `on` as it was fitted (on another grid); those that cannot be
  // evaluated there are dropped.
  auto score_on = [&](const std::vector<Candidate>& list, const compare::Comparison& on, const Scale& scale) {
    std::vector<Candidate> out = list;
    std::vector<char> ok(out.size(), 0);  // not vector<bool>: its elements share words, written from several threads
    for_each_candidate(out.size(), [&](size_t i) {
      try {
        const model::ModelSpec with = ApplyCandidate(summary, out[i]);
        out[i].error_after = on.Error(with);
        out[i].floor_ratio = FloorRatio(on, summary.baseline, with, out[i].effect);
        ok[i] = std::isfinite(out[i].error_after);
      } catch (const std::exception&) {
      }
    });
    std::vector<Candidate> scored;
    for (size_t i = 0; i < out.size(); ++i) {
      if (!ok[i]) continue;
      scored.push_back(out[i]);
      rescore(&scored.back(), scale);
    }
    return scored;
  };
  const Scale screen_scale{static_cast<double>(screen.num_residuals()), screen.Error(summary.baseline)};
  // Near the floor, the profile of every servo's k on the baseline (kServoProfileZeta, header); the
  // location whose profile goes lowest is refined from its lowest minima whatever its screening. Far
  // from the floor the scan on the model as given stands for it (ScanServoStiffness).
  if (!far_from_floor && !servos.empty()) {
    const size_t steps = static_cast<size_t>(kServoProfileLastPower - kServoProfileFirstPower + 1);
    std::vector<double> errors(servos.size() * steps, std::numeric_limits<double>::infinity());
    std::vector<EffectFit> fits(errors.size());
    for_each_candidate(errors.size(), [&](size_t i) {
      model::Effect e = servos[i / steps];
      e.parameters["k"] *= std::pow(2.0, kServoProfileFirstPower + static_cast<int>(i % steps));
      e.parameters["zeta"] = kServoProfileZeta;
      EffectFitOptions fit_options;
      fit_options.max_iterations = kServoProfileIterations;
      fit_options.held = {"k"};
      fit_options.initial_trust_region_radius = kPolishTrustRegionRadius;
      try {
        fits[i] = FitEffect(summary.baseline, screen, e, screening_params, fit_options);
        if (fits[i].summary.status != fit::FitStatus::kFailed && std::isfinite(fits[i].summary.final_error)) {
          errors[i] = fits[i].summary.final_error;
        }
      } catch (const std::exception&) {
      }
    });
    const size_t lowest = static_cast<size_t>(std::min_element(errors.begin(), errors.end()) - errors.begin());
    const size_t first = lowest - lowest % steps;  // the lowest location's profile
    if (std::isfinite(errors[lowest])) {
      say(Format("profiles of %.0f servo stiffnesses: the lowest ", static_cast<double>(servos.size())) + servos[lowest / steps].location +
          Format(" at k %.3g, %.3f of the baseline", fits[lowest].effect.parameters.at("k"), errors[lowest] / screen_scale.error_baseline));
    }
    const std::vector<double> profile(errors.begin() + static_cast<long>(first), errors.begin() + static_cast<long>(first + steps));
    for (size_t j : ServoProfileStarts(profile, screen_scale.error_baseline, kServoProfileStarts)) {
      const EffectFit& f = fits[first + j];
      std::map<std::string, double> start;
      for (const auto& p : f.summary.parameters) start[p.name] = p.value;
      scan_starts.push_back({f.effect, start, {}, true});
    }
  }
  if (screening_comparison || thinned_comparison) {
    say(Format("screening %.0f candidates on %.0f of the %.0f frequencies", static_cast<double>(tries.size()),
               screen.num_frequencies(), comparison.num_frequencies()));
  } else {
    say(Format("screening %.0f candidates", static_cast<double>(tries.size())));
  }
  std::vector<Candidate> screened = run(tries, options.screening_iterations, false, false, screen, screen_scale);
  SortByJudgedError(&screened);
  // Keep the best start per (effect, location, held parameters), then refine the most promising ones.
  std::vector<Candidate> unique;
  for (const auto& c : screened) {
    bool seen = false;
    for (const auto& u : unique) seen = seen || SameCandidate(u, c);
    if (!seen) unique.push_back(c);
  }
  // Screened on a coarser grid: ranked for the refinement by their errors on the search grid, which the
  // refinement compares its fits with (MergeBetter).
  if (screening_comparison) {
    unique = score_on(unique, search, search_scale);
    SortByJudgedError(&unique);
  }
  // The model without a new effect, refitted from where a leader's fit has moved its parameters
  // (DiagnoseOptions::stop_at_times_floor): when that is within the threshold, the search stops with it
  // as the baseline and no effect is sought. A fit with an effect carries the model's parameters out of
  // a local minimum that the baseline's own fit and its probes stop in (seed 79003 of eval_loop: the
  // loop's refit with its second effect at 2.64x the floor, this refit from the screening's leader at
  // 1.02x, where the whole diagnosis ended 21 s later with the same model).
  auto baseline_with = [&](const std::map<std::string, double>& values) {
    model::ModelSpec with = summary.baseline;
    for (const auto& p : model_params) {
      const auto it = values.find(p.name);
      if (it != values.end()) model::SetParameter(with, p, it->second);
    }
    return with;
  };
  // The model without a new effect refitted from `*spec`, in place: from its parameters as they are, or
  // (starts > 1) from them and random draws around them (fit::FitOptions::num_starts). Its error on all
  // frequencies; +infinity when the fit fails.
  auto refit_baseline = [&](model::ModelSpec* spec, int starts) {
    fit::FitOptions fo;
    fo.max_iterations = options.baseline_iterations;
    fo.num_starts = starts;
    fo.stall_iterations = options.stall_iterations;
    try {
      // Several starts, with their basin probes, on the search grid; the best finished on all
      // frequencies: at 1000 frequencies the three starts on all of them took 2-4 s of a diagnosis.
      if (starts > 1 && thinned_comparison) {
        fit::FitModel(*spec, search, model_params, fo);
        fo.num_starts = 1;
        fo.max_probe_rounds = 0;
      }
      fit::FitModel(*spec, comparison, model_params, fo);
      return comparison.Error(*spec);
    } catch (const std::exception&) {
      return std::numeric_limits<double>::infinity();
    }
  };
  auto stop_at_floor = [&](const char* stage) {
    // Only a baseline above that: at the floor the search is asked for (the loop's round after a hold,
    // LoopOptions::hold_rounds, runs even there). And not one far from the floor (far_times_floor): its
    // parameters have bent to mimic what is missing, and an effect is, not a better minimum. Its refits
    // cost 1.6 s of a 40 s diagnosis (79202 of eval_loop, 5.35x the floor after both stages).
    if (!(options.stop_at_times_floor > 0) || !summary.noise_floor.known || !(summary.noise_floor.floor > 0) ||
        model_params.empty() || far_from_floor ||
        !(summary.error_baseline > options.stop_at_times_floor * summary.noise_floor.floor)) {
      return false;
    }
    const double begun = Clock();
    const size_t count = std::min<size_t>(unique.size(), static_cast<size_t>(std::max(options.num_stop_starts, 0)));
    if (count == 0) return false;
    std::vector<model::ModelSpec> refits(count);
    std::vector<double> errors(count, std::numeric_limits<double>::infinity());
    for_each_candidate(count, [&](size_t i) {
      refits[i] = baseline_with(unique[i].model_parameters);
      errors[i] = refit_baseline(&refits[i], 1);
    });
    const size_t best = static_cast<size_t>(std::min_element(errors.begin(), errors.end()) - errors.begin());
    if (!(errors[best] < summary.error_baseline) || !(errors[best] <= options.stop_at_times_floor * summary.noise_floor.floor)) {
      say(Format("the model without a new effect refitted from the best %.0f after the ", static_cast<double>(count)) + stage +
          Format(": %.2f x the noise floor at best (%.1f s); the search goes on", errors[best] / summary.noise_floor.floor,
                 Clock() - begun));
      return false;
    }
    say("baseline refitted from the model parameters of " + unique[best].with + " after the " + stage +
        Format(": error %.4f -> %.4f, %.2f x the noise floor", summary.error_baseline, errors[best], errors[best] / summary.noise_floor.floor) +
        Format(" (%.1f s): no effect sought", Clock() - begun));
    summary.baseline = refits[best];
    summary.error_baseline = errors[best];
    summary.stopped_at_floor = stage;
    // Listed as fitted, scored on all frequencies against the new baseline, and not claimed.
    unique = score_on(unique, comparison, full_scale());
    SortByBic(&unique);
    for (auto& c : unique) c.helps = false;
    return true;
  };
  // Refinement continues from where screening stopped: the effect's and the model's parameters. One
  // effect takes at most kMaxRefinedPerEffect of the places: the 22 channels' sensor-geometry
  // corrections, each a little better than the baseline, filled the ten and left out a joint offset in
  // the hexapod that was the truth (seed 1002).
  auto refine_the_best = [&] {
    std::vector<Try> refine = Continue(unique, options.num_refined, kMaxRefinedPerEffect);
    say(Format("refining the best %.0f", static_cast<double>(refine.size())) +
        (scan_starts.empty() ? "" : Format(" and %.0f servo stiffnesses and couplings from their scans", static_cast<double>(scan_starts.size()))));
    refine.insert(refine.end(), scan_starts.begin(), scan_starts.end());
    MergeBetter(run(refine, options.refine_iterations, true, true, search, search_scale), &unique);
  };
  // A second start for the leaders: the model's parameters as given, with the effect as fitted. The
  // baseline's stiffnesses have bent to mimic the missing effect (a delay's phase, a payload's mass)
  // and can hold the fit with the effect in a local minimum the model as given is not in.
  // A leader already within kSecondStartSkipTimesFloor of the search grid's noise floor is not
  // started again: a second start could lower its error by noise only.
  auto start_leaders_from_the_model_as_given = [&] {
    std::vector<Try> leaders = Continue(unique, options.num_second_starts);
    const compare::NoiseFloor search_floor = search.CalcNoiseFloor();
    size_t at_floor = 0;
    if (search_floor.known && search_floor.floor > 0) {
      std::vector<Try> kept;
      for (size_t i = 0; i < leaders.size(); ++i) {
        if (!(JudgedError(unique[i]) <= kSecondStartSkipTimesFloor * search_floor.floor)) kept.push_back(leaders[i]);
      }
      at_floor = leaders.size() - kept.size();
      leaders = kept;
    }
    for (size_t i = 0, n = leaders.size(); i < n; ++i) {
      leaders[i].start = as_given;
      // A mass's height enters its rotary inertia as z^2: a fit from the wrong side of the host's centre
      // of mass stays there. Also started mirrored (a 9.5 kg payload 148 mm above the hexapod's centre
      // of mass, fitted at 3.7 kg 166 mm below it, 9x the floor; from +166 mm: 1.2x, seed 5006).
      const model::Effect e = leaders[i].effect;  // a copy: the push_back below may move leaders[i]
      if ((e.name == "payload" || e.name == "extra-body") && e.parameters.count("z") && e.parameters.at("z") != 0.0) {
        leaders.push_back(leaders[i]);
        leaders.back().effect.parameters["z"] = -e.parameters.at("z");
      }
    }
    say(Format("second start for the best %.0f", static_cast<double>(leaders.size())) +
        (at_floor ? Format(" (%.0f at the noise floor go without)", static_cast<double>(at_floor)) : ""));
    // Without basin probes: the start from the model as given is itself the way out of the baseline's
    // basin, and the probes after it took most of the step (a payload loop of the suite: 29.6 s of a
    // round's 41.7 s with them, 2.9 s without, the same candidate found). On the 24 cases of eval_loop's
    // seeds 35000 every outcome was the same without them, and the mean loop fell from 72 to 57 s with
    // one effect, from 149 to 116 s with two.
    if (!leaders.empty()) MergeBetter(run(leaders, options.refine_iterations, true, false, search, search_scale), &unique);
  };
  // The leaders fitted on to their optimum: the budgets above stop a slow fit short (a turned sensor's
  // correction with the stiffnesses: 0.109 after the rounds above, 0.038 converged, floor 0.036).
  auto fit_leaders_to_convergence = [&] {
    std::vector<Try> leaders = Continue(unique, options.num_polished);
    for (size_t i = 0, n = leaders.size(); i < n; ++i) {
      // An extra body's rigid limit is a payload: fitted too, with the body's mass and height. A payload
      // of 7.2 kg, 141 mm above the hexapod (seed 1028) lost to an extra body rigid in translation
      // (k 6.8e12 N/m, 1.16x the floor): the payload's own fits, from 1.5 kg at its host's centre of
      // mass, stopped at 7x the floor; from the extra body's mass and height it reached the floor.
      const auto& rigid_limit = model::FindEffectDefinition(leaders[i].effect.name).rigid_limit;
      if (rigid_limit) {
        const model::Effect limit = rigid_limit(leaders[i].effect);
        leaders.push_back({limit, leaders[i].start, {}});
        leaders.push_back({limit, as_given, {}});
      }
      // A coupling is also fitted as the effects that make it (model::EffectDefinition::mimicked_together_by:
      // a joint's stiffness centre off its origin), from what the leader's coupling makes of them, from the
      // leader's state and from the model as given. 82136 of eval_loop (rz's centre 100 mm high beside a
      // hexapod coupling, 150 Hz band): the offset's own starts at dz = +-0.1 m did not outlast the
      // screening, its best fit stayed at dz = 2 mm (0.0406), and rz's Dy-Rx coupling took its place at
      // 1.05x the floor (0.0351).
      const model::Effect leader = leaders[i].effect;  // a copy: the push_back below may move leaders[i]
      const std::string joint = model::LocationJoint(leader.location);
      for (const model::EffectDefinition& one : model::EffectCatalogue()) {
        if (!model::StandsFor(one, leader.name)) continue;
        if (!options.effects.empty() && std::find(options.effects.begin(), options.effects.end(), one.name) == options.effects.end()) continue;
        const std::vector<std::string> at = model::EffectLocations(summary.baseline, one.name);
        if (std::find(at.begin(), at.end(), joint) == at.end()) continue;
        // Nor where the model holds one already: its parameters are refitted with every candidate, and a
        // second one would be the same edit again (82236 of eval_loop: a coupling of the hexapod beside
        // the hexapod's offset).
        if (!model::AddsAnother(summary.baseline, one, joint)) continue;
        model::Effect made;
        try {  // on the model without the leader, at the leader's parameters
          made = {one.name, joint, one.from_mimics(baseline_with(unique[i].model_parameters), joint, {leader}), {}};
        } catch (const std::exception&) {
          continue;  // a joint the effect cannot take gets no such start
        }
        // A coupling the effect does not make (an offset makes none between two rotations) starts nothing.
        if (std::all_of(made.parameters.begin(), made.parameters.end(), [](const auto& p) { return p.second == 0.0; })) continue;
        leaders.push_back({made, leaders[i].start, {}});
        leaders.push_back({made, as_given, {}});
      }
      if (leaders[i].effect.name == "extra-body") {
        // Its rocking modes, like its translation, are found only from near their frequency: also
        // started with kr putting them at the centre of the band where the leader's own error is
        // largest (13008: a body at 246 Hz found with its mass and height, its rocking mode at 301 Hz
        // not, kr 24x too soft, 2.7x the floor, with 70 % of the error in 281-354 Hz).
        std::optional<double> hz;
        try {
          hz = WorstBandCentreHz(search, ApplyCandidate(summary, unique[i]));  // leaders[i] continues unique[i]
        } catch (const std::exception&) {
          // A leader whose model cannot be evaluated gets no such start.
        }
        auto add_rocking_start = [&](double rocking_hz) {
          Try rocking = leaders[i];
          model::SetExtraBodyRockingHz(&rocking.effect, rocking_hz);
          leaders.push_back(rocking);
        };
        if (hz) add_rocking_start(*hz);
        // And from the best rocking frequency of a scan across the band, the leader's other parameters
        // as fitted: the rocking modes' basin is a few % wide. 27007 (a 4 kg body at 72 Hz, rocking at
        // 88 Hz): fits started at 56-80 Hz ended at 56-81 Hz (1.30-1.40x the floor), from 88-120 Hz at
        // 88 Hz (1.03-1.06x); the scan from the 56 Hz fit has its minimum at 88 Hz. 23005 (rocking at
        // 116 Hz): only a start at 120 Hz reached it; the scan's minimum is at 116.5 Hz, 3 % wide.
        if (const auto scanned = ScanRockingHz(search, summary, unique[i])) add_rocking_start(*scanned);
      }
      leaders.push_back(leaders[i]);
      leaders.back().start = as_given;
    }
    say(Format("fitting the best %.0f to convergence (%.0f fits)", static_cast<double>(std::min<size_t>(unique.size(), options.num_polished)),
               static_cast<double>(leaders.size())));
    MergeBetter(run(leaders, options.polish_iterations, true, false, search, search_scale, kPolishTrustRegionRadius,
                    options.stall_iterations),
                &unique);
  };
  // After a search on a thinned grid: every candidate is scored on all frequencies as it was fitted,
  // and the leaders are finished there (their optimum moves a little with the grid).
  auto finish_leaders_on_all_frequencies = [&] {
    unique = score_on(unique, comparison, full_scale());
    SortByBic(&unique);
    const std::vector<Try> leaders = Continue(unique, options.num_finished);
    say(Format("finishing the best %.0f on all %.0f frequencies", static_cast<double>(leaders.size()),
               comparison.num_frequencies()));
    MergeBetter(run(leaders, options.finish_iterations, true, false, comparison, full_scale()), &unique);
  };
  // 3. Is the leader's effect needed? Its fit moved the model's own parameters too, and may have
  // carried them out of a local minimum the baseline fit stopped in. Refit the model without the
  // effect from the leader's parameters, and (first round) from the model as given with several starts
  // (DiagnoseOptions::refit_starts): when that lowers the baseline's error, the baseline was not at its
  // optimum; the candidates are scored again against the better baseline (an effect-free measurement
  // whose baseline fit stopped short otherwise credits the first effect that frees it).
  // A second round only when the better baseline puts another leader (or the same with other model
  // parameters) first: from the same start the refit reaches the same optimum again.
  auto refit_the_baseline_from_the_leader = [&] {
    std::map<std::string, double> refitted_from;
    for (int round = 0; round < 2 && !model_params.empty() && !unique.empty() && unique[0].helps; ++round) {
      if (round > 0 && unique[0].model_parameters == refitted_from) break;
      refitted_from = unique[0].model_parameters;
      struct Refit {
        model::ModelSpec spec;
        int starts = 1;
        std::string from;
        double error = std::numeric_limits<double>::infinity();
      };
      std::vector<Refit> refits(1);
      refits[0].spec = baseline_with(unique[0].model_parameters);
      refits[0].from = "the model parameters of " + unique[0].with;
      if (round == 0 && options.refit_starts > 1) refits.push_back({spec_as_given, options.refit_starts, "the model as given"});
      for_each_candidate(refits.size(), [&](size_t i) { refits[i].error = refit_baseline(&refits[i].spec, refits[i].starts); });
      const Refit& best = *std::min_element(refits.begin(), refits.end(), [](const Refit& a, const Refit& b) { return a.error < b.error; });
      if (!(best.error < summary.error_baseline)) break;
      say("baseline refitted from " + best.from + Format(": error %.4f -> %.4f", summary.error_baseline, best.error));
      summary.baseline = best.spec;
      summary.error_baseline = best.error;
      for (auto& c : unique) rescore(&c, full_scale());
      SortByBic(&unique);
    }
  };
  bool stopped = stop_at_floor("screening");
  if (!stopped) {
    refine_the_best();
    stopped = stop_at_floor("refinement");
  }
  if (!stopped) {
    start_leaders_from_the_model_as_given();
    fit_leaders_to_convergence();
    if (thinned_comparison) finish_leaders_on_all_frequencies();
    refit_the_baseline_from_the_leader();
  }
  // Physically absurd fits are not claimed (they are kept in the list, marked, after those that help).
  const std::vector<measurement::ChannelDirectionEstimate> directions =
      summary.baseline.geometry_corrections.empty()
          ? declared_directions
          : ChannelDirectionsUnder(summary.baseline.geometry_corrections, measurement, comparison.frame_origin_W(),
                                   options.comparison.fmin_hz, options.comparison.fmax_hz);
  for (auto& c : unique) {
    c.implausible = ImplausibleBecause(summary.baseline, c.effect, comparison.frequency_hz()(0), directions);
    if (!c.implausible.empty()) c.helps = false;
  }
  std::stable_partition(unique.begin(), unique.end(), [](const Candidate& c) { return c.helps; });
  NameRigidLimitFirst(&unique);
  summary.candidates = unique;
  summary.effect_found = !summary.candidates.empty() && summary.candidates[0].helps;

  // 4. Where.
  compare::ComparisonResult result = comparison.Evaluate(summary.baseline);
  SortWorst(result, 5, 8, &summary.worst_bands, &summary.worst_elements);
  summary.worst_channels = WorstChannels(summary.baseline, measurement, options.comparison, 6);
  std::optional<compare::ModePairing> pairing;
  try {
    pairing = compare::PairModes(comparison, result.model, summary.baseline);
    for (const auto& p : pairing->pairs) {
      if (std::abs(p.frequency_error) > 0.03) {
        summary.mispaired_modes.push_back({pairing->measured[p.measured].frequency_hz, pairing->model[p.model].frequency_hz,
                                           p.mac, pairing->model[p.model].dominant_dof});
      }
    }
    for (int m : pairing->unpaired_measured) summary.unpaired_measured_hz.push_back(pairing->measured[m].frequency_hz);
    for (int m : pairing->unpaired_model) {
      summary.unpaired_model.push_back({pairing->model[m].frequency_hz, pairing->model[m].dominant_dof});
    }
  } catch (const std::exception&) {
  }

  // The leaders in words, with the measured mode each moves most against the baseline's pairing.
  for_each_candidate(std::min<size_t>(summary.candidates.size(), 5), [&](size_t i) {
    Candidate& c = summary.candidates[i];
    c.explanation = Explain(c);
    if (!pairing) return;
    try {
      c.explanation += ModeSentence(comparison, *pairing, ApplyCandidate(summary, c));
    } catch (const std::exception&) {
    }
  });

  // 5. The verdict, against the noise floor when the measurement's coherence gives it.
  const compare::NoiseFloor& floor = summary.noise_floor;
  const bool floor_known = floor.known && floor.floor > 0.0;
  auto times_floor = [&](double error) { return floor_known ? error / floor.floor : std::numeric_limits<double>::quiet_NaN(); };
  // Where the remaining error sits, in words: the worst bands and elements, and the raw channels that
  // stand out.
  auto where_words = [&] { return WhereWords(summary.worst_bands, summary.worst_elements, summary.worst_channels); };
  std::ostringstream verdict;
  if (summary.effect_found) {
    const Candidate& best = summary.candidates[0];
    verdict << "Most likely missing: " << best.effect.name << " at " << best.effect.location << ": " << best.explanation
            << Format(". Adding it lowers the error from %.4f to %.4f. Add it with --with \"", summary.error_baseline, best.error_after)
            << best.with << "\" and refit.";
    if (floor_known && times_floor(best.error_after) <= kDoneTimesFloor) {
      verdict << Format(" With it the model is at the noise floor (%.2f x %.4f): done after this refit.", times_floor(best.error_after),
                        floor.floor);
    } else if (floor_known && times_floor(best.error_after) > kOutsideTimesFloor) {
      verdict << Format(" Even with it the error is %.1f x the noise floor %.4f: something outside the catalogue is still missing",
                        times_floor(best.error_after), floor.floor)
              << " (the baseline's error is in " << where_words() << ").";
    }
  } else if (!summary.stopped_at_floor.empty()) {
    verdict << "Done: refitted from where the " << summary.stopped_at_floor
            << Format("'s fits with the candidates left its parameters, the model without a new effect reaches %.4f, %.2f x the "
                      "noise floor %.4f; no effect was sought further, and nothing is left to explain.",
                      summary.error_baseline, times_floor(summary.error_baseline), floor.floor);
  } else if (floor_known && times_floor(summary.error_baseline) <= kDoneTimesFloor) {
    verdict << Format("Done: the model's error %.4f is %.2f x the noise floor %.4f that the measurement's coherence gives; no "
                      "effect of the catalogue lowers it by a share that counts, and nothing is left to explain.",
                      summary.error_baseline, times_floor(summary.error_baseline), floor.floor);
  } else if (floor_known && times_floor(summary.error_baseline) > kOutsideTimesFloor) {
    verdict << FormatText("Something outside the catalogue is still missing: the error %.4f after fitting the model's parameters is "
                      "%.1f x the noise floor %.4f, and no effect of the catalogue lowers it by %.0f %% with a better "
                      "information criterion",
                      summary.error_baseline, times_floor(summary.error_baseline), floor.floor, 100 * options.min_relative_improvement);
    if (!summary.candidates.empty() && !summary.candidates[0].implausible.empty()) {
      verdict << " (the best fit, " << summary.candidates[0].with << ", is not claimed: " << summary.candidates[0].implausible << ")";
    }
    verdict << ". It is in " << where_words() << ".";
    if (!summary.inconsistent_channels.empty() && summary.rigid_residual_share > 0.2) {
      verdict << " Channel " << summary.inconsistent_channels[0].channel
              << Format(" does not move rigidly with the others (%.0f %% of its energy near %.0f Hz): check it first.",
                        100 * summary.inconsistent_channels[0].share, summary.inconsistent_channels[0].band_hz);
    }
  } else {
    verdict << Format("No effect of the catalogue explains the remaining error (%.4f after fitting the model's parameters)",
                      summary.error_baseline)
            << ": none lowers it by " << Format("%.0f %%", 100 * options.min_relative_improvement)
            << " with a better information criterion.";
    if (floor_known) {
      verdict << Format(" The error is %.2f x the noise floor %.4f: close to it, but not at it; see where it is below.",
                        times_floor(summary.error_baseline), floor.floor);
    } else {
      verdict << " The remaining error is measurement noise or something the catalogue does not hold (the measurement has "
                 "no coherence, so its noise floor is unknown); see where it is below.";
    }
  }
  summary.verdict = verdict.str();
  summary.time_s = Clock() - start;
  return summary;
}

void NameRigidLimitFirst(std::vector<Candidate>* candidates) {
  if (candidates->empty() || !(*candidates)[0].helps) return;
  const Candidate& leader = (*candidates)[0];
  const auto& rigid_limit = model::FindEffectDefinition(leader.effect.name).rigid_limit;
  if (!rigid_limit) return;
  const std::string limit = rigid_limit(leader.effect).name;
  for (size_t j = 1; j < candidates->size(); ++j) {
    const Candidate& c = (*candidates)[j];
    if (c.helps && c.effect.name == limit && c.effect.location == leader.effect.location &&
        c.error_after <= (1 + kRigidLimitTolerance) * leader.error_after) {
      std::rotate(candidates->begin(), candidates->begin() + j, candidates->begin() + j + 1);
      return;
    }
  }
}

model::ModelSpec ApplyCandidate(const DiagnoseSummary& summary, const Candidate& candidate) {
  model::ModelSpec with = summary.baseline;
  model::ApplyEffect(with, candidate.effect);
  for (const auto& p : model::ListParameters(summary.baseline)) {
    auto it = candidate.model_parameters.find(p.name);
    if (it != candidate.model_parameters.end()) model::SetParameter(with, p, it->second);
  }
  return with;
}

std::vector<double> ScanErrors(const compare::Comparison& comparison, const std::vector<double>& grid,
                               const std::function<model::ModelSpec(double x)>& model_at) {
  std::vector<double> errors(grid.size(), std::numeric_limits<double>::infinity());
  std::vector<std::optional<model::ModelSpec>> specs(grid.size());
  ParallelFor(static_cast<int>(grid.size()), [&](int k, int) {
    try {
      specs[static_cast<size_t>(k)] = model_at(grid[static_cast<size_t>(k)]);
    } catch (const std::exception&) {
      // A stiffness the model cannot take: left out of the scan.
    }
  });
  // The models of a scan differ in one effect parameter: most of them only in a spring's or a
  // coupling's terms, which one set-up of the grid's middle model serves (ErrorsOfStiffnessVariants).
  std::vector<model::ModelSpec> built;
  std::vector<size_t> index;
  for (size_t k = 0; k < specs.size(); ++k) {
    if (!specs[k]) continue;
    built.push_back(std::move(*specs[k]));
    index.push_back(k);
  }
  const std::vector<double> built_errors = compare::ErrorsOfStiffnessVariants(comparison, built);
  for (size_t i = 0; i < index.size(); ++i) errors[index[i]] = built_errors[i];
  return errors;
}

std::optional<ScanMinimum> ScanGrid(const compare::Comparison& comparison, const std::vector<double>& grid,
                                    const std::function<model::ModelSpec(double x)>& model_at) {
  if (grid.empty()) return std::nullopt;
  const std::vector<double> errors = ScanErrors(comparison, grid, model_at);
  const size_t best = static_cast<size_t>(std::min_element(errors.begin(), errors.end()) - errors.begin());
  if (!std::isfinite(errors[best])) return std::nullopt;
  return ScanMinimum{grid[best], errors[best]};
}

namespace {
/// The points from `from` to `to` in relative steps `step` (empty unless 0 < from <= to and step > 0).
std::vector<double> LogGrid(double from, double to, double step) {
  std::vector<double> grid;
  if (!(from > 0) || !(to >= from) || !(step > 0)) return grid;
  for (double x = from; x <= to; x *= 1 + step) grid.push_back(x);
  return grid;
}
}  // namespace

std::optional<ScanMinimum> ScanLogGrid(const compare::Comparison& comparison, double from, double to, double step,
                                       const std::function<model::ModelSpec(double x)>& model_at) {
  return ScanGrid(comparison, LogGrid(from, to, step), model_at);
}

std::optional<ScanMinimum> ScanCouplingStiffness(const compare::Comparison& comparison, const model::ModelSpec& spec,
                                                 const model::Effect& coupling) {
  if (coupling.name != "coupled-stiffness") return std::nullopt;
  const model::EffectParameterRange range = model::EffectRange(spec, coupling, "k");
  if (!std::isfinite(range.lower) || !std::isfinite(range.upper) || !(range.upper > range.lower)) return std::nullopt;
  std::vector<double> grid;
  for (int i = 0; i <= kCouplingScanSteps; ++i) {
    grid.push_back(range.lower + (range.upper - range.lower) * i / kCouplingScanSteps);
  }
  return ScanGrid(comparison, grid, [&](double k) {
    model::Effect e = coupling;
    e.parameters["k"] = k;
    model::ModelSpec with = spec;
    model::ApplyEffect(with, e);
    return with;
  });
}

std::optional<size_t> BandScanPick(const std::vector<double>& errors) {
  if (errors.empty()) return std::nullopt;
  const size_t lowest = static_cast<size_t>(std::min_element(errors.begin(), errors.end()) - errors.begin());
  if (!std::isfinite(errors[lowest])) return std::nullopt;
  if (lowest != 0 && lowest + 1 != errors.size()) return lowest;
  // At an end of the band the mode has left it: the deepest dip inside the band instead, by its
  // prominence (the lower of the highest errors on either side before a point lower than the dip).
  std::optional<size_t> pick;
  double pick_depth = 0;
  for (size_t i = 1; i + 1 < errors.size(); ++i) {
    if (!(errors[i] < errors[i - 1] && errors[i] <= errors[i + 1])) continue;
    double left = errors[i], right = errors[i];
    for (size_t j = i; j-- > 0 && !(errors[j] < errors[i]);) left = std::max(left, errors[j]);
    for (size_t j = i + 1; j < errors.size() && !(errors[j] < errors[i]); ++j) right = std::max(right, errors[j]);
    const double depth = std::min(left, right) - errors[i];
    if (std::isfinite(depth) && depth > pick_depth) {
      pick = i;
      pick_depth = depth;
    }
  }
  return pick ? pick : std::optional<size_t>(lowest);
}

std::optional<double> ScanBandHz(const compare::Comparison& comparison,
                                 const std::function<model::ModelSpec(double hz)>& model_at) {
  const Eigen::VectorXd& f = comparison.frequency_hz();
  if (f.size() < 2) return std::nullopt;
  const std::vector<double> grid = LogGrid(f(0), f(f.size() - 1), kModeScanStep);
  const std::optional<size_t> pick = BandScanPick(ScanErrors(comparison, grid, model_at));
  if (!pick) return std::nullopt;
  return grid[*pick];
}

std::optional<double> ScanServoStiffness(const compare::Comparison& comparison, const model::ModelSpec& spec,
                                         const model::Effect& servo) {
  if (servo.name != "servo-stiffness") return std::nullopt;
  const double k = servo.parameters.at("k");
  const auto best = ScanLogGrid(comparison, k / 100, k * 100, 2 * kModeScanStep, [&](double x) {
    model::Effect e = servo;
    e.parameters["k"] = x;
    model::ModelSpec with = spec;
    model::ApplyEffect(with, e);
    return with;
  });
  if (!best) return std::nullopt;
  double error = 0;
  try {
    error = comparison.Error(spec);
  } catch (const InputError&) {
    return std::nullopt;  // `spec` itself is not a model (the effects it holds on the stiffnesses it has)
  }
  if (!(best->error <= (1 - kServoScanMinDrop) * error)) return std::nullopt;
  return best->at;
}

std::vector<size_t> ServoProfileStarts(const std::vector<double>& errors, double baseline_error, size_t max_starts) {
  std::vector<size_t> minima;
  for (size_t i = 0; i < errors.size(); ++i) {
    const bool below_left = i == 0 || errors[i] <= errors[i - 1];
    const bool below_right = i + 1 == errors.size() || errors[i] <= errors[i + 1];
    if (std::isfinite(errors[i]) && below_left && below_right) minima.push_back(i);
  }
  std::sort(minima.begin(), minima.end(), [&](size_t a, size_t b) { return errors[a] < errors[b]; });
  if (minima.empty() || !(errors[minima[0]] <= (1 - kServoScanMinDrop) * baseline_error)) return {};
  if (minima.size() > max_starts) minima.resize(max_starts);
  return minima;
}

std::optional<double> ScanRockingHz(const compare::Comparison& comparison, const DiagnoseSummary& summary,
                                    const Candidate& candidate) {
  const model::Effect& e = candidate.effect;
  if (e.name != "extra-body") return std::nullopt;
  const double own_hz = model::FindEffectDefinition(e.name).local_modes_hz(e)[1];
  const std::optional<double> best = ScanBandHz(comparison, [&](double hz) {
    Candidate c = candidate;
    model::SetExtraBodyRockingHz(&c.effect, hz);
    return ApplyCandidate(summary, c);
  });
  if (!best || std::abs(*best / own_hz - 1) <= 2 * kModeScanStep) return std::nullopt;
  return best;
}

std::string DiagnoseSummary::BriefReport(int max_candidates) const {
  std::ostringstream out;
  out << Format("Error: %.4f as given, %.4f after fitting the model's own parameters (baseline)\n", error_initial, error_baseline);
  out << compare::NoiseFloorLine(error_baseline, noise_floor) << "\n";
  out << "Candidates (ranked by delta BIC against the baseline; < 0 supports the effect):\n";
  out << "  #  effect@location                          error    dBIC       helps  fitted\n";
  for (int i = 0; i < static_cast<int>(candidates.size()) && i < max_candidates; ++i) {
    const Candidate& c = candidates[i];
    std::string params;
    for (const auto& [k, v] : c.effect.parameters) params += (params.empty() ? "" : ", ") + k + "=" + Format("%.3g", v);
    char line[512];
    std::snprintf(line, sizeof line, "  %-2d %-40s %7.4f  %9.1f  %-5s  %s\n", i + 1,
                  (c.effect.name + "@" + c.effect.location).c_str(), c.error_after, c.delta_bic, c.helps ? "yes" : "no",
                  params.c_str());
    out << line;
  }
  out << "\n" << verdict << "\n";
  for (int i = 0; i < static_cast<int>(candidates.size()) && i < 3; ++i) {
    if (!candidates[i].explanation.empty()) out << "  " << i + 1 << ". " << candidates[i].explanation << "\n";
  }
  out << "\nWhere the baseline's error is:\n";
  for (const auto& b : worst_bands) {
    out << Format("  band %.1f-%.1f Hz", b.band.low_hz, b.band.high_hz) << Format(": error %.4f, %.0f %% of the total\n", b.error, 100 * b.share);
  }
  for (const auto& e : worst_elements) {
    out << "  element " << e.name << Format(": error %.4f, %.0f %% of the total\n", e.error, 100 * e.share);
  }
  if (!worst_channels.empty()) {
    out << Format("  raw channels (median error of their elements; the worst at %.2f x the median channel's):", worst_channels[0].times_median);
    for (const auto& c : worst_channels) {
      out << " " << c.name << (std::isfinite(c.times_floor) ? Format(" %.2f x the floor", c.times_floor) : Format(" %.4f", c.error))
          << (&c == &worst_channels.back() ? "" : ",");
    }
    out << "\n";
  }
  for (const auto& m : mispaired_modes) {
    out << Format("  measured mode at %.1f Hz is at %.1f Hz in the model (MAC %.2f)", m.measured_hz, m.model_hz, m.mac)
        << "; its strain energy is in " << m.dominant_dof << "\n";
  }
  for (double f : unpaired_measured_hz) out << Format("  measured mode at %.1f Hz has no model partner\n", f);
  for (const auto& [f, dof] : unpaired_model) out << Format("  model mode at %.1f Hz (", f) << dof << ") has no measured partner\n";
  if (std::isfinite(rigid_residual_share)) {
    out << Format("  rigid-body consistency of the channels: at most %.1f %% of a band's data energy is not rigid motion",
                  100 * rigid_residual_share);
    if (!inconsistent_channels.empty()) out << "; least consistent:";
    for (const auto& c : inconsistent_channels) {
      out << " " << c.channel << Format(" (%.1f %%, most near %.0f Hz)", 100 * c.share, c.band_hz);
    }
    out << "\n";
  }
  for (const auto& t : turned_channels) {
    out << "  channel " << t.channel << Format(" points %.1f deg off its declared direction, as the other channels' rigid motion sees it", t.angle_deg)
        << Format(" (%.2f %% of its energy unexplained by that direction)\n", 100 * t.residual_share);
  }
  return out.str();
}

}  // namespace stagefit::diagnose
