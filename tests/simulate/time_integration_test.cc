#include "stagefit/simulate/time_integration.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <unsupported/Eigen/MatrixFunctions>

#include <cmath>
#include <complex>
#include <random>

#include "stagefit/common/error.h"
#include "stagefit/model/assembled_model.h"
#include "stagefit/model/linear_system.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/state_space.h"

namespace stagefit::simulate {
namespace {

// Two exact evaluations of the same recurrence in double precision on a 54-state model whose state
// matrix has norm ~1e8 and a modal basis with condition ~1e4: 1e-8 of the signal's size is far above
// the rounding and far below any modelling difference.
constexpr double kSameRecurrenceRelTol = 1e-8;

model::StateSpace ComplianceStateSpace() {
  const auto model = model::AssembledModel::Assemble(model::DefaultModelSpec());
  return model::CalcStateSpace(model::BuildComplianceSystem(model));
}

model::StateSpace GroundToFrameStateSpace() {
  const auto model = model::AssembledModel::Assemble(model::DefaultModelSpec());
  return model::CalcStateSpace(
      model::BuildSystem(model, model::GroundInputs(model), model::FrameMotionOutputs(model.spec(), "X")));
}

TEST(DiscretiseZeroOrderHold, MatchesClosedFormOfFirstOrderLag) {
  model::StateSpace s;
  const double a = 30.0, dt = 1e-3;
  s.A = Eigen::MatrixXd::Constant(1, 1, -a);
  s.B = Eigen::MatrixXd::Constant(1, 1, 1.0);
  s.C = Eigen::MatrixXd::Constant(1, 1, 1.0);
  s.D = Eigen::MatrixXd::Zero(1, 1);
  const DiscreteStateSpace d = DiscretiseZeroOrderHold(s, dt);
  EXPECT_NEAR(d.Ad(0, 0), std::exp(-a * dt), 1e-15);
  EXPECT_NEAR(d.Bd(0, 0), (1 - std::exp(-a * dt)) / a, 1e-15);
}

TEST(DiscretiseZeroOrderHold, RejectsNonPositiveStep) {
  EXPECT_THROW(DiscretiseZeroOrderHold(ComplianceStateSpace(), 0.0), InputError);
}

TEST(ModalIntegrator, StepResponseEqualsExactSolutionOfMicroStation) {
  // For a step held from t = 0, x(t) = A^-1 (e^{A t} - I) B exactly, so ZOH must reproduce it at
  // every sample.
  const model::StateSpace s = ComplianceStateSpace();
  const double dt = 1e-4;
  const ModalIntegrator integrator(s, dt);
  ASSERT_TRUE(integrator.is_modal()) << integrator.message();
  const int steps = 400;
  Eigen::MatrixXd u = Eigen::MatrixXd::Zero(steps, 6);
  u.col(2).setConstant(1.0);  // Fz = 1 N at {X}
  const Eigen::MatrixXd y = integrator.Simulate(u);
  const Eigen::MatrixXd Ainv = s.A.partialPivLu().inverse();
  const Eigen::VectorXd static_response = -s.C * Ainv * s.B.col(2) + s.D.col(2);
  for (int k : {1, 17, 150, 399}) {
    const Eigen::MatrixXd Ak = (s.A * (k * dt)).exp();
    const Eigen::VectorXd exact = s.C * Ainv * (Ak - Eigen::MatrixXd::Identity(s.A.rows(), s.A.cols())) * s.B.col(2) +
                                  s.D.col(2);
    EXPECT_LE((y.row(k).transpose() - exact).norm(), kSameRecurrenceRelTol * static_response.norm()) << "k = " << k;
  }
}

TEST(ModalIntegrator, SineResponseMatchesFrequencyResponse) {
  // Steady state under a sampled sine: the held staircase's fundamental is the sine delayed by dt/2
  // and scaled by sinc(f dt), so y = Im(H(jw) e^{-jw dt/2} sinc e^{jwt}). What remains are the
  // staircase's image harmonics at fs -+ f, filtered by the structure: 1e-3 of the amplitude bounds
  // them with a wide margin.
  const model::StateSpace s = ComplianceStateSpace();
  const double dt = 1e-4, f = 47.0, w = 2 * M_PI * f;
  const int steps = 20000;
  Eigen::MatrixXd u = Eigen::MatrixXd::Zero(steps, 6);
  for (int k = 0; k < steps; ++k) u(k, 2) = std::sin(w * k * dt);
  const Eigen::MatrixXd y = ModalIntegrator(s, dt).Simulate(u);
  using Complex = std::complex<double>;
  const int n = static_cast<int>(s.A.rows());
  const Eigen::MatrixXcd sIA = Complex(0, w) * Eigen::MatrixXcd::Identity(n, n) - s.A.cast<Complex>();
  const Eigen::VectorXcd H =
      s.C.cast<Complex>() * sIA.partialPivLu().solve(s.B.col(2).cast<Complex>()) + s.D.col(2).cast<Complex>();
  const double sinc = std::sin(w * dt / 2) / (w * dt / 2);
  const Complex hold = std::exp(Complex(0, -w * dt / 2)) * sinc;
  double max_error = 0.0, max_amplitude = 0.0;
  for (int k = steps - 2000; k < steps; ++k) {
    for (int o = 0; o < 6; ++o) {
      const double expected = (H(o) * hold * std::exp(Complex(0, w * k * dt))).imag();
      max_error = std::max(max_error, std::abs(y(k, o) - expected));
      max_amplitude = std::max(max_amplitude, std::abs(H(o)));
    }
  }
  EXPECT_LE(max_error, 1e-3 * max_amplitude);
}

TEST(ModalIntegrator, AgreesWithDenseRecurrenceUnderGroundMotion) {
  const model::StateSpace s = GroundToFrameStateSpace();
  const double dt = 1e-4;
  const ModalIntegrator integrator(s, dt);
  ASSERT_TRUE(integrator.is_modal());
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal(0.0, 1e-8);
  Eigen::MatrixXd u(3000, 3);
  for (int k = 0; k < u.rows(); ++k) {
    for (int c = 0; c < 3; ++c) u(k, c) = normal(rng);
  }
  const Eigen::MatrixXd fast = integrator.Simulate(u);
  const Eigen::MatrixXd dense = SimulateDense(integrator.discrete(), u);
  EXPECT_LE((fast - dense).cwiseAbs().maxCoeff(), kSameRecurrenceRelTol * dense.cwiseAbs().maxCoeff());
}

TEST(SimulateRungeKutta4, ConvergesToZeroOrderHoldSolution) {
  // RK4 with the same held input differs from the exact ZOH solution by O(dt^4): with dt = 1e-5 s
  // and the fastest mode near 2 kHz (w dt ~ 0.1) the relative error is ~1e-5 / 120 per step.
  const model::StateSpace s = ComplianceStateSpace();
  const double dt = 1e-5;
  Eigen::MatrixXd u = Eigen::MatrixXd::Zero(2000, 6);
  u.col(0).setConstant(1.0);
  const Eigen::MatrixXd exact = SimulateDense(DiscretiseZeroOrderHold(s, dt), u);
  const Eigen::MatrixXd rk4 = SimulateRungeKutta4(s, dt, u);
  EXPECT_LE((exact - rk4).cwiseAbs().maxCoeff(), 1e-4 * exact.cwiseAbs().maxCoeff());
}

TEST(SimulateDense, RejectsWrongInputWidth) {
  const DiscreteStateSpace d = DiscretiseZeroOrderHold(ComplianceStateSpace(), 1e-4);
  EXPECT_THROW(SimulateDense(d, Eigen::MatrixXd::Zero(10, 5)), InputError);
}

}  // namespace
}  // namespace stagefit::simulate
