#pragma once
// Faults of the test bench before faults of the model: checks of raw hammer-test channels against the
// rigid-body motion the other channels of the same body see (a reversed sensor or hammer channel, two
// channels swapped, a dead or clipped sensor, a sensor whose mount or local structure resonates).
//
// Principle. On one rigid body the sensors see y = J_a x, so the output residual R = (I - J_a pinv(J_a)) H
// is noise only; the impacts likewise give H (I - J_F pinv(J_F)). The noise each residual should hold
// follows from the coherence: a point of coherence g = |H0|^2 / (|H0|^2 + sigma^2) has E|H|^2 (1 - g) = sigma^2, and the
// expected residual energy is sum_ij P_ii sigma_ij^2 (P the residual projector). The ratio of the residual
// energy to that expectation (the "excess", about 1 for sound data) is computed per third-octave band.
// A fault is named by the repair that brings the excess back to about 1: negating one channel
// (reversed polarity), exchanging two channels (swapped), or a per-frequency complex gain on one channel
// that is about 1 outside a band (a local resonance: the mount or the structure under one sensor).
// Output faults do not show in the input residual and conversely, so the two sides are checked apart.

#include <Eigen/Core>

#include <string>
#include <vector>

#include "stagefit/measurement/frf_data.h"

namespace stagefit::measurement {

enum class ChannelFaultKind {
  kReversed,        ///< sign of one channel reversed
  kSwapped,         ///< two channels exchanged
  kDead,            ///< no signal: coherence about 0 or far less energy than the rigid motion predicts
  kClipped,         ///< measured magnitude saturates where the rigid prediction keeps rising
  kLocalResonance,  ///< one sensor not moving with the body in a band (mount or local mode)
};
std::string ToString(ChannelFaultKind kind);  ///< "reversed", "swapped", "dead", "clipped", "local_resonance"

struct ChannelFinding {
  ChannelFaultKind kind = ChannelFaultKind::kReversed;
  bool is_input = false;               ///< an impact (hammer) channel
  std::vector<std::string> channels;   ///< one name, two for kSwapped
  double low_hz = 0, high_hz = 0;      ///< band where it shows (the whole range for reversed/swapped/dead)
  double peak_hz = 0;                  ///< kLocalResonance: estimated resonance frequency
  double excess_before = 0;            ///< residual excess over the noise in that band before the repair
  double excess_after = 0;             ///< ... after the repair (or the exclusion) that explains it
  std::string evidence;                ///< one sentence with the numbers
  std::string action;                  ///< what to do
  bool repairable = false;             ///< RepairChannels() fixes it (reversed, swapped, when not ambiguous)
  /// Other repairs that explain the data as well (a symmetric layout: reversing impact h1 or h5, two
  /// impacts along the same line, gives the same rigid data). Not empty: the data cannot tell which of
  /// `channels` and these is at fault, and nothing is repaired.
  std::vector<std::vector<std::string>> alternatives;
};

struct ChannelCheckOptions {
  /// A band is inconsistent when its residual excess over the noise exceeds this (sound data: about 1).
  double excess_threshold = 4.0;
  /// A repair is accepted when it lowers the excess of the inconsistent bands by at least this factor.
  double min_improvement = 5.0;
  /// Relative noise assumed when the data carry no coherence.
  double default_relative_noise = 0.02;
  /// Dead: mean coherence below this, or energy below dead_energy_ratio of the rigid prediction.
  double dead_coherence = 0.2;
  double dead_energy_ratio = 0.01;
  int max_findings_per_side = 3;
};

/// Channels of one side that do not move rigidly together in a band where no fault of a single channel
/// explains it: a flexible mode of the structure under several sensors or impacts (the top plate bending
/// in a saddle moves the four vertical ones). Not a fault of the test bench, and not something the rigid platform's
/// compliance can hold: the projection to the platform removes it, and a model that reaches the floor
/// there still does not explain these channels' readings.
struct NonRigidBand {
  bool is_input = false;
  double low_hz = 0, high_hz = 0;     ///< the band of the largest excess
  double excess = 0;                  ///< the residual over the noise there (the checks' excess)
  std::vector<std::string> channels;  ///< the channels above the threshold there, largest excess first (at most 4)
  std::string Words() const;          ///< one sentence with the numbers
};

struct ChannelCheckResult {
  bool checked = false;          ///< false: skipped (see skipped_reason)
  std::string skipped_reason;
  std::vector<ChannelFinding> findings;
  std::vector<NonRigidBand> non_rigid;  ///< at most one per side
  std::string Report() const;    ///< human-readable lines, "channels: no fault found" when none
};

/// Checks the channels of raw FRFs (sensors x impacts with geometry). Sensors on several bodies: each
/// body's sensors are checked alone when they observe its six DoF, else that body is skipped; impacts
/// are checked only when they all sit on one body and observe its six DoF. Data without geometry (or
/// already projected) are skipped, not an error. The origin only conditions the Jacobians.
ChannelCheckResult CheckChannels(const FrfData& raw, const Eigen::Vector3d& p_WXo,
                                 const ChannelCheckOptions& options = {});

/// `data` without the named outputs and inputs. Throws InputError naming the data, the unknown name and
/// the channel names that exist, or when nothing would remain on a side.
FrfData ExcludeChannels(const FrfData& data, const std::vector<std::string>& names);

/// `data` with the certain repairs applied: reversed channels negated, swapped pairs exchanged. Other
/// findings are ignored (exclude those channels instead).
FrfData RepairChannels(const FrfData& data, const std::vector<ChannelFinding>& findings);

/// Names of the channels of the findings that RepairChannels() cannot fix (to exclude).
std::vector<std::string> ChannelsToExclude(const std::vector<ChannelFinding>& findings);

}  // namespace stagefit::measurement
