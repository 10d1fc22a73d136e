#include "stagefit/synthetic/outside_catalogue.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <functional>
#include <numeric>
#include <random>

#include "stagefit/common/error.h"

namespace stagefit::synthetic {
namespace {

using Complex = std::complex<double>;
using measurement::ChannelGeometry;
using measurement::FrfData;

/// Adds one flexible mode of the top plate to the accelerance `data`: modal mass `mass`, frequency
/// `f_hz`, damping ratio `zeta`, and the channels' modal participations `phi_out`, `phi_in` (the mode
/// shape at the channel's point, along its direction).
void AddFlexibleMode(FrfData& data, const Eigen::VectorXd& phi_out, const Eigen::VectorXd& phi_in, double f_hz, double zeta,
                     double mass) {
  const double wp = 2 * M_PI * f_hz;
  const Eigen::MatrixXcd shape = (phi_out * phi_in.transpose()).cast<Complex>();
  for (int k = 0; k < data.num_frequencies(); ++k) {
    const double w = 2 * M_PI * data.frequency_hz(k);
    data.frf[k] += shape * (-w * w / (mass * Complex(wp * wp - w * w, 2 * zeta * wp * w)));
  }
}

/// The indices of `energy`, largest entry first.
std::vector<int> LargestFirst(const Eigen::VectorXd& energy) {
  std::vector<int> order(energy.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return energy(a) > energy(b); });
  return order;
}

/// The channels holding at least half their even share of `energy` (one entry per channel), largest
/// first.
std::vector<std::string> MainChannels(const Eigen::VectorXd& energy, const std::vector<ChannelGeometry>& channels) {
  const std::vector<int> order = LargestFirst(energy);
  std::vector<std::string> names;
  const double total = energy.sum();
  for (int c : order) {
    if (total > 0 && energy(c) / total >= 0.5 / static_cast<double>(energy.size())) names.push_back(channels[c].name);
  }
  return names;
}

/// The indices of the fewest entries of `energy` that hold half of its sum, largest first.
std::vector<int> HoldingHalf(const Eigen::VectorXd& energy) {
  std::vector<int> kept;
  double held = 0;
  for (int i : LargestFirst(energy)) {
    if (!(energy.sum() > 0) || held >= 0.5 * energy.sum()) break;
    kept.push_back(i);
    held += energy(i);
  }
  return kept;
}

/// n x 6: the readings of `channels` (d . (v + theta x r) = [d, r x d] . [v; theta]) for a rigid motion
/// [v; theta] of a frame at `origin_W`.
Eigen::MatrixXd RigidReadings(const std::vector<ChannelGeometry>& channels, const Eigen::Vector3d& origin_W) {
  Eigen::MatrixXd a(channels.size(), 6);
  for (size_t k = 0; k < channels.size(); ++k) {
    const Eigen::Vector3d& d = channels[k].direction_W;
    a.row(k) << d.transpose(), (channels[k].position_W - origin_W).cross(d).transpose();
  }
  return a;
}

/// Per element of the 6x6 rigid-body accelerance, OutsideCatalogueCase::elements' measure of the change.
Eigen::MatrixXd PlatformChange(const FrfData& with, const FrfData& without, const Eigen::Vector3d& origin_W) {
  const Eigen::MatrixXcd out = RigidReadings(with.outputs, origin_W).completeOrthogonalDecomposition().pseudoInverse().cast<Complex>();
  // The impacts' wrenches are the transpose of the readings' map: an impact along d at r is [d; r x d].
  const Eigen::MatrixXcd in =
      RigidReadings(with.inputs, origin_W).transpose().completeOrthogonalDecomposition().pseudoInverse().cast<Complex>();
  Eigen::MatrixXd change = Eigen::MatrixXd::Zero(6, 6);
  for (int k = 0; k < with.num_frequencies(); ++k) {
    const Eigen::MatrixXcd g0 = out * without.frf[k] * in, g1 = out * with.frf[k] * in;
    const Eigen::VectorXd diagonal = g0.diagonal().cwiseAbs();
    const double least = 1e-6 * diagonal.maxCoeff();
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j) {
        change(i, j) += std::norm(g1(i, j) - g0(i, j)) / (std::max(diagonal(i), least) * std::max(diagonal(j), least));
      }
    }
  }
  return change;
}

}  // namespace

OutsideCatalogueCase MakeOutsideCatalogueCase(const model::ModelSpec& nominal, uint64_t seed, const std::string& kind,
                                              const HiddenEffectOptions& options) {
  // The scattered truth, the channels and the band of an effect-free hidden-effect case.
  HiddenEffectOptions base_options = options;
  base_options.num_effects = 0;
  base_options.layout = TestLayout::kTopPlate;
  const HiddenEffectCase base = MakeHiddenEffectCase(nominal, seed, base_options);
  const FrfData& declared = base.measurement;
  const Eigen::Vector3d p_WXo = *declared.frame_origin_W;  // set for the top-plate layout

  std::mt19937_64 rng(seed ^ 0x0c47a109ULL);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * u(rng); };
  OutsideCatalogueCase c;
  c.seed = seed;
  c.kind = kind;
  if (c.kind.empty()) {
    const char* kinds[] = {"plate-bending", "plate-breathing", "cable"};
    c.kind = kinds[std::min(2, static_cast<int>(3 * u(rng)))];
  }
  const double noise = uniform(options.noise_min, options.noise_max);
  const double target = uniform(options.min_visibility, 4 * options.min_visibility);
  const FrfData without =
      CalcBruteForceFrf(base.truth, declared.outputs, declared.inputs, declared.frequency_hz, declared.quantity);
  auto visibility = [&](const FrfData& with) {
    return NoiseNormalisedDifference(with, without, noise, options.noise_per_channel);
  };

  FrfData with;
  char text[256];
  if (c.kind == "plate-bending" || c.kind == "plate-breathing") {
    const bool bending = c.kind == "plate-bending";
    const double d = 0.14;  // the radius of the test's channel points (ComplianceTestSensors)
    auto participation = [&](const std::vector<ChannelGeometry>& channels) {
      Eigen::VectorXd phi(channels.size());
      for (size_t k = 0; k < channels.size(); ++k) {
        const Eigen::Vector3d r = channels[k].position_W - p_WXo;
        const Eigen::Vector3d shape = bending ? Eigen::Vector3d(0, 0, (r.x() * r.x() - r.y() * r.y()) / (d * d))
                                              : Eigen::Vector3d(r.x() / d, r.y() / d, 0);
        phi(k) = shape.dot(channels[k].direction_W);
      }
      return phi;
    };
    const double fmax = declared.frequency_hz.maxCoeff();
    const double f_hz = uniform(std::max(40.0, 0.3 * fmax), 0.9 * fmax);
    const double zeta = uniform(0.01, 0.04);
    const Eigen::VectorXd phi_out = participation(declared.outputs), phi_in = participation(declared.inputs);
    // The change is proportional to 1 / mass: the unit-mass visibility gives the mass of the target.
    with = without;
    AddFlexibleMode(with, phi_out, phi_in, f_hz, zeta, 1.0);
    const double mass = visibility(with) / target;
    with = without;
    AddFlexibleMode(with, phi_out, phi_in, f_hz, zeta, mass);
    std::snprintf(text, sizeof text, "%s mode of the top plate at %.0f Hz (zeta %.3f, modal mass %.3g kg)",
                  bending ? "a saddle bending" : "an in-plane breathing", f_hz, zeta, mass);
  } else if (c.kind == "cable") {
    // A lossy spring between the granite and the hexapod along x, y or both, at the hexapod's CoM.
    const int axes = std::min(2, static_cast<int>(3 * u(rng)));  // 0: x, 1: y, 2: both
    const double eta = uniform(0.2, 0.5);
    auto with_cable = [&](double k) {
      model::ModelSpec truth = base.truth;
      model::JointSpec cable;
      cable.name = "cable";
      cable.parent = "granite";
      cable.child = "hexapod";
      cable.origin_W = truth.bodies[model::FindBody(truth, "hexapod")].com_W;
      cable.imposed = {false, false, false, false, false, false};
      for (int i = 0; i < 6; ++i) cable.stiffness[i] = cable.damping[i] = cable.loss_factor[i] = 0.0;
      for (int i = 0; i < 2; ++i) {
        if (axes == 2 || axes == i) {
          cable.stiffness[i] = k;
          cable.loss_factor[i] = eta;
        }
      }
      truth.joints.push_back(cable);
      return CalcBruteForceFrf(truth, declared.outputs, declared.inputs, declared.frequency_hz, declared.quantity);
    };
    // Bisection in log k for the target visibility (the change grows with k).
    double lo = std::log(1e2), hi = std::log(1e8);
    for (int it = 0; it < 30; ++it) {
      const double mid = 0.5 * (lo + hi);
      (visibility(with_cable(std::exp(mid))) < target ? lo : hi) = mid;
    }
    const double k = std::exp(0.5 * (lo + hi));
    with = with_cable(k);
    std::snprintf(text, sizeof text, "a cable between the granite and the hexapod: %.3g N/m along %s, loss factor %.2f", k,
                  axes == 0 ? "x" : axes == 1 ? "y" : "x and y", eta);
  } else {
    throw InputError("outside-catalogue case: kind '" + kind + "' unknown; expected plate-bending, plate-breathing or cable");
  }
  c.description = text;
  c.visibility = visibility(with);

  const auto change = NoiseNormalisedChange(with, without, noise, options.noise_per_channel);
  Eigen::VectorXd per_output = Eigen::VectorXd::Zero(with.num_outputs()), per_input = Eigen::VectorXd::Zero(with.num_inputs());
  double peak = -1;
  for (int k = 0; k < with.num_frequencies(); ++k) {
    per_output += change[k].rowwise().sum();
    per_input += change[k].colwise().sum().transpose();
    if (change[k].sum() > peak) {
      peak = change[k].sum();
      c.peak_hz = with.frequency_hz(k);
    }
  }
  c.outputs = MainChannels(per_output, with.outputs);
  c.inputs = MainChannels(per_input, with.inputs);

  const std::vector<measurement::FrequencyBand> bands =
      measurement::MakeFractionalOctaveBands(with.frequency_hz.minCoeff(), with.frequency_hz.maxCoeff(), 3);
  Eigen::VectorXd per_band = Eigen::VectorXd::Zero(static_cast<int>(bands.size()));
  const std::vector<int> band_of = measurement::BandOfEachFrequency(with.frequency_hz, bands);
  for (int k = 0; k < with.num_frequencies(); ++k) {
    if (band_of[static_cast<size_t>(k)] >= 0) per_band(band_of[static_cast<size_t>(k)]) += change[k].sum();
  }
  for (int b : HoldingHalf(per_band)) c.bands.push_back(bands[b]);
  static const char* kOutputs[6] = {"Dx", "Dy", "Dz", "Rx", "Ry", "Rz"};
  static const char* kInputs[6] = {"Fx", "Fy", "Fz", "Mx", "My", "Mz"};
  const Eigen::MatrixXd per_element = PlatformChange(with, without, p_WXo);
  for (int e : HoldingHalf(per_element.reshaped())) {
    c.elements.push_back(std::string(kOutputs[e % 6]) + "/" + kInputs[e / 6]);  // column-major
  }

  c.measurement = with;
  NoiseOptions n;
  n.relative = n.absolute = noise;
  n.seed = seed * 7919 + 5;
  n.per_channel = options.noise_per_channel;
  AddNoise(c.measurement, n);
  c.measurement.source = "outside-catalogue case " + std::to_string(seed) + " (" + c.kind + ")";
  return c;
}

}  // namespace stagefit::synthetic
