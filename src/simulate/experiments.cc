#include "stagefit/simulate/experiments.h"

#include <Eigen/Dense>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <random>
#include <sstream>

#include "stagefit/common/error.h"
#include "stagefit/common/units.h"
#include "stagefit/kinematics/stage_stack.h"
#include "stagefit/model/assembled_model.h"
#include "stagefit/model/linear_system.h"
#include "stagefit/model/state_space.h"
#include "stagefit/simulate/rotating_frame.h"
#include "stagefit/simulate/time_integration.h"

namespace stagefit::simulate {
namespace {

constexpr const char* kGraniteFrame = "simulate.granite";
constexpr const char* kPoiFrame = "simulate.poi";

disturbance::PsdTable Table(const std::string& name, std::vector<double> f, std::vector<double> s) {
  disturbance::PsdTable t;
  t.name = name;
  t.frequency_hz = Eigen::Map<Eigen::VectorXd>(f.data(), static_cast<Eigen::Index>(f.size()));
  t.psd = Eigen::Map<Eigen::VectorXd>(s.data(), static_cast<Eigen::Index>(s.size()));
  return t;
}

void CheckPositive(double value, const std::string& field) {
  if (!std::isfinite(value) || value <= 0) {
    std::ostringstream out;
    out << "simulation option " << field << " = " << value << ", expected a finite value > 0";
    throw InputError(out.str());
  }
}

int RequireBody(const model::ModelSpec& spec, const std::string& name, const std::string& role) {
  const int b = model::FindBody(spec, name);
  if (b < 0) throw InputError("simulation: " + role + " body '" + name + "' is not a body of the model");
  return b;
}

int RequireJoint(const model::ModelSpec& spec, const std::string& name, const std::string& role) {
  const int j = model::FindJoint(spec, name);
  if (j < 0) throw InputError("simulation: " + role + " joint '" + name + "' is not a joint of the model");
  return j;
}

// A copy of the spec with a frame on the granite and a PoI frame on the sample body, both at the W
// origin with axes along W.
model::ModelSpec WithSimulationFrames(model::ModelSpec spec, const StackRoles& roles) {
  RequireBody(spec, roles.granite_body, "granite");
  RequireBody(spec, roles.sample_body, "sample");
  model::FrameSpec granite, poi;
  granite.name = kGraniteFrame;
  granite.body = roles.granite_body;
  poi.name = kPoiFrame;
  poi.body = roles.sample_body;
  spec.frames.push_back(granite);
  spec.frames.push_back(poi);
  return spec;
}

std::vector<model::OutputSpec> PoiOutputs() {
  std::vector<model::OutputSpec> outputs;
  for (Dof d : kAllDofs) {
    model::OutputSpec out;
    out.kind = model::OutputSpec::Kind::kRelativeMotion;
    out.name = std::string("poi.") + std::string(name(d));
    out.frame = kPoiFrame;
    out.reference_frame = kGraniteFrame;
    out.dof = d;
    outputs.push_back(out);
  }
  return outputs;
}

// Inputs "<joint>.<Dof>" for the free DoF of `joint` among `dofs`, and their indices into 0..5.
void AddJointForceInputs(const model::AssembledModel& model, int joint, const std::vector<Dof>& dofs,
                         std::vector<model::InputSpec>& inputs, std::vector<int>& which) {
  const model::JointSpec& spec = model.spec().joints[joint];
  for (Dof d : dofs) {
    if (model.dof_index(joint, d) < 0) continue;
    model::InputSpec in;
    in.kind = model::InputSpec::Kind::kJointForce;
    in.name = spec.name + "." + std::string(name(d));
    in.joint = spec.name;
    in.dof = d;
    inputs.push_back(in);
    which.push_back(index(d));
  }
}

// Central differences (one-sided at the ends), per column.
Eigen::MatrixXd TimeDerivative(const Eigen::MatrixXd& x, double dt) {
  const Eigen::Index n = x.rows();
  Eigen::MatrixXd d(n, x.cols());
  if (n < 2) return Eigen::MatrixXd::Zero(n, x.cols());
  for (Eigen::Index k = 1; k + 1 < n; ++k) d.row(k) = (x.row(k + 1) - x.row(k - 1)) / (2 * dt);
  d.row(0) = (x.row(1) - x.row(0)) / dt;
  d.row(n - 1) = (x.row(n - 1) - x.row(n - 2)) / dt;
  return d;
}

// Joint force pairs f = K_J delta0 + C_J delta0' restricted to the free DoF `which` (N x |which|).
Eigen::MatrixXd JointForces(const model::AssembledModel& model, int joint, const Eigen::MatrixXd& delta0,
                            double dt, const std::vector<int>& which) {
  const model::Matrix6d K = model.JointStiffness(joint), C = model.JointDamping(joint);
  const Eigen::MatrixXd rate = TimeDerivative(delta0, dt);
  Eigen::MatrixXd f(delta0.rows(), static_cast<Eigen::Index>(which.size()));
  for (size_t c = 0; c < which.size(); ++c) {
    f.col(static_cast<Eigen::Index>(c)) = delta0 * K.row(which[c]).transpose() + rate * C.row(which[c]).transpose();
  }
  return f;
}

ErrorStatistics Statistics(const std::string& name, const Eigen::VectorXd& x) {
  ErrorStatistics s;
  s.name = name;
  const double mean = x.mean();
  s.rms = std::sqrt((x.array() - mean).square().mean());
  s.peak_to_peak = x.maxCoeff() - x.minCoeff();
  return s;
}

void Finish(SimulationSummary& summary, const disturbance::WelchOptions& welch, double sample_rate_hz) {
  for (size_t c = 0; c < summary.error_names.size(); ++c) {
    const Eigen::VectorXd column = summary.errors.col(static_cast<Eigen::Index>(c));
    summary.statistics.push_back(Statistics(summary.error_names[c], column));
    summary.spectra.push_back(disturbance::EstimatePsd(column, sample_rate_hz, welch, summary.experiment,
                                                       summary.error_names[c]));
  }
}

// Integrates the model for `u` and combines it with the kinematic poses X_W_top (one per sample).
void Integrate(const model::AssembledModel& model, const std::vector<model::InputSpec>& inputs,
               const Eigen::MatrixXd& u, double dt, const std::vector<kinematics::RigidTransform>& X_W_top,
               const Eigen::Vector3d& p_off, SimulationSummary& summary) {
  const model::SecondOrderSystem system = model::BuildSystem(model, inputs, PoiOutputs());
  const model::StateSpace ss = model::CalcStateSpace(system);
  for (const auto& note : ss.notes) summary.notes.push_back(note);
  const ModalIntegrator integrator(ss, dt);
  summary.modal_integration = integrator.is_modal();
  if (!integrator.is_modal()) summary.notes.push_back(integrator.message());
  for (const auto& in : inputs) summary.input_names.push_back(in.name);
  const auto start = std::chrono::steady_clock::now();
  // Start at the static equilibrium of the first inputs (x' = 0: x0 = -A^-1 B u[0]), so that the
  // record does not begin with the transient of inputs switched on at t = 0.
  Eigen::PartialPivLU<Eigen::MatrixXd> lu(ss.A);
  const Eigen::VectorXd x0 = -lu.solve(ss.B * u.row(0).transpose());
  summary.vibration = integrator.Simulate(u, x0.allFinite() ? x0 : Eigen::VectorXd::Zero(ss.A.rows()));
  summary.integration_wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const Eigen::Index n = u.rows();
  summary.poi_pose.resize(n, 6);
  double previous_rz = 0.0, turns = 0.0;
  for (Eigen::Index k = 0; k < n; ++k) {
    const Eigen::Vector3d r = X_W_top[k].rotation() * p_off;
    const Eigen::Vector3d translation = summary.vibration.row(k).head<3>().transpose();
    const Eigen::Vector3d theta = summary.vibration.row(k).tail<3>().transpose();
    summary.poi_pose.row(k).head<3>() = (X_W_top[k].translation() + r + translation + theta.cross(r)).transpose();
    const Eigen::Matrix3d R = kinematics::RotationFromEuler({theta(0), theta(1), theta(2)}) * X_W_top[k].rotation();
    const kinematics::EulerXyz e = kinematics::EulerFromRotation(R);
    if (k > 0) {
      if (e.gamma_rad - previous_rz > kPi) turns -= 1;
      if (e.gamma_rad - previous_rz < -kPi) turns += 1;
    }
    previous_rz = e.gamma_rad;
    summary.poi_pose.row(k).tail<3>() << e.alpha_rad, e.beta_rad, e.gamma_rad + 2 * kPi * turns;
  }
}

// Ground displacement inputs (one per ground DoF), each a signal synthesised from `psd`.
void AddGroundMotion(const model::AssembledModel& model, const disturbance::PsdTable& psd,
                     const disturbance::SynthesisOptions& synthesis, int n, std::mt19937_64& rng,
                     std::vector<model::InputSpec>& inputs, std::vector<Eigen::VectorXd>& columns) {
  for (const auto& in : model::GroundInputs(model)) {
    inputs.push_back(in);
    columns.push_back(disturbance::SynthesiseSignal(psd, synthesis, rng).head(n));
  }
}

// The n x inputs matrix of the input signals. Without any disturbance, a single zero ground input
// keeps the system well formed.
Eigen::MatrixXd InputMatrix(const model::AssembledModel& model, int n, const std::vector<Eigen::VectorXd>& columns,
                            std::vector<model::InputSpec>& inputs) {
  if (inputs.empty()) {
    inputs.push_back(model::GroundInputs(model).at(0));
    return Eigen::MatrixXd::Zero(n, 1);
  }
  Eigen::MatrixXd u(n, static_cast<Eigen::Index>(columns.size()));
  for (size_t c = 0; c < columns.size(); ++c) u.col(static_cast<Eigen::Index>(c)) = columns[c];
  return u;
}

// Indices of the stages in kinematics::MicroStationStages().
constexpr int kTranslationStage = 0;
constexpr int kSpindleStage = 2;

// The pose of the top platform at each sample when `stage` follows `setpoint` and the others rest.
std::vector<kinematics::RigidTransform> TopPoses(int stage, const Eigen::VectorXd& setpoint) {
  const auto stages = kinematics::MicroStationStages();
  std::vector<kinematics::RigidTransform> X_W_top(setpoint.size());
  std::vector<kinematics::StageMotion> motions(stages.size());
  for (Eigen::Index k = 0; k < setpoint.size(); ++k) {
    motions[stage].setpoint = setpoint(k);
    X_W_top[k] = kinematics::CalcStackPoses(stages, motions).back();
  }
  return X_W_top;
}

int SampleCount(double duration_s, double sample_rate_hz) {
  CheckPositive(duration_s, "duration");
  CheckPositive(sample_rate_hz, "rate");
  const double n = std::round(duration_s * sample_rate_hz);
  if (n < 16 || n > 1e8) {
    throw InputError("simulation: duration x rate = " + std::to_string(n) + " samples, expected 16 .. 1e8");
  }
  return static_cast<int>(n);
}

// Linear interpolation of y(x) at `at`, x increasing; constant beyond the ends.
double Interpolate(const Eigen::VectorXd& x, const Eigen::VectorXd& y, double at) {
  const Eigen::Index n = x.size();
  if (at <= x(0)) return y(0);
  if (at >= x(n - 1)) return y(n - 1);
  const Eigen::Index i = std::upper_bound(x.data(), x.data() + n, at) - x.data() - 1;
  const double w = (at - x(i)) / (x(i + 1) - x(i));
  return (1 - w) * y(i) + w * y(i + 1);
}

Eigen::VectorXd RemoveLine(const Eigen::VectorXd& x, const Eigen::VectorXd& y) {
  Eigen::MatrixXd A(x.size(), 2);
  A.col(0).setOnes();
  A.col(1) = x;
  const Eigen::Vector2d c = A.colPivHouseholderQr().solve(y);
  return y - A * c;
}

}  // namespace

disturbance::PsdTable QuietHallGroundPsd() {
  return Table("quiet-hall ground PSD", {0.05, 1.0, 128.0}, {1e-16, 1e-16, 1e-16 / (128.0 * 128.0 * 128.0 * 128.0)});
}

std::array<disturbance::PsdTable, 5> DefaultSpindleErrorPsd() {
  return {Table("spindle Dx PSD", {0.1, 100}, {5.8e-16, 5.8e-19}), Table("spindle Dy PSD", {0.1, 100}, {5.8e-16, 5.8e-19}),
          Table("spindle Dz PSD", {0.1, 100}, {1.45e-16, 1.45e-19}), Table("spindle Rx PSD", {0.1, 100}, {5.8e-14, 5.8e-17}),
          Table("spindle Ry PSD", {0.1, 100}, {5.8e-14, 5.8e-17})};
}

std::array<disturbance::PsdTable, 2> DefaultStraightnessPsd() {
  return {Table("straightness vertical PSD", {100, 50000}, {1e-16, 4e-22}),
          Table("straightness lateral PSD", {100, 50000}, {2.5e-17, 1e-22})};
}

Eigen::Vector4d FitCircle(const Eigen::VectorXd& x, const Eigen::VectorXd& y, const Eigen::VectorXd& theta) {
  const Eigen::Index n = x.size();
  STAGEFIT_ASSERT(y.size() == n && theta.size() == n && n >= 4, "circle fit needs equal sizes >= 4");
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(2 * n, 4);
  Eigen::VectorXd b(2 * n);
  for (Eigen::Index k = 0; k < n; ++k) {
    const double c = std::cos(theta(k)), s = std::sin(theta(k));
    A.row(k) << 1, 0, c, -s;
    A.row(n + k) << 0, 1, s, c;
    b(k) = x(k);
    b(n + k) = y(k);
  }
  return A.colPivHouseholderQr().solve(b);
}

Eigen::MatrixXd TransferErrorMotion(const Eigen::MatrixXd& motion_P, const Eigen::Vector3d& p_P, const Eigen::Vector3d& p_J) {
  if (motion_P.cols() != 5 && motion_P.cols() != 6) {
    throw InputError("error motion: expected 5 or 6 columns (Dx Dy Dz Rx Ry [Rz]), got " + std::to_string(motion_P.cols()));
  }
  const Eigen::Vector3d r = p_J - p_P;
  Eigen::MatrixXd out = motion_P;
  for (Eigen::Index k = 0; k < motion_P.rows(); ++k) {
    const Eigen::Vector3d theta(motion_P(k, 3), motion_P(k, 4), motion_P.cols() == 6 ? motion_P(k, 5) : 0.0);
    out.row(k).head<3>() += theta.cross(r).transpose();
  }
  return out;
}

std::array<disturbance::PsdTable, 5> SpindleErrorPsdFromTable(const disturbance::CsvTable& table) {
  if (table.column_names.empty() || table.column_names[0] != "frequency_hz") {
    throw InputError(table.source + ": expected a PSD table whose first column is frequency_hz (Hz), then Dx, Dy, Dz "
                     "(m^2/Hz) and Rx, Ry (rad^2/Hz)");
  }
  std::array<disturbance::PsdTable, 5> psd;
  const char* names[5] = {"Dx", "Dy", "Dz", "Rx", "Ry"};
  for (int c = 0; c < 5; ++c) {
    if (table.FindColumn(names[c]) < 0) {
      throw InputError(table.source + ": no column '" + names[c] + "' (a spindle error PSD needs Dx, Dy, Dz in m^2/Hz and "
                       "Rx, Ry in rad^2/Hz)");
    }
    psd[c].name = table.source + " column " + names[c];
    psd[c].frequency_hz = table.values.col(0);
    psd[c].psd = table.Column(names[c]);
    disturbance::ValidatePsdTable(psd[c]);
  }
  return psd;
}

SimulationSummary RunTomography(const model::ModelSpec& input_spec, const TomographyOptions& o) {
  const int n = SampleCount(o.duration_s, o.sample_rate_hz);
  if (!std::isfinite(o.speed_rad_s)) throw InputError("simulation option speed is not finite");
  if (!std::isfinite(o.offset_m)) throw InputError("simulation option offset is not finite");
  const double dt = 1.0 / o.sample_rate_hz;
  model::ModelSpec spec = WithSimulationFrames(input_spec, o.roles);
  const int spindle = RequireJoint(spec, o.roles.spindle_joint, "spindle");
  const auto asymmetries = FindSpinAsymmetries(spec, o.roles.spindle_joint);
  if (!asymmetries.empty() && o.speed_rad_s != 0.0) {
    std::string message = "simulation: the subtree spinning with joint '" + o.roles.spindle_joint +
                          "' is not axisymmetric, so the linear model depends on the spindle angle "
                          "(docs/simulation.md):";
    for (const auto& a : asymmetries) message += "\n  " + a;
    throw InputError(message);
  }
  spec.joints[spindle].spin_rate_rad_s = o.speed_rad_s;
  const model::AssembledModel model = model::AssembledModel::Assemble(spec, "simulation model");

  SimulationSummary summary;
  summary.experiment = "tomography";
  std::vector<model::InputSpec> inputs;
  std::vector<Eigen::VectorXd> columns;
  std::mt19937_64 rng(o.seed);
  const disturbance::SynthesisOptions synthesis{o.duration_s, o.sample_rate_hz};
  if (o.ground_motion) AddGroundMotion(model, o.ground_psd, synthesis, n, rng, inputs, columns);
  if (o.spindle_error) {
    std::vector<int> which;
    AddJointForceInputs(model, spindle, {Dof::kDx, Dof::kDy, Dof::kDz, Dof::kRx, Dof::kRy}, inputs, which);
    if (!o.spindle_error_reference_W.allFinite()) throw InputError("simulation option spindle reference is not finite");
    // The error as measured at the reference point, moved to the joint's origin by the lever arm, then
    // expressed in the joint's axes (the joint deformation's coordinates).
    Eigen::MatrixXd measured = Eigen::MatrixXd::Zero(n, 6);
    for (int c = 0; c < 5; ++c) measured.col(c) = disturbance::SynthesiseSignal(o.spindle_error_psd[c], synthesis, rng).head(n);
    const model::JointSpec& joint = spec.joints[spindle];
    const Eigen::MatrixXd at_joint = TransferErrorMotion(measured, o.spindle_error_reference_W, joint.origin_W);
    Eigen::MatrixXd delta0(n, 6);
    delta0.leftCols<3>() = at_joint.leftCols<3>() * joint.R_WJ;   // rows: (R_WJ' d)'
    delta0.rightCols<3>() = at_joint.rightCols<3>() * joint.R_WJ;
    const Eigen::MatrixXd f = JointForces(model, spindle, delta0, dt, which);
    for (Eigen::Index c = 0; c < f.cols(); ++c) columns.push_back(f.col(c));
    char where[160];
    std::snprintf(where, sizeof where, "measured at (%.4g, %.4g, %.4g) m, moved to the joint origin (%.4g, %.4g, %.4g) m",
                  o.spindle_error_reference_W.x(), o.spindle_error_reference_W.y(), o.spindle_error_reference_W.z(),
                  joint.origin_W.x(), joint.origin_W.y(), joint.origin_W.z());
    summary.notes.push_back("spindle error motion " + std::string(where) + " by the rigid lever arm d_J = d_P + theta x "
                            "(p_J - p_P), imposed as a deformation of joint '" + o.roles.spindle_joint +
                            "' (forces K delta0 + C delta0' inside the joint), in fixed axes");
  }
  const Eigen::MatrixXd u = InputMatrix(model, n, columns, inputs);

  summary.time_s = Eigen::VectorXd::LinSpaced(n, 0.0, (n - 1) * dt);
  summary.setpoint = o.speed_rad_s * summary.time_s;
  Integrate(model, inputs, u, dt, TopPoses(kSpindleStage, summary.setpoint), Eigen::Vector3d(o.offset_m, 0, 0), summary);

  const Eigen::VectorXd x = summary.poi_pose.col(0), y = summary.poi_pose.col(1), z = summary.poi_pose.col(2);
  const Eigen::Vector4d circle = FitCircle(x, y, summary.setpoint);
  summary.circle_centre_x_m = circle(0);
  summary.circle_centre_y_m = circle(1);
  summary.eccentricity_m = std::hypot(circle(2), circle(3));
  summary.eccentricity_phase_rad = std::atan2(circle(3), circle(2));
  summary.error_names = {"x", "y", "z", "x_fit", "y_fit", "radial", "axial"};
  summary.errors.resize(n, 7);
  for (int k = 0; k < n; ++k) {
    const double c = std::cos(summary.setpoint(k)), s = std::sin(summary.setpoint(k));
    const double rx = x(k) - (circle(0) + circle(2) * c - circle(3) * s);
    const double ry = y(k) - (circle(1) + circle(3) * c + circle(2) * s);
    const double cr = std::cos(summary.setpoint(k) + summary.eccentricity_phase_rad);
    const double sr = std::sin(summary.setpoint(k) + summary.eccentricity_phase_rad);
    summary.errors.row(k) << x(k) - x.mean(), y(k) - y.mean(), z(k) - z.mean(), rx, ry, rx * cr + ry * sr,
        z(k) - z.mean();
  }
  summary.notes.push_back("linear model at the rest geometry, inertial frame, gyroscopic matrix at " +
                          std::to_string(o.speed_rad_s) + " rad/s (axisymmetric spinning subtree: exact)");
  Finish(summary, o.welch, o.sample_rate_hz);
  return summary;
}

SimulationSummary RunRaster(const model::ModelSpec& input_spec, const RasterOptions& o) {
  const int n = SampleCount(o.duration_s, o.sample_rate_hz);
  CheckPositive(o.amplitude_m, "amplitude");
  CheckPositive(o.period_s, "period");
  if (!std::isfinite(o.offset_m)) throw InputError("simulation option offset is not finite");
  const double dt = 1.0 / o.sample_rate_hz;
  model::ModelSpec spec = WithSimulationFrames(input_spec, o.roles);
  const int ty = RequireJoint(spec, o.roles.translation_joint, "translation");
  const model::AssembledModel model = model::AssembledModel::Assemble(spec, "simulation model");

  SimulationSummary summary;
  summary.experiment = "raster";
  summary.time_s = Eigen::VectorXd::LinSpaced(n, 0.0, (n - 1) * dt);
  summary.setpoint.resize(n);
  for (int k = 0; k < n; ++k) {
    const double phase = std::fmod(summary.time_s(k) / o.period_s, 1.0);
    summary.setpoint(k) = o.amplitude_m * (phase < 0.5 ? -1 + 4 * phase : 3 - 4 * phase);
  }

  std::vector<model::InputSpec> inputs;
  std::vector<Eigen::VectorXd> columns;
  std::mt19937_64 rng(o.seed);
  const disturbance::SynthesisOptions synthesis{o.duration_s, o.sample_rate_hz};
  if (o.ground_motion) AddGroundMotion(model, o.ground_psd, synthesis, n, rng, inputs, columns);
  if (o.straightness_error) {
    Eigen::VectorXd position, vertical, lateral;
    if (o.straightness_position_m.size() > 0) {
      const Eigen::Index m = o.straightness_position_m.size();
      if (m < 2 || o.straightness_vertical_m.size() != m || o.straightness_lateral_m.size() != m) {
        throw InputError("simulation: straightness record needs >= 2 positions with one vertical and one lateral "
                         "value each");
      }
      position = o.straightness_position_m;
      for (Eigen::Index i = 1; i < m; ++i) {
        if (!(position(i) > position(i - 1))) {
          throw InputError("simulation: straightness positions must increase (row " + std::to_string(i) + ")");
        }
      }
      vertical = RemoveLine(position, o.straightness_vertical_m);
      lateral = RemoveLine(position, o.straightness_lateral_m);
      summary.notes.push_back("straightness from the given record (best line removed)");
    } else {
      // Spatial synthesis over the stroke at 1 um spacing.
      const double points_per_m = 1e6;
      const disturbance::SynthesisOptions spatial{2 * o.amplitude_m, points_per_m};
      vertical = disturbance::SynthesiseSignal(o.straightness_psd[0], spatial, rng);
      lateral = disturbance::SynthesiseSignal(o.straightness_psd[1], spatial, rng);
      position = Eigen::VectorXd::LinSpaced(vertical.size(), -o.amplitude_m,
                                            -o.amplitude_m + (vertical.size() - 1) / points_per_m);
    }
    Eigen::MatrixXd delta0 = Eigen::MatrixXd::Zero(n, 6);
    for (int k = 0; k < n; ++k) {
      delta0(k, 0) = Interpolate(position, lateral, summary.setpoint(k));
      delta0(k, 2) = Interpolate(position, vertical, summary.setpoint(k));
    }
    std::vector<int> which;
    AddJointForceInputs(model, ty, {Dof::kDx, Dof::kDz}, inputs, which);
    const Eigen::MatrixXd f = JointForces(model, ty, delta0, dt, which);
    for (Eigen::Index c = 0; c < f.cols(); ++c) columns.push_back(f.col(c));
    summary.notes.push_back("straightness imposed as a deformation of joint '" + o.roles.translation_joint +
                            "' Dz (vertical) and Dx (lateral): forces K delta0 + C delta0' inside the joint");
  }
  const Eigen::MatrixXd u = InputMatrix(model, n, columns, inputs);

  Integrate(model, inputs, u, dt, TopPoses(kTranslationStage, summary.setpoint), Eigen::Vector3d(o.offset_m, 0, 0), summary);

  summary.error_names = {"vertical", "lateral", "scan"};
  summary.errors.resize(n, 3);
  const Eigen::VectorXd x = summary.poi_pose.col(0), z = summary.poi_pose.col(2);
  summary.errors.col(0) = z.array() - z.mean();
  summary.errors.col(1) = x.array() - x.mean();
  summary.errors.col(2) = summary.poi_pose.col(1) - summary.setpoint;
  summary.notes.push_back("linear model at the rest geometry (the stroke of +-" + std::to_string(o.amplitude_m) +
                          " m changes the lever arms by a negligible fraction)");
  Finish(summary, o.welch, o.sample_rate_hz);
  return summary;
}

std::string SimulationSummary::BriefReport() const {
  std::ostringstream out;
  out << experiment << ": " << time_s.size() << " samples, inputs:";
  for (const auto& in : input_names) out << " " << in;
  out << "\n";
  if (experiment == "tomography") {
    out << "best circle: eccentricity " << eccentricity_m * 1e9 << " nm at " << eccentricity_phase_rad * 180 / kPi
        << " deg, centre (" << circle_centre_x_m * 1e9 << ", " << circle_centre_y_m * 1e9 << ") nm\n";
  }
  for (const auto& s : statistics) {
    out << "  " << s.name << ": rms " << s.rms * 1e9 << " nm, peak-to-peak " << s.peak_to_peak * 1e9 << " nm\n";
  }
  out << "integration: " << (modal_integration ? "modal" : "dense") << " ZOH recurrence, "
      << integration_wall_time_s << " s\n";
  return out.str();
}

ComparisonSummary CompareWithMeasured(const SimulationSummary& simulation, const disturbance::CsvTable& measured,
                                      const disturbance::WelchOptions& welch) {
  const double measured_rate = disturbance::CalcSampleRate(measured, "time_s");
  const double simulated_rate = 1.0 / (simulation.time_s(1) - simulation.time_s(0));
  ComparisonSummary summary;
  for (size_t c = 0; c < simulation.error_names.size(); ++c) {
    const std::string& name = simulation.error_names[c];
    if (measured.FindColumn(name) < 0) continue;
    const Eigen::VectorXd meas = measured.Column(name);
    const Eigen::VectorXd sim = simulation.errors.col(static_cast<Eigen::Index>(c));
    disturbance::WelchOptions w = welch;
    if (w.segment_length == 0 && w.resolution_hz == 0) {
      // The coarser of the two default resolutions (8 averages), so that both records allow it.
      w.resolution_hz = std::max(simulated_rate / (sim.size() / 4.5), measured_rate / (meas.size() / 4.5));
    }
    ComparisonSummary::Channel channel;
    channel.name = name;
    channel.simulated = Statistics(name, sim);
    channel.measured = Statistics(name, meas);
    channel.simulated_psd = disturbance::EstimatePsd(sim, simulated_rate, w, "simulation", name);
    channel.measured_psd = disturbance::EstimatePsd(meas, measured_rate, w, measured.source, name);
    summary.channels.push_back(channel);
  }
  if (summary.channels.empty()) {
    std::string names;
    for (const auto& n : simulation.error_names) names += " " + n;
    throw InputError(measured.source + ": no column named like a simulated error (expected one of:" + names + ")");
  }
  return summary;
}

std::string ComparisonSummary::BriefReport() const {
  std::ostringstream out;
  out << "comparison with the measured record (rms / peak-to-peak, nm):\n";
  for (const auto& c : channels) {
    out << "  " << c.name << ": simulated " << c.simulated.rms * 1e9 << " / " << c.simulated.peak_to_peak * 1e9
        << ", measured " << c.measured.rms * 1e9 << " / " << c.measured.peak_to_peak * 1e9 << "\n";
  }
  return out.str();
}

}  // namespace stagefit::simulate
