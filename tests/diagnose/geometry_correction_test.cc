// The sensor-geometry effect is seen by the raw-space comparison: data made with a rotated accelerometer
// (by the independent brute-force path) match the nominal model exactly once the model carries the
// same geometry correction.

#include <gtest/gtest.h>

#include "stagefit/compare/residuals.h"
#include "stagefit/kinematics/rigid_transform.h"
#include "stagefit/model/effects.h"
#include "stagefit/model/model_file.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace stagefit {
namespace {

TEST(GeometryCorrection, RotatedSensorIsExplainedInRawSpace) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const Eigen::Vector3d X(0, 0, -0.03);
  auto declared = synthetic::ComplianceTestSensors("hexapod", X);
  auto truth = declared;
  const double angle = 15 * M_PI / 180;
  truth[4].direction_W = kinematics::RotationFromEuler({0, 0, angle}) * truth[4].direction_W;  // a2y about z
  auto data = synthetic::CalcBruteForceFrf(nominal, truth, synthetic::ComplianceTestImpacts("hexapod", X),
                                           synthetic::LogFrequencies(10, 400, 80), measurement::FrfQuantity::kAccelerance);
  data.outputs = declared;
  compare::ComparisonOptions options;
  options.space = compare::ComparisonSpace::kRaw;
  auto comparison = compare::Comparison::Create(nominal, data, options);
  model::ModelSpec corrected = nominal;
  model::ApplyEffect(corrected, model::ParseEffect("sensor-geometry@a2y:rz=15 deg", corrected));
  const double before = comparison.Error(nominal), after = comparison.Error(corrected);
  EXPECT_GT(before, 0.01);
  // Noise-free data from an independent solver: only rounding is left (see tests/synthetic).
  EXPECT_LT(after, 1e-6);
}

}  // namespace
}  // namespace stagefit
