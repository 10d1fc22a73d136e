// libFuzzer target: UFF 58 / 58b files, measurement::ReadUffMeasurement (ReadUff58, then the
// conversion of the FRF records to a measurement).
#include "fuzz_input.h"
#include "stagefit/measurement/uff58.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = stagefit::fuzz::WriteScratchFile("measurement.uff", data, size);
  stagefit::fuzz::ReadAcceptingInputError([&] { stagefit::measurement::ReadUffMeasurement(path); });
  return 0;
}
