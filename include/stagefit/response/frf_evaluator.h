#pragma once
// Frequency responses of a model::SecondOrderSystem, exact, with analytic parameter derivatives.
//
// The system (model/linear_system.h)
//     M z'' + C z' + (K + j K_loss) z = B0 u + B2 u'',      y = Cq z + D0 u,      delay tau
// has at s = j omega (omega >= 0, rad/s) the displacement response (receptance)
//     H0(s) = Cq Z(s)^-1 (B0 + s^2 B2) + D0,      Z(s) = M s^2 + C s + K + j K_loss,
// and the response of quantity p (0 receptance, 1 mobility, 2 accelerance)
//     H(s) = s^p e^{-s tau} H0(s)                  (m/N, m/s/N, m/s^2/N; rad for rotations).
//
// Two evaluation paths, with the same results to rounding:
//  - kDirect: per frequency, an LU factorisation of the complex n x n dynamic stiffness Z(j omega)
//    and a solve for the inputs. Always applicable; O(n^3) per frequency.
//  - kModal: one eigen-decomposition at set-up, then one GEMM for all frequencies (O(n Nout Nin) per
//    frequency). The coordinates are first transformed to the undamped normal modes (Phi' M Phi = I,
//    Phi' K Phi = Omega^2) and the state is scaled as x = [Omega eta; eta'], so that the first-order
//    matrix A = [0 Omega; -(Omega^2 + j Phi' K_loss Phi) Omega^-1, -Phi' C Phi] is close to normal for
//    light damping: its eigenvector matrix V is well conditioned (cond(V) ~ 1 for the micro-station
//    against ~1e4..1e8 for the unscaled [z; z'] state). The B2 (ground) term is removed exactly with
//    s^2 Z^-1 = Phi Phi' - Z^-1 (C s + K + j K_loss) Phi Phi' (mass-normalised modes), so
//        s^p H0(s) = E_p(s) + sum_k lambda_k^p R_k / (s - lambda_k),
//    with residues R_k (Nout x Nin) from V and V^-1 and an exact polynomial direct term E_p
//    (E_0 = D, E_1 = s D + sum_k R_k, E_2 = s^2 D + s sum_k R_k + sum_k lambda_k R_k, the sums
//    evaluated in closed form, D = Cq Phi Phi' B2 + D0). Without K_loss the system is real: the poles
//    come in conjugate pairs and each pair contributes (c_k + c'_k) Re R_k + j (c_k - c'_k) Im R_k with
//    c_k = 1 / (s - lambda_k), c'_k = 1 / (s - conj(lambda_k)), so all frequencies take one REAL GEMM of
//    (2 Nf x 2 npairs) by (2 npairs x Nout Nin); with K_loss != 0 A is complex and one complex GEMM of
//    (Nf x 2n) by (2n x Nout Nin) is used. Frequencies are processed in blocks that stay in cache.
//  - kAuto (default) chooses kModal unless the set-up finds it ill-conditioned: the eigen-solver fails,
//    cond_1(V) > max_condition_number (this also catches nearly repeated, defective poles),
//    or the modal result differs from a direct solve by more than check_tolerance at a few probe
//    frequencies (0 Hz or the lowest one the caller will evaluate, between neighbouring poles above
//    it, above the highest pole). Then kDirect is used and
//    setup_summary() says why.
//
// Derivatives with respect to model parameters (model/parameters.h):
//     dH/dp = -s^p e^{-s tau} (Cq Z^-1) dZ_p (Z^-1 (B0 + s^2 B2)),
//     dZ_p(s) = dK_p + j dK_loss_p + s dC_p + s^2 dM_p.
// For joint parameters dZ_p has one (DoF parameter) or two (coupling) non-zero entries in the
// generalised coordinates z (dK = e_i e_i'), so dH/dp = -g(s) Y(:, i) X(j, :) summed over the non-zero
// entries (i, j) of dZ_p, with Y = Cq Z^-1 (Nout x |S|) and X = Z^-1 (B0 + s^2 B2) (|S| x Nin) computed
// once per frequency for the DoF set S touched by any parameter. On the modal path Y and X are modal
// sums evaluated in the same GEMM as H; on the direct path they come from the same LU.
// dB2/dp is not included: the parameters of model/parameters.h do not change masses (dM = 0).
//
// Thread safety: an FrfEvaluator owns its workspace; use one evaluator per thread.

#include <Eigen/Core>

#include <complex>
#include <string>
#include <vector>

#include "stagefit/model/assembled_model.h"
#include "stagefit/model/linear_system.h"
#include "stagefit/model/parameters.h"

namespace stagefit::response {

/// The kind of response: displacement (receptance/compliance), velocity or acceleration per input.
enum class ResponseQuantity {
  kReceptance,   ///< m/N (rad/Nm): s^0 H0
  kMobility,     ///< m/s/N: s^1 H0
  kAccelerance,  ///< m/s^2/N: s^2 H0
};

/// "receptance" (also "compliance"), "mobility", "accelerance". Throws InputError otherwise, naming
/// `context` (e.g. "--quantity").
ResponseQuantity ParseResponseQuantity(const std::string& text, const std::string& context);
std::string ToString(ResponseQuantity quantity);
/// The power p of s in s^p H0: 0, 1, 2.
int SPower(ResponseQuantity quantity);

/// How the responses are (to be) computed.
enum class FrfMethod { kAuto, kModal, kDirect };
std::string ToString(FrfMethod method);

struct FrfEvaluatorOptions {
  FrfMethod method = FrfMethod::kAuto;
  /// kAuto falls back to kDirect above this 1-norm condition number of the (column-normalised)
  /// eigenvector matrix. Rounding in the modal sum grows like eps * cond(V): 1e6 keeps it near 1e-10.
  double max_condition_number = 1e6;
  /// kAuto falls back to kDirect when the modal result at the probe frequencies (0 Hz, between
  /// neighbouring poles, twice the highest pole) differs from a direct solve by more than this,
  /// relative to the largest response to the same input there. 0 skips the probe.
  double check_tolerance = 1e-10;
  /// The lowest frequency (Hz) the caller will evaluate; Evaluate() rejects lower ones. The probe
  /// check then looks at and above it only: a near-zero pole (a stiffness probed at 1e-6 of its
  /// value, say) leaves the modal sum's rounding at 1e-8 near 0 Hz, falling as 1/f to 1e-11 at 5 Hz
  /// (docs/response.md); 0 probes from 0 Hz up.
  double lowest_frequency_hz = 0.0;
  /// Frequencies per block of the modal GEMM (keeps the block's buffers in the L2 cache).
  int block_size = 256;
};
/// Every field equal (a set-up made with one set of options serves the other).
bool operator==(const FrfEvaluatorOptions& a, const FrfEvaluatorOptions& b);

/// What Create() found and chose.
struct FrfSetupSummary {
  FrfMethod path = FrfMethod::kDirect;   ///< kModal or kDirect, never kAuto
  bool real_arithmetic = false;          ///< modal path with conjugate pole pairs (no K_loss)
  int num_poles = 0;                     ///< 2n on the modal path
  double condition_number = 0.0;         ///< cond_1(V) of the scaled first-order form (modal set-up)
  double check_error = 0.0;              ///< largest probe deviation modal vs direct (relative)
  std::string message;                   ///< one line: the path and why
};

/// FRFs at Nf frequencies: element (f, o, i) at values(f, o + num_outputs * i) (column-major H).
struct FrfArray {
  Eigen::VectorXd frequency_hz;          ///< Nf, Hz
  ResponseQuantity quantity = ResponseQuantity::kReceptance;
  std::vector<std::string> output_names, input_names;
  Eigen::MatrixXcd values;               ///< Nf x (Nout * Nin)

  int num_frequencies() const { return static_cast<int>(frequency_hz.size()); }
  int num_outputs() const { return static_cast<int>(output_names.size()); }
  int num_inputs() const { return static_cast<int>(input_names.size()); }
  std::complex<double> operator()(int f, int o, int i) const { return values(f, o + num_outputs() * i); }
  /// H at frequency index f as an Nout x Nin matrix.
  Eigen::MatrixXcd At(int f) const;
};

/// FRFs and their derivatives with respect to parameters, same layout as FrfArray::values:
/// d(H(f, o, i))/dp_k = derivatives[k](f, o + Nout * i), in (unit of H) / (unit of p_k).
struct FrfWithDerivatives {
  FrfArray frf;
  std::vector<std::string> parameter_names;
  std::vector<Eigen::MatrixXcd> derivatives;  ///< one Nf x (Nout * Nin) matrix per parameter
};

/// The derivative of the dynamic stiffness with respect to one parameter, as its non-zero entries:
/// dZ(s)(row, col) = stiffness + s * damping + s^2 * mass, stiffness = dK + j dK_loss (complex).
struct DynamicStiffnessDerivative {
  struct Entry {
    int row = 0, col = 0;
    std::complex<double> stiffness;
    double damping = 0.0;
    double mass = 0.0;
  };
  std::string name;
  std::vector<Entry> entries;
};

/// The non-zero entries of dM, dC, dK, dK_loss (n x n each). `name` labels the parameter.
DynamicStiffnessDerivative MakeDynamicStiffnessDerivative(const model::SystemDerivative& derivative,
                                                          const std::string& name);

class FrfEvaluator {
 public:
  /// Sets up the evaluation of `system` (copied). Throws InputError when the sizes of the matrices
  /// disagree, NumericalError when M is not positive definite or the forced kModal set-up fails.
  static FrfEvaluator Create(const model::SecondOrderSystem& system, const FrfEvaluatorOptions& options = {});

  const FrfSetupSummary& setup_summary() const { return summary_; }
  /// kModal or kDirect.
  FrfMethod path_used() const { return summary_.path; }
  const model::SecondOrderSystem& system() const { return system_; }
  int num_outputs() const { return system_.num_outputs(); }
  int num_inputs() const { return system_.num_inputs(); }

  /// H(j 2 pi f) of the header equation at every f of `frequency_hz` (Hz, finite, >= 0; > 0 when the
  /// model has a rigid-body mode). Throws InputError naming the first bad frequency.
  FrfArray Evaluate(const Eigen::VectorXd& frequency_hz, ResponseQuantity quantity);
  /// The same into `out` (its storage is reused when the sizes match: no allocation in a loop).
  void Evaluate(const Eigen::VectorXd& frequency_hz, ResponseQuantity quantity, FrfArray* out);

  /// H and dH/dp for each parameter (exact, see the header). `model` must be the assembled model the
  /// system was built from (same generalised coordinates); throws InputError otherwise.
  FrfWithDerivatives EvaluateWithDerivatives(const Eigen::VectorXd& frequency_hz, ResponseQuantity quantity,
                                             const std::vector<model::ParameterInfo>& parameters,
                                             const model::AssembledModel& model);
  /// The same into `out`, whose storage is reused when the sizes match (a fit loop: no allocation of
  /// the Nf x Nout x Nin x P derivative array per call).
  void EvaluateWithDerivatives(const Eigen::VectorXd& frequency_hz, ResponseQuantity quantity,
                               const std::vector<model::ParameterInfo>& parameters,
                               const model::AssembledModel& model, FrfWithDerivatives* out);
  /// The same for derivatives given directly (entries index the generalised coordinates, < n).
  void EvaluateWithDerivatives(const Eigen::VectorXd& frequency_hz, ResponseQuantity quantity,
                               const std::vector<DynamicStiffnessDerivative>& derivatives,
                               FrfWithDerivatives* out);

 private:
  FrfEvaluator() = default;
  void SetUpModal(bool forced);
  void EvaluateModal(const Eigen::VectorXd& omega_rad_s, int power,
                     const std::vector<DynamicStiffnessDerivative>* derivatives, FrfArray* frf,
                     std::vector<Eigen::MatrixXcd>* d_values);
  void EvaluateDirect(const Eigen::VectorXd& omega_rad_s, int power,
                      const std::vector<DynamicStiffnessDerivative>* derivatives, FrfArray* frf,
                      std::vector<Eigen::MatrixXcd>* d_values);
  double ProbeError();

  model::SecondOrderSystem system_;
  FrfEvaluatorOptions options_;
  FrfSetupSummary summary_;

  // Modal factors (header equations; D = diag(Omega), W_r = the right n columns of V^-1).
  Eigen::MatrixXd phi_;        // mass-normalised undamped modes Phi (n x n)
  Eigen::VectorXcd poles_;     // lambda (2n)
  Eigen::MatrixXcd out_pos_;   // Cq Phi D^-1 V_top               (Nout x 2n)
  Eigen::MatrixXcd out_vel_;   // Cq Phi V_bot                    (Nout x 2n)
  Eigen::MatrixXcd dof_pos_;   // Phi D^-1 V_top                  (n x 2n)
  Eigen::MatrixXcd dof_vel_;   // Phi V_bot                       (n x 2n)
  Eigen::MatrixXcd in_b1_;     // W_r (Phi' B0 - Kt Phi' B2)      (2n x Nin)
  Eigen::MatrixXcd in_b2_;     // W_r Ct Phi' B2                  (2n x Nin)
  Eigen::MatrixXcd dof_in_;    // W_r Phi'                        (2n x n)
  Eigen::MatrixXd direct_d_;   // Cq Phi Phi' B2 + D0             (Nout x Nin)
  Eigen::MatrixXd dof_direct_d_;                  // Phi Phi' B2   (n x Nin)
  Eigen::MatrixXcd direct_e1_, direct_e2_;        // sum_k R_k, sum_k lambda_k R_k
  std::vector<int> pair_index_;  // real path: the poles with Im > 0 (one per pair), then the real poles
  int num_pairs_ = 0;

  // Workspace of one thread over one block of frequencies (reused between calls).
  struct BlockWorkspace {
    Eigen::MatrixXcd block, coef_complex;
    Eigen::MatrixXd coef_real, block_real;
    Eigen::ArrayXcd prefactor, factor;
    Eigen::MatrixXcd grouped;  // AccumulateDerivatives' sums over one column's entries (nb x Nout)
    Eigen::ArrayXd scratch1, scratch2, scratch3;
    void Resize(Eigen::Index block_size, int cols, bool real, Eigen::Index num_real_rows, int num_complex);
  };
  void EvaluateModalBlock(const Eigen::VectorXd& omega_rad_s, Eigen::Index f0, Eigen::Index nb, int power,
                          const std::vector<DynamicStiffnessDerivative>* derivatives,
                          const std::vector<int>& support, const std::vector<int>& position, FrfArray* frf,
                          std::vector<Eigen::MatrixXcd>* d_values, BlockWorkspace* ws) const;

  // Workspace (reused between calls).
  Eigen::MatrixXcd residue_;
  Eigen::MatrixXd residue_real_;
  BlockWorkspace direct_workspace_;  // the direct path's (the modal path's are per thread)
};

}  // namespace stagefit::response
