#pragma once
// Time-domain experiments on the stack: tomography (spindle turning) and raster scan (translation
// stage sweeping), driven by stage setpoints and disturbances (docs/simulation.md).
//
// The pose of the point of interest (PoI) relative to the granite is
//   large motion:  X_W_top(t) = CalcStackPoses(MicroStationStages(), setpoints(t)),  p_kin = X_W_top p_off
//   vibration:     [u; theta](t) of the sample body at the W origin relative to the granite (linear
//                  model, kRelativeMotion outputs), moved to the PoI: p = p_kin + u + theta x (R_W_top p_off)
// with p_off the PoI's offset from the W origin in the sample frame (the radial offset from the
// rotation axis in tomography). The linear model is integrated exactly (ZOH, ModalIntegrator) at the
// rest geometry; with a spinning spindle it is the inertial-frame model with the gyroscopic matrix,
// exact only for an axisymmetric spinning subtree (checked: InputError otherwise, see rotating_frame.h).
//
// Disturbances (all synthesised with disturbance::SynthesiseSignal from one std::mt19937_64(seed),
// drawn in the order ground Dx, Dy, Dz, then the stage errors):
// - ground displacement Dx, Dy, Dz (kGround inputs), each with the ground PSD;
// - a stage error as an imposed deformation delta0(t) of a joint (spindle Dx Dy Dz Rx Ry; translation
//   stage vertical Dz and lateral Dx as functions of its position), applied as the joint force pair
//   f = K_J delta0 + C_J delta0' (kJointForce inputs): below the joint's resonances the joint then
//   deforms by delta0, above them the stage's inertia filters it.

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "stagefit/disturbance/record_io.h"
#include "stagefit/disturbance/spectral_density.h"
#include "stagefit/disturbance/synthesis.h"
#include "stagefit/model/model_spec.h"

namespace stagefit::simulate {

/// Ground displacement PSD of a quiet experimental hall (an assumption, as
/// measurements/disturbance/ground_displacement_target.csv): 1e-8 m/sqrt(Hz) from 0.05 to 1 Hz,
/// falling as f^-2 to 128 Hz, m^2/Hz.
disturbance::PsdTable QuietHallGroundPsd();
/// Spindle error motion PSDs Dx, Dy, Dz (m^2/Hz), Rx, Ry (rad^2/Hz), falling as 1/f from 0.1 to 100 Hz
/// (as measurements/disturbance/spindle_target.csv: about 20, 20, 10 nm and 0.2, 0.2 urad rms).
std::array<disturbance::PsdTable, 5> DefaultSpindleErrorPsd();
/// Translation-stage straightness spatial PSDs, vertical then lateral, m^2/(1/m), falling as nu^-2
/// from 100 to 5e4 cycles/m (as measurements/disturbance/straightness_target.csv).
std::array<disturbance::PsdTable, 2> DefaultStraightnessPsd();

/// Which parts of the model play which role.
struct StackRoles {
  std::string granite_body = "granite";
  std::string sample_body = "hexapod";     ///< the body carrying the PoI (top of the stack)
  std::string translation_joint = "ty";
  std::string spindle_joint = "rz";
};

/// Statistics of one error signal.
struct ErrorStatistics {
  std::string name;
  double rms = 0.0;            ///< about the mean, m (rad for rotations)
  double peak_to_peak = 0.0;   ///< max - min
};

/// What both experiments return.
struct SimulationSummary {
  std::string experiment;                 ///< "tomography" or "raster"
  Eigen::VectorXd time_s;                 ///< N
  Eigen::VectorXd setpoint;               ///< N: spindle angle (rad, unwrapped) or stage position (m)
  Eigen::MatrixXd poi_pose;               ///< N x 6: Dx Dy Dz (m) Rx Ry Rz (rad, Rz unwrapped) of the
                                          ///< PoI relative to the granite, large motion plus vibration
  Eigen::MatrixXd vibration;              ///< N x 6: the linear model's part alone (at the W origin)
  std::vector<std::string> error_names;   ///< one per column of errors
  Eigen::MatrixXd errors;                 ///< N x E, m
  std::vector<ErrorStatistics> statistics;  ///< one per error column
  std::vector<disturbance::Spectrum> spectra;  ///< Welch PSD per error column, m^2/Hz
  std::vector<std::string> input_names;   ///< the model inputs driven
  // Tomography only: the best circle x = c_x + e cos(theta + phi), y = c_y + e sin(theta + phi).
  double eccentricity_m = 0.0;
  double eccentricity_phase_rad = 0.0;
  double circle_centre_x_m = 0.0;
  double circle_centre_y_m = 0.0;
  bool modal_integration = false;         ///< the fast modal recurrence was used
  std::vector<std::string> notes;         ///< modelling choices and approximations made
  double integration_wall_time_s = 0.0;   ///< time spent in the recurrence, s
  std::string BriefReport() const;
};

/// Rigid-body error motion measured at a reference point, moved to another point of the same body
/// (docs/simulation.md, "Spindle errors: where they are measured"). `motion_P` is n x 6 or n x 5:
/// translations d_P (m) and small rotations theta (rad) [Dx Dy Dz Rx Ry (Rz)] at p_P, W axes. The
/// rotation is the same everywhere on the body; the translation at p_J is the lever arm
///     d_J = d_P + theta x (p_J - p_P).
/// Returns the same columns at p_J. Throws InputError unless 5 or 6 columns.
Eigen::MatrixXd TransferErrorMotion(const Eigen::MatrixXd& motion_P, const Eigen::Vector3d& p_P, const Eigen::Vector3d& p_J);

/// Spindle error PSDs from a PSD table (frequency_hz and columns Dx, Dy, Dz in m^2/Hz, Rx, Ry in
/// rad^2/Hz; every column required, others ignored). Throws InputError naming the table's source and
/// the missing column or the bad value.
std::array<disturbance::PsdTable, 5> SpindleErrorPsdFromTable(const disturbance::CsvTable& table);

struct TomographyOptions {
  double duration_s = 10.0;               ///< > 0, s
  double sample_rate_hz = 10000.0;        ///< > 0, Hz
  double speed_rad_s = 2 * 3.14159265358979323846;  ///< spindle rate Omega (60 rpm), rad/s
  double offset_m = 1e-6;                 ///< radial offset of the PoI from the axis (along x at t = 0), m
  std::uint64_t seed = 1;
  bool ground_motion = true;
  bool spindle_error = true;
  disturbance::PsdTable ground_psd = QuietHallGroundPsd();
  std::array<disturbance::PsdTable, 5> spindle_error_psd = DefaultSpindleErrorPsd();
  /// Where the spindle error motion is measured (a spindle analyser's sphere), m in W; default the PoI
  /// (the W origin, on the rotation axis). The error is moved from there to the spindle joint's origin by
  /// the rigid lever arm (TransferErrorMotion) before it is imposed as the joint's deformation.
  Eigen::Vector3d spindle_error_reference_W = Eigen::Vector3d::Zero();
  StackRoles roles;
  disturbance::WelchOptions welch;        ///< for the error spectra
};

/// Runs the tomography experiment: theta(t) = Omega t, errors "x", "y", "z" (deviation from the mean,
/// the eccentricity circle included), "x_fit", "y_fit" (the best circle removed by linear least
/// squares over both channels), "radial" (the fitted residual along the PoI's radial direction) and
/// "axial" (z deviation). Throws InputError for invalid options (naming the field), roles that are not
/// in the model, or a spinning subtree that is not axisymmetric (listing why).
SimulationSummary RunTomography(const model::ModelSpec& spec, const TomographyOptions& options);

struct RasterOptions {
  double duration_s = 10.0;
  double sample_rate_hz = 10000.0;
  double amplitude_m = 4.5e-3;            ///< triangle setpoint between -amplitude and +amplitude, m
  double period_s = 1.0;                  ///< one full back-and-forth, s
  double offset_m = 0.0;                  ///< PoI offset along x from the W origin, m
  std::uint64_t seed = 1;
  bool ground_motion = true;
  bool straightness_error = true;
  disturbance::PsdTable ground_psd = QuietHallGroundPsd();
  std::array<disturbance::PsdTable, 2> straightness_psd = DefaultStraightnessPsd();
  /// Optional measured straightness (position_m and vertical_m / lateral_m, m) used instead of the
  /// synthesised one; interpolated linearly at the stage position, its best line removed.
  Eigen::VectorXd straightness_position_m;
  Eigen::VectorXd straightness_vertical_m;
  Eigen::VectorXd straightness_lateral_m;
  StackRoles roles;
  disturbance::WelchOptions welch;
};

/// Runs the raster scan: y_set(t) a triangle starting at -amplitude, errors "vertical" (Dz deviation),
/// "lateral" (Dx deviation) and "scan" (Dy - y_set). Throws InputError as RunTomography.
SimulationSummary RunRaster(const model::ModelSpec& spec, const RasterOptions& options);

/// Side-by-side statistics and PSDs of a simulation and a measured time series.
struct ComparisonSummary {
  struct Channel {
    std::string name;
    ErrorStatistics simulated, measured;
    disturbance::Spectrum simulated_psd, measured_psd;   ///< same resolution
  };
  std::vector<Channel> channels;
  std::string BriefReport() const;
};

/// Compares every column of `measured` (a CSV table with a first column time_s) whose name is one of
/// the simulation's error names. Both PSDs use `welch` with the resolution forced to the coarser of
/// the two records' defaults so that the bins coincide. Throws InputError naming the file when there is
/// no time_s column, no common column, or a record is too short.
ComparisonSummary CompareWithMeasured(const SimulationSummary& simulation, const disturbance::CsvTable& measured,
                                      const disturbance::WelchOptions& welch);

/// Least-squares circle through (x, y) at angles theta: x = c_x + a cos - b sin, y = c_y + b cos + a sin
/// (a = e cos phi, b = e sin phi). Returns [c_x, c_y, a, b]. Requires equal sizes >= 4.
Eigen::Vector4d FitCircle(const Eigen::VectorXd& x, const Eigen::VectorXd& y, const Eigen::VectorXd& theta);

}  // namespace stagefit::simulate
