// Benchmark of the time integration (docs/simulation.md): a 10 s run at 10 kHz of the 54-state
// micro-station model driven by 3 ground-motion inputs, 6 outputs. Prints the time of the modal ZOH
// recurrence (ModalIntegrator), of the dense ZOH recurrence (SimulateDense, the reference) and of RK4
// with the same step, their ratios, and the largest difference between the methods.
//
//   bench_simulate [repetitions]      (default 5; the best time of each method is reported)

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <random>

#include "stagefit/model/assembled_model.h"
#include "stagefit/model/linear_system.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/state_space.h"
#include "stagefit/simulate/experiments.h"
#include "stagefit/simulate/time_integration.h"

namespace {

double BestTime(int repetitions, const std::function<void()>& work) {
  double best = 1e300;
  for (int r = 0; r < repetitions; ++r) {
    const auto start = std::chrono::steady_clock::now();
    work();
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  return best;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace stagefit;
  const int repetitions = argc > 1 ? std::max(1, std::atoi(argv[1])) : 5;
  const double duration_s = 10.0, rate_hz = 10000.0;
  const auto model = model::AssembledModel::Assemble(model::DefaultModelSpec());
  const auto ss = model::CalcStateSpace(
      model::BuildSystem(model, model::GroundInputs(model), model::FrameMotionOutputs(model.spec(), "X")));
  const int steps = static_cast<int>(duration_s * rate_hz);
  Eigen::MatrixXd u(steps, 3);
  std::mt19937_64 rng(1);
  for (int c = 0; c < 3; ++c) {
    u.col(c) = disturbance::SynthesiseSignal(simulate::QuietHallGroundPsd(), {duration_s, rate_hz}, rng);
  }

  const auto setup_start = std::chrono::steady_clock::now();
  const simulate::ModalIntegrator integrator(ss, 1.0 / rate_hz);
  const double setup_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - setup_start).count();

  Eigen::MatrixXd y_modal, y_dense, y_rk4;
  const double t_modal = BestTime(repetitions, [&] { y_modal = integrator.Simulate(u); });
  const double t_dense = BestTime(repetitions, [&] { y_dense = simulate::SimulateDense(integrator.discrete(), u); });
  const double t_rk4 = BestTime(std::min(repetitions, 2), [&] { y_rk4 = simulate::SimulateRungeKutta4(ss, 1.0 / rate_hz, u); });

  const double scale = y_dense.cwiseAbs().maxCoeff();
  std::printf("model: %d states, %d inputs, %d outputs; %d steps (%.0f s at %.0f Hz); best of %d\n",
              static_cast<int>(ss.A.rows()), static_cast<int>(ss.B.cols()), static_cast<int>(ss.C.rows()), steps,
              duration_s, rate_hz, repetitions);
  std::printf("setup (state space -> ZOH exponential + modal basis): %.4f s, modal path: %s\n", setup_s,
              integrator.is_modal() ? "yes" : integrator.message().c_str());
  std::printf("modal ZOH recurrence : %.4f s\n", t_modal);
  std::printf("dense ZOH recurrence : %.4f s   (ratio dense/modal %.2f)\n", t_dense, t_dense / t_modal);
  std::printf("RK4, same step       : %.4f s   (ratio RK4/modal %.2f)\n", t_rk4, t_rk4 / t_modal);
  std::printf("max |modal - dense| / max|y| = %.2e, max |RK4 - dense| / max|y| = %.2e\n",
              (y_modal - y_dense).cwiseAbs().maxCoeff() / scale, (y_rk4 - y_dense).cwiseAbs().maxCoeff() / scale);
  std::printf("target: a 10 s run at 10 kHz under 0.2 s: %s\n", t_modal < 0.2 ? "met" : "NOT met");
  return 0;
}
