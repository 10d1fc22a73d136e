#pragma once
// Private helpers of the disturbance layer: FFTW3 plans behind a small RAII wrapper, and input checks.

#include <fftw3.h>

#include <Eigen/Dense>

#include <complex>
#include <string_view>

namespace stagefit::disturbance::internal {

/// Real-to-complex forward transform of fixed length n: out[k] = sum_n in[n] e^{-j 2 pi k n / N},
/// k = 0..n/2 (unnormalised, as FFTW).
class RealFft {
 public:
  explicit RealFft(int n);
  ~RealFft();
  RealFft(const RealFft&) = delete;
  RealFft& operator=(const RealFft&) = delete;

  int size() const { return n_; }
  /// `in` has n samples; `out` is resized to n/2+1 bins.
  void Forward(const Eigen::VectorXd& in, Eigen::VectorXcd& out);

 private:
  int n_;
  double* in_;
  fftw_complex* out_;
  fftw_plan plan_;
};

/// Complex-to-real inverse transform of length n: out[m] = sum_{k=0}^{n-1} X[k] e^{+j 2 pi k m / N}
/// with X Hermitian (only X[0..n/2] given); unnormalised, as FFTW.
class InverseRealFft {
 public:
  explicit InverseRealFft(int n);
  ~InverseRealFft();
  InverseRealFft(const InverseRealFft&) = delete;
  InverseRealFft& operator=(const InverseRealFft&) = delete;

  /// `in` has n/2+1 bins; `out` is resized to n samples.
  void Inverse(const Eigen::VectorXcd& in, Eigen::VectorXd& out);

 private:
  int n_;
  fftw_complex* in_;
  double* out_;
  fftw_plan plan_;
};

/// Throws InputError "<record>: field '<field>': sample <i> is <value>, expected a finite number"
/// at the first NaN or Inf.
void CheckFinite(const Eigen::VectorXd& x, std::string_view record, std::string_view field);

/// Throws InputError unless rate is finite and > 0.
void CheckSampleRate(double sample_rate_hz, std::string_view record, std::string_view field);

/// Least-squares straight line through (t, x): returns x - (a + b t); slope and intercept optional.
Eigen::VectorXd RemoveLine(const Eigen::VectorXd& t, const Eigen::VectorXd& x,
                           double* intercept = nullptr, double* slope = nullptr);

}  // namespace stagefit::disturbance::internal
