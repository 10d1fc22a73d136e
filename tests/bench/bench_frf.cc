// FRF evaluation speed on the reference micro-station (27 DoF, 54 states), one thread, whole job
// including set-up (FrfEvaluator::Create: eigen-decomposition and probe check).
//
//   bench_frf                      Google Benchmark runs, then a summary in microseconds per frequency
//                                  point with the ratios (fast/direct, derivatives/FRF).
//
// Cases: 6x6 compliance at 10,000 frequencies (modal path and a per-frequency dense direct solve),
// the 12x10 raw channels at 10,000 frequencies, and the derivatives with respect to every free joint
// stiffness (27) at 1000 frequencies against the FRF alone at the same frequencies.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <ctime>
#include <cmath>
#include <cstdio>
#include <functional>
#include <vector>

#include "stagefit/model/model_file.h"
#include "stagefit/response/frf_evaluator.h"
#include "stagefit/response/io_sets.h"

namespace {

using stagefit::model::AssembledModel;
using stagefit::response::FrfEvaluator;
using stagefit::response::FrfEvaluatorOptions;
using stagefit::response::FrfMethod;
using stagefit::response::IoSet;
using stagefit::response::ResponseQuantity;

const AssembledModel& Model() {
  static const AssembledModel model = AssembledModel::Assemble(stagefit::model::DefaultModelSpec());
  return model;
}

Eigen::VectorXd Frequencies(int n) {
  Eigen::VectorXd f(n);
  for (int i = 0; i < n; ++i) f(i) = 1.0 * std::pow(2000.0, static_cast<double>(i) / (n - 1));
  return f;
}

// One whole job: set-up and evaluation.
double RunFrf(IoSet set, FrfMethod method, const Eigen::VectorXd& f) {
  FrfEvaluatorOptions options;
  options.method = method;
  auto ev = FrfEvaluator::Create(stagefit::response::BuildIoSetSystem(Model(), set), options);
  const auto h = ev.Evaluate(f, ResponseQuantity::kAccelerance);
  return std::abs(h.values(0, 0));
}

double RunDerivatives(IoSet set, const Eigen::VectorXd& f) {
  static const auto params = stagefit::model::MatchParameters(Model().spec(), {"*.k.*"});
  auto ev = FrfEvaluator::Create(stagefit::response::BuildIoSetSystem(Model(), set));
  const auto r = ev.EvaluateWithDerivatives(f, ResponseQuantity::kAccelerance, params, Model());
  return std::abs(r.derivatives.back()(0, 0));
}

void SetPerPoint(benchmark::State& state, int points) {
  state.counters["per_point"] =
      benchmark::Counter(points, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

void BM_Compliance6x6Modal(benchmark::State& state) {
  const Eigen::VectorXd f = Frequencies(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(RunFrf(IoSet::kCompliance, FrfMethod::kAuto, f));
  SetPerPoint(state, static_cast<int>(f.size()));
}
void BM_Compliance6x6Direct(benchmark::State& state) {
  const Eigen::VectorXd f = Frequencies(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(RunFrf(IoSet::kCompliance, FrfMethod::kDirect, f));
  SetPerPoint(state, static_cast<int>(f.size()));
}
void BM_Raw12x10Modal(benchmark::State& state) {
  const Eigen::VectorXd f = Frequencies(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(RunFrf(IoSet::kRaw, FrfMethod::kAuto, f));
  SetPerPoint(state, static_cast<int>(f.size()));
}
void BM_Raw12x10Direct(benchmark::State& state) {
  const Eigen::VectorXd f = Frequencies(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(RunFrf(IoSet::kRaw, FrfMethod::kDirect, f));
  SetPerPoint(state, static_cast<int>(f.size()));
}
void BM_Compliance6x6StiffnessDerivatives(benchmark::State& state) {
  const Eigen::VectorXd f = Frequencies(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(RunDerivatives(IoSet::kCompliance, f));
  SetPerPoint(state, static_cast<int>(f.size()));
}
void BM_Raw12x10StiffnessDerivatives(benchmark::State& state) {
  const Eigen::VectorXd f = Frequencies(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(RunDerivatives(IoSet::kRaw, f));
  SetPerPoint(state, static_cast<int>(f.size()));
}

BENCHMARK(BM_Compliance6x6Modal)->Arg(10000)->Arg(1000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Compliance6x6Direct)->Arg(10000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Raw12x10Modal)->Arg(10000)->Arg(1000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Raw12x10Direct)->Arg(10000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Compliance6x6StiffnessDerivatives)->Arg(1000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Raw12x10StiffnessDerivatives)->Arg(1000)->Unit(benchmark::kMicrosecond);

double ThreadCpuMicroseconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return 1e6 * static_cast<double>(t.tv_sec) + 1e-3 * static_cast<double>(t.tv_nsec);
}

// Median CPU time of this thread for `job` over `repeats` runs, in microseconds (robust against other
// processes sharing the machine, unlike wall time).
double MedianMicroseconds(const std::function<double()>& job, int repeats) {
  std::vector<double> times;
  double sink = 0.0;
  for (int r = 0; r < repeats; ++r) {
    const double start = ThreadCpuMicroseconds();
    sink += job();
    times.push_back(ThreadCpuMicroseconds() - start);
  }
  benchmark::DoNotOptimize(sink);
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

void PrintSummary() {
  const Eigen::VectorXd f10k = Frequencies(10000), f1k = Frequencies(1000);
  const double c_modal = MedianMicroseconds([&] { return RunFrf(IoSet::kCompliance, FrfMethod::kAuto, f10k); }, 21);
  const double c_direct = MedianMicroseconds([&] { return RunFrf(IoSet::kCompliance, FrfMethod::kDirect, f10k); }, 5);
  const double r_modal = MedianMicroseconds([&] { return RunFrf(IoSet::kRaw, FrfMethod::kAuto, f10k); }, 21);
  const double r_direct = MedianMicroseconds([&] { return RunFrf(IoSet::kRaw, FrfMethod::kDirect, f10k); }, 5);
  const double c_frf1k = MedianMicroseconds([&] { return RunFrf(IoSet::kCompliance, FrfMethod::kAuto, f1k); }, 51);
  const double c_der1k = MedianMicroseconds([&] { return RunDerivatives(IoSet::kCompliance, f1k); }, 21);
  const double r_frf1k = MedianMicroseconds([&] { return RunFrf(IoSet::kRaw, FrfMethod::kAuto, f1k); }, 51);
  const double r_der1k = MedianMicroseconds([&] { return RunDerivatives(IoSet::kRaw, f1k); }, 21);
  const int num_params = static_cast<int>(stagefit::model::MatchParameters(Model().spec(), {"*.k.*"}).size());
  // The fit's loop: a new model each iteration (set-up included) but the output arrays reused.
  stagefit::response::FrfWithDerivatives reused;
  const auto params = stagefit::model::MatchParameters(Model().spec(), {"*.k.*"});
  auto reuse_job = [&](IoSet set) {
    auto ev = FrfEvaluator::Create(stagefit::response::BuildIoSetSystem(Model(), set));
    ev.EvaluateWithDerivatives(f1k, ResponseQuantity::kAccelerance, params, Model(), &reused);
    return std::abs(reused.derivatives.back()(0, 0));
  };
  const double c_der1k_reused = MedianMicroseconds([&] { return reuse_job(IoSet::kCompliance); }, 21);
  const double r_der1k_reused = MedianMicroseconds([&] { return reuse_job(IoSet::kRaw); }, 11);
  std::printf("\nSummary: one thread, whole job including set-up, median thread CPU time\n");
  std::printf("  6x6 compliance, 10000 points: modal %.3f us/point, direct %.3f us/point, direct/modal %.1f\n",
              c_modal / 1e4, c_direct / 1e4, c_direct / c_modal);
  std::printf("  12x10 raw,      10000 points: modal %.3f us/point, direct %.3f us/point, direct/modal %.1f\n",
              r_modal / 1e4, r_direct / 1e4, r_direct / r_modal);
  std::printf("  6x6 + d/d(%d stiffnesses), 1000 points: %.3f us/point, FRF alone %.3f us/point, ratio %.1f\n",
              num_params, c_der1k / 1e3, c_frf1k / 1e3, c_der1k / c_frf1k);
  std::printf("  12x10 + d/d(%d stiffnesses), 1000 points: %.3f us/point, FRF alone %.3f us/point, ratio %.1f\n",
              num_params, r_der1k / 1e3, r_frf1k / 1e3, r_der1k / r_frf1k);
  std::printf("  with the derivative arrays reused between calls (fit loop): 6x6 ratio %.1f, 12x10 ratio %.1f\n",
              c_der1k_reused / c_frf1k, r_der1k_reused / r_frf1k);
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  PrintSummary();
  return 0;
}
