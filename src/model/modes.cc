#include "stagefit/model/modes.h"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>

#include "stagefit/common/eigen_decomposition.h"
#include "stagefit/common/error.h"

namespace stagefit::model {

NormalModes CalcNormalModes(const Eigen::MatrixXd& M, const Eigen::MatrixXd& K) {
  const auto eig = CalcGeneralizedSymmetricEigenPairs(K, M);
  if (!eig) throw NumericalError("generalised eigenproblem K phi = w^2 M phi failed");
  NormalModes modes;
  modes.omega_rad_s = eig->values.cwiseMax(0.0).cwiseSqrt();
  modes.shapes = eig->vectors;
  return modes;
}

ModalAnalysis CalcModes(const AssembledModel& model) {
  const int n = model.num_dofs();
  using Complex = std::complex<double>;
  Eigen::MatrixXcd A = Eigen::MatrixXcd::Zero(2 * n, 2 * n);
  Eigen::LLT<Eigen::MatrixXd> Mllt(model.M());
  if (Mllt.info() != Eigen::Success) throw NumericalError("the mass matrix is not positive definite");
  Eigen::MatrixXcd Kc = model.K().cast<Complex>() + Complex(0, 1) * model.K_loss().cast<Complex>();
  A.topRightCorner(n, n).setIdentity();
  A.bottomLeftCorner(n, n) = -Mllt.solve(Eigen::MatrixXd::Identity(n, n)).cast<Complex>() * Kc;
  A.bottomRightCorner(n, n) = -Mllt.solve(model.C()).cast<Complex>();

  const auto eig = CalcEigenPairs(A);  // the real solver when there is no loss
  if (!eig) throw NumericalError("eigen-decomposition of the state matrix failed");
  const Eigen::VectorXcd& lambda = eig->values;
  const Eigen::MatrixXcd& vectors = eig->vectors;

  ModalAnalysis result;
  const double scale = std::max(1.0, lambda.cwiseAbs().maxCoeff());
  int real_roots = 0;
  const auto& spec = model.spec();
  for (int k = 0; k < 2 * n; ++k) {
    if (std::abs(lambda(k).imag()) <= 1e-10 * scale) {
      ++real_roots;
      continue;
    }
    if (lambda(k).imag() < 0) continue;
    Mode mode;
    mode.eigenvalue = lambda(k);
    mode.frequency_hz = std::abs(lambda(k)) / (2 * M_PI);
    mode.damping_ratio = -lambda(k).real() / std::abs(lambda(k));
    Eigen::VectorXcd phi = vectors.col(k).head(n);
    Eigen::Index imax;
    phi.cwiseAbs().maxCoeff(&imax);
    phi /= phi(imax);
    mode.shape = phi;
    Eigen::VectorXcd Kphi = model.K().cast<Complex>() * phi;
    double strain_total = phi.dot(Kphi).real();  // dot() conjugates its first argument
    mode.strain_energy_share = Eigen::VectorXd::Zero(n);
    for (int i = 0; i < n; ++i) mode.strain_energy_share(i) = (std::conj(phi(i)) * Kphi(i)).real() / strain_total;
    double kinetic_total = phi.dot(model.M().cast<Complex>() * phi).real();
    mode.kinetic_energy_share = Eigen::VectorXd::Zero(static_cast<int>(spec.bodies.size()));
    for (size_t b = 0; b < spec.bodies.size(); ++b) {
      Eigen::Matrix<Complex, 6, 1> q = model.body_map(static_cast<int>(b)).cast<Complex>() * phi;
      const auto& body = spec.bodies[b];
      double e = body.mass_kg * q.head<3>().squaredNorm() +
                 q.tail<3>().dot(body.inertia_com_W.cast<Complex>() * q.tail<3>()).real();
      mode.kinetic_energy_share(static_cast<int>(b)) = e / kinetic_total;
    }
    Eigen::Index dominant;
    mode.strain_energy_share.maxCoeff(&dominant);
    mode.dominant_dof = static_cast<int>(dominant);
    mode.kinetic_energy_share.maxCoeff(&dominant);
    mode.dominant_body = static_cast<int>(dominant);
    result.modes.push_back(std::move(mode));
  }
  result.num_overdamped = real_roots / 2;
  std::sort(result.modes.begin(), result.modes.end(),
            [](const Mode& a, const Mode& b) { return a.frequency_hz < b.frequency_hz; });
  return result;
}

}  // namespace stagefit::model
