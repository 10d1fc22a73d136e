#include "report.h"

#include "stagefit/measurement/measurement_file.h"
#include "stagefit/measurement/channel_checks.h"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"
#include "stagefit/model/effects.h"
#include "stagefit/model/model_file.h"

namespace stagefit::cli {

model::ModelSpec LoadModelFromOptions(const CommonOptions& options) {
  model::ModelSpec spec = model::LoadModel(options.model_path);
  for (const auto& text : options.with_effects) model::ApplyEffect(spec, model::ParseEffect(text, spec));
  if (!options.with_effects.empty()) model::CheckModel(spec, ModelSource(options) + " with --with effects");
  return spec;
}

std::string ModelSource(const CommonOptions& options) {
  return options.model_path.empty() ? "<embedded micro-station>" : options.model_path;
}

measurement::FrfData ExcludeChannelsOption(const measurement::FrfData& data, const std::string& list) {
  std::vector<std::string> names;
  std::string item;
  for (char c : list + ",") {
    if (c == ',') {
      while (!item.empty() && item.back() == ' ') item.pop_back();
      const auto start = item.find_first_not_of(' ');
      if (start != std::string::npos) names.push_back(item.substr(start));
      item.clear();
    } else {
      item += c;
    }
  }
  if (names.empty()) return data;
  return measurement::ExcludeChannels(data, names);
}

measurement::FrfData ReadMeasurementFor(const std::string& path, const std::string& geometry, int averages,
                                        const model::ModelSpec& spec) {
  measurement::MeasurementReadOptions options;
  options.geometry = geometry;
  options.averages = averages;
  const int frame = model::FindFrame(spec, spec.compliance_frame);
  if (frame >= 0) options.uff.node_body = spec.frames[frame].body;
  return measurement::ReadMeasurement(path, options);
}

nlohmann::json CheckTestBench(measurement::FrfData* data, nlohmann::json* non_rigid) {
  const measurement::ChannelCheckResult checks = measurement::CheckChannels(*data, Eigen::Vector3d::Zero());
  std::printf("%s", checks.Report().c_str());
  if (non_rigid) {
    *non_rigid = nlohmann::json::array();
    for (const auto& n : checks.non_rigid) {
      non_rigid->push_back({{"side", n.is_input ? "impact" : "sensor"}, {"low_hz", n.low_hz}, {"high_hz", n.high_hz},
                            {"excess", n.excess}, {"channels", n.channels}});
    }
  }
  nlohmann::json channel_faults = nlohmann::json::array();
  for (const auto& f : checks.findings) {
    channel_faults.push_back(
        {{"kind", measurement::ToString(f.kind)}, {"side", f.is_input ? "impact" : "sensor"},
         {"channels", f.channels}, {"alternatives", f.alternatives}, {"low_hz", f.low_hz}, {"high_hz", f.high_hz},
         {"peak_hz", f.kind == measurement::ChannelFaultKind::kLocalResonance ? nlohmann::json(f.peak_hz) : nlohmann::json(nullptr)},
         {"evidence", f.evidence}, {"action", f.action}, {"repaired", f.repairable}});
  }
  if (checks.findings.empty()) return channel_faults;
  *data = measurement::RepairChannels(*data, checks.findings);
  const std::vector<std::string> left_out = measurement::ChannelsToExclude(checks.findings);
  if (!left_out.empty()) *data = measurement::ExcludeChannels(*data, left_out);
  std::string text;
  for (const auto& f : checks.findings) {
    if (f.repairable) text += (text.empty() ? "" : ", ") + std::string("repaired ") + f.channels[0];
  }
  for (const auto& n : left_out) text += (text.empty() ? "" : ", ") + std::string("left out ") + n;
  std::printf("the model search runs on the sound channels (%s); fix the test bench, or pass "
              "--exclude-channels to compare and fit as well\n",
              text.c_str());
  return channel_faults;
}

std::vector<std::string> SplitCommaList(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream s(text);
  for (std::string item; std::getline(s, item, ',');) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

compare::ComparisonSpace ResolveComparisonSpace(const std::string& value, const measurement::FrfData& data) {
  if (!value.empty()) return compare::ParseComparisonSpace(value, "--space");
  const compare::DefaultSpace choice = compare::ChooseDefaultSpace(data);
  std::printf("comparison space: %s (%s; --space to choose)\n", compare::ToString(choice.space).c_str(), choice.reason.c_str());
  return choice.space;
}

nlohmann::json NoiseFloorJson(double error, const compare::NoiseFloor& floor) {
  if (!floor.known) return nullptr;
  return {{"floor", floor.floor},
          {"sd", floor.sd},
          {"error_over_floor", floor.floor > 0.0 ? nlohmann::json(error / floor.floor) : nlohmann::json(nullptr)}};
}

nlohmann::json ChannelErrorsJson(const std::vector<diagnose::ChannelError>& channels) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& c : channels) {
    out.push_back({{"channel", c.name},
                   {"kind", c.is_input ? "input" : "output"},
                   {"error", c.error},
                   {"times_floor", std::isfinite(c.times_floor) ? nlohmann::json(c.times_floor) : nlohmann::json(nullptr)},
                   {"times_median", c.times_median}});
  }
  return out;
}

void WriteReport(const std::string& path, const nlohmann::json& report, const std::vector<std::string>& inputs) {
  std::vector<std::filesystem::path> input_paths(inputs.begin(), inputs.end());
  CheckNotAnInput(path, input_paths);
  // Text that is not UTF-8 (a file name, say) is written as U+FFFD rather than failing the run.
  WriteFileAtomically(path, report.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
}

}  // namespace stagefit::cli
