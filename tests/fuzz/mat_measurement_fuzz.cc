// libFuzzer target: measurements in .mat files (v5 and v7.3, through matio),
// measurement::ReadMatMeasurement, which reads every variable with ReadMatFile first.
#include "fuzz_input.h"
#include "stagefit/measurement/mat_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (stagefit::fuzz::SkipMatV73(data, size)) return 0;
  const auto path = stagefit::fuzz::WriteScratchFile("measurement.mat", data, size);
  stagefit::fuzz::ReadAcceptingInputError(
      [&] { stagefit::measurement::ReadMatMeasurement(path, /*require_geometry=*/false); });
  return 0;
}
