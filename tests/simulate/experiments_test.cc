#include "stagefit/simulate/experiments.h"

#include <gtest/gtest.h>

#include <Eigen/LU>

#include <cmath>
#include <random>

#include "stagefit/common/error.h"
#include "stagefit/model/assembled_model.h"
#include "stagefit/model/linear_system.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/state_space.h"
#include "stagefit/simulate/time_integration.h"

namespace stagefit::simulate {
namespace {

// Short runs keep the tests fast: 2 s at 2 kHz.
TomographyOptions ShortTomography() {
  TomographyOptions o;
  o.duration_s = 2.0;
  o.sample_rate_hz = 2000.0;
  o.seed = 11;
  return o;
}

TEST(RunTomography, AtZeroSpeedReducesToTheNonRotatingLinearModel) {
  // Same seed, same signals: the ground motion drawn first (Dx, Dy, Dz) and fed to the state space of
  // the unmodified model must give the same PoI vibration as the tomography run at zero speed.
  TomographyOptions o = ShortTomography();
  o.speed_rad_s = 0.0;
  o.spindle_error = false;
  const SimulationSummary run = RunTomography(model::DefaultModelSpec(), o);

  model::ModelSpec spec = model::DefaultModelSpec();
  model::FrameSpec granite, poi;
  granite.name = "g";
  granite.body = "granite";
  poi.name = "p";
  poi.body = "hexapod";
  spec.frames.push_back(granite);
  spec.frames.push_back(poi);
  const auto model = model::AssembledModel::Assemble(spec);
  std::vector<model::OutputSpec> outputs;
  for (Dof d : kAllDofs) {
    model::OutputSpec out;
    out.kind = model::OutputSpec::Kind::kRelativeMotion;
    out.name = std::string(name(d));
    out.frame = "p";
    out.reference_frame = "g";
    out.dof = d;
    outputs.push_back(out);
  }
  const auto ss = model::CalcStateSpace(model::BuildSystem(model, model::GroundInputs(model), outputs));
  std::mt19937_64 rng(o.seed);
  const int n = static_cast<int>(run.time_s.size());
  Eigen::MatrixXd u(n, 3);
  for (int c = 0; c < 3; ++c) {
    u.col(c) = disturbance::SynthesiseSignal(o.ground_psd, {o.duration_s, o.sample_rate_hz}, rng);
  }
  // The run starts at the static equilibrium of the first input sample.
  const Eigen::VectorXd x0 = -ss.A.partialPivLu().solve(ss.B * u.row(0).transpose());
  const Eigen::MatrixXd y = SimulateDense(DiscretiseZeroOrderHold(ss, 1.0 / o.sample_rate_hz), u, x0);
  // Same recurrence, modal versus dense: rounding only, relative to the size of the states (the
  // granite joint deforms by about the ground displacement, 100 times the PoI's relative motion).
  EXPECT_LE((run.vibration - y).cwiseAbs().maxCoeff(), 1e-8 * u.cwiseAbs().maxCoeff());
  EXPECT_GT(y.cwiseAbs().maxCoeff(), 1e-11);
}

TEST(RunTomography, RecoversTheRadialOffsetAsTheEccentricity) {
  // The 1 um offset makes a once-per-revolution circle; the disturbances (tens of nm, spread over
  // frequency) move the fitted amplitude by far less than 5 %.
  const SimulationSummary run = RunTomography(model::DefaultModelSpec(), ShortTomography());
  EXPECT_NEAR(run.eccentricity_m, 1e-6, 5e-8);
  EXPECT_NEAR(run.eccentricity_phase_rad, 0.0, 0.05);
  ASSERT_EQ(run.error_names.size(), run.statistics.size());
  // With the circle removed, the radial error is the disturbance alone: well below the offset.
  for (const auto& s : run.statistics) {
    if (s.name == "x") {
      EXPECT_GT(s.peak_to_peak, 1.8e-6);
    }
    if (s.name == "radial") {
      EXPECT_LT(s.rms, 2e-7);
    }
  }
  EXPECT_TRUE(run.modal_integration);
}

TEST(RunTomography, UndisturbedRunTracesTheOffsetCircleExactly) {
  TomographyOptions o = ShortTomography();
  o.ground_motion = false;
  o.spindle_error = false;
  const SimulationSummary run = RunTomography(model::DefaultModelSpec(), o);
  for (Eigen::Index k = 0; k < run.time_s.size(); k += 97) {
    const double theta = run.setpoint(k);
    EXPECT_NEAR(run.poi_pose(k, 0), 1e-6 * std::cos(theta), 1e-15);
    EXPECT_NEAR(run.poi_pose(k, 1), 1e-6 * std::sin(theta), 1e-15);
    EXPECT_NEAR(run.poi_pose(k, 5), theta, 1e-9);
  }
}

TEST(RunTomography, RefusesANonAxisymmetricSpinningSubtree) {
  model::ModelSpec spec = model::DefaultModelSpec();
  spec.joints[model::FindJoint(spec, "hexapod")].stiffness[0] *= 2;
  EXPECT_THROW(RunTomography(spec, ShortTomography()), InputError);
}

TEST(TransferErrorMotion, LeverArmOfARigidBody) {
  // Closed form: a tilt theta about the reference point P moves a point J at r = p_J - p_P by theta x r;
  // a translation moves every point alike; the rotation is the same everywhere.
  const Eigen::Vector3d p_P(0, 0, 0), p_J(0, 0, -0.4);
  Eigen::MatrixXd m = Eigen::MatrixXd::Zero(3, 5);
  m.row(0) << 0, 0, 0, 0, 1e-6;  // Ry = 1 urad at P
  m.row(1) << 0, 0, 0, 2e-6, 0;  // Rx = 2 urad
  m.row(2) << 1e-8, -2e-8, 3e-8, 0, 0;
  const Eigen::MatrixXd j = TransferErrorMotion(m, p_P, p_J);
  // Ry x (0, 0, -0.4) = (1e-6 * -0.4 along x?): (0, b, 0) x (0, 0, z) = (b z, 0, 0) = (-4e-7, 0, 0).
  EXPECT_NEAR(j(0, 0), -0.4e-6, 1e-20);
  EXPECT_NEAR(j(0, 1), 0.0, 1e-20);
  // (a, 0, 0) x (0, 0, z) = (0, -a z, 0) = (0, 8e-7, 0).
  EXPECT_NEAR(j(1, 1), 0.8e-6, 1e-20);
  EXPECT_NEAR(j(1, 0), 0.0, 1e-20);
  EXPECT_TRUE(j.row(2).isApprox(m.row(2)));
  EXPECT_TRUE(j.rightCols(2).isApprox(m.rightCols(2)));
  // Round trip J -> P gives back the measured motion.
  EXPECT_LT((TransferErrorMotion(j, p_J, p_P) - m).norm(), 1e-20);
  // Six columns: Rz about P moves an off-axis point J sideways.
  Eigen::MatrixXd six = Eigen::MatrixXd::Zero(1, 6);
  six(0, 5) = 1e-6;
  EXPECT_NEAR(TransferErrorMotion(six, p_P, Eigen::Vector3d(0.1, 0, 0))(0, 1), 1e-7, 1e-20);
  EXPECT_THROW(TransferErrorMotion(Eigen::MatrixXd::Zero(2, 4), p_P, p_J), InputError);
}

// Spindle error only, spindle at rest (the PoI does not turn): below the spindle joint's resonances the
// joint deforms by the error imposed on it, so the PoI moves by the error as measured at the
// reference point. With the reference at the PoI (the default) the PoI's x and y follow the measured Dx
// and Dy; with the error imposed unchanged at the joint 0.4 m below, the tilts add 0.4 m x Ry.
TEST(RunTomography, TheSpindleErrorAppearsAtThePointWhereItWasMeasured) {
  TomographyOptions o = ShortTomography();
  o.speed_rad_s = 0.0;
  o.ground_motion = false;
  // Errors from 0.5 to 4 Hz only: far below the stack's first modes (about 20 Hz), where the response
  // is quasi-static; the default 1/f PSD reaches 100 Hz, where resonances amplify it.
  for (int c = 0; c < 5; ++c) {
    o.spindle_error_psd[c].frequency_hz = Eigen::VectorXd::LinSpaced(2, 0.5, 4.0);
    o.spindle_error_psd[c].psd = Eigen::VectorXd::Constant(2, c < 3 ? 1e-16 : 1e-14);
  }
  const model::ModelSpec spec = model::DefaultModelSpec();
  const double z_joint = spec.joints[model::FindJoint(spec, "rz")].origin_W.z();
  std::mt19937_64 rng(o.seed);
  Eigen::MatrixXd measured(static_cast<Eigen::Index>(std::round(o.duration_s * o.sample_rate_hz)), 5);
  for (int c = 0; c < 5; ++c) {
    measured.col(c) = disturbance::SynthesiseSignal(o.spindle_error_psd[c], {o.duration_s, o.sample_rate_hz}, rng)
                          .head(measured.rows());
  }
  auto centred = [](const Eigen::VectorXd& v) { return Eigen::VectorXd(v.array() - v.mean()); };
  auto rms = [](const Eigen::VectorXd& v) { return std::sqrt(v.squaredNorm() / v.size()); };

  const SimulationSummary at_poi = RunTomography(spec, o);
  for (int c = 0; c < 2; ++c) {
    const Eigen::VectorXd expected = centred(measured.col(c));
    const Eigen::VectorXd got = centred(at_poi.poi_pose.col(c));
    EXPECT_LT(rms(got - expected), 0.05 * rms(expected)) << "axis " << c << ": rms " << rms(got) << " against " << rms(expected);
  }
  o.spindle_error_reference_W = Eigen::Vector3d(0, 0, z_joint);  // as if measured at the joint
  const SimulationSummary at_joint = RunTomography(spec, o);
  // x gains theta_y x (p_PoI - p_J): Ry * (0 - z_joint) along x.
  const Eigen::VectorXd expected_x = centred(measured.col(0) - z_joint * measured.col(4));
  EXPECT_LT(rms(centred(at_joint.poi_pose.col(0)) - expected_x), 0.05 * rms(expected_x));
  EXPECT_GT(rms(expected_x), 2.0 * rms(centred(measured.col(0))));  // the lever arm dominates
}

// Turning at 60 rpm with the default spindle error PSD, ground motion off: the radial error with the
// error applied at the PoI height (the default reference) is the error itself, well below the one with
// the same error imposed unchanged at the joint 0.4 m below, where the tilts' lever arm adds to it.
TEST(RunTomography, RadialErrorWithTheSpindleErrorAppliedAtThePoiHeight) {
  TomographyOptions o = ShortTomography();
  o.ground_motion = false;
  const model::ModelSpec spec = model::DefaultModelSpec();
  auto radial_rms = [](const SimulationSummary& run) {
    for (const auto& s : run.statistics) {
      if (s.name == "radial") return s.rms;
    }
    return -1.0;
  };
  const double at_poi = radial_rms(RunTomography(spec, o));
  o.spindle_error_reference_W = Eigen::Vector3d(0, 0, spec.joints[model::FindJoint(spec, "rz")].origin_W.z());
  const double at_joint = radial_rms(RunTomography(spec, o));
  EXPECT_GT(at_poi, 0.0);
  EXPECT_LT(at_poi, 0.7 * at_joint) << "at the PoI " << at_poi << " m, at the joint " << at_joint << " m";
}

// The default spindle PSD is the shipped target table: read from the file it gives the same run.
TEST(SpindleErrorPsdFromTable, TheShippedTargetIsTheDefault) {
  const auto table = disturbance::ReadCsvTable(std::string(STAGEFIT_SOURCE_DIR) + "/measurements/disturbance/spindle_target.csv");
  const auto psd = SpindleErrorPsdFromTable(table);
  const auto defaults = DefaultSpindleErrorPsd();
  for (int c = 0; c < 5; ++c) {
    EXPECT_TRUE(psd[c].frequency_hz.isApprox(defaults[c].frequency_hz)) << c;
    EXPECT_TRUE(psd[c].psd.isApprox(defaults[c].psd)) << c;
  }
  disturbance::CsvTable missing = table;
  missing.column_names[4] = "Tx";
  try {
    SpindleErrorPsdFromTable(missing);
    ADD_FAILURE() << "a table without Rx was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no column 'Rx'"), std::string::npos) << e.what();
  }
}

TEST(RunRaster, SlowStraightnessPassesToTheSample) {
  // A straightness profile 100 nm cos(2 pi y / 9 mm) seen at 18 mm/s is a 2 Hz signal, far below the
  // stack's first resonance: the sample follows it. The dynamic amplification (f/f1)^2 and the ZOH
  // keep the difference below 2 % of the amplitude. The run starts at the static equilibrium of the
  // first inputs; the first 0.05 s are skipped all the same (the initial velocity is not matched).
  RasterOptions o;
  o.duration_s = 2.0;
  o.sample_rate_hz = 2000.0;
  o.ground_motion = false;
  const int m = 901;
  o.straightness_position_m = Eigen::VectorXd::LinSpaced(m, -4.5e-3, 4.5e-3);
  o.straightness_vertical_m = (2 * M_PI * o.straightness_position_m.array() / 9e-3).cos() * 1e-7;
  o.straightness_lateral_m = Eigen::VectorXd::Zero(m);
  const SimulationSummary run = RunRaster(model::DefaultModelSpec(), o);
  double max_error = 0.0;
  const Eigen::VectorXd expected = (2 * M_PI * run.setpoint.array() / 9e-3).cos() * 1e-7;
  const Eigen::VectorXd centred = expected.array() - expected.mean();
  for (Eigen::Index k = 100; k < run.time_s.size(); ++k) {
    max_error = std::max(max_error, std::abs(run.errors(k, 0) - centred(k)));
  }
  EXPECT_LT(max_error, 2e-9);
  EXPECT_EQ(run.error_names[0], "vertical");
}

TEST(RunRaster, FollowsTheTriangleSetpoint) {
  RasterOptions o;
  o.duration_s = 2.0;
  o.sample_rate_hz = 1000.0;
  const SimulationSummary run = RunRaster(model::DefaultModelSpec(), o);
  EXPECT_NEAR(run.setpoint(0), -4.5e-3, 1e-15);
  EXPECT_NEAR(run.setpoint(500), 4.5e-3, 1e-12);
  EXPECT_NEAR(run.poi_pose(500, 1), 4.5e-3, 1e-6);
  for (const auto& s : run.statistics) EXPECT_LT(s.rms, 1e-6) << s.name;
}

TEST(CompareWithMeasured, ComparesCommonColumns) {
  RasterOptions o;
  o.duration_s = 2.0;
  o.sample_rate_hz = 1000.0;
  const SimulationSummary run = RunRaster(model::DefaultModelSpec(), o);
  disturbance::CsvTable measured;
  measured.source = "measured.csv";
  measured.column_names = {"time_s", "vertical"};
  measured.units = {"", ""};
  measured.values.resize(run.time_s.size(), 2);
  measured.values.col(0) = run.time_s;
  measured.values.col(1) = 2 * run.errors.col(0);
  const ComparisonSummary c = CompareWithMeasured(run, measured, {});
  ASSERT_EQ(c.channels.size(), 1u);
  EXPECT_NEAR(c.channels[0].measured.rms, 2 * c.channels[0].simulated.rms, 1e-12);
  ASSERT_EQ(c.channels[0].measured_psd.psd.size(), c.channels[0].simulated_psd.psd.size());
  EXPECT_NEAR(c.channels[0].measured_psd.psd(3), 4 * c.channels[0].simulated_psd.psd(3),
              1e-9 * c.channels[0].measured_psd.psd(3));
  measured.column_names = {"time_s", "other"};
  EXPECT_THROW(CompareWithMeasured(run, measured, {}), InputError);
}

TEST(FitCircle, RecoversCircle) {
  const int n = 400;
  Eigen::VectorXd theta = Eigen::VectorXd::LinSpaced(n, 0, 4 * M_PI);
  Eigen::VectorXd x = 3.0 + 2.0 * (theta.array() + 0.3).cos();
  Eigen::VectorXd y = -1.0 + 2.0 * (theta.array() + 0.3).sin();
  const Eigen::Vector4d c = FitCircle(x, y, theta);
  EXPECT_NEAR(c(0), 3.0, 1e-12);
  EXPECT_NEAR(c(1), -1.0, 1e-12);
  EXPECT_NEAR(c(2), 2.0 * std::cos(0.3), 1e-12);
  EXPECT_NEAR(c(3), 2.0 * std::sin(0.3), 1e-12);
}

}  // namespace
}  // namespace stagefit::simulate
