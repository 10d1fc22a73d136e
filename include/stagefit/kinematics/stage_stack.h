#pragma once
// Kinematics of stacked stages (seed eq. 1.12-1.14): each stage moves its top relative to its
// bottom by its setpoint, plus a small parasitic motion; the sample pose is the product of the stage
// transforms from the granite up: X_W_sample = T_Dy * T_Ry * T_Rz * T_hexapod.

#include <string>
#include <vector>

#include "stagefit/common/dof.h"
#include "stagefit/kinematics/rigid_transform.h"

namespace stagefit::kinematics {

/// What a stage's setpoint drives.
enum class StageKind {
  kTranslation,  ///< setpoint in m along `axis` (Dx, Dy or Dz)
  kRotation,     ///< setpoint in rad about `axis` (Rx, Ry or Rz), about the origin of W (the PoI)
  kSixDof,       ///< setpoint is a full pose [Dx Dy Dz Rx Ry Rz] (a hexapod)
};

struct Stage {
  std::string name;
  StageKind kind = StageKind::kTranslation;
  Dof axis = Dof::kDx;  ///< for kTranslation / kRotation
};

/// One stage's commanded motion and its measured or assumed error motion.
struct StageMotion {
  double setpoint = 0.0;                          ///< m or rad (kTranslation, kRotation)
  Vector6d pose_setpoint = Vector6d::Zero();      ///< kSixDof only: [m m m rad rad rad]
  Vector6d parasitic = Vector6d::Zero();          ///< small error motion [m m m rad rad rad]
};

/// The transform of one stage, nominal motion first, then its parasitic motion in the moved frame
/// (seed eq. 1.12): T = T_nominal(setpoint) * T_error(parasitic), with T_error = FromPose(parasitic).
RigidTransform CalcStageTransform(const Stage& stage, const StageMotion& motion);

/// Product of the stage transforms, bottom stage first. Throws InputError if the sizes differ.
/// Returns the cumulative transforms: element i is X_W_i, the pose of the top of stage i in W.
std::vector<RigidTransform> CalcStackPoses(const std::vector<Stage>& stages,
                                           const std::vector<StageMotion>& motions);

/// The ID31 micro-station stack: Dy translation, Ry tilt, Rz spindle, hexapod (SPEC §1).
std::vector<Stage> MicroStationStages();

}  // namespace stagefit::kinematics
