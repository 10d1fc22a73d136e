#pragma once
// Faults of the test bench injected into a (synthetic) raw measurement, for tests and the evaluation of
// measurement::CheckChannels(): a reversed sensor or hammer channel, two channels swapped, a dead sensor,
// a clipped sensor and a local resonance (a resonant sensor mount or a local mode under one sensor).

#include <cstdint>
#include <random>
#include <string>

#include "stagefit/measurement/channel_checks.h"
#include "stagefit/measurement/frf_data.h"

namespace stagefit::synthetic {

/// Negates output (is_input false) or input channel `name`.
void InjectReversed(measurement::FrfData& data, const std::string& name, bool is_input);

/// Exchanges the data of two outputs (or two inputs); names and geometry stay, as with crossed cables.
void InjectSwapped(measurement::FrfData& data, const std::string& a, const std::string& b, bool is_input);

/// A dead sensor: its FRFs become complex Gaussian noise of standard deviation `level` times the RMS of
/// the row it replaces, its coherence uniform in [0, 0.05] (an H1 estimate of an uncorrelated output).
void InjectDead(measurement::FrfData& data, const std::string& name, double level, uint64_t seed);

/// A clipped sensor: every FRF magnitude of that output above `fraction` times the row's largest magnitude
/// is set to that level, the phase kept.
void InjectClipped(measurement::FrfData& data, const std::string& name, double fraction);

/// A local resonance under one sensor: its FRFs are multiplied by the base-excited single-DoF mount
/// transmissibility T(f) = (1 + j f/(Q fn)) / (1 - (f/fn)^2 + j f/(Q fn)) (about 1 well below fn, Q at fn).
void InjectLocalResonance(measurement::FrfData& data, const std::string& name, double fn_hz, double q);

/// One drawn fault: kind, channel(s), magnitude; `description` says what was injected.
struct InjectedFault {
  measurement::ChannelFaultKind kind = measurement::ChannelFaultKind::kReversed;
  bool is_input = false;
  std::vector<std::string> channels;
  double fn_hz = 0, q = 0, fraction = 0;
  std::string description;
};

/// Draws a fault of `kind` on random channels (reversed and swapped: a sensor or an impact with equal
/// odds; a swapped pair always has different data), magnitudes: clipping at 0.3-0.7 of the row maximum,
/// local resonance fn log-uniform within the central 80 % of the log frequency range and Q in 5-30,
/// dead noise level 1e-3 to 1e-2; and injects it.
InjectedFault InjectRandomFault(measurement::FrfData& data, measurement::ChannelFaultKind kind, std::mt19937_64& rng);

}  // namespace stagefit::synthetic
