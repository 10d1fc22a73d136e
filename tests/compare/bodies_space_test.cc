// The bodies comparison space (a whole-stack test: sensors on every body, hammer on the translation
// stage): each body's sensors projected to its centre of mass, against the model's motion of the same
// points; the default space follows the geometry; the per-body rigid-body consistency.
#include <gtest/gtest.h>

#include <map>
#include <string>

#include "stagefit/compare/residuals.h"
#include "stagefit/measurement/projection.h"
#include "stagefit/model/model_file.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace stagefit::compare {
namespace {

measurement::FrfData WholeStack(const model::ModelSpec& truth, int points = 120) {
  return synthetic::CalcBruteForceFrf(truth, synthetic::WholeStackSensors(truth), synthetic::WholeStackImpacts(truth),
                                      synthetic::LogFrequencies(10.0, 400.0, points), measurement::FrfQuantity::kAccelerance);
}

TEST(BodiesSpace, TheModelsOwnDataHaveNoErrorAndTheLayoutIsPerBody) {
  // Independent paths: the brute-force FRFs of the truth, projected per body, against the response
  // layer's motion of each body's centre of mass.
  const model::ModelSpec spec = model::DefaultModelSpec();
  const measurement::FrfData data = WholeStack(spec);
  ComparisonOptions options;
  options.space = ComparisonSpace::kBodies;
  const Comparison c = Comparison::Create(spec, data, options);
  EXPECT_EQ(c.num_outputs(), 6 * static_cast<int>(spec.bodies.size()));
  EXPECT_EQ(c.num_inputs(), 5);
  EXPECT_EQ(c.output_names()[0], "granite.Dx");
  EXPECT_EQ(c.output_names()[11], "ty.Rz");
  EXPECT_LT(c.Error(spec), 1e-7);
  // A stiffness off moves the error well away from zero.
  model::ModelSpec soft = spec;
  soft.joints[model::FindJoint(soft, "ry")].stiffness[0] *= 0.7;
  EXPECT_GT(c.Error(soft), 0.01);
  // No channel can be corrected through a per-body projection (diagnose does not try sensor-geometry here).
  EXPECT_TRUE(c.CorrectableChannels().empty());
}

TEST(BodiesSpace, TheTruthsErrorIsTheNoiseFloor) {
  const model::ModelSpec spec = model::DefaultModelSpec();
  measurement::FrfData data = WholeStack(spec, 200);
  synthetic::AddNoise(data, {0.02, 0.01, 5});
  ComparisonOptions options;
  options.space = ComparisonSpace::kBodies;
  const Comparison c = Comparison::Create(spec, data, options);
  const NoiseFloor floor = c.CalcNoiseFloor();
  ASSERT_TRUE(floor.known);
  EXPECT_NEAR(c.Error(spec) / floor.floor, 1.0, 0.08);
}

TEST(BodiesSpace, TheDefaultSpaceFollowsTheGeometry) {
  const model::ModelSpec spec = model::DefaultModelSpec();
  const DefaultSpace whole = ChooseDefaultSpace(WholeStack(spec, 10));
  EXPECT_EQ(whole.space, ComparisonSpace::kBodies);
  EXPECT_NE(whole.reason.find("5 bodies"), std::string::npos) << whole.reason;
  const Eigen::Vector3d p(0, 0, -0.03);
  const measurement::FrfData top = synthetic::CalcBruteForceFrf(spec, synthetic::ComplianceTestSensors("hexapod", p),
                                                                synthetic::ComplianceTestImpacts("hexapod", p),
                                                                synthetic::LogFrequencies(10.0, 400.0, 10),
                                                                measurement::FrfQuantity::kAccelerance);
  const DefaultSpace one = ChooseDefaultSpace(top);
  EXPECT_EQ(one.space, ComparisonSpace::kCompliance);
  EXPECT_NE(one.reason.find("one body ('hexapod')"), std::string::npos) << one.reason;
  EXPECT_EQ(ParseComparisonSpace("bodies", "--space"), ComparisonSpace::kBodies);
  EXPECT_EQ(ToString(ComparisonSpace::kBodies), "bodies");
}

TEST(BodiesSpace, PerBodyConsistencySinglesOutAChannelThatDoesNotMoveWithItsBody) {
  // A sensor mount with a local resonance at 150 Hz (Q 10) on one of the rz body's channels: that
  // channel's residual share rises in the band around it, every other channel stays near zero.
  const model::ModelSpec spec = model::DefaultModelSpec();
  measurement::FrfData data = WholeStack(spec, 200);
  const int bad = 3 * 9 + 4;  // rz_a2y
  ASSERT_EQ(data.outputs[bad].name, "rz_a2y");
  for (int f = 0; f < data.num_frequencies(); ++f) {
    const double r = data.frequency_hz(f) / 150.0;
    const std::complex<double> mount = 1.0 / std::complex<double>(1.0 - r * r, r / 10.0);
    data.frf[f].row(bad) *= mount;
  }
  std::map<std::string, Eigen::Vector3d> p_WBcm;
  for (const auto& b : spec.bodies) p_WBcm[b.name] = b.com_W;
  const measurement::RigidConsistency rc = measurement::CalcRigidConsistencyPerBody(data, p_WBcm);
  ASSERT_FALSE(rc.bands.empty());
  EXPECT_TRUE(rc.input_names.empty());
  // From the mount's resonance up the channel no longer follows its body (above it, it sees less and
  // less of the motion, so the share of its own energy that the body's motion leaves stays high); well
  // below it the channel is sound.
  for (size_t b = 0; b < rc.bands.size(); ++b) {
    const double share = rc.output_residual_share(bad, static_cast<int>(b));
    if (rc.bands[b].low_hz <= 150.0 && rc.bands[b].high_hz > 150.0) {
      EXPECT_GT(share, 0.1) << rc.bands[b].centre_hz();
    }
    if (rc.bands[b].high_hz < 60.0) {
      EXPECT_LT(share, 0.05) << rc.bands[b].centre_hz();
    }
  }
  for (int o = 0; o < data.num_outputs(); ++o) {
    if (data.outputs[o].body == "rz") continue;  // the rz channels share the bad one's projection
    EXPECT_LT(rc.output_residual_share.row(o).maxCoeff(), 1e-12) << data.outputs[o].name;
  }
}

}  // namespace
}  // namespace stagefit::compare
