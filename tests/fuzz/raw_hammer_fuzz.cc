// libFuzzer target: raw hammer time data in .mat files, measurement::ReadRawHammerFile.
#include "fuzz_input.h"
#include "stagefit/measurement/raw_hammer_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (stagefit::fuzz::SkipMatV73(data, size)) return 0;
  const auto path = stagefit::fuzz::WriteScratchFile("raw.mat", data, size);
  stagefit::fuzz::ReadAcceptingInputError([&] { stagefit::measurement::ReadRawHammerFile(path); });
  return 0;
}
