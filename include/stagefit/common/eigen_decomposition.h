#pragma once
// Dense eigen-decompositions, instantiated in one translation unit.
//
// Eigen's general eigen-solvers (real and complex Schur) take tens of seconds each to compile; the
// model, response and simulation layers all need them. They are compiled here, once, and called
// through these functions.

#include <Eigen/Core>

#include <optional>

namespace stagefit {

/// Eigenvalues and eigenvectors of a square matrix (vectors empty when not asked for).
struct EigenPairs {
  Eigen::VectorXcd values;
  Eigen::MatrixXcd vectors;  ///< one per column, in the order of `values`
};

/// A = V diag(values) V^-1 by the real solver (real Schur form) when every imaginary part of A is
/// exactly zero, by the complex one (complex Schur form) otherwise; the real path gives exact
/// conjugate pairs. std::nullopt when the solver does not converge.
std::optional<EigenPairs> CalcEigenPairs(const Eigen::MatrixXcd& A, bool with_vectors = true);

/// The same for a real matrix.
std::optional<EigenPairs> CalcEigenPairs(const Eigen::MatrixXd& A, bool with_vectors = true);

/// Symmetric-definite pencil K phi = lambda M phi (K symmetric, M symmetric positive definite):
/// ascending eigenvalues and M-orthonormal eigenvectors. std::nullopt when M is not positive
/// definite or the solver fails.
struct SymmetricEigenPairs {
  Eigen::VectorXd values;
  Eigen::MatrixXd vectors;
};
std::optional<SymmetricEigenPairs> CalcGeneralizedSymmetricEigenPairs(const Eigen::MatrixXd& K,
                                                                      const Eigen::MatrixXd& M);

}  // namespace stagefit
