#include "stagefit/simulate/rotating_frame.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>

#include "stagefit/common/error.h"
#include "stagefit/model/linear_system.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/state_space.h"
#include "stagefit/simulate/time_integration.h"

namespace stagefit::simulate {
namespace {

// Eigenvalues of matrices of norm ~1e4 computed by QR iteration: 1e-8 rad/s is ~1e-12 relative.
constexpr double kEigenTol = 1e-8;

// A mass on springs kx, ky in x and y (every other DoF imposed), on a table turning about z.
model::ModelSpec MassOnTable(double m, double kx, double ky, double c) {
  model::ModelSpec spec;
  spec.name = "mass on a rotating table";
  spec.compliance_frame = "";
  spec.ground_inputs = {false, false, false};
  model::BodySpec b;
  b.name = "mass";
  b.mass_kg = m;
  b.inertia_com_W = Eigen::Vector3d(1, 1, 1).asDiagonal();
  spec.bodies.push_back(b);
  model::JointSpec j;
  j.name = "table";
  j.parent = model::kGroundName;
  j.child = "mass";
  j.stiffness = {kx, ky, 0, 0, 0, 0};
  j.damping = {c, c, 0, 0, 0, 0};
  j.imposed = {false, false, true, true, true, true};
  spec.joints.push_back(j);
  return spec;
}

// A disc on isotropic tilt springs kr (Rx, Ry free), polar inertia c, diametral a.
model::ModelSpec DiscOnTiltSprings(double a, double c, double kr) {
  model::ModelSpec spec = MassOnTable(1.0, 1.0, 1.0, 0.0);
  spec.bodies[0].inertia_com_W = Eigen::Vector3d(a, a, c).asDiagonal();
  spec.joints[0].stiffness = {0, 0, 0, kr, kr, 0};
  spec.joints[0].damping = {0, 0, 0, 0, 0, 0};
  spec.joints[0].imposed = {true, true, true, false, false, true};
  return spec;
}

std::vector<double> SortedPositiveFrequencies(const Eigen::VectorXcd& lambda) {
  std::vector<double> f;
  for (const auto& l : lambda) {
    if (l.imag() > 0) f.push_back(l.imag());
  }
  std::sort(f.begin(), f.end());
  return f;
}

TEST(AssembleCoRotatingModel, MassOnSpringsHasCoriolisAndCentrifugalTerms) {
  // m x'' - 2 m W y' + (k - m W^2) x = 0,  m y'' + 2 m W x' + (k - m W^2) y = 0.
  const double m = 2.0, k = 800.0, w = 5.0;
  const auto model = model::AssembledModel::Assemble(MassOnTable(m, k, k, 0.0));
  const CoRotatingModel r = AssembleCoRotatingModel(model, "table", w);
  Eigen::Matrix2d C_expected, K_expected;
  C_expected << 0, -2 * m * w, 2 * m * w, 0;
  K_expected << k - m * w * w, 0, 0, k - m * w * w;
  EXPECT_LE((r.M - m * Eigen::Matrix2d::Identity()).norm(), 1e-12);
  EXPECT_LE((r.C - C_expected).norm(), 1e-12);
  EXPECT_LE((r.K - K_expected).norm(), 1e-9);
}

TEST(AssembleCoRotatingModel, IsotropicMassHasFrequenciesShiftedBySpinRate) {
  const double m = 2.0, k = 800.0, w = 5.0, w0 = std::sqrt(k / m);
  const auto model = model::AssembledModel::Assemble(MassOnTable(m, k, k, 0.0));
  const CoRotatingModel r = AssembleCoRotatingModel(model, "table", w);
  const auto f = SortedPositiveFrequencies(CalcEigenvalues(r.M, r.C, r.K));
  ASSERT_EQ(f.size(), 2u);
  EXPECT_NEAR(f[0], w0 - w, kEigenTol);
  EXPECT_NEAR(f[1], w0 + w, kEigenTol);
}

TEST(AssembleCoRotatingModel, AnisotropicMassIsUnstableBetweenItsTwoFrequencies) {
  // Closed form: the rotating anisotropic oscillator diverges for sqrt(kx/m) < W < sqrt(ky/m).
  const double m = 1.0, kx = 100.0, ky = 144.0;
  const auto model = model::AssembledModel::Assemble(MassOnTable(m, kx, ky, 0.0));
  auto max_real = [&](double w) {
    const CoRotatingModel r = AssembleCoRotatingModel(model, "table", w);
    return CalcEigenvalues(r.M, r.C, r.K).real().maxCoeff();
  };
  EXPECT_GT(max_real(11.0), 1e-3);
  EXPECT_LT(max_real(9.0), 1e-9);
  EXPECT_LT(max_real(13.0), 1e-9);
}

TEST(AssembleCoRotatingModel, FreeResponseEqualsRotatedInertialResponse) {
  // Released from rest at (a, 0) in W, the undamped isotropic oscillator moves along x only:
  // r(t) = a cos(w0 t). Seen from the table, r~(t) = R(-W t) r(t), starting with
  // r~'(0) = -W e x r~(0) = (0, -W a). (Dampers turning with the table would add rotating damping,
  // which is not a plain damped oscillator in W; the undamped case has the simple closed form.)
  const double m = 2.0, k = 800.0, w = 3.0, a = 1e-6;
  const auto model = model::AssembledModel::Assemble(MassOnTable(m, k, k, 0.0));
  const CoRotatingModel r = AssembleCoRotatingModel(model, "table", w);
  model::SecondOrderSystem sys;
  sys.M = r.M;
  sys.C = r.C;
  sys.K = r.K;
  sys.K_loss = Eigen::MatrixXd::Zero(2, 2);
  sys.B0 = Eigen::MatrixXd::Identity(2, 2);
  sys.B2 = Eigen::MatrixXd::Zero(2, 2);
  sys.Cq = Eigen::MatrixXd::Identity(2, 2);
  sys.D0 = Eigen::MatrixXd::Zero(2, 2);
  const model::StateSpace ss = model::CalcStateSpace(sys);
  const double dt = 1e-3;
  const int steps = 3000;
  Eigen::VectorXd x0(4);
  x0 << a, 0, 0, -w * a;
  const Eigen::MatrixXd y = ModalIntegrator(ss, dt).Simulate(Eigen::MatrixXd::Zero(steps, 2), x0);
  const double w0 = std::sqrt(k / m);
  double max_error = 0.0;
  for (int n = 0; n < steps; ++n) {
    const double t = n * dt;
    const double inertial = a * std::cos(w0 * t);
    max_error = std::max(max_error, std::abs(y(n, 0) - inertial * std::cos(w * t)));
    max_error = std::max(max_error, std::abs(y(n, 1) + inertial * std::sin(w * t)));
  }
  // Exact discretisation of an exact model: only rounding remains (1e-9 of the amplitude).
  EXPECT_LE(max_error, 1e-9 * a);
}

TEST(AssembleCoRotatingModel, SpinningDiscMatchesInertialGyroscopicModelShiftedBySpinRate) {
  // The inertial-frame model (AssembledModel with spin_rate: gyroscopic matrix) and the co-rotating
  // model (gyroscopic (2a - c) W plus centrifugal (c - a) W^2 terms) describe the same motion: every
  // whirl frequency seen in W is shifted by exactly W in the rotating frame.
  const double a = 0.09, c = 0.17, kr = 1.5e3, w = 20.0;
  model::ModelSpec spec = DiscOnTiltSprings(a, c, kr);
  spec.joints[0].spin_rate_rad_s = w;
  const auto inertial = model::AssembledModel::Assemble(spec);
  const auto f_inertial = SortedPositiveFrequencies(CalcEigenvalues(inertial.M(), inertial.C(), inertial.K()));
  const auto f_rotating = SortedPositiveFrequencies([&] {
    const CoRotatingModel r = AssembleCoRotatingModel(inertial, "table", w);
    return CalcEigenvalues(r.M, r.C, r.K);
  }());
  ASSERT_EQ(f_inertial.size(), 2u);
  ASSERT_EQ(f_rotating.size(), 2u);
  // Backward whirl (lower in W) appears at f + W, forward whirl at f - W.
  std::vector<double> shifted = {std::abs(f_inertial[1] - w), f_inertial[0] + w};
  std::sort(shifted.begin(), shifted.end());
  EXPECT_NEAR(f_rotating[0], shifted[0], 1e-6);
  EXPECT_NEAR(f_rotating[1], shifted[1], 1e-6);
}

TEST(AssembleCoRotatingModel, RefusesAModelWhoseSupportDoesNotSpin) {
  const auto model = model::AssembledModel::Assemble(model::DefaultModelSpec());
  EXPECT_THROW(AssembleCoRotatingModel(model, "rz", 6.28), InputError);
}

TEST(FindSpinAsymmetries, MicroStationSpindleSubtreeIsAxisymmetric) {
  EXPECT_TRUE(FindSpinAsymmetries(model::DefaultModelSpec(), "rz").empty());
}

TEST(FindSpinAsymmetries, ReportsAnisotropicHexapodStiffness) {
  model::ModelSpec spec = model::DefaultModelSpec();
  spec.joints[model::FindJoint(spec, "hexapod")].stiffness[1] *= 1.5;
  const auto problems = FindSpinAsymmetries(spec, "rz");
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("hexapod"), std::string::npos);
}

}  // namespace
}  // namespace stagefit::simulate
