#include "stagefit/kinematics/stage_stack.h"

#include "stagefit/common/error.h"

namespace stagefit::kinematics {

RigidTransform CalcStageTransform(const Stage& stage, const StageMotion& motion) {
  RigidTransform nominal;
  switch (stage.kind) {
    case StageKind::kTranslation: {
      STAGEFIT_ASSERT(!is_rotation(stage.axis), "translation stage along a rotation axis");
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      p(index(stage.axis)) = motion.setpoint;
      nominal = RigidTransform::FromTranslation(p);
      break;
    }
    case StageKind::kRotation: {
      STAGEFIT_ASSERT(is_rotation(stage.axis), "rotation stage about a translation axis");
      switch (stage.axis) {
        case Dof::kRx: nominal = RigidTransform::FromRotation(RotX(motion.setpoint)); break;
        case Dof::kRy: nominal = RigidTransform::FromRotation(RotY(motion.setpoint)); break;
        default: nominal = RigidTransform::FromRotation(RotZ(motion.setpoint)); break;
      }
      break;
    }
    case StageKind::kSixDof:
      nominal = RigidTransform::FromPose(motion.pose_setpoint);
      break;
  }
  return nominal * RigidTransform::FromPose(motion.parasitic);
}

std::vector<RigidTransform> CalcStackPoses(const std::vector<Stage>& stages,
                                           const std::vector<StageMotion>& motions) {
  if (stages.size() != motions.size()) {
    throw InputError("stage stack has " + std::to_string(stages.size()) + " stages but " +
                     std::to_string(motions.size()) + " motions were given");
  }
  std::vector<RigidTransform> poses;
  RigidTransform X_W;
  for (size_t i = 0; i < stages.size(); ++i) {
    X_W = X_W * CalcStageTransform(stages[i], motions[i]);
    poses.push_back(X_W);
  }
  return poses;
}

std::vector<Stage> MicroStationStages() {
  return {{"ty", StageKind::kTranslation, Dof::kDy},
          {"ry", StageKind::kRotation, Dof::kRy},
          {"rz", StageKind::kRotation, Dof::kRz},
          {"hexapod", StageKind::kSixDof, Dof::kDx}};
}

}  // namespace stagefit::kinematics
