#pragma once
// First-order state space of a SecondOrderSystem:  x' = A x + B u,  y = C x + D u.
//
// Without ground-motion inputs (B2 = 0) the state is x = [z; z'] and
//   A = [0 I; -M^-1 K, -M^-1 C], B = [0; M^-1 B0], C = [Cq 0], D = D0.
// With ground displacement inputs the B2 u'' term is removed exactly by the change of variables
//   x1 = z - G u, x2 = x1' + M^-1 C G u, with G = M^-1 B2,
// which gives (no derivative of u anywhere):
//   x1' = x2 - M^-1 C G u
//   x2' = -M^-1 K x1 - M^-1 C x2 + M^-1 (B0 - K G + C M^-1 C G) u
//   y   = Cq x1 + (Cq G + D0) u.
// The outputs are displacements (m, rad). A hysteretic loss (K_loss) has no real state-space form: it
// is replaced by the modal equivalent viscous damping C_eq = M Phi diag(phi_r' K_loss phi_r / w_r) Phi' M
// (mass-normalised undamped modes), which matches the loss at every resonance; `notes` says so. An
// acquisition delay is likewise not part of the state space and is reported in `notes`.

#include <Eigen/Core>

#include <string>
#include <vector>

#include "stagefit/model/linear_system.h"

namespace stagefit::model {

struct StateSpace {
  Eigen::MatrixXd A, B, C, D;
  std::vector<std::string> state_names, input_names, output_names;
  std::vector<std::string> notes;  ///< approximations made, if any
};

StateSpace CalcStateSpace(const SecondOrderSystem& system);

}  // namespace stagefit::model
