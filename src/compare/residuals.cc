#include "stagefit/compare/residuals.h"

#include "stagefit/kinematics/rigid_transform.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <sstream>

#include <unsupported/Eigen/SpecialFunctions>

#include "stagefit/common/dof.h"
#include "stagefit/common/eigen_decomposition.h"
#include "stagefit/common/error.h"
#include "stagefit/common/units.h"
#include "stagefit/model/assembled_model.h"

namespace stagefit::compare {
namespace {

using measurement::FrfData;
using measurement::FrfQuantity;

constexpr const char* kWrenchNames[6] = {"Fx", "Fy", "Fz", "Mx", "My", "Mz"};

std::string Where(const FrfData& data) {
  return "measurement '" + (data.source.empty() ? std::string("<memory>") : data.source) + "'";
}

response::ResponseQuantity ToResponseQuantity(FrfQuantity quantity) {
  switch (quantity) {
    case FrfQuantity::kAccelerance: return response::ResponseQuantity::kAccelerance;
    case FrfQuantity::kMobility: return response::ResponseQuantity::kMobility;
    case FrfQuantity::kReceptance: return response::ResponseQuantity::kReceptance;
  }
  return response::ResponseQuantity::kReceptance;
}

// True when the channels are already the 6 DoF of a frame (names Dx..Rz and Fx..Mz, as written by
// measurement::ProjectToFrame()), or a 6x6 without geometry.
bool IsProjected(const FrfData& data) {
  if (data.num_outputs() != 6 || data.num_inputs() != 6) return false;
  bool named = true;
  for (int k = 0; k < 6; ++k) {
    named = named && data.outputs[k].name == kDofNames[k] && data.inputs[k].name == kWrenchNames[k];
  }
  if (named) return true;
  for (const auto& c : data.outputs) if (c.has_geometry()) return false;
  for (const auto& c : data.inputs) if (c.has_geometry()) return false;
  return true;
}

double SafeLogAbs(std::complex<double> z) {
  return std::log(std::max(std::abs(z), std::numeric_limits<double>::min()));
}

/// Moves and turns the channels named by `corrections` (a channel name names one channel of a
/// measurement, output or input); returns whether any channel was corrected.
template <typename Channel>
bool ApplyGeometryCorrections(const std::vector<model::GeometryCorrection>& corrections, std::vector<Channel>* channels) {
  bool any = false;
  for (const auto& g : corrections) {
    const Eigen::Matrix3d R = kinematics::RotationFromEuler({g.rotation_rad(0), g.rotation_rad(1), g.rotation_rad(2)});
    for (auto& ch : *channels) {
      if (ch.name != g.channel) continue;
      ch.position_W += g.offset_W;
      ch.direction_W = R * ch.direction_W;
      any = true;
    }
  }
  return any;
}

double SnrFromCoherence(double gamma2) {
  if (gamma2 <= 0.0) return 0.0;
  if (gamma2 >= 1.0) return std::numeric_limits<double>::infinity();
  return std::sqrt(gamma2 / (1.0 - gamma2));
}

// The degrees of freedom of each raw point's noise variance: estimated from the n hits averaged for its
// input (FrfData::averages), the residual of n complex records about H1 has 2 (n - 1) real ones;
// infinite when the coherence is the estimate's own (its noise taken as known).
Eigen::MatrixXd RawDegreesOfFreedom(const FrfData& measurement) {
  Eigen::MatrixXd dof = Eigen::MatrixXd::Constant(measurement.num_outputs(), measurement.num_inputs(),
                                                  std::numeric_limits<double>::infinity());
  for (int i = 0; i < static_cast<int>(measurement.averages.size()); ++i) dof.col(i).setConstant(2.0 * (measurement.averages[i] - 1));
  return dof;
}

// The degrees of freedom of the projected variances P2 var Q2 (P2, Q2: the projection's squared
// entries; Q2 null: no right factor), by Satterthwaite: (sum a v)^2 / sum (a v)^2 / dof.
Eigen::MatrixXd PooledDegreesOfFreedom(const Eigen::MatrixXd& P2, const Eigen::MatrixXd& var, const Eigen::MatrixXd& dof,
                                       const Eigen::MatrixXd* Q2) {
  const Eigen::MatrixXd share = var.cwiseProduct(var).cwiseQuotient(dof);  // 0 where dof is infinite
  Eigen::MatrixXd total = P2 * var, spread = P2.cwiseProduct(P2) * share;
  if (Q2) {
    total = total * *Q2;
    spread = spread * Q2->cwiseProduct(*Q2);
  }
  Eigen::MatrixXd out(total.rows(), total.cols());
  for (int a = 0; a < out.size(); ++a) {
    out.data()[a] = spread.data()[a] > 0.0 ? total.data()[a] * total.data()[a] / spread.data()[a]
                                           : std::numeric_limits<double>::infinity();
  }
  return out;
}

}  // namespace

ComparisonSpace ParseComparisonSpace(const std::string& text, const std::string& context) {
  if (text == "compliance") return ComparisonSpace::kCompliance;
  if (text == "raw") return ComparisonSpace::kRaw;
  if (text == "bodies") return ComparisonSpace::kBodies;
  throw InputError(context + ": '" + text + "', expected 'compliance', 'bodies' or 'raw'");
}

std::string ToString(ComparisonSpace space) {
  switch (space) {
    case ComparisonSpace::kCompliance: return "compliance";
    case ComparisonSpace::kBodies: return "bodies";
    case ComparisonSpace::kRaw: break;
  }
  return "raw";
}

measurement::FrfData WithGeometryCorrections(const measurement::FrfData& measurement,
                                             const std::vector<model::GeometryCorrection>& corrections) {
  measurement::FrfData corrected = measurement;
  ApplyGeometryCorrections(corrections, &corrected.outputs);
  ApplyGeometryCorrections(corrections, &corrected.inputs);
  return corrected;
}

DefaultSpace ChooseDefaultSpace(const measurement::FrfData& measurement) {
  std::vector<std::string> bodies;
  for (const auto& ch : measurement.outputs) {
    if (!ch.has_geometry()) return {ComparisonSpace::kCompliance, "the channels carry no geometry"};
    if (std::find(bodies.begin(), bodies.end(), ch.body) == bodies.end()) bodies.push_back(ch.body);
  }
  if (bodies.size() <= 1) {
    return {ComparisonSpace::kCompliance, bodies.empty() ? "no sensors" : "the sensors are on one body ('" + bodies[0] + "')"};
  }
  std::string list;
  for (const auto& b : bodies) list += (list.empty() ? "" : ", ") + b;
  return {ComparisonSpace::kBodies, "the sensors are on " + std::to_string(bodies.size()) + " bodies (" + list + ")"};
}

std::string Comparison::ElementName(ElementIndex index) const {
  return output_names_[index.output] + "/" + input_names_[index.input];
}

Comparison Comparison::Create(const model::ModelSpec& spec, const measurement::FrfData& measurement,
                              const ComparisonOptions& options) {
  const std::string where = Where(measurement);
  if (!(options.significance_threshold >= 0.0 && options.significance_threshold <= 1.0)) {
    throw InputError("comparison: significance threshold " + std::to_string(options.significance_threshold) +
                     ", expected a value in [0, 1]");
  }
  if (!(options.coherence_weight_cap > 0.0) || !std::isfinite(options.coherence_weight_cap)) {
    throw InputError("comparison: coherence weight cap " + std::to_string(options.coherence_weight_cap) +
                     ", expected a finite value > 0");
  }
  if (!(options.fmin_hz <= options.fmax_hz) || std::isnan(options.fmin_hz)) {
    throw InputError("comparison: band [" + std::to_string(options.fmin_hz) + ", " +
                     std::to_string(options.fmax_hz) + "] Hz, expected fmin <= fmax");
  }
  if (options.bands_per_octave < 1) {
    throw InputError("comparison: bands per octave " + std::to_string(options.bands_per_octave) +
                     ", expected >= 1");
  }
  if (!(options.frf_check_tolerance >= 0.0)) {
    throw InputError("comparison: FRF check tolerance " + std::to_string(options.frf_check_tolerance) +
                     ", expected a value >= 0");
  }

  Comparison c;
  c.space_ = options.space;
  c.source_ = measurement.source;
  c.quantity_ = options.quantity.value_or(measurement.quantity);
  c.bands_per_octave_ = options.bands_per_octave;
  c.frf_options_.check_tolerance = options.frf_check_tolerance;

  // Frequencies in the band.
  std::vector<int> rows;
  for (int f = 0; f < measurement.num_frequencies(); ++f) {
    const double hz = measurement.frequency_hz(f);
    if (hz >= options.fmin_hz && hz <= options.fmax_hz) rows.push_back(f);
  }
  if (rows.empty()) {
    std::ostringstream msg;
    msg << where << ": freq_hz: no frequency in the comparison band [" << options.fmin_hz << ", "
        << options.fmax_hz << "] Hz (the data spans " << measurement.frequency_hz(0) << " .. "
        << measurement.frequency_hz(measurement.num_frequencies() - 1) << " Hz)";
    throw InputError(msg.str());
  }
  const int nf = static_cast<int>(rows.size());
  c.frequency_hz_.resize(nf);
  for (int k = 0; k < nf; ++k) c.frequency_hz_(k) = measurement.frequency_hz(rows[k]);
  c.frf_options_.lowest_frequency_hz = c.frequency_hz_.minCoeff();  // the probe check looks from here up

  // Raw SNR per point (infinite = noise-free), from the coherence of the FRF estimate (the ordinary
  // coherence of the records averaged, when the measurement gives their number, turned into it).
  const bool use_coherence = options.use_coherence && measurement.has_coherence();
  auto raw_snr = [&](int k, int o, int i) {
    return use_coherence ? SnrFromCoherence(measurement.estimate_coherence(rows[k], o, i))
                         : std::numeric_limits<double>::infinity();
  };
  const double cap = options.coherence_weight_cap;
  c.weight_cap_ = cap;
  // Each raw point's degrees of freedom, when its noise is estimated from averaged hits (Point::dof);
  // where the space projects the raw noise, pooled through the projection at every frequency.
  const Eigen::MatrixXd raw_dof = RawDegreesOfFreedom(measurement);
  const bool estimated_noise = use_coherence && !measurement.averages.empty();
  std::vector<Eigen::MatrixXd> pooled_dof;
  // Each raw point's noise variance at frequency k, to propagate through a projection (header; docs/
  // error-metric.md §3, §8). For the noise floor: (1 - gamma^2) |H_meas|^2, whose expectation is the
  // noise variance sigma^2 itself (|H_meas|^2 averages |H|^2 + sigma^2, and 1 - gamma^2 = sigma^2 /
  // (|H|^2 + sigma^2)). For the weights: |H_meas|^2 / SNR^2 = sigma^2 |H_meas|^2 / |H|^2, high where the
  // raw coherence is low, with the SNR taken at 1 / cap at least, as it is taken at cap at most: at
  // coherence 0 it was infinite and made every projected point of its frequency weigh 0, so that a
  // sensor's noise on an element a symmetry makes zero dropped the whole measurement. (A point measured
  // as exactly 0 with coherence 0 tells nothing of its noise: its variance stays infinite.)
  auto raw_noise_variances = [&](int k, Eigen::MatrixXd* var_L, Eigen::MatrixXd* var_L_floor) {
    const Eigen::MatrixXcd& H_L = measurement.frf[rows[k]];
    var_L->resize(H_L.rows(), H_L.cols());
    var_L_floor->resize(H_L.rows(), H_L.cols());
    for (int o = 0; o < H_L.rows(); ++o) {
      for (int i = 0; i < H_L.cols(); ++i) {
        const double snr = raw_snr(k, o, i), snr_weights = std::max(snr, 1.0 / cap);
        (*var_L)(o, i) = snr == 0.0 && H_L(o, i) == 0.0 ? std::numeric_limits<double>::infinity()
                                                        : std::norm(H_L(o, i)) / (snr_weights * snr_weights);
        (*var_L_floor)(o, i) = std::isfinite(snr) ? std::norm(H_L(o, i)) / (1.0 + snr * snr) : 0.0;
      }
    }
  };
  c.min_element_snr_ = options.min_element_snr;
  c.measured_side_cache_ = std::make_shared<MeasuredSideCache>();
  c.weights_.assign(nf, Eigen::MatrixXd());
  std::vector<Eigen::MatrixXd> snr(nf);  // uncapped SNR of every point (infinite: noise-free), kept by the points
  std::vector<Eigen::MatrixXcd> raw_measured;  // per frequency, stacked into raw_ at the end
  std::vector<Eigen::MatrixXd> raw_noise_var;
  c.measured_.assign(nf, Eigen::MatrixXcd());

  if (options.space == ComparisonSpace::kCompliance) {
    const int frame = model::FindFrame(spec, spec.compliance_frame);
    if (frame < 0) {
      throw InputError("model '" + spec.name + "': compliance frame '" + spec.compliance_frame +
                       "' is not among its [[frame]] entries, needed by the compliance comparison");
    }
    const model::FrameSpec& X = spec.frames[frame];
    c.p_WXo_ = measurement.frame_origin_W.value_or(X.origin_W);
    Eigen::MatrixXd P, Q;  // H_X = P H_L Q
    const bool projected = IsProjected(measurement);
    if (!projected) {
      if (!measurement.has_all_geometry()) {
        throw InputError(where + ": sensor_position/impact_position: the compliance comparison needs the "
                         "geometry of every channel (or a projected 6x6 FRF with outputs Dx..Rz and inputs "
                         "Fx..Mz); give the geometry or compare with --space raw");
      }
      const FrfData projection = measurement::ProjectToFrame(measurement, X.origin_W);
      P = measurement::PseudoInverse(measurement::CalcSensorJacobian(measurement.outputs, c.p_WXo_));
      Q = measurement::PseudoInverse(measurement::CalcImpactJacobian(measurement.inputs, c.p_WXo_).transpose());
      for (int k = 0; k < nf; ++k) c.measured_[k] = projection.frf[rows[k]];
      c.raw_outputs_ = measurement.outputs;
      c.raw_inputs_ = measurement.inputs;
      raw_measured.resize(nf);
      for (int k = 0; k < nf; ++k) {
        raw_measured[k] = measurement.frf[rows[k]] *
                             measurement::ConversionFactor(c.frequency_hz_(k), measurement.quantity, c.quantity_);
      }
    } else {
      for (int k = 0; k < nf; ++k) c.measured_[k] = measurement.frf[rows[k]];
    }
    for (int k = 0; k < 6; ++k) {
      c.output_names_.push_back(std::string(kDofNames[k]));
      c.input_names_.push_back(kWrenchNames[k]);
    }
    // Weights: propagate the raw noise through the projection (header).
    for (int k = 0; k < nf; ++k) {
      Eigen::MatrixXd w = Eigen::MatrixXd::Ones(6, 6);
      Eigen::MatrixXd snr_k = Eigen::MatrixXd::Constant(6, 6, std::numeric_limits<double>::infinity());
      if (use_coherence) {
        Eigen::MatrixXd var_L, var_L_floor;
        raw_noise_variances(k, &var_L, &var_L_floor);
        const Eigen::MatrixXd var_X_floor =
            projected ? var_L_floor : Eigen::MatrixXd(P.cwiseAbs2() * var_L_floor * Q.cwiseAbs2());
        Eigen::MatrixXd var_X;
        if (projected) {
          var_X = var_L;
        } else {
          var_X = P.cwiseAbs2() * var_L * Q.cwiseAbs2();
        }
        if (!projected) {
          raw_noise_var.push_back(var_L);
          c.raw_noise_var_floor_.push_back(var_L_floor);
        }
        if (estimated_noise && !projected) {
          const Eigen::MatrixXd Q2 = Q.cwiseAbs2();
          pooled_dof.push_back(PooledDegreesOfFreedom(P.cwiseAbs2(), var_L_floor, raw_dof, &Q2));
        }
        for (int a = 0; a < 6; ++a) {
          for (int b = 0; b < 6; ++b) {
            const double sigma = std::sqrt(var_X(a, b));
            const double snr = sigma == 0.0 ? std::numeric_limits<double>::infinity()
                                            : std::abs(c.measured_[k](a, b)) / sigma;
            w(a, b) = std::isfinite(sigma) ? std::min(snr, cap) : 0.0;
            const double sigma_floor = std::sqrt(var_X_floor(a, b));
            snr_k(a, b) = !std::isfinite(sigma) ? 0.0
                          : sigma_floor == 0.0  ? std::numeric_limits<double>::infinity()
                                                : std::abs(c.measured_[k](a, b)) / sigma_floor;
          }
        }
      }
      c.weights_[k] = w;
      snr[k] = snr_k;
    }
    // Model side: motion of the point p_WXo of {X}'s body under a wrench there, W axes.
    for (int k = 0; k < 6; ++k) {
      model::InputSpec in;
      in.kind = k < 3 ? model::InputSpec::Kind::kForce : model::InputSpec::Kind::kTorque;
      in.name = kWrenchNames[k];
      in.body = X.body;
      in.position_W = c.p_WXo_;
      in.direction_W = Eigen::Vector3d::Unit(k % 3);
      c.model_inputs_.push_back(in);
      model::OutputSpec out;
      out.kind = model::OutputSpec::Kind::kFrameMotion;
      out.name = std::string(kDofNames[k]);
      out.body = X.body;
      out.position_W = c.p_WXo_;
      out.dof = static_cast<Dof>(k);
      c.model_outputs_.push_back(out);
    }
  } else if (options.space == ComparisonSpace::kBodies) {
    // Per body (docs/error-metric.md §1): each sensor body's channels projected to the 6 DoF of that
    // body's centre of mass, the impacts kept raw. The model side: the motion of each body's centre of
    // mass under forces at the impacts.
    if (!measurement.has_all_geometry()) {
      throw InputError(where + ": sensor_body/impact_body: the bodies comparison needs the geometry (body, "
                       "position, direction) of every channel");
    }
    std::map<std::string, Eigen::Vector3d> p_WBcm;
    for (const auto& b : spec.bodies) p_WBcm[b.name] = b.com_W;
    for (const auto& ch : measurement.outputs) {
      if (!p_WBcm.count(ch.body)) {
        throw InputError(where + ": sensor '" + ch.name + "' is on body '" + ch.body + "', which the model '" + spec.name +
                         "' does not have");
      }
    }
    const FrfData projection = measurement::ProjectPerBody(measurement, p_WBcm, measurement::InputProjection::kRaw);
    // The left factor P (block per body): the projection of a unit raw row, for the noise propagation.
    Eigen::MatrixXd P = Eigen::MatrixXd::Zero(projection.num_outputs(), measurement.num_outputs());
    {
      FrfData unit = measurement;
      unit.frequency_hz = Eigen::VectorXd::Ones(1);
      unit.frf.assign(1, Eigen::MatrixXcd::Identity(measurement.num_outputs(), measurement.num_outputs()));
      unit.inputs.assign(measurement.num_outputs(), measurement.inputs.front());
      unit.coherence.clear();
      unit.averages.clear();
      P = measurement::ProjectPerBody(unit, p_WBcm, measurement::InputProjection::kRaw).frf[0].real();
    }
    for (int k = 0; k < nf; ++k) c.measured_[k] = projection.frf[rows[k]];
    for (const auto& ch : projection.outputs) {
      c.output_names_.push_back(ch.name);
      model::OutputSpec out;
      out.kind = model::OutputSpec::Kind::kFrameMotion;
      out.name = ch.name;
      out.body = ch.body;
      out.position_W = p_WBcm.at(ch.body);
      out.dof = static_cast<Dof>(static_cast<int>(c.output_names_.size() - 1) % 6);
      c.model_outputs_.push_back(out);
    }
    for (const auto& ch : measurement.inputs) {
      c.input_names_.push_back(ch.name);
      c.model_inputs_.push_back(model::ForceInput(ch.name, ch.body, ch.position_W, ch.direction_W));
    }
    for (int k = 0; k < nf; ++k) {
      const int no = projection.num_outputs(), ni = measurement.num_inputs();
      Eigen::MatrixXd w = Eigen::MatrixXd::Ones(no, ni);
      Eigen::MatrixXd snr_k = Eigen::MatrixXd::Constant(no, ni, std::numeric_limits<double>::infinity());
      if (use_coherence) {
        Eigen::MatrixXd var_L, var_L_floor;
        raw_noise_variances(k, &var_L, &var_L_floor);
        const Eigen::MatrixXd var_X = P.cwiseAbs2() * var_L, var_X_floor = P.cwiseAbs2() * var_L_floor;
        if (estimated_noise) pooled_dof.push_back(PooledDegreesOfFreedom(P.cwiseAbs2(), var_L_floor, raw_dof, nullptr));
        for (int a = 0; a < no; ++a) {
          for (int b = 0; b < ni; ++b) {
            const double sigma = std::sqrt(var_X(a, b)), sigma_floor = std::sqrt(var_X_floor(a, b));
            const double magnitude = std::abs(c.measured_[k](a, b));
            w(a, b) = !std::isfinite(sigma) ? 0.0 : sigma == 0.0 ? cap : std::min(magnitude / sigma, cap);
            snr_k(a, b) = !std::isfinite(sigma) ? 0.0
                          : sigma_floor == 0.0  ? std::numeric_limits<double>::infinity()
                                                : magnitude / sigma_floor;
          }
        }
      }
      c.weights_[k] = w;
      snr[k] = snr_k;
    }
  } else {
    if (!measurement.has_all_geometry()) {
      throw InputError(where + ": sensor_body/impact_body: the raw comparison needs the geometry (body, "
                       "position, direction) of every channel to place them on the model");
    }
    for (const auto& ch : measurement.outputs) {
      c.output_names_.push_back(ch.name);
      c.model_outputs_.push_back(model::SensorOutput(ch.name, ch.body, ch.position_W, ch.direction_W));
    }
    for (const auto& ch : measurement.inputs) {
      c.input_names_.push_back(ch.name);
      c.model_inputs_.push_back(model::ForceInput(ch.name, ch.body, ch.position_W, ch.direction_W));
    }
    for (int k = 0; k < nf; ++k) {
      c.measured_[k] = measurement.frf[rows[k]];
      Eigen::MatrixXd w(measurement.num_outputs(), measurement.num_inputs());
      Eigen::MatrixXd snr_k(w.rows(), w.cols());
      for (int o = 0; o < w.rows(); ++o) {
        for (int i = 0; i < w.cols(); ++i) {
          snr_k(o, i) = raw_snr(k, o, i);
          w(o, i) = std::min(snr_k(o, i), cap);
        }
      }
      c.weights_[k] = w;
      snr[k] = snr_k;
    }
  }

  if (estimated_noise && !c.raw_noise_var_floor_.empty()) c.raw_dof_ = raw_dof;
  // Convert to the comparison quantity.
  if (c.quantity_ != measurement.quantity) {
    for (int k = 0; k < nf; ++k) {
      c.measured_[k] *= measurement::ConversionFactor(c.frequency_hz_(k), measurement.quantity, c.quantity_);
    }
  }

  // Significance (header).
  const int no = c.num_outputs(), ni = c.num_inputs();
  Eigen::MatrixXd mean_log = Eigen::MatrixXd::Zero(no, ni);
  for (int k = 0; k < nf; ++k) {
    for (int o = 0; o < no; ++o) {
      for (int i = 0; i < ni; ++i) mean_log(o, i) += SafeLogAbs(c.measured_[k](o, i)) / nf;
    }
  }
  c.significance_.resize(no, ni);
  if (c.space_ == ComparisonSpace::kCompliance) {
    for (int o = 0; o < no; ++o) {
      for (int i = 0; i < ni; ++i) {
        c.significance_(o, i) = std::exp(mean_log(o, i) - 0.5 * (mean_log(o, o) + mean_log(i, i)));
      }
    }
  } else {
    // Raw and bodies spaces: against the strongest element of the row and of the column. In the bodies
    // space a column holds translations (m) and rotations (rad): rotations count with a 0.1 m lever arm.
    if (c.space_ == ComparisonSpace::kBodies) {
      for (int o = 0; o < no; ++o) {
        if (o % 6 >= 3) mean_log.row(o).array() += std::log(0.1);
      }
    }
    const Eigen::VectorXd row_max = mean_log.rowwise().maxCoeff();
    const Eigen::RowVectorXd col_max = mean_log.colwise().maxCoeff();
    for (int o = 0; o < no; ++o) {
      for (int i = 0; i < ni; ++i) {
        c.significance_(o, i) = std::exp(mean_log(o, i) - 0.5 * (row_max(o) + col_max(i)));
      }
    }
  }
  const bool has_weights = options.use_coherence && measurement.has_coherence();
  c.weights_are_snr_ = has_weights;
  for (int o = 0; o < no; ++o) {
    for (int i = 0; i < ni; ++i) {
      if (!(c.significance_(o, i) >= options.significance_threshold && c.significance_(o, i) > 0.0)) continue;
      // An off-diagonal element that is mostly noise (median coherence SNR below the minimum) carries no
      // information about the model: a symmetric structure's cross-talk measured through noise.
      const bool diagonal = c.space_ == ComparisonSpace::kCompliance && o == i;
      if (!diagonal && has_weights && options.min_element_snr > 0.0) {
        std::vector<double> w(nf);
        for (int k = 0; k < nf; ++k) w[k] = c.weights_[k](o, i);
        std::nth_element(w.begin(), w.begin() + nf / 2, w.end());
        if (w[nf / 2] < options.min_element_snr) continue;
      }
      c.used_elements_.push_back({o, i});
    }
  }

  // Points.
  double sum_w2 = 0.0;
  for (int e = 0; e < static_cast<int>(c.used_elements_.size()); ++e) {
    const ElementIndex idx = c.used_elements_[e];
    for (int k = 0; k < nf; ++k) {
      const double w = c.weights_[k](idx.output, idx.input);
      if (w > 0.0 && std::abs(c.measured_[k](idx.output, idx.input)) > 0.0) {
        const double dof = pooled_dof.empty() ? raw_dof(idx.output, idx.input) : pooled_dof[k](idx.output, idx.input);
        c.points_.push_back({e, k, w, snr[k](idx.output, idx.input), dof});
        sum_w2 += w * w;
      }
    }
  }
  // Unused points carry weight 0 in the published weights.
  Eigen::MatrixXi used = Eigen::MatrixXi::Zero(no, ni);
  for (const auto& idx : c.used_elements_) used(idx.output, idx.input) = 1;
  for (int k = 0; k < nf; ++k) {
    for (int o = 0; o < no; ++o) {
      for (int i = 0; i < ni; ++i) {
        if (!used(o, i) || std::abs(c.measured_[k](o, i)) == 0.0) c.weights_[k](o, i) = 0.0;
      }
    }
  }
  if (c.points_.empty() || !(sum_w2 > 0.0)) {
    throw InputError(where + ": no significant element with a usable point in the band (threshold " +
                     std::to_string(options.significance_threshold) + ", coherence weights)");
  }
  c.weight_norm_ = std::sqrt(sum_w2);

  c.raw_ = RawStacked::Stack(raw_measured, raw_noise_var);
  // Fail early when the model cannot carry the channels.
  const auto assembled = model::AssembledModel::Assemble(spec, "model '" + spec.name + "'");
  c.BuildModelSystem(assembled);
  return c;
}

model::SecondOrderSystem Comparison::BuildModelSystem(const model::AssembledModel& model) const {
  if (space_ != ComparisonSpace::kRaw || model.spec().geometry_corrections.empty()) {
    return model::BuildSystem(model, model_inputs_, model_outputs_);
  }
  // Raw space: the model's sensors and impacts sit where the channels really are, i.e. at the declared
  // geometry corrected by the model's [[geometry_correction]] entries (the sensor-geometry effect).
  std::vector<model::InputSpec> inputs = model_inputs_;
  std::vector<model::OutputSpec> outputs = model_outputs_;
  ApplyGeometryCorrections(model.spec().geometry_corrections, &inputs);
  ApplyGeometryCorrections(model.spec().geometry_corrections, &outputs);
  return model::BuildSystem(model, inputs, outputs);
}

bool Comparison::CorrectedProjection(const model::ModelSpec& spec, Eigen::MatrixXd* P, Eigen::MatrixXd* Q) const {
  if (space_ != ComparisonSpace::kCompliance || !raw_ || spec.geometry_corrections.empty()) {
    return false;
  }
  std::vector<measurement::ChannelGeometry> outputs = raw_outputs_, inputs = raw_inputs_;
  const bool corrected_outputs = ApplyGeometryCorrections(spec.geometry_corrections, &outputs);
  const bool corrected_inputs = ApplyGeometryCorrections(spec.geometry_corrections, &inputs);
  if (!corrected_outputs && !corrected_inputs) return false;
  const std::string what = "comparison with '" + source_ + "' under the model's geometry corrections";
  const Eigen::MatrixXd J_a = measurement::CalcSensorJacobian(outputs, p_WXo_);
  const Eigen::MatrixXd J_F = measurement::CalcImpactJacobian(inputs, p_WXo_);
  measurement::CheckObservable(J_a, what + ": sensors");
  measurement::CheckObservable(J_F, what + ": impacts");
  *P = measurement::PseudoInverse(J_a);
  *Q = measurement::PseudoInverse(J_F.transpose());
  return true;
}

std::shared_ptr<const Comparison::RawStacked> Comparison::RawStacked::Stack(const std::vector<Eigen::MatrixXcd>& raw,
                                                                           const std::vector<Eigen::MatrixXd>& noise_var) {
  if (raw.empty()) return nullptr;
  auto stacked = std::make_shared<RawStacked>();
  const Eigen::Index nf = static_cast<Eigen::Index>(raw.size()), no = raw[0].rows(), ni = raw[0].cols();
  stacked->num_inputs = ni;
  stacked->re.resize(no, ni * nf);
  stacked->im.resize(no, ni * nf);
  for (Eigen::Index k = 0; k < nf; ++k) {
    stacked->re.middleCols(k * ni, ni) = raw[static_cast<size_t>(k)].real();
    stacked->im.middleCols(k * ni, ni) = raw[static_cast<size_t>(k)].imag();
  }
  if (!noise_var.empty()) {
    STAGEFIT_ASSERT(static_cast<Eigen::Index>(noise_var.size()) == nf, "RawStacked::Stack: a noise variance per frequency");
    stacked->noise_var.resize(no, ni * nf);
    for (Eigen::Index k = 0; k < nf; ++k) stacked->noise_var.middleCols(k * ni, ni) = noise_var[static_cast<size_t>(k)];
  }
  return stacked;
}

std::shared_ptr<const Comparison::RawStacked> Comparison::RawStacked::OnFrequencies(const std::vector<int>& kept) const {
  auto subset = std::make_shared<RawStacked>();
  const Eigen::Index ni = num_inputs, nk = static_cast<Eigen::Index>(kept.size());
  subset->num_inputs = ni;
  auto columns = [&](const Eigen::MatrixXd& all, Eigen::MatrixXd* out) {
    if (all.size() == 0) return;
    out->resize(all.rows(), ni * nk);
    for (Eigen::Index k = 0; k < nk; ++k) out->middleCols(k * ni, ni) = all.middleCols(kept[static_cast<size_t>(k)] * ni, ni);
  };
  columns(re, &subset->re);
  columns(im, &subset->im);
  columns(noise_var, &subset->noise_var);
  return subset;
}

void Comparison::ProjectStacked(const Eigen::MatrixXd& P, const Eigen::MatrixXd& stacked, const Eigen::MatrixXd& Q,
                                Eigen::MatrixXd* out) {
  // vec(P H Q) = (Q^T kron P) vec(H), and the stacked parts are vec(H_k) column after column: one
  // product for the whole grid, with no copy of the data. (A standalone timing at 1176 frequencies, per
  // part: 0.17 ms; two products with the blocks rearranged between them 3.3 ms; the complex products
  // per frequency into fresh matrices, as before, 1.9 ms for both parts, 0.41 ms into kept ones.)
  const Eigen::Index no = P.cols(), ni = Q.rows(), np = P.rows(), nq = Q.cols(), nf = stacked.cols() / ni;
  STAGEFIT_ASSERT(stacked.rows() == no && stacked.cols() % ni == 0, "ProjectStacked: the stacked layout");
  Eigen::MatrixXd kron(np * nq, no * ni);
  for (Eigen::Index j = 0; j < nq; ++j) {
    for (Eigen::Index b = 0; b < ni; ++b) kron.block(j * np, b * no, np, no) = Q(b, j) * P;
  }
  out->resize(np * nq, nf);
  out->noalias() = kron * Eigen::Map<const Eigen::MatrixXd>(stacked.data(), no * ni, nf);
}

const std::vector<Eigen::MatrixXcd>& Comparison::Reproject(const Eigen::MatrixXd& P, const Eigen::MatrixXd& Q,
                                                           std::vector<Eigen::MatrixXcd>* storage) const {
  STAGEFIT_ASSERT(raw_ != nullptr, "Reproject: a comparison with raw channels");
  // P and Q are real: the real and imaginary parts project on their own.
  const Eigen::Index nf = raw_->num_frequencies(), np = P.rows();
  // Kept per thread: a fresh result of this size (hundreds of kB) is mapped and faulted in at every call.
  thread_local Eigen::MatrixXd re, im;
  ProjectStacked(P, raw_->re, Q, &re);
  ProjectStacked(P, raw_->im, Q, &im);
  storage->resize(static_cast<size_t>(nf));
  for (Eigen::Index k = 0; k < nf; ++k) {
    Eigen::MatrixXcd& out = (*storage)[static_cast<size_t>(k)];
    out.resize(np, Q.cols());
    out.real() = Eigen::Map<const Eigen::MatrixXd>(re.col(k).data(), np, Q.cols());
    out.imag() = Eigen::Map<const Eigen::MatrixXd>(im.col(k).data(), np, Q.cols());
  }
  return *storage;
}

const std::vector<Eigen::MatrixXcd>& Comparison::MeasuredFor(const model::ModelSpec& spec,
                                                             std::vector<Eigen::MatrixXcd>* storage) const {
  Eigen::MatrixXd P, Q;
  return CorrectedProjection(spec, &P, &Q) ? Reproject(P, Q, storage) : measured_;
}

std::shared_ptr<const Comparison::MeasuredSide> Comparison::MeasuredSideFor(const model::ModelSpec& spec) const {
  Eigen::MatrixXd P, Q;
  if (!CorrectedProjection(spec, &P, &Q) || raw_->noise_var.size() == 0) {
    auto side = std::make_shared<MeasuredSide>();
    if (P.size()) {
      Reproject(P, Q, &side->reprojected);
    } else {
      side->declared = &measured_;
    }
    side->weights.resize(points_.size());
    for (size_t p = 0; p < points_.size(); ++p) side->weights[p] = points_[p].weight;
    side->norm = weight_norm_;
    return side;
  }
  MeasuredSideCache* cache = measured_side_cache_.get();
  if (cache) {
    std::lock_guard<std::mutex> lock(cache->mutex);
    auto& entries = cache->entries;
    for (size_t k = 0; k < entries.size(); ++k) {
      if (entries[k].P == P && entries[k].Q == Q) {
        std::rotate(entries.begin(), entries.begin() + static_cast<long>(k), entries.begin() + static_cast<long>(k) + 1);
        ++cache->num_hits;
        return entries.front().side;
      }
    }
  }
  auto side = std::make_shared<MeasuredSide>();
  Reproject(P, Q, &side->reprojected);
  side->weights = ReprojectedWeights(side->reprojected, P, Q);
  // An off-diagonal element whose re-projected median SNR is below min_element_snr is noise now, as at
  // Create(): it stops counting (header), decided on the whole grid (OnFrequencies()).
  const Eigen::MatrixXi noise = element_reference_ ? element_reference_->NoiseElementsUnder(P, Q) : NoiseElements(side->weights);
  double sum_w2 = 0.0;
  for (size_t p = 0; p < points_.size(); ++p) {
    const ElementIndex idx = used_elements_[points_[p].element];
    if (noise(idx.output, idx.input)) side->weights[p] = 0.0;
    sum_w2 += side->weights[p] * side->weights[p];
  }
  side->norm = sum_w2 > 0.0 ? std::sqrt(sum_w2) : 1.0;
  if (cache) {
    std::lock_guard<std::mutex> lock(cache->mutex);
    auto& entries = cache->entries;
    ++cache->num_misses;
    if (entries.size() == MeasuredSideCache::kCapacity) entries.pop_back();
    entries.insert(entries.begin(), {P, Q, side});
  }
  return side;
}

std::pair<int, int> Comparison::measured_side_reuse() const {
  if (!measured_side_cache_) return {0, 0};
  std::lock_guard<std::mutex> lock(measured_side_cache_->mutex);
  return {measured_side_cache_->num_hits, measured_side_cache_->num_misses};
}

std::vector<double> Comparison::ReprojectedWeights(const std::vector<Eigen::MatrixXcd>& values, const Eigen::MatrixXd& P,
                                                   const Eigen::MatrixXd& Q) const {
  // Re-projected: each point's SNR again (header), as Create() weighs the declared projection, with the
  // raw noise propagated through this projection. (With the declared projection's noise, a turned
  // channel's correction weighed the elements it makes noisier as if they were not: the noise-free
  // truth with its correction scored 0.0835 against a floor of 0.039, seed 2013 of docs/diagnose.md.)
  STAGEFIT_ASSERT(raw_ != nullptr && raw_->noise_var.size() > 0,
                  "ReprojectedWeights: a comparison with the raw channels' noise");
  const Eigen::Index np = P.rows();
  thread_local Eigen::MatrixXd variance;  // as in Reproject()
  ProjectStacked(P.cwiseAbs2(), raw_->noise_var, Q.cwiseAbs2(), &variance);
  std::vector<double> weights(points_.size());
  for (size_t p = 0; p < points_.size(); ++p) {
    const Point& pt = points_[p];
    const ElementIndex idx = used_elements_[pt.element];
    const double sigma = std::sqrt(variance(idx.output + np * idx.input, pt.frequency));
    const double magnitude = std::abs(values[pt.frequency](idx.output, idx.input));
    weights[p] = !std::isfinite(sigma) ? 0.0 : sigma == 0.0 ? weight_cap_ : std::min(magnitude / sigma, weight_cap_);
  }
  return weights;
}

Eigen::MatrixXi Comparison::NoiseElements(const std::vector<double>& weights) const {
  Eigen::MatrixXi noise = Eigen::MatrixXi::Zero(num_outputs(), num_inputs());
  if (!(min_element_snr_ > 0.0)) return noise;
  // Points are element-major, so each element's are contiguous.
  std::vector<double> element_weights;
  for (size_t first = 0; first < points_.size();) {
    size_t last = first;
    while (last < points_.size() && points_[last].element == points_[first].element) ++last;
    const ElementIndex idx = used_elements_[points_[first].element];
    if (idx.output != idx.input) {
      element_weights.assign(weights.begin() + first, weights.begin() + last);
      const size_t mid = element_weights.size() / 2;
      std::nth_element(element_weights.begin(), element_weights.begin() + mid, element_weights.end());
      if (element_weights[mid] < min_element_snr_) noise(idx.output, idx.input) = 1;
    }
    first = last;
  }
  return noise;
}

Eigen::MatrixXi Comparison::NoiseElementsUnder(const Eigen::MatrixXd& P, const Eigen::MatrixXd& Q) const {
  std::vector<Eigen::MatrixXcd> storage;
  return NoiseElements(ReprojectedWeights(Reproject(P, Q, &storage), P, Q));
}

Comparison Comparison::OnFrequencies(const std::vector<int>& kept) const {
  Comparison c = *this;
  c.element_reference_ = element_reference_ ? element_reference_ : std::make_shared<const Comparison>(*this);
  c.measured_side_cache_ = std::make_shared<MeasuredSideCache>();
  const int nf = num_frequencies();
  std::vector<int> index(static_cast<size_t>(nf), -1);
  for (size_t k = 0; k < kept.size(); ++k) {
    STAGEFIT_ASSERT(kept[k] >= 0 && kept[k] < nf && (k == 0 || kept[k] > kept[k - 1]),
                    "OnFrequencies: ascending indices into the comparison's frequencies");
    index[static_cast<size_t>(kept[k])] = static_cast<int>(k);
  }
  auto subset = [&](const auto& all) {
    std::decay_t<decltype(all)> out;
    if (all.empty()) return out;
    for (int k : kept) out.push_back(all[static_cast<size_t>(k)]);
    return out;
  };
  c.frequency_hz_.resize(static_cast<int>(kept.size()));
  for (size_t k = 0; k < kept.size(); ++k) c.frequency_hz_(static_cast<int>(k)) = frequency_hz_(kept[k]);
  if (!kept.empty()) c.frf_options_.lowest_frequency_hz = c.frequency_hz_.minCoeff();
  c.measured_ = subset(measured_);
  c.weights_ = subset(weights_);
  if (raw_) c.raw_ = raw_->OnFrequencies(kept);
  c.raw_noise_var_floor_ = subset(raw_noise_var_floor_);
  c.points_.clear();
  double sum_w2 = 0.0;
  for (const Point& p : points_) {
    const int k = index[static_cast<size_t>(p.frequency)];
    if (k < 0) continue;
    Point q = p;
    q.frequency = k;
    c.points_.push_back(q);
    sum_w2 += q.weight * q.weight;
  }
  if (c.points_.empty() || !(sum_w2 > 0.0)) {
    throw InputError(source_ + ": no compared point at the frequencies kept");
  }
  c.weight_norm_ = std::sqrt(sum_w2);
  return c;
}

std::vector<std::string> Comparison::CorrectableChannels() const {
  std::vector<std::string> names;
  if (space_ == ComparisonSpace::kRaw) {
    names = output_names_;
    names.insert(names.end(), input_names_.begin(), input_names_.end());
  } else {
    for (const auto& ch : raw_outputs_) names.push_back(ch.name);
    for (const auto& ch : raw_inputs_) names.push_back(ch.name);
  }
  return names;
}

std::vector<Eigen::MatrixXcd> Comparison::EvaluateModel(const model::ModelSpec& spec) const {
  const auto assembled = model::AssembledModel::Assemble(spec, "model '" + spec.name + "'");
  auto evaluator = response::FrfEvaluator::Create(BuildModelSystem(assembled), frf_options_);
  const response::FrfArray frf = evaluator.Evaluate(frequency_hz_, ToResponseQuantity(quantity_));
  std::vector<Eigen::MatrixXcd> out(num_frequencies());
  for (int k = 0; k < num_frequencies(); ++k) out[k] = frf.At(k);
  return out;
}

void Comparison::CalcLogErrors(const Eigen::MatrixXcd& model_values, const std::vector<Eigen::MatrixXcd>& measured,
                               Eigen::VectorXcd* e) const {
  e->resize(num_points());
  const int no = num_outputs();
  for (int p = 0; p < num_points(); ++p) {
    const Point& pt = points_[p];
    const ElementIndex idx = used_elements_[pt.element];
    const std::complex<double> h_model = model_values(pt.frequency, idx.output + no * idx.input);
    const std::complex<double> h_meas = measured[pt.frequency](idx.output, idx.input);
    // ln q = ln|q| + j arg q, as std::log computes it, without its exact-arithmetic path for |q| near
    // 1 (where a fit spends its time): that path sorted partial products and took a fifth of a fit.
    // ln|q| from |q|^2 (std::abs would call hypot, a tenth of a fit's time); |q|^2 over- or
    // underflows only for |q| beyond 1e+-154, where hypot takes over.
    const std::complex<double> q = h_model / h_meas;
    const double q2 = std::norm(q);
    const double log_abs = q2 > 0.0 && q2 < std::numeric_limits<double>::infinity() ? 0.5 * std::log(q2)
                                                                                    : std::log(std::abs(q));
    const std::complex<double> value(log_abs, std::arg(q));
    if (!std::isfinite(value.real()) || !std::isfinite(value.imag())) {
      std::ostringstream msg;
      msg << "comparison with '" << source_ << "': the model's response " << ElementName(idx) << " at "
          << frequency_hz_(pt.frequency) << " Hz is " << h_model << ", expected finite and non-zero";
      throw NumericalError(msg.str());
    }
    (*e)(p) = value;
  }
}

void Comparison::Residuals(const model::ModelSpec& spec, Eigen::VectorXd* r) const {
  ResidualsAndJacobian(spec, {}, r, nullptr);
}

double Comparison::Error(const model::ModelSpec& spec) const {
  Eigen::VectorXd r;
  Residuals(spec, &r);
  return r.norm();
}

response::FrfEvaluator& ModelWorkspace::SetUp(const model::SecondOrderSystem& system,
                                              const response::FrfEvaluatorOptions& options) {
  if (setup_ && options_ == options && model::SameSystem(setup_->system(), system)) {
    ++num_reused;
    return *setup_;
  }
  setup_.reset();  // a set-up that throws leaves none behind
  setup_ = response::FrfEvaluator::Create(system, options);
  options_ = options;
  ++num_setups;
  return *setup_;
}

void Comparison::ResidualsAndJacobian(const model::ModelSpec& spec,
                                      const std::vector<model::ParameterInfo>& params, Eigen::VectorXd* r,
                                      Eigen::MatrixXd* J) const {
  ModelWorkspace workspace;
  ResidualsAndJacobian(spec, params, r, J, &workspace);
}

void Comparison::ResidualsAndJacobian(const model::ModelSpec& spec,
                                      const std::vector<model::ParameterInfo>& params, Eigen::VectorXd* r,
                                      Eigen::MatrixXd* J, ModelWorkspace* workspace) const {
  ResidualsAndJacobian(spec, params, {}, r, J, workspace);
}

void Comparison::WeightResiduals(const Eigen::VectorXcd& e, const MeasuredSide& side, Eigen::VectorXd* r) const {
  const int np = num_points();
  r->resize(2 * np);
  for (int p = 0; p < np; ++p) {
    const std::complex<double> we = side.weights[p] * e(p) / side.norm;
    (*r)(p) = we.real();
    (*r)(np + p) = we.imag();
  }
}

void Comparison::ResidualsWithModelResponse(const model::ModelSpec& spec, const Eigen::MatrixXcd& model_values,
                                            Eigen::VectorXd* r, double delay_change_s) const {
  STAGEFIT_ASSERT(r != nullptr, "r must not be null");
  STAGEFIT_ASSERT(model_values.rows() == num_frequencies() && model_values.cols() == num_outputs() * num_inputs(),
                  "model_values must be num_frequencies() x (num_outputs() * num_inputs())");
  const std::shared_ptr<const MeasuredSide> measured_side = MeasuredSideFor(spec);
  const MeasuredSide& side = *measured_side;
  Eigen::VectorXcd e;
  if (delay_change_s == 0.0) {
    CalcLogErrors(model_values, side.values(), &e);
  } else {
    Eigen::MatrixXcd delayed = model_values;
    for (int k = 0; k < num_frequencies(); ++k) {
      delayed.row(k) *= std::polar(1.0, -2.0 * M_PI * frequency_hz_(k) * delay_change_s);
    }
    CalcLogErrors(delayed, side.values(), &e);
  }
  WeightResiduals(e, side, r);
}

response::ResponseQuantity Comparison::response_quantity() const { return ToResponseQuantity(quantity_); }

model::SecondOrderSystem Comparison::ModelSystem(const model::ModelSpec& spec) const {
  return BuildModelSystem(model::AssembledModel::Assemble(spec, "model '" + spec.name + "'"));
}

void Comparison::ResidualsAndJacobian(const model::ModelSpec& spec,
                                      const std::vector<model::ParameterInfo>& params,
                                      const std::vector<response::DynamicStiffnessDerivative>& further,
                                      Eigen::VectorXd* r, Eigen::MatrixXd* J,
                                      ModelWorkspace* workspace) const {
  STAGEFIT_ASSERT(r != nullptr && workspace != nullptr, "r and workspace must not be null");
  const auto assembled = model::AssembledModel::Assemble(spec, "model '" + spec.name + "'");
  response::FrfEvaluator& evaluator = workspace->SetUp(BuildModelSystem(assembled), frf_options_);
  const auto quantity = ToResponseQuantity(quantity_);
  const int np = num_points();
  const int num_columns = static_cast<int>(params.size() + further.size());
  const bool want_jacobian = J != nullptr && num_columns > 0;

  response::FrfWithDerivatives& frf = workspace->frf;
  if (want_jacobian && further.empty()) {
    evaluator.EvaluateWithDerivatives(frequency_hz_, quantity, params, assembled, &frf);
  } else if (want_jacobian) {
    std::vector<response::DynamicStiffnessDerivative> derivatives;
    derivatives.reserve(num_columns);
    for (const auto& p : params) {
      derivatives.push_back(response::MakeDynamicStiffnessDerivative(model::CalcSystemDerivative(assembled, p), p.name));
    }
    // The response layer refuses an entry outside the coordinates (InputError).
    derivatives.insert(derivatives.end(), further.begin(), further.end());
    evaluator.EvaluateWithDerivatives(frequency_hz_, quantity, derivatives, &frf);
  } else {
    evaluator.Evaluate(frequency_hz_, quantity, &frf.frf);
  }
  const std::shared_ptr<const MeasuredSide> measured_side = MeasuredSideFor(spec);
  const MeasuredSide& side = *measured_side;
  Eigen::VectorXcd e;
  CalcLogErrors(frf.frf.values, side.values(), &e);
  WeightResiduals(e, side, r);
  if (J == nullptr) return;
  if (!want_jacobian) {
    J->setZero(2 * np, num_columns);
    return;
  }
  J->resize(2 * np, num_columns);  // every entry is written below
  const int no = num_outputs();
  // w de/dp = (w / H_model) dH/dp: one division per point, not one per point and parameter.
  Eigen::VectorXcd factor(np);
  Eigen::VectorXi column(np);
  for (int p = 0; p < np; ++p) {
    const Point& pt = points_[p];
    const ElementIndex idx = used_elements_[pt.element];
    column(p) = idx.output + no * idx.input;
    factor(p) = (side.weights[p] / side.norm) / frf.frf.values(pt.frequency, column(p));
  }
  for (int k = 0; k < num_columns; ++k) {
    const Eigen::MatrixXcd& dH = frf.derivatives[k];
    for (int p = 0; p < np; ++p) {
      const std::complex<double> wde = factor(p) * dH(points_[p].frequency, column(p));
      (*J)(p, k) = wde.real();
      (*J)(np + p, k) = wde.imag();
    }
  }
}

ComparisonResult Comparison::Evaluate(const model::ModelSpec& spec) const {
  ComparisonResult result;
  result.model = EvaluateModel(spec);
  const int no = num_outputs();
  const int nf = num_frequencies();
  Eigen::MatrixXcd values(nf, no * num_inputs());
  for (int k = 0; k < nf; ++k) {
    for (int i = 0; i < num_inputs(); ++i) values.row(k).segment(no * i, no) = result.model[k].col(i).transpose();
  }
  const std::shared_ptr<const MeasuredSide> measured_side = MeasuredSideFor(spec);
  const MeasuredSide& side = *measured_side;
  result.measured = side.values();
  Eigen::VectorXcd e;
  CalcLogErrors(values, result.measured, &e);

  const auto bands = measurement::MakeFractionalOctaveBands(frequency_hz_(0), frequency_hz_(nf - 1),
                                                            bands_per_octave_);
  const int ne = static_cast<int>(used_elements_.size());
  const int nb_all = static_cast<int>(bands.size());
  const std::vector<int> band_of = measurement::BandOfEachFrequency(frequency_hz_, bands);
  Eigen::MatrixXd num = Eigen::MatrixXd::Zero(ne, nb_all), den = Eigen::MatrixXd::Zero(ne, nb_all);
  Eigen::MatrixXi count = Eigen::MatrixXi::Zero(ne, nb_all);
  Eigen::VectorXd mean_re = Eigen::VectorXd::Zero(ne), mean_im = Eigen::VectorXd::Zero(ne);
  for (int p = 0; p < num_points(); ++p) {
    const Point& pt = points_[p];
    const int b = band_of[pt.frequency];
    STAGEFIT_ASSERT(b >= 0, "frequency outside every band");
    const double w2 = side.weights[p] * side.weights[p];
    num(pt.element, b) += w2 * std::norm(e(p));
    den(pt.element, b) += w2;
    count(pt.element, b) += 1;
    mean_re(pt.element) += w2 * e(p).real();
    mean_im(pt.element) += w2 * e(p).imag();
  }
  const double total_num = num.sum();
  // The scalar itself is ||r||, computed exactly as Residuals() does, so that a compare report and a
  // fit report of the same model agree to the last bit (the sums above only apportion it).
  Eigen::VectorXd r(2 * num_points());
  for (int p = 0; p < num_points(); ++p) {
    const std::complex<double> we = side.weights[p] * e(p) / side.norm;
    r(p) = we.real();
    r(num_points() + p) = we.imag();
  }
  result.error = r.norm();

  for (int k = 0; k < ne; ++k) {
    ElementError el;
    el.index = used_elements_[k];
    el.name = ElementName(el.index);
    el.significance = significance_(el.index.output, el.index.input);
    el.num_points = count.row(k).sum();
    const double d = den.row(k).sum();
    el.error = d > 0 ? std::sqrt(num.row(k).sum() / d) : 0.0;
    el.share = total_num > 0 ? num.row(k).sum() / total_num : 0.0;
    el.mean_log_magnitude = d > 0 ? mean_re(k) / d : 0.0;
    el.mean_phase_rad = d > 0 ? mean_im(k) / d : 0.0;
    if (num.row(k).sum() > 0) {
      Eigen::Index worst = 0;
      el.worst_band_share = num.row(k).maxCoeff(&worst) / num.row(k).sum();
      el.worst_band = bands[worst];
    }
    result.elements.push_back(el);
  }
  std::vector<int> kept;
  for (int b = 0; b < nb_all; ++b) {
    if (count.col(b).sum() == 0) continue;
    kept.push_back(b);
    BandError be;
    be.band = bands[b];
    be.num_points = count.col(b).sum();
    be.error = den.col(b).sum() > 0 ? std::sqrt(num.col(b).sum() / den.col(b).sum()) : 0.0;
    be.share = total_num > 0 ? num.col(b).sum() / total_num : 0.0;
    result.bands.push_back(be);
  }
  result.element_band_error.resize(ne, static_cast<int>(kept.size()));
  for (int k = 0; k < ne; ++k) {
    for (int j = 0; j < static_cast<int>(kept.size()); ++j) {
      const int b = kept[j];
      result.element_band_error(k, j) =
          count(k, b) > 0 && den(k, b) > 0 ? std::sqrt(num(k, b) / den(k, b)) : std::numeric_limits<double>::quiet_NaN();
    }
  }
  return result;
}

namespace {

// E|ln(1 + z)|^2 and E|ln(1 + z)|^4, z ~ CN(0, s^2), by quadrature: |z|^2 = s^2 u with u ~ Exp(1)
// (Gauss-Laguerre nodes, exact for moments of u up to 2 n - 1), arg z uniform (midpoints:
// spectrally accurate for the smooth periodic integrand; the log singularity at z = -1 is integrable
// and never hit by a node).
struct GaussRule {
  Eigen::VectorXd nodes, weights;
};

const GaussRule& LaguerreRule() {
  // Golub-Welsch: the nodes are the eigenvalues of the Jacobi matrix of the Laguerre polynomials
  // (diagonal 2k + 1, off-diagonal k), the weights the squared first components of its eigenvectors.
  static const GaussRule rule = [] {
    constexpr int n = 48;
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(n, n);
    for (int k = 0; k < n; ++k) {
      J(k, k) = 2.0 * k + 1.0;
      if (k + 1 < n) J(k, k + 1) = J(k + 1, k) = k + 1.0;
    }
    const auto eig = CalcSymmetricEigenPairs(J);
    STAGEFIT_ASSERT(eig.has_value(), "the eigen-problem of the Gauss-Laguerre rule did not converge");
    GaussRule r;
    r.nodes = eig->values;
    r.weights = eig->vectors.row(0).transpose().array().square();
    return r;
  }();
  return rule;
}

LogErrorMoments QuadratureMoments(double s) {
  constexpr int kAngular = 128;
  const GaussRule& rule = LaguerreRule();
  double m2 = 0.0, m4 = 0.0;
  for (int a = 0; a < rule.nodes.size(); ++a) {
    const double r = s * std::sqrt(rule.nodes(a));
    double e2_sum = 0.0, e4_sum = 0.0;
    for (int b = 0; b < kAngular; ++b) {
      const double phi = 2.0 * M_PI * (b + 0.5) / kAngular;
      const std::complex<double> e = std::log(std::complex<double>(1.0 + r * std::cos(phi), r * std::sin(phi)));
      const double e2 = std::norm(e);
      e2_sum += e2;
      e4_sum += e2 * e2;
    }
    m2 += rule.weights(a) * e2_sum / kAngular;
    m4 += rule.weights(a) * e4_sum / kAngular;
  }
  return {m2, m4};
}

// The quadrature tabulated on s = 10^(kLogMin + j / kPerDecade), interpolated in log-log.
constexpr double kTableLogMin = -2.0, kTableLogMax = 2.0;
constexpr int kTablePerDecade = 24;

const std::vector<LogErrorMoments>& MomentTable() {
  static const std::vector<LogErrorMoments> table = [] {
    const int n = static_cast<int>((kTableLogMax - kTableLogMin) * kTablePerDecade) + 1;
    std::vector<LogErrorMoments> t(n);
    for (int j = 0; j < n; ++j) t[j] = QuadratureMoments(std::pow(10.0, kTableLogMin + static_cast<double>(j) / kTablePerDecade));
    return t;
  }();
  return table;
}

}  // namespace

LogErrorMoments ExpectedLogErrorMoments(double s) {
  if (!(s > 0.0)) return {0.0, 0.0};
  if (s < std::pow(10.0, kTableLogMin)) {
    const double s2 = s * s;
    return {s2 * (1.0 + s2 / 2.0 + 2.0 * s2 * s2 / 3.0), 2.0 * s2 * s2};
  }
  const double x = (std::log10(s) - kTableLogMin) * kTablePerDecade;
  const std::vector<LogErrorMoments>& table = MomentTable();
  if (!(x < static_cast<double>(table.size() - 1))) return QuadratureMoments(s);
  const int j = static_cast<int>(x);
  const double f = x - j;
  auto interp = [f](double lo, double hi) { return std::exp((1.0 - f) * std::log(lo) + f * std::log(hi)); };
  return {interp(table[j].m2, table[j + 1].m2), interp(table[j].m4, table[j + 1].m4)};
}

// With x^-1 f_nu(x) = f_(nu-2)(x) / (nu - 2) for the chi-square densities:
//     c^2 P(X < t) + nu / (nu - 2) Q((nu - 2) / 2, t / 2),   t = nu / c^2,
// P(X < t) the regularised lower incomplete gamma P(nu / 2, t / 2), Q the upper one; at nu = 2 the
// second term is E1(t / 2).
double MeanSquareWeightOverSnr(double nu, double c) {
  const double t = nu / (c * c);
  const double capped = c * c * Eigen::numext::igamma(0.5 * nu, 0.5 * t);
  // Below nu = 2.05 the gamma function of (nu - 2) / 2 is near its pole: E1, its limit at nu = 2
  // (Satterthwaite's nu is never below the raw points' 2 (n - 1) >= 2).
  const double uncapped = nu > 2.05 ? nu / (nu - 2.0) * Eigen::numext::igammac(0.5 * (nu - 2.0), 0.5 * t)
                                    : 0.5 * nu * -std::expint(-0.5 * t);
  return capped + uncapped;
}

namespace {

/// The NoiseFloor (header of Comparison::CalcNoiseFloor()) of `count` points with weights `weight(p)`,
/// uncapped SNRs `snr(p)` and the degrees of freedom `dof(p)` of the variance their weights are
/// estimated with. A weight estimated from few hits is itself noisy, and the error weighs each point's
/// noise by it: the expected w^2 |e|^2 is the SNR^2 E[min(SNR_est, cap)^2] / SNR^2 = MeanSquareWeightOverSnr
/// times s^2, which exceeds w^2 s^2 by (n - 1) / (n - 2) for an unpooled point of n hits below the cap
/// (docs/error-metric.md §8). The point's SNR stands for the true one in c = cap / SNR.
template <typename Weight, typename Snr, typename Dof>
NoiseFloor NoiseFloorOf(size_t count, const Weight& weight, const Snr& snr, const Dof& dof, double cap) {
  NoiseFloor out;
  double sum_w2 = 0.0, sum_m2 = 0.0, sum_var = 0.0;
  for (size_t p = 0; p < count; ++p) {
    const double w2 = weight(p) * weight(p);
    sum_w2 += w2;
    if (!std::isfinite(snr(p)) || w2 == 0.0) continue;  // a noise-free or uncounted point adds nothing
    const LogErrorMoments m = ExpectedLogErrorMoments(1.0 / snr(p));
    double inflation = 1.0;
    if (std::isfinite(dof(p)) && snr(p) > 0.0) {
      const double c = cap / snr(p);
      inflation = MeanSquareWeightOverSnr(dof(p), c) / std::min(1.0, c * c);
    }
    sum_m2 += w2 * m.m2 * inflation;
    sum_var += w2 * w2 * std::max(0.0, m.m4 - m.m2 * m.m2);
    ++out.num_points;
  }
  if (!(sum_w2 > 0.0)) return out;
  out.known = true;
  out.floor = std::sqrt(sum_m2 / sum_w2);
  out.sd = out.floor > 0.0 ? std::sqrt(sum_var) / sum_w2 / (2.0 * out.floor) : 0.0;
  return out;
}

}  // namespace

NoiseFloor Comparison::CalcNoiseFloor() const {
  if (!weights_are_snr_) return {};
  return NoiseFloorOf(
      points_.size(), [&](size_t p) { return points_[p].weight; }, [&](size_t p) { return points_[p].snr; },
      [&](size_t p) { return points_[p].dof; }, weight_cap_);
}

NoiseFloor Comparison::CalcNoiseFloor(const model::ModelSpec& spec) const {
  Eigen::MatrixXd P, Q;
  if (!weights_are_snr_ || !CorrectedProjection(spec, &P, &Q) || raw_noise_var_floor_.empty()) return CalcNoiseFloor();
  // The side's weights, and each point's SNR for the floor as Create() has it for the declared
  // projection: the re-projected |H_X| over the floor's raw noise propagated through this projection.
  const std::shared_ptr<const MeasuredSide> side = MeasuredSideFor(spec);
  const Eigen::MatrixXd P2 = P.cwiseAbs2(), Q2 = Q.cwiseAbs2();
  std::vector<Eigen::MatrixXd> sigma(raw_noise_var_floor_.size());
  for (size_t k = 0; k < sigma.size(); ++k) sigma[k] = (P2 * raw_noise_var_floor_[k] * Q2).cwiseSqrt();
  auto snr = [&](size_t p) {
    const ElementIndex idx = used_elements_[points_[p].element];
    const double s = sigma[points_[p].frequency](idx.output, idx.input);
    return s == 0.0 ? std::numeric_limits<double>::infinity()
                    : std::abs(side->values()[points_[p].frequency](idx.output, idx.input)) / s;
  };
  // The degrees of freedom pooled through this projection, as Create() pools them through the declared one.
  std::vector<Eigen::MatrixXd> dof;
  if (raw_dof_.size() > 0) {
    for (const Eigen::MatrixXd& var : raw_noise_var_floor_) dof.push_back(PooledDegreesOfFreedom(P2, var, raw_dof_, &Q2));
  }
  auto dof_of = [&](size_t p) {
    if (dof.empty()) return std::numeric_limits<double>::infinity();
    const ElementIndex idx = used_elements_[points_[p].element];
    return dof[points_[p].frequency](idx.output, idx.input);
  };
  return NoiseFloorOf(points_.size(), [&](size_t p) { return side->weights[p]; }, snr, dof_of, weight_cap_);
}

std::string NoiseFloorLine(double error, const NoiseFloor& floor) {
  char line[256];
  if (!floor.known) {
    return "noise floor: unknown (the measurement has no coherence; the error cannot be set against its noise)\n";
  }
  if (floor.floor > 0.0) {
    std::snprintf(line, sizeof line, "noise floor %.5f (sd %.5f); model error %.5f = %.2f x floor\n", floor.floor, floor.sd,
                  error, error / floor.floor);
  } else {
    std::snprintf(line, sizeof line, "noise floor 0 (noise-free data); model error %.5f\n", error);
  }
  return line;
}

std::string ComparisonResult::BriefReport(int max_rows) const {
  std::ostringstream out;
  char line[256];
  std::snprintf(line, sizeof line, "error = %.5f  (%zu elements, %zu bands)\n", error, elements.size(),
                bands.size());
  out << line;
  std::vector<int> order(elements.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = static_cast<int>(k);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return elements[a].share > elements[b].share; });
  out << "worst elements:\n";
  std::snprintf(line, sizeof line, "  %-14s %9s %8s %11s %11s %7s\n", "element", "error", "share", "ln|ratio|",
                "phase[deg]", "kappa");
  out << line;
  for (int k = 0; k < std::min<int>(max_rows, static_cast<int>(order.size())); ++k) {
    const ElementError& el = elements[order[k]];
    std::snprintf(line, sizeof line, "  %-14s %9.4f %7.1f%% %11.4f %11.2f %7.3f\n", el.name.c_str(), el.error,
                  100 * el.share, el.mean_log_magnitude, el.mean_phase_rad * kDegreesPerRadian, el.significance);
    out << line;
  }
  std::vector<int> border(bands.size());
  for (size_t k = 0; k < border.size(); ++k) border[k] = static_cast<int>(k);
  std::sort(border.begin(), border.end(), [&](int a, int b) { return bands[a].share > bands[b].share; });
  out << "worst bands:\n";
  std::snprintf(line, sizeof line, "  %-22s %9s %8s %7s\n", "band [Hz]", "error", "share", "points");
  out << line;
  for (int k = 0; k < std::min<int>(max_rows, static_cast<int>(border.size())); ++k) {
    const BandError& b = bands[border[k]];
    char range[64];
    std::snprintf(range, sizeof range, "%.4g - %.4g", b.band.low_hz, b.band.high_hz);
    std::snprintf(line, sizeof line, "  %-22s %9.4f %7.1f%% %7d\n", range, b.error, 100 * b.share, b.num_points);
    out << line;
  }
  return out.str();
}

}  // namespace stagefit::compare
