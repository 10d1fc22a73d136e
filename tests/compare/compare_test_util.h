#pragma once
// Synthetic measurements for the compare tests: the model's own FRFs between its [[sensor]] and
// [[excitation]] entries, with the geometry of those entries.

#include <Eigen/Core>

#include <vector>

#include "stagefit/measurement/frf_data.h"
#include "stagefit/model/assembled_model.h"
#include "stagefit/model/linear_system.h"
#include "stagefit/model/model_spec.h"
#include "stagefit/response/frf_evaluator.h"

namespace stagefit::compare::testing {

/// `count` logarithmically spaced frequencies from `low_hz` to `high_hz`.
inline Eigen::VectorXd LogFrequencies(double low_hz, double high_hz, int count) {
  Eigen::VectorXd f(count);
  for (int k = 0; k < count; ++k) {
    f(k) = low_hz * std::pow(high_hz / low_hz, static_cast<double>(k) / (count - 1));
  }
  return f;
}

/// The raw accelerance of `spec` from its excitations to its sensors, as a measurement with geometry.
inline measurement::FrfData MakeSyntheticMeasurement(const model::ModelSpec& spec,
                                                     const Eigen::VectorXd& frequency_hz) {
  const auto assembled = model::AssembledModel::Assemble(spec);
  const auto system =
      model::BuildSystem(assembled, model::ExcitationInputs(spec), model::SensorOutputs(spec));
  auto evaluator = response::FrfEvaluator::Create(system);
  const auto frf = evaluator.Evaluate(frequency_hz, response::ResponseQuantity::kAccelerance);
  measurement::FrfData data;
  data.frequency_hz = frequency_hz;
  data.quantity = measurement::FrfQuantity::kAccelerance;
  data.source = "synthetic";
  for (int k = 0; k < frf.num_frequencies(); ++k) data.frf.push_back(frf.At(k));
  for (const auto& s : spec.sensors) data.outputs.push_back({s.name, s.body, s.position_W, s.direction_W});
  for (const auto& e : spec.excitations) data.inputs.push_back({e.name, e.body, e.position_W, e.direction_W});
  return data;
}

/// Coherence 1 at every point of `data`.
inline void SetPerfectCoherence(measurement::FrfData* data) {
  data->coherence.assign(data->num_frequencies(),
                         Eigen::MatrixXd::Ones(data->num_outputs(), data->num_inputs()));
}

}  // namespace stagefit::compare::testing
