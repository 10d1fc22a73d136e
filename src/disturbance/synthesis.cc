#include "stagefit/disturbance/synthesis.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "fft_internal.h"
#include "stagefit/common/error.h"

namespace stagefit::disturbance {

void ValidatePsdTable(const PsdTable& table) {
  auto fail = [&](const std::string& what) { throw InputError(table.name + ": " + what); };
  if (table.frequency_hz.size() != table.psd.size()) {
    fail("frequency_hz has " + std::to_string(table.frequency_hz.size()) + " values and psd " +
         std::to_string(table.psd.size()) + ", expected the same number");
  }
  if (table.psd.size() < 1) fail("the PSD table is empty, expected at least one point");
  for (Eigen::Index i = 0; i < table.psd.size(); ++i) {
    const double f = table.frequency_hz[i];
    const double s = table.psd[i];
    std::ostringstream at;
    at << "row " << i << ": ";
    if (!std::isfinite(f) || f < 0.0) {
      at << "frequency_hz = " << f << ", expected a finite frequency >= 0";
      fail(at.str());
    }
    if (i > 0 && !(f > table.frequency_hz[i - 1])) {
      at << "frequency_hz = " << f << " after " << table.frequency_hz[i - 1]
         << ", expected strictly increasing frequencies";
      fail(at.str());
    }
    if (!std::isfinite(s) || s < 0.0) {
      at << "psd = " << s << ", expected a finite value >= 0";
      fail(at.str());
    }
  }
}

double InterpolatePsd(const PsdTable& table, double frequency_hz) {
  const Eigen::VectorXd& f = table.frequency_hz;
  const Eigen::VectorXd& s = table.psd;
  const Eigen::Index m = f.size();
  if (m == 0 || frequency_hz < f[0] || frequency_hz > f[m - 1]) return 0.0;
  if (m == 1) return s[0];
  Eigen::Index hi = std::upper_bound(f.data(), f.data() + m, frequency_hz) - f.data();
  if (hi >= m) hi = m - 1;
  const Eigen::Index lo = hi - 1;
  if (frequency_hz == f[hi]) return s[hi];
  if (f[lo] > 0.0 && s[lo] > 0.0 && s[hi] > 0.0) {
    const double t = std::log(frequency_hz / f[lo]) / std::log(f[hi] / f[lo]);
    return std::exp(std::log(s[lo]) + t * std::log(s[hi] / s[lo]));
  }
  const double t = (frequency_hz - f[lo]) / (f[hi] - f[lo]);
  return s[lo] + t * (s[hi] - s[lo]);
}

int SynthesisSampleCount(const SynthesisOptions& options, const std::string& context) {
  if (!(std::isfinite(options.duration_s) && options.duration_s > 0.0)) {
    throw InputError(context + ": duration " + std::to_string(options.duration_s) +
                     " s, expected a finite duration > 0");
  }
  if (!(std::isfinite(options.sample_rate_hz) && options.sample_rate_hz > 0.0)) {
    throw InputError(context + ": sample rate " + std::to_string(options.sample_rate_hz) +
                     " Hz, expected a finite rate > 0");
  }
  const double n = std::round(options.duration_s * options.sample_rate_hz);
  constexpr double kMaxSamples = 1e9;
  if (n < 2.0 || n > kMaxSamples) {
    std::ostringstream message;
    message << context << ": duration " << options.duration_s << " s at " << options.sample_rate_hz
            << " Hz gives " << n << " samples, expected 2 to " << kMaxSamples;
    throw InputError(message.str());
  }
  return static_cast<int>(n);
}

Eigen::VectorXd SynthesiseSignal(const PsdTable& target, const SynthesisOptions& options,
                                 std::mt19937_64& rng,
                                 const std::function<double(double)>& gain2) {
  ValidatePsdTable(target);
  const int n = SynthesisSampleCount(options, target.name);
  const double df = options.sample_rate_hz / n;
  const int last = (n + 1) / 2 - 1;  // highest k strictly below Nyquist

  Eigen::VectorXcd bins = Eigen::VectorXcd::Zero(n / 2 + 1);
  for (int k = 1; k <= last; ++k) {
    const double f = k * df;
    const double psd = InterpolatePsd(target, f) * (gain2 ? gain2(f) : 1.0);
    const double amplitude = std::sqrt(2.0 * psd * df);
    const double phase = 2.0 * M_PI * static_cast<double>(rng() >> 11) * 0x1.0p-53;
    bins[k] = std::polar(0.5 * amplitude, phase);
  }
  internal::InverseRealFft ifft(n);
  Eigen::VectorXd x;
  ifft.Inverse(bins, x);
  return x;
}

}  // namespace stagefit::disturbance
