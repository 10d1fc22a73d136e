#include "stagefit/compare/mode_pairing.h"

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

#include "stagefit/common/error.h"
#include "stagefit/model/assembled_model.h"
#include "stagefit/model/modes.h"

namespace stagefit::compare {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

void CheckOptions(const ModeIdentificationOptions& options) {
  if (!(options.min_prominence >= 1.0) || !std::isfinite(options.min_prominence)) {
    throw InputError("mode identification: min prominence " + std::to_string(options.min_prominence) +
                     ", expected a finite ratio >= 1");
  }
  if (!(options.rotation_length_m > 0.0) || !std::isfinite(options.rotation_length_m)) {
    throw InputError("mode identification: rotation length " + std::to_string(options.rotation_length_m) +
                     " m, expected > 0");
  }
  if (!(options.noise_prominence >= 0.0) || !std::isfinite(options.noise_prominence)) {
    throw InputError("mode identification: noise prominence " + std::to_string(options.noise_prominence) +
                     ", expected a finite value >= 0");
  }
  if (!(options.min_mac >= 0.0 && options.min_mac <= 1.0)) {
    throw InputError("mode identification: min MAC " + std::to_string(options.min_mac) +
                     ", expected a value in [0, 1]");
  }
}

// Frequency where s crosses `level` between samples a and b (linear interpolation).
double Crossing(const Eigen::VectorXd& f, const Eigen::VectorXd& s, int a, int b, double level) {
  const double t = (level - s(a)) / (s(b) - s(a));
  return f(a) + t * (f(b) - f(a));
}

std::vector<Eigen::MatrixXcd> Scaled(const Comparison& comparison, const std::vector<Eigen::MatrixXcd>& frf,
                                     double length_m) {
  if (comparison.space() == ComparisonSpace::kRaw) return frf;
  // Rotations (rows, and in compliance space columns: torques) with a lever arm, so that they weigh
  // like translations in the shapes. Bodies space: outputs <body>.Dx..Rz, inputs raw forces.
  Eigen::VectorXd s = Eigen::VectorXd::Ones(comparison.num_outputs());
  for (int o = 0; o < s.size(); ++o) {
    if (o % 6 >= 3) s(o) = length_m;
  }
  Eigen::VectorXd t = Eigen::VectorXd::Ones(comparison.num_inputs());
  if (comparison.space() == ComparisonSpace::kCompliance) t.tail<3>().setConstant(length_m);
  std::vector<Eigen::MatrixXcd> out;
  out.reserve(frf.size());
  for (const auto& H : frf) out.push_back(s.asDiagonal() * H * t.asDiagonal());
  return out;
}

}  // namespace

Eigen::MatrixXd CalcCmif(const std::vector<Eigen::MatrixXcd>& frf) {
  if (frf.empty()) return Eigen::MatrixXd();
  const int ns = static_cast<int>(std::min(frf[0].rows(), frf[0].cols()));
  Eigen::MatrixXd sigma(static_cast<int>(frf.size()), ns);
  for (size_t k = 0; k < frf.size(); ++k) {
    Eigen::JacobiSVD<Eigen::MatrixXcd> svd(frf[k]);
    sigma.row(k) = svd.singularValues().head(ns).transpose();
  }
  return sigma;
}

std::vector<IdentifiedMode> IdentifyModes(const Eigen::VectorXd& frequency_hz,
                                          const std::vector<Eigen::MatrixXcd>& frf,
                                          const ModeIdentificationOptions& options, const Eigen::VectorXd& snr) {
  CheckOptions(options);
  const int nf = static_cast<int>(frequency_hz.size());
  if (static_cast<int>(frf.size()) != nf) {
    throw InputError("mode identification: " + std::to_string(frf.size()) + " FRF matrices for " +
                     std::to_string(nf) + " frequencies, expected one per frequency");
  }
  if (snr.size() != 0 && snr.size() != nf) {
    throw InputError("mode identification: " + std::to_string(snr.size()) + " SNR values for " +
                     std::to_string(nf) + " frequencies, expected one per frequency or none");
  }
  std::vector<IdentifiedMode> modes;
  if (nf < 3) return modes;
  const Eigen::VectorXd s = CalcCmif(frf).col(0);
  for (int k = 1; k + 1 < nf; ++k) {
    if (!(s(k) > s(k - 1) && s(k) >= s(k + 1))) continue;
    int left = k, right = k;
    double left_base = s(k), right_base = s(k);
    for (int j = k - 1; j >= 0 && s(j) <= s(k); --j) {
      left_base = std::min(left_base, s(j));
      left = j;
    }
    for (int j = k + 1; j < nf && s(j) <= s(k); ++j) {
      right_base = std::min(right_base, s(j));
      right = j;
    }
    const double base = std::max(left_base, right_base);
    if (!(base > 0.0) || s(k) / base < options.min_prominence) continue;
    if (snr.size() != 0 && !(std::log(s(k) / base) >= options.noise_prominence / snr(k))) continue;

    IdentifiedMode mode;
    mode.frequency_index = k;
    mode.peak_singular_value = s(k);
    // Parabolic refinement of ln sigma on ln f.
    const double x0 = std::log(frequency_hz(k - 1)), x1 = std::log(frequency_hz(k)),
                 x2 = std::log(frequency_hz(k + 1));
    const double y0 = std::log(s(k - 1)), y1 = std::log(s(k)), y2 = std::log(s(k + 1));
    const double d01 = (y1 - y0) / (x1 - x0), d12 = (y2 - y1) / (x2 - x1);
    const double curvature = (d12 - d01) / (x2 - x0);
    double x_peak = x1;
    if (curvature < 0.0) x_peak = std::clamp(0.5 * (x0 + x1) - d01 / (2.0 * curvature), x0, x2);
    mode.frequency_hz = std::exp(x_peak);
    // Half-power points, searched within the peak's bases.
    const double level = s(k) / std::sqrt(2.0);
    double f1 = kNaN, f2 = kNaN;
    for (int j = k - 1; j >= left; --j) {
      if (s(j) < level) {
        f1 = Crossing(frequency_hz, s, j, j + 1, level);
        break;
      }
    }
    for (int j = k + 1; j <= right; ++j) {
      if (s(j) < level) {
        f2 = Crossing(frequency_hz, s, j - 1, j, level);
        break;
      }
    }
    mode.damping_ratio = (f2 - f1) / (2.0 * mode.frequency_hz);
    Eigen::JacobiSVD<Eigen::MatrixXcd> svd(frf[k], Eigen::ComputeThinU);
    Eigen::VectorXcd u = svd.matrixU().col(0);
    Eigen::Index largest = 0;
    u.cwiseAbs().maxCoeff(&largest);
    if (std::abs(u(largest)) > 0.0) u *= std::conj(u(largest)) / std::abs(u(largest));
    mode.shape = u;
    modes.push_back(mode);
  }
  return modes;
}

double CalcMac(const Eigen::VectorXcd& a, const Eigen::VectorXcd& b) {
  const double aa = a.squaredNorm(), bb = b.squaredNorm();
  if (a.size() != b.size() || aa == 0.0 || bb == 0.0) return 0.0;
  return std::norm(a.dot(b)) / (aa * bb);
}

ModePairing PairModes(const Comparison& comparison, const std::vector<Eigen::MatrixXcd>& model_frf,
                      const model::ModelSpec& spec, const ModeIdentificationOptions& options) {
  CheckOptions(options);
  if (static_cast<int>(model_frf.size()) != comparison.num_frequencies()) {
    throw InputError("mode pairing: the model FRF has " + std::to_string(model_frf.size()) +
                     " frequencies, expected the comparison's " + std::to_string(comparison.num_frequencies()));
  }
  ModePairing pairing;
  const double L = options.rotation_length_m;
  std::vector<Eigen::MatrixXcd> corrected;
  const std::vector<Eigen::MatrixXcd> measured = Scaled(comparison, comparison.MeasuredFor(spec, &corrected), L);
  Eigen::VectorXd snr;  // of the measured sigma_1: the SNR of the used element that dominates it
  if (comparison.weights_are_snr()) {
    snr.resize(comparison.num_frequencies());
    for (int k = 0; k < comparison.num_frequencies(); ++k) {
      const Eigen::MatrixXd& w = comparison.weights()[k];
      double largest = -1.0;
      snr(k) = 0.0;
      for (const ElementIndex& e : comparison.used_elements()) {
        const double magnitude = std::abs(measured[k](e.output, e.input));
        if (w(e.output, e.input) > 0.0 && magnitude > largest) {
          largest = magnitude;
          snr(k) = w(e.output, e.input);
        }
      }
    }
  }
  pairing.measured = IdentifyModes(comparison.frequency_hz(), measured, options, snr);
  pairing.model = IdentifyModes(comparison.frequency_hz(), Scaled(comparison, model_frf, L), options);

  const auto assembled = model::AssembledModel::Assemble(spec, "model '" + spec.name + "'");
  const model::ModalAnalysis modal = model::CalcModes(assembled);
  for (auto& m : pairing.model) {
    double best = std::numeric_limits<double>::infinity();
    for (size_t j = 0; j < modal.modes.size(); ++j) {
      const double distance = std::abs(std::log(modal.modes[j].frequency_hz / m.frequency_hz));
      if (distance < best) {
        best = distance;
        m.model_mode = static_cast<int>(j);
      }
    }
    if (m.model_mode >= 0) {
      const model::Mode& mode = modal.modes[m.model_mode];
      m.model_frequency_hz = mode.frequency_hz;
      m.model_damping_ratio = mode.damping_ratio;
      if (mode.dominant_dof >= 0) m.dominant_dof = assembled.dof_names()[mode.dominant_dof];
    }
  }

  const int nm = static_cast<int>(pairing.measured.size());
  const int nk = static_cast<int>(pairing.model.size());
  pairing.mac.resize(nm, nk);
  std::vector<std::pair<double, std::pair<int, int>>> candidates;
  for (int a = 0; a < nm; ++a) {
    for (int b = 0; b < nk; ++b) {
      pairing.mac(a, b) = CalcMac(pairing.measured[a].shape, pairing.model[b].shape);
      if (pairing.mac(a, b) >= options.min_mac) candidates.push_back({pairing.mac(a, b), {a, b}});
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const auto& x, const auto& y) {
    if (x.first != y.first) return x.first > y.first;
    return x.second < y.second;
  });
  std::vector<bool> used_a(nm, false), used_b(nk, false);
  for (const auto& c : candidates) {
    const int a = c.second.first, b = c.second.second;
    if (used_a[a] || used_b[b]) continue;
    used_a[a] = used_b[b] = true;
    ModePair pair;
    pair.measured = a;
    pair.model = b;
    pair.mac = c.first;
    pair.frequency_error =
        (pairing.model[b].frequency_hz - pairing.measured[a].frequency_hz) / pairing.measured[a].frequency_hz;
    pair.damping_difference = pairing.model[b].damping_ratio - pairing.measured[a].damping_ratio;
    pairing.pairs.push_back(pair);
  }
  std::sort(pairing.pairs.begin(), pairing.pairs.end(),
            [](const ModePair& x, const ModePair& y) { return x.measured < y.measured; });
  for (int a = 0; a < nm; ++a) if (!used_a[a]) pairing.unpaired_measured.push_back(a);
  for (int b = 0; b < nk; ++b) if (!used_b[b]) pairing.unpaired_model.push_back(b);
  return pairing;
}

std::string ModePairing::BriefReport() const {
  std::ostringstream out;
  char line[256];
  std::snprintf(line, sizeof line, "mode pairing: %zu measured, %zu model, %zu pairs\n", measured.size(),
                model.size(), pairs.size());
  out << line;
  if (!pairs.empty()) {
    std::snprintf(line, sizeof line, "  %10s %10s %8s %9s %9s %6s   %s\n", "f_meas[Hz]", "f_model[Hz]", "df[%]",
                  "zeta_meas", "zeta_mod", "MAC", "model mode (dominant DoF)");
    out << line;
    for (const auto& p : pairs) {
      const auto& a = measured[p.measured];
      const auto& b = model[p.model];
      std::snprintf(line, sizeof line, "  %10.2f %10.2f %+8.2f %8.2f%% %8.2f%% %6.3f   #%d %s\n", a.frequency_hz,
                    b.frequency_hz, 100 * p.frequency_error, 100 * a.damping_ratio, 100 * b.damping_ratio, p.mac,
                    b.model_mode + 1, b.dominant_dof.c_str());
      out << line;
    }
  }
  for (int a : unpaired_measured) {
    std::snprintf(line, sizeof line, "  unpaired measured mode at %.2f Hz (zeta %.2f %%)\n", measured[a].frequency_hz,
                  100 * measured[a].damping_ratio);
    out << line;
  }
  for (int b : unpaired_model) {
    std::snprintf(line, sizeof line, "  unpaired model mode at %.2f Hz (zeta %.2f %%, #%d %s)\n",
                  model[b].frequency_hz, 100 * model[b].damping_ratio, model[b].model_mode + 1,
                  model[b].dominant_dof.c_str());
    out << line;
  }
  return out.str();
}

}  // namespace stagefit::compare
