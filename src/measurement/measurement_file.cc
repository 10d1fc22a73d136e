#include "stagefit/measurement/measurement_file.h"

#include <cctype>
#include <string>

#include "stagefit/common/error.h"
#include "stagefit/measurement/csv_file.h"

namespace stagefit::measurement {

MeasurementFormat MeasurementFormatOf(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".mat") return MeasurementFormat::kMat;
  if (ext == ".csv") return MeasurementFormat::kCsv;
  if (ext == ".uff" || ext == ".unv") return MeasurementFormat::kUff;
  throw InputError("measurement file '" + path.string() + "': extension '" +
                   path.extension().string() + "' is not a measurement format, expected .mat, "
                   ".csv, .uff or .unv");
}

FrfData ReadMeasurement(const std::filesystem::path& path, const MeasurementReadOptions& options) {
  switch (MeasurementFormatOf(path)) {
    case MeasurementFormat::kMat:
      return ReadMatMeasurement(path, options.require_geometry);
    case MeasurementFormat::kCsv:
      return ReadCsvMeasurement(path, options.require_geometry);
    case MeasurementFormat::kUff: {
      FrfData data = ReadUffMeasurement(path, options.uff);
      if (options.require_geometry) {
        for (const auto* channels : {&data.outputs, &data.inputs}) {
          for (const ChannelGeometry& c : *channels) {
            if (!c.has_geometry()) {
              throw InputError("UFF file '" + path.string() + "': missing geometry for channel '" +
                               c.name + "' (UFF 58 holds node numbers only; give node locations)");
            }
          }
        }
      }
      return data;
    }
  }
  STAGEFIT_ASSERT(false, "unhandled measurement format");
}

void WriteMeasurement(const std::filesystem::path& path, const FrfData& data,
                      const MeasurementWriteOptions& options) {
  switch (MeasurementFormatOf(path)) {
    case MeasurementFormat::kMat:
      WriteMatMeasurement(path, data, options.mat_version);
      return;
    case MeasurementFormat::kCsv:
      WriteCsvMeasurement(path, data);
      return;
    case MeasurementFormat::kUff:
      WriteUffMeasurement(path, data, options.uff_encoding);
      return;
  }
}

}  // namespace stagefit::measurement
