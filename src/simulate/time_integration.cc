#include "stagefit/simulate/time_integration.h"

#include <Eigen/LU>
#include <unsupported/Eigen/MatrixFunctions>

#include <cmath>
#include <sstream>

#include "stagefit/common/eigen_decomposition.h"
#include "stagefit/common/error.h"

namespace stagefit::simulate {
namespace {

void CheckSizes(const model::StateSpace& s) {
  const auto n = s.A.rows();
  if (s.A.cols() != n || s.B.rows() != n || s.C.cols() != n || s.D.rows() != s.C.rows() ||
      s.D.cols() != s.B.cols()) {
    std::ostringstream out;
    out << "state space: inconsistent sizes A " << s.A.rows() << "x" << s.A.cols() << ", B " << s.B.rows() << "x"
        << s.B.cols() << ", C " << s.C.rows() << "x" << s.C.cols() << ", D " << s.D.rows() << "x" << s.D.cols();
    throw InputError(out.str());
  }
}

Eigen::VectorXd InitialState(const Eigen::VectorXd& x0, Eigen::Index n) {
  if (x0.size() == 0) return Eigen::VectorXd::Zero(n);
  if (x0.size() != n) {
    throw InputError("simulation: initial state has " + std::to_string(x0.size()) + " values, expected " +
                     std::to_string(n));
  }
  return x0;
}

void CheckInputs(const Eigen::MatrixXd& u, Eigen::Index num_inputs) {
  if (u.cols() != num_inputs) {
    throw InputError("simulation: input signal has " + std::to_string(u.cols()) + " columns, expected " +
                     std::to_string(num_inputs) + " (one per model input)");
  }
}

}  // namespace

DiscreteStateSpace DiscretiseZeroOrderHold(const model::StateSpace& system, double time_step_s) {
  CheckSizes(system);
  if (!std::isfinite(time_step_s) || time_step_s <= 0) {
    throw InputError("simulation: time step = " + std::to_string(time_step_s) + " s, expected a finite value > 0");
  }
  const Eigen::Index n = system.A.rows(), ni = system.B.cols();
  Eigen::MatrixXd augmented = Eigen::MatrixXd::Zero(n + ni, n + ni);
  augmented.topLeftCorner(n, n) = system.A * time_step_s;
  augmented.topRightCorner(n, ni) = system.B * time_step_s;
  const Eigen::MatrixXd exponential = augmented.exp();
  DiscreteStateSpace d;
  d.Ad = exponential.topLeftCorner(n, n);
  d.Bd = exponential.topRightCorner(n, ni);
  d.C = system.C;
  d.D = system.D;
  d.time_step_s = time_step_s;
  if (!d.Ad.allFinite() || !d.Bd.allFinite()) {
    throw NumericalError("simulation: the matrix exponential of the state matrix is not finite");
  }
  return d;
}

Eigen::MatrixXd SimulateDense(const DiscreteStateSpace& s, const Eigen::MatrixXd& u, const Eigen::VectorXd& x0) {
  CheckInputs(u, s.Bd.cols());
  Eigen::VectorXd x = InitialState(x0, s.Ad.rows());
  Eigen::VectorXd next(x.size());
  Eigen::MatrixXd y(u.rows(), s.C.rows());
  for (Eigen::Index k = 0; k < u.rows(); ++k) {
    const Eigen::VectorXd uk = u.row(k).transpose();
    y.row(k).noalias() = (s.C * x + s.D * uk).transpose();
    next.noalias() = s.Ad * x;
    next.noalias() += s.Bd * uk;
    x.swap(next);
  }
  return y;
}

Eigen::MatrixXd SimulateRungeKutta4(const model::StateSpace& s, double dt, const Eigen::MatrixXd& u,
                                    const Eigen::VectorXd& x0) {
  CheckSizes(s);
  CheckInputs(u, s.B.cols());
  Eigen::VectorXd x = InitialState(x0, s.A.rows());
  Eigen::MatrixXd y(u.rows(), s.C.rows());
  for (Eigen::Index k = 0; k < u.rows(); ++k) {
    const Eigen::VectorXd uk = u.row(k).transpose();
    y.row(k) = (s.C * x + s.D * uk).transpose();
    const Eigen::VectorXd bu = s.B * uk;
    const Eigen::VectorXd k1 = s.A * x + bu;
    const Eigen::VectorXd k2 = s.A * (x + 0.5 * dt * k1) + bu;
    const Eigen::VectorXd k3 = s.A * (x + 0.5 * dt * k2) + bu;
    const Eigen::VectorXd k4 = s.A * (x + dt * k3) + bu;
    x += dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4);
  }
  return y;
}

ModalIntegrator::ModalIntegrator(const model::StateSpace& system, double time_step_s,
                                 const ModalIntegratorOptions& options)
    : discrete_(DiscretiseZeroOrderHold(system, time_step_s)) {
  const Eigen::Index n = system.A.rows();
  const auto eig = CalcEigenPairs(system.A);
  if (!eig) {
    message_ = "eigen decomposition of A failed; dense recurrence used";
    return;
  }
  const Eigen::VectorXcd& lambda = eig->values;
  const Eigen::MatrixXcd& V = eig->vectors;
  T_.resize(n, n);
  Eigen::MatrixXd Lambda = Eigen::MatrixXd::Zero(n, n);
  phi_ = Eigen::MatrixXd::Zero(2, n);
  const double scale = lambda.cwiseAbs().maxCoeff();
  for (Eigen::Index i = 0; i < n;) {
    const double s = lambda(i).real(), w = lambda(i).imag();
    if (std::abs(w) <= 1e-14 * scale || i + 1 == n) {
      T_.col(i) = V.col(i).real();
      Lambda(i, i) = s;
      phi_(0, i) = std::exp(s * time_step_s);
      block_size_.push_back(1);
      i += 1;
      continue;
    }
    // A conjugate pair: use the member with w > 0 so that the block is [s w; -w s].
    const Eigen::VectorXcd v = w > 0 ? V.col(i) : V.col(i + 1);
    const double wp = std::abs(w);
    T_.col(i) = v.real();
    T_.col(i + 1) = v.imag();
    Lambda(i, i) = s;
    Lambda(i, i + 1) = wp;
    Lambda(i + 1, i) = -wp;
    Lambda(i + 1, i + 1) = s;
    const double decay = std::exp(s * time_step_s);
    phi_(0, i) = decay * std::cos(wp * time_step_s);
    phi_(1, i) = decay * std::sin(wp * time_step_s);
    block_size_.push_back(2);
    i += 2;
  }
  Eigen::PartialPivLU<Eigen::MatrixXd> lu(T_);
  const double rcond = lu.rcond();
  if (!(rcond > options.min_rcond)) {
    std::ostringstream out;
    out << "modal basis ill-conditioned (rcond " << rcond << "); dense recurrence used";
    message_ = out.str();
    return;
  }
  T_inverse_ = lu.inverse();
  const double error = (T_ * Lambda * T_inverse_ - system.A).norm();
  if (!(error <= options.reconstruction_tolerance * system.A.norm())) {
    std::ostringstream out;
    out << "A is not safely diagonalisable (relative reconstruction error " << error / system.A.norm()
        << "); dense recurrence used";
    message_ = out.str();
    return;
  }
  gamma_t_ = (T_inverse_ * discrete_.Bd).transpose();
  c_modal_ = discrete_.C * T_;
  modal_ = true;
}

Eigen::MatrixXd ModalIntegrator::Simulate(const Eigen::MatrixXd& u, const Eigen::VectorXd& x0) const {
  if (!modal_) return SimulateDense(discrete_, u, x0);
  CheckInputs(u, num_inputs());
  const Eigen::Index n = num_states(), ni = num_inputs(), no = num_outputs(), steps = u.rows();
  Eigen::VectorXd xi = T_inverse_ * InitialState(x0, n);
  // Plain loops over contiguous storage: inputs and outputs one sample per column, (C T) and D
  // row-major so that each output is a dot product over contiguous memory.
  const Eigen::MatrixXd u_t = u.transpose();  // ni x N
  Eigen::MatrixXd y_t(no, steps);             // no x N
  const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> c_rows = c_modal_;
  const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> d_rows = discrete_.D;
  const double* phi = phi_.data();
  const double* gamma = gamma_t_.data();
  const double* c = c_rows.data();
  const double* d = d_rows.data();
  double* x = xi.data();
  for (Eigen::Index k = 0; k < steps; ++k) {
    const double* uk = u_t.data() + k * ni;
    double* yk = y_t.data() + k * no;
    for (Eigen::Index o = 0; o < no; ++o) {
      const double* row = c + o * n;
      double sum = 0.0;
      for (Eigen::Index i = 0; i < n; ++i) sum += row[i] * x[i];
      const double* drow = d + o * ni;
      for (Eigen::Index j = 0; j < ni; ++j) sum += drow[j] * uk[j];
      yk[o] = sum;
    }
    Eigen::Index i = 0;
    for (int size : block_size_) {
      const double* g0 = gamma + i * ni;
      double forced0 = 0.0;
      for (Eigen::Index j = 0; j < ni; ++j) forced0 += g0[j] * uk[j];
      if (size == 1) {
        x[i] = phi[2 * i] * x[i] + forced0;
        i += 1;
      } else {
        const double* g1 = g0 + ni;
        double forced1 = 0.0;
        for (Eigen::Index j = 0; j < ni; ++j) forced1 += g1[j] * uk[j];
        const double a = phi[2 * i], b = phi[2 * i + 1];
        const double x0v = x[i], x1v = x[i + 1];
        x[i] = a * x0v + b * x1v + forced0;
        x[i + 1] = a * x1v - b * x0v + forced1;
        i += 2;
      }
    }
  }
  return y_t.transpose();
}

}  // namespace stagefit::simulate
