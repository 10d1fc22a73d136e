#include <cstdio>
#include <iostream>

#include <nlohmann/json.hpp>

#include "command.h"
#include "report.h"
#include "stagefit/model/assembled_model.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/modes.h"

namespace stagefit::cli {

void RegisterModelCommand(CLI::App& app) {
  auto* command = app.add_subcommand("model", "print bodies, joints, DoF/state count and modes of the model");
  auto options = std::make_shared<CommonOptions>();
  AddCommonOptions(*command, *options);
  AddWithOption(*command, *options);
  command->callback([options] {
    model::ModelSpec spec = LoadModelFromOptions(*options);
    auto assembled = model::AssembledModel::Assemble(spec, ModelSource(*options));
    auto modal = model::CalcModes(assembled);

    std::printf("Model: %s%s\n", spec.name.c_str(), options->model_path.empty() ? " (embedded default)" : "");
    std::printf("\nBodies (%zu):\n  %-10s %10s   %-26s %s\n", spec.bodies.size(), "name", "mass [kg]",
                "CoM in W [m]", "inertia diag [kg m^2]");
    for (const auto& b : spec.bodies) {
      std::printf("  %-10s %10.4g   (%7.4f, %7.4f, %7.4f)   %.4g, %.4g, %.4g\n", b.name.c_str(), b.mass_kg, b.com_W.x(),
                  b.com_W.y(), b.com_W.z(), b.inertia_com_W(0, 0), b.inertia_com_W(1, 1), b.inertia_com_W(2, 2));
    }
    std::printf("\nJoints (%zu):\n", spec.joints.size());
    for (const auto& j : spec.joints) {
      std::string imposed;
      for (int i = 0; i < 6; ++i) {
        if (j.imposed[i]) imposed += (imposed.empty() ? "" : " ") + std::string(kDofNames[i]);
      }
      std::printf("  %-10s %s -> %s, origin z = %.3f m%s%s\n", j.name.c_str(), j.parent.c_str(), j.child.c_str(),
                  j.origin_W.z(), imposed.empty() ? "" : ", imposed: ", imposed.c_str());
      std::printf("  %-10s k:", "");
      for (int i = 0; i < 6; ++i) {
        if (j.imposed[i]) std::printf("  %s -", std::string(kDofNames[i]).c_str());
        else std::printf("  %s %.3g", std::string(kDofNames[i]).c_str(), j.stiffness[i]);
      }
      std::printf("\n");
    }
    std::printf("\nFree DoF: %d    States: %d    Ground inputs: %d\n", assembled.num_dofs(), assembled.num_states(),
                assembled.num_ground_inputs());
    std::printf("\nModes (%zu%s):\n  %3s %10s %9s   %-24s %-20s\n", modal.modes.size(),
                modal.num_overdamped ? ", plus overdamped roots" : "", "#", "f [Hz]", "zeta [%]",
                "dominant joint DoF", "dominant body");
    nlohmann::json modes = nlohmann::json::array();
    for (size_t k = 0; k < modal.modes.size(); ++k) {
      const auto& m = modal.modes[k];
      const std::string& dof = assembled.dof_names()[m.dominant_dof];
      const std::string& body = spec.bodies[m.dominant_body].name;
      char dof_text[64], body_text[64];
      std::snprintf(dof_text, sizeof dof_text, "%s (%.0f %%)", dof.c_str(), 100 * m.strain_energy_share(m.dominant_dof));
      std::snprintf(body_text, sizeof body_text, "%s (%.0f %%)", body.c_str(),
                    100 * m.kinetic_energy_share(m.dominant_body));
      std::printf("  %3zu %10.2f %9.2f   %-24s %-20s\n", k + 1, m.frequency_hz, 100 * m.damping_ratio, dof_text,
                  body_text);
      nlohmann::json strain = nlohmann::json::object();
      for (int i = 0; i < assembled.num_dofs(); ++i) strain[assembled.dof_names()[i]] = m.strain_energy_share(i);
      nlohmann::json kinetic = nlohmann::json::object();
      for (size_t b = 0; b < spec.bodies.size(); ++b) kinetic[spec.bodies[b].name] = m.kinetic_energy_share(b);
      modes.push_back({{"frequency_hz", m.frequency_hz}, {"damping_ratio", m.damping_ratio},
                       {"dominant_dof", dof}, {"dominant_body", body},
                       {"strain_energy_share", strain}, {"kinetic_energy_share", kinetic}});
    }
    if (!options->report_path.empty()) {
      nlohmann::json report = {{"command", "model"}, {"model", spec.name}, {"num_dofs", assembled.num_dofs()},
                               {"num_states", assembled.num_states()}, {"dof_names", assembled.dof_names()},
                               {"modes", modes}};
      WriteReport(options->report_path, report, {options->model_path});
    }
  });
}

}  // namespace stagefit::cli
