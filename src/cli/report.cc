#include "report.h"

#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"
#include "stagefit/model/model_file.h"

namespace stagefit::cli {

model::ModelSpec LoadModelFromOptions(const CommonOptions& options) {
  return model::LoadModel(options.model_path);
}

std::string ModelSource(const CommonOptions& options) {
  return options.model_path.empty() ? "<embedded micro-station>" : options.model_path;
}

void WriteReport(const std::string& path, const nlohmann::json& report, const std::vector<std::string>& inputs) {
  std::vector<std::filesystem::path> input_paths(inputs.begin(), inputs.end());
  CheckNotAnInput(path, input_paths);
  WriteFileAtomically(path, report.dump(2) + "\n");
}

}  // namespace stagefit::cli
