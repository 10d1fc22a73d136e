#include "fft_internal.h"

#include <cmath>
#include <mutex>
#include <sstream>

#include "stagefit/common/error.h"

namespace stagefit::disturbance::internal {
namespace {

// FFTW's planner is not thread-safe; plan creation and destruction are serialised.
std::mutex& PlannerMutex() {
  static std::mutex mutex;
  return mutex;
}

}  // namespace

RealFft::RealFft(int n) : n_(n) {
  STAGEFIT_ASSERT(n >= 1, "FFT length " << n);
  std::lock_guard<std::mutex> lock(PlannerMutex());
  in_ = fftw_alloc_real(n);
  out_ = fftw_alloc_complex(n / 2 + 1);
  plan_ = fftw_plan_dft_r2c_1d(n, in_, out_, FFTW_ESTIMATE);
  STAGEFIT_ASSERT(plan_ != nullptr, "FFTW could not plan a real FFT of length " << n);
}

RealFft::~RealFft() {
  std::lock_guard<std::mutex> lock(PlannerMutex());
  fftw_destroy_plan(plan_);
  fftw_free(in_);
  fftw_free(out_);
}

void RealFft::Forward(const Eigen::VectorXd& in, Eigen::VectorXcd& out) {
  STAGEFIT_ASSERT(in.size() == n_, "FFT input has " << in.size() << " samples, plan is for " << n_);
  for (int i = 0; i < n_; ++i) in_[i] = in[i];
  fftw_execute(plan_);
  out.resize(n_ / 2 + 1);
  for (int k = 0; k <= n_ / 2; ++k) out[k] = std::complex<double>(out_[k][0], out_[k][1]);
}

InverseRealFft::InverseRealFft(int n) : n_(n) {
  STAGEFIT_ASSERT(n >= 1, "FFT length " << n);
  std::lock_guard<std::mutex> lock(PlannerMutex());
  in_ = fftw_alloc_complex(n / 2 + 1);
  out_ = fftw_alloc_real(n);
  plan_ = fftw_plan_dft_c2r_1d(n, in_, out_, FFTW_ESTIMATE);
  STAGEFIT_ASSERT(plan_ != nullptr, "FFTW could not plan an inverse real FFT of length " << n);
}

InverseRealFft::~InverseRealFft() {
  std::lock_guard<std::mutex> lock(PlannerMutex());
  fftw_destroy_plan(plan_);
  fftw_free(in_);
  fftw_free(out_);
}

void InverseRealFft::Inverse(const Eigen::VectorXcd& in, Eigen::VectorXd& out) {
  STAGEFIT_ASSERT(in.size() == n_ / 2 + 1,
                  "inverse FFT input has " << in.size() << " bins, plan needs " << n_ / 2 + 1);
  for (int k = 0; k <= n_ / 2; ++k) {
    in_[k][0] = in[k].real();
    in_[k][1] = in[k].imag();
  }
  fftw_execute(plan_);  // c2r destroys its input; it is refilled on every call
  out.resize(n_);
  for (int i = 0; i < n_; ++i) out[i] = out_[i];
}

void CheckFinite(const Eigen::VectorXd& x, std::string_view record, std::string_view field) {
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    if (!std::isfinite(x[i])) {
      std::ostringstream message;
      message << record << ": field '" << field << "': sample " << i << " is " << x[i]
              << ", expected a finite number";
      throw InputError(message.str());
    }
  }
}

void CheckSampleRate(double sample_rate_hz, std::string_view record, std::string_view field) {
  if (!(std::isfinite(sample_rate_hz) && sample_rate_hz > 0.0)) {
    std::ostringstream message;
    message << record << ": field '" << field << "': sample rate " << sample_rate_hz
            << " Hz, expected a finite rate > 0";
    throw InputError(message.str());
  }
}

Eigen::VectorXd RemoveLine(const Eigen::VectorXd& t, const Eigen::VectorXd& x, double* intercept,
                           double* slope) {
  STAGEFIT_ASSERT(t.size() == x.size() && t.size() >= 1, "line fit sizes " << t.size() << ", "
                                                                           << x.size());
  const double n = static_cast<double>(t.size());
  const double t_mean = t.sum() / n;
  const double x_mean = x.sum() / n;
  const Eigen::VectorXd dt = t.array() - t_mean;
  const double stt = dt.squaredNorm();
  const double b = stt > 0.0 ? dt.dot(x.array().matrix() - Eigen::VectorXd::Constant(t.size(), x_mean)) / stt
                             : 0.0;
  const double a = x_mean - b * t_mean;
  if (intercept != nullptr) *intercept = a;
  if (slope != nullptr) *slope = b;
  return (x.array() - a - b * t.array()).matrix();
}

}  // namespace stagefit::disturbance::internal
