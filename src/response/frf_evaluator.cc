#include "stagefit/response/frf_evaluator.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "stagefit/common/eigen_decomposition.h"
#include "stagefit/common/error.h"
#include "stagefit/common/parallel.h"
#include "stagefit/model/modes.h"

namespace stagefit::response {

bool operator==(const FrfEvaluatorOptions& a, const FrfEvaluatorOptions& b) {
  return a.method == b.method && a.max_condition_number == b.max_condition_number &&
         a.check_tolerance == b.check_tolerance && a.lowest_frequency_hz == b.lowest_frequency_hz &&
         a.block_size == b.block_size;
}

namespace {

using Complex = std::complex<double>;
constexpr Complex kJ(0.0, 1.0);

// Column layout of one block of the modal GEMM (and of the direct path's per-frequency buffer):
// [H: Nout*Nin | Y = Cq Z^-1 E_S: Nout*ns | X = E_S' Z^-1 F: ns*Nin].
struct Layout {
  int no = 0, ni = 0, ns = 0;
  int h() const { return 0; }
  int y() const { return no * ni; }
  int x() const { return no * ni + no * ns; }
  int cols() const { return no * ni + no * ns + ns * ni; }
};

void CheckFrequencies(const Eigen::VectorXd& frequency_hz, double lowest_hz) {
  for (Eigen::Index f = 0; f < frequency_hz.size(); ++f) {
    const double v = frequency_hz(f);
    if (!std::isfinite(v) || v < lowest_hz) {
      std::ostringstream msg;
      msg << "frequency_hz[" << f << "] = " << v << ", expected a finite frequency >= " << lowest_hz << " Hz";
      if (lowest_hz > 0) msg << " (the lowest frequency the evaluator was set up for)";
      throw InputError(msg.str());
    }
  }
}

void PrepareOutput(const model::SecondOrderSystem& sys, const Eigen::VectorXd& frequency_hz,
                   ResponseQuantity quantity, FrfArray* out) {
  out->frequency_hz = frequency_hz;
  out->quantity = quantity;
  out->output_names = sys.output_names;
  out->input_names = sys.input_names;
  out->output_names.resize(sys.num_outputs());
  out->input_names.resize(sys.num_inputs());
  for (int o = 0; o < sys.num_outputs(); ++o) {
    if (out->output_names[o].empty()) out->output_names[o] = "y" + std::to_string(o);
  }
  for (int i = 0; i < sys.num_inputs(); ++i) {
    if (out->input_names[i].empty()) out->input_names[i] = "u" + std::to_string(i);
  }
  out->values.resize(frequency_hz.size(), static_cast<Eigen::Index>(sys.num_outputs()) * sys.num_inputs());
}

// The DoF set S touched by the derivatives, and the position of each DoF in it (-1 if absent).
std::vector<int> SupportOf(const std::vector<DynamicStiffnessDerivative>& derivatives, int n,
                           std::vector<int>* position) {
  position->assign(n, -1);
  std::vector<int> support;
  for (const auto& d : derivatives) {
    for (const auto& e : d.entries) {
      if (e.row < 0 || e.row >= n || e.col < 0 || e.col >= n) {
        std::ostringstream msg;
        msg << "derivative '" << d.name << "': entry (" << e.row << ", " << e.col
            << ") outside the " << n << " generalised coordinates of the system";
        throw InputError(msg.str());
      }
      for (int k : {e.row, e.col}) {
        if ((*position)[k] < 0) {
          (*position)[k] = static_cast<int>(support.size());
          support.push_back(k);
        }
      }
    }
  }
  return support;
}

// dH_q += -s^p e^{-s tau} dZ_q(s)(i, j) Y(:, i) X(j, :) for the block of rows [f0, f0 + nb) of the
// outputs. `block` holds Y and X (complex, nb rows) in the Layout columns. The entries of one column j
// (consecutive, as MakeDynamicStiffnessDerivative orders them) share X(j, :): their terms are summed as
// G = sum_i g_ij Y(:, i) first (`grouped`, nb x Nout), then multiplied by X(j, :) once. A dense
// derivative (a mass over a chain of joints: hundreds of entries) then costs Nout per entry, not
// Nout Nin.
void AccumulateDerivatives(const Eigen::Ref<const Eigen::ArrayXd>& omega, const Eigen::ArrayXcd& prefactor,
                           Eigen::Index f0, const Eigen::MatrixXcd& block, const Layout& layout,
                           const std::vector<int>& position,
                           const std::vector<DynamicStiffnessDerivative>& derivatives,
                           std::vector<Eigen::MatrixXcd>* out, Eigen::ArrayXcd* factor, Eigen::MatrixXcd* grouped) {
  const Eigen::Index nb = omega.size();
  auto g = factor->head(nb);
  // As tall as `block` (the workspace's block size), whatever nb: see BlockWorkspace::Resize.
  if (grouped->rows() != block.rows() || grouped->cols() != layout.no) grouped->resize(block.rows(), layout.no);
  for (size_t q = 0; q < derivatives.size(); ++q) {
    Eigen::MatrixXcd& d = (*out)[q];
    const auto& entries = derivatives[q].entries;
    if (entries.empty()) d.middleRows(f0, nb).setZero();
    bool first = true;
    for (size_t a = 0; a < entries.size();) {
      size_t b = a;
      while (b < entries.size() && entries[b].col == entries[a].col) ++b;
      for (size_t k = a; k < b; ++k) {
        const auto& e = entries[k];
        // g = -s^p e^{-s tau} (stiffness + s damping + s^2 mass), s = j omega.
        g = -prefactor.head(nb) * (e.stiffness + (kJ * e.damping) * omega - e.mass * omega.square());
        const int si = position[e.row];
        for (int o = 0; o < layout.no; ++o) {
          const auto y = block.col(layout.y() + o + layout.no * si).head(nb).array();
          auto sum = grouped->col(o).head(nb).array();
          if (k == a) {
            sum = g * y;
          } else {
            sum += g * y;
          }
        }
      }
      const int sj = position[entries[a].col];
      for (int i = 0; i < layout.ni; ++i) {
        const auto x = block.col(layout.x() + sj + layout.ns * i).head(nb).array();
        for (int o = 0; o < layout.no; ++o) {
          auto target = d.col(o + layout.no * i).segment(f0, nb).array();
          if (first) {
            target = grouped->col(o).head(nb).array() * x;
          } else {
            target += grouped->col(o).head(nb).array() * x;
          }
        }
      }
      first = false;
      a = b;
    }
  }
}

}  // namespace

ResponseQuantity ParseResponseQuantity(const std::string& text, const std::string& context) {
  if (text == "receptance" || text == "compliance") return ResponseQuantity::kReceptance;
  if (text == "mobility") return ResponseQuantity::kMobility;
  if (text == "accelerance") return ResponseQuantity::kAccelerance;
  throw InputError(context + " = '" + text + "', expected accelerance, mobility or receptance");
}

std::string ToString(ResponseQuantity quantity) {
  switch (quantity) {
    case ResponseQuantity::kReceptance: return "receptance";
    case ResponseQuantity::kMobility: return "mobility";
    case ResponseQuantity::kAccelerance: return "accelerance";
  }
  return "receptance";
}

int SPower(ResponseQuantity quantity) {
  switch (quantity) {
    case ResponseQuantity::kReceptance: return 0;
    case ResponseQuantity::kMobility: return 1;
    case ResponseQuantity::kAccelerance: return 2;
  }
  return 0;
}

std::string ToString(FrfMethod method) {
  switch (method) {
    case FrfMethod::kAuto: return "auto";
    case FrfMethod::kModal: return "modal";
    case FrfMethod::kDirect: return "direct";
  }
  return "auto";
}

Eigen::MatrixXcd FrfArray::At(int f) const {
  Eigen::MatrixXcd h(num_outputs(), num_inputs());
  for (int i = 0; i < num_inputs(); ++i) {
    for (int o = 0; o < num_outputs(); ++o) h(o, i) = values(f, o + num_outputs() * i);
  }
  return h;
}

DynamicStiffnessDerivative MakeDynamicStiffnessDerivative(const model::SystemDerivative& derivative,
                                                          const std::string& name) {
  DynamicStiffnessDerivative result;
  result.name = name;
  const Eigen::Index n = derivative.dK.rows();
  auto at = [](const Eigen::MatrixXd& m, Eigen::Index i, Eigen::Index j) {
    return m.size() == 0 ? 0.0 : m(i, j);
  };
  for (Eigen::Index j = 0; j < n; ++j) {
    for (Eigen::Index i = 0; i < n; ++i) {
      DynamicStiffnessDerivative::Entry e;
      e.row = static_cast<int>(i);
      e.col = static_cast<int>(j);
      e.stiffness = Complex(at(derivative.dK, i, j), at(derivative.dK_loss, i, j));
      e.damping = at(derivative.dC, i, j);
      e.mass = at(derivative.dM, i, j);
      if (e.stiffness != 0.0 || e.damping != 0.0 || e.mass != 0.0) result.entries.push_back(e);
    }
  }
  return result;
}

FrfEvaluator FrfEvaluator::Create(const model::SecondOrderSystem& system, const FrfEvaluatorOptions& options) {
  const int n = system.num_dofs();
  const int ni = system.num_inputs(), no = system.num_outputs();
  auto check = [&](const Eigen::MatrixXd& m, int rows, int cols, const char* what) {
    if (m.rows() != rows || m.cols() != cols) {
      std::ostringstream msg;
      msg << "second-order system: " << what << " is " << m.rows() << " x " << m.cols() << ", expected "
          << rows << " x " << cols;
      throw InputError(msg.str());
    }
  };
  check(system.C, n, n, "C");
  check(system.K, n, n, "K");
  check(system.K_loss, n, n, "K_loss");
  check(system.B2, n, ni, "B2");
  check(system.Cq, no, n, "Cq");
  check(system.D0, no, ni, "D0");
  if (n == 0) throw InputError("second-order system: no generalised coordinates");
  if (options.block_size < 1) throw InputError("FrfEvaluatorOptions.block_size must be >= 1");
  if (!(options.lowest_frequency_hz >= 0.0) || !std::isfinite(options.lowest_frequency_hz)) {
    std::ostringstream msg;
    msg << "FrfEvaluatorOptions.lowest_frequency_hz = " << options.lowest_frequency_hz
        << ", expected a finite frequency >= 0 Hz";
    throw InputError(msg.str());
  }

  FrfEvaluator ev;
  ev.system_ = system;
  ev.options_ = options;
  Eigen::LLT<Eigen::MatrixXd> llt(system.M);
  if (llt.info() != Eigen::Success) throw NumericalError("FRF set-up: the mass matrix is not positive definite");

  if (options.method == FrfMethod::kDirect) {
    ev.summary_.path = FrfMethod::kDirect;
    ev.summary_.message = "direct solve per frequency (requested)";
    return ev;
  }
  ev.SetUpModal(options.method == FrfMethod::kModal);
  return ev;
}

void FrfEvaluator::SetUpModal(bool forced) {
  const model::SecondOrderSystem& sys = system_;
  const int n = sys.num_dofs();
  auto fall_back = [&](const std::string& why) {
    if (forced) throw NumericalError("FRF set-up: the modal path was requested but " + why);
    summary_.path = FrfMethod::kDirect;
    summary_.real_arithmetic = false;
    summary_.message = "direct solve per frequency: " + why;
  };

  // Undamped normal modes of the symmetric part of K (any invertible M-orthonormal basis is exact).
  const Eigen::MatrixXd K_sym = 0.5 * (sys.K + sys.K.transpose());
  const auto normal = CalcGeneralizedSymmetricEigenPairs(K_sym, sys.M);
  if (!normal) return fall_back("the normal-mode eigenproblem failed");
  phi_ = normal->vectors;
  const double omega2_max = std::max(normal->values.maxCoeff(), 0.0);
  const double floor2 = omega2_max > 0 ? 1e-12 * omega2_max : 1.0;
  Eigen::VectorXd scale = normal->values.cwiseMax(floor2).cwiseSqrt();  // D = diag(scale)
  const bool real = sys.K_loss.isZero(0.0);

  const Eigen::MatrixXcd Kt = (phi_.transpose() * sys.K * phi_).cast<Complex>() +
                              kJ * (phi_.transpose() * sys.K_loss * phi_).cast<Complex>();
  const Eigen::MatrixXd Ct = phi_.transpose() * sys.C * phi_;
  Eigen::MatrixXcd A = Eigen::MatrixXcd::Zero(2 * n, 2 * n);
  A.topRightCorner(n, n) = scale.cast<Complex>().asDiagonal();
  A.bottomLeftCorner(n, n) = Kt * scale.cwiseInverse().cast<Complex>().asDiagonal();
  A.bottomRightCorner(n, n) = -Ct.cast<Complex>();
  A.bottomLeftCorner(n, n) *= -1.0;

  auto eig = CalcEigenPairs(A);  // the real solver when there is no loss (exact conjugate pairs)
  if (!eig) return fall_back("the eigen-decomposition of the first-order matrix failed");
  poles_ = eig->values;
  Eigen::MatrixXcd V = std::move(eig->vectors);
  for (int k = 0; k < 2 * n; ++k) V.col(k).normalize();
  Eigen::PartialPivLU<Eigen::MatrixXcd> lu(V);
  Eigen::MatrixXcd unit = Eigen::MatrixXcd::Zero(2 * n, n);
  unit.bottomRows(n).setIdentity();
  const Eigen::MatrixXcd Wr = lu.solve(unit);  // the right n columns of V^-1
  const double cond = 1.0 / lu.rcond();         // estimate of cond_1(V)
  summary_.condition_number = cond;
  summary_.num_poles = 2 * n;
  if (!std::isfinite(cond) || !poles_.allFinite() || !Wr.allFinite()) {
    return fall_back("the eigenvector matrix is singular (defective, repeated poles)");
  }

  // Conjugate pairs on the real path: each pole with Im > 0 must have its conjugate in the list.
  pair_index_.clear();
  num_pairs_ = 0;
  bool paired = real;
  if (real) {
    std::vector<int> real_poles;
    const double tol = 1e-10 * std::max(1.0, poles_.cwiseAbs().maxCoeff());
    int num_conjugates = 0;
    for (int k = 0; k < 2 * n; ++k) {
      const Complex p = poles_(k);
      if (p.imag() == 0.0) {
        real_poles.push_back(k);
      } else if (p.imag() > 0) {
        pair_index_.push_back(k);
      } else {
        ++num_conjugates;
        bool found = false;
        for (int l = 0; l < 2 * n && !found; ++l) found = std::abs(poles_(l) - std::conj(p)) <= tol;
        paired = paired && found;
      }
    }
    num_pairs_ = static_cast<int>(pair_index_.size());
    paired = paired && num_conjugates == num_pairs_;
    pair_index_.insert(pair_index_.end(), real_poles.begin(), real_poles.end());
  }
  summary_.real_arithmetic = paired;

  // Factors (see the header): Z^-1 = Phi D^-1 V_top diag(1/(s - lambda)) W_r Phi', s Z^-1 uses V_bot.
  const Eigen::MatrixXcd phi_c = phi_.cast<Complex>();
  dof_pos_ = phi_c * scale.cwiseInverse().cast<Complex>().asDiagonal() * V.topRows(n);
  dof_vel_ = phi_c * V.bottomRows(n);
  out_pos_ = sys.Cq.cast<Complex>() * dof_pos_;
  out_vel_ = sys.Cq.cast<Complex>() * dof_vel_;
  const Eigen::MatrixXd Gt = phi_.transpose() * sys.B2;
  const Eigen::MatrixXcd b1 = (phi_.transpose() * sys.B0).cast<Complex>() - Kt * Gt.cast<Complex>();
  const Eigen::MatrixXcd b2 = (Ct * Gt).cast<Complex>();
  in_b1_ = Wr * b1;
  in_b2_ = Wr * b2;
  dof_in_ = Wr * phi_c.transpose();
  dof_direct_d_ = phi_ * Gt;
  direct_d_ = sys.Cq * dof_direct_d_ + sys.D0;
  const Eigen::MatrixXcd Cq_phi = (sys.Cq * phi_).cast<Complex>();
  direct_e1_ = -Cq_phi * b2;
  direct_e2_ = Cq_phi * (b1 + Ct.cast<Complex>() * b2);

  summary_.path = FrfMethod::kModal;
  std::ostringstream why;
  if (!forced && cond > options_.max_condition_number) {
    why << "eigenvector condition number " << cond << " > " << options_.max_condition_number;
    return fall_back(why.str());
  }
  if (!forced && options_.check_tolerance > 0) {
    summary_.check_error = ProbeError();
    if (!(summary_.check_error <= options_.check_tolerance)) {
      why << "modal and direct results differ by " << summary_.check_error << " (relative) at a probe frequency";
      return fall_back(why.str());
    }
  }
  std::ostringstream msg;
  msg << "modal (" << (summary_.real_arithmetic ? "real" : "complex") << " arithmetic, " << 2 * n
      << " poles, eigenvector condition " << cond << ")";
  summary_.message = msg.str();
}

double FrfEvaluator::ProbeError() {
  // Probes away from the resonances (where Z itself is ill-conditioned and the direct reference
  // loses digits): 0 Hz when no pole is near 0, the geometric means of neighbouring pole magnitudes at
  // the bottom, middle and top of the spectrum, and twice the highest pole magnitude.
  std::vector<double> magnitudes;
  for (Eigen::Index k = 0; k < poles_.size(); ++k) magnitudes.push_back(std::abs(poles_(k)));
  std::sort(magnitudes.begin(), magnitudes.end());
  const double top = magnitudes.back();
  magnitudes.erase(std::unique(magnitudes.begin(), magnitudes.end(),
                               [top](double a, double b) { return b - a <= 1e-3 * top; }),
                   magnitudes.end());
  std::vector<double> omegas;
  if (magnitudes.front() > 1e-6 * top) omegas.push_back(0.0);
  const size_t m = magnitudes.size();
  for (size_t k : {size_t{0}, m / 2, m >= 2 ? m - 2 : size_t{0}}) {
    if (k + 1 < m) omegas.push_back(std::sqrt(magnitudes[k] * magnitudes[k + 1]));
  }
  omegas.push_back(2.0 * top);
  const double lowest = 2.0 * M_PI * options_.lowest_frequency_hz;
  if (lowest > 0.0) {  // only where the caller will evaluate
    omegas.erase(std::remove_if(omegas.begin(), omegas.end(), [lowest](double w) { return w < lowest; }),
                 omegas.end());
    omegas.insert(omegas.begin(), lowest);
  }
  const Eigen::VectorXd omega =
      Eigen::Map<Eigen::VectorXd>(omegas.data(), static_cast<Eigen::Index>(omegas.size()));
  // Deviations are measured against the largest response to the same input over the probes (one
  // unit per input column). Elements that vanish by symmetry are exact zeros in the direct solve and
  // rounding noise (~1e-16 of that peak) in the modal sum, so a per-element measure would flag them.
  FrfArray modal, direct;
  double worst = 0.0;
  const int no = system_.num_outputs();
  EvaluateDirect(omega, 0, nullptr, &direct, nullptr);
  for (int power : {0, 2}) {
    EvaluateModal(omega, power, nullptr, &modal, nullptr);
    if (power == 2) {
      for (Eigen::Index f = 0; f < omega.size(); ++f) direct.values.row(f) *= -omega(f) * omega(f);
    }
    for (int i = 0; i < system_.num_inputs(); ++i) {
      const double input_peak = direct.values.middleCols(no * i, no).cwiseAbs().maxCoeff();
      if (input_peak == 0.0) continue;
      const double diff =
          (modal.values.middleCols(no * i, no) - direct.values.middleCols(no * i, no)).cwiseAbs().maxCoeff();
      worst = std::max(worst, std::isfinite(diff) ? diff / input_peak : std::numeric_limits<double>::infinity());
    }
  }
  return worst;
}

FrfArray FrfEvaluator::Evaluate(const Eigen::VectorXd& frequency_hz, ResponseQuantity quantity) {
  FrfArray out;
  Evaluate(frequency_hz, quantity, &out);
  return out;
}

void FrfEvaluator::Evaluate(const Eigen::VectorXd& frequency_hz, ResponseQuantity quantity, FrfArray* out) {
  CheckFrequencies(frequency_hz, options_.lowest_frequency_hz);
  PrepareOutput(system_, frequency_hz, quantity, out);
  const Eigen::VectorXd omega = 2.0 * M_PI * frequency_hz;
  if (summary_.path == FrfMethod::kModal) {
    EvaluateModal(omega, SPower(quantity), nullptr, out, nullptr);
  } else {
    EvaluateDirect(omega, SPower(quantity), nullptr, out, nullptr);
  }
}

FrfWithDerivatives FrfEvaluator::EvaluateWithDerivatives(const Eigen::VectorXd& frequency_hz,
                                                         ResponseQuantity quantity,
                                                         const std::vector<model::ParameterInfo>& parameters,
                                                         const model::AssembledModel& model) {
  FrfWithDerivatives out;
  EvaluateWithDerivatives(frequency_hz, quantity, parameters, model, &out);
  return out;
}

void FrfEvaluator::EvaluateWithDerivatives(const Eigen::VectorXd& frequency_hz, ResponseQuantity quantity,
                                           const std::vector<model::ParameterInfo>& parameters,
                                           const model::AssembledModel& model, FrfWithDerivatives* out) {
  if (model.num_dofs() != system_.num_dofs() ||
      (!system_.dof_names.empty() && model.dof_names() != system_.dof_names)) {
    std::ostringstream msg;
    msg << "FRF derivatives: the assembled model has " << model.num_dofs()
        << " generalised coordinates that differ from the system's " << system_.num_dofs()
        << "; build the system from the same model";
    throw InputError(msg.str());
  }
  std::vector<DynamicStiffnessDerivative> derivatives;
  derivatives.reserve(parameters.size());
  for (const auto& p : parameters) {
    derivatives.push_back(MakeDynamicStiffnessDerivative(model::CalcSystemDerivative(model, p), p.name));
  }
  EvaluateWithDerivatives(frequency_hz, quantity, derivatives, out);
}

void FrfEvaluator::EvaluateWithDerivatives(const Eigen::VectorXd& frequency_hz, ResponseQuantity quantity,
                                           const std::vector<DynamicStiffnessDerivative>& derivatives,
                                           FrfWithDerivatives* out) {
  CheckFrequencies(frequency_hz, options_.lowest_frequency_hz);
  PrepareOutput(system_, frequency_hz, quantity, &out->frf);
  out->parameter_names.clear();
  for (const auto& d : derivatives) out->parameter_names.push_back(d.name);
  out->derivatives.resize(derivatives.size());
  for (auto& d : out->derivatives) d.resize(frequency_hz.size(), out->frf.values.cols());
  const Eigen::VectorXd omega = 2.0 * M_PI * frequency_hz;
  if (summary_.path == FrfMethod::kModal) {
    EvaluateModal(omega, SPower(quantity), &derivatives, &out->frf, &out->derivatives);
  } else {
    EvaluateDirect(omega, SPower(quantity), &derivatives, &out->frf, &out->derivatives);
  }
}

void FrfEvaluator::EvaluateModal(const Eigen::VectorXd& omega_rad_s, int power,
                                 const std::vector<DynamicStiffnessDerivative>* derivatives, FrfArray* frf,
                                 std::vector<Eigen::MatrixXcd>* d_values) {
  const model::SecondOrderSystem& sys = system_;
  const int n = sys.num_dofs();
  const Eigen::Index nf = omega_rad_s.size();
  Layout layout;
  layout.no = sys.num_outputs();
  layout.ni = sys.num_inputs();
  std::vector<int> position;
  std::vector<int> support;
  if (derivatives) support = SupportOf(*derivatives, n, &position);
  layout.ns = static_cast<int>(support.size());
  const int cols = layout.cols();
  if (frf->values.rows() != nf || frf->values.cols() != layout.no * layout.ni) {
    frf->values.resize(nf, layout.no * layout.ni);
  }

  // Residues (one row per pole) for this quantity and DoF set.
  const bool real = summary_.real_arithmetic;
  const int num_used = real ? static_cast<int>(pair_index_.size()) : 2 * n;
  residue_.resize(num_used, cols);
  for (int r = 0; r < num_used; ++r) {
    const int k = real ? pair_index_[r] : r;
    const Complex lp = std::pow(poles_(k), power);
    for (int i = 0; i < layout.ni; ++i) {
      for (int o = 0; o < layout.no; ++o) {
        residue_(r, o + layout.no * i) = lp * (out_pos_(o, k) * in_b1_(k, i) - out_vel_(o, k) * in_b2_(k, i));
      }
    }
    for (int s = 0; s < layout.ns; ++s) {
      for (int o = 0; o < layout.no; ++o) {
        residue_(r, layout.y() + o + layout.no * s) = out_pos_(o, k) * dof_in_(k, support[s]);
      }
      for (int i = 0; i < layout.ni; ++i) {
        const int d = support[s];
        residue_(r, layout.x() + s + layout.ns * i) = dof_pos_(d, k) * in_b1_(k, i) - dof_vel_(d, k) * in_b2_(k, i);
      }
    }
  }
  if (real) {
    // Pair rows become two real rows (Re R, Im R); a real pole's row is real.
    const int m = 2 * num_pairs_ + (num_used - num_pairs_);
    residue_real_.resize(m, cols);
    for (int r = 0; r < num_pairs_; ++r) {
      residue_real_.row(2 * r) = residue_.row(r).real();
      residue_real_.row(2 * r + 1) = residue_.row(r).imag();
    }
    for (int r = num_pairs_; r < num_used; ++r) residue_real_.row(num_pairs_ + r) = residue_.row(r).real();
  }

  const Eigen::Index block = std::min<Eigen::Index>(options_.block_size, std::max<Eigen::Index>(nf, 1));
  const int num_blocks = static_cast<int>((nf + block - 1) / block);
  const Eigen::Index real_rows = real ? residue_real_.rows() : 0;
  ParallelFor(num_blocks, [&](int task, int) {
    // Each thread keeps its block workspace from call to call, one for FRFs and one for FRFs with
    // derivatives (their sizes differ): a fit evaluates thousands of times, and fresh megabytes per
    // evaluation cost page faults, on a pool or diagnose thread also the return of its arena's memory.
    thread_local BlockWorkspace workspace[2];
    BlockWorkspace& ws = workspace[derivatives != nullptr ? 1 : 0];
    ws.Resize(block, cols, real, real_rows, num_used);
    const Eigen::Index f0 = task * block;
    EvaluateModalBlock(omega_rad_s, f0, std::min(block, nf - f0), power, derivatives, support, position, frf,
                       d_values, &ws);
  });
}

void FrfEvaluator::BlockWorkspace::Resize(Eigen::Index block_size, int cols, bool real, Eigen::Index num_real_rows,
                                          int num_complex) {
  // Exact sizes, set by the call alone (the block size and the layout), never by what the thread
  // computed before. Where a column starts depends on the matrix's height, and a vectorised loop
  // over a column that does not start on a vector boundary takes its leading elements apart, and they
  // round differently (FrfEvaluator.ResultsDoNotDependOnWhatTheThreadComputedBefore fails with
  // workspaces that only grow). A workspace grown by an earlier call would make a block's numbers
  // depend on the thread that computes it, and a fit's result on the thread count and the machine's
  // load. Within a fit the sizes repeat from call to call, so nothing is reallocated.
  auto shape = [](auto& m, Eigen::Index rows, Eigen::Index columns) {
    if (m.rows() != rows || m.cols() != columns) m.resize(rows, columns);
  };
  auto length = [](auto& a, Eigen::Index n) {
    if (a.size() != n) a.resize(n);
  };
  shape(block, block_size, cols);
  length(prefactor, block_size);
  length(factor, block_size);
  length(scratch1, block_size);
  length(scratch2, block_size);
  length(scratch3, block_size);
  if (real) {
    shape(coef_real, 2 * block_size, num_real_rows);
    shape(block_real, 2 * block_size, cols);
  } else {
    shape(coef_complex, block_size, num_complex);
  }
}

// One block of frequencies [f0, f0 + nb): writes those rows of frf and d_values only, and its own workspace.
void FrfEvaluator::EvaluateModalBlock(const Eigen::VectorXd& omega_rad_s, Eigen::Index f0, Eigen::Index nb,
                                      int power, const std::vector<DynamicStiffnessDerivative>* derivatives,
                                      const std::vector<int>& support, const std::vector<int>& position,
                                      FrfArray* frf, std::vector<Eigen::MatrixXcd>* d_values,
                                      BlockWorkspace* ws) const {
  const model::SecondOrderSystem& sys = system_;
  Layout layout;
  layout.no = sys.num_outputs();
  layout.ni = sys.num_inputs();
  layout.ns = static_cast<int>(support.size());
  const int cols = layout.cols();
  const bool real = summary_.real_arithmetic;
  const int num_used = real ? static_cast<int>(pair_index_.size()) : 2 * sys.num_dofs();
  const double tau = sys.delay_s;
  const auto w = omega_rad_s.segment(f0, nb).array();
  if (real) {
    // c = 1/(j w - lambda), c' = 1/(j w - conj(lambda)), lambda = a + j b:
    // alpha = c + c', beta = j (c - c'); rows [0, nb) real parts, [nb, 2 nb) imaginary parts.
    for (int r = 0; r < num_pairs_; ++r) {
      const Complex p = poles_(pair_index_[r]);
      const double a = p.real(), b = p.imag();
      auto re_a = ws->coef_real.col(2 * r).head(nb).array();
      auto re_b = ws->coef_real.col(2 * r + 1).head(nb).array();
      auto im_a = ws->coef_real.col(2 * r).segment(nb, nb).array();
      auto im_b = ws->coef_real.col(2 * r + 1).segment(nb, nb).array();
      auto inv1 = ws->scratch1.head(nb);
      auto inv2 = ws->scratch2.head(nb);
      // One division for both: 1/den1 = den2 / (den1 den2) and vice versa.
      auto r_both = ws->scratch3.head(nb);
      inv1 = a * a + (w - b).square();
      inv2 = a * a + (w + b).square();
      r_both = (inv1 * inv2).inverse();
      inv1 = inv2 * r_both;
      inv2 = (a * a + (w - b).square()) * r_both;
      re_a = -a * (inv1 + inv2);
      re_b = (w - b) * inv1 - (w + b) * inv2;
      im_a = -(w - b) * inv1 - (w + b) * inv2;
      im_b = a * (inv2 - inv1);
    }
    for (int r = num_pairs_; r < num_used; ++r) {
      const double a = poles_(pair_index_[r]).real();
      const int c = num_pairs_ + r;
      auto re = ws->coef_real.col(c).head(nb).array();
      auto im = ws->coef_real.col(c).segment(nb, nb).array();
      im = (a * a + w.square()).inverse();
      re = -a * im;
      im = -w * im;
    }
    ws->block_real.topRows(2 * nb).noalias() = ws->coef_real.topRows(2 * nb) * residue_real_;
    for (int c = layout.y(); c < cols; ++c) {
      ws->block.col(c).head(nb).real() = ws->block_real.col(c).head(nb);
      ws->block.col(c).head(nb).imag() = ws->block_real.col(c).segment(nb, nb);
    }
  } else {
    for (int r = 0; r < num_used; ++r) {
      const double a = poles_(r).real(), b = poles_(r).imag();
      auto inv = ws->scratch1.head(nb);
      inv = (a * a + (w - b).square()).inverse();
      ws->coef_complex.col(r).head(nb).real() = -a * inv;
      ws->coef_complex.col(r).head(nb).imag() = -(w - b) * inv;
    }
    ws->block.topRows(nb).noalias() = ws->coef_complex.topRows(nb) * residue_;
  }

  // H = e^{-s tau} (modal sum + E_p(s)).
  auto pre = ws->prefactor.head(nb);
  if (tau != 0.0) {
    pre = (Complex(0.0, -tau) * w.cast<Complex>()).exp();
  } else {
    pre.setConstant(1.0);
  }
  for (int i = 0; i < layout.ni; ++i) {
    for (int o = 0; o < layout.no; ++o) {
      const int c = o + layout.no * i;
      auto h = frf->values.col(c).segment(f0, nb);
      if (real) {
        h.real() = ws->block_real.col(c).head(nb);
        h.imag() = ws->block_real.col(c).segment(nb, nb);
      } else {
        h = ws->block.col(c).head(nb);
      }
      auto ha = h.array();
      const double d = direct_d_(o, i);
      switch (power) {
        case 0:
          ha += d;
          break;
        case 1:
          ha += direct_e1_(o, i) + (kJ * d) * w;
          break;
        default:
          ha += direct_e2_(o, i) + (kJ * direct_e1_(o, i)) * w - d * w.square();
          break;
      }
      if (tau != 0.0) ha *= pre;
    }
  }
  if (derivatives) {
    for (int i = 0; i < layout.ni; ++i) {
      for (int s = 0; s < layout.ns; ++s) {
        ws->block.col(layout.x() + s + layout.ns * i).head(nb).array() += dof_direct_d_(support[s], i);
      }
    }
    if (power == 1) pre *= kJ * w;
    if (power == 2) pre *= -w.square();
    AccumulateDerivatives(w, ws->prefactor, f0, ws->block, layout, position, *derivatives, d_values,
                          &ws->factor, &ws->grouped);
  }
}

void FrfEvaluator::EvaluateDirect(const Eigen::VectorXd& omega_rad_s, int power,
                                 const std::vector<DynamicStiffnessDerivative>* derivatives, FrfArray* frf,
                                 std::vector<Eigen::MatrixXcd>* d_values) {
  const model::SecondOrderSystem& sys = system_;
  const int n = sys.num_dofs();
  const Eigen::Index nf = omega_rad_s.size();
  Layout layout;
  layout.no = sys.num_outputs();
  layout.ni = sys.num_inputs();
  std::vector<int> position;
  std::vector<int> support;
  if (derivatives) support = SupportOf(*derivatives, n, &position);
  layout.ns = static_cast<int>(support.size());
  if (frf->values.rows() != nf || frf->values.cols() != layout.no * layout.ni) {
    frf->values.resize(nf, layout.no * layout.ni);
  }
  const Eigen::Index block = std::min<Eigen::Index>(options_.block_size, std::max<Eigen::Index>(nf, 1));
  BlockWorkspace& ws = direct_workspace_;
  ws.block.resize(block, layout.cols());
  ws.prefactor.resize(block);
  ws.factor.resize(block);
  Eigen::MatrixXcd Z(n, n), F(n, layout.ni), X(n, layout.ni), H(layout.no, layout.ni), Y(n, layout.no);
  const Eigen::MatrixXcd CqT = sys.Cq.transpose().cast<Complex>();
  Eigen::PartialPivLU<Eigen::MatrixXcd> lu(n);
  const double tau = sys.delay_s;

  for (Eigen::Index f0 = 0; f0 < nf; f0 += block) {
    const Eigen::Index nb = std::min(block, nf - f0);
    const auto w = omega_rad_s.segment(f0, nb).array();
    auto pre = ws.prefactor.head(nb);
    pre = (Complex(0.0, -tau) * w.cast<Complex>()).exp();
    if (power == 1) pre *= kJ * w;
    if (power == 2) pre *= -w.square();
    for (Eigen::Index f = 0; f < nb; ++f) {
      const double wf = w(f);
      Z.real() = sys.K - wf * wf * sys.M;
      Z.imag() = sys.K_loss + wf * sys.C;
      lu.compute(Z);
      F.real() = sys.B0 - wf * wf * sys.B2;
      F.imag().setZero();
      X.noalias() = lu.solve(F);
      H.noalias() = sys.Cq.cast<Complex>() * X;
      H += sys.D0.cast<Complex>();
      const Complex scale = pre(f);
      for (int i = 0; i < layout.ni; ++i) {
        for (int o = 0; o < layout.no; ++o) frf->values(f0 + f, o + layout.no * i) = scale * H(o, i);
      }
      if (derivatives) {
        Y.noalias() = lu.transpose().solve(CqT);  // (Cq Z^-1)'
        for (int s = 0; s < layout.ns; ++s) {
          for (int o = 0; o < layout.no; ++o) ws.block(f, layout.y() + o + layout.no * s) = Y(support[s], o);
          for (int i = 0; i < layout.ni; ++i) ws.block(f, layout.x() + s + layout.ns * i) = X(support[s], i);
        }
      }
    }
    if (derivatives) {
      AccumulateDerivatives(w, ws.prefactor, f0, ws.block, layout, position, *derivatives, d_values,
                            &ws.factor, &ws.grouped);
    }
  }
}

}  // namespace stagefit::response
