#include "stagefit/measurement/projection.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <random>
#include <string>

#include "stagefit/common/error.h"
#include "stagefit/common/units.h"

namespace stagefit::measurement {
namespace {

using Complex = std::complex<double>;

constexpr double d = 0.14;            // SPEC §2 lever arm, m
const Eigen::Vector3d kOrigin(0.0, 0.0, -0.03);  // {X} origin in W (SPEC §2)

// J_a and J_F are exact sums of products of d with 0 and +-1; the only rounding is in forming
// r = p_WS - p_WXo (positions are stored in W), a few ulps of 0.14.
constexpr double kJacobianTolerance = 1e-15;
// H_X = pinv(J_a) J_a H_X J_F' pinv(J_F'): the projectors are identities up to the rounding of the
// SVD of a 12 x 6 (10 x 6) matrix with condition number ~ 10; 1e-12 relative leaves a margin of 100.
constexpr double kRecoveryTolerance = 1e-12;

ChannelGeometry Channel(const std::string& name, const Eigen::Vector3d& r_XS,
                        const Eigen::Vector3d& n) {
  ChannelGeometry c;
  c.name = name;
  c.body = "hexapod";
  c.position_W = kOrigin + r_XS;
  c.direction_W = n;
  return c;
}

std::vector<ChannelGeometry> SpecSensors() {
  const Eigen::Vector3d pos[4] = {{0, d, 0}, {-d, 0, 0}, {0, -d, 0}, {d, 0, 0}};
  const char* axis = "xyz";
  std::vector<ChannelGeometry> sensors;
  for (int s = 0; s < 4; ++s) {
    for (int k = 0; k < 3; ++k) {
      sensors.push_back(Channel("a" + std::to_string(s + 1) + axis[k], pos[s],
                                Eigen::Vector3d::Unit(k)));
    }
  }
  return sensors;
}

std::vector<ChannelGeometry> SpecImpacts() {
  const Eigen::Vector3d pos[10] = {{0, d, 0},  {0, d, 0},  {-d, 0, 0}, {-d, 0, 0}, {0, -d, 0},
                                   {0, -d, 0}, {d, 0, 0},  {d, 0, 0},  {0, -d, 0}, {0, d, 0}};
  const Eigen::Vector3d dir[10] = {{0, -1, 0}, {0, 0, -1}, {1, 0, 0},  {0, 0, -1}, {0, 1, 0},
                                   {0, 0, -1}, {-1, 0, 0}, {0, 0, -1}, {-1, 0, 0}, {-1, 0, 0}};
  std::vector<ChannelGeometry> impacts;
  for (int i = 0; i < 10; ++i) impacts.push_back(Channel("F" + std::to_string(i + 1), pos[i], dir[i]));
  return impacts;
}

// The seed's J_a (2.1), written out by hand: row = [n', (r x n)'].
Eigen::MatrixXd SeedJa() {
  Eigen::MatrixXd J(12, 6);
  J << 1, 0, 0, 0, 0, -d,   // a1x at (0, d, 0)
       0, 1, 0, 0, 0, 0,    // a1y
       0, 0, 1, d, 0, 0,    // a1z
       1, 0, 0, 0, 0, 0,    // a2x at (-d, 0, 0)
       0, 1, 0, 0, 0, -d,   // a2y
       0, 0, 1, 0, d, 0,    // a2z
       1, 0, 0, 0, 0, d,    // a3x at (0, -d, 0)
       0, 1, 0, 0, 0, 0,    // a3y
       0, 0, 1, -d, 0, 0,   // a3z
       1, 0, 0, 0, 0, 0,    // a4x at (d, 0, 0)
       0, 1, 0, 0, 0, d,    // a4y
       0, 0, 1, 0, -d, 0;   // a4z
  return J;
}

// The seed's J_F (2.3), written out by hand: row = [n', (r x n)'].
Eigen::MatrixXd SeedJF() {
  Eigen::MatrixXd J(10, 6);
  J << 0, -1, 0, 0, 0, 0,    // 1: (0, d, 0; -y)
       0, 0, -1, -d, 0, 0,   // 2: (0, d, 0; -z)
       1, 0, 0, 0, 0, 0,     // 3: (-d, 0, 0; +x)
       0, 0, -1, 0, -d, 0,   // 4: (-d, 0, 0; -z)
       0, 1, 0, 0, 0, 0,     // 5: (0, -d, 0; +y)
       0, 0, -1, d, 0, 0,    // 6: (0, -d, 0; -z)
       -1, 0, 0, 0, 0, 0,    // 7: (d, 0, 0; -x)
       0, 0, -1, 0, d, 0,    // 8: (d, 0, 0; -z)
       -1, 0, 0, 0, 0, -d,   // 9: (0, -d, 0; -x)
       -1, 0, 0, 0, 0, d;    // 10: (0, d, 0; -x)
  return J;
}

Eigen::MatrixXcd RandomComplex(int rows, int cols, std::mt19937& rng) {
  std::normal_distribution<double> normal;
  Eigen::MatrixXcd m(rows, cols);
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) m(i, j) = Complex(normal(rng), normal(rng));
  }
  return m;
}

// Raw data H_L = J_a H_X J_F' from a seeded random 6 x 6 H_X(f) at frequencies 1..1000 Hz.
struct Synthetic {
  FrfData raw;
  std::vector<Eigen::MatrixXcd> H_X;
};

Synthetic MakeRigidData(const std::vector<ChannelGeometry>& sensors, unsigned seed) {
  std::mt19937 rng(seed);
  Synthetic s;
  const int nf = 200;
  s.raw.frequency_hz = Eigen::VectorXd::LinSpaced(nf, 1.0, 1000.0);
  s.raw.outputs = sensors;
  s.raw.inputs = SpecImpacts();
  s.raw.source = "synthetic";
  const Eigen::MatrixXcd J_a = SeedJa().cast<Complex>();
  const Eigen::MatrixXcd J_Ft = SeedJF().transpose().cast<Complex>();
  for (int f = 0; f < nf; ++f) {
    s.H_X.push_back(RandomComplex(6, 6, rng));
    s.raw.frf.push_back(J_a * s.H_X.back() * J_Ft);
  }
  return s;
}

TEST(CalcSensorJacobian, EqualsSeedMatrixElementByElement) {
  const Eigen::MatrixXd J_a = CalcSensorJacobian(SpecSensors(), kOrigin);
  const Eigen::MatrixXd seed = SeedJa();
  ASSERT_EQ(J_a.rows(), 12);
  ASSERT_EQ(J_a.cols(), 6);
  for (int i = 0; i < 12; ++i) {
    for (int j = 0; j < 6; ++j) {
      EXPECT_NEAR(J_a(i, j), seed(i, j), kJacobianTolerance) << "row " << i << " col " << j;
    }
  }
}

TEST(CalcImpactJacobian, EqualsSeedMatrixElementByElement) {
  const Eigen::MatrixXd J_F = CalcImpactJacobian(SpecImpacts(), kOrigin);
  const Eigen::MatrixXd seed = SeedJF();
  ASSERT_EQ(J_F.rows(), 10);
  ASSERT_EQ(J_F.cols(), 6);
  for (int i = 0; i < 10; ++i) {
    for (int j = 0; j < 6; ++j) {
      EXPECT_NEAR(J_F(i, j), seed(i, j), kJacobianTolerance) << "row " << i << " col " << j;
    }
  }
}

TEST(CalcImpactJacobian, GivesTheWrenchOfEachImpact) {
  // F_X = J_F' F_L: a unit force at impact 4 (-z at (-d, 0, 0)) is Fz = -1 and My = r x F = -d.
  Eigen::VectorXd F_L = Eigen::VectorXd::Zero(10);
  F_L(3) = 1.0;
  const Eigen::VectorXd F_X = CalcImpactJacobian(SpecImpacts(), kOrigin).transpose() * F_L;
  Eigen::VectorXd expected(6);
  expected << 0, 0, -1, 0, -d, 0;
  EXPECT_LT((F_X - expected).norm(), kJacobianTolerance);
}

TEST(ProjectToFrame, RecoversRigidComplianceToMachinePrecision) {
  const Synthetic s = MakeRigidData(SpecSensors(), 20240611u);
  const FrfData projected = ProjectToFrame(s.raw, kOrigin);
  ASSERT_EQ(projected.num_outputs(), 6);
  ASSERT_EQ(projected.num_inputs(), 6);
  EXPECT_EQ(projected.outputs[0].name, "Dx");
  EXPECT_EQ(projected.outputs[5].name, "Rz");
  EXPECT_EQ(projected.inputs[3].name, "Mx");
  ASSERT_TRUE(projected.frame_origin_W.has_value());
  EXPECT_EQ(*projected.frame_origin_W, kOrigin);
  for (int f = 0; f < projected.num_frequencies(); ++f) {
    const double error = (projected.frf[f] - s.H_X[f]).norm() / s.H_X[f].norm();
    EXPECT_LT(error, kRecoveryTolerance) << "at " << projected.frequency_hz(f) << " Hz";
  }
}

TEST(ProjectToFrame, UsesTheFileFrameOriginOverTheDefault) {
  Synthetic s = MakeRigidData(SpecSensors(), 7u);
  s.raw.frame_origin_W = kOrigin;
  const FrfData projected = ProjectToFrame(s.raw, Eigen::Vector3d(1.0, 2.0, 3.0));
  EXPECT_LT((projected.frf[0] - s.H_X[0]).norm() / s.H_X[0].norm(), kRecoveryTolerance);
}

TEST(ProjectToFrame, NamesTheUnobservableDofWhenSensorsOnlyMeasureVertically) {
  std::vector<ChannelGeometry> sensors;
  for (const ChannelGeometry& c : SpecSensors()) {
    if (c.name.back() == 'z') sensors.push_back(c);
  }
  Synthetic s = MakeRigidData(SpecSensors(), 3u);
  s.raw.outputs = sensors;
  for (auto& H : s.raw.frf) {
    Eigen::MatrixXcd z(4, 10);
    for (int k = 0; k < 4; ++k) z.row(k) = H.row(3 * k + 2);
    H = z;
  }
  try {
    ProjectToFrame(s.raw, kOrigin);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("sensors"), std::string::npos) << message;
    EXPECT_NE(message.find("Dx (1.00)"), std::string::npos) << message;
    EXPECT_NE(message.find("Dy (1.00)"), std::string::npos) << message;
    EXPECT_NE(message.find("Rz (1.00)"), std::string::npos) << message;
    EXPECT_EQ(message.find("Dz ("), std::string::npos) << message;
    EXPECT_EQ(message.find("Rx ("), std::string::npos) << message;
  }
}

TEST(CheckObservable, NamesRzWhenAllImpactsPassThroughTheOrigin) {
  // Impacts along x, y, z at the origin and -z at (+-d, 0, 0), (0, d, 0): no lever about z.
  std::vector<ChannelGeometry> impacts = {
      Channel("F1", {0, 0, 0}, {1, 0, 0}),  Channel("F2", {0, 0, 0}, {0, 1, 0}),
      Channel("F3", {0, 0, 0}, {0, 0, 1}),  Channel("F4", {d, 0, 0}, {0, 0, -1}),
      Channel("F5", {0, d, 0}, {0, 0, -1}), Channel("F6", {-d, 0, 0}, {0, 0, -1})};
  const Eigen::MatrixXd J_F = CalcImpactJacobian(impacts, kOrigin);
  try {
    CheckObservable(J_F, "impacts");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("cannot observe Rz (1.00)"), std::string::npos) << message;
    EXPECT_NE(message.find("rank 5"), std::string::npos) << message;
  }
}

TEST(ProjectPerBody, ProjectsEachBodyToItsCentreOfMass) {
  // Body "ty" carries the SPEC sensor layout shifted to its CoM; body "hexapod" the layout at {X}.
  std::mt19937 rng(99u);
  const Eigen::Vector3d p_WTy(0.0, 0.0, -0.62);
  std::vector<ChannelGeometry> sensors = SpecSensors();
  for (ChannelGeometry c : SpecSensors()) {
    c.name = "ty." + c.name;
    c.body = "ty";
    c.position_W = c.position_W - kOrigin + p_WTy;
    sensors.push_back(c);
  }
  FrfData raw;
  raw.frequency_hz = Eigen::VectorXd::LinSpaced(5, 10.0, 50.0);
  raw.outputs = sensors;
  raw.inputs = SpecImpacts();
  const Eigen::MatrixXcd J_a = SeedJa().cast<Complex>();
  const Eigen::MatrixXcd J_Ft = SeedJF().transpose().cast<Complex>();
  std::vector<Eigen::MatrixXcd> expected;
  for (int f = 0; f < 5; ++f) {
    const Eigen::MatrixXcd H_hex = RandomComplex(6, 6, rng);
    const Eigen::MatrixXcd H_ty = RandomComplex(6, 6, rng);
    Eigen::MatrixXcd H_L(24, 10);
    H_L << J_a * H_hex * J_Ft, J_a * H_ty * J_Ft;
    raw.frf.push_back(H_L);
    Eigen::MatrixXcd e(12, 6);
    e << H_hex, H_ty;
    expected.push_back(e);
  }
  const std::map<std::string, Eigen::Vector3d> coms = {{"hexapod", kOrigin}, {"ty", p_WTy}};
  const FrfData out = ProjectPerBody(raw, coms, InputProjection::kBodyCom);
  ASSERT_EQ(out.num_outputs(), 12);
  ASSERT_EQ(out.num_inputs(), 6);
  EXPECT_EQ(out.outputs[0].name, "hexapod.Dx");
  EXPECT_EQ(out.outputs[11].name, "ty.Rz");
  EXPECT_EQ(out.inputs[5].name, "hexapod.Mz");
  for (int f = 0; f < 5; ++f) {
    EXPECT_LT((out.frf[f] - expected[f]).norm() / expected[f].norm(), kRecoveryTolerance);
  }
  const FrfData raw_inputs = ProjectPerBody(raw, coms, InputProjection::kRaw);
  ASSERT_EQ(raw_inputs.num_inputs(), 10);
  EXPECT_EQ(raw_inputs.inputs[0].name, "F1");
  const Eigen::MatrixXcd expected_raw = expected[0] * J_Ft;
  EXPECT_LT((raw_inputs.frf[0] - expected_raw).norm() / expected_raw.norm(), kRecoveryTolerance);
}

TEST(ProjectPerBody, RejectsABodyWithoutCentreOfMass) {
  const Synthetic s = MakeRigidData(SpecSensors(), 5u);
  EXPECT_THROW(ProjectPerBody(s.raw, {{"ty", kOrigin}}), InputError);
}

TEST(ConvertQuantity, MultipliesByPowersOfJOmega) {
  FrfData data;
  data.frequency_hz = Eigen::VectorXd::Constant(1, 10.0);
  data.frf = {Eigen::MatrixXcd::Constant(1, 1, Complex(2.0, 1.0))};
  data.quantity = FrfQuantity::kAccelerance;
  const double w = 2.0 * kPi * 10.0;
  const FrfData receptance = ConvertQuantity(data, FrfQuantity::kReceptance);
  EXPECT_LT(std::abs(receptance.frf[0](0, 0) - Complex(2.0, 1.0) / (-w * w)), 1e-15);
  const FrfData mobility = ConvertQuantity(data, FrfQuantity::kMobility);
  EXPECT_LT(std::abs(mobility.frf[0](0, 0) - Complex(2.0, 1.0) / Complex(0.0, w)), 1e-15);
  const FrfData back = ConvertQuantity(receptance, FrfQuantity::kAccelerance);
  EXPECT_LT(std::abs(back.frf[0](0, 0) - Complex(2.0, 1.0)), 1e-14);
  EXPECT_EQ(back.quantity, FrfQuantity::kAccelerance);
}

TEST(MakeFractionalOctaveBands, CoversTheRangeWithNominalCentres) {
  const auto bands = MakeFractionalOctaveBands(20.0, 2000.0, 3);
  ASSERT_FALSE(bands.empty());
  EXPECT_LE(bands.front().low_hz, 20.0);
  EXPECT_GE(bands.back().high_hz, 2000.0);
  for (std::size_t b = 1; b < bands.size(); ++b) {
    EXPECT_NEAR(bands[b].low_hz, bands[b - 1].high_hz, 1e-9 * bands[b].low_hz);
  }
  bool has_1k = false;
  for (const auto& b : bands) has_1k |= std::abs(b.centre_hz() - 1000.0) < 1e-9;
  EXPECT_TRUE(has_1k);
  EXPECT_THROW(MakeFractionalOctaveBands(0.0, 10.0, 3), InputError);
}

TEST(BandOfEachFrequency, HalfOpenBandsWithTheLastClosed) {
  const std::vector<FrequencyBand> bands = {{10.0, 20.0}, {20.0, 40.0}};
  Eigen::VectorXd f(7);
  f << 5.0, 10.0, 19.999, 20.0, 39.999, 40.0, 40.001;
  const std::vector<int> expected = {-1, 0, 0, 1, 1, 1, -1};
  EXPECT_EQ(BandOfEachFrequency(f, bands), expected);
  EXPECT_EQ(BandOfEachFrequency(f, {}), std::vector<int>(7, -1));
}

TEST(CalcRigidConsistency, IsZeroForRigidData) {
  const Synthetic s = MakeRigidData(SpecSensors(), 11u);
  const RigidConsistency c = CalcRigidConsistency(s.raw, kOrigin);
  ASSERT_GT(c.bands.size(), 5u);
  // Rigid data lies in the range of J_a: the residual is rounding, |R|^2/|H|^2 ~ (1e-15)^2.
  EXPECT_LT(c.output_residual_share.maxCoeff(), 1e-24);
  EXPECT_LT(c.input_residual_share.maxCoeff(), 1e-24);
}

TEST(CalcRigidConsistency, FlagsALocalModeOnOneChannelOnlyInItsBand) {
  // A local resonance seen by channel a2y only, confined to 40-60 Hz: a smooth bump
  // sin^2(pi (f - 40)/20) times a resonant factor, added to every input's FRF of that channel.
  // (An in-plane channel: the 8 x/y channels observe 3 DoF, so a residual stays mostly on the
  // channel that causes it; the 4 z channels observe 3 DoF and share a single redundancy, so a
  // residual of one of them shows equally on all four.)
  Synthetic s = MakeRigidData(SpecSensors(), 21u);
  const int channel = 4;  // a2y
  for (int f = 0; f < s.raw.num_frequencies(); ++f) {
    const double fhz = s.raw.frequency_hz(f);
    if (fhz <= 40.0 || fhz >= 60.0) continue;
    const double bump = std::pow(std::sin(kPi * (fhz - 40.0) / 20.0), 2);
    const Complex mode = 1.0 / Complex(1.0 - std::pow(fhz / 50.0, 2), 0.5 * fhz / 50.0);
    s.raw.frf[f].row(channel) += 0.1 * bump * mode * s.raw.frf[f].row(channel).norm() *
                                 Eigen::RowVectorXcd::Ones(10) / std::sqrt(10.0);
  }
  std::vector<FrequencyBand> bands = {{20.0, 40.0}, {40.0, 60.0}, {60.0, 120.0},
                                      {120.0, 500.0}, {500.0, 1001.0}};
  const RigidConsistency c = CalcRigidConsistency(s.raw, kOrigin, bands);
  ASSERT_EQ(c.bands.size(), bands.size());
  // In the band: |delta|^2 / |H|^2 averages 0.1^2 * <sin^4> * <|mode|^2> ~ 0.01 * 0.375 * 2.5
  // ~ 1e-2, and a fraction (1 - P_ii)^2 ~ 0.35 of it (P_ii ~ 0.4, leverage of a2y among the
  // in-plane channels) cannot be a rigid motion: ~ 3e-3. The rest of the perturbation moves the
  // rigid estimate and shows on the other in-plane channels, less than on a2y itself.
  EXPECT_GT(c.output_residual_share(channel, 1), 1e-3);
  EXPECT_LT(c.output_residual_share(channel, 1), 1e-2);
  Eigen::Index worst = -1;
  c.output_residual_share.col(1).maxCoeff(&worst);
  EXPECT_EQ(worst, channel);
  EXPECT_GT(c.output_overall(1), 1e-4);
  EXPECT_GT(c.input_overall(1), 1e-4);
  // Elsewhere the data are exactly rigid: the shares are rounding (< 1e-24).
  for (int b : {0, 2, 3, 4}) {
    EXPECT_LT(c.output_residual_share.col(b).maxCoeff(), 1e-24) << "band " << b;
    EXPECT_LT(c.output_overall(b), 1e-24) << "band " << b;
    EXPECT_LT(c.input_overall(b), 1e-24) << "band " << b;
  }
}

TEST(CalcRigidConsistency, FlagsAnAccelerometerRotatedByTenDegrees) {
  // The data come from a1x turned 10 deg about z towards y; the geometry says +x.
  std::vector<ChannelGeometry> actual = SpecSensors();
  const double angle = 10.0 * kPi / 180.0;
  actual[0].direction_W = Eigen::Vector3d(std::cos(angle), std::sin(angle), 0.0);
  const Eigen::MatrixXd J_actual = CalcSensorJacobian(actual, kOrigin);
  Synthetic s = MakeRigidData(SpecSensors(), 31u);
  const Eigen::MatrixXcd J_Ft = SeedJF().transpose().cast<Complex>();
  for (int f = 0; f < s.raw.num_frequencies(); ++f) {
    s.raw.frf[f] = J_actual.cast<Complex>() * s.H_X[f] * J_Ft;
  }
  const RigidConsistency c = CalcRigidConsistency(s.raw, kOrigin);
  // Expected size: the rotation changes the row by |dn| = 2 sin(5 deg) = 0.17 of a unit direction,
  // i.e. a relative error ~ 0.17 on a row of comparable magnitude, of which a fraction of order
  // 1 - P_ii remains: ~ 1e-2 of the energy. Bounds [1e-3, 1e-1] in every band.
  for (std::size_t b = 0; b < c.bands.size(); ++b) {
    EXPECT_GT(c.output_residual_share(0, b), 1e-3) << "band " << b;
    EXPECT_LT(c.output_residual_share(0, b), 1e-1) << "band " << b;
    Eigen::Index worst = -1;
    c.output_residual_share.col(b).maxCoeff(&worst);
    EXPECT_EQ(worst, 0) << "band " << b;
    // Channels that observe no y-x coupling with a1x (the z channels) see none of the residual.
    EXPECT_LT(c.output_residual_share(2, b), 1e-20) << "band " << b;
  }
}

}  // namespace
}  // namespace stagefit::measurement
