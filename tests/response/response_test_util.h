#pragma once
// Helpers shared by the response tests: frequency grids and the comparison of two FRF arrays
// element by element.

#include <gtest/gtest.h>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>

namespace stagefit::response::testing {

/// `n` logarithmically spaced frequencies from `fmin` to `fmax` (Hz).
inline Eigen::VectorXd LogFrequencies(double fmin, double fmax, int n) {
  Eigen::VectorXd f(n);
  for (int i = 0; i < n; ++i) f(i) = fmin * std::pow(fmax / fmin, static_cast<double>(i) / (n - 1));
  return f;
}

/// Elements that vanish by symmetry are exact zeros in a dense direct solve and rounding noise in a
/// modal sum: about 2n eps cond(V) ~ 1e-13 of the largest element of the matrix for the micro-station
/// (54 poles, cond(V) ~ 12). They must stay below this fraction of that largest element.
constexpr double kStructuralZero = 1e-12;

/// Largest |a - b| per element (column) over the frequencies (rows), divided by that element's peak
/// |b|; elements with a zero peak are checked against kStructuralZero of the largest |b| and not
/// counted.
inline double WorstRelativeToPeak(const Eigen::MatrixXcd& a, const Eigen::MatrixXcd& b) {
  double worst = 0.0;
  const double global_peak = b.cwiseAbs().maxCoeff();
  for (Eigen::Index c = 0; c < b.cols(); ++c) {
    const double peak = b.col(c).cwiseAbs().maxCoeff();
    const double error = (a.col(c) - b.col(c)).cwiseAbs().maxCoeff();
    if (peak == 0.0) {
      EXPECT_LE(error, kStructuralZero * global_peak) << "element " << c << " vanishes by symmetry";
      continue;
    }
    worst = std::max(worst, error / peak);
  }
  return worst;
}

}  // namespace stagefit::response::testing
