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

/// In which frame a stage's parasitic translation D_err is expressed (docs/notation.md, "Parasitic
/// motion"). With the nominal motion (R_nom, p_nom) and the error (R_err = Euler XYZ of the parasitic
/// angles, D_err):
///  - kFixed (seed eq. 1.12, the default): one transform holds setpoint and error, the error's
///    translation in the stage's fixed (bottom) frame:  T = [R_nom R_err, p_nom + D_err];
///    a spindle's radial error measured along x stays along x whatever the spindle angle.
///  - kMoved: the error follows the moved frame, T = T_nom * T_err = [R_nom R_err, p_nom + R_nom D_err];
///    at Rz = 90 deg an error of 1 um along x appears along y.
/// The two differ only in the translation, and only where the setpoint rotates.
enum class ParasiticFrame { kFixed, kMoved };

/// "fixed" | "moved"; throws InputError naming `context` otherwise.
ParasiticFrame ParseParasiticFrame(const std::string& text, const std::string& context);

/// The transform of one stage with its parasitic motion (ParasiticFrame).
RigidTransform CalcStageTransform(const Stage& stage, const StageMotion& motion,
                                  ParasiticFrame frame = ParasiticFrame::kFixed);

/// Product of the stage transforms, bottom stage first. Throws InputError if the sizes differ.
/// Returns the cumulative transforms: element i is X_W_i, the pose of the top of stage i in W.
std::vector<RigidTransform> CalcStackPoses(const std::vector<Stage>& stages,
                                           const std::vector<StageMotion>& motions,
                                           ParasiticFrame frame = ParasiticFrame::kFixed);

/// The ID31 micro-station stack: Dy translation, Ry tilt, Rz spindle, hexapod (SPEC §1).
std::vector<Stage> MicroStationStages();

}  // namespace stagefit::kinematics
