// libFuzzer target: disturbance record and PSD tables (CSV), disturbance::ReadCsvTable, followed by
// the sample-rate check every time record goes through (CalcSampleRate on the first column).
#include "fuzz_input.h"
#include "stagefit/disturbance/record_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = stagefit::fuzz::WriteScratchFile("record.csv", data, size);
  stagefit::fuzz::ReadAcceptingInputError([&] {
    const stagefit::disturbance::CsvTable table = stagefit::disturbance::ReadCsvTable(path);
    if (!table.column_names.empty()) {
      stagefit::disturbance::CalcSampleRate(table, table.column_names.front());
    }
  });
  return 0;
}
