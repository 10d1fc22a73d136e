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
}

}  // namespace
}  // namespace stagefit::measurement
