// libFuzzer target: model files (TOML), model::ReadModelFile.
#include "fuzz_input.h"
#include "stagefit/model/model_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = stagefit::fuzz::WriteScratchFile("model.toml", data, size);
  stagefit::fuzz::ReadAcceptingInputError([&] { stagefit::model::ReadModelFile(path); });
  return 0;
}
