// UFF files as acquisition systems write them: node coordinates in datasets 15 and 2411 in the units
// of dataset 164, FRFs whose units labels are g, mm/s^2 or lbf, raw time records (function type 1)
// for estimate, and the field files of several vendors (../shared/data/uff).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "stagefit/common/error.h"
#include "stagefit/measurement/csv_file.h"
#include "stagefit/measurement/hammer_estimation.h"
#include "stagefit/measurement/measurement_file.h"
#include "stagefit/measurement/raw_hammer_file.h"
#include "stagefit/measurement/uff58.h"
#include "stagefit/measurement/uff_time.h"

namespace stagefit::measurement {
namespace {
namespace fs = std::filesystem;

fs::path Dir() {
  const fs::path dir = fs::temp_directory_path() / ("stagefit_uff_units_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

FrfData ShippedFrf() { return ReadMeasurement(fs::path(STAGEFIT_SOURCE_DIR) / "measurements/microstation-12x10/frf.mat"); }

// Dataset 164 in millimetres (length factor 1000: file value / 1000 = m) and the nodes of the channels
// of ConvertFrfDataToUff (outputs 1..Nout, inputs 1001..) in dataset 2411 (D25.16) or 15 (E13.5), mm.
std::string NodesText(const FrfData& d, int dataset) {
  std::string text = "    -1\n   164\n         2  mm (milli newton)   2\n"
                     "  1.00000000000000000D+03  1.00000000000000000D+00  1.00000000000000000D+00\n"
                     "  2.73150000000000000D+02\n    -1\n";
  text += "    -1\n" + std::string(dataset == 2411 ? "  2411\n" : "    15\n");
  char line[200];
  auto add = [&](int node, const Eigen::Vector3d& p_m) {
    const Eigen::Vector3d mm = 1e3 * p_m;
    if (dataset == 2411) {
      std::snprintf(line, sizeof line, "%10d%10d%10d%10d\n%25.16E%25.16E%25.16E\n", node, 1, 1, 11, mm.x(), mm.y(), mm.z());
    } else {
      std::snprintf(line, sizeof line, "%10d%10d%10d%10d%13.5E%13.5E%13.5E\n", node, 0, 0, 11, mm.x(), mm.y(), mm.z());
    }
    std::string s(line);
    if (dataset == 2411) {
      for (std::size_t e = s.find('E', s.find('\n')); e != std::string::npos; e = s.find('E', e + 1)) s[e] = 'D';
    }
    text += s;
  };
  for (int o = 0; o < d.num_outputs(); ++o) add(1 + o, d.outputs[o].position_W);
  for (int j = 0; j < d.num_inputs(); ++j) add(1001 + j, d.inputs[j].position_W);
  text += "    -1\n";
  return text;
}

TEST(UffNodes, Datasets2411And15GiveTheChannelsTheirPositionsInMetres) {
  const FrfData d = ShippedFrf();
  const std::string frf = FormatUff58(ConvertFrfDataToUff(d), UffEncoding::kBinaryLittleEndian);
  for (int dataset : {2411, 15}) {
    const UffFile file = ParseUffFile(NodesText(d, dataset) + frf, "nodes.uff");
    ASSERT_TRUE(file.has_units);
    EXPECT_EQ(file.length_factor, 1000.0);
    ASSERT_EQ(file.nodes_m.size(), static_cast<std::size_t>(d.num_outputs() + d.num_inputs()));
    const double tolerance = dataset == 2411 ? 1e-15 : 5e-6 * 0.14;  // D25.16 vs E13.5
    EXPECT_NEAR(file.nodes_m.at(1).y(), d.outputs[0].position_W.y(), tolerance) << dataset;
    EXPECT_NEAR(file.nodes_m.at(1001).z(), d.inputs[0].position_W.z(), tolerance) << dataset;
  }
  // Through the measurement reader: the nodes put the channels on the node body, and the compliance
  // projection has what it needs.
  const fs::path path = Dir() / "nodes.uff";
  std::ofstream(path, std::ios::binary) << NodesText(d, 2411) + frf;
  MeasurementReadOptions options;
  options.uff.node_body = "hexapod";
  const FrfData back = ReadMeasurement(path, options);
  ASSERT_EQ(back.num_outputs(), d.num_outputs());
  for (int o = 0; o < d.num_outputs(); ++o) {
    EXPECT_EQ(back.outputs[o].body, "hexapod");
    EXPECT_LT((back.outputs[o].position_W - d.outputs[o].position_W).norm(), 1e-15);
    EXPECT_EQ(back.outputs[o].direction_W, d.outputs[o].direction_W);
  }
  for (int k = 0; k < d.num_frequencies(); ++k) EXPECT_EQ(back.frf[k], d.frf[k]);
  fs::remove_all(path.parent_path());
}

TEST(UffUnits, DataInGAndLbfEqualTheSameDataInSi) {
  const FrfData d = ShippedFrf();
  std::vector<UffRecord> records = ConvertFrfDataToUff(d);
  for (const char* labels : {"g", "g/lbf", "mm/s^2", "in/s2"}) {
    std::vector<UffRecord> scaled = records;
    const std::string label(labels);
    double factor = label == "g" ? 9.80665 : label == "g/lbf" ? 9.80665 / 4.4482216152605 : label == "mm/s^2" ? 1e-3 : 0.0254;
    for (UffRecord& r : scaled) {
      if (r.function_type != uff_function::kFrequencyResponseFunction) continue;
      r.ordinate.units_label = label;
      r.ordinate.specific_data_type = uff_data_type::kUnknown;
      r.complex_y /= factor;
    }
    const fs::path path = Dir() / "scaled.uff";
    WriteUff58(path, scaled, UffEncoding::kBinaryLittleEndian);
    const FrfData back = ReadUffMeasurement(path);
    EXPECT_EQ(back.quantity, FrfQuantity::kAccelerance) << label;
    double worst = 0;
    for (int k = 0; k < d.num_frequencies(); ++k) {
      worst = std::max(worst, ((back.frf[k] - d.frf[k]).cwiseAbs().array() / d.frf[k].cwiseAbs().array()).maxCoeff());
    }
    EXPECT_LT(worst, 1e-14) << label;
    std::string how;
    EXPECT_NE(UffFrfScaleToSi(scaled[0], UffFile{}, &how), 1.0);
    EXPECT_NE(how.find(label), std::string::npos) << how;
    fs::remove_all(path.parent_path());
  }
  // Without a label, dataset 164's factors and the records' exponents: mm and mN.
  UffFile mm;
  mm.has_units = true;
  mm.length_factor = 1000.0;
  mm.force_factor = 1000.0;
  UffRecord r = records[0];
  r.ordinate.units_label = "NONE";
  r.ordinate.specific_data_type = uff_data_type::kAcceleration;
  r.ordinate.length_unit_exponent = 1;
  r.ordinate_denominator.force_unit_exponent = 1;
  EXPECT_DOUBLE_EQ(UffFrfScaleToSi(r, mm), 1.0);  // (mm/s^2) / mN = (1e-3 m/s^2) / (1e-3 N)
  mm.force_factor = 1.0;
  EXPECT_DOUBLE_EQ(UffFrfScaleToSi(r, mm), 1e-3);
}

TEST(UffGeometry, ASidecarOrAGeometryFileGivesTheChannelsTheirGeometry) {
  const FrfData d = ShippedFrf();
  const fs::path dir = Dir();
  WriteUffMeasurement(dir / "m.uff", d, UffEncoding::kBinaryLittleEndian);
  EXPECT_FALSE(ReadMeasurement(dir / "m.uff").outputs[0].has_geometry());
  // The geometry CSV of the same data (the CSV writer's sidecar), beside the .uff.
  WriteMeasurement(dir / "m.csv", d);
  fs::copy_file(dir / "m.geometry.csv", dir / "g.csv");
  const FrfData with_sidecar = ReadMeasurement(dir / "m.uff");
  ASSERT_TRUE(with_sidecar.outputs[0].has_geometry());
  EXPECT_EQ(with_sidecar.outputs[0].position_W, d.outputs[0].position_W);
  fs::remove(dir / "m.geometry.csv");
  MeasurementReadOptions options;
  options.geometry = dir / "g.csv";
  options.require_geometry = true;
  const FrfData with_file = ReadMeasurement(dir / "m.uff", options);
  EXPECT_EQ(with_file.inputs[3].direction_W, d.inputs[3].direction_W);
  // A geometry file that misses a channel names it.
  std::ofstream(dir / "short.csv") << "kind,name,body,x,y,z,nx,ny,nz\nsensor,a1x,hexapod,0,0.14,-0.03,1,0,0\n";
  options.geometry = dir / "short.csv";
  try {
    ReadMeasurement(dir / "m.uff", options);
    ADD_FAILURE() << "a geometry file without every channel was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("short.csv"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("has no 'sensor' row"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

TEST(UffTime, EstimateOnUffTimeRecordsEqualsEstimateOnTheSameMat) {
  const RawHammerData raw = ReadRawHammerFile(fs::path(STAGEFIT_SOURCE_DIR) / "measurements/microstation-12x10/raw.mat");
  const EstimationSummary reference = EstimateFrf(raw);
  for (UffEncoding encoding : {UffEncoding::kBinaryLittleEndian, UffEncoding::kAscii}) {
    const UffFile file = ParseUffFile(FormatUff58(ConvertRawHammerToUff(raw), encoding), "raw.uff");
    const RawHammerData back = ConvertUffToRawHammer(file, "raw.uff");
    ASSERT_EQ(back.num_outputs(), raw.num_outputs());
    ASSERT_EQ(back.num_inputs(), raw.num_inputs());
    EXPECT_EQ(back.outputs[5].name, raw.outputs[5].name);
    EXPECT_EQ(back.inputs[2].name, raw.inputs[2].name);
    EXPECT_EQ(back.hits[0].size(), raw.hits[0].size());
    const EstimationSummary estimated = EstimateFrf(back);
    ASSERT_EQ(estimated.frf.num_frequencies(), reference.frf.num_frequencies());
    double worst = 0;
    for (int k = 0; k < reference.frf.num_frequencies(); ++k) {
      worst = std::max(worst, (estimated.frf.frf[k] - reference.frf.frf[k]).cwiseAbs().maxCoeff() /
                                  reference.frf.frf[k].cwiseAbs().maxCoeff());
    }
    // Binary 58b keeps every double; ASCII E20.12 keeps 13 significant digits of every sample.
    EXPECT_LT(worst, encoding == UffEncoding::kAscii ? 1e-10 : 1e-13);
  }
  // Responses in g and a force in lbf: the same FRFs.
  std::vector<UffRecord> records = ConvertRawHammerToUff(raw);
  for (UffRecord& r : records) {
    if (r.ordinate.units_label == "N") {
      r.ordinate.units_label = "lbf";
      r.real_y /= 4.4482216152605;
    } else {
      r.ordinate.units_label = "g";
      r.real_y /= 9.80665;
    }
  }
  UffFile file;
  file.records = records;
  const EstimationSummary in_g = EstimateFrf(ConvertUffToRawHammer(file, "g.uff"));
  double worst = 0;
  for (int k = 0; k < reference.frf.num_frequencies(); ++k) {
    worst = std::max(worst, (in_g.frf.frf[k] - reference.frf.frf[k]).cwiseAbs().maxCoeff() /
                                reference.frf.frf[k].cwiseAbs().maxCoeff());
  }
  EXPECT_LT(worst, 1e-12);
  // A hit without its force record is named.
  records.erase(records.begin());
  file.records = records;
  try {
    ConvertUffToRawHammer(file, "noforce.uff");
    ADD_FAILURE() << "a hit without force was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("load case 1: no force record"), std::string::npos) << e.what();
  }
}

TEST(UffFieldFiles, EveryVendorFileParsesOrIsReportedAsTruncated) {
  const fs::path dir = fs::path(STAGEFIT_SHARED_DATA_DIR) / "uff";
  if (!fs::is_directory(dir)) GTEST_SKIP() << "shared UFF field files not found in " << dir;
  int parsed = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (name == "dataset_milestone_in_header.uff") {
      EXPECT_THROW(ReadUffFile(entry.path()), InputError);
      continue;
    }
    const UffFile file = ReadUffFile(entry.path());
    EXPECT_FALSE(file.records.empty()) << name;
    ++parsed;
    // Every time record of a field file reads as raw data when its channels form hits; a single
    // microphone record has no force, which must be reported, not guessed.
    bool time = false;
    for (const auto& r : file.records) time = time || r.function_type == uff_function::kTimeResponse;
    if (time) {
      EXPECT_THROW(ConvertUffToRawHammer(file, name), InputError) << name;
    }
  }
  EXPECT_GE(parsed, 6);
}

}  // namespace
}  // namespace stagefit::measurement
