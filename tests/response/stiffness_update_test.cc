#include "stagefit/response/stiffness_update.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "response_test_util.h"
#include "stagefit/common/error.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"
#include "stagefit/response/io_sets.h"

namespace stagefit::response {
namespace {

using testing::LogFrequencies;
using testing::WorstRelativeToPeak;

// The update and a new set-up of the changed system (its own direct solve per frequency) agree to
// this fraction of each element's peak: the identity is exact; rounding in the subtraction grows with
// |Z^-1| at the unchanged system's resonances (|H| / 2 zeta, ~1e3 for the micro-station's damping),
// ~1e-13 of the peak.
constexpr double kAgreement = 1e-9;

// The micro-station with loss factors and a coupling in the hexapod (a twentieth of the largest the
// joint allows, sqrt(k_Dy k_Rx), so that it stays so with either stiffness or itself changed by 8):
// every term of D(s).
model::ModelSpec LossyCoupledSpec() {
  model::ModelSpec spec = model::DefaultModelSpec();
  for (auto& joint : spec.joints) {
    joint.loss_factor.fill(0.02);
    if (joint.name != "hexapod") continue;
    const double largest = std::sqrt(joint.stiffness[1] * joint.stiffness[3]);
    joint.couplings.push_back({Dof::kDy, Dof::kRx, 0.05 * largest, 50.0});
  }
  return spec;
}

// The change of Z when `parameters` go from their values in `spec` to `values`.
std::vector<DynamicStiffnessDerivative::Entry> ChangeOf(const model::ModelSpec& spec,
                                                        const std::vector<model::ParameterInfo>& parameters,
                                                        const std::vector<double>& values) {
  const auto assembled = model::AssembledModel::Assemble(spec);
  std::vector<DynamicStiffnessDerivative::Entry> change;
  for (size_t k = 0; k < parameters.size(); ++k) {
    const double delta = values[k] - model::GetParameter(spec, parameters[k]);
    for (auto e : MakeDynamicStiffnessDerivative(model::CalcSystemDerivative(assembled, parameters[k]), parameters[k].name).entries) {
      e.stiffness *= delta;
      e.damping *= delta;
      change.push_back(e);
    }
  }
  return change;
}

// H of the changed model from a new direct solve.
Eigen::MatrixXcd Reference(model::ModelSpec spec, const std::vector<model::ParameterInfo>& parameters,
                           const std::vector<double>& values, IoSet set, double delay_s, const Eigen::VectorXd& f,
                           ResponseQuantity quantity) {
  for (size_t k = 0; k < parameters.size(); ++k) model::SetParameter(spec, parameters[k], values[k]);
  model::SecondOrderSystem sys = BuildIoSetSystem(model::AssembledModel::Assemble(spec), set);
  sys.delay_s = delay_s;
  return FrfEvaluator::Create(sys, {FrfMethod::kDirect}).Evaluate(f, quantity).values;
}

std::vector<int> AllCoordinates(int n) {
  std::vector<int> all(n);
  for (int i = 0; i < n; ++i) all[i] = i;
  return all;
}

TEST(StiffnessUpdate, AgreesWithANewSolveForEveryJointParameterChangedByAFactor) {
  const model::ModelSpec spec = LossyCoupledSpec();
  const Eigen::VectorXd f = LogFrequencies(5.0, 600.0, 120);
  constexpr double kDelay = 2e-4;
  for (const IoSet set : {IoSet::kCompliance, IoSet::kRaw}) {
    model::SecondOrderSystem sys = BuildIoSetSystem(model::AssembledModel::Assemble(spec), set);
    sys.delay_s = kDelay;
    const ResponseQuantity quantity = set == IoSet::kRaw ? ResponseQuantity::kAccelerance : ResponseQuantity::kReceptance;
    const StiffnessUpdate update = StiffnessUpdate::Create(sys, f, quantity, AllCoordinates(sys.num_dofs()));
    // The unchanged system itself.
    EXPECT_LT(WorstRelativeToPeak(update.values(), Reference(spec, {}, {}, set, kDelay, f, quantity)), kAgreement);
    int checked = 0;
    for (const auto& p : model::MatchParameters(spec, {"*.k.*", "*.c.*"})) {
      const double value = model::GetParameter(spec, p);
      for (const double factor : {0.125, 8.0}) {
        Eigen::MatrixXcd h;
        ASSERT_TRUE(update.Evaluate(ChangeOf(spec, {p}, {value * factor}), &h)) << p.name;
        const double worst = WorstRelativeToPeak(h, Reference(spec, {p}, {value * factor}, set, kDelay, f, quantity));
        EXPECT_LT(worst, kAgreement) << ToString(set) << " " << p.name << " x " << factor;
        ++checked;
      }
    }
    EXPECT_EQ(checked, 2 * (27 + 27 + 2));  // every free DoF's stiffness and damping, the coupling's two
  }
}

TEST(StiffnessUpdate, AgreesWithANewSolveForTwoSpringsChangedTogether) {
  const model::ModelSpec spec = LossyCoupledSpec();
  const Eigen::VectorXd f = LogFrequencies(5.0, 600.0, 120);
  const auto sys = BuildIoSetSystem(model::AssembledModel::Assemble(spec), IoSet::kCompliance);
  const StiffnessUpdate update = StiffnessUpdate::Create(sys, f, ResponseQuantity::kAccelerance, AllCoordinates(sys.num_dofs()));
  // Two springs in series on the vertical path, their shares swapped, and a coupling with one of its DoF.
  const std::vector<std::vector<std::string>> pairs = {{"ry.k.Dz", "hexapod.k.Dz"}, {"hexapod.k.Dy-Rx", "hexapod.k.Rx"}};
  for (const auto& names : pairs) {
    std::vector<model::ParameterInfo> params;
    std::vector<double> values;
    for (const auto& name : names) {
      params.push_back(model::FindParameter(spec, name));
      values.push_back(model::GetParameter(spec, params.back()) * (values.empty() ? 5.0 : 0.3));
    }
    Eigen::MatrixXcd h;
    ASSERT_TRUE(update.Evaluate(ChangeOf(spec, params, values), &h));
    EXPECT_LT(WorstRelativeToPeak(h, Reference(spec, params, values, IoSet::kCompliance, 0.0, f, ResponseQuantity::kAccelerance)),
              kAgreement)
        << names[0] << " + " << names[1];
  }
}

TEST(StiffnessUpdate, RefusesAMassAndCoordinatesItWasNotSetUpFor) {
  const model::ModelSpec spec = model::DefaultModelSpec();
  const auto sys = BuildIoSetSystem(model::AssembledModel::Assemble(spec), IoSet::kCompliance);
  const Eigen::VectorXd f = LogFrequencies(5.0, 600.0, 20);
  const StiffnessUpdate update = StiffnessUpdate::Create(sys, f, ResponseQuantity::kAccelerance, {0, 3});
  Eigen::MatrixXcd h;
  EXPECT_TRUE(update.Evaluate({}, &h));
  EXPECT_EQ(h, update.values());
  DynamicStiffnessDerivative::Entry outside{1, 1, {1e6, 0.0}, 0.0, 0.0};
  EXPECT_THROW(update.Evaluate({outside}, &h), InputError);
  DynamicStiffnessDerivative::Entry mass{0, 0, {0.0, 0.0}, 0.0, 1.0};
  EXPECT_THROW(update.Evaluate({mass}, &h), InputError);
  EXPECT_THROW(StiffnessUpdate::Create(sys, f, ResponseQuantity::kAccelerance, {0, 0}), InputError);
  EXPECT_THROW(StiffnessUpdate::Create(sys, f, ResponseQuantity::kAccelerance, {sys.num_dofs()}), InputError);
}

}  // namespace
}  // namespace stagefit::response
