// The Jacobian of a candidate effect's problem (diagnose/effect_problem.h): every effect parameter's
// column, whichever route computes it, agrees with a central difference of the problem's own
// residuals at another step; the model parameters' columns and the residuals are the comparison's.

#include "stagefit/diagnose/effect_problem.h"

#include <gtest/gtest.h>

#include <cctype>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "stagefit/compare/residuals.h"
#include "stagefit/model/effects.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace stagefit::diagnose {
namespace {

struct RouteCase {
  std::string with;
  compare::ComparisonSpace space;
  /// The route every effect parameter takes; kResidualDifference also accepts kMeasuredDifference
  /// (a channel's offset along its own direction changes neither the model nor the data).
  EffectColumnRoute route;
};

class EffectProblemTest : public ::testing::TestWithParam<RouteCase> {};

TEST_P(EffectProblemTest, EffectColumnsMatchDifferencesOfTheResiduals) {
  const RouteCase& rc = GetParam();
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectOptions hidden;
  hidden.num_effects = 0;
  hidden.num_frequencies = 80;
  const auto data = synthetic::MakeHiddenEffectCase(nominal, 5, hidden);
  compare::ComparisonOptions options;
  options.space = rc.space;
  const auto comparison = compare::Comparison::Create(nominal, data.measurement, options);

  const model::Effect effect = model::ParseEffect(rc.with, nominal, comparison.CorrectableChannels());
  std::vector<int> index;
  const auto effect_specs = EffectParameterSpecs(nominal, effect, {}, &index);
  const auto params = model::MatchParameters(nominal, {"hexapod.k.*", "ry.k.*"});
  EffectProblem problem(nominal, comparison, effect, effect_specs, index, params);
  const int ne = static_cast<int>(effect_specs.size());
  const int nm = static_cast<int>(params.size());
  Eigen::VectorXd p(ne + nm);
  for (int i = 0; i < ne; ++i) p(i) = effect_specs[i].initial;
  for (int k = 0; k < nm; ++k) p(ne + k) = 1.2 * model::GetParameter(nominal, params[k]);

  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  ASSERT_TRUE(problem.Evaluate(p, &r, &J));
  ASSERT_EQ(J.rows(), comparison.num_residuals());
  ASSERT_EQ(J.cols(), ne + nm);

  // Residuals and model columns: the comparison's own.
  model::ModelSpec at;
  ASSERT_TRUE(problem.SpecAt(p, &at));
  Eigen::VectorXd r_ref;
  Eigen::MatrixXd J_ref;
  comparison.ResidualsAndJacobian(at, params, &r_ref, &J_ref);
  EXPECT_LT((r - r_ref).norm(), 1e-12 * r_ref.norm());
  EXPECT_LT((J.rightCols(nm) - J_ref).norm(), 1e-9 * J_ref.norm());

  // Effect columns: against central differences at 10x the problem's step.
  for (int i = 0; i < ne; ++i) {
    const auto& s = effect_specs[i];
    const double h = s.log_scale ? 1e-4 * std::abs(p(i)) : 1e-5 * (s.upper - s.lower);
    Eigen::VectorXd pp = p, pm = p, rp, rm;
    pp(i) += h;
    pm(i) -= h;
    ASSERT_TRUE(problem.Evaluate(pp, &rp, nullptr));
    ASSERT_TRUE(problem.Evaluate(pm, &rm, nullptr));
    const Eigen::VectorXd fd = (rp - rm) / (2 * h);
    // Both are differences: truncation O(h^2) relative, and rounding of the residuals (about 1e-14 of
    // |r| after the eigen-decomposition) over h; a column near zero (an offset along the channel's
    // own direction) is all rounding.
    const double rounding = 1e-12 * r.norm() / h;
    EXPECT_LE((J.col(i) - fd).norm(), 1e-5 * fd.norm() + rounding) << rc.with << ": " << s.name;
    std::printf("%-28s |J| %.3e  |fd| %.3e  |J - fd| %.3e  rounding %.1e\n", s.name.c_str(), J.col(i).norm(),
                fd.norm(), (J.col(i) - fd).norm(), rounding);
    if (rc.route == EffectColumnRoute::kResidualDifference) {
      EXPECT_NE(problem.routes()[i], EffectColumnRoute::kSystemDifference) << s.name;
    } else {
      EXPECT_EQ(problem.routes()[i], rc.route) << s.name;
    }
  }
  // Some column must carry the effect: a test whose columns are all zero cannot fail.
  EXPECT_GT(J.leftCols(ne).norm(), 1e-6 * J.rightCols(nm).norm());
}

constexpr auto kCompliance = compare::ComparisonSpace::kCompliance;
constexpr auto kRaw = compare::ComparisonSpace::kRaw;
INSTANTIATE_TEST_SUITE_P(
    Routes, EffectProblemTest,
    ::testing::Values(
        RouteCase{"payload@hexapod:mass=3 kg,x=0.02 m,y=-0.01 m,z=0.1 m", kCompliance, EffectColumnRoute::kSystemDifference},
        RouteCase{"extra-body@ry:mass=4 kg,k=2e7 N/m,kr=5e4 Nm/rad,z=0.1 m", kCompliance, EffectColumnRoute::kSystemDifference},
        // In raw space too: the channels' rows stay the same while the body's centre of mass moves.
        RouteCase{"payload@hexapod:mass=3 kg,x=0.02 m,y=-0.01 m,z=0.1 m", kRaw, EffectColumnRoute::kSystemDifference},
        RouteCase{"extra-body@ry:mass=4 kg,k=2e7 N/m,kr=5e4 Nm/rad,z=0.1 m", kRaw, EffectColumnRoute::kSystemDifference},
        RouteCase{"servo-stiffness@ty.Dy:k=3e7 N/m,zeta=0.05", kCompliance, EffectColumnRoute::kSystemDifference},
        RouteCase{"coupled-stiffness@hexapod.Dx-Ry:k=1e5 N/m", kCompliance, EffectColumnRoute::kSystemDifference},
        RouteCase{"structural-damping@ry:eta=0.05", kCompliance, EffectColumnRoute::kSystemDifference},
        RouteCase{"joint-offset@rz:dx=0.01 m,dy=-0.02 m,dz=0.05 m", kCompliance, EffectColumnRoute::kResidualDifference},
        RouteCase{"delay@acquisition:tau=0.2 ms", kCompliance, EffectColumnRoute::kDelayDifference},
        RouteCase{"delay@acquisition:tau=0.2 ms", kRaw, EffectColumnRoute::kDelayDifference},
        RouteCase{"sensor-geometry@a1y:dx=0.01 m,dz=-0.01 m,rx=0.05 rad,rz=0.1 rad", kCompliance,
                  EffectColumnRoute::kMeasuredDifference},
        RouteCase{"sensor-geometry@a1y:dx=0.01 m,dz=-0.01 m,rx=0.05 rad,rz=0.1 rad", kRaw,
                  EffectColumnRoute::kResidualDifference}),
    [](const ::testing::TestParamInfo<RouteCase>& info) {
      std::string name = info.param.with.substr(0, info.param.with.find('@'));
      name += info.param.space == kRaw ? "_raw" : "_compliance";
      for (char& c : name) c = std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
      return name;
    });

// Several effects in one problem (the loop's joint refit): the spec at p is the base with each effect
// applied in order; every effect parameter's column, of either effect, agrees with a central difference.
TEST(EffectProblemSeveral, ColumnsOfEveryEffectMatchDifferences) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  synthetic::HiddenEffectOptions hidden;
  hidden.num_effects = 0;
  hidden.num_frequencies = 80;
  const auto data = synthetic::MakeHiddenEffectCase(nominal, 5, hidden);
  const auto comparison = compare::Comparison::Create(nominal, data.measurement);
  const std::vector<model::Effect> effects = {model::ParseEffect("payload@hexapod:mass=3 kg,z=0.1 m", nominal),
                                              model::ParseEffect("coupled-stiffness@hexapod.Dx-Ry:k=1e5 N/m", nominal)};
  std::vector<fit::ParameterSpec> specs;
  std::vector<int> of, index;
  model::ModelSpec applied = nominal;
  for (int k = 0; k < 2; ++k) {
    std::vector<int> idx;
    for (const auto& s : EffectParameterSpecs(applied, effects[k], {}, &idx)) specs.push_back(s);
    for (int i : idx) {
      of.push_back(k);
      index.push_back(i);
    }
    model::ApplyEffect(applied, effects[k]);
  }
  const auto params = model::MatchParameters(nominal, {"hexapod.k.Dz"});
  EffectProblem problem(nominal, comparison, effects, specs, of, index, params);
  const int ne = static_cast<int>(specs.size());
  ASSERT_EQ(ne, 5);  // mass, x, y, z; k
  Eigen::VectorXd p(ne + 1);
  for (int i = 0; i < ne; ++i) p(i) = specs[i].initial;
  p(ne) = model::GetParameter(nominal, params[0]);
  p(3) = 0.12;   // the payload's z
  p(4) = 2e5;    // the coupling
  const std::vector<model::Effect> at = problem.EffectsAt(p);
  ASSERT_EQ(at.size(), 2u);
  EXPECT_EQ(at[0].parameters.at("z"), 0.12);
  EXPECT_EQ(at[1].parameters.at("k"), 2e5);
  model::ModelSpec spec;
  ASSERT_TRUE(problem.SpecAt(p, &spec));
  model::ModelSpec expected = nominal;
  for (const auto& e : at) model::ApplyEffect(expected, e);
  EXPECT_EQ(comparison.Error(spec), comparison.Error(expected));

  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  ASSERT_TRUE(problem.Evaluate(p, &r, &J));
  for (int i = 0; i < ne; ++i) {
    const auto& s = specs[i];
    const double h = s.log_scale ? 1e-4 * std::abs(p(i)) : 1e-5 * (s.upper - s.lower);
    Eigen::VectorXd pp = p, pm = p, rp, rm;
    pp(i) += h;
    pm(i) -= h;
    ASSERT_TRUE(problem.Evaluate(pp, &rp, nullptr));
    ASSERT_TRUE(problem.Evaluate(pm, &rm, nullptr));
    const Eigen::VectorXd fd = (rp - rm) / (2 * h);
    const double rounding = 1e-12 * r.norm() / h;
    EXPECT_LE((J.col(i) - fd).norm(), 1e-5 * fd.norm() + rounding) << s.name;
  }
  EXPECT_GT(J.col(4).norm(), 0.0);  // the second effect's column is not empty

  // A clone (fit::SolveWithProbes runs probes and bound resets on clones side by side) evaluates to
  // the same bits, here after the original's evaluations above have filled its workspaces.
  const std::unique_ptr<fit::LeastSquaresProblem> clone = problem.Clone();
  ASSERT_NE(clone, nullptr);
  ASSERT_EQ(clone->num_parameters(), problem.num_parameters());
  Eigen::VectorXd r_clone;
  Eigen::MatrixXd J_clone;
  ASSERT_TRUE(clone->Evaluate(p, &r_clone, &J_clone));
  EXPECT_TRUE(r_clone == r);
  EXPECT_TRUE(J_clone == J);
}

}  // namespace
}  // namespace stagefit::diagnose
