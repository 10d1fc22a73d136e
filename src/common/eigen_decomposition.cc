#include "stagefit/common/eigen_decomposition.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

namespace stagefit {

namespace {

// Values and (when asked for) vectors of a solver that has run.
template <typename Solver>
std::optional<EigenPairs> Collect(const Solver& eig, bool with_vectors) {
  if (eig.info() != Eigen::Success) return std::nullopt;
  EigenPairs pairs;
  pairs.values = eig.eigenvalues();
  if (with_vectors) pairs.vectors = eig.eigenvectors();
  return pairs;
}

}  // namespace

std::optional<EigenPairs> CalcEigenPairs(const Eigen::MatrixXd& A, bool with_vectors) {
  return Collect(Eigen::EigenSolver<Eigen::MatrixXd>(A, with_vectors), with_vectors);
}

std::optional<EigenPairs> CalcEigenPairs(const Eigen::MatrixXcd& A, bool with_vectors) {
  if (A.imag().isZero(0.0)) return CalcEigenPairs(Eigen::MatrixXd(A.real()), with_vectors);
  return Collect(Eigen::ComplexEigenSolver<Eigen::MatrixXcd>(A, with_vectors), with_vectors);
}

std::optional<SymmetricEigenPairs> CalcGeneralizedSymmetricEigenPairs(const Eigen::MatrixXd& K,
                                                                      const Eigen::MatrixXd& M) {
  // Eigen's solver reduces with the Cholesky factor of M without checking it.
  if (Eigen::LLT<Eigen::MatrixXd>(M).info() != Eigen::Success) return std::nullopt;
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(K, M);
  if (eig.info() != Eigen::Success) return std::nullopt;
  return SymmetricEigenPairs{eig.eigenvalues(), eig.eigenvectors()};
}

std::optional<SymmetricEigenPairs> CalcSymmetricEigenPairs(const Eigen::MatrixXd& A) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(A);
  if (eig.info() != Eigen::Success) return std::nullopt;
  return SymmetricEigenPairs{eig.eigenvalues(), eig.eigenvectors()};
}

SingularValueDecomposition CalcSvd(const Eigen::MatrixXd& A, unsigned vectors) {
  unsigned options = 0;
  if (vectors & kSvdThinU) options |= Eigen::ComputeThinU;
  if (vectors & kSvdThinV) options |= Eigen::ComputeThinV;
  if (vectors & kSvdFullV) options |= Eigen::ComputeFullV;
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, options);
  SingularValueDecomposition result;
  result.values = svd.singularValues();
  if (vectors & kSvdThinU) result.U = svd.matrixU();
  if (vectors & (kSvdThinV | kSvdFullV)) result.V = svd.matrixV();
  return result;
}

}  // namespace stagefit
