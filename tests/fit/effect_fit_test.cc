// Effect parameters as fit parameters (model/parameters.h): their Jacobian columns in ModelFitProblem
// agree with central differences of the residuals whichever route computes them, and a fit of the
// stiffnesses and a payload's parameters recovers a payload the truth carries, built by hand (not by
// the catalogue's edit), from seeded noisy data; the tuned model reloads with its error bit for bit.

#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "fit_test_util.h"
#include "stagefit/compare/residuals.h"
#include "stagefit/fit/model_fit.h"
#include "stagefit/model/effects.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace stagefit::fit {
namespace {

struct ColumnCase {
  compare::ComparisonSpace space;
  std::string name;
};

class EffectColumnsTest : public ::testing::TestWithParam<ColumnCase> {};

TEST_P(EffectColumnsTest, EveryDifferencedColumnMatchesADifferenceOfTheResiduals) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectOptions hidden;
  hidden.num_effects = 0;
  hidden.num_frequencies = 80;
  const auto data = synthetic::MakeHiddenEffectCase(nominal, 7, hidden);
  compare::ComparisonOptions options;
  options.space = GetParam().space;
  const auto comparison = compare::Comparison::Create(nominal, data.measurement, options);

  model::ModelSpec spec = nominal;
  for (const char* text : {"payload@hexapod:mass=3 kg,x=0.02 m,z=0.1 m", "joint-offset@rz:dz=0.05 m",
                           "sensor-geometry@a1y:dx=0.01 m,rz=0.1 rad", "delay@acquisition:tau=0.2 ms"}) {
    model::ApplyEffect(spec, model::ParseEffect(text, spec));
  }
  const auto params = model::MatchParameters(
      spec, {"hexapod.k.*", "payload@*", "joint-offset@rz.dz", "sensor-geometry@a1y.dx", "sensor-geometry@a1y.rz",
             "delay@*", "hexapod.m"});
  ModelFitProblem problem(spec, comparison, params);
  Eigen::VectorXd p(static_cast<int>(params.size()));
  for (size_t k = 0; k < params.size(); ++k) p(k) = model::GetParameter(spec, params[k]);
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  ASSERT_TRUE(problem.Evaluate(p, &r, &J));
  EXPECT_LT(std::abs(r.norm() - comparison.Error(spec)), 1e-12 * r.norm());
  int differenced = 0;
  for (size_t k = 0; k < params.size(); ++k) {
    const bool analytic = model::HasAnalyticDerivative(spec, params[k]);
    differenced += !analytic;
    const double v = p(k);
    const double h = v != 0.0 ? 1e-4 * std::abs(v) : 1e-5;
    Eigen::VectorXd pp = p, pm = p, rp, rm;
    pp(k) += h;
    pm(k) -= h;
    ASSERT_TRUE(problem.Evaluate(pp, &rp, nullptr));
    ASSERT_TRUE(problem.Evaluate(pm, &rm, nullptr));
    const Eigen::VectorXd fd = (rp - rm) / (2 * h);
    const double rounding = 1e-12 * r.norm() / h;
    EXPECT_LE((J.col(k) - fd).norm(), 2e-5 * fd.norm() + rounding) << params[k].name;
    EXPECT_GT(fd.norm(), 0.0) << params[k].name;  // every column carries something: the test can fail
  }
  EXPECT_EQ(differenced, 4 + 1 + 2 + 1 + 1);  // payload 4, offset, channel 2, delay, the hexapod's mass
  const auto& routes = problem.routes();
  ASSERT_EQ(routes.size(), 9u);
  // In the parameters' order: the hexapod's mass, the payload's 4, the offset, the channel's 2, the delay.
  // The hexapod's mass under the payload moves the combined centre of mass: any route but the
  // analytic one.
  for (int k = 1; k < 5; ++k) EXPECT_EQ(routes[k], ColumnRoute::kSystemDifference) << k;  // the payload
  EXPECT_EQ(routes[5], ColumnRoute::kResidualDifference);                                // a joint's origin
  EXPECT_EQ(routes[8], ColumnRoute::kDelayDifference);                                   // a delay
}

INSTANTIATE_TEST_SUITE_P(Spaces, EffectColumnsTest,
                         ::testing::Values(ColumnCase{compare::ComparisonSpace::kCompliance, "compliance"},
                                           ColumnCase{compare::ComparisonSpace::kRaw, "raw"}),
                         [](const ::testing::TestParamInfo<ColumnCase>& info) { return info.param.name; });

/// The hexapod of `spec` carrying a point mass `m` at `offset` from its centre of mass, computed here
/// (not by the payload effect's edit).
model::ModelSpec WithPointMass(model::ModelSpec spec, double m, const Eigen::Vector3d& offset) {
  model::BodySpec& b = spec.bodies[model::FindBody(spec, "hexapod")];
  const double total = b.mass_kg + m;
  const Eigen::Vector3d c = b.com_W + (m / total) * offset;
  const Eigen::Vector3d d1 = b.com_W - c, d2 = b.com_W + offset - c;
  Eigen::Matrix3d I = b.inertia_com_W;
  for (const auto& [mass, d] : {std::pair<double, Eigen::Vector3d>{b.mass_kg, d1}, {m, d2}}) {
    I += mass * (d.dot(d) * Eigen::Matrix3d::Identity() - d * d.transpose());
  }
  b.mass_kg = total;
  b.com_W = c;
  b.inertia_com_W = I;
  return spec;
}

TEST(EffectFit, StiffnessesAndAPayloadRecoveredFromNoisyDataAndReloadedBitForBit) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  std::mt19937_64 generator(20261125);
  model::ModelSpec truth = nominal;
  testing::ScatterParameters(&truth, {"*.k.*"}, 1.3, generator);
  truth = WithPointMass(truth, 8.0, Eigen::Vector3d(0.0, 0.0, 0.12));
  const Eigen::Vector3d X = nominal.frames[model::FindFrame(nominal, nominal.compliance_frame)].origin_W;
  measurement::FrfData data = synthetic::CalcBruteForceFrf(
      truth, synthetic::ComplianceTestSensors("hexapod", X), synthetic::ComplianceTestImpacts("hexapod", X),
      synthetic::LogFrequencies(10, 400, 250), measurement::FrfQuantity::kAccelerance);
  synthetic::AddNoise(data, {0.01, 0.002, 11});
  const auto comparison = compare::Comparison::Create(nominal, data);

  model::ModelSpec spec = nominal;
  model::ApplyEffect(spec, model::ParseEffect("payload@hexapod", spec));  // 10 % of the hexapod, at its CoM
  const auto params = model::MatchParameters(spec, model::WithEffectParameters({"*.k.*"}, spec));
  // With the continuation in band (fit's default route): the direct fit of 27 stiffnesses scattered
  // by up to 1.3x stopped at 2x the floor, with the payload's parameters right.
  const FitSummary summary = FitModelWithBandContinuation(spec, data, {}, comparison, params, FitOptions{});
  const model::Effect& payload = spec.effects.at(0);
  EXPECT_NEAR(payload.parameters.at("mass"), 8.0, 0.2);
  EXPECT_NEAR(payload.parameters.at("z"), 0.12, 0.005);
  EXPECT_NEAR(payload.parameters.at("x"), 0.0, 0.01);
  const compare::NoiseFloor floor = comparison.CalcNoiseFloor();
  ASSERT_TRUE(floor.known);
  EXPECT_LT(summary.final_error, 1.2 * floor.floor);
  // The tuned file: the base and the [[effect]] table; loaded again, the same error to the last bit.
  const model::ModelSpec back = model::ParseModelToml(model::WriteModelToml(spec), "tuned.toml");
  EXPECT_EQ(comparison.Error(back), summary.final_error);
  EXPECT_EQ(back.effects, spec.effects);
  // And the fit without the payload stays far above the floor: the test needs the effect's parameters.
  model::ModelSpec without = nominal;
  FitModel(without, comparison, model::MatchParameters(without, {"*.k.*"}), FitOptions{});
  EXPECT_GT(comparison.Error(without), 2.0 * floor.floor);
}

}  // namespace
}  // namespace stagefit::fit
