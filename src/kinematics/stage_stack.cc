#include "stagefit/kinematics/stage_stack.h"

#include "stagefit/common/error.h"

namespace stagefit::kinematics {

ParasiticFrame ParseParasiticFrame(const std::string& text, const std::string& context) {
  if (text == "fixed") return ParasiticFrame::kFixed;
  if (text == "moved") return ParasiticFrame::kMoved;
  throw InputError(context + " '" + text + "': expected fixed (seed eq. 1.12) or moved");
}

RigidTransform CalcStageTransform(const Stage& stage, const StageMotion& motion, ParasiticFrame frame) {
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
  const RigidTransform error = RigidTransform::FromPose(motion.parasitic);
  if (frame == ParasiticFrame::kMoved) return nominal * error;
  // Eq. 1.12: rotation R_nom R_err, translation p_nom + D_err (D_err in the fixed frame).
  return RigidTransform(nominal.rotation() * error.rotation(), nominal.translation() + error.translation());
}

std::vector<RigidTransform> CalcStackPoses(const std::vector<Stage>& stages,
                                           const std::vector<StageMotion>& motions, ParasiticFrame frame) {
  if (stages.size() != motions.size()) {
    throw InputError("stage stack has " + std::to_string(stages.size()) + " stages but " +
                     std::to_string(motions.size()) + " motions were given");
  }
  std::vector<RigidTransform> poses;
  RigidTransform X_W;
  for (size_t i = 0; i < stages.size(); ++i) {
    X_W = X_W * CalcStageTransform(stages[i], motions[i], frame);
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
