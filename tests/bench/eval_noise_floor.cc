// The noise floor on FRFs estimated from raw hammer hits (docs/error-metric.md §8): the brute-force
// generator's time data of the noise-free embedded model (synthetic::MakeRawHammerTest: per impact n
// half-sine hits, noise a share of each channel's RMS per hit), estimated with measurement::EstimateFrf
// over 10-400 Hz, and the noise-free truth's error over the floor, which should be 1. Per hit count, the
// mean over the draws in compliance and raw space, with the hits averaged as estimate writes them
// (FrfData::averages) and without them (the ordinary coherence read as the estimate's own, as before).
//
//   eval_noise_floor [--hits 2,3,5,10,20] [--draws 4] [--first-seed 3000] [--noise 0.005]
//
// Draw d of n hits has seed first_seed + 100 n + d.

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include "stagefit/compare/residuals.h"
#include "stagefit/measurement/hammer_estimation.h"
#include "stagefit/model/model_file.h"
#include "stagefit/synthetic/synthetic_measurement.h"

using namespace stagefit;

int main(int argc, char** argv) {
  std::vector<int> hit_counts = {2, 3, 5, 10, 20};
  int draws = 4;
  uint64_t first_seed = 3000;
  double noise = 0.005;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--hits") && i + 1 < argc) {
      hit_counts.clear();
      std::istringstream in(argv[++i]);
      for (std::string item; std::getline(in, item, ',');) hit_counts.push_back(std::atoi(item.c_str()));
    } else if (!std::strcmp(argv[i], "--draws") && i + 1 < argc) {
      draws = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--first-seed") && i + 1 < argc) {
      first_seed = std::strtoull(argv[++i], nullptr, 10);
    } else if (!std::strcmp(argv[i], "--noise") && i + 1 < argc) {
      noise = std::atof(argv[++i]);
    } else {
      std::fprintf(stderr, "usage: eval_noise_floor [--hits 2,3,5,10,20] [--draws 4] [--first-seed 3000] [--noise 0.005]\n");
      return 2;
    }
  }
  const model::ModelSpec truth = model::DefaultModelSpec();
  const model::FrameSpec& X = truth.frames[model::FindFrame(truth, truth.compliance_frame)];
  std::printf("noise-free truth's error over its noise floor, mean over %d draws (min-max)\n", draws);
  std::printf("%5s  %-22s %-22s %-22s %-22s\n", "hits", "compliance", "  without the count", "raw", "  without the count");
  for (int hits : hit_counts) {
    // [space][with the count or without]: sum, min, max
    double sum[2][2] = {}, lo[2][2], hi[2][2];
    for (auto& row : lo) row[0] = row[1] = 1e300;
    for (auto& row : hi) row[0] = row[1] = 0.0;
    for (int d = 0; d < draws; ++d) {
      synthetic::RawHammerOptions raw_options;
      raw_options.hits_per_impact = hits;
      raw_options.noise = noise;
      raw_options.seed = first_seed + 100 * static_cast<uint64_t>(hits) + static_cast<uint64_t>(d);
      measurement::RawHammerData raw = synthetic::MakeRawHammerTest(
          truth, synthetic::ComplianceTestSensors(X.body, X.origin_W), synthetic::ComplianceTestImpacts(X.body, X.origin_W), raw_options);
      raw.frame_origin_W = X.origin_W;
      measurement::EstimationOptions estimation;
      estimation.min_frequency_hz = 10.0;
      estimation.max_frequency_hz = 400.0;
      const measurement::FrfData counted = measurement::EstimateFrf(raw, estimation).frf;
      measurement::FrfData uncounted = counted;
      uncounted.averages.clear();
      for (int s = 0; s < 2; ++s) {
        compare::ComparisonOptions options;
        options.space = s == 0 ? compare::ComparisonSpace::kCompliance : compare::ComparisonSpace::kRaw;
        for (int w = 0; w < 2; ++w) {
          const compare::Comparison c = compare::Comparison::Create(truth, w == 0 ? counted : uncounted, options);
          const double ratio = c.Error(truth) / c.CalcNoiseFloor().floor;
          sum[s][w] += ratio / draws;
          lo[s][w] = std::min(lo[s][w], ratio);
          hi[s][w] = std::max(hi[s][w], ratio);
        }
      }
    }
    std::printf("%5d ", hits);
    for (int s = 0; s < 2; ++s) {
      for (int w = 0; w < 2; ++w) std::printf(" %5.3f (%5.3f-%5.3f)     ", sum[s][w], lo[s][w], hi[s][w]);
    }
    std::printf("\n");
    std::fflush(stdout);
  }
  return 0;
}
