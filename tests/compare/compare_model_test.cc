#include "stagefit/compare/compare_model.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <unistd.h>

#include "compare_test_util.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"

namespace stagefit::compare {
namespace {

int CountLines(const std::string& text) {
  int n = 0;
  for (char c : text) n += c == '\n';
  return n;
}

class CompareModelTest : public ::testing::Test {
 protected:
  void SetUp() override {
    spec_ = model::DefaultModelSpec();
    data_ = testing::MakeSyntheticMeasurement(spec_, testing::LogFrequencies(5.0, 500.0, 300));
    softer_ = spec_;
    model::SetParameter(softer_, model::FindParameter(softer_, "hexapod.k.Rx"), 1.2e6);
  }
  model::ModelSpec spec_, softer_;
  measurement::FrfData data_;
};

TEST_F(CompareModelTest, SummaryHoldsComplianceAndRawComparisons) {
  const CompareSummary summary = CompareModel(softer_, data_);
  EXPECT_EQ(summary.comparison.space(), ComparisonSpace::kCompliance);
  EXPECT_NEAR(summary.result.error, summary.comparison.Error(softer_), 1e-12);
  ASSERT_TRUE(summary.raw.has_value());
  EXPECT_TRUE(summary.raw_skipped.empty());
  EXPECT_GT(summary.raw_result->error, 0.0);
  // A softer hexapod tilt: the Rx/Mx element carries more error than Dz/Fz, which it does not touch
  // below the tilt mode.
  double rx = -1, dz = -1;
  for (const auto& el : summary.result.elements) {
    if (el.name == "Rx/Mx") rx = el.error;
    if (el.name == "Dz/Fz") dz = el.error;
  }
  EXPECT_GT(rx, 10 * dz);
  const std::string report = summary.BriefReport();
  EXPECT_NE(report.find("error = "), std::string::npos);
  EXPECT_NE(report.find("mode pairing"), std::string::npos);
}

TEST_F(CompareModelTest, TablesHaveOneRowPerElementFrequencyAndBand) {
  const CompareSummary summary = CompareModel(softer_, data_);
  const int ne = static_cast<int>(summary.comparison.used_elements().size());
  const int nf = summary.comparison.num_frequencies();
  const int nb = static_cast<int>(summary.result.bands.size());
  const std::string frf = FormatFrfTable(summary.comparison, summary.result);
  EXPECT_EQ(CountLines(frf), 1 + ne * nf);
  EXPECT_EQ(frf.rfind("freq_hz,element,output,input,meas_re,meas_im,model_re,model_im,", 0), 0u);
  EXPECT_EQ(CountLines(FormatElementTable(summary.result, summary.comparison)), 1 + ne);
  EXPECT_EQ(CountLines(FormatBandTable(summary.result)), 1 + nb);
  EXPECT_EQ(CountLines(FormatElementBandTable(summary.result)), 1 + ne * nb);
  const auto& modes = summary.modes;
  EXPECT_EQ(CountLines(FormatModeTable(modes)),
            1 + static_cast<int>(modes.pairs.size() + modes.unpaired_measured.size() + modes.unpaired_model.size()));
}

TEST_F(CompareModelTest, WritesEveryTableIntoTheDirectory) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("stagefit_compare_tables_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  const CompareSummary summary = CompareModel(softer_, data_);
  const auto written = WriteCompareTables(dir, summary);
  EXPECT_EQ(written.size(), 7u);
  for (const auto& path : written) EXPECT_TRUE(std::filesystem::is_regular_file(path)) << path;
  std::ifstream in(dir / "compare_elements.csv");
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), FormatElementTable(summary.result, summary.comparison));
  std::filesystem::remove_all(dir);
}

TEST_F(CompareModelTest, RawSpaceMakesNoSecondComparison) {
  CompareOptions options;
  options.comparison.space = ComparisonSpace::kRaw;
  const CompareSummary summary = CompareModel(spec_, data_, options);
  EXPECT_FALSE(summary.raw.has_value());
  EXPECT_LT(summary.result.error, 1e-8);
}

}  // namespace
}  // namespace stagefit::compare
