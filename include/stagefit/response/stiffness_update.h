#pragma once
// Responses of a model::SecondOrderSystem whose dynamic stiffness changes in a few generalised
// coordinates, from factors of the unchanged system computed once (the Woodbury identity).
//
// With Z(s) = M s^2 + C s + K + j K_loss (frf_evaluator.h) and a change dZ(s) = P_U D(s) P_U' confined
// to the coordinates U (P_U: the columns of the identity for U; D(s) = dK + j dK_loss + s dC, |U| x |U|),
//     (Z + P_U D P_U')^-1 = Z^-1 - Z^-1 P_U (I + D G_UU)^-1 D P_U' Z^-1,      G = P_T' Z^-1 P_T,
// so that for U within a set T of coordinates fixed at set-up
//     H'(s) = H(s) - Y_U(s) (I + D G_UU)^-1 D X_U(s),
//     Y = s^p e^{-s tau} Cq Z^-1 P_T (Nout x |T|),      X = P_T' Z^-1 (B0 + s^2 B2) (|T| x Nin).
// The factors H, Y, X and G come from one evaluation of the system with |T| more inputs (P_T) and
// outputs (P_T'), by FrfEvaluator (modal or direct as it chooses); each changed system then costs
// O(|U| Nout Nin) per frequency instead of a new set-up (an eigen-decomposition) and evaluation. A
// change of mass is not of this form (it also changes the ground-input term s^2 B2) and is refused.
//
// This is what the basin probes of a fit need (fit::SolveWithProbes): hundreds of models, each with
// one or two joint stiffnesses, dampings or coupling terms changed by a factor (model/parameters.h:
// the system is linear in each of them).

#include <Eigen/Core>

#include <vector>

#include "stagefit/model/linear_system.h"
#include "stagefit/response/frf_evaluator.h"

namespace stagefit::response {

class StiffnessUpdate {
 public:
  /// Factors of `system` at `frequency_hz` (Hz, as FrfEvaluator::Evaluate() takes them) for the
  /// response `quantity` and the coordinates `coordinates` (T: distinct, each in [0, n)). Throws
  /// InputError for a coordinate outside the system or given twice, and as FrfEvaluator::Create() and
  /// Evaluate() do.
  static StiffnessUpdate Create(const model::SecondOrderSystem& system, const Eigen::VectorXd& frequency_hz,
                                ResponseQuantity quantity, const std::vector<int>& coordinates,
                                const FrfEvaluatorOptions& options = {});

  int num_frequencies() const { return static_cast<int>(omega_rad_s_.size()); }
  int num_outputs() const { return no_; }
  int num_inputs() const { return ni_; }
  /// The unchanged system's H (layout of FrfArray::values: Nf x (Nout * Nin)).
  const Eigen::MatrixXcd& values() const { return values_; }

  /// H' of the system with Z changed by `change` (its entries summed: entries in the system's
  /// coordinates, each row and column in the set-up's coordinates, mass 0) into `out` (resized to
  /// Nf x (Nout * Nin), layout of FrfArray::values). Returns false when the result is not finite (I +
  /// D G_UU singular at a frequency: the changed system has a pole there) or more than kMaxChanged
  /// coordinates change; `out` is then unspecified. Throws InputError for an entry outside the
  /// coordinates or with a mass.
  bool Evaluate(const std::vector<DynamicStiffnessDerivative::Entry>& change, Eigen::MatrixXcd* out) const;

  /// The most coordinates one change may touch.
  static constexpr int kMaxChanged = 8;

 private:
  StiffnessUpdate() = default;

  Eigen::VectorXd omega_rad_s_;
  int power_ = 0;
  double delay_s_ = 0.0;
  int no_ = 0, ni_ = 0, nt_ = 0;  // outputs, inputs, |T|
  std::vector<int> position_;  // per system coordinate: its index in T, or -1
  // Per frequency (column f), the augmented receptance [H0, Cq Z^-1 P_T; P_T' Z^-1 B, G] column-major
  // ((Nout + |T|) x (Nin + |T|)), without s^p e^{-s tau}.
  Eigen::MatrixXcd augmented_;
  Eigen::MatrixXcd values_;
  Eigen::VectorXcd prefactor_;  // per frequency: s^p e^{-s tau}
};

}  // namespace stagefit::response
