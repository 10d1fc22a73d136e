#include "stagefit/model/state_space.h"

#include <gtest/gtest.h>

#include <Eigen/LU>

#include "stagefit/common/eigen_decomposition.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/modes.h"

namespace stagefit::model {
namespace {

using Complex = std::complex<double>;

// Direct solve of the second-order system: H = Cq Z^-1 (B0 - w^2 B2) + D0.
Eigen::MatrixXcd DirectFrf(const SecondOrderSystem& s, double omega) {
  const Complex j(0, 1);
  Eigen::MatrixXcd Z = s.K.cast<Complex>() + j * s.K_loss.cast<Complex>() + j * omega * s.C.cast<Complex>() -
                       omega * omega * s.M.cast<Complex>();
  Eigen::MatrixXcd F = s.B0.cast<Complex>() - omega * omega * s.B2.cast<Complex>();
  return s.Cq.cast<Complex>() * Z.partialPivLu().solve(F) + s.D0.cast<Complex>();
}

Eigen::MatrixXcd StateSpaceFrf(const StateSpace& ss, double omega) {
  const int n = static_cast<int>(ss.A.rows());
  Eigen::MatrixXcd sIA = Complex(0, omega) * Eigen::MatrixXcd::Identity(n, n) - ss.A.cast<Complex>();
  return ss.C.cast<Complex>() * sIA.partialPivLu().solve(ss.B.cast<Complex>()) + ss.D.cast<Complex>();
}

// Both sides are exact formulas evaluated in double precision with LU solves of matrices whose
// condition numbers reach ~1e8 at this scale: 1e-7 of the element's size is well above the rounding.
constexpr double kFrfRelTol = 1e-7;

void ExpectSameFrf(const SecondOrderSystem& sys, const StateSpace& ss) {
  for (double f : {1.0, 13.0, 61.0, 150.0, 420.0, 1500.0}) {
    const double w = 2 * M_PI * f;
    Eigen::MatrixXcd a = DirectFrf(sys, w), b = StateSpaceFrf(ss, w);
    for (int r = 0; r < a.rows(); ++r) {
      for (int c = 0; c < a.cols(); ++c) {
        EXPECT_LE(std::abs(a(r, c) - b(r, c)), kFrfRelTol * std::abs(a(r, c)) + 1e-30)
            << sys.output_names[r] << "/" << sys.input_names[c] << " at " << f << " Hz";
      }
    }
  }
}

TEST(StateSpace, ComplianceMatchesDirectSolve) {
  auto model = AssembledModel::Assemble(DefaultModelSpec());
  auto sys = BuildComplianceSystem(model);
  auto ss = CalcStateSpace(sys);
  EXPECT_EQ(ss.A.rows(), 54);
  ExpectSameFrf(sys, ss);
}

TEST(StateSpace, GroundMotionInputsNeedNoDerivativeAndMatchDirectSolve) {
  auto model = AssembledModel::Assemble(DefaultModelSpec());
  std::vector<OutputSpec> outputs = FrameMotionOutputs(model.spec(), "X");
  for (const auto& o : BodyCoMOutputs(model.spec(), "granite")) outputs.push_back(o);
  auto sys = BuildSystem(model, GroundInputs(model), outputs);
  ExpectSameFrf(sys, CalcStateSpace(sys));
}

TEST(StateSpace, GroundMotionAtLowFrequencyMovesEverythingRigidly) {
  // Far below the first mode the stack follows the ground: absolute displacement / ground
  // displacement -> identity for the translations.
  auto model = AssembledModel::Assemble(DefaultModelSpec());
  auto sys = BuildSystem(model, GroundInputs(model), FrameMotionOutputs(model.spec(), "X"));
  Eigen::MatrixXcd H = DirectFrf(sys, 2 * M_PI * 0.01);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(std::abs(H(i, j)), i == j ? 1.0 : 0.0, 1e-5);
  }
}

TEST(StateSpace, EigenvaluesAreTheModes) {
  auto model = AssembledModel::Assemble(DefaultModelSpec());
  auto ss = CalcStateSpace(BuildComplianceSystem(model));
  auto modes = CalcModes(model);
  const auto eig = CalcEigenPairs(ss.A, /*with_vectors=*/false);
  ASSERT_TRUE(eig);
  for (const auto& m : modes.modes) {
    double best = 1e300;
    for (int k = 0; k < eig->values.size(); ++k) best = std::min(best, std::abs(eig->values(k) - m.eigenvalue));
    EXPECT_LE(best, 1e-8 * std::abs(m.eigenvalue));
  }
}

TEST(StateSpace, HystereticLossBecomesEquivalentViscousAtResonance) {
  // Single DoF with loss factor eta: the equivalent viscous damping at resonance is c = eta k / w_n,
  // so the state space's damping ratio is eta / 2.
  ModelSpec spec;
  spec.compliance_frame = "";
  BodySpec b;
  b.name = "m";
  b.mass_kg = 4.0;
  b.inertia_com_W = Eigen::Matrix3d::Identity();
  spec.bodies.push_back(b);
  JointSpec j;
  j.name = "j";
  j.parent = "ground";
  j.child = "m";
  j.imposed = {true, true, false, true, true, true};
  j.stiffness[2] = 1e6;
  j.loss_factor[2] = 0.04;
  spec.joints.push_back(j);
  auto model = AssembledModel::Assemble(spec);
  OutputSpec out;
  out.kind = OutputSpec::Kind::kJointMotion;
  out.name = "z";
  out.joint = "j";
  out.dof = Dof::kDz;
  InputSpec in;
  in.kind = InputSpec::Kind::kJointForce;
  in.name = "f";
  in.joint = "j";
  in.dof = Dof::kDz;
  auto ss = CalcStateSpace(BuildSystem(model, {in}, {out}));
  ASSERT_EQ(ss.notes.size(), 1u);
  const auto eig = CalcEigenPairs(ss.A, /*with_vectors=*/false);
  ASSERT_TRUE(eig);
  const Complex lambda = eig->values(0);
  EXPECT_NEAR(-lambda.real() / std::abs(lambda), 0.02, 1e-12);
}

}  // namespace
}  // namespace stagefit::model
