#include "stagefit/measurement/csv_file.h"

#include <gtest/gtest.h>

#include <fstream>

#include "measurement_test_data.h"
#include "stagefit/common/csv_meta.h"

namespace stagefit::measurement {
namespace {
namespace fs = std::filesystem;
using testing::ExpectInputError;
using testing::ExpectSameMeasurement;
using testing::MakeMeasurement;

class CsvFile : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = testing::MakeTempDir("csv"); }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path Write(const std::string& name, const std::string& csv,
                 const std::string& geometry = "") {
    const fs::path path = dir_ / name;
    std::ofstream(path) << csv;
    if (!geometry.empty()) std::ofstream(GeometrySidecarPath(path)) << geometry;
    return path;
  }

  fs::path dir_;
};

constexpr const char* kHeader = "freq_hz,output,input,re,im\n";

TEST_F(CsvFile, RoundTripIsBitIdentical) {
  const FrfData data = MakeMeasurement(31);
  const fs::path path = dir_ / "m.csv";
  WriteCsvMeasurement(path, data);
  EXPECT_TRUE(fs::exists(dir_ / "m.geometry.csv"));
  ExpectSameMeasurement(ReadCsvMeasurement(path, true), data);
}

// The hits averaged per input go to the meta sidecar, in the order the inputs first appear.
TEST_F(CsvFile, NumAveragesRoundTripThroughTheSidecar) {
  FrfData data = MakeMeasurement(33);
  data.averages = {4, 2};
  const fs::path path = dir_ / "avg.csv";
  WriteCsvMeasurement(path, data);
  ExpectSameMeasurement(ReadCsvMeasurement(path, true), data);
  // A hand-edited sidecar with a bad count names the sidecar, the field and the count.
  std::ofstream(CsvMetaPath(path), std::ios::trunc) << R"({"quantity": "accelerance", "num_averages": [4, 1.5]})";
  ExpectInputError([&] { ReadCsvMeasurement(path); }, "avg.meta.json': num_averages: 1.5, expected whole counts >= 2");
  std::ofstream(CsvMetaPath(path), std::ios::trunc) << R"({"quantity": "accelerance", "num_averages": "4 2"})";
  ExpectInputError([&] { ReadCsvMeasurement(path); }, "num_averages: \"4 2\", expected an array of counts");
  std::ofstream(CsvMetaPath(path), std::ios::trunc) << R"({"quantity": "accelerance", "num_averages": [4]})";
  ExpectInputError([&] { ReadCsvMeasurement(path); }, "num_averages: 1 counts, expected 2 (one per input");
}

TEST_F(CsvFile, RoundTripWithoutGeometryOrCoherence) {
  FrfData data = MakeMeasurement(32, false);
  data.coherence.clear();
  const fs::path path = dir_ / "plain.csv";
  WriteCsvMeasurement(path, data);
  ExpectSameMeasurement(ReadCsvMeasurement(path), data);
  ExpectInputError([&] { ReadCsvMeasurement(path, true); }, "missing geometry");
}

TEST_F(CsvFile, RowsInAnyOrderAndDefaultQuantity) {
  const fs::path path = Write("any.csv", std::string(kHeader) +
                                             "20,a,h,3,4\n10,b,h,5,6\n10,a,h,1,2\n20,b,h,7,8\n");
  ExpectInputError([&] { ReadCsvMeasurement(path); }, "line 4: freq_hz = 10 Hz for output 'a'");
  const fs::path ok = Write("ok.csv", std::string(kHeader) +
                                          "10,a,h,1,2\n20,a,h,3,4\n10,b,h,5,6\n20,b,h,7,8\n");
  const FrfData d = ReadCsvMeasurement(ok);
  EXPECT_EQ(d.quantity, FrfQuantity::kAccelerance);
  EXPECT_EQ(d.num_outputs(), 2);
  EXPECT_EQ(d.frf[1](1, 0), std::complex<double>(7, 8));
}

TEST_F(CsvFile, QuantityCommentIsRead) {
  const fs::path path = Write("q.csv", "# quantity: compliance\n" + std::string(kHeader) + "10,a,h,1,2\n");
  EXPECT_EQ(ReadCsvMeasurement(path).quantity, FrfQuantity::kReceptance);
}

// Header first (docs/csv-outputs.md): the written file's first line is the header, the quantity, the
// frame origin and the units are in "<stem>.meta.json", and reading it back restores them; an older
// file's comment lines win over a sidecar.
TEST_F(CsvFile, HeaderFirstWithTheQuantityInTheSidecar) {
  FrfData data = MakeMeasurement(33);
  data.quantity = FrfQuantity::kMobility;
  data.frame_origin_W = Eigen::Vector3d(0.01, -0.02, -0.03);
  const fs::path path = dir_ / "h.csv";
  WriteCsvMeasurement(path, data);
  std::ifstream in(path);
  std::string first;
  std::getline(in, first);
  EXPECT_EQ(first, "freq_hz,output,input,re,im,coherence");
  ASSERT_TRUE(fs::exists(dir_ / "h.meta.json"));
  const auto meta = ReadCsvMeta(path);
  ASSERT_TRUE(meta.has_value());
  EXPECT_EQ(meta->fields.at("quantity"), "mobility");
  ASSERT_EQ(meta->units.size(), 6u);
  EXPECT_EQ(meta->units[3], (std::pair<std::string, std::string>("re", "m/s/N")));
  const FrfData back = ReadCsvMeasurement(path, true);
  EXPECT_EQ(back.quantity, FrfQuantity::kMobility);
  ASSERT_TRUE(back.frame_origin_W.has_value());
  EXPECT_EQ(*back.frame_origin_W, *data.frame_origin_W);
  ExpectSameMeasurement(back, data);
  // A comment line of an older file wins over the sidecar.
  const fs::path old = Write("h2.csv", "# quantity: receptance\n" + std::string(kHeader) + "10,a,h,1,2\n");
  std::ofstream(dir_ / "h2.meta.json") << "{\"quantity\": \"accelerance\", \"units\": {}}";
  EXPECT_EQ(ReadCsvMeasurement(old).quantity, FrfQuantity::kReceptance);
}

TEST_F(CsvFile, BadInputIsAnInputErrorWithLineAndField) {
  ExpectInputError([&] { ReadCsvMeasurement(dir_ / "absent.csv"); }, "does not exist");
  ExpectInputError([&] { ReadCsvMeasurement(Write("h.csv", "f,out,in,re,im\n10,a,h,1,2\n")); },
                   "line 1: header 'f,out,in,re,im'");
  ExpectInputError([&] { ReadCsvMeasurement(Write("e.csv", "# quantity: mobility\n")); },
                   "no header line");
  ExpectInputError([&] { ReadCsvMeasurement(Write("n.csv", std::string(kHeader) + "10,a,h,1\n")); },
                   "line 2: 4 fields, expected 5");
  ExpectInputError([&] { ReadCsvMeasurement(Write("x.csv", std::string(kHeader) + "10,a,h,1,abc\n")); },
                   "line 2: column 'im': 'abc' is not a number");
  ExpectInputError([&] { ReadCsvMeasurement(Write("nan.csv", std::string(kHeader) + "10,a,h,nan,0\n")); },
                   "line 2: column 're': nan, expected a finite number");
  ExpectInputError(
      [&] { ReadCsvMeasurement(Write("dup.csv", std::string(kHeader) + "10,a,h,1,2\n10,a,h,1,2\n")); },
      "line 3: freq_hz = 10 Hz");
  ExpectInputError(
      [&] { ReadCsvMeasurement(Write("q.csv", "# quantity: inertance\n" + std::string(kHeader))); },
      "line 1: '# quantity: inertance'");
  ExpectInputError(
      [&] {
        ReadCsvMeasurement(Write("c.csv", "freq_hz,output,input,re,im,coherence\n10,a,h,1,2,1.2\n"));
      },
      "line 2: column 'coherence': 1.2, expected a value in [0, 1]");
  ExpectInputError(
      [&] {
        ReadCsvMeasurement(
            Write("miss.csv", std::string(kHeader) + "10,a,h,1,2\n10,b,g,1,2\n10,a,g,1,2\n"));
      },
      "no rows for output 'b' and input 'h'");
  ExpectInputError(
      [&] {
        ReadCsvMeasurement(Write("diff.csv", std::string(kHeader) + "10,a,h,1,2\n20,a,h,1,2\n"
                                                                    "10,b,h,1,2\n25,b,h,1,2\n"));
      },
      "line 5: frequency 2 of output 'b' and input 'h' is 25 Hz, expected 20 Hz");
  ExpectInputError(
      [&] { ReadCsvMeasurement(Write("neg.csv", std::string(kHeader) + "-10,a,h,1,2\n")); },
      "freq_hz[1] = -10 Hz, expected a finite frequency > 0");
  ExpectInputError(
      [&] {
        ReadCsvMeasurement(Write("dead.csv", std::string(kHeader) + "10,a,h,1,2\n10,b,h,0,0\n"));
      },
      "output channel 2 'b' is dead");
  ExpectInputError([&] { ReadCsvMeasurement(Write("q2.csv", std::string(kHeader) + "10,\"a,h,1,2\n")); },
                   "line 2: unterminated double quote");
}

TEST_F(CsvFile, BadGeometrySidecarIsAnInputError) {
  const std::string csv = std::string(kHeader) + "10,a,h,1,2\n";
  const std::string header = "kind,name,body,x,y,z,nx,ny,nz\n";
  ExpectInputError([&] { ReadCsvMeasurement(Write("g1.csv", csv, "kind,name\n")); },
                   "g1.geometry.csv', line 1: header 'kind,name'");
  ExpectInputError(
      [&] { ReadCsvMeasurement(Write("g2.csv", csv, header + "probe,a,hexapod,0,0,0,1,0,0\n")); },
      "line 2: column 'kind': 'probe', expected 'sensor' or 'impact'");
  ExpectInputError(
      [&] { ReadCsvMeasurement(Write("g3.csv", csv, header + "sensor,zz,hexapod,0,0,0,1,0,0\n")); },
      "line 2: sensor 'zz' is not an output of the CSV");
  ExpectInputError(
      [&] {
        ReadCsvMeasurement(
            Write("g4.csv", csv, header + "sensor,a,hexapod,0,0,0,1,0,0\nimpact,h,hexapod,0,0,,0,0,1\n"));
      },
      "line 3: impact 'h': column 'z' is empty, expected a number (missing geometry)");
  ExpectInputError(
      [&] {
        ReadCsvMeasurement(
            Write("g5.csv", csv, header + "sensor,a,hexapod,0,0,0,1,1,0\nimpact,h,hexapod,0,0,0,0,0,1\n"));
      },
      "line 2: sensor 'a': direction (nx, ny, nz) has length 1.41");
  ExpectInputError(
      [&] { ReadCsvMeasurement(Write("g6.csv", csv, header + "sensor,a,hexapod,0,0,0,1,0,0\n")); },
      "input 'h' of the CSV has no 'impact' row (missing geometry)");
  ExpectInputError(
      [&] { ReadCsvMeasurement(Write("g7.csv", csv, header + "sensor,a,hexapod,0,0,0,1,0,0,9\n")); },
      "line 2: 10 fields, expected 9");
}

}  // namespace
}  // namespace stagefit::measurement
