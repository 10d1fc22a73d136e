#include "stagefit/measurement/uff_time.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "stagefit/common/error.h"

namespace stagefit::measurement {
namespace {

using Dof = std::pair<int, int>;  // node, direction code

std::string DofName(const Dof& d) {
  if (d.second == 0) return std::to_string(d.first);
  static const char kAxes[] = {'X', 'Y', 'Z'};
  return std::to_string(d.first) + (d.second > 0 ? "+" : "-") + kAxes[std::abs(d.second) - 1];
}

Eigen::Vector3d DirectionOf(int code) {
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  if (code != 0 && std::abs(code) <= 3) v[std::abs(code) - 1] = code > 0 ? 1.0 : -1.0;
  return v;
}

int CodeOf(const Eigen::Vector3d& n, const std::string& name) {
  for (int a = 0; a < 3; ++a) {
    if (std::abs(std::abs(n[a]) - 1.0) < 1e-12 && std::abs(n.norm() - 1.0) < 1e-12) return n[a] > 0 ? a + 1 : -(a + 1);
  }
  throw InputError("channel '" + name + "': direction is not along +-x, +-y or +-z; a UFF direction code cannot hold it");
}

// The channel name of a record: record 4 "channels: <name>" when written by ConvertRawHammerToUff, else
// "<node><sign><axis>".
std::string NameOf(const UffRecord& r) {
  const std::string prefix = "channels: ";
  if (r.id[3].rfind(prefix, 0) == 0 && r.id[3].size() > prefix.size()) return r.id[3].substr(prefix.size());
  return DofName({r.response_node, r.response_direction});
}

}  // namespace

RawHammerData ConvertUffToRawHammer(const UffFile& file, const std::string& source, const UffTimeOptions& options) {
  const std::string where = "UFF file '" + source + "'";
  std::vector<std::size_t> time;
  for (std::size_t i = 0; i < file.records.size(); ++i) {
    if (file.records[i].function_type == uff_function::kTimeResponse) time.push_back(i);
  }
  if (time.empty()) {
    throw InputError(where + ": no time record (dataset 58 with function type 1) among its " +
                     std::to_string(file.records.size()) + " dataset(s); estimate needs raw time data");
  }
  auto label = [&](std::size_t i) {
    const UffRecord& r = file.records[i];
    return where + ", dataset 58 number " + std::to_string(i + 1) + " (channel " + NameOf(r) + ", reference " +
           DofName({r.reference_node, r.reference_direction}) + ", load case " + std::to_string(r.load_case_id) + ")";
  };
  const UffRecord& first = file.records[time.front()];
  for (std::size_t i : time) {
    const UffRecord& r = file.records[i];
    if (r.is_complex()) throw InputError(label(i) + ": complex time record, expected real samples");
    if (!r.even_abscissa || !(r.abscissa_increment > 0.0)) {
      throw InputError(label(i) + ": abscissa increment " + std::to_string(r.abscissa_increment) +
                       " with " + (r.even_abscissa ? "even" : "uneven") + " spacing, expected evenly spaced samples");
    }
    if (r.num_points() != first.num_points() || r.abscissa_increment != first.abscissa_increment) {
      throw InputError(label(i) + ": " + std::to_string(r.num_points()) + " samples at " +
                       std::to_string(1.0 / r.abscissa_increment) + " Hz, expected " +
                       std::to_string(first.num_points()) + " at " + std::to_string(1.0 / first.abscissa_increment) +
                       " Hz as the first time record");
    }
  }
  // Group: impact (reference DOF) -> hit (load case) -> records.
  std::vector<Dof> impacts;
  std::map<Dof, std::map<int, std::vector<std::size_t>>> runs;
  for (std::size_t i : time) {
    const UffRecord& r = file.records[i];
    const Dof ref{r.reference_node, r.reference_direction};
    if (std::find(impacts.begin(), impacts.end(), ref) == impacts.end()) impacts.push_back(ref);
    runs[ref][r.load_case_id].push_back(i);
  }
  // The force record of a hit, and the response channels (in order of first appearance).
  auto is_force = [&](std::size_t i, const Dof& ref) {
    const UffRecord& r = file.records[i];
    if (!options.force_channel.empty()) return NameOf(r) == options.force_channel;
    return Dof{r.response_node, r.response_direction} == ref;
  };
  std::vector<std::string> channels;
  std::map<std::string, Dof> channel_dof;
  for (std::size_t i : time) {
    const UffRecord& r = file.records[i];
    if (is_force(i, {r.reference_node, r.reference_direction})) continue;
    const std::string name = NameOf(r);
    if (!options.responses.empty() &&
        std::find(options.responses.begin(), options.responses.end(), name) == options.responses.end()) {
      continue;
    }
    if (std::find(channels.begin(), channels.end(), name) == channels.end()) {
      channels.push_back(name);
      channel_dof[name] = {r.response_node, r.response_direction};
    }
  }
  for (const std::string& wanted : options.responses) {
    if (std::find(channels.begin(), channels.end(), wanted) == channels.end()) {
      throw InputError(where + ": --responses names '" + wanted + "', which is not a response channel of the file");
    }
  }
  if (channels.empty()) throw InputError(where + ": no response channel besides the force");

  RawHammerData data;
  data.source = source;
  data.sample_rate_hz = 1.0 / first.abscissa_increment;
  // Quantity and scale of the responses from their units (all responses must agree on the quantity).
  std::optional<FrfQuantity> quantity;
  auto response_scale = [&](std::size_t i) {
    const UffRecord& r = file.records[i];
    const auto unit = UffMotionUnitToSi(r.ordinate.units_label);
    FrfQuantity q = FrfQuantity::kAccelerance;
    double scale = 1.0;
    if (unit) {
      q = unit->first;
      scale = unit->second;
    } else if (r.ordinate.specific_data_type == uff_data_type::kVelocity) {
      q = FrfQuantity::kMobility;
    } else if (r.ordinate.specific_data_type == uff_data_type::kDisplacement) {
      q = FrfQuantity::kReceptance;
    } else if (file.has_units) {
      scale = std::pow(file.length_factor, -r.ordinate.length_unit_exponent);
    }
    if (quantity && *quantity != q) {
      throw InputError(label(i) + ": units '" + r.ordinate.units_label + "' make it " + ToString(q) +
                       " data, but earlier responses were " + ToString(*quantity));
    }
    quantity = q;
    return scale;
  };
  auto force_scale = [&](std::size_t i) {
    const UffRecord& r = file.records[i];
    if (const auto n = UffForceUnitToNewtons(r.ordinate.units_label)) return *n;
    if (file.has_units) return std::pow(file.force_factor, -r.ordinate.force_unit_exponent);
    return 1.0;
  };
  for (const std::string& name : channels) {
    ChannelGeometry c;
    c.name = name;
    c.direction_W = DirectionOf(channel_dof[name].second);
    data.outputs.push_back(c);
  }
  const int ns = first.num_points();
  data.hits.resize(impacts.size());
  for (std::size_t k = 0; k < impacts.size(); ++k) {
    const Dof& ref = impacts[k];
    ChannelGeometry in;
    in.name = DofName(ref);
    in.direction_W = DirectionOf(ref.second);
    // The input is named as its force record's channel (record 4 "channels: <name>"), else by its DOF.
    for (std::size_t i : runs[ref].begin()->second) {
      if (is_force(i, ref)) in.name = NameOf(file.records[i]);
    }
    data.inputs.push_back(in);
    for (const auto& [load_case, records] : runs[ref]) {
      HammerHit hit;
      hit.response = Eigen::MatrixXd::Zero(ns, static_cast<Eigen::Index>(channels.size()));
      std::vector<bool> have(channels.size(), false);
      bool have_force = false;
      for (std::size_t i : records) {
        const UffRecord& r = file.records[i];
        if (is_force(i, ref)) {
          if (have_force) throw InputError(label(i) + ": a second force record in this hit");
          hit.force = r.real_y * force_scale(i);
          have_force = true;
          continue;
        }
        const auto at = std::find(channels.begin(), channels.end(), NameOf(r));
        if (at == channels.end()) continue;
        const std::size_t c = static_cast<std::size_t>(at - channels.begin());
        if (have[c]) throw InputError(label(i) + ": a second record of this channel in this hit");
        hit.response.col(static_cast<Eigen::Index>(c)) = r.real_y * response_scale(i);
        have[c] = true;
      }
      const std::string hit_name = where + ", impact " + in.name + ", load case " + std::to_string(load_case);
      if (!have_force) {
        throw InputError(hit_name + ": no force record (" +
                         (options.force_channel.empty() ? "a record whose response DOF is the reference DOF"
                                                        : "channel '" + options.force_channel + "'") + ")");
      }
      for (std::size_t c = 0; c < channels.size(); ++c) {
        if (!have[c]) throw InputError(hit_name + ": no record of response channel '" + channels[c] + "'");
      }
      data.hits[k].push_back(std::move(hit));
    }
  }
  data.quantity = quantity.value_or(FrfQuantity::kAccelerance);
  Validate(data);
  return data;
}

RawHammerData ReadUffRawHammer(const std::filesystem::path& path, const UffTimeOptions& options) {
  return ConvertUffToRawHammer(ReadUffFile(path), path.string(), options);
}

std::vector<UffRecord> ConvertRawHammerToUff(const RawHammerData& data) {
  Validate(data);
  std::vector<UffRecord> records;
  const char* motion = data.quantity == FrfQuantity::kAccelerance ? "m/s^2"
                       : data.quantity == FrfQuantity::kMobility  ? "m/s"
                                                                  : "m";
  const int motion_type = data.quantity == FrfQuantity::kAccelerance ? uff_data_type::kAcceleration
                          : data.quantity == FrfQuantity::kMobility  ? uff_data_type::kVelocity
                                                                     : uff_data_type::kDisplacement;
  auto base = [&](int response_node, int response_direction, int reference_node, int reference_direction, int hit,
                  const std::string& name) {
    UffRecord r;
    r.id = {"stagefit raw hammer data", "NONE", "NONE", "channels: " + name, "NONE"};
    r.function_type = uff_function::kTimeResponse;
    r.load_case_id = hit + 1;
    r.response_entity = name.substr(0, 10);
    r.response_node = response_node;
    r.response_direction = response_direction;
    r.reference_node = reference_node;
    r.reference_direction = reference_direction;
    r.ordinate_type = UffOrdinateType::kRealDouble;
    r.even_abscissa = true;
    r.abscissa_minimum = 0.0;
    r.abscissa_increment = 1.0 / data.sample_rate_hz;
    r.abscissa.specific_data_type = uff_data_type::kTime;
    r.abscissa.label = "Time";
    r.abscissa.units_label = "s";
    return r;
  };
  const int ns = data.num_samples();
  const Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(ns, 0.0, (ns - 1) / data.sample_rate_hz);
  for (int k = 0; k < data.num_inputs(); ++k) {
    const int in_code = CodeOf(data.inputs[k].direction_W, data.inputs[k].name);
    for (std::size_t h = 0; h < data.hits[k].size(); ++h) {
      const HammerHit& hit = data.hits[k][h];
      UffRecord f = base(1001 + k, in_code, 1001 + k, in_code, static_cast<int>(h), data.inputs[k].name);
      f.ordinate.specific_data_type = uff_data_type::kExcitationForce;
      f.ordinate.force_unit_exponent = 1;
      f.ordinate.label = "Force";
      f.ordinate.units_label = "N";
      f.x = t;
      f.real_y = hit.force;
      records.push_back(f);
      for (int o = 0; o < data.num_outputs(); ++o) {
        UffRecord r = base(1 + o, CodeOf(data.outputs[o].direction_W, data.outputs[o].name), 1001 + k, in_code,
                           static_cast<int>(h), data.outputs[o].name);
        r.ordinate.specific_data_type = motion_type;
        r.ordinate.length_unit_exponent = 1;
        r.ordinate.label = "Response";
        r.ordinate.units_label = motion;
        r.x = t;
        r.real_y = hit.response.col(o);
        records.push_back(r);
      }
    }
  }
  return records;
}

}  // namespace stagefit::measurement
