#pragma once
// Synthetic measurements whose truth holds something the effects catalogue cannot express, for
// evaluating whether `diagnose` and `loop` refrain from claiming a catalogue effect and say where the
// model fails instead. Written outside the catalogue's code path: the truth is the brute-force model
// of synthetic_measurement.h (stiffnesses scattered as in MakeHiddenEffectCase), plus one of
//
//  - "plate-bending":   the top plate is not rigid: one flexible mode whose shape moves the four
//                       vertical accelerometers and impacts in the saddle pattern (+ at x = +-d,
//                       - at y = +-d), the only pattern four vertical points cannot take rigidly;
//  - "plate-breathing": an in-plane flexible mode of the top plate, every point moving radially;
//  - "cable":           a cable chain or hose between the granite and the hexapod: a lossy spring
//                       across four joints, a load path no joint of the stack's tree holds.
//
// The flexible modes are added to the rigid model's accelerance by modal superposition
// (-w^2 phi_o phi_i / (m (w_p^2 - w^2 + 2 j zeta w_p w))); the cable is an extra spring row in the
// brute-force assembly (which, unlike the model, does not need a tree).

#include <cstdint>
#include <string>
#include <vector>

#include "stagefit/measurement/frf_data.h"
#include "stagefit/measurement/projection.h"
#include "stagefit/model/model_spec.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace stagefit::synthetic {

struct OutsideCatalogueCase {
  uint64_t seed = 0;
  std::string kind;         ///< "plate-bending", "plate-breathing" or "cable"
  std::string description;  ///< in words, with the drawn values
  measurement::FrfData measurement;  ///< noisy, with the declared (nominal) geometry and coherence
  /// Where the hidden part changes the data most, in noise standard deviations (the weights of
  /// NoiseNormalisedDifference): the frequency of the largest change summed over all elements, and
  /// the output and input channels holding at least a share 1/(2 n) of the change (n: their number),
  /// largest first.
  double peak_hz = 0;
  std::vector<std::string> outputs, inputs;
  /// The same change by third-octave band (measurement::MakeFractionalOctaveBands over the data's
  /// range, a point in [low, high)): the fewest bands that hold half of it, largest first. A lossy
  /// part changes a band of modes, not one frequency: this is where it acts, peak_hz where it acts most.
  std::vector<measurement::FrequencyBand> bands;
  /// The change in the top platform's 6x6 accelerance, "<output>/<input>" ("Dx/Fx", "Ry/My"): the data
  /// of `with` and of the truth without the hidden part each projected by least squares onto the rigid
  /// motion of {X} (an output channel reads d . (v + theta x r), an impact of force f along d at r is the
  /// wrench f [d; r x d], r from the frame origin), written here from the channel geometry, not with the
  /// library's projection. An element's change is normalised by its diagonal elements,
  /// |dG_ij|^2 / (|G_ii| |G_jj|) summed over the frequencies (G without the hidden part), so that
  /// translations, rotations and off-diagonal elements weigh alike: the fewest elements that hold half
  /// of it, largest first. The comparison's compliance elements are these elements' names.
  std::vector<std::string> elements;
  double visibility = 0;  ///< RMS change over every point in noise standard deviations
};

/// A case of kind `kind` ("plate-bending", "plate-breathing", "cable", or "" to draw one) for the
/// 12x10 top-plate test with options' band, number of frequencies, noise and stiffness scatter
/// (num_effects and layout are ignored). The hidden part is scaled to a visibility drawn in
/// [min_visibility, 4 min_visibility]. Throws InputError for an unknown kind.
OutsideCatalogueCase MakeOutsideCatalogueCase(const model::ModelSpec& nominal, uint64_t seed, const std::string& kind,
                                              const HiddenEffectOptions& options);

}  // namespace stagefit::synthetic
