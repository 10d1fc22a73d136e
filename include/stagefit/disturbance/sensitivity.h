#pragma once
// Sensitivities of the model to its disturbance sources (seed Figure 3.7): ground motion Dx/Dy/Dz, force
// pairs inside the translation stage (ty Dz, Dx) and inside the spindle (rz Dz, Dx, Dy), to the motion
// of the top platform {X} relative to the granite (response::BuildDisturbanceSystem). Their squared
// magnitudes turn a measured motion PSD into a disturbance (force) PSD: EstimateForcePsd().

#include <Eigen/Core>

#include <string>
#include <vector>

#include "stagefit/model/model_spec.h"

namespace stagefit::disturbance {

/// The names of the sources and outputs of the model's disturbance system, e.g. "ground.Dz", "ty.F.Dz",
/// and "X_rel.Dz" (outputs are {X} relative to the granite, Dx..Rz).
struct DisturbanceChannels {
  std::vector<std::string> sources;
  std::vector<std::string> outputs;
};
DisturbanceChannels ListDisturbanceChannels(const model::ModelSpec& spec);

/// The receptance (m/N, m/m for ground motion, rad for rotations) from `source` to `output` at
/// `frequency_hz` (Hz, > 0). Throws InputError naming the unknown source or output and listing the
/// valid names.
Eigen::VectorXcd CalcModelSensitivity(const model::ModelSpec& spec, const std::string& source,
                                      const std::string& output, const Eigen::VectorXd& frequency_hz);

}  // namespace stagefit::disturbance
