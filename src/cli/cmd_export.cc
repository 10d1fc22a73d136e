#include <cstdio>
#include <filesystem>
#include <sstream>

#include "command.h"
#include "report.h"
#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"
#include "stagefit/model/assembled_model.h"
#include "stagefit/model/linear_system.h"
#include "stagefit/model/state_space.h"
#include "state_space_export.h"

namespace stagefit::cli {

void RegisterExportCommand(CLI::App& app) {
  auto* command = app.add_subcommand(
      "export", "write the linearised state space (A, B, C, D with names, plus M, C, K) to .mat or CSV");
  struct Options {
    CommonOptions common;
    std::string out;
    std::string io = "compliance";
  };
  auto o = std::make_shared<Options>();
  AddCommonOptions(*command, o->common);
  AddWithOption(*command, o->common);
  command->add_option("--out", o->out, "output: FILE.mat, or a folder / FILE.csv stem for CSV files")->required();
  command->add_option("--io", o->io,
                      "inputs and outputs: compliance (wrench at {X} -> motion of {X}), raw (hammer impacts -> "
                      "accelerometers, displacement level), ground (ground motion -> motion of {X})")
      ->check(CLI::IsMember({"compliance", "raw", "ground"}));
  command->callback([o] {
    model::ModelSpec spec = LoadModelFromOptions(o->common);
    auto assembled = model::AssembledModel::Assemble(spec, ModelSource(o->common));
    model::SecondOrderSystem sys;
    if (o->io == "compliance") {
      sys = model::BuildComplianceSystem(assembled);
    } else if (o->io == "raw") {
      sys = model::BuildSystem(assembled, model::ExcitationInputs(spec), model::SensorOutputs(spec));
    } else {
      sys = model::BuildSystem(assembled, model::GroundInputs(assembled),
                               model::FrameMotionOutputs(spec, spec.compliance_frame));
    }
    model::StateSpace ss = model::CalcStateSpace(sys);
    std::vector<std::string> inputs;
    if (!o->common.model_path.empty()) inputs.push_back(o->common.model_path);
    for (const auto& file : StateSpaceFiles(o->out)) CheckNotAnInput(file, {inputs.begin(), inputs.end()});
    std::vector<std::string> written = WriteStateSpace(o->out, ss, sys);
    std::printf("State space: %d states, %d inputs, %d outputs (%s)\n", static_cast<int>(ss.A.rows()),
                static_cast<int>(ss.B.cols()), static_cast<int>(ss.C.rows()), o->io.c_str());
    for (const auto& note : ss.notes) std::printf("note: %s\n", note.c_str());
    for (const auto& w : written) std::printf("wrote %s\n", w.c_str());
  });
}

}  // namespace stagefit::cli
