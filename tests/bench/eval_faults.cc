// Evaluation of the channel checks (measurement::CheckChannels) on synthetic top-plate measurements with
// one injected fault of the test bench (synthetic/channel_faults.h), plus sound cases.
//
//   eval_faults [--cases N] [--first-seed S]
//
// Case c (seed S + c) is a 12x10 accelerance measurement of a scattered truth without hidden effect
// (synthetic::MakeHiddenEffectCase with 0 effects), 1-3 % noise, upper frequency drawn from 150, 400 and
// 600 Hz, 300-1200 points; kind S + c mod 6: sound, reversed, swapped, dead, clipped, local resonance, the
// channels and magnitudes drawn. A fault counts as detected and named when a finding has its kind and
// its channel(s); every other finding counts as false.

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <set>
#include <string>

#include "stagefit/measurement/channel_checks.h"
#include "stagefit/measurement/projection.h"
#include "stagefit/model/model_file.h"
#include "stagefit/synthetic/channel_faults.h"
#include "stagefit/synthetic/synthetic_measurement.h"

using namespace stagefit;
using measurement::ChannelFaultKind;

int main(int argc, char** argv) {
  int cases = 60;
  uint64_t first_seed = 1;
  bool verbose = false;
  // --hidden-effects: no injected fault but one hidden catalogue effect per case; every finding is false.
  bool hidden_effects = false;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--cases") && i + 1 < argc) cases = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--first-seed") && i + 1 < argc) first_seed = std::strtoull(argv[++i], nullptr, 10);
    else if (!std::strcmp(argv[i], "--verbose")) verbose = true;
    else if (!std::strcmp(argv[i], "--hidden-effects")) hidden_effects = true;
    else {
      std::fprintf(stderr, "usage: eval_faults [--cases N] [--first-seed S] [--verbose] [--hidden-effects]\n");
      return 2;
    }
  }
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const char* kinds[] = {"sound", "reversed", "swapped", "dead", "clipped", "local_resonance"};
  int ambiguous[6] = {0}, total[6] = {0}, named[6] = {0}, false_cases[6] = {0}, non_rigid[6] = {0}, false_findings = 0, unobservable = 0, unobservable_named = 0;
  for (int c = 0; c < cases; ++c) {
    const uint64_t seed = first_seed + c;
    std::mt19937_64 rng(seed * 7919 + 13);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    synthetic::HiddenEffectOptions options;
    options.num_effects = hidden_effects ? 1 : 0;
    const double fmax[] = {150.0, 400.0, 600.0};
    options.fmax_hz = fmax[static_cast<int>(u(rng) * 3) % 3];
    options.fmin_hz = options.fmax_hz / 40.0;
    options.num_frequencies = 300 + static_cast<int>(u(rng) * 900);
    auto hidden = synthetic::MakeHiddenEffectCase(nominal, seed, options);
    const int k = hidden_effects ? 0 : static_cast<int>(seed % 6);
    synthetic::InjectedFault injected;
    if (k > 0) injected = synthetic::InjectRandomFault(hidden.measurement, static_cast<ChannelFaultKind>(k - 1), rng);
    // A swap that maps the rigid geometry onto itself (e.g. the vertical impacts at +y and -y, which enter
    // the one parity relation of the four vertical impacts alike) leaves the data rigid: no check can see it.
    bool observable = true;
    if (k == 2) {
      const auto& ch = injected.is_input ? hidden.measurement.inputs : hidden.measurement.outputs;
      const Eigen::MatrixXd J = injected.is_input ? measurement::CalcImpactJacobian(ch, Eigen::Vector3d::Zero())
                                                  : measurement::CalcSensorJacobian(ch, Eigen::Vector3d::Zero());
      Eigen::MatrixXd PJ = J;
      int a = 0, b = 0;
      for (std::size_t i = 0; i < ch.size(); ++i) {
        if (ch[i].name == injected.channels[0]) a = static_cast<int>(i);
        if (ch[i].name == injected.channels[1]) b = static_cast<int>(i);
      }
      PJ.row(a).swap(PJ.row(b));
      const Eigen::MatrixXd P = Eigen::MatrixXd::Identity(J.rows(), J.rows()) - J * measurement::PseudoInverse(J);
      observable = (P * PJ).norm() > 1e-9 * J.norm();
      if (!observable) ++unobservable;
    }
    const auto result = measurement::CheckChannels(hidden.measurement, Eigen::Vector3d::Zero());
    ++total[k];
    bool hit = false;
    int wrong = 0;
    for (const auto& f : result.findings) {
      const std::set<std::string> truth(injected.channels.begin(), injected.channels.end());
      const bool same_kind = k > 0 && f.kind == injected.kind && f.is_input == injected.is_input;
      bool match = same_kind && std::set<std::string>(f.channels.begin(), f.channels.end()) == truth;
      const bool unique = match && f.alternatives.empty();
      for (const auto& a : f.alternatives)
        if (same_kind && std::set<std::string>(a.begin(), a.end()) == truth) match = true;
      if (match) hit = true;
      if (match && !unique) ++ambiguous[k];
      if (!match) ++wrong;
    }
    if (hit) ++named[k];
    if (hit && !observable) ++unobservable_named;
    if (wrong) ++false_cases[k];
    false_findings += wrong;
    // Channels named not rigid together (ChannelCheckResult::non_rigid: no single channel at fault): on
    // sound data and under a catalogue effect a false alarm; beside a fault, what the checks say after it.
    if (!result.non_rigid.empty()) ++non_rigid[k];
    if (verbose || (k > 0 && !hit) || wrong) {
      std::printf("seed %llu %s (%s; %.0f Hz, %d points): %s", static_cast<unsigned long long>(seed), kinds[k],
                  k ? injected.description.c_str() : (hidden.effects.empty() ? "-" : hidden.effects[0].description.c_str()), options.fmax_hz, options.num_frequencies, k == 0 ? (wrong ? "FALSE FINDING" : "no finding") : hit ? "named" : "MISSED");
      if (!observable) std::printf(" (unobservable swap)");
      std::printf("\n%s", result.Report().c_str());
    }
  }
  std::printf("\n%-16s %6s %8s %10s %12s\n", "kind", "cases", "named", "ambiguous", "false-case");
  for (int k = 0; k < 6; ++k)
    std::printf("%-16s %6d %7.1f%% %10d %12d\n", kinds[k], total[k], k ? 100.0 * named[k] / std::max(1, total[k]) : 0.0,
                ambiguous[k], false_cases[k]);
  std::printf("named: a finding of the injected kind that names the injected channel(s), alone or among the\n"
              "alternatives that explain the data equally (ambiguous: the symmetric layout cannot tell them apart)\n");
  std::printf("swaps that leave the rigid geometry unchanged (no check can see them): %d of %d, named %d\n",
              unobservable, total[2], unobservable_named);
  std::printf("swapped, observable swaps only: %.1f%%\n",
              100.0 * (named[2] - unobservable_named) / std::max(1, total[2] - unobservable));
  std::printf("false findings in all cases: %d\n", false_findings);
  std::printf("channels named not rigid together (no single channel at fault):");
  for (int k = 0; k < 6; ++k) std::printf(" %s %d of %d%s", kinds[k], non_rigid[k], total[k], k < 5 ? "," : "\n");
  return 0;
}
