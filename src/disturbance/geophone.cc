#include "stagefit/disturbance/geophone.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <sstream>

#include "stagefit/common/error.h"

namespace stagefit::disturbance {

GeophoneModel L4cGeophone() { return {"L-4C", 1.0, 0.28, 276.8, 1.0}; }

GeophoneModel L22Geophone() { return {"L-22", 2.0, 0.57, 88.0, 1.0}; }

GeophoneModel GeophoneByName(std::string_view name, std::string_view context) {
  std::string key;
  for (char c : name) {
    if (c != '-') key += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  }
  if (key == "L4C") return L4cGeophone();
  if (key == "L22" || key == "L22D") return L22Geophone();
  throw InputError(std::string(context) + ": geophone '" + std::string(name) +
                   "', expected L-4C or L-22");
}

void ValidateGeophone(const GeophoneModel& geophone, std::string_view context) {
  auto check = [&](double value, const char* field, const char* unit) {
    if (!(std::isfinite(value) && value > 0.0)) {
      std::ostringstream message;
      message << context << ": geophone '" << geophone.name << "': " << field << " = " << value
              << " " << unit << ", expected a finite value > 0";
      throw InputError(message.str());
    }
  };
  check(geophone.natural_frequency_hz, "natural_frequency_hz", "Hz");
  check(geophone.damping_ratio, "damping_ratio", "");
  check(geophone.generator_constant_v_s_m, "generator_constant", "V/(m/s)");
  check(geophone.amplifier_gain, "amplifier_gain", "V/V");
}

std::complex<double> CalcGeophoneResponse(const GeophoneModel& geophone, double frequency_hz) {
  const std::complex<double> s(0.0, 2.0 * M_PI * frequency_hz);
  const double w0 = 2.0 * M_PI * geophone.natural_frequency_hz;
  return geophone.amplifier_gain * geophone.generator_constant_v_s_m * s * s /
         (s * s + 2.0 * geophone.damping_ratio * w0 * s + w0 * w0);
}

double CalcGeophoneDisplacementGain2(const GeophoneModel& geophone, double frequency_hz) {
  const double w = 2.0 * M_PI * frequency_hz;
  return std::norm(CalcGeophoneResponse(geophone, frequency_hz)) * w * w;
}

Spectrum CalcGroundDisplacementPsd(const Spectrum& voltage_psd, const GeophoneModel& geophone) {
  ValidateGeophone(geophone, "ground motion correction");
  STAGEFIT_ASSERT(voltage_psd.frequency_hz.size() == voltage_psd.psd.size(), "spectrum sizes");
  std::vector<Eigen::Index> kept;
  for (Eigen::Index k = 0; k < voltage_psd.psd.size(); ++k) {
    if (voltage_psd.frequency_hz[k] > 0.0) kept.push_back(k);
  }
  Spectrum out = voltage_psd;
  out.frequency_hz.resize(static_cast<Eigen::Index>(kept.size()));
  out.psd.resize(static_cast<Eigen::Index>(kept.size()));
  for (size_t i = 0; i < kept.size(); ++i) {
    const double f = voltage_psd.frequency_hz[kept[i]];
    out.frequency_hz[i] = f;
    out.psd[i] = voltage_psd.psd[kept[i]] / CalcGeophoneDisplacementGain2(geophone, f);
  }
  return out;
}

}  // namespace stagefit::disturbance
