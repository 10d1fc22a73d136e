#include "stagefit/response/frf_evaluator.h"

#include <gtest/gtest.h>

#include <Eigen/LU>

#include <cmath>
#include <complex>
#include <thread>

#include "response_test_util.h"
#include "stagefit/common/eigen_decomposition.h"
#include "stagefit/common/error.h"
#include "stagefit/common/parallel.h"
#include "stagefit/model/model_file.h"
#include "stagefit/response/io_sets.h"

namespace stagefit::response {
namespace {

const FrfEvaluatorOptions kDirectOptions{FrfMethod::kDirect};
using Complex = std::complex<double>;
using testing::kStructuralZero;
using testing::LogFrequencies;
using testing::WorstRelativeToPeak;
constexpr Complex kJ(0.0, 1.0);

// Modal and direct paths agree to this fraction of each element's peak |H| over the frequency set
// (the accuracy requirement; rounding in either path is ~1e-13 for the micro-station).
constexpr double kPathAgreement = 1e-9;
// A closed-form response is matched to this fraction of its peak: both paths round at ~1e-15 on
// a 1-DoF system; the margin covers the eigen-solver's backward error.
constexpr double kClosedForm = 1e-12;

// One body of mass m on one spring: only Dz free.
model::ModelSpec SingleDofSpec(double k, double c, double eta, double m) {
  model::ModelSpec spec;
  spec.name = "single DoF";
  model::BodySpec body;
  body.name = "mass";
  body.mass_kg = m;
  body.inertia_com_W = Eigen::Matrix3d::Identity();
  spec.bodies.push_back(body);
  model::JointSpec joint;
  joint.name = "spring";
  joint.parent = model::kGroundName;
  joint.child = "mass";
  joint.imposed = {true, true, false, true, true, true};
  joint.stiffness[2] = k;
  joint.damping[2] = c;
  joint.loss_factor[2] = eta;
  spec.joints.push_back(joint);
  model::FrameSpec frame;
  frame.name = "X";
  frame.body = "mass";
  spec.frames.push_back(frame);
  spec.ground_inputs = {false, false, true};
  return spec;
}

model::OutputSpec MassDz() {
  model::OutputSpec out;
  out.kind = model::OutputSpec::Kind::kFrameMotion;
  out.name = "mass.Dz";
  out.body = "mass";
  out.dof = Dof::kDz;
  return out;
}

model::InputSpec ForceZ() {
  model::InputSpec in;
  in.kind = model::InputSpec::Kind::kForce;
  in.name = "Fz";
  in.body = "mass";
  in.direction_W = Eigen::Vector3d::UnitZ();
  return in;
}

// The reference: a dense complex solve of (K + j K_loss + j w C - w^2 M) z = B0 - w^2 B2, written
// independently of the evaluator.
Eigen::MatrixXcd DirectReference(const model::SecondOrderSystem& sys, double frequency_hz, int power) {
  const double w = 2 * M_PI * frequency_hz;
  Eigen::MatrixXcd Z = sys.K.cast<Complex>() + kJ * sys.K_loss.cast<Complex>() + kJ * w * sys.C.cast<Complex>() -
                       w * w * sys.M.cast<Complex>();
  Eigen::MatrixXcd F = (sys.B0 - w * w * sys.B2).cast<Complex>();
  Eigen::MatrixXcd H = sys.Cq.cast<Complex>() * Z.fullPivLu().solve(F) + sys.D0.cast<Complex>();
  return H * std::pow(kJ * w, power) * std::exp(-kJ * w * sys.delay_s);
}

Eigen::MatrixXcd ReferenceArray(const model::SecondOrderSystem& sys, const Eigen::VectorXd& f, int power) {
  Eigen::MatrixXcd values(f.size(), sys.num_outputs() * sys.num_inputs());
  for (Eigen::Index k = 0; k < f.size(); ++k) {
    const Eigen::MatrixXcd H = DirectReference(sys, f(k), power);
    for (int i = 0; i < sys.num_inputs(); ++i) {
      for (int o = 0; o < sys.num_outputs(); ++o) values(k, o + sys.num_outputs() * i) = H(o, i);
    }
  }
  return values;
}

// The default model with hysteretic loss, a coupling term and the spindle spinning at 60 rpm.
model::ModelSpec LossySpinningSpec() {
  model::ModelSpec spec = model::DefaultModelSpec();
  for (auto& joint : spec.joints) {
    for (int d = 0; d < 6; ++d) {
      if (!joint.imposed[d]) joint.loss_factor[d] = 0.01 + 0.002 * d;
    }
    if (joint.name == "rz") joint.spin_rate_rad_s = 2 * M_PI;
    if (joint.name == "hexapod") joint.couplings.push_back({Dof::kDx, Dof::kRy, 1e5, 3.0});
  }
  return spec;
}

model::ModelSpec SpinningSpec() {
  model::ModelSpec spec = model::DefaultModelSpec();
  for (auto& joint : spec.joints) {
    if (joint.name == "rz") joint.spin_rate_rad_s = 2 * M_PI;
  }
  return spec;
}


TEST(FrfEvaluator, SingleDofMatchesClosedFormForEveryQuantityAndPath) {
  const double k = 2e6, c = 80.0, eta = 0.03, m = 12.0;
  const auto spec = SingleDofSpec(k, c, eta, m);
  const auto assembled = model::AssembledModel::Assemble(spec);
  const auto sys = model::BuildSystem(assembled, {ForceZ()}, {MassDz()});
  const Eigen::VectorXd f = LogFrequencies(1.0, 500.0, 301);
  for (FrfMethod method : {FrfMethod::kModal, FrfMethod::kDirect}) {
    FrfEvaluatorOptions options;
    options.method = method;
    auto ev = FrfEvaluator::Create(sys, options);
    EXPECT_EQ(ev.path_used(), method);
    for (auto q : {ResponseQuantity::kReceptance, ResponseQuantity::kMobility, ResponseQuantity::kAccelerance}) {
      const FrfArray h = ev.Evaluate(f, q);
      Eigen::MatrixXcd expected(f.size(), 1);
      for (Eigen::Index i = 0; i < f.size(); ++i) {
        const double w = 2 * M_PI * f(i);
        expected(i, 0) = std::pow(kJ * w, SPower(q)) / (k * (1.0 + kJ * eta) - m * w * w + kJ * c * w);
      }
      EXPECT_LT(WorstRelativeToPeak(h.values, expected), kClosedForm) << ToString(method) << " " << ToString(q);
    }
  }
}

TEST(FrfEvaluator, SingleDofGroundTransmissibilityMatchesClosedForm) {
  // Absolute motion of the mass over the ground displacement: (k' + j c w) / (k' - m w^2 + j c w),
  // k' = k (1 + j eta). Exercises the B2 (inertial) and D0 (rigid translation) terms.
  const double k = 5e5, c = 40.0, eta = 0.02, m = 3.0;
  const auto spec = SingleDofSpec(k, c, eta, m);
  const auto assembled = model::AssembledModel::Assemble(spec);
  const auto sys = model::BuildSystem(assembled, model::GroundInputs(assembled), {MassDz()});
  ASSERT_EQ(sys.num_inputs(), 1);
  const Eigen::VectorXd f = LogFrequencies(0.5, 2000.0, 301);
  for (FrfMethod method : {FrfMethod::kModal, FrfMethod::kDirect}) {
    FrfEvaluatorOptions options;
    options.method = method;
    auto ev = FrfEvaluator::Create(sys, options);
    for (auto q : {ResponseQuantity::kReceptance, ResponseQuantity::kAccelerance}) {
      const FrfArray h = ev.Evaluate(f, q);
      Eigen::MatrixXcd expected(f.size(), 1);
      for (Eigen::Index i = 0; i < f.size(); ++i) {
        const double w = 2 * M_PI * f(i);
        const Complex kc = k * (1.0 + kJ * eta);
        expected(i, 0) = std::pow(kJ * w, SPower(q)) * (kc + kJ * c * w) / (kc - m * w * w + kJ * c * w);
      }
      EXPECT_LT(WorstRelativeToPeak(h.values, expected), kClosedForm) << ToString(method) << " " << ToString(q);
    }
  }
}

TEST(FrfEvaluator, DelayMultipliesEveryQuantityByItsPhase) {
  const auto assembled = model::AssembledModel::Assemble(model::DefaultModelSpec());
  auto sys = model::BuildComplianceSystem(assembled);
  const Eigen::VectorXd f = LogFrequencies(2.0, 1000.0, 97);
  auto plain = FrfEvaluator::Create(sys);
  sys.delay_s = 3.5e-4;
  auto delayed = FrfEvaluator::Create(sys);
  for (auto q : {ResponseQuantity::kReceptance, ResponseQuantity::kMobility, ResponseQuantity::kAccelerance}) {
    Eigen::MatrixXcd expected = plain.Evaluate(f, q).values;
    for (Eigen::Index i = 0; i < f.size(); ++i) expected.row(i) *= std::exp(-kJ * 2.0 * M_PI * f(i) * sys.delay_s);
    EXPECT_LT(WorstRelativeToPeak(delayed.Evaluate(f, q).values, expected), kPathAgreement) << ToString(q);
  }
}

TEST(FrfEvaluator, QuantitiesArePowersOfSTimesTheReceptance) {
  // On the direct path the receptance at each frequency is accurate to rounding relative to itself, so
  // s^p times it is a reference for the modal mobility and accelerance (a modal receptance is not: its
  // error is relative to its low-frequency peak, which s^2 amplifies at high frequency).
  const auto assembled = model::AssembledModel::Assemble(model::DefaultModelSpec());
  const auto sys = model::BuildSystem(assembled, model::ExcitationInputs(assembled.spec()),
                                      model::SensorOutputs(assembled.spec()));
  const Eigen::VectorXd f = LogFrequencies(1.0, 2000.0, 150);
  const FrfArray receptance = FrfEvaluator::Create(sys, kDirectOptions).Evaluate(f, ResponseQuantity::kReceptance);
  auto ev = FrfEvaluator::Create(sys);
  for (auto q : {ResponseQuantity::kMobility, ResponseQuantity::kAccelerance}) {
    Eigen::MatrixXcd expected = receptance.values;
    for (Eigen::Index i = 0; i < f.size(); ++i) expected.row(i) *= std::pow(kJ * 2.0 * M_PI * f(i), SPower(q));
    EXPECT_LT(WorstRelativeToPeak(ev.Evaluate(f, q).values, expected), kPathAgreement) << ToString(q);
  }
}

TEST(FrfEvaluator, ComplianceIsSymmetricWhenNothingSpins) {
  const auto assembled = model::AssembledModel::Assemble(model::DefaultModelSpec());
  auto ev = FrfEvaluator::Create(model::BuildComplianceSystem(assembled));
  const FrfArray h = ev.Evaluate(LogFrequencies(1.0, 2000.0, 200), ResponseQuantity::kReceptance);
  const double peak = h.values.cwiseAbs().maxCoeff();
  for (int f = 0; f < h.num_frequencies(); ++f) {
    const Eigen::MatrixXcd H = h.At(f);
    // Reciprocity H_ij = H_ji: the modal sum is symmetric to rounding (1e-12 of the peak).
    EXPECT_LT((H - H.transpose()).cwiseAbs().maxCoeff(), 1e-12 * peak) << "f = " << h.frequency_hz(f);
  }
}

TEST(FrfEvaluator, ComplianceIsNotSymmetricWhenTheSpindleSpins) {
  const auto assembled = model::AssembledModel::Assemble(SpinningSpec());
  auto ev = FrfEvaluator::Create(model::BuildComplianceSystem(assembled));
  const FrfArray h = ev.Evaluate(LogFrequencies(20.0, 2000.0, 200), ResponseQuantity::kReceptance);
  double asymmetry = 0.0;
  for (int f = 0; f < h.num_frequencies(); ++f) {
    const Eigen::MatrixXcd H = h.At(f);
    asymmetry = std::max(asymmetry, (H - H.transpose()).cwiseAbs().maxCoeff() / H.cwiseAbs().maxCoeff());
  }
  EXPECT_GT(asymmetry, 1e-9);
}

// The static compliance of a serial chain of joints: a unit wrench at {X} loads every joint with the
// same wrench moved to the joint origin; joint J's deflection K_J^-1 (free DoF only) moves {X} rigidly.
Eigen::Matrix<double, 6, 6> ChainStaticCompliance(const model::ModelSpec& spec) {
  const auto& frame = spec.frames[model::FindFrame(spec, spec.compliance_frame)];
  auto skew = [](const Eigen::Vector3d& r) {
    Eigen::Matrix3d s;
    s << 0, -r.z(), r.y(), r.z(), 0, -r.x(), -r.y(), r.x(), 0;
    return s;
  };
  Eigen::Matrix<double, 6, 6> compliance = Eigen::Matrix<double, 6, 6>::Zero();
  // Walk from {X}'s body down to the ground.
  std::string body = frame.body;
  while (body != model::kGroundName) {
    const model::JointSpec* joint = nullptr;
    for (const auto& j : spec.joints) {
      if (j.child == body) joint = &j;
    }
    Eigen::Matrix<double, 6, 6> T = Eigen::Matrix<double, 6, 6>::Zero();  // joint motion -> {X} motion
    T.topLeftCorner<3, 3>() = joint->R_WJ;
    T.topRightCorner<3, 3>() = -skew(frame.origin_W - joint->origin_W) * joint->R_WJ;
    T.bottomRightCorner<3, 3>() = joint->R_WJ;
    Eigen::Matrix<double, 6, 6> flexibility = Eigen::Matrix<double, 6, 6>::Zero();
    for (int d = 0; d < 6; ++d) {
      if (!joint->imposed[d]) flexibility(d, d) = 1.0 / joint->stiffness[d];
    }
    compliance += T * flexibility * T.transpose();
    body = joint->parent;
  }
  return compliance;
}

TEST(FrfEvaluator, StaticComplianceEqualsTheChainOfJointFlexibilities) {
  const auto spec = model::DefaultModelSpec();
  const auto assembled = model::AssembledModel::Assemble(spec);
  const Eigen::Matrix<double, 6, 6> expected = ChainStaticCompliance(spec);
  for (FrfMethod method : {FrfMethod::kAuto, FrfMethod::kDirect}) {
    FrfEvaluatorOptions options;
    options.method = method;
    auto ev = FrfEvaluator::Create(model::BuildComplianceSystem(assembled), options);
    const FrfArray h = ev.Evaluate(Eigen::VectorXd::Zero(1), ResponseQuantity::kReceptance);
    const Eigen::MatrixXcd H = h.At(0);
    EXPECT_LT(H.imag().cwiseAbs().maxCoeff(), 1e-14 * expected.cwiseAbs().maxCoeff());
    // Element-wise to 1e-9 of the row's largest element (the static solve conditions at ~1e5).
    for (int r = 0; r < 6; ++r) {
      const double scale = expected.row(r).cwiseAbs().maxCoeff();
      EXPECT_LT((H.real().row(r) - expected.row(r)).cwiseAbs().maxCoeff(), 1e-9 * scale)
          << ToString(method) << " row " << r << "\n" << H.real() << "\n" << expected;
    }
  }
}

struct PathCase {
  const char* label;
  model::ModelSpec spec;
  IoSet set;
};

TEST(FrfEvaluator, ModalPathAgreesWithDirectSolveOnEveryStudy) {
  const std::vector<PathCase> cases = {
      {"default compliance", model::DefaultModelSpec(), IoSet::kCompliance},
      {"default raw", model::DefaultModelSpec(), IoSet::kRaw},
      {"default stages", model::DefaultModelSpec(), IoSet::kStages},
      {"default disturbance", model::DefaultModelSpec(), IoSet::kDisturbance},
      {"spinning compliance", SpinningSpec(), IoSet::kCompliance},
      {"lossy spinning compliance", LossySpinningSpec(), IoSet::kCompliance},
      {"lossy spinning raw", LossySpinningSpec(), IoSet::kRaw},
      {"lossy spinning disturbance", LossySpinningSpec(), IoSet::kDisturbance},
  };
  for (const auto& c : cases) {
    const auto assembled = model::AssembledModel::Assemble(c.spec);
    const auto sys = BuildIoSetSystem(assembled, c.set);
    auto ev = FrfEvaluator::Create(sys);
    EXPECT_EQ(ev.path_used(), FrfMethod::kModal) << c.label << ": " << ev.setup_summary().message;
    EXPECT_EQ(ev.setup_summary().real_arithmetic, !assembled.has_loss()) << c.label;
    const Eigen::VectorXd f = LogFrequencies(0.5, 3000.0, 400);
    for (auto q : {ResponseQuantity::kReceptance, ResponseQuantity::kMobility, ResponseQuantity::kAccelerance}) {
      const FrfArray h = ev.Evaluate(f, q);
      const double error = WorstRelativeToPeak(h.values, ReferenceArray(sys, f, SPower(q)));
      EXPECT_LT(error, kPathAgreement) << c.label << " " << ToString(q);
    }
  }
}

TEST(FrfEvaluator, ModalPathIsAccurateAtTheResonances) {
  const auto assembled = model::AssembledModel::Assemble(model::DefaultModelSpec());
  const auto sys = model::BuildComplianceSystem(assembled);
  auto ev = FrfEvaluator::Create(sys);
  ASSERT_EQ(ev.path_used(), FrfMethod::kModal);
  // Undamped natural frequencies from a generalised eigen-solve of the system's K and M, and 0.1 % either
  // side; the reference responses there are direct solves.
  const auto eig = CalcGeneralizedSymmetricEigenPairs(sys.K, sys.M);
  ASSERT_TRUE(eig);
  std::vector<double> f;
  for (Eigen::Index i = 0; i < eig->values.size(); ++i) {
    const double fn = std::sqrt(eig->values(i)) / (2 * M_PI);
    for (double r : {0.999, 1.0, 1.001}) f.push_back(fn * r);
  }
  const Eigen::VectorXd fv = Eigen::Map<Eigen::VectorXd>(f.data(), static_cast<Eigen::Index>(f.size()));
  const FrfArray h = ev.Evaluate(fv, ResponseQuantity::kAccelerance);
  EXPECT_LT(WorstRelativeToPeak(h.values, ReferenceArray(sys, fv, 2)), kPathAgreement);
}

TEST(FrfEvaluator, ReportsTheDirectPathWhenTheConditionLimitIsExceeded) {
  const auto assembled = model::AssembledModel::Assemble(model::DefaultModelSpec());
  FrfEvaluatorOptions options;
  options.max_condition_number = 0.5;  // below any condition number: forces the fall-back
  auto ev = FrfEvaluator::Create(model::BuildComplianceSystem(assembled), options);
  EXPECT_EQ(ev.path_used(), FrfMethod::kDirect);
  EXPECT_NE(ev.setup_summary().message.find("condition"), std::string::npos) << ev.setup_summary().message;
}

// A near-zero pole (the hexapod's Dx stiffness at 1e-6 of its value, as a diagnosis probes it, with the
// loss factors of structural damping) leaves the modal sum 1e-8..1e-7 off a direct solve at the probe
// between it and the next pole (0.01 Hz), while it stays as exact as on the plain model in a hammer
// test's band (4e-11). Told the lowest frequency it will be asked for, the evaluator probes only from there up
// and keeps the modal path.
TEST(FrfEvaluator, ProbesOnlyFromTheLowestFrequencyItWillEvaluate) {
  auto spec = model::DefaultModelSpec();
  for (auto& joint : spec.joints) {
    if (joint.name == "hexapod") joint.stiffness[0] *= 1e-6;
    joint.loss_factor.fill(0.02);
  }
  const auto sys = BuildIoSetSystem(model::AssembledModel::Assemble(spec), IoSet::kRaw);
  FrfEvaluatorOptions from_zero;
  from_zero.check_tolerance = 1e-8;
  EXPECT_EQ(FrfEvaluator::Create(sys, from_zero).path_used(), FrfMethod::kDirect);

  FrfEvaluatorOptions in_band = from_zero;
  in_band.lowest_frequency_hz = 5.0;
  auto ev = FrfEvaluator::Create(sys, in_band);
  ASSERT_EQ(ev.path_used(), FrfMethod::kModal) << ev.setup_summary().message;
  EXPECT_LT(ev.setup_summary().check_error, in_band.check_tolerance);
  const Eigen::VectorXd f = LogFrequencies(5.0, 3000.0, 400);
  for (auto q : {ResponseQuantity::kReceptance, ResponseQuantity::kAccelerance}) {
    const double worst = WorstRelativeToPeak(ev.Evaluate(f, q).values, ReferenceArray(sys, f, SPower(q)));
    EXPECT_LT(worst, kPathAgreement) << ToString(q);
  }
  // Below the lowest frequency it was set up for, it refuses rather than answer unchecked.
  const Eigen::VectorXd below = Eigen::VectorXd::Constant(1, 0.5);
  try {
    ev.Evaluate(below, ResponseQuantity::kReceptance);
    ADD_FAILURE() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("frequency_hz[0] = 0.5, expected a finite frequency >= 5 Hz"),
              std::string::npos)
        << e.what();
  }
  FrfEvaluatorOptions negative;
  negative.lowest_frequency_hz = -1.0;
  EXPECT_THROW(FrfEvaluator::Create(sys, negative), InputError);
}

TEST(FrfEvaluator, RejectsNegativeAndNonFiniteFrequencies) {
  const auto assembled = model::AssembledModel::Assemble(model::DefaultModelSpec());
  auto ev = FrfEvaluator::Create(model::BuildComplianceSystem(assembled));
  Eigen::VectorXd f(2);
  f << 10.0, -1.0;
  EXPECT_THROW(ev.Evaluate(f, ResponseQuantity::kReceptance), InputError);
  f << 10.0, std::nan("");
  EXPECT_THROW(ev.Evaluate(f, ResponseQuantity::kReceptance), InputError);
}

// Central differences in log p (relative step 1e-6) on the direct path, against the analytic
// derivatives of both paths. Truncation is O(1e-12) relative; rounding in the two direct solves is
// ~eps cond(Z) |H| / 2e-6 ~ 1e-10 cond(Z) |H|, with cond(Z) up to ~1e2 near the resonances: ~1e-8 |H|.
// Elements are compared with a tolerance (kFiniteDifference = 1e-5) of the larger of the element's peak |p dH/dp| and 1e-3 of its peak |H| (smaller
// sensitivities carry no information for a fit). Elements that vanish by symmetry (H exactly zero in
// the direct solve; p dH/dp has the units of H) must have |p dH/dp| below kStructuralZero of the
// largest |H|.
constexpr double kFiniteDifference = 1e-5;
void CheckDerivatives(const model::ModelSpec& spec, IoSet set, const std::vector<std::string>& patterns,
                      ResponseQuantity quantity) {
  const auto assembled = model::AssembledModel::Assemble(spec);
  const auto params = model::MatchParameters(spec, patterns);
  const auto sys = BuildIoSetSystem(assembled, set);
  const Eigen::VectorXd f = LogFrequencies(5.0, 1500.0, 120);
  for (FrfMethod method : {FrfMethod::kAuto, FrfMethod::kDirect}) {
    FrfEvaluatorOptions options;
    options.method = method;
    auto ev = FrfEvaluator::Create(sys, options);
    const FrfWithDerivatives result = ev.EvaluateWithDerivatives(f, quantity, params, assembled);
    ASSERT_EQ(result.derivatives.size(), params.size());
    const FrfArray base = FrfEvaluator::Create(sys, kDirectOptions).Evaluate(f, quantity);
    EXPECT_LT(WorstRelativeToPeak(result.frf.values, base.values), kPathAgreement);
    for (size_t k = 0; k < params.size(); ++k) {
      const double p = model::GetParameter(spec, params[k]);
      const double step = p != 0.0 ? 1e-6 * std::abs(p) : 1e-6;
      Eigen::MatrixXcd h[2];
      for (int side = 0; side < 2; ++side) {
        model::ModelSpec moved = spec;
        model::SetParameter(moved, params[k], p + (side == 0 ? step : -step));
        const auto moved_assembled = model::AssembledModel::Assemble(moved);
        auto moved_ev = FrfEvaluator::Create(BuildIoSetSystem(moved_assembled, set), kDirectOptions);
        h[side] = moved_ev.Evaluate(f, quantity).values;
      }
      const double scale_p = p != 0.0 ? std::abs(p) : 1.0;
      const Eigen::MatrixXcd fd = (h[0] - h[1]) * (scale_p / (2 * step));
      const Eigen::MatrixXcd analytic = result.derivatives[k] * scale_p;
      const double largest_h = base.values.cwiseAbs().maxCoeff();
      for (Eigen::Index c = 0; c < fd.cols(); ++c) {
        if (base.values.col(c).cwiseAbs().maxCoeff() == 0.0) {
          EXPECT_LE(analytic.col(c).cwiseAbs().maxCoeff(), kStructuralZero * largest_h)
              << params[k].name << " element " << c << " fd " << fd.col(c).cwiseAbs().maxCoeff();
          continue;
        }
        const double scale =
            std::max(analytic.col(c).cwiseAbs().maxCoeff(), 1e-3 * base.values.col(c).cwiseAbs().maxCoeff());
        const double error = (analytic.col(c) - fd.col(c)).cwiseAbs().maxCoeff() / scale;
        EXPECT_LT(error, kFiniteDifference) << params[k].name << " element " << c << " (" << ToString(method) << ")";
      }
    }
  }
}

TEST(FrfEvaluator, StiffnessDerivativesMatchFiniteDifferences) {
  CheckDerivatives(model::DefaultModelSpec(), IoSet::kCompliance, {"*.k.*"}, ResponseQuantity::kReceptance);
}

TEST(FrfEvaluator, DampingDerivativesMatchFiniteDifferencesWithSpin) {
  CheckDerivatives(SpinningSpec(), IoSet::kRaw, {"*.c.*"}, ResponseQuantity::kAccelerance);
}

TEST(FrfEvaluator, LossAndCouplingDerivativesMatchFiniteDifferences) {
  CheckDerivatives(LossySpinningSpec(), IoSet::kCompliance,
                   {"*.eta.*", "hexapod.k.Dx-Ry", "hexapod.c.Dx-Ry", "hexapod.k.*", "rz.k.D?"},
                   ResponseQuantity::kMobility);
}

TEST(FrfEvaluator, DerivativesWithGroundInputsAndDelayMatchFiniteDifferences) {
  model::ModelSpec spec = LossySpinningSpec();
  spec.acquisition_delay_s = 2e-4;
  CheckDerivatives(spec, IoSet::kDisturbance, {"ty.k.*", "granite.c.Dz", "rz.eta.Dx"},
                   ResponseQuantity::kAccelerance);
}

TEST(FrfEvaluator, ResultsDoNotDependOnTheNumberOfThreads) {
  // The frequency blocks are spread over the threads; each block computes the same numbers whichever
  // thread runs it, so the results are bit-identical (complex spin: the complex path too).
  for (const model::ModelSpec& spec : {model::DefaultModelSpec(), LossySpinningSpec()}) {
    const auto assembled = model::AssembledModel::Assemble(spec);
    const auto sys = BuildIoSetSystem(assembled, IoSet::kCompliance);
    const auto params = model::MatchParameters(spec, {"*.k.*"});
    const Eigen::VectorXd f = LogFrequencies(1.0, 2000.0, 1500);  // 6 blocks of 256
    FrfWithDerivatives result[2];
    for (const int threads : {1, 2}) {
      SetMaxThreads(threads);
      auto ev = FrfEvaluator::Create(sys);
      ev.EvaluateWithDerivatives(f, ResponseQuantity::kReceptance, params, assembled, &result[threads - 1]);
    }
    SetMaxThreads(0);
    EXPECT_TRUE(result[0].frf.values == result[1].frf.values) << spec.name;
    ASSERT_EQ(result[0].derivatives.size(), result[1].derivatives.size());
    for (size_t k = 0; k < params.size(); ++k) {
      EXPECT_TRUE(result[0].derivatives[k] == result[1].derivatives[k]) << spec.name << " " << params[k].name;
    }
  }
}

TEST(FrfEvaluator, ResultsDoNotDependOnWhatTheThreadComputedBefore) {
  // A thread keeps its block workspace from call to call. A call on 201 frequencies (one block of 201)
  // must give the same numbers on a fresh thread as on one whose workspace an earlier call on 1500
  // frequencies (blocks of 256) shaped: else a fit's result depends on which thread ran what before,
  // that is on the thread count and the machine's load.
  for (const model::ModelSpec& spec : {model::DefaultModelSpec(), LossySpinningSpec()}) {
    const auto assembled = model::AssembledModel::Assemble(spec);
    const auto sys = BuildIoSetSystem(assembled, IoSet::kCompliance);
    const auto params = model::MatchParameters(spec, {"*.k.*"});
    const Eigen::VectorXd large = LogFrequencies(1.0, 2000.0, 1500);
    const Eigen::VectorXd small = LogFrequencies(5.0, 150.0, 201);
    FrfWithDerivatives result[2];
    FrfArray plain[2];
    SetMaxThreads(1);  // every block on the calling thread
    for (const bool warmed : {false, true}) {
      std::thread([&] {
        auto ev = FrfEvaluator::Create(sys);
        if (warmed) {
          ev.EvaluateWithDerivatives(large, ResponseQuantity::kReceptance, params, assembled);
          ev.Evaluate(large, ResponseQuantity::kReceptance);
        }
        ev.EvaluateWithDerivatives(small, ResponseQuantity::kReceptance, params, assembled, &result[warmed]);
        plain[warmed] = ev.Evaluate(small, ResponseQuantity::kReceptance);
      }).join();
    }
    SetMaxThreads(0);
    EXPECT_TRUE(plain[0].values == plain[1].values) << spec.name;
    EXPECT_TRUE(result[0].frf.values == result[1].frf.values) << spec.name;
    ASSERT_EQ(result[0].derivatives.size(), result[1].derivatives.size());
    for (size_t k = 0; k < params.size(); ++k) {
      EXPECT_TRUE(result[0].derivatives[k] == result[1].derivatives[k]) << spec.name << " " << params[k].name;
    }
  }
}

TEST(FrfEvaluator, RejectsDerivativesForAnotherModel) {
  const auto assembled = model::AssembledModel::Assemble(model::DefaultModelSpec());
  const auto small = model::AssembledModel::Assemble(SingleDofSpec(1e6, 1.0, 0.0, 1.0));
  auto ev = FrfEvaluator::Create(model::BuildComplianceSystem(assembled));
  const auto params = model::MatchParameters(small.spec(), {"*.k.*"});
  EXPECT_THROW(ev.EvaluateWithDerivatives(Eigen::VectorXd::Constant(1, 10.0), ResponseQuantity::kReceptance,
                                          params, small),
               InputError);
}

}  // namespace
}  // namespace stagefit::response
