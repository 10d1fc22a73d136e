#pragma once
// Modes of the assembled model: natural frequencies, damping ratios, complex mode shapes, and where
// each mode lives: its strain-energy share per joint DoF and kinetic-energy share per body.

#include <Eigen/Core>

#include <complex>
#include <string>
#include <vector>

#include "stagefit/model/assembled_model.h"

namespace stagefit::model {

struct Mode {
  std::complex<double> eigenvalue;       ///< lambda, rad/s (Im > 0)
  double frequency_hz = 0.0;             ///< |lambda| / 2 pi
  double damping_ratio = 0.0;            ///< -Re(lambda) / |lambda|
  Eigen::VectorXcd shape;                ///< generalised coordinates z, largest element 1
  Eigen::VectorXd strain_energy_share;   ///< per generalised coordinate (joint DoF), sums to 1
  Eigen::VectorXd kinetic_energy_share;  ///< per body, sums to 1
  int dominant_dof = -1;                 ///< index into dof_names() with the largest strain share
  int dominant_body = -1;                ///< body with the largest kinetic share
};

struct ModalAnalysis {
  std::vector<Mode> modes;    ///< sorted by frequency
  int num_overdamped = 0;     ///< real eigenvalue pairs (no oscillation), not listed in `modes`
};

/// Eigen-decomposition of the first-order system [0 I; -M^-1 (K + j K_loss), -M^-1 C].
/// Strain share of coordinate i: Re(conj(phi_i) (K phi)_i) / Re(phi^H K phi); kinetic share of body b:
/// Re(q_b^H M_b q_b) / Re(phi^H M phi) with q_b = Phi_b phi. Throws NumericalError if the
/// eigen-solver fails.
ModalAnalysis CalcModes(const AssembledModel& model);

/// Undamped normal modes: K phi = omega^2 M phi, mass-normalised (phi' M phi = 1), ascending.
struct NormalModes {
  Eigen::VectorXd omega_rad_s;
  Eigen::MatrixXd shapes;  ///< n x n, one mode per column
};
NormalModes CalcNormalModes(const Eigen::MatrixXd& M, const Eigen::MatrixXd& K);

}  // namespace stagefit::model
