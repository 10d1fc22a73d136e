// Writes the generated seed files of tests/fuzz/corpus/ with the project's own writers: small
// measurements (.mat v5 and v7.3, CSV with and without sidecar, UFF 58 ASCII and 58b in both byte
// orders and several ordinate types) and small raw hammer files. The text seeds copied from shipped
// files are added by scripts/fuzz.sh --make-corpus, which runs this program.
// Usage: stagefit_fuzz_make_corpus <corpus folder>

#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "stagefit/measurement/csv_file.h"
#include "stagefit/measurement/mat_file.h"
#include "stagefit/measurement/raw_hammer_file.h"
#include "stagefit/measurement/uff58.h"

namespace stagefit::fuzz {
namespace {

namespace fs = std::filesystem;
using measurement::ChannelGeometry;
using measurement::FrfData;
using measurement::FrfQuantity;

// Nout = 2 sensors, Nin = 1 impact, Nf = 3 frequencies: small enough for a seed, large enough that
// every loop of a reader runs more than once.
FrfData SmallMeasurement(bool geometry, bool coherence) {
  FrfData d;
  d.quantity = FrfQuantity::kAccelerance;
  d.frequency_hz = Eigen::Vector3d(10.0, 20.0, 40.0);
  for (int k = 0; k < 3; ++k) {
    Eigen::MatrixXcd h(2, 1);
    h << std::complex<double>(1.5e-3 * (k + 1), -4.5e-4), std::complex<double>(-2e-4, 7e-5 * k);
    d.frf.push_back(h);
    if (coherence) d.coherence.push_back((Eigen::MatrixXd(2, 1) << 0.98, 0.5 + 0.1 * k).finished());
  }
  const char* names[] = {"a1x", "a1y"};
  for (int i = 0; i < 2; ++i) {
    ChannelGeometry c;
    c.name = names[i];
    if (geometry) {
      c.body = "hexapod";
      c.position_W = Eigen::Vector3d(0.0, 0.14, -0.03);
      c.direction_W = Eigen::Vector3d::Unit(i);
    }
    d.outputs.push_back(c);
  }
  ChannelGeometry h;
  h.name = "h1";
  if (geometry) {
    h.body = "hexapod";
    h.position_W = Eigen::Vector3d(0.14, 0.0, -0.03);
    h.direction_W = -Eigen::Vector3d::UnitZ();
  }
  d.inputs.push_back(h);
  if (geometry) d.frame_origin_W = Eigen::Vector3d(0.0, 0.0, -0.03);
  return d;
}

// One input, two hits of 32 samples each (the minimum record is 16): a decaying pulse response.
measurement::RawHammerData SmallRaw(int num_outputs, bool geometry) {
  measurement::RawHammerData raw;
  raw.sample_rate_hz = 1024.0;
  for (int i = 0; i < num_outputs; ++i) {
    ChannelGeometry c;
    c.name = "a" + std::to_string(i + 1) + "x";
    if (geometry) {
      c.body = "hexapod";
      c.position_W = Eigen::Vector3d(0.0, 0.14, -0.03);
      c.direction_W = Eigen::Vector3d::UnitX();
    }
    raw.outputs.push_back(c);
  }
  ChannelGeometry in;
  in.name = "h1";
  if (geometry) {
    in.body = "hexapod";
    in.position_W = Eigen::Vector3d(0.14, 0.0, -0.03);
    in.direction_W = -Eigen::Vector3d::UnitZ();
  }
  raw.inputs.push_back(in);
  const int ns = 32;
  raw.hits.resize(1);
  for (int h = 0; h < 2; ++h) {
    measurement::HammerHit hit;
    hit.force = Eigen::VectorXd::Zero(ns);
    hit.force.segment(2 + h, 3) << 40.0, 100.0, 35.0;
    hit.response.resize(ns, num_outputs);
    for (int s = 0; s < ns; ++s) {
      for (int i = 0; i < num_outputs; ++i) {
        hit.response(s, i) = std::exp(-0.2 * s) * std::sin(0.7 * s + i) * (1.0 + 0.1 * h);
      }
    }
    raw.hits[0].push_back(hit);
  }
  if (geometry) {
    raw.response_full_scale = Eigen::VectorXd::Constant(num_outputs, 50.0);
    raw.force_full_scale = Eigen::VectorXd::Constant(1, 500.0);
    raw.frame_origin_W = Eigen::Vector3d(0.0, 0.0, -0.03);
  }
  return raw;
}

std::string ReadBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void WriteBytes(const fs::path& path, const std::string& bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << bytes;
  std::printf("%8zu  %s\n", bytes.size(), path.string().c_str());
}

// The CSV fuzz target's input: the CSV, a NUL byte, the sidecar (when there is one).
void WriteCsvSeed(const fs::path& out, const fs::path& scratch, const FrfData& data, bool sidecar) {
  const fs::path csv = scratch / "seed.csv";
  measurement::WriteCsvMeasurement(csv, data);
  std::string bytes = ReadBytes(csv);
  if (sidecar) bytes += std::string(1, '\0') + ReadBytes(measurement::GeometrySidecarPath(csv));
  WriteBytes(out, bytes);
}

void MakeCorpus(const fs::path& corpus) {
  const fs::path scratch = fs::temp_directory_path() / "stagefit-make-corpus";
  fs::create_directories(scratch);
  const FrfData full = SmallMeasurement(true, true);
  const FrfData bare = SmallMeasurement(false, false);

  const fs::path mat = corpus / "mat_measurement_fuzz";
  measurement::WriteMatMeasurement(scratch / "m.mat", full, measurement::MatVersion::kV5);
  WriteBytes(mat / "v5_geometry_coherence.mat", ReadBytes(scratch / "m.mat"));
  measurement::WriteMatMeasurement(scratch / "m.mat", bare, measurement::MatVersion::kV5);
  WriteBytes(mat / "v5_bare.mat", ReadBytes(scratch / "m.mat"));
  if (measurement::IsMatV73Supported()) {
    measurement::WriteMatMeasurement(scratch / "m.mat", bare, measurement::MatVersion::kV73);
    WriteBytes(mat / "v73_bare.mat", ReadBytes(scratch / "m.mat"));
  }

  const fs::path raw = corpus / "raw_hammer_fuzz";
  measurement::WriteRawHammerFile(scratch / "r.mat", SmallRaw(2, true), measurement::MatVersion::kV5);
  WriteBytes(raw / "v5_geometry.mat", ReadBytes(scratch / "r.mat"));
  measurement::WriteRawHammerFile(scratch / "r.mat", SmallRaw(1, false), measurement::MatVersion::kV5);
  WriteBytes(raw / "v5_bare.mat", ReadBytes(scratch / "r.mat"));
  if (measurement::IsMatV73Supported()) {
    measurement::WriteRawHammerFile(scratch / "r.mat", SmallRaw(1, false), measurement::MatVersion::kV73);
    WriteBytes(raw / "v73_bare.mat", ReadBytes(scratch / "r.mat"));
  }

  const fs::path csv = corpus / "csv_measurement_fuzz";
  WriteCsvSeed(csv / "with_sidecar.csv", scratch, full, true);
  WriteCsvSeed(csv / "no_sidecar.csv", scratch, bare, false);

  using measurement::UffEncoding;
  using measurement::UffOrdinateType;
  const fs::path uff = corpus / "uff_measurement_fuzz";
  const auto records = measurement::ConvertFrfDataToUff(full);
  WriteBytes(uff / "ascii_double.uff", measurement::FormatUff58(records, UffEncoding::kAscii));
  WriteBytes(uff / "binary_le.uff", measurement::FormatUff58(records, UffEncoding::kBinaryLittleEndian));
  WriteBytes(uff / "binary_be.uff", measurement::FormatUff58(records, UffEncoding::kBinaryBigEndian));
  // Single precision with an uneven abscissa: the other data-record layouts.
  auto single = measurement::ConvertFrfDataToUff(bare);
  for (auto& r : single) {
    r.ordinate_type = r.is_complex() ? UffOrdinateType::kComplexSingle : UffOrdinateType::kRealSingle;
    r.even_abscissa = false;
  }
  WriteBytes(uff / "ascii_single_uneven.uff", measurement::FormatUff58(single, UffEncoding::kAscii));
  WriteBytes(uff / "binary_single_uneven.uff",
             measurement::FormatUff58(single, UffEncoding::kBinaryLittleEndian));
  fs::remove_all(scratch);
}

}  // namespace
}  // namespace stagefit::fuzz

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <corpus folder>\n", argv[0]);
    return 1;
  }
  try {
    stagefit::fuzz::MakeCorpus(argv[1]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
  return 0;
}
