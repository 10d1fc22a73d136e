#include "stagefit/measurement/hammer_estimation.h"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <set>
#include <sstream>

#include "stagefit/common/error.h"
#include "stagefit/common/units.h"
#include "stagefit/common/utf8.h"

namespace stagefit::measurement {
namespace {

using Complex = std::complex<double>;
constexpr int kMinSamples = 16;
// Leakage warning: the windowed response still holds this share of its peak in the last 5 % of
// the record.
constexpr double kLeakagePeakShare = 0.05;
constexpr double kLeakageTailShare = 0.05;

std::string Where(const RawHammerData& data) {
  return data.source.empty() ? std::string("raw hammer data") : "'" + data.source + "'";
}

[[noreturn]] void Fail(const RawHammerData& data, const std::string& message) {
  throw InputError(Where(data) + ": " + message);
}

std::string Quote(const std::string& s) { return "'" + s + "'"; }

// One real-to-complex FFTW plan of a fixed length, made once and reused for every record.
class RealFft {
 public:
  explicit RealFft(int n) : n_(n) {
    in_ = fftw_alloc_real(n);
    out_ = fftw_alloc_complex(n / 2 + 1);
    STAGEFIT_ASSERT(in_ != nullptr && out_ != nullptr, "FFTW could not allocate " << n << " points");
    plan_ = fftw_plan_dft_r2c_1d(n, in_, out_, FFTW_ESTIMATE);
    STAGEFIT_ASSERT(plan_ != nullptr, "FFTW could not plan a transform of " << n << " points");
  }
  ~RealFft() {
    fftw_destroy_plan(plan_);
    fftw_free(in_);
    fftw_free(out_);
  }
  RealFft(const RealFft&) = delete;
  RealFft& operator=(const RealFft&) = delete;

  // DFT X(k) = sum_n x(n) w(n) exp(-2 pi j k n / N) for k = k0 .. k0 + out.size() - 1.
  void Transform(const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::VectorXd& w, int k0,
                 Eigen::Ref<Eigen::VectorXcd> out) {
    for (int i = 0; i < n_; ++i) in_[i] = x(i) * w(i);
    fftw_execute(plan_);
    for (Eigen::Index k = 0; k < out.size(); ++k) {
      out(k) = Complex(out_[k0 + k][0], out_[k0 + k][1]);
    }
  }

 private:
  int n_;
  double* in_ = nullptr;
  fftw_complex* out_ = nullptr;
  fftw_plan plan_ = nullptr;
};

struct Pulse {
  int start = 0;
  int end = 0;
  double peak = 0.0;
};

Pulse DetectPulse(const Eigen::VectorXd& force, double threshold) {
  Eigen::Index peak_index = 0;
  force.cwiseAbs().maxCoeff(&peak_index);
  Pulse p;
  p.peak = force(peak_index);
  const double level = threshold * std::abs(p.peak);
  p.start = static_cast<int>(peak_index);
  while (p.start > 0 && std::abs(force(p.start - 1)) >= level) --p.start;
  p.end = static_cast<int>(peak_index);
  while (p.end + 1 < force.size() && std::abs(force(p.end + 1)) >= level) ++p.end;
  return p;
}

bool Overloaded(const Eigen::Ref<const Eigen::VectorXd>& x, double full_scale,
                const EstimationOptions& options) {
  const double peak = x.cwiseAbs().maxCoeff();
  if (peak == 0.0) return false;
  if (full_scale > 0.0 && peak >= options.overload_fraction * full_scale) return true;
  int run = 1;
  for (Eigen::Index i = 1; i < x.size(); ++i) {
    const bool high = std::abs(x(i)) >= 0.9 * peak && std::abs(x(i - 1)) >= 0.9 * peak;
    if (high && std::abs(x(i) - x(i - 1)) <= 1e-9 * peak) {
      if (++run >= options.clip_run_samples) return true;
    } else {
      run = 1;
    }
  }
  return false;
}

double FullScale(const Eigen::VectorXd& ranges, int index) {
  return index < ranges.size() ? ranges(index) : 0.0;
}

void CheckOptions(const EstimationOptions& o) {
  auto in_unit = [](double v) { return v > 0.0 && v < 1.0; };
  std::ostringstream m;
  if (!(o.exp_tau_s >= 0.0) || !std::isfinite(o.exp_tau_s)) {
    m << "exponential window tau = " << o.exp_tau_s << " s, expected > 0 (or 0 for none)";
  } else if (!(o.force_window_s >= 0.0) || !std::isfinite(o.force_window_s)) {
    m << "force window = " << o.force_window_s << " s, expected > 0 (or 0 for automatic)";
  } else if (!(o.force_taper_s >= 0.0) || !std::isfinite(o.force_taper_s)) {
    m << "force window taper = " << o.force_taper_s << " s, expected > 0 (or 0 for automatic)";
  } else if (!(o.min_frequency_hz >= 0.0) || !(o.max_frequency_hz >= 0.0)) {
    m << "frequency band [" << o.min_frequency_hz << ", " << o.max_frequency_hz
      << "] Hz, expected non-negative bounds";
  } else if (!in_unit(o.pulse_threshold)) {
    m << "pulse threshold = " << o.pulse_threshold << ", expected in (0, 1)";
  } else if (!in_unit(o.double_hit_ratio)) {
    m << "double-hit ratio = " << o.double_hit_ratio << ", expected in (0, 1)";
  } else if (!(o.force_band_db > 0.0) || !std::isfinite(o.force_band_db)) {
    m << "force band = " << o.force_band_db << " dB, expected > 0";
  } else if (!(o.overload_fraction > 0.0 && o.overload_fraction <= 1.0)) {
    m << "overload fraction = " << o.overload_fraction << ", expected in (0, 1]";
  } else if (o.clip_run_samples < 2) {
    m << "clip run = " << o.clip_run_samples << " samples, expected >= 2";
  } else if (!(o.min_hit_coherence >= 0.0 && o.min_hit_coherence <= 1.0) ||
             !(o.low_coherence >= 0.0 && o.low_coherence <= 1.0) ||
             !(o.low_coherence_share >= 0.0 && o.low_coherence_share <= 1.0)) {
    m << "coherence thresholds must lie in [0, 1]";
  }
  if (m.tellp() > 0) throw InputError("estimation options: " + m.str());
}

std::string HitLabel(const RawHammerData& data, int input, int hit) {
  return "input " + std::to_string(input + 1) + " " + Quote(data.inputs[input].name) + " hit " +
         std::to_string(hit + 1);
}

// Force window and exponential window of one hit.
void MakeWindows(const RawHammerData& data, const EstimationOptions& options, const Pulse& pulse,
                 Eigen::VectorXd& force_window, Eigen::VectorXd& exp_window) {
  const int n = data.num_samples();
  const double fs = data.sample_rate_hz;
  const double t0 = pulse.start / fs;
  const double width = (pulse.end - pulse.start + 1) / fs;
  force_window = Eigen::VectorXd::Ones(n);
  exp_window = Eigen::VectorXd::Ones(n);
  if (options.apply_force_window) {
    const double length = options.force_window_s > 0.0 ? options.force_window_s
                                                       : std::max(3.0 * width, 8.0 / fs);
    const double taper = options.force_taper_s > 0.0 ? options.force_taper_s
                                                     : std::max(width, 4.0 / fs);
    const double a = t0 - taper;
    const double b = t0 + length;
    for (int i = 0; i < n; ++i) {
      const double t = i / fs;
      double w = 0.0;
      if (t >= a && t <= b) {
        w = 1.0;
      } else if (t >= a - taper && t < a) {
        w = 0.5 * (1.0 - std::cos(kPi * (t - (a - taper)) / taper));
      } else if (t > b && t <= b + taper) {
        w = 0.5 * (1.0 + std::cos(kPi * (t - b) / taper));
      }
      force_window(i) = w;
    }
  }
  if (options.exp_tau_s > 0.0) {
    for (int i = pulse.start; i < n; ++i) {
      exp_window(i) = std::exp(-(i / fs - t0) / options.exp_tau_s);
    }
  }
}

}  // namespace

int RawHammerData::num_samples() const {
  for (const auto& input_hits : hits) {
    if (!input_hits.empty()) return static_cast<int>(input_hits.front().force.size());
  }
  return 0;
}

void Validate(const RawHammerData& data) {
  if (!(data.sample_rate_hz > 0.0) || !std::isfinite(data.sample_rate_hz)) {
    std::ostringstream m;
    m << "sample_rate_hz = " << data.sample_rate_hz << ", expected a finite rate > 0 Hz";
    Fail(data, m.str());
  }
  if (data.outputs.empty()) Fail(data, "no response channels, expected at least one");
  if (data.inputs.empty()) Fail(data, "no impact locations (inputs), expected at least one");
  if (static_cast<int>(data.hits.size()) != data.num_inputs()) {
    Fail(data, "hits for " + std::to_string(data.hits.size()) + " inputs, expected " +
                   std::to_string(data.num_inputs()) + " (one list per input)");
  }
  auto check_names = [&](const std::vector<ChannelGeometry>& channels, const char* field) {
    std::set<std::string> names;
    for (std::size_t i = 0; i < channels.size(); ++i) {
      const ChannelGeometry& c = channels[i];
      if (c.name.empty()) {
        Fail(data, std::string(field) + "(" + std::to_string(i + 1) + "): empty name, expected one");
      }
      if (!IsValidUtf8(c.name)) {
        Fail(data, std::string(field) + "(" + std::to_string(i + 1) + "): " + Quote(EscapeNonUtf8(c.name)) +
                       " is not valid UTF-8, expected UTF-8 text");
      }
      if (!names.insert(c.name).second) {
        Fail(data, std::string(field) + ": " + Quote(c.name) + " appears twice, expected unique names");
      }
      if (c.has_geometry() && (!c.position_W.allFinite() || !c.direction_W.allFinite() ||
                               std::abs(c.direction_W.norm() - 1.0) > kUnitDirectionTolerance)) {
        std::ostringstream m;
        m << field << " " << Quote(c.name) << ": position (" << c.position_W.transpose()
          << "), direction (" << c.direction_W.transpose()
          << "), expected finite values and a unit direction";
        Fail(data, m.str());
      }
    }
  };
  check_names(data.outputs, "output_names");
  check_names(data.inputs, "input_names");
  if (data.response_full_scale.size() != 0 &&
      data.response_full_scale.size() != data.num_outputs()) {
    Fail(data, "response_full_scale: " + std::to_string(data.response_full_scale.size()) +
                   " values, expected " + std::to_string(data.num_outputs()) + " (one per output)");
  }
  if (data.force_full_scale.size() != 0 && data.force_full_scale.size() != data.num_inputs()) {
    Fail(data, "force_full_scale_n: " + std::to_string(data.force_full_scale.size()) +
                   " values, expected " + std::to_string(data.num_inputs()) + " (one per input)");
  }
  if ((data.response_full_scale.size() && !data.response_full_scale.allFinite()) ||
      (data.force_full_scale.size() && !data.force_full_scale.allFinite())) {
    Fail(data, "full-scale ranges must be finite");
  }
  const long long ns = data.num_samples();
  if (ns < kMinSamples) {
    Fail(data, "records of " + std::to_string(ns) + " samples, expected at least " +
                   std::to_string(kMinSamples));
  }
  if (ns > kMaxRawSamplesPerRecord) {
    Fail(data, "records of " + std::to_string(ns) + " samples, expected at most " +
                   std::to_string(kMaxRawSamplesPerRecord));
  }
  long long total = 0;
  std::vector<bool> alive(data.num_outputs(), false);
  for (int j = 0; j < data.num_inputs(); ++j) {
    if (data.hits[j].empty()) {
      Fail(data, "input " + std::to_string(j + 1) + " " + Quote(data.inputs[j].name) +
                     ": no hits, expected at least one");
    }
    for (std::size_t h = 0; h < data.hits[j].size(); ++h) {
      const HammerHit& hit = data.hits[j][h];
      const std::string label = HitLabel(data, j, static_cast<int>(h));
      if (hit.force.size() != ns || hit.response.rows() != ns ||
          hit.response.cols() != data.num_outputs()) {
        std::ostringstream m;
        m << label << ": force of " << hit.force.size() << " samples and response of "
          << hit.response.rows() << " x " << hit.response.cols() << ", expected " << ns << " and "
          << ns << " x " << data.num_outputs();
        Fail(data, m.str());
      }
      total += ns * (1 + data.num_outputs());
      if (total > kMaxRawSamplesTotal) {
        Fail(data, "more than " + std::to_string(kMaxRawSamplesTotal) +
                       " samples in all, expected at most that");
      }
      if (!hit.force.allFinite()) Fail(data, "force: " + label + ": NaN or Inf samples");
      if (!hit.response.allFinite()) {
        for (int i = 0; i < data.num_outputs(); ++i) {
          if (!hit.response.col(i).allFinite()) {
            Fail(data, "response: " + label + ", output " + Quote(data.outputs[i].name) +
                           ": NaN or Inf samples");
          }
        }
      }
      if ((hit.force.array() == 0.0).all()) {
        Fail(data, "force: " + label + ": all samples are zero, expected an impact");
      }
      for (int i = 0; i < data.num_outputs(); ++i) {
        if (!alive[i] && (hit.response.col(i).array() != 0.0).any()) alive[i] = true;
      }
    }
  }
  for (int i = 0; i < data.num_outputs(); ++i) {
    if (!alive[i]) {
      Fail(data, "response: output " + std::to_string(i + 1) + " " + Quote(data.outputs[i].name) +
                     " is zero in every hit (a dead channel), expected a signal");
    }
  }
}

EstimationSummary EstimateFrf(const RawHammerData& data, const EstimationOptions& options) {
  Validate(data);
  CheckOptions(options);
  const int ns = data.num_samples();
  const int nout = data.num_outputs();
  const int nin = data.num_inputs();
  const double fs = data.sample_rate_hz;
  const double df = fs / ns;
  const int k_nyquist = ns / 2;
  const int k_min = std::max(1, static_cast<int>(std::ceil(options.min_frequency_hz / df - 1e-9)));
  const int k_max = options.max_frequency_hz > 0.0
                        ? std::min(k_nyquist,
                                   static_cast<int>(std::floor(options.max_frequency_hz / df + 1e-9)))
                        : k_nyquist;
  if (k_max < k_min) {
    std::ostringstream m;
    m << "estimation band [" << options.min_frequency_hz << ", " << options.max_frequency_hz
      << "] Hz holds no DFT bin (resolution " << df << " Hz, Nyquist " << fs / 2 << " Hz)";
    Fail(data, m.str());
  }
  const int nk = k_max - k_min + 1;

  EstimationSummary summary;
  summary.frequency_resolution_hz = df;
  summary.added_decay_rate_1_s = options.exp_tau_s > 0.0 ? 1.0 / options.exp_tau_s : 0.0;
  summary.h1.assign(nk, Eigen::MatrixXcd::Zero(nout, nin));
  summary.h2.assign(nk, Eigen::MatrixXcd::Zero(nout, nin));
  std::vector<Eigen::MatrixXd> coherence(nk, Eigen::MatrixXd::Zero(nout, nin));
  summary.hits_used.assign(nin, 0);

  RealFft fft(ns);
  Eigen::VectorXd force_window, exp_window, both;
  const int tail = std::max(1, static_cast<int>(kLeakageTailShare * ns));

  for (int j = 0; j < nin; ++j) {
    const int nh = static_cast<int>(data.hits[j].size());
    std::vector<Eigen::VectorXcd> F(nh, Eigen::VectorXcd(nk));
    std::vector<Eigen::MatrixXcd> X(nh, Eigen::MatrixXcd(nk, nout));
    std::vector<HitDiagnostics> diag(nh);
    double leakage = 0.0;
    int leakage_output = 0;

    for (int h = 0; h < nh; ++h) {
      const HammerHit& hit = data.hits[j][h];
      HitDiagnostics& d = diag[h];
      d.input = j;
      d.hit = h;
      const Pulse pulse = DetectPulse(hit.force, options.pulse_threshold);
      d.peak_force_n = pulse.peak;
      d.impact_time_s = pulse.start / fs;
      const int width = pulse.end - pulse.start + 1;
      d.pulse_width_s = width / fs;
      const int guard = std::max(width, 2);
      double outside = 0.0;
      int outside_index = -1;
      for (int i = 0; i < ns; ++i) {
        if (i >= pulse.start - guard && i <= pulse.end + guard) continue;
        if (std::abs(hit.force(i)) > outside) {
          outside = std::abs(hit.force(i));
          outside_index = i;
        }
      }
      d.second_peak_ratio = outside / std::abs(pulse.peak);
      d.second_peak_time_s = outside_index >= 0 ? outside_index / fs : 0.0;
      const std::string label = HitLabel(data, j, h);
      if (d.second_peak_ratio > options.double_hit_ratio) {
        d.double_hit = true;
        std::ostringstream m;
        m << label << ": double hit (second force peak " << std::setprecision(3)
          << 100.0 * d.second_peak_ratio << " % of the first, at " << d.second_peak_time_s
          << " s; first pulse at " << d.impact_time_s << " s)";
        d.messages.push_back(m.str());
      }
      if (Overloaded(hit.force, FullScale(data.force_full_scale, j), options)) {
        d.force_overload = true;
        d.messages.push_back(label + ": force channel overloaded or clipped");
      }
      for (int i = 0; i < nout; ++i) {
        if (Overloaded(hit.response.col(i), FullScale(data.response_full_scale, i), options)) {
          d.overloaded_outputs.push_back(i);
          d.messages.push_back(label + ": output " + Quote(data.outputs[i].name) +
                               " overloaded or clipped");
        }
      }

      MakeWindows(data, options, pulse, force_window, exp_window);
      both = force_window.cwiseProduct(exp_window);
      fft.Transform(hit.force, both, k_min, F[h]);
      for (int i = 0; i < nout; ++i) {
        fft.Transform(hit.response.col(i), exp_window, k_min, X[h].col(i));
        const double peak = (hit.response.col(i).cwiseProduct(exp_window)).cwiseAbs().maxCoeff();
        const double end = (hit.response.col(i).tail(tail).cwiseProduct(exp_window.tail(tail)))
                               .cwiseAbs().maxCoeff();
        if (peak > 0.0 && end / peak > leakage) {
          leakage = end / peak;
          leakage_output = i;
        }
      }
    }

    // Usable band: where the force autospectrum is within force_band_db of its maximum.
    Eigen::VectorXd force_power = Eigen::VectorXd::Zero(nk);
    for (int h = 0; h < nh; ++h) force_power += F[h].cwiseAbs2();
    const double power_floor = force_power.maxCoeff() * std::pow(10.0, -options.force_band_db / 10.0);
    std::vector<int> usable;
    for (int k = 0; k < nk; ++k) {
      if (force_power(k) >= power_floor) usable.push_back(k);
    }

    // Hit coherence: the upper median over the other hits g of how well g's FRF X_g / F_g predicts
    // this hit's response in the usable band (robust against one bad hit among the references).
    if (nh >= 2) {
      for (int h = 0; h < nh; ++h) {
        std::vector<double> agreement;
        for (int g = 0; g < nh; ++g) {
          if (g == h) continue;
          double residual = 0.0;
          double energy = 0.0;
          for (int k : usable) {
            const Complex ratio = std::norm(F[g](k)) > 0.0 ? F[h](k) / F[g](k) : Complex(0.0);
            for (int i = 0; i < nout; ++i) {
              residual += std::norm(X[h](k, i) - X[g](k, i) * ratio);
              energy += std::norm(X[h](k, i));
            }
          }
          agreement.push_back(energy > 0.0 ? std::clamp(1.0 - residual / energy, 0.0, 1.0) : 0.0);
        }
        std::sort(agreement.begin(), agreement.end());
        diag[h].hit_coherence = agreement[agreement.size() / 2];
        if (diag[h].hit_coherence < options.min_hit_coherence) {
          diag[h].poor_coherence = true;
          std::ostringstream m;
          m << HitLabel(data, j, h) << ": poor coherence with the other hits ("
            << std::setprecision(3) << diag[h].hit_coherence << " < " << options.min_hit_coherence
            << ")";
          diag[h].messages.push_back(m.str());
        }
      }
    }

    std::vector<int> used;
    for (int h = 0; h < nh; ++h) {
      if (!options.exclude_flagged || !diag[h].flagged()) used.push_back(h);
    }
    if (used.empty()) {
      summary.warnings.push_back("input " + std::to_string(j + 1) + " " +
                                 Quote(data.inputs[j].name) +
                                 ": every hit is flagged; all were averaged nevertheless");
      for (int h = 0; h < nh; ++h) used.push_back(h);
    }
    std::vector<bool> is_used(nh, false);
    for (int h : used) is_used[h] = true;
    for (int h = 0; h < nh; ++h) {
      diag[h].rejected = !is_used[h];
      if (diag[h].rejected) summary.rejected_hits.push_back(diag[h]);
      summary.hits.push_back(diag[h]);
    }
    summary.hits_used[j] = static_cast<int>(used.size());

    Eigen::VectorXd gff = Eigen::VectorXd::Zero(nk);
    Eigen::MatrixXcd gfx = Eigen::MatrixXcd::Zero(nk, nout);
    Eigen::MatrixXd gxx = Eigen::MatrixXd::Zero(nk, nout);
    for (int h : used) {
      gff += F[h].cwiseAbs2();
      gfx += F[h].conjugate().asDiagonal() * X[h];
      gxx += X[h].cwiseAbs2();
    }
    int low = 0;
    for (int k = 0; k < nk; ++k) {
      for (int i = 0; i < nout; ++i) {
        const Complex fx = gfx(k, i);
        summary.h1[k](i, j) = gff(k) > 0.0 ? fx / gff(k) : Complex(0.0);
        summary.h2[k](i, j) = std::norm(fx) > 0.0 ? gxx(k, i) / std::conj(fx) : Complex(0.0);
        const double denominator = gff(k) * gxx(k, i);
        const double c = denominator > 0.0 ? std::clamp(std::norm(fx) / denominator, 0.0, 1.0) : 0.0;
        coherence[k](i, j) = c;
      }
    }
    for (int k : usable) {
      for (int i = 0; i < nout; ++i) low += coherence[k](i, j) < options.low_coherence ? 1 : 0;
    }
    const double low_share = static_cast<double>(low) / (static_cast<double>(usable.size()) * nout);
    if (used.size() >= 2 && low_share > options.low_coherence_share) {
      std::ostringstream m;
      m << "input " << j + 1 << " " << Quote(data.inputs[j].name) << ": coherence below "
        << options.low_coherence << " at " << std::setprecision(3) << 100.0 * low_share
        << " % of the points";
      summary.warnings.push_back(m.str());
    }
    if (leakage > kLeakagePeakShare) {
      std::ostringstream m;
      m << "input " << j + 1 << " " << Quote(data.inputs[j].name) << ": output "
        << Quote(data.outputs[leakage_output].name) << " has not decayed at the end of the record ("
        << std::setprecision(3) << 100.0 * leakage
        << " % of its peak in the last 5 %): leakage; use an exponential window";
      summary.warnings.push_back(m.str());
    }
  }

  FrfData& frf = summary.frf;
  frf.frequency_hz.resize(nk);
  for (int k = 0; k < nk; ++k) frf.frequency_hz(k) = (k_min + k) * df;
  frf.frf = options.estimator == FrfEstimator::kH1 ? summary.h1 : summary.h2;
  // The coherence is the ordinary coherence of the hits averaged, written with their number per input
  // (FrfData::averages): the comparison turns it into the coherence of the averaged estimate. One hit's
  // coherence is 1 whatever the noise, so with a single hit on some input none is written.
  const auto single = std::find_if(summary.hits_used.begin(), summary.hits_used.end(), [](int n) { return n < 2; });
  if (single == summary.hits_used.end()) {
    frf.coherence = std::move(coherence);
    frf.averages = summary.hits_used;
  } else {
    const int j = static_cast<int>(single - summary.hits_used.begin());
    summary.warnings.push_back("input " + std::to_string(j + 1) + " " + Quote(data.inputs[j].name) +
                               ": one hit averaged; its coherence tells nothing of the noise, so no coherence is written "
                               "(the noise floor is unknown)");
  }
  frf.quantity = data.quantity;
  frf.outputs = data.outputs;
  frf.inputs = data.inputs;
  frf.frame_origin_W = data.frame_origin_W;
  frf.source = data.source;
  return summary;
}

std::string EstimationSummary::BriefReport() const {
  std::ostringstream s;
  const int nf = frf.num_frequencies();
  s << "FRF estimate from " << (frf.source.empty() ? std::string("raw data") : Quote(frf.source))
    << ": " << frf.num_outputs() << " outputs x " << frf.num_inputs() << " inputs, " << nf
    << " frequencies";
  if (nf > 0) {
    s << " from " << frf.frequency_hz(0) << " to " << frf.frequency_hz(nf - 1) << " Hz";
  }
  s << " (resolution " << frequency_resolution_hz << " Hz), " << ToString(frf.quantity) << "\n";
  if (added_decay_rate_1_s > 0.0) {
    s << "Exponential window: tau = " << 1.0 / added_decay_rate_1_s << " s adds the decay rate "
      << added_decay_rate_1_s << " 1/s, i.e. a damping ratio of";
    for (double f : {10.0, 100.0, 1000.0}) {
      s << " " << std::setprecision(3) << added_decay_rate_1_s / (2.0 * kPi * f) << " at "
        << static_cast<int>(f) << " Hz" << (f < 1000.0 ? "," : "");
    }
    s << "; correct identified modes with zeta = zeta_measured - 1/(tau omega_n)\n";
  } else {
    s << "Exponential window: none\n";
  }
  int total = static_cast<int>(hits.size());
  int used = 0;
  for (int n : hits_used) used += n;
  int flagged = 0;
  for (const HitDiagnostics& d : hits) flagged += d.flagged() ? 1 : 0;
  s << "Hits: " << total << " in all, " << used << " averaged, " << flagged << " flagged, "
    << rejected_hits.size() << " rejected\n";
  for (const HitDiagnostics& d : hits) {
    for (const std::string& m : d.messages) {
      s << "  flag: " << m << (d.rejected ? " [rejected]" : "") << "\n";
    }
  }
  for (const std::string& w : warnings) s << "  warning: " << w << "\n";
  return s.str();
}

double ExponentialWindowAddedDamping(double natural_frequency_hz, double tau_s) {
  if (!(tau_s > 0.0) || !(natural_frequency_hz > 0.0)) {
    std::ostringstream m;
    m << "exponential window correction: tau = " << tau_s << " s, f = " << natural_frequency_hz
      << " Hz, expected both > 0";
    throw InputError(m.str());
  }
  return 1.0 / (tau_s * 2.0 * kPi * natural_frequency_hz);
}

ModalParameters CorrectExponentialWindowDamping(const ModalParameters& measured, double tau_s) {
  ExponentialWindowAddedDamping(measured.natural_frequency_hz, tau_s);
  const double zeta_m = measured.damping_ratio;
  if (!(zeta_m >= 0.0 && zeta_m < 1.0)) {
    std::ostringstream m;
    m << "exponential window correction: damping ratio " << zeta_m << ", expected in [0, 1)";
    throw InputError(m.str());
  }
  const double omega_m = 2.0 * kPi * measured.natural_frequency_hz;
  const double sigma = zeta_m * omega_m - 1.0 / tau_s;
  if (sigma < 0.0) {
    std::ostringstream m;
    m << "exponential window correction: the mode at " << measured.natural_frequency_hz
      << " Hz has damping ratio " << zeta_m << ", below the "
      << 1.0 / (tau_s * omega_m) << " that a window with tau = " << tau_s
      << " s adds; expected a mode identified from data with this window";
    throw InputError(m.str());
  }
  const double omega_d = omega_m * std::sqrt(1.0 - zeta_m * zeta_m);
  const double omega_n = std::hypot(sigma, omega_d);
  return {omega_n / (2.0 * kPi), sigma / omega_n};
}

}  // namespace stagefit::measurement
