#pragma once
// A set of measured (or model) frequency responses with the geometry of its channels (SPEC §3).

#include <Eigen/Core>

#include <complex>
#include <optional>
#include <string>
#include <vector>

namespace stagefit::measurement {

/// What an FRF relates: output/input at s = j*omega (SPEC §1).
enum class FrfQuantity {
  kAccelerance,  ///< m/s^2/N (rad/s^2/Nm for rotations)
  kMobility,     ///< m/s/N
  kReceptance,   ///< m/N (rad/Nm); "compliance" is read as receptance
};

/// "accelerance" | "mobility" | "receptance" | "compliance"; nullopt otherwise.
std::optional<FrfQuantity> ParseFrfQuantity(const std::string& text);
std::string ToString(FrfQuantity quantity);

/// A sensor (output) or an impact (input): where it sits and which way it measures or pushes.
struct ChannelGeometry {
  std::string name;
  std::string body;                                  ///< body carrying it; empty = geometry unknown
  Eigen::Vector3d position_W = Eigen::Vector3d::Zero();   ///< m, in W at rest
  Eigen::Vector3d direction_W = Eigen::Vector3d::Zero();  ///< unit vector in W
  bool has_geometry() const { return !body.empty(); }
};

/// FRFs H(f) of shape Nout x Nin at Nf frequencies.
struct FrfData {
  Eigen::VectorXd frequency_hz;                          ///< Nf, strictly increasing, Hz
  std::vector<Eigen::MatrixXcd> frf;                     ///< Nf matrices, each Nout x Nin
  FrfQuantity quantity = FrfQuantity::kAccelerance;
  std::vector<Eigen::MatrixXd> coherence;                ///< empty, or Nf matrices Nout x Nin in [0, 1]
  /// Empty: `coherence` is that of the FRF estimate itself, |H|^2 / (|H|^2 + sigma^2) with sigma^2 the
  /// estimate's noise variance (as `synthesize` writes it). Else one count per input (>= 2): the number
  /// of hits (records) averaged for it, and `coherence` is their ordinary coherence, as `estimate` and
  /// modal-test systems write it. EstimateCoherence() turns the one into the other.
  std::vector<int> averages;
  std::vector<ChannelGeometry> outputs;                  ///< Nout
  std::vector<ChannelGeometry> inputs;                   ///< Nin
  std::optional<Eigen::Vector3d> frame_origin_W;         ///< origin of {X} in W, if the file gives it
  std::string source;                                    ///< file it came from (for messages)

  int num_frequencies() const { return static_cast<int>(frequency_hz.size()); }
  int num_outputs() const { return static_cast<int>(outputs.size()); }
  int num_inputs() const { return static_cast<int>(inputs.size()); }
  bool has_coherence() const { return !coherence.empty(); }
  /// The coherence of the FRF estimate at frequency k, output o, input i (EstimateCoherence()).
  double estimate_coherence(int k, int o, int i) const;
  /// Every output and every input carries its geometry.
  bool has_all_geometry() const {
    for (const auto& c : outputs) if (!c.has_geometry()) return false;
    for (const auto& c : inputs) if (!c.has_geometry()) return false;
    return true;
  }
  /// The data's name in messages: its file quoted, or "measurement".
  std::string where() const { return source.empty() ? std::string("measurement") : "'" + source + "'"; }
};

/// Checks, in this order, and throws InputError naming `data.source`, the field and the problem:
///  - at least one frequency, one output and one input;
///  - frequencies finite, > 0 Hz and strictly increasing (a 0 Hz bin must be dropped first);
///  - `frf` holds Nf matrices of size Nout x Nin with finite entries;
///  - `coherence` empty or Nf matrices Nout x Nin with entries in [0, 1];
///  - `averages` empty, or one count >= 2 per input, and then `coherence` present;
///  - channel names non-empty and unique among the outputs and among the inputs;
///  - every channel with geometry (non-empty body) has finite position_W and a direction_W of unit
///    length (|1 - |n|| <= 1e-6); a channel without geometry may carry a unit direction or zero;
///  - `frame_origin_W`, if set, is finite;
///  - no dead channel: an output row (or input column) whose FRF is exactly zero at every frequency
///    and every input (output) is reported by name.
void Validate(const FrfData& data);

/// The coherence of an FRF estimate averaged from n records, from their ordinary coherence g2:
/// (n g2 - 1) / ((n - 1) g2), clamped to [0, 1]; g2 itself for n = 0 (the coherence is already the
/// estimate's). Why: the H1 estimate's noise variance is (1 - g2) |H_est|^2 / ((n - 1) g2) (the
/// residual of n records about it has n - 1 degrees of freedom), and |H_est|^2 averages |H|^2 plus that
/// variance, so that |H|^2 / (|H|^2 + variance) is the expression above (docs/error-metric.md §8). A
/// noise-free record set (g2 = 1) stays 1; records that are noise alone (g2 about 1 / n) give 0.
double EstimateCoherence(double g2, int n);

/// Tolerance on the length of a direction vector read from a file: files print about 7 to 17
/// significant digits, so a unit vector written in single precision is within 1e-6 of length 1.
inline constexpr double kUnitDirectionTolerance = 1e-6;

}  // namespace stagefit::measurement
