#pragma once
// Spindle error motion from an error analyser: five capacitive sensors looking at two precision
// spheres mounted on the spindle's rotor.
//
// Geometry assumed (heights along the spindle axis z, m, in any datum shared by the three values):
//   sphere 1 at height z1, sphere 2 at height z2 > z1, both centred (nominally) on the axis;
//   radial sensors x1, y1 at sphere 1 and x2, y2 at sphere 2, measuring along +x and +y;
//   one axial sensor z on the top of sphere 2, on the axis, measuring along +z.
//   A reading is the displacement of the target surface along the sensor's axis, m (positive when
//   the target moves along +x, +y or +z).
// Small rigid motion of the rotor (Dx, Dy, Dz at the reference height z_r; small rotations Rx, Ry)
// moves a point of the axis at height z by dx = Dx + (z - z_r) Ry, dy = Dy - (z - z_r) Rx, dz = Dz.
// A sphere i mounted off the axis by e_i at angle phi_i in the rotor adds its once-per-revolution
// circle (e_i cos(theta + phi_i), e_i sin(theta + phi_i)) at spindle angle theta, plus constant sensor
// offsets (c_xi, c_yi). Hence
//   x_i = c_xi + e_i cos(theta + phi_i) + Dx + (z_i - z_r) Ry
//   y_i = c_yi + e_i sin(theta + phi_i) + Dy - (z_i - z_r) Rx
//   z   = c_z + a_z cos(theta + phi_z) + Dz
// The analysis fits, for each sphere, the best circle (c_x, c_y, e cos phi, e sin phi: linear least
// squares over both radial channels together) and, for the axial channel, a constant and optionally a
// once-per-revolution sinusoid; removes them; then inverts the geometry for the stochastic part:
//   Ry = (x2 - x1) / (z2 - z1),   Rx = -(y2 - y1) / (z2 - z1),
//   Dx = x1 - (z1 - z_r) Ry,      Dy = y1 + (z1 - z_r) Rx,      Dz = z.

#include <Eigen/Dense>

#include <array>
#include <string>

#include "stagefit/disturbance/spectral_density.h"

namespace stagefit::disturbance {

/// Sensor columns, in this order, in SpindleRecord::sensors_m.
inline constexpr std::array<const char*, 5> kSpindleSensorNames = {"x1", "y1", "x2", "y2", "z"};
/// Motion columns, in this order, in SpindleErrorSummary::motion.
inline constexpr std::array<const char*, 5> kSpindleMotionNames = {"Dx", "Dy", "Dz", "Rx", "Ry"};

/// Heights of the spheres and of the point where Dx, Dy, Dz are given, m (the defaults are this
/// project's assumption for the reference set-up: spheres 100 mm apart, motions at the upper sphere).
struct SpindleGeometry {
  double sphere1_height_m = 0.0;    ///< z1
  double sphere2_height_m = 0.1;    ///< z2 > z1
  double reference_height_m = 0.1;  ///< z_r
};

/// One error-analyser record.
struct SpindleRecord {
  double sample_rate_hz = 0.0;  ///< fs > 0, Hz
  Eigen::MatrixXd sensors_m;    ///< N x 5 readings x1 y1 x2 y2 z, m
  /// N spindle angles theta, rad (unwrapped or not); empty: theta = omega t, t = n / fs, with
  /// omega = SpindleOptions::rotation_speed_rad_s.
  Eigen::VectorXd angle_rad;
};

struct SpindleOptions {
  SpindleGeometry geometry;
  double rotation_speed_rad_s = 0.0;     ///< omega, rad/s (60 rpm = 2 pi rad/s); used without angles
  bool remove_axial_once_per_rev = true; ///< fit and remove a_z cos(theta + phi_z) from z
  WelchOptions welch;                    ///< PSD of the residual motions
};

/// The fitted once-per-revolution circle of one sphere.
struct SphereEccentricity {
  double amplitude_m = 0.0;  ///< e, m
  double phase_rad = 0.0;    ///< phi in (-pi, pi], rad
  double offset_x_m = 0.0;   ///< c_x, m
  double offset_y_m = 0.0;   ///< c_y, m
};

struct SpindleErrorSummary {
  std::array<SphereEccentricity, 2> eccentricity;
  double axial_offset_m = 0.0;        ///< c_z, m
  double axial_amplitude_m = 0.0;     ///< a_z, m (0 when not removed)
  double axial_phase_rad = 0.0;       ///< phi_z, rad
  double revolutions = 0.0;           ///< angle covered by the record / 2 pi
  Eigen::VectorXd angle_rad;          ///< N angles used
  Eigen::MatrixXd motion;             ///< N x 5 residual motions Dx Dy Dz (m) Rx Ry (rad)
  std::array<double, 5> rms{};        ///< rms of each motion column (m or rad)
  std::array<double, 5> peak_to_peak{};
  std::array<Spectrum, 5> psd;        ///< Welch PSD of each motion column, m^2/Hz or rad^2/Hz
  std::string BriefReport() const;
};

/// Analyses a record as described at the top of this file. Throws InputError naming `record` (and
/// the sensor) when the sensors matrix is not N x 5 with N >= 8, a value is NaN/Inf, the angles are
/// not N values, there is neither an angle column nor a rotation speed > 0, the record covers less
/// than one revolution (the circle fit needs one), z2 <= z1, or the record is too short for the
/// Welch options.
SpindleErrorSummary AnalyseSpindleError(const SpindleRecord& record, const SpindleOptions& options,
                                        const std::string& record_name);

/// The forward model (the equations above): sensor readings N x 5 (x1 y1 x2 y2 z, m) from rigid
/// motions N x 5 (Dx Dy Dz m, Rx Ry rad), N angles (rad), the two spheres' circles and an axial
/// once-per-revolution term. Used to synthesise records and in tests.
Eigen::MatrixXd CalcSpindleSensorSignals(const Eigen::MatrixXd& motion,
                                         const Eigen::VectorXd& angle_rad,
                                         const SpindleGeometry& geometry,
                                         const std::array<SphereEccentricity, 2>& eccentricity,
                                         double axial_offset_m, double axial_amplitude_m,
                                         double axial_phase_rad);

}  // namespace stagefit::disturbance
