// The cost of comparing under a channel's correction (the sensor-geometry effect in compliance space),
// one thread: the measurement is re-projected, weighed again and its noise elements decided under the
// corrected J_a and J_F at every new value of the correction (a fit's every evaluation and two per
// differenced parameter of the correction).
//
//   bench_reproject [--benchmark_filter=...]
//
// A 12x10 hammer test of the default micro-station's top plate (the brute-force path, 1 % noise with
// coherence) at 1000 log-spaced frequencies, 10-600 Hz. Cases:
//   - Error/declared: the error of the nominal model, no correction (the FRF set-up, the modal FRF and
//     the log residuals);
//   - Error/new correction: the same model with a2x turned by a new angle at every iteration (no reuse
//     of the measured side), i.e. the above plus the re-projection with its weights;
//   - Reproject/whole grid: Comparison::MeasuredFor() under a new correction (the projection's values
//     alone, as one product by Q^T kron P);
//   - Reproject/per frequency: the peer, P H_k Q as two complex products at each frequency (as the
//     re-projection was computed before), with the same P and Q sizes.

#include <benchmark/benchmark.h>

#include <complex>
#include <vector>

#include "stagefit/compare/residuals.h"
#include "stagefit/measurement/projection.h"
#include "stagefit/model/model_file.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace {

using namespace stagefit;

struct Setup {
  model::ModelSpec nominal = model::DefaultModelSpec();
  measurement::FrfData data;
  compare::Comparison comparison;
};

const Setup& TheSetup() {
  static const Setup setup = [] {
    const model::ModelSpec nominal = model::DefaultModelSpec();
    const Eigen::Vector3d X(0, 0, -0.03);
    measurement::FrfData data = synthetic::CalcBruteForceFrf(
        nominal, synthetic::ComplianceTestSensors("hexapod", X), synthetic::ComplianceTestImpacts("hexapod", X),
        synthetic::LogFrequencies(10, 600, 1000), measurement::FrfQuantity::kAccelerance);
    synthetic::AddNoise(data, {0.01, 0.01, 7});
    compare::Comparison comparison = compare::Comparison::Create(nominal, data);
    return Setup{nominal, data, std::move(comparison)};
  }();
  return setup;
}

// The nominal model with a2x turned about z by an angle that changes at every call.
model::ModelSpec WithNewCorrection(const model::ModelSpec& nominal, int* counter) {
  model::ModelSpec spec = nominal;
  const double angle = 1e-4 * (1 + (*counter)++ % 997);
  spec.geometry_corrections.push_back({"a2x", false, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, angle)});
  return spec;
}

void BM_ErrorDeclared(benchmark::State& state) {
  const Setup& s = TheSetup();
  for (auto _ : state) benchmark::DoNotOptimize(s.comparison.Error(s.nominal));
}

void BM_ErrorNewCorrection(benchmark::State& state) {
  const Setup& s = TheSetup();
  int counter = 0;
  for (auto _ : state) {
    const model::ModelSpec spec = WithNewCorrection(s.nominal, &counter);
    benchmark::DoNotOptimize(s.comparison.Error(spec));
  }
}

void BM_ReprojectWholeGrid(benchmark::State& state) {
  const Setup& s = TheSetup();
  int counter = 0;
  std::vector<Eigen::MatrixXcd> storage;
  for (auto _ : state) {
    const model::ModelSpec spec = WithNewCorrection(s.nominal, &counter);
    benchmark::DoNotOptimize(s.comparison.MeasuredFor(spec, &storage).data());
  }
}

void BM_ReprojectPerFrequency(benchmark::State& state) {
  const Setup& s = TheSetup();
  const Eigen::Vector3d origin = s.comparison.frame_origin_W();
  const Eigen::MatrixXd P = measurement::PseudoInverse(measurement::CalcSensorJacobian(s.data.outputs, origin));
  const Eigen::MatrixXd Q =
      measurement::PseudoInverse(measurement::CalcImpactJacobian(s.data.inputs, origin).transpose());
  std::vector<Eigen::MatrixXcd> storage(s.data.frf.size());
  for (auto _ : state) {
    const Eigen::MatrixXcd Pc = P.cast<std::complex<double>>(), Qc = Q.cast<std::complex<double>>();
    for (size_t k = 0; k < s.data.frf.size(); ++k) storage[k] = Pc * s.data.frf[k] * Qc;
    benchmark::DoNotOptimize(storage.data());
  }
}

BENCHMARK(BM_ErrorDeclared)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ErrorNewCorrection)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ReprojectWholeGrid)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ReprojectPerFrequency)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
