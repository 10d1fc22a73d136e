#include "stagefit/disturbance/spectral_density.h"

#include <cmath>
#include <sstream>

#include "fft_internal.h"
#include "stagefit/common/error.h"

namespace stagefit::disturbance {
namespace {

struct Segmenting {
  int length = 0;
  int step = 0;
  int averages = 0;
};

Segmenting ChooseSegments(Eigen::Index n, double fs, const WelchOptions& options,
                          std::string_view record, std::string_view field) {
  auto fail = [&](const std::string& what) {
    std::ostringstream message;
    message << record << ": field '" << field << "': " << what;
    throw InputError(message.str());
  };
  if (!(options.overlap >= 0.0 && options.overlap < 1.0)) {
    fail("Welch overlap " + std::to_string(options.overlap) + ", expected 0 <= overlap < 1");
  }
  Segmenting s;
  if (options.segment_length > 0) {
    s.length = options.segment_length;
  } else if (options.resolution_hz > 0.0) {
    if (!std::isfinite(options.resolution_hz)) fail("resolution is not finite");
    const double length = std::ceil(fs / options.resolution_hz - 1e-9);
    if (length > static_cast<double>(n)) {
      std::ostringstream what;
      what << n << " samples at " << fs << " Hz (" << n / fs << " s) is too short for a resolution of "
           << options.resolution_hz << " Hz: one segment needs " << length << " samples ("
           << length / fs << " s)";
      fail(what.str());
    }
    s.length = static_cast<int>(length);
  } else if (options.resolution_hz < 0.0 || options.segment_length < 0) {
    fail("negative Welch resolution or segment length");
  } else {
    if (options.default_averages < 1) fail("default_averages must be >= 1");
    const double k = options.default_averages;
    s.length = static_cast<int>(std::floor(static_cast<double>(n) / (1.0 + (k - 1.0) * (1.0 - options.overlap))));
  }
  constexpr int kMinSegment = 8;
  if (s.length < kMinSegment || s.length > n) {
    std::ostringstream what;
    what << n << " samples: a Welch segment of " << s.length << " samples is impossible (need "
         << kMinSegment << " <= segment <= record length)";
    fail(what.str());
  }
  s.step = std::max(1, s.length - static_cast<int>(std::lround(options.overlap * s.length)));
  s.averages = 1 + static_cast<int>((n - s.length) / s.step);
  return s;
}

void DetrendSegment(Detrend detrend, Eigen::VectorXd& segment) {
  switch (detrend) {
    case Detrend::kNone:
      return;
    case Detrend::kMean:
      segment.array() -= segment.mean();
      return;
    case Detrend::kLinear: {
      const Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(segment.size(), 0.0, segment.size() - 1.0);
      segment = internal::RemoveLine(t, segment);
      return;
    }
  }
}

double DegreesOfFreedom(const Eigen::VectorXd& w, int step, int averages) {
  const double w2 = w.squaredNorm();
  double sum = 0.0;
  for (int l = 1; l < averages; ++l) {
    const Eigen::Index shift = static_cast<Eigen::Index>(l) * step;
    if (shift >= w.size()) break;
    const Eigen::Index overlap = w.size() - shift;
    const double c = w.head(overlap).dot(w.tail(overlap));
    sum += (averages - l) * (c * c) / (w2 * w2);
  }
  const double k = averages;
  return 2.0 * k * k / (k + 2.0 * sum);
}

struct WelchSetup {
  Segmenting seg;
  Eigen::VectorXd window;
  double scale = 0.0;  // 1 / (fs sum w^2)
};

WelchSetup PrepareWelch(Eigen::Index n, double fs, const WelchOptions& options,
                        std::string_view record, std::string_view field) {
  WelchSetup setup;
  setup.seg = ChooseSegments(n, fs, options, record, field);
  setup.window = CalcWindow(options.window, setup.seg.length);
  setup.scale = 1.0 / (fs * setup.window.squaredNorm());
  return setup;
}

double OneSidedFactor(int k, int length) {
  const bool nyquist = (length % 2 == 0) && (k == length / 2);
  return (k == 0 || nyquist) ? 1.0 : 2.0;
}

Eigen::VectorXd Frequencies(int length, double fs) {
  return Eigen::VectorXd::LinSpaced(length / 2 + 1, 0.0, (length / 2) * fs / length);
}

// Regularised lower incomplete gamma function P(a, x).
double RegularisedGammaP(double a, double x) {
  if (x <= 0.0) return 0.0;
  const double log_prefactor = -x + a * std::log(x) - std::lgamma(a);
  if (x < a + 1.0) {
    double term = 1.0 / a;
    double sum = term;
    for (int n = 1; n < 100000; ++n) {
      term *= x / (a + n);
      sum += term;
      if (std::abs(term) < std::abs(sum) * 1e-16) break;
    }
    return sum * std::exp(log_prefactor);
  }
  // Continued fraction for Q(a, x) (modified Lentz).
  constexpr double kTiny = 1e-300;
  double b = x + 1.0 - a;
  double c = 1.0 / kTiny;
  double d = 1.0 / b;
  double h = d;
  for (int i = 1; i < 100000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < kTiny) d = kTiny;
    c = b + an / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1.0) < 1e-16) break;
  }
  return 1.0 - std::exp(log_prefactor) * h;
}

}  // namespace

Window ParseWindow(std::string_view text, std::string_view context) {
  if (text == "hann") return Window::kHann;
  if (text == "hamming") return Window::kHamming;
  if (text == "blackman-harris") return Window::kBlackmanHarris;
  if (text == "flat-top") return Window::kFlatTop;
  if (text == "rectangular") return Window::kRectangular;
  throw InputError(std::string(context) + ": window '" + std::string(text) +
                   "', expected hann, hamming, blackman-harris, flat-top or rectangular");
}

Detrend ParseDetrend(std::string_view text, std::string_view context) {
  if (text == "none") return Detrend::kNone;
  if (text == "mean") return Detrend::kMean;
  if (text == "linear") return Detrend::kLinear;
  throw InputError(std::string(context) + ": detrend '" + std::string(text) +
                   "', expected none, mean or linear");
}

std::string_view WindowName(Window window) {
  switch (window) {
    case Window::kHann: return "hann";
    case Window::kHamming: return "hamming";
    case Window::kBlackmanHarris: return "blackman-harris";
    case Window::kFlatTop: return "flat-top";
    case Window::kRectangular: return "rectangular";
  }
  return "?";
}

std::string_view DetrendName(Detrend detrend) {
  switch (detrend) {
    case Detrend::kNone: return "none";
    case Detrend::kMean: return "mean";
    case Detrend::kLinear: return "linear";
  }
  return "?";
}

Eigen::VectorXd CalcWindow(Window window, int length) {
  STAGEFIT_ASSERT(length >= 1, "window length " << length);
  Eigen::VectorXd w(length);
  for (int n = 0; n < length; ++n) {
    const double x = 2.0 * M_PI * n / length;
    switch (window) {
      case Window::kHann:
        w[n] = 0.5 - 0.5 * std::cos(x);
        break;
      case Window::kHamming:
        w[n] = 0.54 - 0.46 * std::cos(x);
        break;
      case Window::kBlackmanHarris:
        w[n] = 0.35875 - 0.48829 * std::cos(x) + 0.14128 * std::cos(2 * x) - 0.01168 * std::cos(3 * x);
        break;
      case Window::kFlatTop:
        w[n] = 0.21557895 - 0.41663158 * std::cos(x) + 0.277263158 * std::cos(2 * x) -
               0.083578947 * std::cos(3 * x) + 0.006947368 * std::cos(4 * x);
        break;
      case Window::kRectangular:
        w[n] = 1.0;
        break;
    }
  }
  return w;
}

Spectrum EstimatePsd(const Eigen::VectorXd& x, double sample_rate_hz, const WelchOptions& options,
                     std::string_view record, std::string_view field) {
  internal::CheckSampleRate(sample_rate_hz, record, field);
  internal::CheckFinite(x, record, field);
  const WelchSetup setup = PrepareWelch(x.size(), sample_rate_hz, options, record, field);
  const int length = setup.seg.length;

  internal::RealFft fft(length);
  Eigen::VectorXd accumulated = Eigen::VectorXd::Zero(length / 2 + 1);
  Eigen::VectorXd segment(length);
  Eigen::VectorXcd bins;
  for (int m = 0; m < setup.seg.averages; ++m) {
    segment = x.segment(static_cast<Eigen::Index>(m) * setup.seg.step, length);
    DetrendSegment(options.detrend, segment);
    segment.array() *= setup.window.array();
    fft.Forward(segment, bins);
    accumulated += bins.cwiseAbs2();
  }

  Spectrum s;
  s.frequency_hz = Frequencies(length, sample_rate_hz);
  s.psd.resize(length / 2 + 1);
  for (int k = 0; k <= length / 2; ++k) {
    s.psd[k] = OneSidedFactor(k, length) * setup.scale * accumulated[k] / setup.seg.averages;
  }
  s.sample_rate_hz = sample_rate_hz;
  s.segment_length = length;
  s.averages = setup.seg.averages;
  s.resolution_hz = sample_rate_hz / length;
  s.enbw_hz = sample_rate_hz * setup.window.squaredNorm() / std::pow(setup.window.sum(), 2);
  s.degrees_of_freedom = DegreesOfFreedom(setup.window, setup.seg.step, setup.seg.averages);
  return s;
}

CrossSpectrum EstimateCrossSpectrum(const Eigen::VectorXd& x, const Eigen::VectorXd& y,
                                    double sample_rate_hz, const WelchOptions& options,
                                    std::string_view record, std::string_view field_x,
                                    std::string_view field_y) {
  internal::CheckSampleRate(sample_rate_hz, record, field_x);
  internal::CheckFinite(x, record, field_x);
  internal::CheckFinite(y, record, field_y);
  if (x.size() != y.size()) {
    std::ostringstream message;
    message << record << ": fields '" << field_x << "' and '" << field_y << "' have " << x.size()
            << " and " << y.size() << " samples, expected the same number";
    throw InputError(message.str());
  }
  const WelchSetup setup = PrepareWelch(x.size(), sample_rate_hz, options, record, field_x);
  const int length = setup.seg.length;
  const int bins_count = length / 2 + 1;

  internal::RealFft fft(length);
  Eigen::VectorXcd sxy = Eigen::VectorXcd::Zero(bins_count);
  Eigen::VectorXd sxx = Eigen::VectorXd::Zero(bins_count);
  Eigen::VectorXd syy = Eigen::VectorXd::Zero(bins_count);
  Eigen::VectorXd segment(length);
  Eigen::VectorXcd bx, by;
  for (int m = 0; m < setup.seg.averages; ++m) {
    const Eigen::Index start = static_cast<Eigen::Index>(m) * setup.seg.step;
    segment = x.segment(start, length);
    DetrendSegment(options.detrend, segment);
    segment.array() *= setup.window.array();
    fft.Forward(segment, bx);
    segment = y.segment(start, length);
    DetrendSegment(options.detrend, segment);
    segment.array() *= setup.window.array();
    fft.Forward(segment, by);
    sxy.array() += bx.array().conjugate() * by.array();
    sxx += bx.cwiseAbs2();
    syy += by.cwiseAbs2();
  }

  CrossSpectrum c;
  c.frequency_hz = Frequencies(length, sample_rate_hz);
  c.csd.resize(bins_count);
  c.psd_x.resize(bins_count);
  c.psd_y.resize(bins_count);
  c.coherence.resize(bins_count);
  for (int k = 0; k < bins_count; ++k) {
    const double f = OneSidedFactor(k, length) * setup.scale / setup.seg.averages;
    c.csd[k] = f * sxy[k];
    c.psd_x[k] = f * sxx[k];
    c.psd_y[k] = f * syy[k];
    const double denominator = c.psd_x[k] * c.psd_y[k];
    c.coherence[k] = denominator > 0.0 ? std::norm(c.csd[k]) / denominator : 0.0;
  }
  c.averages = setup.seg.averages;
  return c;
}

double IntegratePsd(const Spectrum& spectrum, double min_frequency_hz, double max_frequency_hz) {
  STAGEFIT_ASSERT(spectrum.frequency_hz.size() == spectrum.psd.size(),
                  "spectrum sizes " << spectrum.frequency_hz.size() << ", " << spectrum.psd.size());
  if (spectrum.psd.size() < 2) return 0.0;
  const double df = spectrum.frequency_hz[1] - spectrum.frequency_hz[0];
  double sum = 0.0;
  for (Eigen::Index k = 0; k < spectrum.psd.size(); ++k) {
    const double f = spectrum.frequency_hz[k];
    if (f >= min_frequency_hz && f <= max_frequency_hz) sum += spectrum.psd[k];
  }
  return sum * df;
}

double CalcChiSquareQuantile(double degrees_of_freedom, double probability) {
  STAGEFIT_ASSERT(degrees_of_freedom > 0.0 && probability > 0.0 && probability < 1.0,
                  "chi-square quantile nu = " << degrees_of_freedom << ", p = " << probability);
  const double a = 0.5 * degrees_of_freedom;
  double lo = 0.0;
  double hi = degrees_of_freedom + 10.0 * std::sqrt(2.0 * degrees_of_freedom) + 10.0;
  while (RegularisedGammaP(a, 0.5 * hi) < probability) hi *= 2.0;
  for (int i = 0; i < 200 && hi - lo > 1e-14 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (RegularisedGammaP(a, 0.5 * mid) < probability ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

PsdConfidenceBand CalcPsdConfidenceBand(double degrees_of_freedom, double confidence) {
  STAGEFIT_ASSERT(confidence > 0.0 && confidence < 1.0, "confidence " << confidence);
  const double alpha = 1.0 - confidence;
  return {CalcChiSquareQuantile(degrees_of_freedom, 0.5 * alpha) / degrees_of_freedom,
          CalcChiSquareQuantile(degrees_of_freedom, 1.0 - 0.5 * alpha) / degrees_of_freedom};
}

}  // namespace stagefit::disturbance
