#pragma once
// Synthetic fit problems of the micro-station: a "true" model with scattered stiffnesses, and its
// compliance at {X} with seeded complex noise as the measurement. Shared by the fit tests and the
// fit benchmark.

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <complex>
#include <random>
#include <string>
#include <vector>

#include "stagefit/common/dof.h"
#include "stagefit/measurement/frf_data.h"
#include "stagefit/model/assembled_model.h"
#include "stagefit/model/linear_system.h"
#include "stagefit/model/model_spec.h"
#include "stagefit/model/parameters.h"
#include "stagefit/response/frf_evaluator.h"

namespace stagefit::fit::testing {

/// `count` logarithmically spaced frequencies from `low_hz` to `high_hz`.
inline Eigen::VectorXd LogFrequencies(double low_hz, double high_hz, int count) {
  Eigen::VectorXd f(count);
  for (int k = 0; k < count; ++k) f(k) = low_hz * std::pow(high_hz / low_hz, static_cast<double>(k) / (count - 1));
  return f;
}

/// A uniform number in [0, 1) from 53 bits (the same on every standard library).
inline double Uniform(std::mt19937_64& generator) { return static_cast<double>(generator() >> 11) * 0x1.0p-53; }

/// A standard normal number (Box-Muller on Uniform(), reproducible across standard libraries).
inline double Normal(std::mt19937_64& generator) {
  const double u1 = 1.0 - Uniform(generator);
  const double u2 = Uniform(generator);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

/// Multiplies each parameter matching `patterns` by a factor drawn log-uniformly in
/// [1 / max_factor, max_factor].
inline void ScatterParameters(model::ModelSpec* spec, const std::vector<std::string>& patterns, double max_factor,
                              std::mt19937_64& generator) {
  for (const auto& p : model::MatchParameters(*spec, patterns)) {
    const double factor = std::exp((2.0 * Uniform(generator) - 1.0) * std::log(max_factor));
    model::SetParameter(*spec, p, model::GetParameter(*spec, p) * factor);
  }
}

/// Multiplies each parameter matching `patterns` by exp(sigma z), sigma = ln(max_factor) / 2, z standard
/// normal truncated at +-2: log-normal scatter of at most a factor max_factor (the fit benchmark's).
inline void ScatterParametersLogNormal(model::ModelSpec* spec, const std::vector<std::string>& patterns,
                                       double max_factor, std::mt19937_64& generator) {
  for (const auto& p : model::MatchParameters(*spec, patterns)) {
    const double sigma = std::log(max_factor) / 2.0;
    const double z = std::clamp(Normal(generator), -2.0, 2.0);
    model::SetParameter(*spec, p, model::GetParameter(*spec, p) * std::exp(sigma * z));
  }
}

/// The receptance compliance of `spec` at its frame {X} (6 x 6, outputs Dx..Rz, inputs Fx..Mz, no
/// geometry: compare::Comparison takes it as projected), each point multiplied by
/// 1 + noise (n1 + j n2) / sqrt(2) with n1, n2 standard normal: `noise` is the RMS relative error.
inline measurement::FrfData MakeComplianceMeasurement(const model::ModelSpec& spec,
                                                      const Eigen::VectorXd& frequency_hz, double noise,
                                                      std::mt19937_64& generator) {
  const auto assembled = model::AssembledModel::Assemble(spec);
  auto evaluator = response::FrfEvaluator::Create(model::BuildComplianceSystem(assembled));
  const auto frf = evaluator.Evaluate(frequency_hz, response::ResponseQuantity::kReceptance);
  measurement::FrfData data;
  data.frequency_hz = frequency_hz;
  data.quantity = measurement::FrfQuantity::kReceptance;
  data.source = "synthetic compliance";
  static const char* kWrench[] = {"Fx", "Fy", "Fz", "Mx", "My", "Mz"};
  for (int k = 0; k < 6; ++k) {
    data.outputs.push_back({std::string(kDofNames[k]), "", Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()});
    data.inputs.push_back({kWrench[k], "", Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()});
  }
  for (int f = 0; f < frf.num_frequencies(); ++f) {
    Eigen::MatrixXcd H = frf.At(f);
    for (int j = 0; j < H.cols(); ++j) {
      for (int i = 0; i < H.rows(); ++i) {
        const double n1 = Normal(generator), n2 = Normal(generator);
        H(i, j) *= 1.0 + noise * std::complex<double>(n1, n2) / std::sqrt(2.0);
      }
    }
    data.frf.push_back(H);
  }
  return data;
}

}  // namespace stagefit::fit::testing
