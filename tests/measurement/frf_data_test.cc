#include "stagefit/measurement/frf_data.h"

#include <gtest/gtest.h>

#include "measurement_test_data.h"

namespace stagefit::measurement {
namespace {
using testing::ExpectInputError;
using testing::MakeMeasurement;

TEST(FrfQuantity, ParsesNamesAndCompliance) {
  EXPECT_EQ(ParseFrfQuantity("accelerance"), FrfQuantity::kAccelerance);
  EXPECT_EQ(ParseFrfQuantity("compliance"), FrfQuantity::kReceptance);
  EXPECT_FALSE(ParseFrfQuantity("Mobility").has_value());
  EXPECT_EQ(ToString(FrfQuantity::kMobility), "mobility");
}

TEST(Validate, AcceptsConsistentData) { EXPECT_NO_THROW(Validate(MakeMeasurement(1))); }

TEST(Validate, RejectsEachInconsistency) {
  const FrfData good = MakeMeasurement(2);
  auto check = [&](auto edit, const std::string& fragment) {
    FrfData d = good;
    d.source = "m.mat";
    edit(d);
    ExpectInputError([&] { Validate(d); }, fragment);
  };
  check([](FrfData& d) { d.frequency_hz.resize(0); d.frf.clear(); d.coherence.clear(); }, "'m.mat': freq_hz: no frequencies");
  check([](FrfData& d) { d.frequency_hz[0] = 0.0; }, "freq_hz[1] = 0 Hz, expected a finite frequency > 0");
  check([](FrfData& d) { d.frequency_hz[4] = d.frequency_hz[3]; }, "expected strictly increasing");
  check([](FrfData& d) { d.frf.pop_back(); }, "frf: 10 frequency slices, expected 11");
  check([](FrfData& d) { d.frf[2].resize(2, 2); }, "frf at frequency 3: size 2 x 2, expected 3 x 2");
  check([](FrfData& d) { d.frf[1](0, 1) = {0.0, INFINITY}; }, "frf(1, 2, 2)");
  check([](FrfData& d) { d.coherence[0](2, 1) = -0.1; }, "coherence(3, 2, 1) = -0.1");
  check([](FrfData& d) { d.outputs[1].name = d.outputs[0].name; }, "is used twice");
  check([](FrfData& d) { d.inputs[0].direction_W *= 1.01; }, "direction has length 1.01");
  check([](FrfData& d) { d.frame_origin_W = Eigen::Vector3d(NAN, 0, 0); }, "frame_origin");
  check([](FrfData& d) { for (auto& h : d.frf) h.col(1).setZero(); }, "input 2 'h2' is dead");
  check([](FrfData& d) { d.averages = {3}; }, "num_averages: 1 counts, expected 2 (one per input)");
  check([](FrfData& d) { d.averages = {3, 1}; }, "num_averages(2) = 1, expected a count >= 2");
  check([](FrfData& d) { d.averages = {3, 3}; d.coherence.clear(); }, "num_averages: given without coherence");
}

// The coherence of an estimate averaged from n records, from their ordinary coherence g2: its relative
// noise variance (1 - c) / c is (1 - g2) / ((n - 1) g2) - 1 / ... in closed form (n g2 - 1) / ((n - 1) g2).
TEST(EstimateCoherence, IsTheCoherenceOfTheAveragedEstimate) {
  EXPECT_EQ(EstimateCoherence(0.7, 0), 0.7);  // no count: already the estimate's
  for (int n : {2, 3, 5, 10}) {
    EXPECT_EQ(EstimateCoherence(1.0, n), 1.0) << n;          // noise-free records
    EXPECT_NEAR(EstimateCoherence(1.0 / n, n), 0.0, 1e-15) << n;  // records of noise alone: E[g2] = 1 / n
    EXPECT_EQ(EstimateCoherence(0.5 / n, n), 0.0) << n;      // below that, clamped
    EXPECT_EQ(EstimateCoherence(0.0, n), 0.0) << n;
    // At high coherence the estimate's SNR^2 = c / (1 - c) is (n - 1) times the records' g2 / (1 - g2),
    // less the 1 that |H_est|^2 = |H|^2 + variance adds: c / (1 - c) = (n - 1) g2 / (1 - g2) - 1.
    for (double g2 : {0.5, 0.9, 0.999}) {
      const double c = EstimateCoherence(g2, n);
      EXPECT_NEAR(c / (1.0 - c), (n - 1) * g2 / (1.0 - g2) - 1.0, 1e-9 * c / (1.0 - c)) << n << " " << g2;
    }
  }
  // A worked value: n = 5, g2 = 0.8: (4 - 1) / (4 * 0.8) = 0.9375.
  EXPECT_DOUBLE_EQ(EstimateCoherence(0.8, 5), 0.9375);
}

}  // namespace
}  // namespace stagefit::measurement
