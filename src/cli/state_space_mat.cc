#include "state_space_export.h"

#include "stagefit/measurement/mat_file.h"

namespace stagefit::cli {

std::vector<std::string> WriteStateSpaceMat(const std::string& out, const model::StateSpace& ss,
                                            const model::SecondOrderSystem& sys) {
  using measurement::MatVariable;
  std::vector<MatVariable> vars = {
      {"A", ss.A}, {"B", ss.B}, {"C", ss.C}, {"D", ss.D},
      {"M", sys.M}, {"C_damping", sys.C}, {"K", sys.K},
      {"state_names", ss.state_names}, {"input_names", ss.input_names}, {"output_names", ss.output_names},
      {"dof_names", sys.dof_names},
  };
  measurement::WriteMatFile(out, vars, measurement::MatVersion::kV5);
  return {out};
}

}  // namespace stagefit::cli
