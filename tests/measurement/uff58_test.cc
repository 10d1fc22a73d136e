#include "stagefit/measurement/uff58.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <functional>
#include <filesystem>
#include <random>

#include "stagefit/common/error.h"

namespace stagefit::measurement {
namespace {
namespace fs = std::filesystem;

// Values printed as E13.5 carry 6 significant digits: relative rounding error <= 5e-6.
constexpr double kE13Tolerance = 5e-6;
// Values printed as E20.12 carry 13 significant digits: relative rounding error <= 5e-13.
constexpr double kE20Tolerance = 5e-13;

fs::path UffDir() { return fs::path(STAGEFIT_SHARED_DATA_DIR) / "uff"; }

#define SKIP_WITHOUT_SHARED_DATA()                                                            \
  if (!fs::is_directory(UffDir())) {                                                          \
    GTEST_SKIP() << "shared UFF test files not found in " << UffDir()                         \
                 << " (they live beside the repository, in ../shared/data/uff)";              \
  }

void ExpectInputError(const std::function<void()>& f, const std::string& fragment) {
  try {
    f();
    ADD_FAILURE() << "expected InputError containing '" << fragment << "'";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos)
        << "message: " << e.what() << "\nexpected fragment: " << fragment;
  }
}

fs::path TempDir() {
  fs::path dir = fs::temp_directory_path() / ("stagefit_uff58_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

TEST(ReadUff58, AsciiTimeRecordReadsAllPoints) {
  SKIP_WITHOUT_SHARED_DATA();
  const auto records = ReadUff58(UffDir() / "Sample_UFF58_ascii.uff");
  ASSERT_EQ(records.size(), 1u);
  const UffRecord& r = records[0];
  EXPECT_EQ(r.function_type, uff_function::kTimeResponse);
  EXPECT_EQ(r.ordinate_type, UffOrdinateType::kRealSingle);
  EXPECT_EQ(r.num_points(), 79292);
  EXPECT_TRUE(r.even_abscissa);
  EXPECT_EQ(r.id[0], "Mic 01.0Scalar");
  EXPECT_EQ(r.response_entity, "Mic 01");
  EXPECT_EQ(r.response_direction, 1);
  EXPECT_EQ(r.abscissa.units_label, "s");
  EXPECT_EQ(r.ordinate.units_label, "Pa");
  EXPECT_EQ(r.x[0], 0.0);
  EXPECT_DOUBLE_EQ(r.x[1], 1.52588e-5);
  EXPECT_DOUBLE_EQ(r.x[79291], 79291 * 1.52588e-5);
  EXPECT_DOUBLE_EQ(r.real_y[0], -1.47553e-2);
  EXPECT_DOUBLE_EQ(r.real_y[79291], -4.31469e-3);
}

TEST(ReadUff58, BinarySingleRecordMatchesAsciiCopy) {
  SKIP_WITHOUT_SHARED_DATA();
  const auto ascii = ReadUff58(UffDir() / "Sample_UFF58_ascii.uff");
  const auto binary = ReadUff58(UffDir() / "Sample_UFF58b_bin.uff");
  ASSERT_EQ(binary.size(), 1u);
  ASSERT_EQ(binary[0].num_points(), 79292);
  EXPECT_EQ(binary[0].ordinate_type, UffOrdinateType::kRealSingle);
  EXPECT_EQ(binary[0].x, ascii[0].x);
  // The ASCII copy prints the same floats with 6 significant digits.
  for (int i = 0; i < 79292; ++i) {
    ASSERT_NEAR(binary[0].real_y[i], ascii[0].real_y[i],
                kE13Tolerance * std::abs(ascii[0].real_y[i]) + 1e-12)
        << "point " << i;
  }
}

TEST(ReadUff58, BinaryDoubleRecordHoldsSine) {
  SKIP_WITHOUT_SHARED_DATA();
  const auto records = ReadUff58(UffDir() / "binary8byte.uff");
  ASSERT_EQ(records.size(), 1u);
  const UffRecord& r = records[0];
  EXPECT_EQ(r.ordinate_type, UffOrdinateType::kRealDouble);
  EXPECT_EQ(r.num_points(), 250);
  EXPECT_DOUBLE_EQ(r.x[1], 0.01);
  EXPECT_DOUBLE_EQ(r.x[249], 2.49);
  EXPECT_EQ(r.response_entity, "sine 5 Hz");
  EXPECT_EQ(r.ordinate.units_label, "g");
  // A 5 Hz sine sampled at 100 Hz, stored from single precision: sin(pi/10) to ~1e-7.
  constexpr double kSingleSampleTolerance = 1e-6;
  EXPECT_EQ(r.real_y[0], 0.0);
  EXPECT_NEAR(r.real_y[1], std::sin(M_PI / 10.0), kSingleSampleTolerance);
  EXPECT_NEAR(r.real_y[5], 1.0, kSingleSampleTolerance);
}

TEST(ReadUff58, UnevenComplexPsdReadsAbscissaPerPoint) {
  SKIP_WITHOUT_SHARED_DATA();
  const auto records = ReadUff58(UffDir() / "sample_dataset58_psd.uff");
  ASSERT_EQ(records.size(), 1u);
  const UffRecord& r = records[0];
  EXPECT_EQ(r.function_type, uff_function::kPowerSpectralDensity);
  EXPECT_EQ(r.ordinate_type, UffOrdinateType::kComplexSingle);
  EXPECT_FALSE(r.even_abscissa);
  EXPECT_EQ(r.num_points(), 3201);
  EXPECT_EQ(r.x[0], 0.0);
  EXPECT_EQ(r.x[1], 1.0);
  EXPECT_EQ(r.x[3200], 3200.0);
  EXPECT_EQ(r.complex_y[1], std::complex<double>(1.255863e-6, 0.0));
  EXPECT_EQ(r.complex_y[3200], std::complex<double>(2.634827e-10, 0.0));
  EXPECT_EQ(r.ordinate.units_label, "g\xC2\xB2/Hz");
}

TEST(ReadUff58, NonAsciiHeaderByteIsReadAsLatin1) {
  SKIP_WITHOUT_SHARED_DATA();
  const auto records = ReadUff58(UffDir() / "non_ascii_header.uff");
  ASSERT_EQ(records.size(), 1u);
  const UffRecord& r = records[0];
  EXPECT_EQ(r.function_type, uff_function::kFrequencyResponseFunction);
  EXPECT_EQ(r.num_points(), 6);
  EXPECT_EQ(r.ordinate.units_label, "(1/N)*(m/s\xC2\xB2)");
  EXPECT_DOUBLE_EQ(r.x[1], 0.195313);
  EXPECT_EQ(r.complex_y[0], std::complex<double>(0.407994, 0.0));
  EXPECT_EQ(r.complex_y[5], std::complex<double>(3.75037, 2.93363));
}

TEST(ReadUff58, NonAsciiFrfConvertsToAccelerance) {
  SKIP_WITHOUT_SHARED_DATA();
  const FrfData data = ReadUffMeasurement(UffDir() / "non_ascii_header.uff");
  EXPECT_EQ(data.quantity, FrfQuantity::kAccelerance);
  ASSERT_EQ(data.num_frequencies(), 5);  // the 0 Hz line is dropped
  EXPECT_DOUBLE_EQ(data.frequency_hz[0], 0.195313);
  EXPECT_EQ(data.num_outputs(), 1);
  EXPECT_EQ(data.num_inputs(), 1);
  EXPECT_FALSE(data.outputs[0].has_geometry());
  EXPECT_EQ(data.frf[4](0, 0), std::complex<double>(3.75037, 2.93363));
}

TEST(ReadUff58, ShortLastDataLineIsAccepted) {
  SKIP_WITHOUT_SHARED_DATA();
  const auto records = ReadUff58(UffDir() / "time-history-not-all-columns-filled.uff");
  ASSERT_EQ(records.size(), 1u);
  EXPECT_EQ(records[0].num_points(), 13);
  EXPECT_DOUBLE_EQ(records[0].x[1], 5e-5);
  EXPECT_DOUBLE_EQ(records[0].real_y[0], -3.81956);
  EXPECT_DOUBLE_EQ(records[0].real_y[12], -5.84096);
  EXPECT_EQ(records[0].ordinate.units_label, "m/s\xC2\xB2");
}

TEST(ReadUff58, TruncatedFileIsReportedNotReadPast) {
  SKIP_WITHOUT_SHARED_DATA();
  const fs::path path = UffDir() / "dataset_milestone_in_header.uff";
  ExpectInputError([&] { ReadUff58(path); }, "dataset_milestone_in_header.uff");
  ExpectInputError([&] { ReadUff58(path); }, "declares 2508876 points");
  ExpectInputError([&] { ReadUff58(path); }, "truncated");
}

UffRecord MakeRecord(UffOrdinateType type, bool even, int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  UffRecord r;
  r.function_type = uff_function::kFrequencyResponseFunction;
  r.ordinate_type = type;
  r.even_abscissa = even;
  r.response_node = 12;
  r.response_direction = -3;
  r.reference_node = 7;
  r.reference_direction = 2;
  r.id[0] = "round trip";
  r.abscissa.label = "Frequency";
  r.abscissa.units_label = "Hz";
  r.ordinate.specific_data_type = uff_data_type::kAcceleration;
  r.ordinate.units_label = "m/s^2";
  r.abscissa_minimum = 0.5;
  r.abscissa_increment = 0.25;
  r.x.resize(n);
  double f = 0.3;
  for (int i = 0; i < n; ++i) {
    f += 0.1 + std::abs(u(rng));
    r.x[i] = even ? r.abscissa_minimum + i * r.abscissa_increment : f;
  }
  const bool single = type == UffOrdinateType::kRealSingle || type == UffOrdinateType::kComplexSingle;
  auto value = [&] {
    const double v = u(rng) * std::pow(10.0, std::floor(u(rng) / 2.0));
    return single ? static_cast<double>(static_cast<float>(v)) : v;
  };
  if (single && !even) {
    for (int i = 0; i < n; ++i) r.x[i] = static_cast<float>(r.x[i]);
  }
  if (r.is_complex()) {
    r.complex_y.resize(n);
    for (int i = 0; i < n; ++i) r.complex_y[i] = {value(), value()};
  } else {
    r.real_y.resize(n);
    for (int i = 0; i < n; ++i) r.real_y[i] = value();
  }
  return r;
}

std::vector<UffRecord> AllKinds() {
  std::vector<UffRecord> records;
  unsigned seed = 1;
  for (auto type : {UffOrdinateType::kRealSingle, UffOrdinateType::kRealDouble,
                    UffOrdinateType::kComplexSingle, UffOrdinateType::kComplexDouble}) {
    for (bool even : {true, false}) {
      for (int n : {1, 7, 13}) records.push_back(MakeRecord(type, even, n, seed++));
    }
  }
  return records;
}

void ExpectSameHeader(const UffRecord& a, const UffRecord& b) {
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(a.function_type, b.function_type);
  EXPECT_EQ(a.response_node, b.response_node);
  EXPECT_EQ(a.response_direction, b.response_direction);
  EXPECT_EQ(a.reference_node, b.reference_node);
  EXPECT_EQ(a.reference_direction, b.reference_direction);
  EXPECT_EQ(a.ordinate_type, b.ordinate_type);
  EXPECT_EQ(a.even_abscissa, b.even_abscissa);
  EXPECT_EQ(a.ordinate.specific_data_type, b.ordinate.specific_data_type);
  EXPECT_EQ(a.ordinate.units_label, b.ordinate.units_label);
  EXPECT_EQ(a.abscissa.label, b.abscissa.label);
}

TEST(WriteUff58, BinaryRoundTripIsBitIdenticalInBothByteOrders) {
  const auto records = AllKinds();
  for (auto encoding : {UffEncoding::kBinaryLittleEndian, UffEncoding::kBinaryBigEndian}) {
    const auto back = ParseUff58(FormatUff58(records, encoding), "memory");
    ASSERT_EQ(back.size(), records.size());
    for (std::size_t i = 0; i < records.size(); ++i) {
      SCOPED_TRACE("record " + std::to_string(i));
      ExpectSameHeader(records[i], back[i]);
      EXPECT_EQ(back[i].x, records[i].x);
      EXPECT_EQ(back[i].real_y, records[i].real_y);
      EXPECT_EQ(back[i].complex_y, records[i].complex_y);
    }
  }
}

TEST(WriteUff58, AsciiRoundTripKeepsPrintedPrecision) {
  const auto records = AllKinds();
  const auto back = ParseUff58(FormatUff58(records, UffEncoding::kAscii), "memory");
  ASSERT_EQ(back.size(), records.size());
  for (std::size_t i = 0; i < records.size(); ++i) {
    SCOPED_TRACE("record " + std::to_string(i));
    const UffRecord& a = records[i];
    const UffRecord& b = back[i];
    ExpectSameHeader(a, b);
    const double tol = a.is_double() ? kE20Tolerance : kE13Tolerance;
    ASSERT_EQ(b.num_points(), a.num_points());
    for (int k = 0; k < a.num_points(); ++k) {
      // Uneven abscissae are printed E13.5 even in double precision (the standard format).
      EXPECT_NEAR(b.x[k], a.x[k], kE13Tolerance * std::abs(a.x[k]));
      if (a.is_complex()) {
        EXPECT_NEAR(b.complex_y[k].real(), a.complex_y[k].real(), tol * std::abs(a.complex_y[k].real()));
        EXPECT_NEAR(b.complex_y[k].imag(), a.complex_y[k].imag(), tol * std::abs(a.complex_y[k].imag()));
      } else {
        EXPECT_NEAR(b.real_y[k], a.real_y[k], tol * std::abs(a.real_y[k]));
      }
    }
  }
}

TEST(WriteUff58, FileWriteIsReadBack) {
  const fs::path path = TempDir() / "records.uff";
  const auto records = AllKinds();
  WriteUff58(path, records, UffEncoding::kBinaryBigEndian);
  const auto back = ReadUff58(path);
  ASSERT_EQ(back.size(), records.size());
  EXPECT_EQ(back[5].complex_y, records[5].complex_y);
  fs::remove_all(path.parent_path());
}

FrfData MakeFrfData(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  FrfData d;
  d.source = "generated";
  const int nf = 9, nout = 3, nin = 2;
  d.frequency_hz.resize(nf);
  double f = 1.0;
  for (int k = 0; k < nf; ++k) d.frequency_hz[k] = (f += 1.0 + std::abs(u(rng)));
  for (int k = 0; k < nf; ++k) {
    d.frf.push_back(Eigen::MatrixXcd::Random(nout, nin) * std::exp(3.0 * u(rng)));
    Eigen::MatrixXd c(nout, nin);
    for (int i = 0; i < c.size(); ++i) c.data()[i] = 0.5 + 0.5 * std::abs(u(rng));
    d.coherence.push_back(c);
  }
  const char* outs[] = {"a1x", "3+Y", "a2z"};
  for (int i = 0; i < nout; ++i) {
    ChannelGeometry c;
    c.name = outs[i];
    c.direction_W = Eigen::Vector3d::Unit(i);
    d.outputs.push_back(c);
  }
  for (int j = 0; j < nin; ++j) {
    ChannelGeometry c;
    c.name = "h" + std::to_string(j + 1);
    c.direction_W = -Eigen::Vector3d::Unit(2 - j);
    d.inputs.push_back(c);
  }
  return d;
}

TEST(WriteUffMeasurement, BinaryRoundTripIsBitIdentical) {
  std::srand(7);
  const FrfData d = MakeFrfData(3);
  const fs::path path = TempDir() / "frf.uff";
  WriteUffMeasurement(path, d, UffEncoding::kBinaryLittleEndian);
  const FrfData back = ReadUffMeasurement(path);
  EXPECT_EQ(back.quantity, d.quantity);
  EXPECT_EQ(back.frequency_hz, d.frequency_hz);
  ASSERT_EQ(back.num_outputs(), 3);
  ASSERT_EQ(back.num_inputs(), 2);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(back.outputs[i].name, d.outputs[i].name);
  for (int j = 0; j < 2; ++j) EXPECT_EQ(back.inputs[j].name, d.inputs[j].name);
  EXPECT_EQ(back.inputs[1].direction_W, d.inputs[1].direction_W);
  for (int k = 0; k < d.num_frequencies(); ++k) {
    EXPECT_EQ(back.frf[k], d.frf[k]);
    EXPECT_EQ(back.coherence[k], d.coherence[k]);
  }
  fs::remove_all(path.parent_path());
}

TEST(ConvertUffToFrfData, NodeLocationsGiveGeometry) {
  std::srand(11);
  FrfData d = MakeFrfData(5);
  auto records = ConvertFrfDataToUff(d);
  UffFrfOptions options;
  options.nodes[3] = {"hexapod", Eigen::Vector3d(0.0, 0.14, -0.03)};
  const FrfData back = ConvertUffToFrfData(records, "memory", options);
  EXPECT_EQ(back.outputs[1].body, "hexapod");
  EXPECT_EQ(back.outputs[1].direction_W, Eigen::Vector3d(0, 1, 0));
  EXPECT_FALSE(back.outputs[0].has_geometry());
}

TEST(ConvertUffToFrfData, MissingPairIsAnInputError) {
  std::srand(13);
  auto records = ConvertFrfDataToUff(MakeFrfData(7));
  records.erase(records.begin());  // the first FRF
  ExpectInputError([&] { ConvertUffToFrfData(records, "memory"); }, "no FRF for response a1x");
}

TEST(ConvertUffToFrfData, RealFrfRecordIsAnInputError) {
  UffRecord r = MakeRecord(UffOrdinateType::kRealDouble, true, 5, 3);
  ExpectInputError([&] { ConvertUffToFrfData({r}, "memory"); }, "expected complex data");
}

TEST(ConvertUffToFrfData, UnknownQuantityIsAnInputError) {
  UffRecord r = MakeRecord(UffOrdinateType::kComplexDouble, true, 5, 3);
  r.ordinate.specific_data_type = uff_data_type::kGeneral;
  r.ordinate.units_label = "V/V";
  ExpectInputError([&] { ConvertUffToFrfData({r}, "memory"); }, "accelerance, mobility or receptance");
  UffFrfOptions options;
  options.quantity = FrfQuantity::kMobility;
  EXPECT_EQ(ConvertUffToFrfData({r}, "memory", options).quantity, FrfQuantity::kMobility);
}

// A small valid ASCII dataset that the bad-input cases below break one field at a time.
std::string ValidAscii() {
  UffRecord r = MakeRecord(UffOrdinateType::kRealSingle, true, 7, 21);
  return FormatUff58({r}, UffEncoding::kAscii);
}

std::string Replace(std::string s, const std::string& from, const std::string& to) {
  const std::size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << "test setup: '" << from << "' not in\n" << s;
  if (at != std::string::npos) s.replace(at, from.size(), to);
  return s;
}

std::vector<std::string> Lines(const std::string& s) {
  std::vector<std::string> lines;
  std::size_t pos = 0;
  while (pos < s.size()) {
    std::size_t e = s.find('\n', pos);
    lines.push_back(s.substr(pos, e - pos));
    pos = e + 1;
  }
  return lines;
}

std::string Join(const std::vector<std::string>& lines) {
  std::string s;
  for (const auto& l : lines) s += l + "\n";
  return s;
}

TEST(ParseUff58, BadInputIsAnInputErrorNamingTheProblem) {
  const std::string valid = ValidAscii();
  ASSERT_NO_THROW(ParseUff58(valid, "ok.uff"));
  auto lines = Lines(valid);
  ASSERT_EQ(lines.size(), 16u);  // -1, 58, 11 header records, 2 data lines, -1

  ExpectInputError([&] { ParseUff58("", "empty.uff"); }, "empty.uff");
  ExpectInputError([&] { ParseUff58("hello,world\n1,2\n", "x.uff"); },
                   "line 1: 'hello,world', expected the dataset delimiter");
  {
    auto l = lines;
    l.resize(9);
    ExpectInputError([&] { ParseUff58(Join(l), "short.uff"); }, "ends inside its header");
  }
  {
    auto l = lines;
    l[7].replace(0, 5, "  abc");
    ExpectInputError([&] { ParseUff58(Join(l), "r6.uff"); },
                     "line 8: record 6, columns 1-5 (function type): 'abc', expected an integer");
  }
  {
    auto l = lines;
    l[8].replace(0, 10, "         7");
    ExpectInputError([&] { ParseUff58(Join(l), "r7.uff"); }, "line 9: record 7");
    ExpectInputError([&] { ParseUff58(Join(l), "r7.uff"); }, "ordinate data type): 7");
  }
  {
    auto l = lines;
    l[8].replace(10, 10, "2000000000");
    ExpectInputError([&] { ParseUff58(Join(l), "huge.uff"); },
                     "declares 2000000000 points");
  }
  {
    auto l = lines;
    l[8].replace(10, 10, "         9");
    ExpectInputError([&] { ParseUff58(Join(l), "few.uff"); }, "declares 9 values");
  }
  {
    auto l = lines;
    l[8].replace(10, 10, "         5");
    ExpectInputError([&] { ParseUff58(Join(l), "many.uff"); }, "more data values than the 5 points");
  }
  {
    auto l = lines;
    l.pop_back();
    ExpectInputError([&] { ParseUff58(Join(l), "open.uff"); }, "without the closing '-1' delimiter");
  }
  {
    auto l = lines;
    l[13].replace(0, 13, "          NaN");
    ExpectInputError([&] { ParseUff58(Join(l), "nan.uff"); }, "line 14: data value 1 is not finite");
  }
  {
    auto l = lines;
    l[13].replace(0, 13, " 1.2.3E+00xyz");
    ExpectInputError([&] { ParseUff58(Join(l), "garbage.uff"); }, "line 14: data value in columns 1-13");
  }
  {
    auto l = lines;
    l[8].replace(20, 10, "         3");
    ExpectInputError([&] { ParseUff58(Join(l), "spacing.uff"); }, "abscissa spacing): 3");
  }
  {
    auto l = lines;
    l[9].replace(0, 10, "      x17 ");
    ExpectInputError([&] { ParseUff58(Join(l), "axis.uff"); }, "line 10: record 8");
  }
}

TEST(ParseUff58, BadBinaryHeaderIsAnInputError) {
  UffRecord r = MakeRecord(UffOrdinateType::kRealDouble, true, 7, 22);
  const std::string valid = FormatUff58({r}, UffEncoding::kBinaryLittleEndian);
  ASSERT_NO_THROW(ParseUff58(valid, "ok.uff"));
  // "    58b     1     2          11          56     0 ..." : byte order, format, lines, bytes.
  ExpectInputError([&] { ParseUff58(Replace(valid, "b     1", "b     3"), "bo.uff"); },
                   "byte ordering 3");
  ExpectInputError([&] { ParseUff58(Replace(valid, "          56", "          64"), "n.uff"); },
                   "declares 64 bytes of data");
  ExpectInputError([&] { ParseUff58(valid.substr(0, valid.size() - 20), "cut.uff"); },
                   "truncated");
  ExpectInputError([&] { ParseUff58(Replace(valid, "     2          11", "     1          11"), "vax.uff"); },
                   "floating-point format 1");
}

TEST(ParseUff58, OtherDatasetsAreSkipped) {
  const std::string other = "    -1\n   164\n         1  SI\n    -1\n";
  const auto records = ParseUff58(other + ValidAscii(), "mixed.uff");
  EXPECT_EQ(records.size(), 1u);
  ExpectInputError([&] { ParseUff58(other, "units-only.uff"); }, "holds no dataset 58");
}

}  // namespace
}  // namespace stagefit::measurement
