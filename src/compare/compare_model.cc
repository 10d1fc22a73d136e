#include "stagefit/compare/compare_model.h"

#include <cmath>
#include <cstdio>
#include <sstream>
#include <system_error>

#include "stagefit/common/atomic_file.h"
#include "stagefit/common/csv_meta.h"
#include "stagefit/measurement/csv_file.h"
#include "stagefit/common/error.h"
#include "stagefit/common/units.h"

namespace stagefit::compare {
namespace {

std::string Number(double value) {
  if (std::isnan(value)) return "nan";
  char text[40];
  std::snprintf(text, sizeof text, "%.10g", value);
  return text;
}

}  // namespace

CompareSummary CompareModel(const model::ModelSpec& spec, const measurement::FrfData& measurement,
                            const CompareOptions& options) {
  Comparison comparison = Comparison::Create(spec, measurement, options.comparison);
  ComparisonResult result = comparison.Evaluate(spec);
  ModePairing modes = PairModes(comparison, result.model, spec, options.modes);
  CompareSummary summary{std::move(comparison), std::move(result), std::move(modes), {}, {}, {}};
  if (options.also_raw && options.comparison.space == ComparisonSpace::kCompliance) {
    if (!measurement.has_all_geometry()) {
      summary.raw_skipped = "the measurement has no channel geometry";
    } else {
      ComparisonOptions raw_options = options.comparison;
      raw_options.space = ComparisonSpace::kRaw;
      try {
        summary.raw = Comparison::Create(spec, measurement, raw_options);
        summary.raw_result = summary.raw->Evaluate(spec);
      } catch (const InputError& e) {
        summary.raw.reset();
        summary.raw_result.reset();
        summary.raw_skipped = e.what();
      }
    }
  }
  return summary;
}

std::string CompareSummary::BriefReport(int max_rows) const {
  std::ostringstream out;
  out << "space: " << ToString(comparison.space()) << ", " << comparison.num_frequencies() << " frequencies "
      << Number(comparison.frequency_hz()(0)) << " .. "
      << Number(comparison.frequency_hz()(comparison.num_frequencies() - 1)) << " Hz, "
      << comparison.used_elements().size() << " of " << comparison.num_outputs() * comparison.num_inputs()
      << " elements used\n";
  out << result.BriefReport(max_rows);
  if (raw_result) {
    char line[128];
    std::snprintf(line, sizeof line, "raw channels (for reference): error = %.5f over %zu elements\n",
                  raw_result->error, raw_result->elements.size());
    out << line;
  }
  out << modes.BriefReport();
  return out.str();
}

std::string FormatFrfTable(const Comparison& comparison, const ComparisonResult& result) {
  std::ostringstream out;
  out << "freq_hz,element,output,input,meas_re,meas_im,model_re,model_im,meas_abs,model_abs,"
         "meas_phase_deg,model_phase_deg,weight\n";
  for (const auto& idx : comparison.used_elements()) {
    const std::string name = comparison.ElementName(idx);
    for (int k = 0; k < comparison.num_frequencies(); ++k) {
      const std::complex<double> a = result.measured[k](idx.output, idx.input);
      const std::complex<double> b = result.model[k](idx.output, idx.input);
      out << Number(comparison.frequency_hz()(k)) << ',' << name << ',' << comparison.output_names()[idx.output]
          << ',' << comparison.input_names()[idx.input] << ',' << Number(a.real()) << ',' << Number(a.imag())
          << ',' << Number(b.real()) << ',' << Number(b.imag()) << ',' << Number(std::abs(a)) << ','
          << Number(std::abs(b)) << ',' << Number(std::arg(a) * kDegreesPerRadian) << ','
          << Number(std::arg(b) * kDegreesPerRadian) << ',' << Number(comparison.weights()[k](idx.output, idx.input))
          << '\n';
    }
  }
  return out.str();
}

std::string FormatElementTable(const ComparisonResult& result, const Comparison& comparison) {
  std::ostringstream out;
  out << "element,output,input,kappa,points,error,share,mean_ln_ratio,mean_phase_deg\n";
  for (const auto& el : result.elements) {
    out << el.name << ',' << comparison.output_names()[el.index.output] << ','
        << comparison.input_names()[el.index.input] << ',' << Number(el.significance) << ',' << el.num_points
        << ',' << Number(el.error) << ',' << Number(el.share) << ',' << Number(el.mean_log_magnitude) << ','
        << Number(el.mean_phase_rad * kDegreesPerRadian) << '\n';
  }
  return out.str();
}

std::string FormatBandTable(const ComparisonResult& result) {
  std::ostringstream out;
  out << "band_low_hz,band_high_hz,band_centre_hz,points,error,share\n";
  for (const auto& b : result.bands) {
    out << Number(b.band.low_hz) << ',' << Number(b.band.high_hz) << ',' << Number(b.band.centre_hz()) << ','
        << b.num_points << ',' << Number(b.error) << ',' << Number(b.share) << '\n';
  }
  return out.str();
}

std::string FormatElementBandTable(const ComparisonResult& result) {
  std::ostringstream out;
  out << "element_index,band_index,element,band_centre_hz,error\n";
  for (size_t e = 0; e < result.elements.size(); ++e) {
    for (size_t b = 0; b < result.bands.size(); ++b) {
      out << e << ',' << b << ',' << result.elements[e].name << ',' << Number(result.bands[b].band.centre_hz())
          << ',' << Number(result.element_band_error(e, b)) << '\n';
    }
  }
  return out.str();
}

std::string FormatModeTable(const ModePairing& pairing) {
  std::ostringstream out;
  out << "kind,measured,model,f_meas_hz,f_model_hz,df_percent,zeta_meas,zeta_model,mac,model_mode,model_mode_hz,"
         "dominant_dof\n";
  for (const auto& p : pairing.pairs) {
    const auto& a = pairing.measured[p.measured];
    const auto& b = pairing.model[p.model];
    out << "pair," << p.measured << ',' << p.model << ',' << Number(a.frequency_hz) << ',' << Number(b.frequency_hz)
        << ',' << Number(100 * p.frequency_error) << ',' << Number(a.damping_ratio) << ','
        << Number(b.damping_ratio) << ',' << Number(p.mac) << ',' << b.model_mode + 1 << ','
        << Number(b.model_frequency_hz) << ',' << b.dominant_dof << '\n';
  }
  for (int a : pairing.unpaired_measured) {
    const auto& m = pairing.measured[a];
    out << "measured_only," << a << ",," << Number(m.frequency_hz) << ",,," << Number(m.damping_ratio)
        << ",,,,,\n";
  }
  for (int b : pairing.unpaired_model) {
    const auto& m = pairing.model[b];
    out << "model_only,," << b << ",," << Number(m.frequency_hz) << ",,," << Number(m.damping_ratio) << ",,"
        << m.model_mode + 1 << ',' << Number(m.model_frequency_hz) << ',' << m.dominant_dof << '\n';
  }
  return out.str();
}

std::vector<std::filesystem::path> WriteCompareTables(const std::filesystem::path& dir,
                                                      const CompareSummary& summary,
                                                      const std::vector<std::filesystem::path>& inputs) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir)) {
    throw InputError("--out-dir '" + dir.string() + "': cannot create the directory (" + ec.message() + ")");
  }
  std::vector<std::pair<std::string, std::string>> files = {
      {"compare_frf.csv", FormatFrfTable(summary.comparison, summary.result)},
      {"compare_elements.csv", FormatElementTable(summary.result, summary.comparison)},
      {"compare_bands.csv", FormatBandTable(summary.result)},
      {"compare_element_band.csv", FormatElementBandTable(summary.result)},
      {"compare_modes.csv", FormatModeTable(summary.modes)},
  };
  if (summary.raw && summary.raw_result) {
    files.push_back({"compare_frf_raw.csv", FormatFrfTable(*summary.raw, *summary.raw_result)});
    files.push_back({"compare_elements_raw.csv", FormatElementTable(*summary.raw_result, *summary.raw)});
  }
  // Units and notes of each table in its "<stem>.meta.json" sidecar (docs/csv-outputs.md).
  const std::string q = measurement::ToString(summary.comparison.quantity());
  const std::string frf_unit = measurement::FrfCsvMeta(summary.comparison.quantity()).units[3].second;
  auto meta_of = [&](const std::string& name) {
    CsvMeta meta;
    meta.fields["quantity"] = q;
    meta.fields["space"] = ToString(summary.comparison.space());
    if (name.rfind("compare_frf", 0) == 0) {
      meta.units = {{"freq_hz", "Hz"},       {"meas_re", frf_unit},  {"meas_im", frf_unit},  {"model_re", frf_unit},
                    {"model_im", frf_unit},  {"meas_abs", frf_unit}, {"model_abs", frf_unit}, {"meas_phase_deg", "deg"},
                    {"model_phase_deg", "deg"}, {"weight", "1"}};
      meta.notes = {"FRF values in the comparison quantity, SI: " + frf_unit +
                    " for a translation over a force; rad for rotations, Nm for torques"};
    } else if (name.rfind("compare_elements", 0) == 0) {
      meta.units = {{"kappa", "1"}, {"error", "1"}, {"share", "1"}, {"mean_ln_ratio", "1"}, {"mean_phase_deg", "deg"}};
    } else if (name == "compare_bands.csv") {
      meta.units = {{"band_low_hz", "Hz"}, {"band_high_hz", "Hz"}, {"band_centre_hz", "Hz"}, {"error", "1"}, {"share", "1"}};
    } else if (name == "compare_element_band.csv") {
      meta.units = {{"band_centre_hz", "Hz"}, {"error", "1"}};
    } else {
      meta.units = {{"f_meas_hz", "Hz"}, {"f_model_hz", "Hz"}, {"df_percent", "%"}, {"zeta_meas", "1"},
                    {"zeta_model", "1"}, {"mac", "1"}, {"model_mode_hz", "Hz"}};
    }
    return meta;
  };
  std::vector<std::filesystem::path> written;
  for (const auto& [name, content] : files) {
    const std::filesystem::path path = dir / name;
    CheckNotAnInput(path, inputs);
    CheckNotAnInput(CsvMetaPath(path), inputs);
    WriteFileAtomically(path, content);
    WriteCsvMeta(path, meta_of(name));
    written.push_back(path);
  }
  return written;
}

}  // namespace stagefit::compare
