#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>

#include <nlohmann/json.hpp>

#include "command.h"
#include "report.h"
#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"
#include "stagefit/measurement/csv_file.h"
#include "stagefit/measurement/measurement_file.h"
#include "stagefit/model/assembled_model.h"
#include "stagefit/model/linear_system.h"
#include "stagefit/response/frf_evaluator.h"
#include "stagefit/response/io_sets.h"

namespace stagefit::cli {
namespace {

struct FrfOptions {
  CommonOptions common;
  std::string out;
  std::string io = "compliance";
  std::string quantity;
  std::string method = "auto";
  std::string measurement;
  std::string geometry;
  double fmin_hz = 1.0;
  double fmax_hz = 2000.0;
  int points = 500;
};

// A channel's geometry for the sidecar; `body` empty when unknown (frame and CoM outputs).
struct Geometry {
  std::string body;
  Eigen::Vector3d position_W = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction_W = Eigen::Vector3d::Zero();
};

std::string Number(double value) {
  char text[40];
  std::snprintf(text, sizeof text, "%.17g", value);
  return text;
}

// SPEC §3 long-format CSV and its "<stem>.geometry.csv" sidecar, each written atomically.
void WriteFrfCsv(const std::filesystem::path& path, const response::FrfArray& h,
                 const std::vector<Geometry>& outputs, const std::vector<Geometry>& inputs) {
  std::ostringstream csv;
  csv << "freq_hz,output,input,re,im\n";  // header first; quantity and units in the .meta.json sidecar
  for (int o = 0; o < h.num_outputs(); ++o) {
    for (int i = 0; i < h.num_inputs(); ++i) {
      for (int f = 0; f < h.num_frequencies(); ++f) {
        const std::complex<double> v = h(f, o, i);
        csv << Number(h.frequency_hz(f)) << ',' << h.output_names[o] << ',' << h.input_names[i] << ','
            << Number(v.real()) << ',' << Number(v.imag()) << '\n';
      }
    }
  }
  std::ostringstream geometry;
  geometry << "kind,name,body,x,y,z,nx,ny,nz\n";
  auto row = [&geometry](const char* kind, const std::string& name, const Geometry& g) {
    geometry << kind << ',' << name << ',' << g.body;
    if (g.body.empty()) {
      geometry << ",,,,,,\n";
      return;
    }
    for (int k = 0; k < 3; ++k) geometry << ',' << Number(g.position_W(k));
    for (int k = 0; k < 3; ++k) geometry << ',' << Number(g.direction_W(k));
    geometry << '\n';
  };
  for (int o = 0; o < h.num_outputs(); ++o) row("sensor", h.output_names[o], outputs[o]);
  for (int i = 0; i < h.num_inputs(); ++i) row("impact", h.input_names[i], inputs[i]);
  std::filesystem::path sidecar = path;
  sidecar.replace_extension();
  sidecar += ".geometry.csv";
  WriteFileAtomically(path, csv.str());
  WriteFileAtomically(sidecar, geometry.str());
  const auto quantity = measurement::ParseFrfQuantity(response::ToString(h.quantity));
  WriteCsvMeta(path, measurement::FrfCsvMeta(quantity.value_or(measurement::FrfQuantity::kAccelerance)));
}

// A measurement channel as a model input or output: its own geometry, or a model sensor/excitation
// of the same name.
const model::PointSpec* FindPoint(const std::vector<model::PointSpec>& points, const std::string& name) {
  for (const auto& p : points) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

Geometry ChannelGeometry(const measurement::ChannelGeometry& channel, const std::vector<model::PointSpec>& points,
                         const std::string& file, const char* kind) {
  Geometry g;
  if (channel.has_geometry()) {
    g.body = channel.body;
    g.position_W = channel.position_W;
    g.direction_W = channel.direction_W;
    return g;
  }
  const model::PointSpec* p = FindPoint(points, channel.name);
  if (!p) {
    throw InputError(file + ": " + kind + " '" + channel.name +
                     "' has no geometry and the model has no " + kind + " of that name; expected body, "
                     "position and direction in the file");
  }
  g.body = p->body;
  g.position_W = p->position_W;
  g.direction_W = p->direction_W;
  return g;
}

}  // namespace

void RegisterFrfCommand(CLI::App& app) {
  auto* command = app.add_subcommand(
      "frf", "model FRFs or compliance at chosen frequencies to CSV (SPEC §3 long format + geometry sidecar)");
  auto o = std::make_shared<FrfOptions>();
  AddCommonOptions(*command, o->common);
  AddWithOption(*command, o->common);
  command->add_option("--out", o->out, "output FILE.csv (a FILE.geometry.csv sidecar is written beside it)")
      ->required();
  command->add_option("--io", o->io,
                      "inputs/outputs: compliance (wrench at {X} -> motion of {X}), raw (hammer impacts -> "
                      "accelerometers), stages (3 hammer forces on ty -> every body's CoM motion), "
                      "disturbance (ground motion and joint forces in ty and rz -> {X} relative to the granite)")
      ->check(CLI::IsMember({"compliance", "raw", "stages", "disturbance"}));
  command->add_option("--quantity", o->quantity,
                      "accelerance | mobility | receptance (default: accelerance, or the measurement's)")
      ->check(CLI::IsMember({"accelerance", "mobility", "receptance", "compliance"}));
  command->add_option("--fmin", o->fmin_hz, "lowest frequency, Hz (log spacing)")->check(CLI::PositiveNumber);
  command->add_option("--fmax", o->fmax_hz, "highest frequency, Hz")->check(CLI::PositiveNumber);
  command->add_option("--points", o->points, "number of frequencies")->check(CLI::Range(1, 10000000));
  command->add_option("--method", o->method, "evaluation path: auto | modal | direct")
      ->check(CLI::IsMember({"auto", "modal", "direct"}));
  command->add_option("--geometry", o->geometry, kGeometryHelp);
  command->add_option("--measurement", o->measurement,
                      "evaluate at this measurement's frequencies, for its channels (sensors and impacts)");
  command->callback([o] {
    if (o->fmax_hz < o->fmin_hz) throw UsageError("--fmax must not be below --fmin");
    if (std::filesystem::path(o->out).extension() != ".csv") {
      throw UsageError("--out '" + o->out + "': expected a file name ending in .csv");
    }
    model::ModelSpec spec = LoadModelFromOptions(o->common);
    const auto assembled = model::AssembledModel::Assemble(spec, ModelSource(o->common));

    model::SecondOrderSystem system;
    std::vector<Geometry> output_geometry, input_geometry;
    Eigen::VectorXd frequency_hz;
    response::ResponseQuantity quantity = response::ResponseQuantity::kAccelerance;
    std::string io_label = o->io;
    if (!o->measurement.empty()) {
      const measurement::FrfData data = ReadMeasurementFor(o->measurement, o->geometry, 0, spec);
      std::vector<model::InputSpec> inputs;
      std::vector<model::OutputSpec> outputs;
      for (const auto& channel : data.outputs) {
        Geometry g = ChannelGeometry(channel, spec.sensors, o->measurement, "sensor");
        outputs.push_back(model::SensorOutput(channel.name, g.body, g.position_W, g.direction_W));
        output_geometry.push_back(g);
      }
      for (const auto& channel : data.inputs) {
        Geometry g = ChannelGeometry(channel, spec.excitations, o->measurement, "impact");
        inputs.push_back(model::ForceInput(channel.name, g.body, g.position_W, g.direction_W));
        input_geometry.push_back(g);
      }
      system = model::BuildSystem(assembled, inputs, outputs);
      frequency_hz = data.frequency_hz;
      quantity = response::ParseResponseQuantity(measurement::ToString(data.quantity), o->measurement);
      io_label = "measurement channels";
    } else {
      system = response::BuildIoSetSystem(assembled, response::ParseIoSet(o->io, "--io"));
      frequency_hz.resize(o->points);
      for (int k = 0; k < o->points; ++k) {
        frequency_hz(k) = o->points == 1 ? o->fmin_hz
                                         : o->fmin_hz * std::pow(o->fmax_hz / o->fmin_hz,
                                                                 static_cast<double>(k) / (o->points - 1));
      }
      const bool raw = o->io == "raw";
      for (int i = 0; i < system.num_inputs(); ++i) {
        Geometry g;
        if (raw) {
          const auto& e = spec.excitations[i];
          g = {e.body, e.position_W, e.direction_W};
        }
        input_geometry.push_back(g);
      }
      for (int k = 0; k < system.num_outputs(); ++k) {
        Geometry g;
        if (raw) {
          const auto& s = spec.sensors[k];
          g = {s.body, s.position_W, s.direction_W};
        }
        output_geometry.push_back(g);
      }
    }
    if (!o->quantity.empty()) quantity = response::ParseResponseQuantity(o->quantity, "--quantity");

    response::FrfEvaluatorOptions options;
    options.method = o->method == "modal"    ? response::FrfMethod::kModal
                     : o->method == "direct" ? response::FrfMethod::kDirect
                                             : response::FrfMethod::kAuto;
    auto evaluator = response::FrfEvaluator::Create(system, options);
    const response::FrfArray h = evaluator.Evaluate(frequency_hz, quantity);

    std::vector<std::filesystem::path> protected_inputs;
    if (!o->common.model_path.empty()) protected_inputs.push_back(o->common.model_path);
    if (!o->measurement.empty()) protected_inputs.push_back(o->measurement);
    if (!o->measurement.empty()) protected_inputs.push_back(measurement::GeometrySidecarPath(o->measurement));
    CheckNotAnInput(o->out, protected_inputs);
    CheckNotAnInput(std::filesystem::path(o->out).replace_extension().string() + ".geometry.csv", protected_inputs);
    WriteFrfCsv(o->out, h, output_geometry, input_geometry);

    std::printf("FRF: %d outputs x %d inputs (%s), %d frequencies, %s\n", h.num_outputs(), h.num_inputs(),
                io_label.c_str(), h.num_frequencies(), response::ToString(quantity).c_str());
    std::printf("path: %s\n", evaluator.setup_summary().message.c_str());
    std::printf("wrote %s\n", o->out.c_str());
    if (!o->common.report_path.empty()) {
      nlohmann::json report;
      report["command"] = "frf";
      report["error"] = nullptr;  // no comparison with a measurement is made here
      report["io"] = io_label;
      report["quantity"] = response::ToString(quantity);
      report["path"] = response::ToString(evaluator.path_used());
      report["path_message"] = evaluator.setup_summary().message;
      report["eigenvector_condition"] = evaluator.setup_summary().condition_number;
      report["num_frequencies"] = h.num_frequencies();
      report["outputs"] = h.output_names;
      report["inputs"] = h.input_names;
      report["out"] = o->out;
      std::vector<std::string> inputs;
      for (const auto& p : protected_inputs) inputs.push_back(p.string());
      inputs.push_back(o->out);
      WriteReport(o->common.report_path, report, inputs);
    }
  });
}

}  // namespace stagefit::cli
