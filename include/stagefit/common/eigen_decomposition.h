#pragma once
// Dense eigen- and singular value decompositions, instantiated in one translation unit.
//
// Eigen's general eigen-solvers (real and complex Schur) take 10-20 s each to compile, its symmetric
// eigen-solver and its Jacobi SVD 7-9 s (g++ 12, -O3): every file that named one paid that again. The
// model, response, measurement, fit and simulation layers and their tests call them through these
// functions, compiled here once.

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

/// Symmetric A (its lower triangle is read): ascending eigenvalues and orthonormal eigenvectors.
/// std::nullopt when the solver does not converge.
std::optional<SymmetricEigenPairs> CalcSymmetricEigenPairs(const Eigen::MatrixXd& A);

/// A = U diag(values) V' by Eigen's two-sided Jacobi SVD: min(m, n) singular values, descending; U and V
/// only as asked for (`vectors`: an or of SvdVectors), thin (min(m, n) columns) or full (V: n columns).
enum SvdVectors : unsigned { kSvdValuesOnly = 0, kSvdThinU = 1, kSvdThinV = 2, kSvdFullV = 4 };
struct SingularValueDecomposition {
  Eigen::VectorXd values;
  Eigen::MatrixXd U;
  Eigen::MatrixXd V;
};
SingularValueDecomposition CalcSvd(const Eigen::MatrixXd& A, unsigned vectors = kSvdValuesOnly);

}  // namespace stagefit
