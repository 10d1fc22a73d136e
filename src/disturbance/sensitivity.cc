#include "stagefit/disturbance/sensitivity.h"

#include "stagefit/common/error.h"
#include "stagefit/model/assembled_model.h"
#include "stagefit/response/frf_evaluator.h"
#include "stagefit/response/io_sets.h"

namespace stagefit::disturbance {
namespace {

int Find(const std::vector<std::string>& names, const std::string& name, const std::string& what) {
  for (size_t i = 0; i < names.size(); ++i) {
    if (names[i] == name) return static_cast<int>(i);
  }
  std::string list;
  for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
  throw InputError(what + " '" + name + "' is not one of the model's disturbance " + what + "s (" + list + ")");
}

}  // namespace

DisturbanceChannels ListDisturbanceChannels(const model::ModelSpec& spec) {
  const auto system = response::BuildDisturbanceSystem(model::AssembledModel::Assemble(spec));
  return {system.input_names, system.output_names};
}

Eigen::VectorXcd CalcModelSensitivity(const model::ModelSpec& spec, const std::string& source,
                                      const std::string& output, const Eigen::VectorXd& frequency_hz) {
  const auto system = response::BuildDisturbanceSystem(model::AssembledModel::Assemble(spec));
  const int i = Find(system.input_names, source, "source");
  const int o = Find(system.output_names, output, "output");
  auto evaluator = response::FrfEvaluator::Create(system);
  const auto frf = evaluator.Evaluate(frequency_hz, response::ResponseQuantity::kReceptance);
  Eigen::VectorXcd h(frequency_hz.size());
  for (int k = 0; k < frequency_hz.size(); ++k) h(k) = frf(k, o, i);
  return h;
}

}  // namespace stagefit::disturbance
