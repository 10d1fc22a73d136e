#pragma once
// The model description: plain data, as read from a model file (TOML) or built in code. Validate it
// with ValidateModel(); AssembledModel::Assemble() turns it into the immutable linearised model.
//
// Every quantity is SI and every position and axis is in the world frame W at rest (SPEC §1).

#include <Eigen/Core>

#include <array>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "stagefit/common/dof.h"

namespace stagefit::model {

/// The name of the implicit ground body: its translations are the ground-motion inputs.
inline constexpr const char* kGroundName = "ground";

/// A rigid body.
struct BodySpec {
  std::string name;
  double mass_kg = 0.0;
  Eigen::Vector3d com_W = Eigen::Vector3d::Zero();             ///< centre of mass in W at rest, m
  Eigen::Matrix3d inertia_com_W = Eigen::Matrix3d::Zero();     ///< about the CoM, along W, kg m^2
  std::string note;                                            ///< provenance of the numbers
};

/// An off-diagonal stiffness/damping term between two DoF of a joint: adds k to K(a,b) and K(b,a).
/// Units: N/m between translations, Nm/rad between rotations, N/rad (= Nm/m) between the two kinds.
struct CouplingSpec {
  Dof a = Dof::kDx;
  Dof b = Dof::kDy;
  double stiffness = 0.0;
  double damping = 0.0;
};

/// A 6-DoF spring/damper joint between a parent and a child body. Its relative motion delta is the
/// child's motion minus the parent's, both taken at the joint origin, in joint axes; its energy is
/// 0.5 delta' K delta with K = diag(stiffness) + couplings (SPEC §2). An imposed DoF is a constraint
/// (delta_i = 0, the stage's controlled motion) and carries no stiffness.
struct JointSpec {
  std::string name;
  std::string parent;
  std::string child;
  Eigen::Vector3d origin_W = Eigen::Vector3d::Zero();           ///< m
  Eigen::Matrix3d R_WJ = Eigen::Matrix3d::Identity();           ///< joint axes in W
  std::array<double, 6> stiffness{};     ///< N/m (Dx..Dz), Nm/rad (Rx..Rz)
  std::array<double, 6> damping{};       ///< N s/m, Nm s/rad
  std::array<double, 6> loss_factor{};   ///< hysteretic loss factor eta (dimensionless), 0 = none
  std::array<bool, 6> imposed{};         ///< true = controlled DoF, removed from the free DoF
  std::vector<CouplingSpec> couplings;
  double spin_rate_rad_s = 0.0;          ///< the child's subtree spins about the joint z axis
  std::string note;
};

/// A named frame fixed to a body (e.g. the compliance frame {X}).
struct FrameSpec {
  std::string name;
  std::string body;
  Eigen::Vector3d origin_W = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R_WF = Eigen::Matrix3d::Identity();
};

/// A sensor or an excitation point on a body: position and unit direction in W.
struct PointSpec {
  std::string name;
  std::string body;
  Eigen::Vector3d position_W = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction_W = Eigen::Vector3d::UnitX();
};

/// A correction of a measurement channel's declared geometry (the sensor-geometry effect): the sensor
/// or impact named `channel` really sits at position + offset_W and measures along R(rotation) times
/// its declared direction, with R = RotationFromEuler(rotation_rad). Applied by the comparison to the
/// measurement's geometry before the model's outputs and the projections are built.
struct GeometryCorrection {
  std::string channel;
  bool is_impact = false;                                   ///< false: a sensor (output) channel
  Eigen::Vector3d offset_W = Eigen::Vector3d::Zero();       ///< m
  Eigen::Vector3d rotation_rad = Eigen::Vector3d::Zero();   ///< Euler XYZ, rad
};

/// One step of the compare -> diagnose -> fit loop, kept with a tuned model.
struct HistoryEntry {
  std::string step;     ///< e.g. "fit", "fit --with payload@hexapod"
  double error = 0.0;   ///< SPEC §4 error scalar after the step
  std::string detail;
};

/// A catalogued effect (model/effects.h) at a location, with its parameter values (SI).
struct Effect {
  std::string name;
  std::string location;
  std::map<std::string, double> parameters;
  /// Parameters every fit leaves at their value, in catalogue order: a user's choice, or the loop's
  /// for a length or turn a fit ran to the bound of its range (diagnose::HoldParametersAtBounds).
  std::vector<std::string> held;
  /// "name@location:p1=v1,p2=v2[,held=p1]" with 17 significant digits, parameters in catalogue order.
  std::string ToString() const;
  bool operator==(const Effect& other) const {
    return name == other.name && location == other.location && parameters == other.parameters && held == other.held;
  }
};

struct ModelSpec;

/// The description before its effects, shared between copies of a spec (copy on write).
using BaseSpecPtr = std::shared_ptr<ModelSpec>;

/// A model description: its base (bodies, joints, channels) and an ordered list of effects.
///
/// The fields below hold the assembled description, the base with every effect of `effects` applied
/// in order (model::ApplyEffect), which is what the rest of the program reads. When `effects` is not
/// empty, `base` holds the description before them: the effects' parameters stay parameters
/// (model/parameters.h: "payload@hexapod.mass"), and changing one re-expands the description from the
/// base (model::ExpandEffects), deterministically. A model's own parameters (joint stiffnesses, body
/// masses) are those of the base; model::SetParameter keeps base and assembled description in step.
/// A model file holds the base and the effects as [[effect]] tables (docs/model-file.md).
struct ModelSpec {
  std::string name;
  std::string description;
  std::vector<BodySpec> bodies;
  std::vector<JointSpec> joints;
  std::vector<FrameSpec> frames;
  std::vector<PointSpec> sensors;
  std::vector<PointSpec> excitations;
  std::array<bool, 3> ground_inputs{true, true, true};  ///< which ground translations are inputs
  std::string compliance_frame = "X";
  double acquisition_delay_s = 0.0;                     ///< pure delay on every output
  std::vector<Effect> effects;                          ///< catalogued effects applied, in order
  BaseSpecPtr base;                                     ///< the description before `effects`; null if none
  /// Effects of files written before effects were kept as parameters ([model] effects): text only,
  /// already part of the bodies and joints.
  std::vector<std::string> baked_effects;
  std::vector<GeometryCorrection> geometry_corrections;
  std::vector<HistoryEntry> history;
};

/// Every problem of `spec` at once, each naming the item, field, value and what was expected.
/// Empty when the model is valid. Checks: unique non-empty names; positive finite mass; symmetric
/// positive-definite inertia satisfying the triangle inequality; finite, non-negative stiffness,
/// damping and loss factors; unit rotation matrices; known parent/child bodies; every body the child
/// of exactly one joint (a tree rooted at the ground: no loops, nothing disconnected); frames, sensors
/// and excitations on known bodies with unit directions; couplings between distinct free DoF keeping
/// the joint stiffness positive semi-definite.
std::vector<std::string> ValidateModel(const ModelSpec& spec);

/// Throws InputError listing every problem of ValidateModel(), prefixed with `source` (file name).
void CheckModel(const ModelSpec& spec, const std::string& source);

/// Index of a body by name, or -1 (also for the ground).
int FindBody(const ModelSpec& spec, const std::string& name);
int FindJoint(const ModelSpec& spec, const std::string& name);
int FindFrame(const ModelSpec& spec, const std::string& name);

}  // namespace stagefit::model
