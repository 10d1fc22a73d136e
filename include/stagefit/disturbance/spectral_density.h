#pragma once
// Power spectral densities by Welch's method (averaged, windowed, overlapped periodograms), computed
// with FFTW3.
//
// Conventions, used by every function of the disturbance layer:
// - One-sided densities per unit of frequency: for a record x in unit U sampled at fs, the PSD is in
//   U^2/Hz on the bins f_k = k fs / L, k = 0..floor(L/2), L the segment length, and
//     sum_k Pxx(f_k) df = variance of x   (df = fs / L; Parseval, exact for a rectangular window).
//   The amplitude spectral density (ASD) is sqrt(PSD), in U/sqrt(Hz).
// - For spatial records (a position axis instead of time) the same functions apply with the "sample
//   rate" in samples per metre and "frequency" in cycles per metre; the PSD is then in U^2/(1/m).
// - Periodogram of one segment x_m (detrended, then multiplied by the window w):
//     P(f_k) = c_k |sum_n w[n] x_m[n] e^{-j 2 pi k n / L}|^2 / (fs sum_n w[n]^2),
//   c_k = 1 for the DC bin and the Nyquist bin (L even), 2 otherwise; the estimate is the mean over
//   the segments.

#include <Eigen/Dense>

#include <string>
#include <string_view>

namespace stagefit::disturbance {

/// Data windows. Hann is the default; flat-top keeps amplitudes of lines, Blackman-Harris keeps
/// leakage 92 dB down (for steep spectra), rectangular makes Parseval exact.
enum class Window { kHann, kHamming, kBlackmanHarris, kFlatTop, kRectangular };

/// What is removed from each segment before windowing.
enum class Detrend { kNone, kMean, kLinear };

/// "hann", "hamming", "blackman-harris", "flat-top", "rectangular" (case-sensitive). Throws
/// InputError naming `context` for anything else.
Window ParseWindow(std::string_view text, std::string_view context);
/// "none", "mean", "linear". Throws InputError naming `context` for anything else.
Detrend ParseDetrend(std::string_view text, std::string_view context);
std::string_view WindowName(Window window);
std::string_view DetrendName(Detrend detrend);

/// The L samples of a periodic ("DFT-even") window, e.g. Hann w[n] = 0.5 - 0.5 cos(2 pi n / L).
/// Requires L >= 1.
Eigen::VectorXd CalcWindow(Window window, int length);

/// How a Welch estimate is made. The segment length L is, in order of precedence:
/// `segment_length` if > 0; else ceil(fs / resolution_hz) if resolution_hz > 0; else the largest L
/// giving `default_averages` segments with the chosen overlap.
struct WelchOptions {
  int segment_length = 0;       ///< samples per segment; 0 = derive it
  double resolution_hz = 0.0;   ///< wanted bin spacing fs / L, Hz (cycles/m for spatial records)
  int default_averages = 8;     ///< segments used when neither of the above is given
  double overlap = 0.5;         ///< fraction of a segment shared with the next, in [0, 1)
  Window window = Window::kHann;
  Detrend detrend = Detrend::kMean;
};

/// A one-sided PSD estimate and what is needed to judge it.
struct Spectrum {
  Eigen::VectorXd frequency_hz;  ///< floor(L/2)+1 bins, 0 .. fs/2, Hz (or cycles/m)
  Eigen::VectorXd psd;           ///< same size, U^2/Hz (or U^2/(1/m))
  double sample_rate_hz = 0.0;   ///< fs of the record, Hz (or samples/m)
  int segment_length = 0;        ///< L, samples
  int averages = 0;              ///< number of segments averaged
  double resolution_hz = 0.0;    ///< bin spacing fs / L
  double enbw_hz = 0.0;          ///< equivalent noise bandwidth fs sum(w^2) / (sum w)^2
  /// Equivalent degrees of freedom nu of the estimate at bins other than DC and Nyquist (those have
  /// nu / 2): nu = 2 K^2 / (K + 2 sum_{l=1}^{K-1} (K - l) rho(l)), with K the averages and
  /// rho(l) = (sum_n w[n] w[n + l S])^2 / (sum_n w[n]^2)^2 the correlation of periodograms whose
  /// segments are l steps S apart (Welch 1967). nu = 2K without overlap.
  double degrees_of_freedom = 0.0;
};

/// Welch PSD of `x` (N samples in unit U, sampled at `sample_rate_hz`), as defined above.
/// `record` and `field` name the data in error messages (e.g. "ground.csv", "voltage").
/// Throws InputError when fs <= 0 or not finite, when x holds NaN or Inf (naming the first bad
/// sample), when the options are out of range, or when N is shorter than one segment (the message
/// gives the duration needed for the requested resolution).
Spectrum EstimatePsd(const Eigen::VectorXd& x, double sample_rate_hz, const WelchOptions& options,
                     std::string_view record, std::string_view field);

/// Welch cross-spectral density of two records of equal length.
struct CrossSpectrum {
  Eigen::VectorXd frequency_hz;  ///< as in Spectrum
  Eigen::VectorXcd csd;          ///< one-sided G_xy = c_k mean(conj(X) Y) / (fs sum w^2), U_x U_y/Hz
  Eigen::VectorXd psd_x;         ///< G_xx, U_x^2/Hz
  Eigen::VectorXd psd_y;         ///< G_yy, U_y^2/Hz
  Eigen::VectorXd coherence;     ///< |G_xy|^2 / (G_xx G_yy), 0..1 (0 where G_xx G_yy = 0)
  int averages = 0;
};

/// Cross-spectrum of x and y (same size N) with the same segmenting as EstimatePsd. The estimate of
/// the FRF from x to y is csd / psd_x (H1). Throws InputError as EstimatePsd, and when the sizes
/// differ.
CrossSpectrum EstimateCrossSpectrum(const Eigen::VectorXd& x, const Eigen::VectorXd& y,
                                    double sample_rate_hz, const WelchOptions& options,
                                    std::string_view record, std::string_view field_x,
                                    std::string_view field_y);

/// Variance in a band: sum of psd(f_k) df over the bins with f_lo <= f_k <= f_hi (the rectangle rule
/// that makes Parseval exact), in U^2. Requires the bins to be evenly spaced (a Spectrum's are).
double IntegratePsd(const Spectrum& spectrum, double min_frequency_hz, double max_frequency_hz);

/// Bounds of the ratio estimate/true PSD that hold with probability `confidence` for a Gaussian
/// record: [chi2_nu((1-c)/2) / nu, chi2_nu((1+c)/2) / nu], chi2_nu(p) the chi-square quantile with
/// nu degrees of freedom (nu may be fractional). Requires nu > 0 and 0 < confidence < 1.
struct PsdConfidenceBand {
  double lower = 0.0;
  double upper = 0.0;
};
PsdConfidenceBand CalcPsdConfidenceBand(double degrees_of_freedom, double confidence);

/// The chi-square quantile chi2_nu(p): the x with P(chi2_nu <= x) = p. Requires nu > 0, 0 < p < 1.
double CalcChiSquareQuantile(double degrees_of_freedom, double probability);

}  // namespace stagefit::disturbance
