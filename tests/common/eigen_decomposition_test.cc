#include "stagefit/common/eigen_decomposition.h"

#include <gtest/gtest.h>

#include <complex>

namespace stagefit {
namespace {

// A V = V diag(values), relative to |A| |V|.
double EigenResidual(const Eigen::MatrixXcd& A, const EigenPairs& e) {
  return (A * e.vectors - e.vectors * e.values.asDiagonal()).norm() / (A.norm() * e.vectors.norm());
}

TEST(CalcEigenPairs, RealMatrixGivesExactConjugatePairs) {
  std::srand(3);
  const Eigen::MatrixXd A = Eigen::MatrixXd::Random(12, 12);
  const auto e = CalcEigenPairs(A);
  ASSERT_TRUE(e.has_value());
  EXPECT_LT(EigenResidual(A.cast<std::complex<double>>(), *e), 1e-13);
  // Every eigenvalue's conjugate is in the list, to the last bit (the real Schur form pairs them).
  for (int i = 0; i < e->values.size(); ++i) {
    bool found = false;
    for (int j = 0; j < e->values.size(); ++j) found = found || e->values(j) == std::conj(e->values(i));
    EXPECT_TRUE(found) << e->values(i);
  }
  // The same matrix given as complex takes the real path: the same numbers.
  const auto c = CalcEigenPairs(Eigen::MatrixXcd(A.cast<std::complex<double>>()));
  ASSERT_TRUE(c.has_value());
  EXPECT_EQ((c->values - e->values).norm(), 0.0);
}

TEST(CalcEigenPairs, ComplexMatrixAndValuesOnly) {
  std::srand(4);
  const Eigen::MatrixXcd A = Eigen::MatrixXcd::Random(10, 10);
  const auto e = CalcEigenPairs(A);
  ASSERT_TRUE(e.has_value());
  EXPECT_LT(EigenResidual(A, *e), 1e-13);
  // The trace is the sum of the eigenvalues.
  EXPECT_NEAR(std::abs(e->values.sum() - A.trace()), 0.0, 1e-12 * A.norm());
  const auto values_only = CalcEigenPairs(A, /*with_vectors=*/false);
  ASSERT_TRUE(values_only.has_value());
  EXPECT_EQ(values_only->vectors.size(), 0);
  EXPECT_NEAR(std::abs(values_only->values.sum() - A.trace()), 0.0, 1e-12 * A.norm());
}

TEST(CalcGeneralizedSymmetricEigenPairs, MassOrthonormalModes) {
  std::srand(5);
  const Eigen::MatrixXd R = Eigen::MatrixXd::Random(8, 8);
  const Eigen::MatrixXd M = R * R.transpose() + 8 * Eigen::MatrixXd::Identity(8, 8);
  const Eigen::MatrixXd S = Eigen::MatrixXd::Random(8, 8);
  const Eigen::MatrixXd K = S * S.transpose();
  const auto e = CalcGeneralizedSymmetricEigenPairs(K, M);
  ASSERT_TRUE(e.has_value());
  const Eigen::MatrixXd& V = e->vectors;
  EXPECT_LT((V.transpose() * M * V - Eigen::MatrixXd::Identity(8, 8)).norm(), 1e-12);
  EXPECT_LT((K * V - M * V * e->values.asDiagonal()).norm(), 1e-12 * K.norm());
  for (int i = 1; i < 8; ++i) EXPECT_LE(e->values(i - 1), e->values(i));
  // M not positive definite: no result.
  EXPECT_FALSE(CalcGeneralizedSymmetricEigenPairs(K, -M).has_value());
}

}  // namespace
}  // namespace stagefit
