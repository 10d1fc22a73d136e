#pragma once
// Helpers shared by the subcommands: model loading, JSON reports.

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "command.h"
#include "stagefit/compare/residuals.h"
#include "stagefit/diagnose/diagnose.h"
#include "stagefit/model/model_spec.h"

namespace stagefit::cli {

/// The model of --model (or the embedded default), with every --with effect applied in order.
model::ModelSpec LoadModelFromOptions(const CommonOptions& options);

/// "<embedded micro-station>" or the --model path, for messages.
std::string ModelSource(const CommonOptions& options);

/// The measurement of a command: `--geometry FILE.csv` (when given) over the file's own geometry; a UFF
/// file's node coordinates (datasets 15 / 2411) put its channels on the body of `spec`'s compliance frame;
/// `averages` (`--averages`, 0: the file's) is MeasurementReadOptions::averages.
measurement::FrfData ReadMeasurementFor(const std::string& path, const std::string& geometry, int averages,
                                        const model::ModelSpec& spec);

/// Faults of the test bench first (docs/diagnose.md, "Test bench first"): measurement::CheckChannels on
/// `data`, the findings printed with what to do; certain ones (a reversed channel, a swapped pair)
/// repaired in `data`, the other faulty channels left out of it. Returns the findings as the reports'
/// "channel_faults" array (empty when the channels are sound); `non_rigid`, when given, gets the reports'
/// "non_rigid" array: channels that do not move as one rigid body where no single channel is at fault
/// (measurement::NonRigidBand; nothing is left out for them).
nlohmann::json CheckTestBench(measurement::FrfData* data, nlohmann::json* non_rigid = nullptr);

/// The non-empty items of a comma-separated list ("payload,extra-body").
std::vector<std::string> SplitCommaList(const std::string& text);

/// `data` without the channels of `--exclude-channels A,B` (comma-separated output or input names; empty:
/// unchanged). Throws InputError naming an unknown channel (exit 2).
measurement::FrfData ExcludeChannelsOption(const measurement::FrfData& data, const std::string& list);
inline constexpr const char* kExcludeChannelsHelp =
    "leave these channels out (comma-separated sensor or impact names, e.g. a2z,h3): a faulty channel that "
    "diagnose's channel checks named";

/// Help text of the shared --geometry option.
inline constexpr const char* kGeometryHelp =
    "geometry CSV of the measurement's channels (kind,name,body,x,y,z,nx,ny,nz), over the file's own; default: "
    "<stem>.geometry.csv beside a .uff or .mat file, else the file's (UFF: node coordinates of datasets 15/2411)";

/// Help text of the shared --averages option.
inline constexpr const char* kAveragesHelp =
    "the number of hits averaged for each input, when the file's coherence is their ordinary coherence and the "
    "file does not say how many (a UFF file, data from a modal-test system); the noise floor and the weights "
    "depend on it (docs/error-metric.md §8). Default: the file's num_averages (written by estimate), else the "
    "coherence is taken as that of the FRF estimate itself";

/// The comparison space of `--space VALUE`, or when VALUE is empty the one the measurement's geometry
/// calls for (compare::ChooseDefaultSpace), printed with its reason.
compare::ComparisonSpace ResolveComparisonSpace(const std::string& value, const measurement::FrfData& data);

/// {"floor", "sd", "error_over_floor"} of compare::Comparison::CalcNoiseFloor() for `error`; null when
/// the measurement has no coherence (the floor is unknown).
nlohmann::json NoiseFloorJson(double error, const compare::NoiseFloor& floor);

/// The raw channels' errors (diagnose::WorstChannels) as the reports' "channels" array: channel, kind
/// ("output" or "input"), error, times_floor (null without a floor), times_median.
nlohmann::json ChannelErrorsJson(const std::vector<diagnose::ChannelError>& channels);

/// Writes `report` as indented JSON, atomically, refusing to overwrite any of `inputs`.
void WriteReport(const std::string& path, const nlohmann::json& report, const std::vector<std::string>& inputs);

}  // namespace stagefit::cli
