#include "stagefit/synthetic/synthetic_measurement.h"

#include <Eigen/LU>
#include <fftw3.h>

#include <cmath>
#include <functional>
#include <map>
#include <random>

#include "stagefit/common/eigen_decomposition.h"
#include "stagefit/common/error.h"
#include "stagefit/common/units.h"
#include "stagefit/kinematics/rigid_transform.h"

namespace stagefit::synthetic {
namespace {

using Complex = std::complex<double>;
using measurement::ChannelGeometry;
using measurement::FrfData;
using measurement::FrfQuantity;

Eigen::Matrix3d Cross(const Eigen::Vector3d& r) {
  Eigen::Matrix3d S;
  S << 0, -r.z(), r.y(), r.z(), 0, -r.x(), -r.y(), r.x(), 0;
  return S;
}

// Motion [u; theta] of a body at its CoM -> motion of the body point at CoM + r.
Eigen::Matrix<double, 6, 6> Move(const Eigen::Vector3d& r) {
  Eigen::Matrix<double, 6, 6> S = Eigen::Matrix<double, 6, 6>::Identity();
  S.topRightCorner<3, 3>() = -Cross(r);
  return S;
}

struct BruteForceSystem {
  Eigen::MatrixXd N;                 // null-space basis: q = N y
  Eigen::MatrixXd M, C, K, L;        // reduced; L = loss stiffness
  std::map<std::string, int> body;   // name -> block
  std::vector<Eigen::Vector3d> com;
};

BruteForceSystem Build(const model::ModelSpec& spec) {
  const int nb = static_cast<int>(spec.bodies.size());
  const int n = 6 * nb;
  BruteForceSystem s;
  for (int b = 0; b < nb; ++b) {
    s.body[spec.bodies[b].name] = b;
    s.com.push_back(spec.bodies[b].com_W);
  }
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n, n), C = M, K = M, L = M, G = M;
  for (int b = 0; b < nb; ++b) {
    M.block<3, 3>(6 * b, 6 * b) = spec.bodies[b].mass_kg * Eigen::Matrix3d::Identity();
    M.block<3, 3>(6 * b + 3, 6 * b + 3) = spec.bodies[b].inertia_com_W;
  }
  std::vector<Eigen::RowVectorXd> constraints;
  for (const auto& j : spec.joints) {
    auto child = s.body.find(j.child);
    if (child == s.body.end()) throw InputError("synthetic model: joint '" + j.name + "' child unknown");
    Eigen::Matrix<double, 6, 6> axes = Eigen::Matrix<double, 6, 6>::Zero();
    axes.topLeftCorner<3, 3>() = j.R_WJ.transpose();
    axes.bottomRightCorner<3, 3>() = j.R_WJ.transpose();
    Eigen::MatrixXd rel = Eigen::MatrixXd::Zero(6, n);  // relative motion of the joint, joint axes
    const int c = child->second;
    rel.middleCols(6 * c, 6) = axes * Move(j.origin_W - s.com[c]);
    if (j.parent != model::kGroundName) {
      const int p = s.body.at(j.parent);
      rel.middleCols(6 * p, 6) -= axes * Move(j.origin_W - s.com[p]);
    }
    Eigen::Matrix<double, 6, 6> kj = Eigen::Matrix<double, 6, 6>::Zero(), cj = kj, lj = kj;
    for (int i = 0; i < 6; ++i) {
      if (j.imposed[i]) {
        constraints.push_back(rel.row(i));
        continue;
      }
      kj(i, i) = j.stiffness[i];
      cj(i, i) = j.damping[i];
      lj(i, i) = j.loss_factor[i] * j.stiffness[i];
    }
    for (const auto& cp : j.couplings) {
      const int a = index(cp.a), b = index(cp.b);
      const double eta = 0.5 * (j.loss_factor[a] + j.loss_factor[b]);
      kj(a, b) += cp.stiffness;
      kj(b, a) += cp.stiffness;
      cj(a, b) += cp.damping;
      cj(b, a) += cp.damping;
      lj(a, b) += eta * cp.stiffness;
      lj(b, a) += eta * cp.stiffness;
    }
    K += rel.transpose() * kj * rel;
    C += rel.transpose() * cj * rel;
    L += rel.transpose() * lj * rel;
    if (j.spin_rate_rad_s != 0.0) {
      // Every body above this joint spins with it.
      const Eigen::Vector3d e = j.R_WJ.col(2);
      std::function<void(const std::string&)> spin = [&](const std::string& name) {
        const int b = s.body.at(name);
        const double polar = e.dot(spec.bodies[b].inertia_com_W * e);
        G.block<3, 3>(6 * b + 3, 6 * b + 3) += -j.spin_rate_rad_s * polar * Cross(e);
        for (const auto& other : spec.joints) {
          if (other.parent == name) spin(other.child);
        }
      };
      spin(j.child);
    }
  }
  if (constraints.empty()) {
    s.N = Eigen::MatrixXd::Identity(n, n);
  } else {
    Eigen::MatrixXd A(constraints.size(), n);
    for (size_t r = 0; r < constraints.size(); ++r) A.row(r) = constraints[r];
    const SingularValueDecomposition svd = CalcSvd(A, kSvdFullV);
    const double tol = 1e-10 * svd.values(0);
    int rank = 0;
    for (int i = 0; i < svd.values.size(); ++i) rank += svd.values(i) > tol;
    s.N = svd.V.rightCols(n - rank);
  }
  s.M = s.N.transpose() * M * s.N;
  s.C = s.N.transpose() * (C + G) * s.N;
  s.K = s.N.transpose() * K * s.N;
  s.L = s.N.transpose() * L * s.N;
  return s;
}

int BodyOf(const BruteForceSystem& s, const ChannelGeometry& ch) {
  auto it = s.body.find(ch.body);
  if (it == s.body.end()) throw InputError("synthetic measurement: channel '" + ch.name + "' is on unknown body '" + ch.body + "'");
  return it->second;
}

}  // namespace

FrfData CalcBruteForceFrf(const model::ModelSpec& truth, const std::vector<ChannelGeometry>& sensors,
                          const std::vector<ChannelGeometry>& impacts, const Eigen::VectorXd& frequency_hz,
                          FrfQuantity quantity) {
  BruteForceSystem s = Build(truth);
  const int n = static_cast<int>(s.N.rows());
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(sensors.size(), n), in = Eigen::MatrixXd::Zero(n, impacts.size());
  for (size_t o = 0; o < sensors.size(); ++o) {
    const int b = BodyOf(s, sensors[o]);
    out.block(o, 6 * b, 1, 6) = sensors[o].direction_W.transpose() * Move(sensors[o].position_W - s.com[b]).topRows<3>();
  }
  for (size_t i = 0; i < impacts.size(); ++i) {
    const int b = BodyOf(s, impacts[i]);
    Eigen::Matrix<double, 6, 1> wrench = Eigen::Matrix<double, 6, 1>::Zero();
    wrench.head<3>() = impacts[i].direction_W;
    in.block(6 * b, i, 6, 1) = Move(impacts[i].position_W - s.com[b]).transpose() * wrench;
  }
  const Eigen::MatrixXcd Cr = (out * s.N).cast<Complex>(), Br = (s.N.transpose() * in).cast<Complex>();
  const int power = quantity == FrfQuantity::kReceptance ? 0 : quantity == FrfQuantity::kMobility ? 1 : 2;
  FrfData data;
  data.frequency_hz = frequency_hz;
  data.quantity = quantity;
  data.outputs = sensors;
  data.inputs = impacts;
  data.source = "synthetic (brute-force)";
  for (int f = 0; f < frequency_hz.size(); ++f) {
    const double w = 2 * M_PI * frequency_hz(f);
    const Complex jw(0, w);
    Eigen::MatrixXcd Z = s.K.cast<Complex>() + Complex(0, 1) * s.L.cast<Complex>() + jw * s.C.cast<Complex>() -
                         w * w * s.M.cast<Complex>();
    Complex factor = std::pow(jw, power) * std::exp(-jw * truth.acquisition_delay_s);
    data.frf.push_back(factor * (Cr * Z.fullPivLu().solve(Br)));
  }
  return data;
}

namespace {

/// Per element, the RMS of |H| over the band that scales AddNoise's absolute noise: the element's own
/// or, with `per_channel`, that of its output channel over every input (NoiseOptions::per_channel).
Eigen::MatrixXd AbsoluteNoiseScale(const FrfData& data, bool per_channel) {
  const int nf = data.num_frequencies(), no = data.num_outputs(), ni = data.num_inputs();
  Eigen::MatrixXd mean_square = Eigen::MatrixXd::Zero(no, ni);
  for (int f = 0; f < nf; ++f) mean_square += data.frf[f].cwiseAbs2();
  mean_square /= nf;
  if (per_channel) mean_square = mean_square.rowwise().mean().replicate(1, ni);
  return mean_square.cwiseSqrt();
}

}  // namespace

void AddNoise(FrfData& data, const NoiseOptions& options) {
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> g(0.0, 1.0 / std::sqrt(2.0));  // complex unit variance
  const int nf = data.num_frequencies(), no = data.num_outputs(), ni = data.num_inputs();
  const Eigen::MatrixXd rms = AbsoluteNoiseScale(data, options.per_channel);
  data.coherence.assign(nf, Eigen::MatrixXd::Zero(no, ni));
  for (int f = 0; f < nf; ++f) {
    for (int i = 0; i < ni; ++i) {
      for (int o = 0; o < no; ++o) {
        Complex& h = data.frf[f](o, i);
        const double magnitude = std::abs(h);
        const double sigma_rel = options.relative * magnitude, sigma_abs = options.absolute * rms(o, i);
        const double variance = sigma_rel * sigma_rel + sigma_abs * sigma_abs;
        // An element the model makes exactly zero (a symmetry) gets no noise: its zero is exact.
        const double power = magnitude * magnitude + variance;
        data.coherence[f](o, i) = power > 0.0 ? magnitude * magnitude / power : 1.0;
        h += sigma_rel * Complex(g(rng), g(rng)) + sigma_abs * Complex(g(rng), g(rng));
      }
    }
  }
}

std::vector<ChannelGeometry> ComplianceTestSensors(const std::string& body, const Eigen::Vector3d& p_WXo) {
  const double d = 0.14;
  const Eigen::Vector3d positions[4] = {{0, d, 0}, {-d, 0, 0}, {0, -d, 0}, {d, 0, 0}};
  std::vector<ChannelGeometry> channels;
  for (int a = 0; a < 4; ++a) {
    for (int axis = 0; axis < 3; ++axis) {
      ChannelGeometry c;
      c.name = "a" + std::to_string(a + 1) + "xyz"[axis];
      c.body = body;
      c.position_W = p_WXo + positions[a];
      c.direction_W = Eigen::Vector3d::Unit(axis);
      channels.push_back(c);
    }
  }
  return channels;
}

std::vector<ChannelGeometry> ComplianceTestImpacts(const std::string& body, const Eigen::Vector3d& p_WXo) {
  const double d = 0.14;
  const std::pair<Eigen::Vector3d, Eigen::Vector3d> hits[10] = {
      {{0, d, 0}, {0, -1, 0}}, {{0, d, 0}, {0, 0, -1}},  {{-d, 0, 0}, {1, 0, 0}}, {{-d, 0, 0}, {0, 0, -1}},
      {{0, -d, 0}, {0, 1, 0}}, {{0, -d, 0}, {0, 0, -1}}, {{d, 0, 0}, {-1, 0, 0}}, {{d, 0, 0}, {0, 0, -1}},
      {{0, -d, 0}, {-1, 0, 0}}, {{0, d, 0}, {-1, 0, 0}}};
  std::vector<ChannelGeometry> channels;
  for (int i = 0; i < 10; ++i) {
    ChannelGeometry c;
    c.name = "h" + std::to_string(i + 1);
    c.body = body;
    c.position_W = p_WXo + hits[i].first;
    c.direction_W = hits[i].second;
    channels.push_back(c);
  }
  return channels;
}

std::vector<ChannelGeometry> WholeStackSensors(const model::ModelSpec& spec) {
  const Eigen::Vector3d offsets[3] = {{0.2, 0.0, 0.05}, {-0.1, 0.17, 0.05}, {-0.1, -0.17, 0.05}};
  std::vector<ChannelGeometry> channels;
  for (const auto& body : spec.bodies) {
    for (int a = 0; a < 3; ++a) {
      for (int axis = 0; axis < 3; ++axis) {
        ChannelGeometry c;
        c.name = body.name + "_a" + std::to_string(a + 1) + "xyz"[axis];
        c.body = body.name;
        c.position_W = body.com_W + offsets[a];
        c.direction_W = Eigen::Vector3d::Unit(axis);
        channels.push_back(c);
      }
    }
  }
  return channels;
}

std::vector<ChannelGeometry> WholeStackImpacts(const model::ModelSpec& spec, const std::string& hit_body) {
  const int b = model::FindBody(spec, hit_body);
  if (b < 0) throw InputError("whole-stack test: the model has no body '" + hit_body + "' to hit");
  const Eigen::Vector3d p = spec.bodies[b].com_W;
  const std::pair<Eigen::Vector3d, Eigen::Vector3d> hits[5] = {{{0.25, 0.15, 0.05}, {-1, 0, 0}},
                                                               {{0.25, 0.15, 0.05}, {0, -1, 0}},
                                                               {{0.25, 0.15, 0.05}, {0, 0, -1}},
                                                               {{-0.25, -0.15, 0.05}, {0, 1, 0}},
                                                               {{-0.25, -0.15, 0.05}, {0, 0, -1}}};
  std::vector<ChannelGeometry> channels;
  for (int i = 0; i < 5; ++i) {
    ChannelGeometry c;
    c.name = "h" + std::to_string(i + 1);
    c.body = hit_body;
    c.position_W = p + hits[i].first;
    c.direction_W = hits[i].second;
    channels.push_back(c);
  }
  return channels;
}

Eigen::VectorXd LogFrequencies(double fmin_hz, double fmax_hz, int count) {
  Eigen::VectorXd f(count);
  for (int i = 0; i < count; ++i) f(i) = fmin_hz * std::pow(fmax_hz / fmin_hz, count == 1 ? 0.0 : double(i) / (count - 1));
  return f;
}

/// Draws one hidden effect of kind `kind` (a location and a magnitude) and applies it to `truth` and,
/// for a sensor error, to `true_sensors` (the truth then also carries the correction that undoes it,
/// so that its error against the declared geometry is the noise floor).
template <typename Rng>
HiddenEffect ApplyHiddenEffect(const std::string& kind, Rng& rng, model::ModelSpec& truth,
                               std::vector<ChannelGeometry>& true_sensors) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * u(rng); };
  auto pick = [&](int count) { return static_cast<int>(std::min<double>(count - 1, std::floor(u(rng) * count))); };
  char text[256];
  HiddenEffect e;
  e.name = kind;
if (e.name == "payload") {
    // A separate body rigidly fixed (all six DoF imposed) on the hexapod or the spindle.
    const bool on_hexapod = u(rng) < 0.6;
    e.location = on_hexapod ? "hexapod" : "rz";
    const auto& host = truth.bodies[model::FindBody(truth, e.location)];
    const double mass = on_hexapod ? uniform(4, 10) : uniform(30, 70);
    const double dz = on_hexapod ? uniform(0.04, 0.15) : uniform(0.0, 0.1);
    model::BodySpec b;
    b.name = "hidden_payload";
    b.mass_kg = mass;
    b.com_W = host.com_W + Eigen::Vector3d(0, 0, dz);
    b.inertia_com_W = Eigen::Matrix3d::Identity() * 1e-6 * mass;
    model::JointSpec j;
    j.name = "hidden_payload";
    j.parent = e.location;
    j.child = b.name;
    j.origin_W = b.com_W;
    j.imposed = {true, true, true, true, true, true};
    truth.bodies.push_back(b);
    truth.joints.push_back(j);
    std::snprintf(text, sizeof text, "%.1f kg rigidly fixed %.0f mm above the CoM of %s", mass, 1e3 * dz, e.location.c_str());
  } else if (e.name == "extra-body") {
    e.location = u(rng) < 0.5 ? "hexapod" : "rz";
    const auto& host = truth.bodies[model::FindBody(truth, e.location)];
    const double mass = e.location == "hexapod" ? uniform(1.5, 4) : uniform(10, 25);
    const double f = uniform(60, 300), w = 2 * M_PI * f;
    model::BodySpec b;
    b.name = "hidden_body";
    b.mass_kg = mass;
    b.com_W = host.com_W + Eigen::Vector3d(0, 0, 0.05);
    b.inertia_com_W = mass * 0.0025 * Eigen::Matrix3d::Identity();
    model::JointSpec j;
    j.name = "hidden_body";
    j.parent = e.location;
    j.child = b.name;
    j.origin_W = b.com_W;
    for (int i = 0; i < 6; ++i) {
      const double inertia = i < 3 ? mass : mass * 0.0025;
      j.stiffness[i] = inertia * w * w * (i < 3 ? 1.0 : 1.5);
      j.damping[i] = 2 * 0.02 * std::sqrt(j.stiffness[i] * inertia);
    }
    truth.bodies.push_back(b);
    truth.joints.push_back(j);
    std::snprintf(text, sizeof text, "a %.1f kg body on %s with a local mode at %.0f Hz", mass, e.location.c_str(), f);
  } else if (e.name == "servo-stiffness") {
    const char* where[] = {"ty.Dy", "ry.Ry", "rz.Rz"};
    int w = pick(3);
    e.location = where[w];
    model::JointSpec& j = truth.joints[model::FindJoint(truth, e.location.substr(0, 2))];
    const int d = w == 0 ? 1 : w == 1 ? 4 : 5;
    const model::BodySpec& child = truth.bodies[model::FindBody(truth, j.child)];
    // A drive stiffness meant to put a new mode of the stage roughly between 40 and 250 Hz: the
    // inertia is a rough figure for what moves on that axis (the stage and everything above it).
    const double f = uniform(40, 250), omega = 2 * M_PI * f;
    const double inertia = d < 3 ? 1000.0 : child.inertia_com_W(d - 3, d - 3) * 20;
    j.imposed[d] = false;
    j.stiffness[d] = inertia * omega * omega;
    j.damping[d] = 2 * 0.03 * std::sqrt(j.stiffness[d] * inertia);
    std::snprintf(text, sizeof text, "%s is a spring of %.3g instead of a rigid constraint", e.location.c_str(), j.stiffness[d]);
  } else if (e.name == "coupled-stiffness") {
    const bool xr = u(rng) < 0.5;
    e.location = xr ? "hexapod.Dx-Ry" : "hexapod.Dy-Rx";
    model::JointSpec& j = truth.joints[model::FindJoint(truth, "hexapod")];
    const Dof a = xr ? Dof::kDx : Dof::kDy, b = xr ? Dof::kRy : Dof::kRx;
    const double rho = (u(rng) < 0.5 ? -1 : 1) * uniform(0.4, 0.8);
    const double k = rho * std::sqrt(j.stiffness[index(a)] * j.stiffness[index(b)]);
    j.couplings.push_back({a, b, k, 0.0});
    std::snprintf(text, sizeof text, "a coupling term %.3g N/rad between %s (correlation %.2f)", k, e.location.c_str(), rho);
  } else if (e.name == "structural-damping") {
    e.location = u(rng) < 0.5 ? "hexapod" : "rz";
    model::JointSpec& j = truth.joints[model::FindJoint(truth, e.location)];
    const double eta = uniform(0.04, 0.1);
    for (int i = 0; i < 6; ++i) {
      j.loss_factor[i] = j.imposed[i] ? 0.0 : eta;
      j.damping[i] = 0.0;
    }
    std::snprintf(text, sizeof text, "hysteretic loss factor %.3f in joint %s instead of viscous damping", eta, e.location.c_str());
  } else if (e.name == "joint-offset") {
    e.location = u(rng) < 0.5 ? "hexapod" : "rz";
    model::JointSpec& j = truth.joints[model::FindJoint(truth, e.location)];
    const double dz = (u(rng) < 0.5 ? -1 : 1) * uniform(0.06, 0.15);
    j.origin_W.z() += dz;
    std::snprintf(text, sizeof text, "the stiffness centre of %s is %.0f mm from where assumed", e.location.c_str(), 1e3 * dz);
  } else if (e.name == "sensor-geometry") {
    int s = pick(12);
    e.location = true_sensors[s].name;
    const double angle = (u(rng) < 0.5 ? -1 : 1) * uniform(10, 25) * M_PI / 180;
    const int axis = (s % 3 + 1 + pick(2)) % 3;  // rotate about an axis other than its own
    Eigen::Vector3d euler = Eigen::Vector3d::Zero();
    euler(axis) = angle;
    true_sensors[s].direction_W =
        kinematics::RotationFromEuler({euler(0), euler(1), euler(2)}) * true_sensors[s].direction_W;
    // The truth model knows where the channel really points (as a fitted sensor-geometry effect would).
    model::GeometryCorrection g;
    g.channel = e.location;
    g.rotation_rad = euler;
    truth.geometry_corrections.push_back(g);
    std::snprintf(text, sizeof text, "accelerometer channel %s is rotated by %.0f deg", e.location.c_str(), angle * kDegreesPerRadian);
  } else {
    e.location = "acquisition";
    const double tau = uniform(0.3e-3, 1.0e-3);
    truth.acquisition_delay_s += tau;
    std::snprintf(text, sizeof text, "a %.2f ms delay in the acquisition chain", tau * 1e3);
  }
  e.description = text;
  return e;
}

std::vector<Eigen::MatrixXd> NoiseNormalisedChange(const FrfData& with, const FrfData& without, double noise,
                                                   bool per_channel) {
  const int nf = without.num_frequencies(), no = without.num_outputs(), ni = without.num_inputs();
  const Eigen::MatrixXd rms = AbsoluteNoiseScale(without, per_channel);
  // An element the symmetric model makes exactly zero gets no noise from AddNoise; a real test would
  // still show its channel's noise floor: 1e-3 of the strongest element's RMS.
  const double floor2 = 1e-6 * rms.maxCoeff() * rms.maxCoeff();
  std::vector<Eigen::MatrixXd> change(nf, Eigen::MatrixXd::Zero(no, ni));
  for (int f = 0; f < nf; ++f) {
    for (int o = 0; o < no; ++o) {
      for (int i = 0; i < ni; ++i) {
        const double sigma2 = noise * noise * (std::norm(without.frf[f](o, i)) + rms(o, i) * rms(o, i) + floor2);
        change[f](o, i) = std::norm(with.frf[f](o, i) - without.frf[f](o, i)) / sigma2;
      }
    }
  }
  return change;
}

double NoiseNormalisedDifference(const FrfData& with, const FrfData& without, double noise, bool per_channel) {
  double sum = 0.0;
  for (const auto& c : NoiseNormalisedChange(with, without, noise, per_channel)) sum += c.sum();
  return std::sqrt(sum / (static_cast<double>(without.num_frequencies()) * without.num_outputs() * without.num_inputs()));
}

HiddenEffectOptions EvalLoopCaseOptions(int num_effects, double fmax_hz, int num_frequencies) {
  HiddenEffectOptions options;
  options.num_effects = num_effects;
  options.fmin_hz = 5.0;
  options.fmax_hz = fmax_hz;
  options.num_frequencies = num_frequencies;
  options.noise_min = 0.01;
  options.noise_max = 0.03;
  return options;
}

HiddenEffectCase MakeHiddenEffectCase(const model::ModelSpec& nominal, uint64_t seed, const HiddenEffectOptions& options) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * u(rng); };
  auto pick = [&](int count) { return static_cast<int>(std::min<double>(count - 1, std::floor(u(rng) * count))); };
  HiddenEffectCase c;
  c.seed = seed;
  c.truth = nominal;
  model::ModelSpec& truth = c.truth;

  std::normal_distribution<double> scatter(0.0, options.stiffness_scatter);
  for (auto& j : truth.joints) {
    for (int i = 0; i < 6; ++i) {
      if (j.imposed[i]) continue;
      j.stiffness[i] *= std::exp(std::clamp(scatter(rng), -std::log(1.6), std::log(1.6)));
      c.scattered_parameters.push_back(j.name + ".k." + std::string(kDofNames[i]));
    }
  }
  int frame = model::FindFrame(nominal, nominal.compliance_frame);
  const Eigen::Vector3d p_WXo = frame >= 0 ? nominal.frames[frame].origin_W : Eigen::Vector3d(0, 0, -0.03);
  const bool whole_stack = options.layout == TestLayout::kWholeStack;
  std::vector<ChannelGeometry> sensors = whole_stack ? WholeStackSensors(nominal) : ComplianceTestSensors("hexapod", p_WXo);
  std::vector<ChannelGeometry> impacts = whole_stack ? WholeStackImpacts(nominal) : ComplianceTestImpacts("hexapod", p_WXo);
  std::vector<ChannelGeometry> true_sensors = sensors;

  const char* kinds[] = {"payload", "extra-body", "servo-stiffness", "coupled-stiffness",
                         "structural-damping", "joint-offset", "sensor-geometry", "delay"};
  std::vector<int> chosen;
  while (static_cast<int>(chosen.size()) < options.num_effects) {
    int k = pick(8);
    if (std::find(chosen.begin(), chosen.end(), k) == chosen.end()) chosen.push_back(k);
  }
  const Eigen::VectorXd f = LogFrequencies(options.fmin_hz, options.fmax_hz, options.num_frequencies);
  const double noise_level = uniform(options.noise_min, options.noise_max);
  c.noise = noise_level;
  // Each effect is drawn again (location and magnitude) until it matters: alone, it changes the data
  // by at least min_visibility noise standard deviations (RMS over all points) against the truth with
  // the effects drawn before it; the most visible draw is kept when none does (the first rule:
  // HiddenEffectOptions::visibility_against_no_effect).
  const FrfData without_any = CalcBruteForceFrf(truth, true_sensors, impacts, f, FrfQuantity::kAccelerance);
  for (size_t n = 0; n < chosen.size(); ++n) {
    const int k = chosen[n];
    const FrfData without = n == 0 || options.visibility_against_no_effect
                                ? without_any
                                : CalcBruteForceFrf(truth, true_sensors, impacts, f, FrfQuantity::kAccelerance);
    HiddenEffect kept;
    model::ModelSpec kept_truth;
    std::vector<ChannelGeometry> kept_sensors;
    const int draws = std::max(1, options.max_draws);  // one draw at least: the effect is always applied
    for (int attempt = 0; attempt < draws; ++attempt) {
      model::ModelSpec trial = truth;
      std::vector<ChannelGeometry> trial_sensors = true_sensors;
      HiddenEffect e = ApplyHiddenEffect(kinds[k], rng, trial, trial_sensors);
      const FrfData with = CalcBruteForceFrf(trial, trial_sensors, impacts, f, FrfQuantity::kAccelerance);
      e.visibility = NoiseNormalisedDifference(with, without, noise_level, options.noise_per_channel);
      const bool last = attempt + 1 == draws;
      if (attempt == 0 || e.visibility > kept.visibility || (last && options.visibility_against_no_effect)) {
        kept = e;
        kept_truth = std::move(trial);
        kept_sensors = std::move(trial_sensors);
      }
      if (e.visibility >= options.min_visibility) break;
    }
    truth = std::move(kept_truth);
    true_sensors = std::move(kept_sensors);
    c.effects.push_back(kept);
  }
  c.measurement = CalcBruteForceFrf(truth, true_sensors, impacts, f, FrfQuantity::kAccelerance);
  c.measurement.outputs = sensors;  // the declared (nominal) geometry
  NoiseOptions noise;
  noise.relative = noise.absolute = noise_level;
  noise.seed = seed * 7919 + 1;
  noise.per_channel = options.noise_per_channel;
  AddNoise(c.measurement, noise);
  if (!whole_stack) c.measurement.frame_origin_W = p_WXo;
  c.measurement.source = "hidden-effect case " + std::to_string(seed);
  return c;
}

measurement::RawHammerData MakeRawHammerTest(const model::ModelSpec& truth, const std::vector<ChannelGeometry>& sensors,
                                             const std::vector<ChannelGeometry>& impacts, const RawHammerOptions& options) {
  const int ns = options.num_samples, nbins = ns / 2 + 1;
  const double fs = options.sample_rate_hz;
  Eigen::VectorXd f(nbins);
  for (int k = 0; k < nbins; ++k) f(k) = k * fs / ns;
  FrfData H = CalcBruteForceFrf(truth, sensors, impacts, f, FrfQuantity::kAccelerance);
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> time(ns);
  std::vector<fftw_complex> spectrum(nbins);
  fftw_plan forward = fftw_plan_dft_r2c_1d(ns, time.data(), spectrum.data(), FFTW_ESTIMATE);
  fftw_plan backward = fftw_plan_dft_c2r_1d(ns, spectrum.data(), time.data(), FFTW_ESTIMATE);
  measurement::RawHammerData raw;
  raw.sample_rate_hz = fs;
  raw.quantity = FrfQuantity::kAccelerance;
  raw.outputs = sensors;
  raw.inputs = impacts;
  raw.source = "synthetic raw hammer test";
  raw.hits.resize(impacts.size());
  for (size_t i = 0; i < impacts.size(); ++i) {
    for (int h = 0; h < options.hits_per_impact; ++h) {
      measurement::HammerHit hit;
      hit.force = Eigen::VectorXd::Zero(ns);
      const double t0 = 0.02 + 0.01 * u(rng);
      const double peak = options.peak_force_n * (0.8 + 0.4 * u(rng));
      for (int n = 0; n < ns; ++n) {
        const double t = n / fs - t0;
        if (t >= 0 && t <= options.pulse_s) hit.force(n) = peak * std::sin(M_PI * t / options.pulse_s);
      }
      std::copy(hit.force.data(), hit.force.data() + ns, time.begin());
      fftw_execute(forward);
      std::vector<Complex> F(nbins);
      for (int k = 0; k < nbins; ++k) F[k] = Complex(spectrum[k][0], spectrum[k][1]);
      hit.response = Eigen::MatrixXd::Zero(ns, sensors.size());
      for (size_t o = 0; o < sensors.size(); ++o) {
        for (int k = 0; k < nbins; ++k) {
          Complex y = H.frf[k](o, i) * F[k];
          if (k == nbins - 1 && ns % 2 == 0) y = Complex(y.real(), 0.0);  // Nyquist bin of a real signal
          spectrum[k][0] = y.real() / ns;
          spectrum[k][1] = y.imag() / ns;
        }
        fftw_execute(backward);
        for (int n = 0; n < ns; ++n) hit.response(n, o) = time[n];
      }
      const double force_rms = std::sqrt(hit.force.squaredNorm() / ns);
      for (int n = 0; n < ns; ++n) hit.force(n) += options.noise * force_rms * g(rng);
      for (int o = 0; o < hit.response.cols(); ++o) {
        const double rms = std::sqrt(hit.response.col(o).squaredNorm() / ns);
        for (int n = 0; n < ns; ++n) hit.response(n, o) += options.noise * rms * g(rng);
      }
      raw.hits[i].push_back(std::move(hit));
    }
  }
  fftw_destroy_plan(forward);
  fftw_destroy_plan(backward);
  return raw;
}

}  // namespace stagefit::synthetic
