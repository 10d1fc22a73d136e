#include <cstdio>

#include <nlohmann/json.hpp>

#include "command.h"
#include "report.h"
#include "stagefit/common/error.h"
#include "stagefit/common/units.h"
#include "stagefit/kinematics/stage_stack.h"

namespace stagefit::cli {
namespace {

kinematics::Vector6d ParsePose(const std::vector<std::string>& values, const std::string& option) {
  kinematics::Vector6d pose = kinematics::Vector6d::Zero();
  if (values.empty()) return pose;
  if (values.size() != 6) {
    throw UsageError(option + " takes 6 values Dx Dy Dz Rx Ry Rz, got " + std::to_string(values.size()));
  }
  for (int i = 0; i < 6; ++i) {
    pose(i) = ParseQuantity(values[i], i < 3 ? dim::kLength : dim::kAngle,
                            option + " " + std::string(kDofNames[i]));
  }
  return pose;
}

}  // namespace

void RegisterPoseCommand(CLI::App& app) {
  auto* command = app.add_subcommand(
      "pose", "kinematics: sample pose from the stage setpoints and parasitic motions (T = T_Dy T_Ry T_Rz T_hexapod)");
  struct Options {
    std::string dy = "0", ry = "0", rz = "0";
    std::vector<std::string> hexapod, err_dy, err_ry, err_rz, err_hexapod;
    std::string report;
    std::string parasitic_frame = "fixed";
  };
  auto o = std::make_shared<Options>();
  command->add_option("--dy", o->dy, "translation stage setpoint (e.g. \"2.5 mm\"; bare = m)");
  command->add_option("--ry", o->ry, "tilt stage setpoint (e.g. \"0.5 deg\"; bare = rad)");
  command->add_option("--rz", o->rz, "spindle setpoint (e.g. \"90 deg\"; bare = rad)");
  command->add_option("--hexapod", o->hexapod, "hexapod pose Dx Dy Dz Rx Ry Rz")->expected(6);
  command->add_option("--parasitic-dy", o->err_dy, "parasitic motion of the Dy stage, Dx Dy Dz Rx Ry Rz")->expected(6);
  command->add_option("--parasitic-ry", o->err_ry, "parasitic motion of the Ry stage")->expected(6);
  command->add_option("--parasitic-rz", o->err_rz, "parasitic motion of the Rz stage")->expected(6);
  command->add_option("--parasitic-hexapod", o->err_hexapod, "parasitic motion of the hexapod")->expected(6);
  command->add_option("--parasitic-frame", o->parasitic_frame,
                      "fixed (default, seed eq. 1.12: the parasitic translation in the stage's fixed frame) or moved "
                      "(in the frame moved by the setpoint)");
  command->add_option("--report", o->report, "write a JSON report to this file");
  command->callback([o] {
    std::vector<kinematics::StageMotion> motions(4);
    motions[0].setpoint = ParseQuantity(o->dy, dim::kLength, "--dy");
    motions[1].setpoint = ParseQuantity(o->ry, dim::kAngle, "--ry");
    motions[2].setpoint = ParseQuantity(o->rz, dim::kAngle, "--rz");
    motions[3].pose_setpoint = ParsePose(o->hexapod, "--hexapod");
    motions[0].parasitic = ParsePose(o->err_dy, "--parasitic-dy");
    motions[1].parasitic = ParsePose(o->err_ry, "--parasitic-ry");
    motions[2].parasitic = ParsePose(o->err_rz, "--parasitic-rz");
    motions[3].parasitic = ParsePose(o->err_hexapod, "--parasitic-hexapod");
    const kinematics::ParasiticFrame frame = kinematics::ParseParasiticFrame(o->parasitic_frame, "--parasitic-frame");
    auto poses = kinematics::CalcStackPoses(kinematics::MicroStationStages(), motions, frame);
    const auto& X = poses.back();
    Eigen::Matrix4d T = X.GetAsMatrix4();
    std::printf("Sample pose X_W_sample = T_Dy T_Ry T_Rz T_hexapod:\n");
    for (int r = 0; r < 4; ++r) {
      std::printf("  [%13.9f %13.9f %13.9f %13.9f]\n", T(r, 0), T(r, 1), T(r, 2), T(r, 3));
    }
    kinematics::Vector6d pose = X.ToPose();
    std::printf("Dx = %.9g m, Dy = %.9g m, Dz = %.9g m, Rx = %.9g rad, Ry = %.9g rad, Rz = %.9g rad\n", pose(0),
                pose(1), pose(2), pose(3), pose(4), pose(5));
    if (!o->report.empty()) {
      nlohmann::json rows = nlohmann::json::array();
      for (int r = 0; r < 4; ++r) rows.push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
      WriteReport(o->report,
                  {{"command", "pose"},
                   {"parasitic_frame", o->parasitic_frame},
                   {"transform", rows},
                   {"pose", {{"Dx", pose(0)}, {"Dy", pose(1)}, {"Dz", pose(2)}, {"Rx", pose(3)}, {"Ry", pose(4)}, {"Rz", pose(5)}}}},
                  {});
    }
  });
}

}  // namespace stagefit::cli
