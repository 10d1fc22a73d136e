#include "stagefit/synthetic/channel_faults.h"

#include <cmath>
#include <complex>

#include "stagefit/common/error.h"

namespace stagefit::synthetic {
namespace {

int Index(const measurement::FrfData& d, const std::string& name, bool is_input) {
  const auto& ch = is_input ? d.inputs : d.outputs;
  for (std::size_t i = 0; i < ch.size(); ++i)
    if (ch[i].name == name) return static_cast<int>(i);
  throw InputError("'" + d.source + "': no " + std::string(is_input ? "input" : "output") + " channel '" + name + "'");
}

std::string Fmt(const char* f, double a, double b = 0) {
  char buf[128];
  std::snprintf(buf, sizeof buf, f, a, b);
  return buf;
}

}  // namespace

void InjectReversed(measurement::FrfData& data, const std::string& name, bool is_input) {
  const int i = Index(data, name, is_input);
  for (auto& h : data.frf) {
    if (is_input) h.col(i) *= -1.0; else h.row(i) *= -1.0;
  }
}

void InjectSwapped(measurement::FrfData& data, const std::string& a, const std::string& b, bool is_input) {
  const int i = Index(data, a, is_input), k = Index(data, b, is_input);
  for (auto& h : data.frf) {
    if (is_input) h.col(i).swap(h.col(k)); else h.row(i).swap(h.row(k));
  }
  for (auto& c : data.coherence) {
    if (is_input) c.col(i).swap(c.col(k)); else c.row(i).swap(c.row(k));
  }
}

void InjectDead(measurement::FrfData& data, const std::string& name, double level, uint64_t seed) {
  const int i = Index(data, name, false);
  double e = 0;
  int n = 0;
  for (const auto& h : data.frf) {
    e += h.row(i).squaredNorm();
    n += static_cast<int>(h.cols());
  }
  const double sigma = level * std::sqrt(e / n);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, sigma / std::sqrt(2.0));
  std::uniform_real_distribution<double> u(0.0, 0.05);
  for (std::size_t k = 0; k < data.frf.size(); ++k)
    for (int j = 0; j < data.frf[k].cols(); ++j) {
      data.frf[k](i, j) = {g(rng), g(rng)};
      if (data.has_coherence()) data.coherence[k](i, j) = u(rng);
    }
}

void InjectClipped(measurement::FrfData& data, const std::string& name, double fraction) {
  const int i = Index(data, name, false);
  double mx = 0;
  for (const auto& h : data.frf) mx = std::max(mx, h.row(i).cwiseAbs().maxCoeff());
  const double level = fraction * mx;
  for (auto& h : data.frf)
    for (int j = 0; j < h.cols(); ++j)
      if (std::abs(h(i, j)) > level) h(i, j) *= level / std::abs(h(i, j));
}

void InjectLocalResonance(measurement::FrfData& data, const std::string& name, double fn_hz, double q) {
  const int i = Index(data, name, false);
  for (int k = 0; k < data.num_frequencies(); ++k) {
    const double r = data.frequency_hz(k) / fn_hz;
    const std::complex<double> damp(0.0, r / q);
    data.frf[k].row(i) *= (1.0 + damp) / (1.0 - r * r + damp);
  }
}

InjectedFault InjectRandomFault(measurement::FrfData& data, measurement::ChannelFaultKind kind, std::mt19937_64& rng) {
  using measurement::ChannelFaultKind;
  InjectedFault f;
  f.kind = kind;
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto pick = [&](int n) { return static_cast<int>(u(rng) * n) % n; };
  const int nout = data.num_outputs(), nin = data.num_inputs();
  switch (kind) {
    case ChannelFaultKind::kReversed: {
      f.is_input = u(rng) < 0.5;
      const auto& ch = f.is_input ? data.inputs : data.outputs;
      f.channels = {ch[pick(static_cast<int>(ch.size()))].name};
      InjectReversed(data, f.channels[0], f.is_input);
      f.description = "reversed " + std::string(f.is_input ? "impact " : "sensor ") + f.channels[0];
      break;
    }
    case ChannelFaultKind::kSwapped: {
      f.is_input = u(rng) < 0.5;
      const auto& ch = f.is_input ? data.inputs : data.outputs;
      const int n = static_cast<int>(ch.size());
      const int a = pick(n);
      int b = pick(n - 1);
      if (b >= a) ++b;
      f.channels = {ch[a].name, ch[b].name};
      InjectSwapped(data, f.channels[0], f.channels[1], f.is_input);
      f.description = "swapped " + std::string(f.is_input ? "impacts " : "sensors ") + f.channels[0] + " and " + f.channels[1];
      break;
    }
    case ChannelFaultKind::kDead: {
      f.channels = {data.outputs[pick(nout)].name};
      const double level = std::pow(10.0, -3.0 + u(rng));
      InjectDead(data, f.channels[0], level, rng());
      f.description = "dead sensor " + f.channels[0] + Fmt(" (noise %.1g of its RMS)", level);
      break;
    }
    case ChannelFaultKind::kClipped: {
      f.channels = {data.outputs[pick(nout)].name};
      f.fraction = 0.3 + 0.4 * u(rng);
      InjectClipped(data, f.channels[0], f.fraction);
      f.description = "sensor " + f.channels[0] + Fmt(" clipped at %.2f of its largest magnitude", f.fraction);
      break;
    }
    case ChannelFaultKind::kLocalResonance: {
      f.channels = {data.outputs[pick(nout)].name};
      const double lo = std::log(data.frequency_hz(0)), hi = std::log(data.frequency_hz(data.num_frequencies() - 1));
      f.fn_hz = std::exp(lo + (0.1 + 0.8 * u(rng)) * (hi - lo));
      f.q = 5.0 + 25.0 * u(rng);
      InjectLocalResonance(data, f.channels[0], f.fn_hz, f.q);
      f.description = "local resonance under " + f.channels[0] + Fmt(" at %.0f Hz, Q %.0f", f.fn_hz, f.q);
      break;
    }
  }
  (void)nin;
  return f;
}

}  // namespace stagefit::synthetic
