// The raw channels' errors (diagnose::WorstChannels): on noisy data of the true model every channel sits
// at the noise floor; a local resonance under one sensor, which the compliance space spreads over every
// element, puts that sensor first, far above the others.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "stagefit/diagnose/diagnose.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"
#include "stagefit/synthetic/channel_faults.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace stagefit::diagnose {
namespace {

class WorstChannelsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    truth_ = model::DefaultModelSpec();
    const Eigen::Vector3d p = truth_.frames[model::FindFrame(truth_, truth_.compliance_frame)].origin_W;
    data_ = synthetic::CalcBruteForceFrf(truth_, synthetic::ComplianceTestSensors("hexapod", p),
                                         synthetic::ComplianceTestImpacts("hexapod", p), synthetic::LogFrequencies(5.0, 300.0, 300),
                                         measurement::FrfQuantity::kAccelerance);
    synthetic::AddNoise(data_, {0.02, 0.01, 7});
  }
  model::ModelSpec truth_;
  measurement::FrfData data_;
};

TEST_F(WorstChannelsTest, EveryChannelOfTheTrueModelIsAtTheNoiseFloor) {
  const auto channels = WorstChannels(truth_, data_, {}, 100);
  // Every accelerometer and every impact with a used element.
  ASSERT_EQ(channels.size(), static_cast<size_t>(data_.num_outputs() + data_.num_inputs()));
  for (size_t k = 1; k < channels.size(); ++k) EXPECT_GE(channels[k - 1].error, channels[k].error);
  for (const auto& c : channels) {
    SCOPED_TRACE(c.name);
    EXPECT_GT(c.num_elements, 0);
    ASSERT_TRUE(std::isfinite(c.times_floor));
    // A channel's elements hold a tenth of the points: their errors scatter about the floor by a few %
    // (0.95-1.05 on this draw), and the elements' noise levels differ a little (the absolute noise is per
    // element).
    EXPECT_GT(c.times_floor, 0.9);
    EXPECT_LT(c.times_floor, 1.1);
  }
}

TEST_F(WorstChannelsTest, ALocalResonanceUnderOneSensorPutsItFirst) {
  measurement::FrfData mounted = data_;
  synthetic::InjectLocalResonance(mounted, "a2z", 140.0, 10.0);
  const auto channels = WorstChannels(truth_, mounted, {}, 4);
  ASSERT_EQ(channels.size(), 4u);
  EXPECT_EQ(channels[0].name, "a2z");
  EXPECT_FALSE(channels[0].is_input);
  EXPECT_GT(channels[0].times_floor, 3.0);
  // The impacts see a2z as one of their twelve outputs, the other sensors not at all: every other
  // channel stays at the floor.
  EXPECT_LT(channels[1].times_floor, 1.1);
  EXPECT_GT(channels[0].times_median, 30.0);
  EXPECT_LT(channels[1].times_median, kChannelStandsOut);
  // Only the sensor that stands out is named.
  char expected[64];
  std::snprintf(expected, sizeof expected, "a2z (%.1f x the floor)", channels[0].times_floor);
  EXPECT_EQ(ChannelWords(channels), expected);
  // On data the true model explains no channel stands out, and none is named.
  EXPECT_EQ(ChannelWords(WorstChannels(truth_, data_, {}, 4)), "");
}

TEST_F(WorstChannelsTest, NoneForAMeasurementGivenAlreadyProjected) {
  // A 6x6 compliance without channel geometry has no raw channel to name.
  measurement::FrfData projected = data_;
  projected.outputs.resize(6);
  projected.inputs.resize(6);
  const char* dofs[] = {"Dx", "Dy", "Dz", "Rx", "Ry", "Rz"};
  const char* loads[] = {"Fx", "Fy", "Fz", "Mx", "My", "Mz"};
  for (int k = 0; k < 6; ++k) {
    projected.outputs[k] = measurement::ChannelGeometry{};
    projected.outputs[k].name = dofs[k];
    projected.inputs[k] = measurement::ChannelGeometry{};
    projected.inputs[k].name = loads[k];
  }
  for (auto& m : projected.frf) m = m.topLeftCorner(6, 6).eval();
  for (auto& m : projected.coherence) m = m.topLeftCorner(6, 6).eval();
  EXPECT_TRUE(WorstChannels(truth_, projected, {}, 4).empty());
}

}  // namespace
}  // namespace stagefit::diagnose
