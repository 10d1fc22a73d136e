#include "stagefit/model/assembled_model.h"

#include <gtest/gtest.h>

#include <cmath>

#include "stagefit/common/eigen_decomposition.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/modes.h"
#include "test_models.h"

namespace stagefit::model {
namespace {

// Frequencies are computed by a dense eigen-solver from exactly assembled matrices: agreement with the
// closed forms is limited only by rounding, about 1e-12 relative for these well-conditioned cases.
constexpr double kFrequencyRelTol = 1e-9;

std::vector<double> Frequencies(const AssembledModel& m) {
  NormalModes modes = CalcNormalModes(m.M(), m.K());
  std::vector<double> f;
  for (int i = 0; i < modes.omega_rad_s.size(); ++i) f.push_back(modes.omega_rad_s(i));
  return f;
}

TEST(AssembledModel, SingleBodyAtJointMatchesClosedForm) {
  const double m = 12.0;
  const Eigen::Vector3d I(0.5, 0.7, 0.9);
  const std::array<double, 6> k = {1e6, 2e6, 3e6, 4e4, 5e4, 6e4};
  auto model = AssembledModel::Assemble(testing::SingleBody(m, I, Eigen::Vector3d(0.1, -0.2, 0.3),
                                                            Eigen::Vector3d(0.1, -0.2, 0.3), k));
  std::vector<double> expected = {std::sqrt(k[0] / m), std::sqrt(k[1] / m), std::sqrt(k[2] / m),
                                  std::sqrt(k[3] / I(0)), std::sqrt(k[4] / I(1)), std::sqrt(k[5] / I(2))};
  std::sort(expected.begin(), expected.end());
  auto f = Frequencies(model);
  ASSERT_EQ(f.size(), 6u);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(f[i], expected[i], kFrequencyRelTol * expected[i]);
}

TEST(AssembledModel, CoMAboveJointCouplesTranslationAndTilt) {
  // CoM a height h above the joint: x of the joint point and tilt theta_y couple through the mass,
  // M = [m, m h; m h, Iyy + m h^2], K = diag(kx, kry). det(K - w^2 M) = 0 gives
  // m Iyy w^4 - (kx (Iyy + m h^2) + kry m) w^2 + kx kry = 0.
  const double m = 20.0, h = 0.25, kx = 1e6, kry = 3e4;
  const Eigen::Vector3d I(0.4, 0.6, 0.8);
  auto model = AssembledModel::Assemble(testing::SingleBody(m, I, Eigen::Vector3d(0, 0, h), Eigen::Vector3d::Zero(),
                                                            {kx, 5e6, 7e6, 9e4, kry, 2e5}));
  const int ix = model.dof_index(0, Dof::kDx), iry = model.dof_index(0, Dof::kRy);
  EXPECT_DOUBLE_EQ(model.M()(ix, iry), m * h);
  EXPECT_DOUBLE_EQ(model.M()(iry, iry), I(1) + m * h * h);
  const double a = m * I(1), b = -(kx * (I(1) + m * h * h) + kry * m), c = kx * kry;
  const double disc = std::sqrt(b * b - 4 * a * c);
  const double w1 = std::sqrt((-b - disc) / (2 * a)), w2 = std::sqrt((-b + disc) / (2 * a));
  auto f = Frequencies(model);
  auto near = [&](double w) {
    for (double x : f) {
      if (std::abs(x - w) <= kFrequencyRelTol * w) return true;
    }
    return false;
  };
  EXPECT_TRUE(near(w1)) << w1;
  EXPECT_TRUE(near(w2)) << w2;
}

TEST(AssembledModel, TwoBodyChainMatchesHandDerivedSystem) {
  // ground -k1- m1 -k2- m2 along z; relative coordinates z1 = x1, z2 = x2 - x1:
  // M = [m1 + m2, m2; m2, m2], K = diag(k1, k2).
  const double m1 = 100, m2 = 10, k1 = 4e7, k2 = 1e6;
  ModelSpec spec;
  spec.compliance_frame = "";
  for (auto [name, m, z] : {std::tuple{"lower", m1, 0.0}, std::tuple{"upper", m2, 0.5}}) {
    BodySpec b;
    b.name = name;
    b.mass_kg = m;
    b.com_W = Eigen::Vector3d(0, 0, z);
    b.inertia_com_W = Eigen::Matrix3d::Identity();
    spec.bodies.push_back(b);
  }
  for (auto [name, parent, child, k] :
       {std::tuple{"j1", "ground", "lower", k1}, std::tuple{"j2", "lower", "upper", k2}}) {
    JointSpec j;
    j.name = name;
    j.parent = parent;
    j.child = child;
    j.imposed = {true, true, false, true, true, true};
    j.stiffness[2] = k;
    spec.joints.push_back(j);
  }
  auto model = AssembledModel::Assemble(spec);
  ASSERT_EQ(model.num_dofs(), 2);
  Eigen::Matrix2d M_expected, K_expected;
  M_expected << m1 + m2, m2, m2, m2;
  K_expected << k1, 0, 0, k2;
  EXPECT_TRUE(model.M().isApprox(M_expected, 1e-15));
  EXPECT_TRUE(model.K().isApprox(K_expected, 1e-15));
  // Absolute coordinates: [m1 0; 0 m2] x'' + [k1 + k2, -k2; -k2, k2] x = 0.
  Eigen::Matrix2d Ma, Ka;
  Ma << m1, 0, 0, m2;
  Ka << k1 + k2, -k2, -k2, k2;
  const auto eig = CalcGeneralizedSymmetricEigenPairs(Ka, Ma);
  ASSERT_TRUE(eig);
  auto f = Frequencies(model);
  for (int i = 0; i < 2; ++i) EXPECT_NEAR(f[i], std::sqrt(eig->values(i)), kFrequencyRelTol * f[i]);
}

TEST(AssembledModel, DefaultModelHas27DofAnd54States) {
  auto model = AssembledModel::Assemble(DefaultModelSpec());
  EXPECT_EQ(model.num_dofs(), 27);
  EXPECT_EQ(model.num_states(), 54);
  EXPECT_EQ(model.num_ground_inputs(), 3);
  EXPECT_EQ(model.dof_names().front(), "granite.Dx");
}

TEST(AssembledModel, MatricesAreSymmetricAndDefinite) {
  auto model = AssembledModel::Assemble(DefaultModelSpec());
  const double tol = 1e-12;
  EXPECT_LE((model.M() - model.M().transpose()).cwiseAbs().maxCoeff(), tol * model.M().cwiseAbs().maxCoeff());
  EXPECT_LE((model.K() - model.K().transpose()).cwiseAbs().maxCoeff(), tol * model.K().cwiseAbs().maxCoeff());
  EXPECT_LE((model.C() - model.C().transpose()).cwiseAbs().maxCoeff(), tol * model.C().cwiseAbs().maxCoeff());
  const auto m = CalcSymmetricEigenPairs(model.M()), k = CalcSymmetricEigenPairs(model.K());
  ASSERT_TRUE(m && k);
  EXPECT_GT(m->values.minCoeff(), 0.0);
  EXPECT_GE(k->values.minCoeff(), 0.0);
}

TEST(AssembledModel, ImposingADofRemovesExactlyOneMode) {
  ModelSpec spec = DefaultModelSpec();
  auto before = CalcModes(AssembledModel::Assemble(spec));
  spec.joints[4].imposed[index(Dof::kRz)] = true;  // hexapod Rz becomes a constraint
  spec.joints[4].stiffness[index(Dof::kRz)] = 0.0;
  spec.joints[4].damping[index(Dof::kRz)] = 0.0;
  auto model = AssembledModel::Assemble(spec);
  auto after = CalcModes(model);
  EXPECT_EQ(model.num_dofs(), 26);
  EXPECT_EQ(after.modes.size() + 1, before.modes.size());
  // The removed mode is the hexapod's torsion (about 201 Hz): no mode of that frequency is left.
  for (const auto& m : after.modes) EXPECT_GT(std::abs(m.frequency_hz - 200.92), 1.0);
}

TEST(AssembledModel, MassIsInvariantToJointPosition) {
  // The kinetic energy of a rigid motion does not depend on where the coordinates are measured:
  // a pure translation of the whole stack has kinetic energy 0.5 * total mass * v^2.
  auto model = AssembledModel::Assemble(DefaultModelSpec());
  Eigen::VectorXd z = Eigen::VectorXd::Zero(model.num_dofs());
  z(model.dof_index(0, Dof::kDx)) = 1.0;  // granite joint translation: everything moves rigidly
  double total_mass = 0;
  for (const auto& b : model.spec().bodies) total_mass += b.mass_kg;
  EXPECT_NEAR(z.dot(model.M() * z), total_mass, 1e-9 * total_mass);
}

TEST(AssembledModel, GyroscopicSpinSplitsRotorModesAsClosedForm) {
  // An axisymmetric rotor on rotational springs k about x and y, spinning at Omega about z:
  // It theta_x'' + Omega Ip theta_y' + k theta_x = 0 (and the mirror equation) gives the whirl
  // frequencies w = (+-Ip Omega + sqrt(Ip^2 Omega^2 + 4 It k)) / (2 It).
  const double It = 0.8, Ip = 1.4, k = 2e4, omega = 60.0;
  ModelSpec spec = testing::SingleBody(10.0, Eigen::Vector3d(It, It, Ip), Eigen::Vector3d::Zero(),
                                       Eigen::Vector3d::Zero(), {0, 0, 0, k, k, 0});
  spec.joints[0].imposed = {true, true, true, false, false, true};
  spec.joints[0].stiffness = {0, 0, 0, k, k, 0};
  spec.joints[0].spin_rate_rad_s = omega;
  auto model = AssembledModel::Assemble(spec);
  EXPECT_LE((model.G() + model.G().transpose()).cwiseAbs().maxCoeff(), 1e-12);
  auto modes = CalcModes(model);
  ASSERT_EQ(modes.modes.size(), 2u);
  const double root = std::sqrt(Ip * Ip * omega * omega + 4 * It * k);
  const double backward = (-Ip * omega + root) / (2 * It), forward = (Ip * omega + root) / (2 * It);
  EXPECT_NEAR(modes.modes[0].frequency_hz * 2 * M_PI, backward, 1e-9 * backward);
  EXPECT_NEAR(modes.modes[1].frequency_hz * 2 * M_PI, forward, 1e-9 * forward);
}

TEST(Modes, EnergySharesSumToOneAndNameTheHexapod) {
  auto model = AssembledModel::Assemble(DefaultModelSpec());
  auto modes = CalcModes(model);
  ASSERT_EQ(modes.modes.size(), 27u);
  for (const auto& m : modes.modes) {
    EXPECT_NEAR(m.strain_energy_share.sum(), 1.0, 1e-9);
    EXPECT_NEAR(m.kinetic_energy_share.sum(), 1.0, 1e-9);
    EXPECT_GT(m.damping_ratio, 0.0);
  }
  // The hexapod's vertical mode (15 kg on 1e8 N/m, about 410 Hz) is held by hexapod.Dz.
  bool found = false;
  for (const auto& m : modes.modes) {
    if (model.dof_names()[m.dominant_dof] == "hexapod.Dz") {
      found = true;
      EXPECT_NEAR(m.frequency_hz, std::sqrt(1e8 / 15.0) / (2 * M_PI), 20.0);
    }
  }
  EXPECT_TRUE(found);
}

}  // namespace
}  // namespace stagefit::model
