#pragma once
// Time signals with a prescribed PSD: a sum of cosines at the record's Fourier frequencies with
// deterministic amplitudes and random phases, evaluated with one inverse FFT (Preumont, Random
// Vibration and Spectral Analysis, section 12.11).

#include <Eigen/Dense>

#include <cstdint>
#include <functional>
#include <random>
#include <string>

namespace stagefit::disturbance {

/// A target one-sided PSD tabulated at arbitrary frequencies. Between two points it is interpolated
/// linearly in log(f)-log(S) (linearly where f or S is zero); outside [front, back] it is zero.
struct PsdTable {
  Eigen::VectorXd frequency_hz;  ///< M >= 1 points, strictly increasing, >= 0, Hz
  Eigen::VectorXd psd;           ///< M values >= 0, U^2/Hz
  std::string name = "psd";      ///< names the table in error messages
};

/// Throws InputError (naming table.name, the field and the index) unless the sizes agree, M >= 1,
/// frequencies are finite, >= 0 and strictly increasing, and PSD values are finite and >= 0.
void ValidatePsdTable(const PsdTable& table);

/// The interpolated PSD at f (see PsdTable), U^2/Hz. Precondition: a valid table.
double InterpolatePsd(const PsdTable& table, double frequency_hz);

/// Length and rate of a synthesised record.
struct SynthesisOptions {
  double duration_s = 10.0;         ///< T > 0, s (or metres of scan for spatial records)
  double sample_rate_hz = 1000.0;   ///< fs > 0, Hz (or samples/m)
};

/// Number of samples N = round(T fs) of a synthesised record; throws InputError (naming `context`)
/// unless T and fs are finite and > 0 and N >= 2.
int SynthesisSampleCount(const SynthesisOptions& options, const std::string& context);

/// Synthesises N = round(T fs) samples x[n] (time n / fs):
///   x[n] = sum_{k=1}^{K} A_k cos(2 pi f_k n / fs + phi_k),   f_k = k df,  df = fs / N,
///   A_k = sqrt(2 S(f_k) df),   K = ceil(N/2) - 1 (the DC and Nyquist terms are zero),
/// phi_k independent and uniform on [0, 2 pi), drawn in order k = 1..K from `rng` as
/// 2 pi (rng() >> 11) 2^-53 (so the phases are reproducible on every platform for a given seed).
/// The signal is periodic with period T; its mean square is exactly sum_k S(f_k) df, the rectangle-rule
/// integral of S over (0, fs/2), and its Welch PSD estimates S. Computed as one inverse real FFT of
/// X_k = (A_k / 2) e^{j phi_k}. Throws InputError for an invalid table or options.
///
/// `gain2`, when given, multiplies the interpolated PSD at every f_k: S(f_k) -> gain2(f_k) S(f_k)
/// (e.g. CalcGeophoneDisplacementGain2 to synthesise a geophone's voltage from a ground displacement
/// PSD; applied at each synthesis frequency, not at the table's points, so the interpolation stays
/// on the smooth physical spectrum).
Eigen::VectorXd SynthesiseSignal(const PsdTable& target, const SynthesisOptions& options,
                                 std::mt19937_64& rng,
                                 const std::function<double(double)>& gain2 = nullptr);

}  // namespace stagefit::disturbance
