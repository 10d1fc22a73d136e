// libFuzzer target: CSV measurements with their geometry sidecar, measurement::ReadCsvMeasurement.
// The input is split at its first NUL byte: the bytes before it are the CSV file, the bytes after
// it the sidecar "<stem>.geometry.csv". Without a NUL there is no sidecar.
#include <algorithm>

#include "fuzz_input.h"
#include "stagefit/measurement/csv_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::uint8_t* end = data + size;
  const std::uint8_t* separator = std::find(data, end, std::uint8_t{0});
  const auto path = stagefit::fuzz::WriteScratchFile(
      "measurement.csv", data, static_cast<std::size_t>(separator - data));
  if (separator != end) {
    stagefit::fuzz::WriteScratchFile("measurement.geometry.csv", separator + 1,
                                     static_cast<std::size_t>(end - separator - 1));
  } else {
    stagefit::fuzz::RemoveScratchFile("measurement.geometry.csv");
  }
  stagefit::fuzz::ReadAcceptingInputError(
      [&] { stagefit::measurement::ReadCsvMeasurement(path, /*require_geometry=*/false); });
  return 0;
}
