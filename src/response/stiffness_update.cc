#include "stagefit/response/stiffness_update.h"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <complex>
#include <string>

#include "stagefit/common/error.h"

namespace stagefit::response {

namespace {

using Complex = std::complex<double>;
using Small = Eigen::Matrix<Complex, Eigen::Dynamic, Eigen::Dynamic, 0, StiffnessUpdate::kMaxChanged,
                            StiffnessUpdate::kMaxChanged>;

}  // namespace

StiffnessUpdate StiffnessUpdate::Create(const model::SecondOrderSystem& system, const Eigen::VectorXd& frequency_hz,
                                        ResponseQuantity quantity, const std::vector<int>& coordinates,
                                        const FrfEvaluatorOptions& options) {
  const int n = system.num_dofs();
  StiffnessUpdate u;
  u.position_.assign(n, -1);
  const int nt = static_cast<int>(coordinates.size());
  for (int t = 0; t < nt; ++t) {
    const int c = coordinates[t];
    if (c < 0 || c >= n) {
      throw InputError("stiffness update: coordinate " + std::to_string(c) + " outside the system's " +
                       std::to_string(n) + " coordinates");
    }
    if (u.position_[c] >= 0) throw InputError("stiffness update: coordinate " + std::to_string(c) + " given twice");
    u.position_[c] = t;
  }
  u.nt_ = nt;
  u.no_ = system.num_outputs();
  u.ni_ = system.num_inputs();
  u.power_ = SPower(quantity);
  u.delay_s_ = system.delay_s;
  u.omega_rad_s_ = 2.0 * M_PI * frequency_hz;

  // The system with the coordinates T as further inputs (unit forces) and outputs, as a receptance
  // without delay: its blocks are H0, Cq Z^-1 P_T, P_T' Z^-1 B and G.
  model::SecondOrderSystem augmented = system;
  augmented.delay_s = 0.0;
  augmented.B0.conservativeResize(n, u.ni_ + nt);
  augmented.B2.conservativeResize(n, u.ni_ + nt);
  augmented.Cq.conservativeResize(u.no_ + nt, n);
  augmented.D0.conservativeResize(u.no_ + nt, u.ni_ + nt);
  augmented.B0.rightCols(nt).setZero();
  augmented.B2.rightCols(nt).setZero();
  augmented.Cq.bottomRows(nt).setZero();
  augmented.D0.rightCols(nt).setZero();
  augmented.D0.bottomRows(nt).setZero();
  for (int t = 0; t < nt; ++t) {
    augmented.B0(coordinates[t], u.ni_ + t) = 1.0;
    augmented.Cq(u.no_ + t, coordinates[t]) = 1.0;
    augmented.input_names.push_back("coordinate " + std::to_string(coordinates[t]));
    augmented.output_names.push_back("coordinate " + std::to_string(coordinates[t]));
  }
  FrfEvaluator evaluator = FrfEvaluator::Create(augmented, options);
  const FrfArray frf = evaluator.Evaluate(frequency_hz, ResponseQuantity::kReceptance);
  u.augmented_ = frf.values.transpose();

  const int nf = u.num_frequencies();
  const int na = u.no_ + nt;
  u.values_.resize(nf, u.no_ * u.ni_);
  u.prefactor_.resize(nf);
  for (int f = 0; f < nf; ++f) {
    const Complex pre = std::pow(Complex(0.0, u.omega_rad_s_(f)), u.power_) * std::polar(1.0, -u.omega_rad_s_(f) * u.delay_s_);
    u.prefactor_(f) = pre;
    for (int i = 0; i < u.ni_; ++i) {
      for (int o = 0; o < u.no_; ++o) u.values_(f, o + u.no_ * i) = pre * u.augmented_(o + na * i, f);
    }
  }
  return u;
}

bool StiffnessUpdate::Evaluate(const std::vector<DynamicStiffnessDerivative::Entry>& change, Eigen::MatrixXcd* out) const {
  // The changed coordinates U, in the order first met, with their indices in T.
  std::vector<int> changed;  // system coordinates
  for (const auto& e : change) {
    for (const int c : {e.row, e.col}) {
      if (c < 0 || c >= static_cast<int>(position_.size()) || position_[c] < 0) {
        throw InputError("stiffness update: coordinate " + std::to_string(c) + " is not one the update was set up for");
      }
      if (std::find(changed.begin(), changed.end(), c) == changed.end()) changed.push_back(c);
    }
    if (e.mass != 0.0) throw InputError("stiffness update: a change of mass is not a change of the dynamic stiffness alone");
  }
  const int m = static_cast<int>(changed.size());
  if (m > kMaxChanged) return false;
  *out = values_;
  if (m == 0) return true;
  auto local = [&](int c) { return static_cast<int>(std::find(changed.begin(), changed.end(), c) - changed.begin()); };
  // Each entry's place in D, found once for all frequencies.
  struct Placed {
    int a, b;
    Complex stiffness;
    double damping;
  };
  std::vector<Placed> placed;
  placed.reserve(change.size());
  for (const auto& e : change) placed.push_back({local(e.row), local(e.col), e.stiffness, e.damping});

  const int nf = num_frequencies();
  const int na = no_ + nt_;
  Small D(m, m), G(m, m), A(m, m);
  Eigen::Matrix<Complex, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxChanged, Eigen::Dynamic> X(m, ni_), W(m, ni_);
  Eigen::MatrixXcd Y(no_, m), update(no_, ni_);
  for (int f = 0; f < nf; ++f) {
    const Complex s(0.0, omega_rad_s_(f));
    D.setZero();
    for (const Placed& e : placed) D(e.a, e.b) += e.stiffness + s * e.damping;
    const auto column = augmented_.col(f);
    for (int a = 0; a < m; ++a) {
      const int ta = position_[changed[a]];
      for (int b = 0; b < m; ++b) G(a, b) = column((no_ + ta) + na * (ni_ + position_[changed[b]]));
      for (int i = 0; i < ni_; ++i) X(a, i) = column((no_ + ta) + na * i);
      for (int o = 0; o < no_; ++o) Y(o, a) = column(o + na * (ni_ + ta));
    }
    A = Small::Identity(m, m) + D * G;
    // I + D G singular (the changed system has a pole at this frequency) leaves W, and so `out`, not
    // finite. Partial pivoting suffices for this small matrix; full pivoting had been about 60 % of
    // this function's time, which a diagnosis' scans and probes repeat for hundreds of models.
    if (m == 1) {
      W = (D(0, 0) / A(0, 0)) * X;
    } else {
      W = Eigen::PartialPivLU<Small>(A).solve(D * X);
    }
    update.noalias() = Y * W;
    update *= prefactor_(f);
    for (int i = 0; i < ni_; ++i) {
      for (int o = 0; o < no_; ++o) (*out)(f, o + no_ * i) -= update(o, i);
    }
  }
  return out->allFinite();
}

}  // namespace stagefit::response
