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
  const MeasurementFormat format = MeasurementFormatOf(path);
  // The geometry: --geometry, else a sidecar beside a .uff / .mat, else what the file holds.
  std::filesystem::path geometry = options.geometry;
  if (geometry.empty() && format != MeasurementFormat::kCsv) {
    const std::filesystem::path sidecar = GeometrySidecarPath(path);
    std::error_code ec;
    if (std::filesystem::exists(sidecar, ec)) geometry = sidecar;
  }
  const bool file_geometry_required = options.require_geometry && geometry.empty();
  FrfData data;
  switch (format) {
    case MeasurementFormat::kMat:
      data = ReadMatMeasurement(path, file_geometry_required);
      break;
    case MeasurementFormat::kCsv:
      data = ReadCsvMeasurement(path, file_geometry_required);
      break;
    case MeasurementFormat::kUff:
      data = ReadUffMeasurement(path, options.uff);
      break;
  }
  if (options.averages != 0) {
    if (options.averages < 2) {
      throw InputError("measurement '" + path.string() + "': --averages " + std::to_string(options.averages) +
                       ", expected the number of hits averaged, >= 2");
    }
    if (!data.has_coherence()) {
      throw InputError("measurement '" + path.string() + "': --averages " + std::to_string(options.averages) +
                       " given, but the file holds no coherence, expected one with it");
    }
    data.averages.assign(data.num_inputs(), options.averages);
  }
  if (!geometry.empty()) ApplyGeometryFile(geometry, &data, options.require_geometry);
  if (options.require_geometry) {
    for (const auto* channels : {&data.outputs, &data.inputs}) {
      for (const ChannelGeometry& c : *channels) {
        if (!c.has_geometry()) {
          throw InputError("measurement '" + path.string() + "': missing geometry for channel '" + c.name +
                           "' (give it with --geometry FILE.csv, a .geometry.csv beside the file, or, in a UFF "
                           "file, node coordinates in datasets 15 / 2411)");
        }
      }
    }
  }
  return data;
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
