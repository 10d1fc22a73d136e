#include "stagefit/measurement/frf_data.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

#include "stagefit/common/error.h"
#include "stagefit/common/utf8.h"

namespace stagefit::measurement {
namespace {

[[noreturn]] void Fail(const FrfData& data, const std::string& message) {
  throw InputError(data.where() + ": " + message);
}

bool IsFinite(const Eigen::Vector3d& v) { return v.allFinite(); }

void ValidateChannels(const FrfData& data, const std::vector<ChannelGeometry>& channels,
                      const char* kind) {
  std::set<std::string> names;
  for (std::size_t i = 0; i < channels.size(); ++i) {
    const ChannelGeometry& c = channels[i];
    const std::string label = std::string(kind) + " " + std::to_string(i + 1);
    if (c.name.empty()) Fail(data, label + ": empty channel name, expected a name");
    if (!IsValidUtf8(c.name)) {
      Fail(data, label + ": channel name '" + EscapeNonUtf8(c.name) +
                     "' is not valid UTF-8, expected UTF-8 text");
    }
    if (!names.insert(c.name).second) {
      Fail(data, label + ": channel name '" + c.name + "' is used twice, expected unique names");
    }
    const double norm = c.direction_W.norm();
    if (!IsFinite(c.direction_W)) {
      Fail(data, label + " '" + c.name + "': direction is not finite");
    }
    if (c.has_geometry()) {
      if (!IsFinite(c.position_W)) {
        Fail(data, label + " '" + c.name + "': position is not finite");
      }
      if (std::abs(norm - 1.0) > kUnitDirectionTolerance) {
        std::ostringstream m;
        m << label << " '" << c.name << "': direction has length " << norm
          << ", expected a unit vector";
        Fail(data, m.str());
      }
    } else if (norm != 0.0 && std::abs(norm - 1.0) > kUnitDirectionTolerance) {
      std::ostringstream m;
      m << label << " '" << c.name << "': direction has length " << norm
        << ", expected a unit vector or zero (unknown)";
      Fail(data, m.str());
    }
  }
}

}  // namespace

std::optional<FrfQuantity> ParseFrfQuantity(const std::string& text) {
  if (text == "accelerance") return FrfQuantity::kAccelerance;
  if (text == "mobility") return FrfQuantity::kMobility;
  if (text == "receptance" || text == "compliance") return FrfQuantity::kReceptance;
  return std::nullopt;
}

std::string ToString(FrfQuantity quantity) {
  switch (quantity) {
    case FrfQuantity::kAccelerance:
      return "accelerance";
    case FrfQuantity::kMobility:
      return "mobility";
    case FrfQuantity::kReceptance:
      return "receptance";
  }
  STAGEFIT_ASSERT(false, "unknown FrfQuantity " << static_cast<int>(quantity));
}

double EstimateCoherence(double g2, int n) {
  if (n == 0 || g2 >= 1.0) return g2;
  if (!(g2 > 0.0)) return 0.0;
  return std::clamp((n * g2 - 1.0) / ((n - 1) * g2), 0.0, 1.0);
}

double FrfData::estimate_coherence(int k, int o, int i) const {
  return EstimateCoherence(coherence[k](o, i), averages.empty() ? 0 : averages[i]);
}

void Validate(const FrfData& data) {
  const int nf = data.num_frequencies();
  const int nout = data.num_outputs();
  const int nin = data.num_inputs();
  if (nf == 0) Fail(data, "freq_hz: no frequencies, expected at least one");
  if (nout == 0) Fail(data, "no output channels, expected at least one");
  if (nin == 0) Fail(data, "no input channels, expected at least one");
  for (int k = 0; k < nf; ++k) {
    const double f = data.frequency_hz[k];
    std::ostringstream m;
    m.precision(17);
    if (!std::isfinite(f) || f <= 0.0) {
      m << "freq_hz[" << k + 1 << "] = " << f << " Hz, expected a finite frequency > 0";
      Fail(data, m.str());
    }
    if (k > 0 && !(f > data.frequency_hz[k - 1])) {
      m << "freq_hz[" << k + 1 << "] = " << f << " Hz is not above freq_hz[" << k << "] = "
        << data.frequency_hz[k - 1] << " Hz, expected strictly increasing frequencies";
      Fail(data, m.str());
    }
  }
  if (static_cast<int>(data.frf.size()) != nf) {
    Fail(data, "frf: " + std::to_string(data.frf.size()) + " frequency slices, expected " +
                   std::to_string(nf) + " (one per frequency)");
  }
  for (int k = 0; k < nf; ++k) {
    const Eigen::MatrixXcd& h = data.frf[k];
    if (h.rows() != nout || h.cols() != nin) {
      Fail(data, "frf at frequency " + std::to_string(k + 1) + ": size " +
                     std::to_string(h.rows()) + " x " + std::to_string(h.cols()) + ", expected " +
                     std::to_string(nout) + " x " + std::to_string(nin));
    }
    for (int i = 0; i < nout; ++i) {
      for (int j = 0; j < nin; ++j) {
        if (!std::isfinite(h(i, j).real()) || !std::isfinite(h(i, j).imag())) {
          std::ostringstream m;
          m << "frf(" << i + 1 << ", " << j + 1 << ", " << k + 1 << ") = " << h(i, j)
            << " at " << data.frequency_hz[k] << " Hz, expected a finite value";
          Fail(data, m.str());
        }
      }
    }
  }
  if (data.has_coherence()) {
    if (static_cast<int>(data.coherence.size()) != nf) {
      Fail(data, "coherence: " + std::to_string(data.coherence.size()) +
                     " frequency slices, expected " + std::to_string(nf));
    }
    for (int k = 0; k < nf; ++k) {
      const Eigen::MatrixXd& c = data.coherence[k];
      if (c.rows() != nout || c.cols() != nin) {
        Fail(data, "coherence at frequency " + std::to_string(k + 1) + ": size " +
                       std::to_string(c.rows()) + " x " + std::to_string(c.cols()) +
                       ", expected " + std::to_string(nout) + " x " + std::to_string(nin));
      }
      for (int i = 0; i < nout; ++i) {
        for (int j = 0; j < nin; ++j) {
          const double g = c(i, j);
          if (!(g >= 0.0 && g <= 1.0)) {
            std::ostringstream m;
            m << "coherence(" << i + 1 << ", " << j + 1 << ", " << k + 1 << ") = " << g
              << ", expected a value in [0, 1]";
            Fail(data, m.str());
          }
        }
      }
    }
  }
  if (!data.averages.empty()) {
    if (static_cast<int>(data.averages.size()) != nin) {
      Fail(data, "num_averages: " + std::to_string(data.averages.size()) + " counts, expected " + std::to_string(nin) +
                     " (one per input)");
    }
    for (int j = 0; j < nin; ++j) {
      if (data.averages[j] < 2) {
        Fail(data, "num_averages(" + std::to_string(j + 1) + ") = " + std::to_string(data.averages[j]) +
                       ", expected a count >= 2 (the ordinary coherence of one record is 1 and tells nothing of the noise)");
      }
    }
    if (!data.has_coherence()) Fail(data, "num_averages: given without coherence, expected coherence with it");
  }
  ValidateChannels(data, data.outputs, "output");
  ValidateChannels(data, data.inputs, "input");
  if (data.frame_origin_W && !data.frame_origin_W->allFinite()) {
    Fail(data, "frame_origin: not finite, expected three finite coordinates in m");
  }
  std::vector<bool> output_alive(nout, false);
  std::vector<bool> input_alive(nin, false);
  for (int k = 0; k < nf; ++k) {
    for (int i = 0; i < nout; ++i) {
      for (int j = 0; j < nin; ++j) {
        if (data.frf[k](i, j) != std::complex<double>(0.0, 0.0)) {
          output_alive[i] = true;
          input_alive[j] = true;
        }
      }
    }
  }
  for (int i = 0; i < nout; ++i) {
    if (!output_alive[i]) {
      Fail(data, "output channel " + std::to_string(i + 1) + " '" + data.outputs[i].name +
                     "' is dead: its FRF is exactly zero for every input and frequency "
                     "(check the sensor and its cable, or remove the channel)");
    }
  }
  for (int j = 0; j < nin; ++j) {
    if (!input_alive[j]) {
      Fail(data, "input " + std::to_string(j + 1) + " '" + data.inputs[j].name +
                     "' is dead: its FRF is exactly zero for every output and frequency "
                     "(check the hammer channel, or remove the input)");
    }
  }
}

}  // namespace stagefit::measurement
