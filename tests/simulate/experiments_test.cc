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
