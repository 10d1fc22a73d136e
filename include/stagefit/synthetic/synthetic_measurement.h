#pragma once
// Synthetic hammer-test measurements with known truth, for tests, benchmarks, the shipped example data
// and the evaluation of `diagnose` on data with hidden effects.
//
// The FRFs come from a deliberately independent, brute-force code path that shares nothing with the
// model assembly and the response layer under test: ABSOLUTE body coordinates (6 per body at its CoM),
// every joint's relative motion built directly from both bodies' motions, imposed DoF and rigid
// attachments eliminated by an SVD null-space basis of the constraint rows, and a dense complex solve
// per frequency. Hidden effects are written here as edits of the truth model's bodies and joints (a
// payload is a separate body rigidly attached by a joint whose six DoF are all imposed), not through
// the effects catalogue.

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

#include "stagefit/measurement/frf_data.h"
#include "stagefit/measurement/hammer_estimation.h"
#include "stagefit/model/model_spec.h"

namespace stagefit::synthetic {

/// Exact FRFs of `truth` between force inputs at `impacts` and translation outputs at `sensors`
/// (channel geometry in W, on named bodies), by the brute-force path. The truth's loss factors,
/// gyroscopic spin and acquisition delay are included. Returns FrfData with the given channels.
/// Throws InputError for unknown bodies.
measurement::FrfData CalcBruteForceFrf(const model::ModelSpec& truth,
                                       const std::vector<measurement::ChannelGeometry>& sensors,
                                       const std::vector<measurement::ChannelGeometry>& impacts,
                                       const Eigen::VectorXd& frequency_hz, measurement::FrfQuantity quantity);

/// Measurement noise: each averaged FRF point gets relative noise (complex Gaussian, standard deviation
/// `relative` of |H|) plus absolute noise (standard deviation `absolute` times the RMS of |H| of that
/// element over the band). The absolute part makes the coherence drop at antiresonances, as in a real
/// hammer test. Coherence is set to |H|^2 / (|H|^2 + sigma^2) with sigma^2 the point's total noise
/// variance (the coherence of an H1 estimate whose output noise has that variance).
struct NoiseOptions {
  double relative = 0.01;
  double absolute = 0.01;
  uint64_t seed = 1;
  /// The absolute part per output channel instead of per element: `absolute` times the RMS of |H| over
  /// every input of the channel and the band. A sensor's noise floor does not know which impact excited
  /// it, so an element that a symmetry makes (nearly) zero gets its channel's noise, not none.
  bool per_channel = false;
};
void AddNoise(measurement::FrfData& data, const NoiseOptions& options);

/// The micro-station's compliance-test geometry (SPEC §2) as channels: 12 accelerometer channels and
/// 10 hammer impacts on `body`, positions relative to the frame origin `p_WXo`.
std::vector<measurement::ChannelGeometry> ComplianceTestSensors(const std::string& body, const Eigen::Vector3d& p_WXo);
std::vector<measurement::ChannelGeometry> ComplianceTestImpacts(const std::string& body, const Eigen::Vector3d& p_WXo);

/// A whole-stack modal test (seed Figure 2.3): three triaxial accelerometers on every body of `spec`
/// (channels "<body>_a1x" ... "<body>_a3z", in a triangle 0.2 m around the body's centre of mass, 50 mm
/// above it, so that each body's six DoF are observed), and five hammer impacts on the translation
/// stage `hit_body` ("h1" ... "h5": x, y, z at one corner, y and z at the opposite one).
std::vector<measurement::ChannelGeometry> WholeStackSensors(const model::ModelSpec& spec);
std::vector<measurement::ChannelGeometry> WholeStackImpacts(const model::ModelSpec& spec, const std::string& hit_body = "ty");

/// Which test a synthetic measurement imitates.
enum class TestLayout {
  kTopPlate,    ///< the 12x10 compliance test of the top plate (SPEC §2)
  kWholeStack,  ///< accelerometers on every body, hammer on the translation stage (WholeStackSensors)
};

/// Log-spaced frequencies, Hz.
Eigen::VectorXd LogFrequencies(double fmin_hz, double fmax_hz, int count);

/// A hidden-effect test case: a truth model made from the nominal one by scattering its stiffnesses and
/// adding zero, one or two physical effects at random locations and magnitudes large enough to matter
/// (HiddenEffectOptions::min_visibility), and its noisy 12x10 accelerance measurement of the top plate
/// with the DECLARED (nominal) geometry. For a rotated sensor the truth carries the geometry correction
/// that undoes it, so that the truth's error is the noise floor in either comparison space.
struct HiddenEffect {
  std::string name;       ///< catalogue name, e.g. "payload"
  std::string location;   ///< catalogue location, e.g. "hexapod"
  std::string description;
  /// How much the effect alone changes the noise-free data, in noise standard deviations (RMS over all
  /// elements and frequencies of |H_with - H_without| / sigma, sigma of AddNoise's model), "without"
  /// being the truth with the effects drawn before it.
  double visibility = 0;
};
struct HiddenEffectCase {
  uint64_t seed = 0;
  model::ModelSpec truth;
  std::vector<HiddenEffect> effects;
  measurement::FrfData measurement;
  std::vector<std::string> scattered_parameters;  ///< "<joint>.k.<Dof>" that were scattered
  double noise = 0;  ///< the drawn noise level: AddNoise's relative and absolute parts, and visibility's sigma
};
struct HiddenEffectOptions {
  int num_effects = 1;              ///< 0 to 8, each of a different kind
  TestLayout layout = TestLayout::kTopPlate;
  double stiffness_scatter = 0.15;  ///< log-normal sigma of the stiffness factors (clipped to [1/1.6, 1.6])
  double noise_min = 0.01, noise_max = 0.03;
  double fmin_hz = 10.0, fmax_hz = 400.0;
  int num_frequencies = 300;
  /// "Large enough to matter": an effect is drawn again (location and magnitude) until its visibility
  /// reaches this, at most max_draws times and once at least (the most visible draw is kept when none
  /// reaches it).
  double min_visibility = 2.0;
  int max_draws = 20;
  /// The first rule of the draws, kept so that cases drawn by it can be rebuilt bit for bit (set by the
  /// tests that hold such a case where the rule now draws another): each effect's visibility taken against
  /// the truth with no effect (a later effect then passes on the change of the ones before it, however
  /// little it changes the data itself) and the last draw kept when none reaches min_visibility.
  bool visibility_against_no_effect = false;
  /// The noise's absolute part per output channel (NoiseOptions::per_channel), in the measurement and
  /// in the visibility the effects are drawn to.
  bool noise_per_channel = false;
};
HiddenEffectCase MakeHiddenEffectCase(const model::ModelSpec& nominal, uint64_t seed, const HiddenEffectOptions& options);

/// The options of a case of tests/bench/eval_loop: `num_effects`, 5 Hz to `fmax_hz` (150 or 600),
/// `num_frequencies` (300-1200), noise 1-3 %, the rest HiddenEffectOptions' defaults. eval_loop draws
/// the band and the number of frequencies from the seed; tests rebuild one of its cases with these.
HiddenEffectOptions EvalLoopCaseOptions(int num_effects, double fmax_hz, int num_frequencies);

/// How much `with` differs from `without` against the measurement noise of AddNoise with relative =
/// absolute = `noise` (and its `per_channel`): per frequency, |H_with - H_without|^2 / sigma^2 of every
/// element (an element the model makes exactly zero gets sigma from 1e-3 of the strongest element's RMS
/// at least, as a real test's channel noise would). NoiseNormalisedDifference is the RMS of its square
/// root over every point: the "visibility" of HiddenEffect.
std::vector<Eigen::MatrixXd> NoiseNormalisedChange(const measurement::FrfData& with, const measurement::FrfData& without,
                                                   double noise, bool per_channel = false);
double NoiseNormalisedDifference(const measurement::FrfData& with, const measurement::FrfData& without, double noise,
                                 bool per_channel = false);

/// Raw hammer-test time data of `truth`: for every impact, `hits_per_impact` half-sine force pulses
/// (duration `pulse_s`, peak `peak_force_n`, start jittered), and the accelerometer records computed in
/// the frequency domain from the brute-force FRFs (the record is long enough for the responses to
/// decay, so the circular convolution equals the linear one to the noise level), plus Gaussian noise
/// of `noise` times each channel's RMS on responses and forces.
struct RawHammerOptions {
  double sample_rate_hz = 2048;
  int num_samples = 4096;
  int hits_per_impact = 3;
  double pulse_s = 1.5e-3;
  double peak_force_n = 300;
  double noise = 0.005;
  uint64_t seed = 1;
};
measurement::RawHammerData MakeRawHammerTest(const model::ModelSpec& truth,
                                             const std::vector<measurement::ChannelGeometry>& sensors,
                                             const std::vector<measurement::ChannelGeometry>& impacts,
                                             const RawHammerOptions& options);

}  // namespace stagefit::synthetic
