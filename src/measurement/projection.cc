#include "stagefit/measurement/projection.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "stagefit/common/dof.h"
#include "stagefit/common/eigen_decomposition.h"
#include "stagefit/common/error.h"
#include "stagefit/common/units.h"

namespace stagefit::measurement {
namespace {

constexpr double kNullSpaceShareToName = 0.1;

Eigen::MatrixXd CalcJacobian(const std::vector<ChannelGeometry>& channels,
                             const Eigen::Vector3d& p_WXo, const char* kind,
                             const std::string& prefix = "") {
  Eigen::MatrixXd J(channels.size(), 6);
  for (std::size_t i = 0; i < channels.size(); ++i) {
    const ChannelGeometry& c = channels[i];
    if (!c.has_geometry()) {
      throw InputError(prefix + kind + " '" + c.name +
                       "': no geometry (body, position, direction), expected it for the projection");
    }
    const Eigen::Vector3d& n = c.direction_W;
    if (!n.allFinite() || std::abs(n.norm() - 1.0) > kUnitDirectionTolerance) {
      std::ostringstream m;
      m << prefix << kind << " '" << c.name << "': direction (" << n.transpose()
        << ") is not a unit vector, expected length 1";
      throw InputError(m.str());
    }
    const Eigen::Vector3d r = c.position_W - p_WXo;
    J.row(i).head<3>() = n.transpose();
    J.row(i).tail<3>() = r.cross(n).transpose();
  }
  return J;
}

// Rows (or columns) of `channels` grouped by body, in order of first appearance.
std::vector<std::pair<std::string, std::vector<int>>> GroupByBody(
    const std::vector<ChannelGeometry>& channels, const FrfData& data, const char* kind) {
  std::vector<std::pair<std::string, std::vector<int>>> groups;
  for (std::size_t i = 0; i < channels.size(); ++i) {
    const ChannelGeometry& c = channels[i];
    if (!c.has_geometry()) {
      throw InputError(data.where() + ": " + kind + " '" + c.name +
                       "': no geometry (body, position, direction), expected it for the projection");
    }
    auto it = std::find_if(groups.begin(), groups.end(),
                           [&](const auto& g) { return g.first == c.body; });
    if (it == groups.end()) {
      groups.push_back({c.body, {}});
      it = std::prev(groups.end());
    }
    it->second.push_back(static_cast<int>(i));
  }
  return groups;
}

void CheckShapes(const FrfData& data) {
  if (static_cast<int>(data.frf.size()) != data.num_frequencies()) {
    throw InputError(data.where() + ": frf: " + std::to_string(data.frf.size()) +
                     " frequency points, expected " + std::to_string(data.num_frequencies()) +
                     " (one per freq_hz)");
  }
  for (const Eigen::MatrixXcd& H : data.frf) {
    if (H.rows() != data.num_outputs() || H.cols() != data.num_inputs()) {
      throw InputError(data.where() + ": frf: a matrix of " + std::to_string(H.rows()) + " x " +
                       std::to_string(H.cols()) + ", expected Nout x Nin = " +
                       std::to_string(data.num_outputs()) + " x " +
                       std::to_string(data.num_inputs()));
    }
  }
}

std::vector<ChannelGeometry> Subset(const std::vector<ChannelGeometry>& channels,
                                    const std::vector<int>& rows) {
  std::vector<ChannelGeometry> out;
  out.reserve(rows.size());
  for (int r : rows) out.push_back(channels[r]);
  return out;
}

std::vector<ChannelGeometry> RigidChannels(const std::string& body, const Eigen::Vector3d& p_WXo,
                                           const std::string& prefix, bool wrench) {
  static const char* kWrenchNames[6] = {"Fx", "Fy", "Fz", "Mx", "My", "Mz"};
  std::vector<ChannelGeometry> out(6);
  for (int k = 0; k < 6; ++k) {
    out[k].name = prefix + (wrench ? std::string(kWrenchNames[k]) : std::string(kDofNames[k]));
    out[k].body = body;
    out[k].position_W = p_WXo;
    out[k].direction_W = Eigen::Vector3d::Unit(k % 3);
  }
  return out;
}

}  // namespace

Eigen::MatrixXd CalcSensorJacobian(const std::vector<ChannelGeometry>& channels,
                                   const Eigen::Vector3d& p_WXo) {
  return CalcJacobian(channels, p_WXo, "sensor");
}

Eigen::MatrixXd CalcImpactJacobian(const std::vector<ChannelGeometry>& channels,
                                   const Eigen::Vector3d& p_WXo) {
  return CalcJacobian(channels, p_WXo, "impact");
}

void CheckObservable(const Eigen::MatrixXd& J, const std::string& what) {
  STAGEFIT_ASSERT(J.cols() == 6, "Jacobian with " << J.cols() << " columns, expected 6");
  std::ostringstream m;
  if (J.rows() < 6) {
    m << what << ": " << J.rows() << " channel(s) cannot observe 6 DoF";
  }
  const SingularValueDecomposition svd = CalcSvd(J, kSvdFullV);
  const Eigen::VectorXd& s = svd.values;
  const double smax = s.size() > 0 ? s(0) : 0.0;
  std::vector<int> null_columns;
  for (int k = 0; k < 6; ++k) {
    const double sk = k < s.size() ? s(k) : 0.0;
    if (!(sk > kObservabilityTolerance * smax) || smax == 0.0) null_columns.push_back(k);
  }
  if (null_columns.empty()) return;
  Eigen::MatrixXd V0(6, null_columns.size());
  for (std::size_t c = 0; c < null_columns.size(); ++c) V0.col(c) = svd.V.col(null_columns[c]);
  const Eigen::VectorXd share = (V0 * V0.transpose()).diagonal();
  if (m.tellp() == 0) m << what;
  m << ": the geometry cannot observe ";
  bool first = true;
  for (int k = 0; k < 6; ++k) {
    if (share(k) <= kNullSpaceShareToName) continue;
    m << (first ? "" : ", ") << kDofNames[k] << " (" << std::fixed << std::setprecision(2)
      << share(k) << ")";
    first = false;
  }
  m << " (rank " << 6 - null_columns.size()
    << " of 6; the numbers are each DoF's share of the unobservable motion); expected channels "
       "that observe all of Dx Dy Dz Rx Ry Rz";
  throw InputError(m.str());
}

Eigen::MatrixXd PseudoInverse(const Eigen::MatrixXd& J) {
  const SingularValueDecomposition svd = CalcSvd(J, kSvdThinU | kSvdThinV);
  const Eigen::VectorXd& s = svd.values;
  Eigen::VectorXd inv = Eigen::VectorXd::Zero(s.size());
  const double smax = s.size() > 0 ? s(0) : 0.0;
  for (int i = 0; i < s.size(); ++i) {
    if (s(i) > kObservabilityTolerance * smax) inv(i) = 1.0 / s(i);
  }
  return svd.V * inv.asDiagonal() * svd.U.transpose();
}

FrfData ProjectToFrame(const FrfData& raw, const Eigen::Vector3d& default_p_WXo) {
  CheckShapes(raw);
  const Eigen::Vector3d p_WXo = raw.frame_origin_W.value_or(default_p_WXo);
  const auto sensor_groups = GroupByBody(raw.outputs, raw, "sensor");
  const auto impact_groups = GroupByBody(raw.inputs, raw, "impact");
  if (sensor_groups.size() > 1 || impact_groups.size() > 1) {
    const bool sensors = sensor_groups.size() > 1;
    const auto& groups = sensors ? sensor_groups : impact_groups;
    throw InputError(raw.where() + ": " + (sensors ? "sensor_body" : "impact_body") +
                     ": channels on several bodies ('" + groups[0].first + "', '" +
                     groups[1].first +
                     "'), expected one body for the projection to {X}; project per body instead");
  }
  STAGEFIT_ASSERT(!sensor_groups.empty() && !impact_groups.empty(), "no channels");
  const Eigen::MatrixXd J_a = CalcJacobian(raw.outputs, p_WXo, "sensor", raw.where() + ": ");
  const Eigen::MatrixXd J_F = CalcJacobian(raw.inputs, p_WXo, "impact", raw.where() + ": ");
  CheckObservable(J_a, raw.where() + ": sensors");
  CheckObservable(J_F, raw.where() + ": impacts");
  const Eigen::MatrixXcd left = PseudoInverse(J_a).cast<std::complex<double>>();
  const Eigen::MatrixXcd right =
      PseudoInverse(J_F.transpose()).cast<std::complex<double>>();

  FrfData out;
  out.frequency_hz = raw.frequency_hz;
  out.quantity = raw.quantity;
  out.outputs = RigidChannels(sensor_groups.front().first, p_WXo, "", false);
  out.inputs = RigidChannels(impact_groups.front().first, p_WXo, "", true);
  out.frame_origin_W = p_WXo;
  out.source = raw.source;
  out.frf.reserve(raw.frf.size());
  for (const Eigen::MatrixXcd& H_L : raw.frf) out.frf.push_back(left * H_L * right);
  return out;
}

FrfData ProjectPerBody(const FrfData& raw, const std::map<std::string, Eigen::Vector3d>& p_WBcm,
                       InputProjection inputs) {
  CheckShapes(raw);
  const auto sensor_groups = GroupByBody(raw.outputs, raw, "sensor");
  auto com = [&](const std::string& body) {
    auto it = p_WBcm.find(body);
    if (it == p_WBcm.end()) {
      throw InputError(raw.where() + ": body '" + body +
                       "' carries channels but has no centre of mass given, expected one of the "
                       "model's bodies");
    }
    return it->second;
  };

  FrfData out;
  out.frequency_hz = raw.frequency_hz;
  out.quantity = raw.quantity;
  out.source = raw.source;

  // Left factor: block rows per sensor body.
  Eigen::MatrixXd left = Eigen::MatrixXd::Zero(6 * sensor_groups.size(), raw.num_outputs());
  for (std::size_t b = 0; b < sensor_groups.size(); ++b) {
    const auto& [body, rows] = sensor_groups[b];
    const Eigen::Vector3d p = com(body);
    const Eigen::MatrixXd J_a = CalcJacobian(Subset(raw.outputs, rows), p, "sensor", raw.where() + ": ");
    CheckObservable(J_a, raw.where() + ": sensors on body '" + body + "'");
    const Eigen::MatrixXd pinv = PseudoInverse(J_a);
    for (std::size_t r = 0; r < rows.size(); ++r) left.block(6 * b, rows[r], 6, 1) = pinv.col(r);
    const auto channels = RigidChannels(body, p, body + ".", false);
    out.outputs.insert(out.outputs.end(), channels.begin(), channels.end());
  }

  Eigen::MatrixXd right;
  if (inputs == InputProjection::kRaw) {
    right = Eigen::MatrixXd::Identity(raw.num_inputs(), raw.num_inputs());
    out.inputs = raw.inputs;
  } else {
    const auto impact_groups = GroupByBody(raw.inputs, raw, "impact");
    right = Eigen::MatrixXd::Zero(raw.num_inputs(), 6 * impact_groups.size());
    for (std::size_t b = 0; b < impact_groups.size(); ++b) {
      const auto& [body, cols] = impact_groups[b];
      const Eigen::Vector3d p = com(body);
      const Eigen::MatrixXd J_F = CalcJacobian(Subset(raw.inputs, cols), p, "impact", raw.where() + ": ");
      CheckObservable(J_F, raw.where() + ": impacts on body '" + body + "'");
      const Eigen::MatrixXd pinv_t = PseudoInverse(J_F.transpose());
      for (std::size_t c = 0; c < cols.size(); ++c) {
        right.block(cols[c], 6 * b, 1, 6) = pinv_t.row(c);
      }
      const auto channels = RigidChannels(body, p, body + ".", true);
      out.inputs.insert(out.inputs.end(), channels.begin(), channels.end());
    }
  }
  const Eigen::MatrixXcd left_c = left.cast<std::complex<double>>();
  const Eigen::MatrixXcd right_c = right.cast<std::complex<double>>();
  out.frf.reserve(raw.frf.size());
  for (const Eigen::MatrixXcd& H_L : raw.frf) out.frf.push_back(left_c * H_L * right_c);
  return out;
}

int DifferentiationOrder(FrfQuantity quantity) {
  switch (quantity) {
    case FrfQuantity::kReceptance:
      return 0;
    case FrfQuantity::kMobility:
      return 1;
    case FrfQuantity::kAccelerance:
      return 2;
  }
  STAGEFIT_ASSERT(false, "unknown FrfQuantity " << static_cast<int>(quantity));
}

std::complex<double> ConversionFactor(double frequency_hz, FrfQuantity from, FrfQuantity to) {
  const int k = DifferentiationOrder(to) - DifferentiationOrder(from);
  const std::complex<double> s(0.0, 2.0 * kPi * frequency_hz);
  std::complex<double> factor(1.0, 0.0);
  for (int i = 0; i < std::abs(k); ++i) factor *= s;
  return k >= 0 ? factor : 1.0 / factor;
}

FrfData ConvertQuantity(const FrfData& data, FrfQuantity to) {
  FrfData out = data;
  out.quantity = to;
  if (to == data.quantity) return out;
  for (int f = 0; f < data.num_frequencies(); ++f) {
    const double fhz = data.frequency_hz(f);
    if (!(fhz > 0.0) || !std::isfinite(fhz)) {
      std::ostringstream m;
      m << data.where() << ": freq_hz(" << f + 1 << ") = " << fhz
        << ", expected > 0 to convert " << ToString(data.quantity) << " to " << ToString(to);
      throw InputError(m.str());
    }
    out.frf[f] *= ConversionFactor(fhz, data.quantity, to);
  }
  return out;
}

double FrequencyBand::centre_hz() const { return std::sqrt(low_hz * high_hz); }

std::vector<FrequencyBand> MakeFractionalOctaveBands(double min_hz, double max_hz,
                                                     int bands_per_octave) {
  if (!(min_hz > 0.0) || !(max_hz >= min_hz) || !std::isfinite(max_hz)) {
    std::ostringstream m;
    m << "frequency bands: range [" << min_hz << ", " << max_hz
      << "] Hz, expected 0 < min <= max";
    throw InputError(m.str());
  }
  if (bands_per_octave < 1) {
    throw InputError("frequency bands: " + std::to_string(bands_per_octave) +
                     " bands per octave, expected >= 1");
  }
  const double n = bands_per_octave;
  const double half = std::pow(2.0, 0.5 / n);
  const int k_low = static_cast<int>(std::floor(n * std::log2(min_hz / 1000.0)));
  const int k_high = static_cast<int>(std::ceil(n * std::log2(max_hz / 1000.0)));
  std::vector<FrequencyBand> bands;
  for (int k = k_low; k <= k_high; ++k) {
    const double centre = 1000.0 * std::pow(2.0, k / n);
    FrequencyBand band{centre / half, centre * half};
    if (band.high_hz > min_hz && band.low_hz <= max_hz) bands.push_back(band);
  }
  return bands;
}

std::vector<int> BandOfEachFrequency(const Eigen::VectorXd& frequency_hz, const std::vector<FrequencyBand>& bands) {
  std::vector<int> band_of(static_cast<size_t>(frequency_hz.size()), -1);
  for (Eigen::Index k = 0; k < frequency_hz.size(); ++k) {
    const double f = frequency_hz(k);
    for (size_t b = 0; b < bands.size(); ++b) {
      if (f >= bands[b].low_hz && (f < bands[b].high_hz || (b + 1 == bands.size() && f <= bands[b].high_hz))) {
        band_of[static_cast<size_t>(k)] = static_cast<int>(b);
        break;
      }
    }
  }
  return band_of;
}

std::string RigidConsistency::BriefReport() const {
  std::ostringstream s;
  s << "Rigid-body consistency (share of the data energy no rigid motion explains)\n";
  s << "   band Hz            outputs  worst output           inputs   worst input\n";
  for (std::size_t b = 0; b < bands.size(); ++b) {
    Eigen::Index io = 0, ii = 0;
    const double wo = output_residual_share.rows() > 0
                          ? output_residual_share.col(b).maxCoeff(&io) : 0.0;
    const double wi = input_residual_share.rows() > 0
                          ? input_residual_share.col(b).maxCoeff(&ii) : 0.0;
    s << std::fixed << std::setprecision(1) << std::setw(8) << bands[b].low_hz << "-"
      << std::left << std::setw(9) << bands[b].high_hz << std::right << std::setprecision(4)
      << std::setw(9) << output_overall(b) << "  " << std::left << std::setw(10)
      << (output_names.empty() ? "" : output_names[io]) << std::right << std::setw(8) << wo
      << "   " << std::setw(8) << input_overall(b) << "  " << std::left << std::setw(10)
      << (input_names.empty() ? "" : input_names[ii]) << std::right << std::setw(8) << wi
      << "\n";
  }
  return s.str();
}

namespace {

/// Shares of the data energy that the residual operators leave, per channel and band (header of
/// CalcRigidConsistency()): R_out = out_residual H_L, R_in = H_L in_residual (no inputs when
/// in_residual is empty).
RigidConsistency ConsistencyOf(const FrfData& raw, const Eigen::MatrixXcd& out_residual,
                               const Eigen::MatrixXcd& in_residual, const std::vector<FrequencyBand>& bands) {
  const int nout = raw.num_outputs();
  const bool with_inputs = in_residual.size() > 0;
  const int nin = with_inputs ? raw.num_inputs() : 0;
  RigidConsistency result;
  for (const auto& c : raw.outputs) result.output_names.push_back(c.name);
  if (with_inputs) {
    for (const auto& c : raw.inputs) result.input_names.push_back(c.name);
  }
  std::vector<FrequencyBand> candidate = bands;
  if (candidate.empty() && raw.num_frequencies() > 0) {
    candidate = MakeFractionalOctaveBands(raw.frequency_hz(0),
                                          raw.frequency_hz(raw.num_frequencies() - 1), 3);
  }
  std::vector<Eigen::VectorXd> out_r, out_h, in_r, in_h;
  for (const FrequencyBand& band : candidate) {
    Eigen::VectorXd orow = Eigen::VectorXd::Zero(nout), ohrow = Eigen::VectorXd::Zero(nout);
    Eigen::VectorXd icol = Eigen::VectorXd::Zero(nin), ihcol = Eigen::VectorXd::Zero(nin);
    int count = 0;
    for (int f = 0; f < raw.num_frequencies(); ++f) {
      const double fhz = raw.frequency_hz(f);
      if (fhz < band.low_hz || fhz >= band.high_hz) continue;
      ++count;
      const Eigen::MatrixXcd& H = raw.frf[f];
      const Eigen::MatrixXd energy = H.cwiseAbs2();
      orow += (out_residual * H).cwiseAbs2().rowwise().sum();
      ohrow += energy.rowwise().sum();
      if (with_inputs) {
        icol += (H * in_residual).cwiseAbs2().colwise().sum().transpose();
        ihcol += energy.colwise().sum().transpose();
      }
    }
    if (count == 0) continue;
    result.bands.push_back(band);
    out_r.push_back(orow);
    out_h.push_back(ohrow);
    in_r.push_back(icol);
    in_h.push_back(ihcol);
  }
  const int nb = static_cast<int>(result.bands.size());
  auto share = [](double r, double h) { return h > 0.0 ? r / h : 0.0; };
  result.output_residual_share.resize(nout, nb);
  result.input_residual_share.resize(nin, nb);
  result.output_overall.resize(nb);
  result.input_overall = Eigen::VectorXd::Zero(nb);
  for (int b = 0; b < nb; ++b) {
    for (int i = 0; i < nout; ++i) result.output_residual_share(i, b) = share(out_r[b](i), out_h[b](i));
    for (int j = 0; j < nin; ++j) result.input_residual_share(j, b) = share(in_r[b](j), in_h[b](j));
    result.output_overall(b) = share(out_r[b].sum(), out_h[b].sum());
    if (with_inputs) result.input_overall(b) = share(in_r[b].sum(), in_h[b].sum());
  }
  return result;
}

}  // namespace

RigidConsistency CalcRigidConsistency(const FrfData& raw, const Eigen::Vector3d& default_p_WXo,
                                      const std::vector<FrequencyBand>& bands) {
  CheckShapes(raw);
  const Eigen::Vector3d p_WXo = raw.frame_origin_W.value_or(default_p_WXo);
  const Eigen::MatrixXd J_a = CalcJacobian(raw.outputs, p_WXo, "sensor", raw.where() + ": ");
  const Eigen::MatrixXd J_F = CalcJacobian(raw.inputs, p_WXo, "impact", raw.where() + ": ");
  CheckObservable(J_a, raw.where() + ": sensors");
  CheckObservable(J_F, raw.where() + ": impacts");
  const int nout = raw.num_outputs();
  const int nin = raw.num_inputs();
  const Eigen::MatrixXcd out_residual =
      (Eigen::MatrixXd::Identity(nout, nout) - J_a * PseudoInverse(J_a)).cast<std::complex<double>>();
  const Eigen::MatrixXcd in_residual =
      (Eigen::MatrixXd::Identity(nin, nin) - J_F * PseudoInverse(J_F)).cast<std::complex<double>>();
  return ConsistencyOf(raw, out_residual, in_residual, bands);
}

RigidConsistency CalcRigidConsistencyPerBody(const FrfData& raw, const std::map<std::string, Eigen::Vector3d>& p_WBcm,
                                             const std::vector<FrequencyBand>& bands) {
  CheckShapes(raw);
  const int nout = raw.num_outputs();
  Eigen::MatrixXd out_residual = Eigen::MatrixXd::Zero(nout, nout);
  for (const auto& [body, rows] : GroupByBody(raw.outputs, raw, "sensor")) {
    auto it = p_WBcm.find(body);
    if (it == p_WBcm.end()) {
      throw InputError(raw.where() + ": body '" + body + "' carries sensors but has no centre of mass given");
    }
    const Eigen::MatrixXd J_a = CalcJacobian(Subset(raw.outputs, rows), it->second, "sensor", raw.where() + ": ");
    CheckObservable(J_a, raw.where() + ": sensors on body '" + body + "'");
    const int m = static_cast<int>(rows.size());
    const Eigen::MatrixXd block = Eigen::MatrixXd::Identity(m, m) - J_a * PseudoInverse(J_a);
    for (int r = 0; r < m; ++r) {
      for (int c = 0; c < m; ++c) out_residual(rows[r], rows[c]) = block(r, c);
    }
  }
  return ConsistencyOf(raw, out_residual.cast<std::complex<double>>(), Eigen::MatrixXcd(), bands);
}

namespace {

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

/// d minimising sum |h - a d|^2 over the accumulated normal equations (M d = b, h2 = sum |h|^2),
/// normalised, and the share of h2 the minimum leaves.
bool SolveDirection(const Eigen::Matrix3d& M, const Eigen::Vector3d& b, double h2, Eigen::Vector3d* d,
                    double* residual_share) {
  const Eigen::Vector3d x = M.ldlt().solve(b);
  if (!x.allFinite() || x.norm() == 0.0 || !(h2 > 0.0)) return false;
  *d = x.normalized();
  *residual_share = std::max(0.0, 1.0 - b.dot(x) / h2);
  return true;
}

/// J without row `skip`.
Eigen::MatrixXd WithoutRow(const Eigen::MatrixXd& J, int skip) {
  Eigen::MatrixXd out(J.rows() - 1, J.cols());
  for (int r = 0, k = 0; r < J.rows(); ++r) {
    if (r != skip) out.row(k++) = J.row(r);
  }
  return out;
}

}  // namespace

double ChannelDirectionEstimate::ResidualShareAlong(const Eigen::Vector3d& direction_W) const {
  // min_c sum |h - c u' a|^2 = energy - (u' rhs)^2 / (u' normal u).
  const double uMu = direction_W.dot(normal * direction_W), ub = direction_W.dot(rhs);
  if (!estimable || !(uMu > 0.0) || !(energy > 0.0)) return 1.0;
  return std::max(0.0, 1.0 - ub * ub / (uMu * energy));
}

bool Observes6(const Eigen::MatrixXd& J) {
  if (J.rows() < 6) return false;
  const Eigen::VectorXd s = CalcSvd(J).values;
  return s(5) > kObservabilityTolerance * s(0);
}

std::vector<ChannelDirectionEstimate> EstimateChannelDirections(const FrfData& raw, const Eigen::Vector3d& default_p_WXo,
                                                                double fmin_hz, double fmax_hz) {
  CheckShapes(raw);
  const Eigen::Vector3d p_WXo = raw.frame_origin_W.value_or(default_p_WXo);
  const Eigen::MatrixXd J_a = CalcJacobian(raw.outputs, p_WXo, "sensor", raw.where() + ": ");
  const Eigen::MatrixXd J_F = CalcJacobian(raw.inputs, p_WXo, "impact", raw.where() + ": ");
  std::vector<int> used;
  for (int f = 0; f < raw.num_frequencies(); ++f) {
    const double fhz = raw.frequency_hz(f);
    if (fhz >= fmin_hz && fhz <= fmax_hz && raw.frf[f].squaredNorm() > 0.0) used.push_back(f);
  }
  // Channel k of `rows` (the rows of rows_of(f): a frequency's FRFs, or their transpose for impacts)
  // checked against the motion the other rows give: the sensors' problem; for impacts, with
  // H' = J_F G', B' = [I, -[r]x] is the sensors' A and the transpose is the same problem.
  std::vector<ChannelDirectionEstimate> estimates;
  auto estimate = [&](const std::vector<ChannelGeometry>& channels, const Eigen::MatrixXd& J, bool is_impact,
                      auto rows_of) {
    const int n = static_cast<int>(channels.size());
    for (int i = 0; i < n; ++i) {
      const Eigen::MatrixXd J_o = WithoutRow(J, i);
      const bool observable = Observes6(J_o);
      Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
      Eigen::Vector3d b = Eigen::Vector3d::Zero();
      double h2 = 0.0;
      if (observable) {
        Eigen::Matrix<double, 3, 6> A;
        A << Eigen::Matrix3d::Identity(), -Skew(channels[i].position_W - p_WXo);
        const Eigen::MatrixXcd P = (A * PseudoInverse(J_o)).cast<std::complex<double>>();  // 3 x (n - 1)
        for (int f : used) {
          const Eigen::MatrixXcd H = rows_of(f);
          Eigen::MatrixXcd H_o(n - 1, H.cols());
          for (int r = 0, k = 0; r < n; ++r) {
            if (r != i) H_o.row(k++) = H.row(r);
          }
          const Eigen::MatrixXcd a = P * H_o;  // 3 x columns: the channel's point moved by each other-side channel
          M += (a * a.adjoint()).real();
          b += (a * H.row(i).adjoint()).real();
          h2 += H.row(i).squaredNorm();
        }
      }
      ChannelDirectionEstimate e;
      e.name = channels[i].name;
      e.is_impact = is_impact;
      e.declared_W = channels[i].direction_W.normalized();
      e.estimated_W = e.declared_W;
      e.residual_share = 1.0;
      e.estimable = observable && !used.empty() && SolveDirection(M, b, h2, &e.estimated_W, &e.residual_share);
      if (e.estimable) {
        e.normal = M;
        e.rhs = b;
        e.energy = h2;
        e.declared_residual_share = e.ResidualShareAlong(e.declared_W);
      }
      e.angle_rad = std::atan2(e.declared_W.cross(e.estimated_W).norm(), e.declared_W.dot(e.estimated_W));
      estimates.push_back(e);
    }
  };
  estimate(raw.outputs, J_a, false, [&](int f) { return Eigen::MatrixXcd(raw.frf[f]); });
  estimate(raw.inputs, J_F, true, [&](int f) { return Eigen::MatrixXcd(raw.frf[f].transpose()); });
  return estimates;
}

std::optional<ChannelDirectionEstimate> FindTurnedChannel(const FrfData& raw, const Eigen::Vector3d& default_p_WXo,
                                                          double min_angle_rad, double fmin_hz, double fmax_hz,
                                                          std::vector<ChannelDirectionEstimate>* rivals) {
  if (rivals) rivals->clear();
  const std::vector<ChannelDirectionEstimate> estimates = EstimateChannelDirections(raw, default_p_WXo, fmin_hz, fmax_hz);
  std::vector<ChannelDirectionEstimate> consistent;  // the corrections that leave the others consistent
  std::optional<ChannelDirectionEstimate> strong;    // else: of the channels the data put clearly off
  double best_strong_others = std::numeric_limits<double>::infinity();
  for (const auto& e : estimates) {
    if (!e.estimable || !(e.angle_rad > min_angle_rad)) continue;
    // The channel's declared direction replaced by its estimate, the others estimated again.
    FrfData corrected = raw;
    auto& channels = e.is_impact ? corrected.inputs : corrected.outputs;
    for (auto& c : channels) {
      if (c.name == e.name) c.direction_W = e.estimated_W;
    }
    double others = 0.0;
    for (const auto& o : EstimateChannelDirections(corrected, default_p_WXo, fmin_hz, fmax_hz)) {
      if (o.estimable && !(o.name == e.name && o.is_impact == e.is_impact)) others = std::max(others, o.angle_rad);
    }
    if (others <= min_angle_rad) {
      consistent.push_back(e);
    } else if (e.declared_residual_share >= 2 * e.residual_share && others < best_strong_others) {
      strong = e;
      best_strong_others = others;
    }
  }
  if (consistent.empty()) return strong;
  // Stable: of equal residuals the first channel is named, as before there were rivals.
  std::stable_sort(consistent.begin(), consistent.end(),
                   [](const auto& a, const auto& b) { return a.residual_share < b.residual_share; });
  if (rivals) {
    for (size_t k = 1; k < consistent.size(); ++k) {
      if (consistent[k].residual_share < kRivalResidualRatio * consistent[0].residual_share) rivals->push_back(consistent[k]);
    }
  }
  return consistent[0];
}

}  // namespace stagefit::measurement
