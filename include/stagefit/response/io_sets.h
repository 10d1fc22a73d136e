#pragma once
// The input/output sets of the standard studies, as second-order systems ready for FrfEvaluator.
//
//  - compliance:  wrench at {X} -> motion of {X} (6 x 6), model::BuildComplianceSystem().
//  - raw:         the model's hammer impacts -> its accelerometer channels (12 x 10 for the reference
//                 micro-station), model::ExcitationInputs() / SensorOutputs().
//  - stages:      the modal test of the whole stack (the seed's Figure 2.3): three hammer forces Fx, Fy,
//                 Fz on the translation stage "ty" at kStageHammerOffset from its centre of mass, and
//                 the motion Dx..Rz of every body at its centre of mass (6 per body, W axes).
//  - disturbance: the seed's Figure 3.7 case: ground motion Dx, Dy, Dz (m), a force inside the
//                 translation-stage joint "ty" (Dz, Dx; N) and inside the spindle joint "rz" (Dz, Dx, Dy;
//                 N) -> motion of {X} relative to the granite (Dx..Rz, in {X}'s axes).

#include <Eigen/Core>

#include <string>
#include <vector>

#include "stagefit/model/assembled_model.h"
#include "stagefit/model/linear_system.h"

namespace stagefit::response {

/// The named input/output sets of `stagefit frf --io`.
enum class IoSet { kCompliance, kRaw, kStages, kDisturbance };

/// "compliance" | "raw" | "stages" | "disturbance"; throws InputError naming `context` otherwise.
IoSet ParseIoSet(const std::string& text, const std::string& context);
std::string ToString(IoSet set);

/// Hammer point of the stages study, relative to the CoM of the translation stage "ty" in W (m): on
/// the stage's top surface, off every axis so that the three forces excite all six rigid-body motions.
inline const Eigen::Vector3d kStageHammerOffset{0.25, 0.20, 0.08};

/// The body receiving the hammer forces of the stages study.
inline constexpr const char* kStageHammerBody = "ty";

/// The name of the frame added on the granite for the disturbance study: at {X}'s origin, {X}'s axes.
inline constexpr const char* kGraniteReferenceFrame = "granite_X";

/// Inputs "ty.hammer.Fx", "ty.hammer.Fy", "ty.hammer.Fz": unit forces along W at the hammer point.
/// Throws InputError when the model has no body "ty".
std::vector<model::InputSpec> StageHammerInputs(const model::ModelSpec& spec);

/// Outputs "<body>.Dx" ... "<body>.Rz" for every body, in the model's body order.
std::vector<model::OutputSpec> AllBodyCoMOutputs(const model::ModelSpec& spec);

/// The stages study (3 inputs, 6 x num_bodies outputs).
model::SecondOrderSystem BuildStagesSystem(const model::AssembledModel& model);

/// The disturbance study. A COPY of the model's description gets the frame kGraniteReferenceFrame on
/// body "granite" at {X}'s origin with {X}'s axes, and is assembled again (the matrices are those of
/// `model`: frames do not change them); outputs "X_rel.Dx" ... are OutputSpec::kRelativeMotion of {X}
/// with respect to it. Inputs: "ground.Dx", "ground.Dy", "ground.Dz" (those the model declares),
/// "ty.F.Dz", "ty.F.Dx", "rz.F.Dz", "rz.F.Dx", "rz.F.Dy" (joint forces, skipped when the DoF is
/// imposed or the joint is absent). Throws InputError when the model has no body "granite" or no
/// compliance frame.
model::SecondOrderSystem BuildDisturbanceSystem(const model::AssembledModel& model);

/// The system of `set` for `model`.
model::SecondOrderSystem BuildIoSetSystem(const model::AssembledModel& model, IoSet set);

}  // namespace stagefit::response
