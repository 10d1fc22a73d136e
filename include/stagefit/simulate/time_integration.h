#pragma once
// Exact time integration of a linear time-invariant state space  x' = A x + B u,  y = C x + D u  with
// the inputs held constant over each step (zero-order hold, ZOH):
//
//   x[k+1] = Ad x[k] + Bd u[k],   y[k] = C x[k] + D u[k],
//   [Ad Bd; 0 I] = exp([A B; 0 0] dt)                     (one matrix exponential per model and step).
//
// For a stable, diagonalisable A (every damped structure) the fast path works in real modal
// coordinates: A = T Lambda T^-1 with Lambda block diagonal (1x1 blocks for real eigenvalues,
// [s w; -w s] for each pair s +- j w, T = [Re v, Im v]), so that one step costs 4 n + n ni + no n
// flops instead of n^2 + n ni + no n. Both paths implement the same recurrence (tested to agree).

#include <Eigen/Core>

#include <string>
#include <vector>

#include "stagefit/model/state_space.h"

namespace stagefit::simulate {

/// The ZOH discretisation of a state space.
struct DiscreteStateSpace {
  Eigen::MatrixXd Ad, Bd, C, D;  ///< n x n, n x ni, no x n, no x ni
  double time_step_s = 0.0;      ///< dt, s
};

/// [Ad Bd; 0 I] = exp([A B; 0 0] dt) (Eigen's MatrixFunctions, scaling and squaring Pade).
/// Throws InputError unless dt is finite and > 0 and the sizes of A, B, C, D agree.
DiscreteStateSpace DiscretiseZeroOrderHold(const model::StateSpace& system, double time_step_s);

/// Reference integrator: the dense recurrence above, one n x n matrix-vector product per step.
/// u: N x ni inputs (row k is u[k], held over [k dt, (k+1) dt)); x0: n initial states (empty = 0).
/// Returns N x no outputs y[k]. Throws InputError when u has the wrong number of columns or x0 the
/// wrong size.
Eigen::MatrixXd SimulateDense(const DiscreteStateSpace& system, const Eigen::MatrixXd& u,
                              const Eigen::VectorXd& x0 = Eigen::VectorXd());

/// A second reference: classical fourth-order Runge-Kutta with step dt and u held constant over each
/// step (the same ZOH input), error O(dt^4) per unit time. Same arguments and result as SimulateDense.
Eigen::MatrixXd SimulateRungeKutta4(const model::StateSpace& system, double time_step_s,
                                    const Eigen::MatrixXd& u,
                                    const Eigen::VectorXd& x0 = Eigen::VectorXd());

struct ModalIntegratorOptions {
  /// The modal form is used only when ||T Lambda T^-1 - A|| <= tolerance ||A|| (Frobenius norms) and
  /// T is well conditioned (rcond > min_rcond); otherwise the dense recurrence is used and the
  /// summary says why. Rounding of a 54-state model gives ~1e-13; 1e-8 flags a defective A.
  double reconstruction_tolerance = 1e-8;
  double min_rcond = 1e-12;
};

/// The ZOH recurrence in real modal coordinates xi = T^-1 x:
///   xi[k+1] = Phi xi[k] + Gamma u[k],   y[k] = (C T) xi[k] + D u[k],
///   Phi = exp(Lambda dt) (closed form per block: e^{s dt} [cos w dt, sin w dt; -sin w dt, cos w dt]),
///   Gamma = T^-1 Bd with Bd from DiscretiseZeroOrderHold.
/// Falls back to the dense recurrence when A is not safely diagonalisable (see options).
class ModalIntegrator {
 public:
  /// Throws InputError as DiscretiseZeroOrderHold.
  ModalIntegrator(const model::StateSpace& system, double time_step_s,
                  const ModalIntegratorOptions& options = {});

  /// Same contract as SimulateDense (x0 in the original state coordinates).
  Eigen::MatrixXd Simulate(const Eigen::MatrixXd& u, const Eigen::VectorXd& x0 = Eigen::VectorXd()) const;

  bool is_modal() const { return modal_; }
  /// Why the dense path was taken, or empty.
  const std::string& message() const { return message_; }
  const DiscreteStateSpace& discrete() const { return discrete_; }
  int num_states() const { return static_cast<int>(discrete_.Ad.rows()); }
  int num_inputs() const { return static_cast<int>(discrete_.Bd.cols()); }
  int num_outputs() const { return static_cast<int>(discrete_.C.rows()); }

 private:
  DiscreteStateSpace discrete_;
  bool modal_ = false;
  std::string message_;
  Eigen::MatrixXd T_;              // n x n, modal basis
  Eigen::MatrixXd T_inverse_;      // n x n
  std::vector<int> block_size_;    // 1 or 2 per block, in order
  Eigen::MatrixXd phi_;            // 2 x n: columns hold the block entries (see .cc)
  Eigen::MatrixXd gamma_t_;        // ni x n: Gamma transposed, so that a state's row is contiguous
  Eigen::MatrixXd c_modal_;        // no x n
};

}  // namespace stagefit::simulate
