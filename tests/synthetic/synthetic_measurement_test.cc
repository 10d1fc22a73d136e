#include "stagefit/synthetic/synthetic_measurement.h"

#include <gtest/gtest.h>

#include "stagefit/compare/residuals.h"
#include "stagefit/model/assembled_model.h"
#include "stagefit/model/effects.h"
#include "stagefit/model/linear_system.h"
#include "stagefit/model/model_file.h"
#include "stagefit/response/frf_evaluator.h"

namespace stagefit::synthetic {
namespace {

// Two independent methods (relative coordinates + modal evaluation vs absolute coordinates + null
// space + dense solve per frequency) agree to rounding: 1e-8 of the peak response of the element's row
// and column (rounding in a solve scales with the largest response it carries; elements that vanish
// by symmetry, such as a1x/h1, are pure rounding on both sides).
constexpr double kAgreement = 1e-8;

void ExpectSameAsModel(const model::ModelSpec& spec) {
  auto assembled = model::AssembledModel::Assemble(spec);
  const Eigen::Vector3d X = spec.frames[model::FindFrame(spec, "X")].origin_W;
  auto sensors = ComplianceTestSensors("hexapod", X);
  auto impacts = ComplianceTestImpacts("hexapod", X);
  const Eigen::VectorXd f = LogFrequencies(5, 800, 120);
  auto brute = CalcBruteForceFrf(spec, sensors, impacts, f, measurement::FrfQuantity::kAccelerance);
  auto system = model::BuildSystem(assembled, model::ExcitationInputs(spec), model::SensorOutputs(spec));
  auto evaluator = response::FrfEvaluator::Create(system);
  auto frf = evaluator.Evaluate(f, response::ResponseQuantity::kAccelerance);
  for (int o = 0; o < 12; ++o) {
    for (int i = 0; i < 10; ++i) {
      double peak = 0;
      for (int k = 0; k < f.size(); ++k) {
        for (int oo = 0; oo < 12; ++oo) peak = std::max(peak, std::abs(frf(k, oo, i)));
        for (int ii = 0; ii < 10; ++ii) peak = std::max(peak, std::abs(frf(k, o, ii)));
      }
      for (int k = 0; k < f.size(); ++k) {
        ASSERT_LE(std::abs(frf(k, o, i) - brute.frf[k](o, i)), kAgreement * peak)
            << system.output_names[o] << "/" << system.input_names[i] << " at " << f(k) << " Hz";
      }
    }
  }
}

TEST(BruteForceFrf, AgreesWithTheModelAndResponseLayers) { ExpectSameAsModel(model::DefaultModelSpec()); }

TEST(BruteForceFrf, AgreesWithEffectsAppliedThroughTheCatalogue) {
  // The catalogue's payload (parallel-axis edit of the host body) against the brute-force path's
  // separate rigidly attached body is checked in PayloadMatchesARigidlyAttachedBody; here the other
  // edits: extra body, servo stiffness, coupling, loss factors, offset, delay.
  model::ModelSpec spec = model::DefaultModelSpec();
  for (const char* text : {"extra-body@rz:mass=10,k=5e6,kr=2e4", "servo-stiffness@ty.Dy:k=2e8",
                           "coupled-stiffness@hexapod.Dx-Ry:k=2e6", "structural-damping@hexapod:eta=0.05",
                           "joint-offset@rz:dz=0.05", "delay@acquisition:tau=0.5 ms"}) {
    model::ApplyEffect(spec, model::ParseEffect(text, spec));
  }
  ExpectSameAsModel(spec);
}

TEST(BruteForceFrf, PayloadMatchesARigidlyAttachedBody) {
  model::ModelSpec edited = model::DefaultModelSpec();
  model::ApplyEffect(edited, model::ParseEffect("payload@hexapod:mass=6,z=0.08", edited));
  model::ModelSpec attached = model::DefaultModelSpec();
  model::BodySpec b;
  b.name = "payload";
  b.mass_kg = 6;
  b.com_W = attached.bodies[4].com_W + Eigen::Vector3d(0, 0, 0.08);
  b.inertia_com_W = Eigen::Matrix3d::Identity() * 1e-12;
  attached.bodies.push_back(b);
  model::JointSpec j;
  j.name = "payload";
  j.parent = "hexapod";
  j.child = "payload";
  j.origin_W = b.com_W;
  j.imposed = {true, true, true, true, true, true};
  attached.joints.push_back(j);
  const Eigen::Vector3d X(0, 0, -0.03);
  const Eigen::VectorXd f = LogFrequencies(5, 800, 60);
  auto a = CalcBruteForceFrf(edited, ComplianceTestSensors("hexapod", X), ComplianceTestImpacts("hexapod", X), f,
                             measurement::FrfQuantity::kReceptance);
  auto c = CalcBruteForceFrf(attached, ComplianceTestSensors("hexapod", X), ComplianceTestImpacts("hexapod", X), f,
                             measurement::FrfQuantity::kReceptance);
  for (int k = 0; k < f.size(); ++k) {
    EXPECT_LE((a.frf[k] - c.frf[k]).cwiseAbs().maxCoeff(), 1e-6 * a.frf[k].cwiseAbs().maxCoeff()) << f(k);
  }
}

TEST(AddNoise, CoherenceDropsWhereTheResponseIsSmall) {
  const Eigen::Vector3d X(0, 0, -0.03);
  auto data = CalcBruteForceFrf(model::DefaultModelSpec(), ComplianceTestSensors("hexapod", X),
                                ComplianceTestImpacts("hexapod", X), LogFrequencies(10, 400, 200),
                                measurement::FrfQuantity::kAccelerance);
  auto clean = data;
  AddNoise(data, {0.02, 0.02, 5});
  double low = 1, high = 0;
  int smallest = 0, largest = 0;
  for (int k = 0; k < 200; ++k) {
    if (std::abs(clean.frf[k](0, 2)) < std::abs(clean.frf[smallest](0, 2))) smallest = k;
    if (std::abs(clean.frf[k](0, 2)) > std::abs(clean.frf[largest](0, 2))) largest = k;
  }
  low = data.coherence[smallest](0, 2);
  high = data.coherence[largest](0, 2);
  EXPECT_LT(low, high);
  EXPECT_GT(high, 0.99);
  measurement::Validate(data);
}

// A sensor's noise floor does not know which impact excited it: with the absolute part per channel, an
// element that is exactly zero gets its channel's noise (absolute x the RMS over the channel's row) and
// coherence 0; per element it stays exactly zero, with coherence 1.
TEST(AddNoise, PerChannelGivesAZeroElementItsChannelsNoise) {
  const Eigen::Vector3d X(0, 0, -0.03);
  auto clean = CalcBruteForceFrf(model::DefaultModelSpec(), ComplianceTestSensors("hexapod", X),
                                 ComplianceTestImpacts("hexapod", X), LogFrequencies(10, 400, 2000),
                                 measurement::FrfQuantity::kAccelerance);
  for (auto& h : clean.frf) h(1, 3) = 0.0;
  double row_mean_square = 0;
  for (const auto& h : clean.frf) row_mean_square += h.row(1).cwiseAbs2().mean();
  row_mean_square /= clean.num_frequencies();

  auto per_element = clean, per_channel = clean;
  AddNoise(per_element, {0.0, 0.02, 5});
  AddNoise(per_channel, {0.0, 0.02, 5, true});
  double variance = 0;
  for (int k = 0; k < clean.num_frequencies(); ++k) {
    EXPECT_EQ(per_element.frf[k](1, 3), 0.0);
    EXPECT_EQ(per_element.coherence[k](1, 3), 1.0);
    EXPECT_EQ(per_channel.coherence[k](1, 3), 0.0);
    variance += std::norm(per_channel.frf[k](1, 3));
  }
  variance /= clean.num_frequencies();
  // 2000 complex draws: the sample variance is within 10 % of the true one (4.5 sigma).
  EXPECT_NEAR(variance / (0.02 * 0.02 * row_mean_square), 1.0, 0.1);

  // The noise-normalised change of the zero element: per channel, its change over the channel's sigma
  // (1e-3 of the row's RMS against 2 % of it); per element, over 1e-3 of the strongest element's RMS,
  // which makes a change far below the channel's noise look large.
  auto with = clean;
  for (auto& h : with.frf) h(1, 3) = 1e-3 * std::sqrt(row_mean_square);
  const double channel = NoiseNormalisedChange(with, clean, 0.02, true)[0](1, 3);
  const double element = NoiseNormalisedChange(with, clean, 0.02)[0](1, 3);
  EXPECT_NEAR(channel, 1e-6 / (0.02 * 0.02), 0.01 * channel);
  EXPECT_GT(element, 100 * channel);
}

TEST(HiddenEffectCase, IsReproducibleFromItsSeed) {
  auto a = MakeHiddenEffectCase(model::DefaultModelSpec(), 17, {});
  auto b = MakeHiddenEffectCase(model::DefaultModelSpec(), 17, {});
  ASSERT_EQ(a.effects.size(), 1u);
  EXPECT_EQ(a.effects[0].description, b.effects[0].description);
  EXPECT_EQ(a.measurement.frf.back(), b.measurement.frf.back());
  measurement::Validate(a.measurement);
}

// Every case records how much its effect matters and is a valid measurement that the compliance comparison accepts: seed 1012 makes an element exactly zero (a
// drive spring in ty.Dy keeps a symmetry), which once gave 0/0 coherence, then coherence 0, whose
// infinite variance the projection spread over every compliance element.
TEST(HiddenEffectCase, DrawsVisibleEffectsAndValidMeasurements) {
  for (uint64_t seed : {1012u, 1013u, 1014u}) {
    SCOPED_TRACE(seed);
    auto c = MakeHiddenEffectCase(model::DefaultModelSpec(), seed, {});
    ASSERT_EQ(c.effects.size(), 1u);
    EXPECT_GT(c.effects[0].visibility, 0.0);  // (a drive spring of ry.Ry can stay below min_visibility)
    measurement::Validate(c.measurement);
    EXPECT_NO_THROW(compare::Comparison::Create(model::DefaultModelSpec(), c.measurement));
  }
}

// A later effect's visibility is its own: the change it makes to the truth with the effects drawn
// before it. Seed 82000 of eval_loop (150 Hz, 574 points) draws a loss factor of rz, then a drive
// spring of ty.Dy; the spring is undone by imposing ty.Dy again. Measured against the truth with no
// effect, the first rule's spring (another draw, whose own change is 0.55) was recorded at 7.0, the
// change of both effects (the loss factor's alone is 6.7).
TEST(HiddenEffectCase, MeasuresALaterEffectAgainstTheEffectsBeforeIt) {
  const auto c = MakeHiddenEffectCase(model::DefaultModelSpec(), 82000, EvalLoopCaseOptions(2, 150, 574));
  ASSERT_EQ(c.effects.size(), 2u);
  ASSERT_EQ(c.effects[0].name, "structural-damping");
  ASSERT_EQ(c.effects[1].name + "@" + c.effects[1].location, "servo-stiffness@ty.Dy");
  model::ModelSpec without_spring = c.truth;
  model::JointSpec& ty = without_spring.joints[model::FindJoint(without_spring, "ty")];
  ASSERT_FALSE(ty.imposed[1]);
  ty.imposed[1] = true;
  const auto& m = c.measurement;
  const auto with = CalcBruteForceFrf(c.truth, m.outputs, m.inputs, m.frequency_hz, measurement::FrfQuantity::kAccelerance);
  const auto without = CalcBruteForceFrf(without_spring, m.outputs, m.inputs, m.frequency_hz, measurement::FrfQuantity::kAccelerance);
  const double own = NoiseNormalisedDifference(with, without, c.noise);
  EXPECT_NEAR(c.effects[1].visibility, own, 1e-9 * own);
  EXPECT_GE(own, HiddenEffectOptions{}.min_visibility);
}

// Seed 1014 draws a drive spring of ry.Ry 20 times without reaching min_visibility: the most visible
// draw is kept, not the last one (which the first rule kept).
TEST(HiddenEffectCase, KeepsTheMostVisibleDrawWhenNoneReachesTheMinimum) {
  HiddenEffectOptions first_rule;
  first_rule.visibility_against_no_effect = true;
  const auto kept = MakeHiddenEffectCase(model::DefaultModelSpec(), 1014, {});
  const auto last = MakeHiddenEffectCase(model::DefaultModelSpec(), 1014, first_rule);
  ASSERT_EQ(kept.effects.size(), 1u);
  ASSERT_EQ(kept.effects[0].name + "@" + kept.effects[0].location, "servo-stiffness@ry.Ry");
  EXPECT_LT(kept.effects[0].visibility, HiddenEffectOptions{}.min_visibility);
  EXPECT_GT(kept.effects[0].visibility, last.effects[0].visibility);
}

// No draw asked for is one draw: the effect is applied, whatever its visibility.
TEST(HiddenEffectCase, DrawsEachEffectOnceAtLeast) {
  HiddenEffectOptions options;
  options.max_draws = 0;
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = MakeHiddenEffectCase(nominal, 17, options);
  ASSERT_EQ(c.effects.size(), 1u);
  EXPECT_FALSE(c.effects[0].name.empty());
  EXPECT_GE(c.truth.bodies.size(), nominal.bodies.size());
  EXPECT_GE(c.truth.joints.size(), nominal.joints.size());
  measurement::Validate(c.measurement);
}

}  // namespace
}  // namespace stagefit::synthetic
