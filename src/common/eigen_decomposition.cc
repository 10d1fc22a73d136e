#include "stagefit/common/eigen_decomposition.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

namespace stagefit {

std::optional<EigenPairs> CalcEigenPairs(const Eigen::MatrixXd& A, bool with_vectors) {
  Eigen::EigenSolver<Eigen::MatrixXd> eig(A, with_vectors);
  if (eig.info() != Eigen::Success) return std::nullopt;
  EigenPairs pairs;
  pairs.values = eig.eigenvalues();
  if (with_vectors) pairs.vectors = eig.eigenvectors();
  return pairs;
}

std::optional<EigenPairs> CalcEigenPairs(const Eigen::MatrixXcd& A, bool with_vectors) {
  if (A.imag().isZero(0.0)) return CalcEigenPairs(Eigen::MatrixXd(A.real()), with_vectors);
  Eigen::ComplexEigenSolver<Eigen::MatrixXcd> eig(A, with_vectors);
  if (eig.info() != Eigen::Success) return std::nullopt;
  EigenPairs pairs;
  pairs.values = eig.eigenvalues();
  if (with_vectors) pairs.vectors = eig.eigenvectors();
  return pairs;
}

std::optional<SymmetricEigenPairs> CalcGeneralizedSymmetricEigenPairs(const Eigen::MatrixXd& K,
                                                                      const Eigen::MatrixXd& M) {
  // Eigen's solver reduces with the Cholesky factor of M without checking it.
  if (Eigen::LLT<Eigen::MatrixXd>(M).info() != Eigen::Success) return std::nullopt;
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(K, M);
  if (eig.info() != Eigen::Success) return std::nullopt;
  return SymmetricEigenPairs{eig.eigenvalues(), eig.eigenvectors()};
}

}  // namespace stagefit
