// `stagefit disturbance`: PSDs of disturbance records, synthesised time signals with a given PSD,
// force PSDs from a motion PSD and a sensitivity. Record layouts: docs/disturbances.md.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <random>

#include <nlohmann/json.hpp>

#include "command.h"
#include "report.h"
#include "stagefit/common/atomic_file.h"
#include "stagefit/common/error.h"
#include "stagefit/common/units.h"
#include "stagefit/disturbance/force_psd.h"
#include "stagefit/disturbance/geophone.h"
#include "stagefit/disturbance/record_io.h"
#include "stagefit/disturbance/sensitivity.h"
#include "stagefit/disturbance/spectral_density.h"
#include "stagefit/disturbance/spindle_error.h"
#include "stagefit/disturbance/straightness.h"
#include "stagefit/disturbance/synthesis.h"

namespace stagefit::cli {
namespace {

namespace sd = stagefit::disturbance;

std::string FormatNumber(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%g", value);
  return buffer;
}

struct WelchFlags {
  std::string resolution;
  std::string window = "hann";
  double overlap = 0.5;
  std::string detrend = "mean";
};

void AddWelchOptions(CLI::App* command, WelchFlags& w) {
  command->add_option("--resolution", w.resolution,
                      "frequency resolution (e.g. \"0.1 Hz\"; bare = Hz, or 1/m for a spatial PSD); "
                      "default: 8 averaged segments");
  command->add_option("--window", w.window, "hann (default), hamming, blackman-harris, flat-top, rectangular");
  command->add_option("--overlap", w.overlap, "segment overlap fraction, 0 <= overlap < 1 (default 0.5)");
  command->add_option("--detrend", w.detrend, "per segment: none, mean (default) or linear");
}

sd::WelchOptions ToWelch(const WelchFlags& w, bool spatial) {
  sd::WelchOptions o;
  if (!w.resolution.empty()) {
    o.resolution_hz = spatial ? ParseQuantity(w.resolution, Dimension{0, -2, 0, 0}, "--resolution")
                              : ParseQuantity(w.resolution, dim::kFrequency, "--resolution");
  }
  o.window = sd::ParseWindow(w.window, "--window");
  o.overlap = w.overlap;
  o.detrend = sd::ParseDetrend(w.detrend, "--detrend");
  return o;
}

sd::CsvTable SpectrumTable(const std::string& frequency_column, const Eigen::VectorXd& frequency,
                           const std::vector<std::string>& names, const std::vector<std::string>& units,
                           const std::vector<Eigen::VectorXd>& columns) {
  sd::CsvTable t;
  t.column_names.push_back(frequency_column);
  t.units.push_back(frequency_column == "frequency_hz" ? "Hz" : "1/m");
  t.values.resize(frequency.size(), static_cast<Eigen::Index>(columns.size() + 1));
  t.values.col(0) = frequency;
  for (size_t c = 0; c < columns.size(); ++c) {
    t.column_names.push_back(names[c]);
    t.units.push_back(units[c]);
    t.values.col(static_cast<Eigen::Index>(c + 1)) = columns[c];
  }
  return t;
}

void AddSpectrumComments(sd::CsvTable& t, const std::string& what, const sd::Spectrum& s,
                         const sd::WelchOptions& w) {
  t.comments.push_back("stagefit disturbance psd: " + what);
  char line[200];
  std::snprintf(line, sizeof(line),
                "one-sided PSD; Welch: window %s, segment %d samples, overlap %.3g, detrend %s, "
                "%d averages, %.4g degrees of freedom, resolution %.6g",
                std::string(sd::WindowName(w.window)).c_str(), s.segment_length, w.overlap,
                std::string(sd::DetrendName(w.detrend)).c_str(), s.averages, s.degrees_of_freedom,
                s.resolution_hz);
  t.comments.push_back(line);
}

nlohmann::json SpectrumJson(const sd::Spectrum& s) {
  return {{"segment_length", s.segment_length}, {"averages", s.averages},
          {"resolution", s.resolution_hz},      {"degrees_of_freedom", s.degrees_of_freedom},
          {"sample_rate", s.sample_rate_hz}};
}

std::vector<std::string> DataColumns(const sd::CsvTable& t, const std::string& first) {
  if (t.column_names.empty() || t.column_names[0] != first) {
    throw InputError(t.source + ": first column is '" + (t.column_names.empty() ? "" : t.column_names[0]) +
                     "', expected '" + first + "'");
  }
  std::vector<std::string> names(t.column_names.begin() + 1, t.column_names.end());
  if (names.empty()) throw InputError(t.source + ": no data column after '" + first + "'");
  return names;
}

struct PsdFlags {
  std::string record, kind = "raw", out, report, geophone = "L-4C", speed, residuals;
  double gain = 1.0;
  std::string z1 = "0", z2 = "0.1", z_ref = "0.1";
  bool keep_axial_once_per_rev = false;
  WelchFlags welch;
};

sd::SpindleGeometry ParseGeometry(const std::string& z1, const std::string& z2, const std::string& zr) {
  return {ParseQuantity(z1, dim::kLength, "--z1"), ParseQuantity(z2, dim::kLength, "--z2"),
          ParseQuantity(zr, dim::kLength, "--z-ref")};
}

void RunPsd(const PsdFlags& f) {
  CheckNotAnInput(f.out, {f.record});
  if (!f.report.empty()) CheckNotAnInput(f.report, {f.record});
  const sd::CsvTable table = sd::ReadCsvTable(f.record);
  nlohmann::json report = {{"record", f.record}, {"kind", f.kind}};
  sd::CsvTable out;
  if (f.kind == "raw" || f.kind == "ground-geophone") {
    const bool ground = f.kind == "ground-geophone";
    const double rate = sd::CalcSampleRate(table, "time_s");
    const sd::WelchOptions welch = ToWelch(f.welch, false);
    sd::GeophoneModel geophone;
    if (ground) {
      geophone = sd::GeophoneByName(f.geophone, "--geophone");
      geophone.amplifier_gain = f.gain;
      sd::ValidateGeophone(geophone, "--gain");
    }
    std::vector<std::string> names = DataColumns(table, "time_s"), units;
    std::vector<Eigen::VectorXd> columns;
    sd::Spectrum first;
    for (const std::string& name : names) {
      if (ground) sd::CheckColumnUnit(table, name, "V");
      sd::Spectrum s = sd::EstimatePsd(table.Column(name), rate, welch, table.source, name);
      const int c = table.FindColumn(name);
      units.push_back(ground ? "m^2/Hz" : (table.units[c].empty() ? "U" : table.units[c]) + "^2/Hz");
      if (ground) s = sd::CalcGroundDisplacementPsd(s, geophone);
      first = s;
      columns.push_back(s.psd);
      const double rms = std::sqrt(sd::IntegratePsd(s, 0.0, rate));
      std::printf("%s: rms %.4g %s (%d averages, resolution %.4g Hz)\n", name.c_str(), rms,
                  ground ? "m" : "U", s.averages, s.resolution_hz);
      report["channels"][name] = {{"rms", rms}};
    }
    out = SpectrumTable("frequency_hz", first.frequency_hz, names, units, columns);
    AddSpectrumComments(out, ground ? "ground displacement from " + geophone.name + " geophone voltage (gain " +
                                          FormatNumber(f.gain) + ") of " + f.record
                                    : "raw channels of " + f.record,
                        first, welch);
    report["welch"] = SpectrumJson(first);
  } else if (f.kind == "straightness") {
    const std::vector<std::string> names = DataColumns(table, "position_m");
    sd::StraightnessOptions options;
    if (!f.speed.empty()) options.scan_speed_m_s = ParseQuantity(f.speed, dim::kVelocity, "--speed");
    options.welch = ToWelch(f.welch, options.scan_speed_m_s == 0.0);
    std::vector<Eigen::VectorXd> columns;
    std::vector<std::string> units;
    sd::StraightnessSummary last;
    for (const std::string& name : names) {
      sd::CheckColumnUnit(table, name, "m");
      last = sd::AnalyseStraightness(table.Column("position_m"), table.Column(name), options,
                                     table.source, name);
      std::printf("%s: %s\n", name.c_str(), last.BriefReport().c_str());
      columns.push_back(last.psd.psd);
      units.push_back(last.temporal ? "m^2/Hz" : "m^2/(1/m)");
      report["channels"][name] = {{"offset_m", last.offset_m},
                                  {"tilt_rad", last.slope_rad},
                                  {"residual_rms_m", last.residual_rms_m},
                                  {"residual_peak_to_peak_m", last.residual_peak_to_peak_m}};
    }
    out = SpectrumTable(last.temporal ? "frequency_hz" : "spatial_frequency_per_m",
                        last.psd.frequency_hz, names, units, columns);
    AddSpectrumComments(out, "straightness of " + f.record + " (best line removed)", last.psd,
                        options.welch);
    report["welch"] = SpectrumJson(last.psd);
  } else if (f.kind == "spindle") {
    sd::SpindleRecord record;
    record.sample_rate_hz = sd::CalcSampleRate(table, "time_s");
    record.sensors_m.resize(table.values.rows(), 5);
    for (int c = 0; c < 5; ++c) {
      sd::CheckColumnUnit(table, sd::kSpindleSensorNames[c], "m");
      record.sensors_m.col(c) = table.Column(sd::kSpindleSensorNames[c]);
    }
    if (table.FindColumn("angle_rad") >= 0) record.angle_rad = table.Column("angle_rad");
    sd::SpindleOptions options;
    options.geometry = ParseGeometry(f.z1, f.z2, f.z_ref);
    if (!f.speed.empty()) {
      options.rotation_speed_rad_s = ParseQuantity(f.speed, dim::kAngularVelocity, "--speed");
    }
    options.remove_axial_once_per_rev = !f.keep_axial_once_per_rev;
    options.welch = ToWelch(f.welch, false);
    const sd::SpindleErrorSummary s = sd::AnalyseSpindleError(record, options, table.source);
    std::printf("%s\n", s.BriefReport().c_str());
    std::vector<std::string> names, units;
    std::vector<Eigen::VectorXd> columns;
    for (int c = 0; c < 5; ++c) {
      names.push_back(sd::kSpindleMotionNames[c]);
      units.push_back(c < 3 ? "m^2/Hz" : "rad^2/Hz");
      columns.push_back(s.psd[c].psd);
      report["channels"][names.back()] = {{"rms", s.rms[c]}, {"peak_to_peak", s.peak_to_peak[c]}};
    }
    for (int k = 0; k < 2; ++k) {
      report["eccentricity"].push_back({{"amplitude_m", s.eccentricity[k].amplitude_m},
                                        {"phase_rad", s.eccentricity[k].phase_rad},
                                        {"offset_x_m", s.eccentricity[k].offset_x_m},
                                        {"offset_y_m", s.eccentricity[k].offset_y_m}});
    }
    report["axial_once_per_rev"] = {{"amplitude_m", s.axial_amplitude_m}, {"phase_rad", s.axial_phase_rad}};
    report["revolutions"] = s.revolutions;
    out = SpectrumTable("frequency_hz", s.psd[0].frequency_hz, names, units, columns);
    AddSpectrumComments(out, "spindle error motion of " + f.record + " (once-per-revolution fit removed)",
                        s.psd[0], options.welch);
    report["welch"] = SpectrumJson(s.psd[0]);
    if (!f.residuals.empty()) {
      CheckNotAnInput(f.residuals, {f.record});
      sd::CsvTable r;
      r.comments.push_back("spindle residual motions of " + f.record);
      r.column_names = {"time_s", "angle_rad", "Dx", "Dy", "Dz", "Rx", "Ry"};
      r.units = {"s", "rad", "m", "m", "m", "rad", "rad"};
      r.values.resize(s.motion.rows(), 7);
      r.values.col(0) = table.Column("time_s");
      r.values.col(1) = s.angle_rad;
      r.values.rightCols(5) = s.motion;
      sd::WriteCsvTable(f.residuals, r);
    }
  } else {
    throw UsageError("--kind '" + f.kind + "', expected raw, ground-geophone, straightness or spindle");
  }
  sd::WriteCsvTable(f.out, out);
  std::printf("wrote %s\n", f.out.c_str());
  if (!f.report.empty()) WriteReport(f.report, report, {f.record});
}

struct SynthFlags {
  std::string psd, out, report, as = "raw", geophone = "L-4C";
  std::string duration = "10", rate = "1000", speed = "60 rpm";
  uint64_t seed = 1;
  double gain = 1.0;
  std::string scan_from = "-4.5 mm", scan_to = "4.5 mm", tilt = "0", offset = "0";
  int points = 901;
  std::string z1 = "0", z2 = "0.1", z_ref = "0.1";
  std::string ecc1 = "0", phase1 = "0", ecc2 = "0", phase2 = "0", axial = "0", axial_phase = "0";
};

sd::PsdTable PsdColumn(const sd::CsvTable& t, const std::string& frequency_column, const std::string& name) {
  sd::PsdTable p;
  p.frequency_hz = t.Column(frequency_column);
  p.psd = t.Column(name);
  p.name = t.source + ": column '" + name + "'";
  return p;
}

void RunSynth(const SynthFlags& f) {
  CheckNotAnInput(f.out, {f.psd});
  if (!f.report.empty()) CheckNotAnInput(f.report, {f.psd});
  const sd::CsvTable table = sd::ReadCsvTable(f.psd);
  std::mt19937_64 rng(f.seed);
  sd::CsvTable out;
  char line[300];
  std::snprintf(line, sizeof(line), "stagefit disturbance synth --as %s --psd %s --seed %llu",
                f.as.c_str(), f.psd.c_str(), static_cast<unsigned long long>(f.seed));
  out.comments.push_back(line);
  out.comments.push_back("synthetic: random phases, amplitudes sqrt(2 S(f_k) df), one inverse FFT");

  if (f.as == "raw" || f.as == "ground-geophone") {
    const bool ground = f.as == "ground-geophone";
    sd::SynthesisOptions options{ParseQuantity(f.duration, dim::kTime, "--duration"),
                                 ParseQuantity(f.rate, dim::kFrequency, "--rate")};
    const int n = sd::SynthesisSampleCount(options, "--duration/--rate");
    sd::GeophoneModel geophone;
    if (ground) {
      geophone = sd::GeophoneByName(f.geophone, "--geophone");
      geophone.amplifier_gain = f.gain;
      sd::ValidateGeophone(geophone, "--gain");
    }
    // A force PSD from `disturbance force` carries a `reliable` column: it is not a signal, and the
    // bins it flags (sensitivity too small) are left out of the synthesis rather than amplified noise.
    std::vector<std::string> names = DataColumns(table, "frequency_hz");
    const int reliable_column = table.FindColumn("reliable");
    if (reliable_column >= 0) {
      names.erase(std::find(names.begin(), names.end(), "reliable"));
      if (names.empty()) throw InputError(table.source + ": no PSD column besides 'reliable'");
    }
    out.column_names.push_back("time_s");
    out.units.push_back("s");
    out.values.resize(n, static_cast<Eigen::Index>(names.size() + 1));
    out.values.col(0) = Eigen::VectorXd::LinSpaced(n, 0.0, n - 1.0) / options.sample_rate_hz;
    for (size_t c = 0; c < names.size(); ++c) {
      sd::PsdTable target = PsdColumn(table, "frequency_hz", names[c]);
      if (reliable_column >= 0) {
        const Eigen::VectorXd reliable = table.values.col(reliable_column);
        const Eigen::Index dropped = (reliable.array() == 0.0).count();
        target.psd = (reliable.array() == 0.0).select(0.0, target.psd);
        std::printf("%s: %ld bins flagged unreliable set to zero\n", names[c].c_str(), static_cast<long>(dropped));
      }
      std::function<double(double)> gain2;
      if (ground) gain2 = [&](double fr) { return sd::CalcGeophoneDisplacementGain2(geophone, fr); };
      out.values.col(static_cast<Eigen::Index>(c + 1)) = sd::SynthesiseSignal(target, options, rng, gain2);
      out.column_names.push_back(ground ? names[c] + "_voltage" : names[c]);
      // The signal's unit from its PSD's "X^2/Hz".
      const std::string psd_unit = table.units[table.FindColumn(names[c])];
      const size_t squared = psd_unit.find("^2/Hz");
      const bool plain = squared != std::string::npos && squared + 5 == psd_unit.size();
      out.units.push_back(ground ? "V" : plain ? psd_unit.substr(0, squared) : "");
    }
    if (ground) {
      out.comments.push_back("geophone " + geophone.name + " voltage, amplifier gain " + FormatNumber(f.gain) +
                             "; the PSD columns are ground displacement, m^2/Hz");
    }
  } else if (f.as == "straightness") {
    const double from = ParseQuantity(f.scan_from, dim::kLength, "--scan-from");
    const double to = ParseQuantity(f.scan_to, dim::kLength, "--scan-to");
    if (f.points < 8 || !(to > from)) throw UsageError("--points >= 8 and --scan-to > --scan-from are required");
    const double step = (to - from) / (f.points - 1);
    const sd::SynthesisOptions options{f.points * step, 1.0 / step};
    const double tilt = ParseQuantity(f.tilt, dim::kAngle, "--tilt");
    const double offset = ParseQuantity(f.offset, dim::kLength, "--offset");
    const std::vector<std::string> names = DataColumns(table, "spatial_frequency_per_m");
    out.column_names.push_back("position_m");
    out.units.push_back("m");
    out.values.resize(f.points, static_cast<Eigen::Index>(names.size() + 1));
    out.values.col(0) = Eigen::VectorXd::LinSpaced(f.points, from, to);
    for (size_t c = 0; c < names.size(); ++c) {
      const Eigen::VectorXd r =
          sd::SynthesiseSignal(PsdColumn(table, "spatial_frequency_per_m", names[c]), options, rng);
      out.values.col(static_cast<Eigen::Index>(c + 1)) =
          (offset + tilt * out.values.col(0).array()).matrix() + r.head(f.points);
      out.column_names.push_back(names[c]);
      out.units.push_back("m");
    }
    out.comments.push_back("straightness scan: line offset " + f.offset + ", tilt " + f.tilt + " added");
  } else if (f.as == "spindle") {
    sd::SynthesisOptions options{ParseQuantity(f.duration, dim::kTime, "--duration"),
                                 ParseQuantity(f.rate, dim::kFrequency, "--rate")};
    const int n = sd::SynthesisSampleCount(options, "--duration/--rate");
    DataColumns(table, "frequency_hz");
    Eigen::MatrixXd motion = Eigen::MatrixXd::Zero(n, 5);
    for (int c = 0; c < 5; ++c) {
      if (table.FindColumn(sd::kSpindleMotionNames[c]) < 0) continue;
      motion.col(c) = sd::SynthesiseSignal(PsdColumn(table, "frequency_hz", sd::kSpindleMotionNames[c]),
                                           options, rng);
    }
    const double omega = ParseQuantity(f.speed, dim::kAngularVelocity, "--speed");
    const Eigen::VectorXd time = Eigen::VectorXd::LinSpaced(n, 0.0, n - 1.0) / options.sample_rate_hz;
    const Eigen::VectorXd angle = omega * time;
    const std::array<sd::SphereEccentricity, 2> circles = {
        sd::SphereEccentricity{ParseQuantity(f.ecc1, dim::kLength, "--eccentricity1"),
                               ParseQuantity(f.phase1, dim::kAngle, "--phase1"), 0.0, 0.0},
        sd::SphereEccentricity{ParseQuantity(f.ecc2, dim::kLength, "--eccentricity2"),
                               ParseQuantity(f.phase2, dim::kAngle, "--phase2"), 0.0, 0.0}};
    const Eigen::MatrixXd sensors = sd::CalcSpindleSensorSignals(
        motion, angle, ParseGeometry(f.z1, f.z2, f.z_ref), circles, 0.0,
        ParseQuantity(f.axial, dim::kLength, "--axial-once-per-rev"),
        ParseQuantity(f.axial_phase, dim::kAngle, "--axial-phase"));
    out.column_names = {"time_s", "angle_rad", "x1", "y1", "x2", "y2", "z"};
    out.units = {"s", "rad", "m", "m", "m", "m", "m"};
    out.values.resize(n, 7);
    out.values.col(0) = time;
    out.values.col(1) = angle;
    out.values.rightCols(5) = sensors;
    out.comments.push_back("spindle error analyser: spheres at z1 = " + f.z1 + ", z2 = " + f.z2 +
                           ", motions at z_ref = " + f.z_ref + "; speed " + f.speed + "; eccentricity " +
                           f.ecc1 + " at " + f.phase1 + " and " + f.ecc2 + " at " + f.phase2 +
                           "; axial once-per-rev " + f.axial);
  } else {
    throw UsageError("--as '" + f.as + "', expected raw, ground-geophone, straightness or spindle");
  }
  sd::WriteCsvTable(f.out, out);
  std::printf("wrote %s (%ld rows)\n", f.out.c_str(), static_cast<long>(out.values.rows()));
  if (!f.report.empty()) {
    WriteReport(f.report, {{"psd", f.psd}, {"as", f.as}, {"seed", f.seed}, {"rows", out.values.rows()}},
                {f.psd});
  }
}

struct ForceFlags {
  std::string psd, sensitivity, column, out, report;
  double min_relative = 1e-3;
};

void RunForce(const ForceFlags& f) {
  CheckNotAnInput(f.out, {f.psd, f.sensitivity});
  if (!f.report.empty()) CheckNotAnInput(f.report, {f.psd, f.sensitivity});
  const sd::CsvTable motion_table = sd::ReadCsvTable(f.psd);
  const std::vector<std::string> names = DataColumns(motion_table, "frequency_hz");
  const std::string column = f.column.empty() ? names.front() : f.column;
  sd::Spectrum motion;
  motion.frequency_hz = motion_table.Column("frequency_hz");
  motion.psd = motion_table.Column(column);
  const sd::CsvTable h_table = sd::ReadCsvTable(f.sensitivity);
  const Eigen::VectorXd h_frequency = h_table.Column("frequency_hz");
  if (h_frequency.size() != motion.frequency_hz.size() ||
      (h_frequency - motion.frequency_hz).cwiseAbs().maxCoeff() >
          1e-9 * motion.frequency_hz.cwiseAbs().maxCoeff()) {
    throw InputError(h_table.source + ": frequency_hz differs from the frequencies of " + f.psd +
                     ", expected the sensitivity at the PSD's bins");
  }
  // Units: the sensitivity is "A/B" (motion per source unit); the motion PSD must be in A^2/Hz and the
  // source PSD comes out in B^2/Hz. Hand-made sensitivity files without units are taken as m/N.
  const int abs_column = h_table.FindColumn("abs");
  std::string h_unit = abs_column >= 0 ? h_table.units[abs_column] : "";
  if (h_unit.empty()) {
    h_unit = "m/N";
    std::printf("note: %s gives no unit for 'abs'; taking it as m/N\n", f.sensitivity.c_str());
  }
  const size_t slash = h_unit.find('/');
  if (slash == std::string::npos || slash == 0 || slash + 1 == h_unit.size()) {
    throw InputError(h_table.source + ": unit of 'abs' is '" + h_unit +
                     "', expected motion per source unit such as m/N, rad/N or m/m");
  }
  const std::string motion_unit = h_unit.substr(0, slash), source_unit = h_unit.substr(slash + 1);
  const std::string motion_psd_unit = motion_table.units[motion_table.FindColumn(column)];
  if (!motion_psd_unit.empty() && motion_psd_unit != motion_unit + "^2/Hz") {
    throw InputError(motion_table.source + ": column '" + column + "' is in " + motion_psd_unit + ", but " +
                     f.sensitivity + " is in " + h_unit + "; expected a motion PSD in " + motion_unit +
                     "^2/Hz");
  }
  const Eigen::VectorXcd h = h_table.Column("re").cast<std::complex<double>>() +
                             std::complex<double>(0.0, 1.0) * h_table.Column("im").cast<std::complex<double>>();
  sd::ForcePsdOptions options;
  options.min_relative_sensitivity = f.min_relative;
  const sd::ForcePsdSummary s = sd::EstimateForcePsd(motion, h, options, f.sensitivity);
  std::printf("%s\n", s.BriefReport().c_str());
  Eigen::VectorXd reliable(s.reliable.size());
  for (size_t k = 0; k < s.reliable.size(); ++k) reliable[k] = s.reliable[k] ? 1.0 : 0.0;
  const std::string name = column + (source_unit == "N" ? "_force" : "_source");
  sd::CsvTable out = SpectrumTable("frequency_hz", s.force_psd.frequency_hz, {name, "reliable"},
                                   {source_unit + "^2/Hz", ""}, {s.force_psd.psd, reliable});
  out.comments.push_back("stagefit disturbance force: S_F = S_x / |H|^2 from " + f.psd + " and " + f.sensitivity);
  for (Eigen::Index k = 0; k < out.values.rows(); ++k) {
    if (std::isnan(out.values(k, 1))) out.values(k, 1) = 0.0;
  }
  out.comments.push_back("bins where H = 0 are written as 0 with reliable = 0");
  sd::WriteCsvTable(f.out, out);
  std::printf("wrote %s\n", f.out.c_str());
  if (!f.report.empty()) {
    WriteReport(f.report, {{"psd", f.psd}, {"sensitivity", f.sensitivity}, {"warnings", s.warnings}},
                {f.psd, f.sensitivity});
  }
}

struct SensitivityFlags {
  CommonOptions common;
  std::string source = "ty.F.Dz", output = "X_rel.Dz", at, out;
  double fmin = 1, fmax = 1000;
  int points = 500;
};

void RunSensitivity(const SensitivityFlags& f) {
  const model::ModelSpec spec = LoadModelFromOptions(f.common);
  Eigen::VectorXd frequency;
  if (!f.at.empty()) {
    frequency = sd::ReadCsvTable(f.at).Column("frequency_hz");
  } else {
    if (!(f.fmin > 0 && f.fmax > f.fmin && f.points >= 2)) throw UsageError("need 0 < --fmin < --fmax and --points >= 2");
    frequency.resize(f.points);
    for (int k = 0; k < f.points; ++k) frequency(k) = f.fmin * std::pow(f.fmax / f.fmin, double(k) / (f.points - 1));
  }
  if (frequency.size() == 0 || frequency.minCoeff() < 0) {
    throw InputError((f.at.empty() ? std::string("--fmin") : f.at) + ": frequencies must be >= 0 Hz");
  }
  CheckNotAnInput(f.out, {f.at, f.common.model_path});
  if (!f.common.report_path.empty()) CheckNotAnInput(f.common.report_path, {f.at, f.common.model_path});
  const Eigen::VectorXcd h = sd::CalcModelSensitivity(spec, f.source, f.output, frequency);
  const bool rotation = f.output.size() > 2 && f.output.compare(f.output.size() - 2, 1, "R") == 0;
  const bool ground = f.source.rfind("ground.", 0) == 0;
  const std::string unit = std::string(rotation ? "rad" : "m") + (ground ? "/m" : "/N");
  sd::CsvTable out = SpectrumTable("frequency_hz", frequency, {"re", "im", "abs"}, {unit, unit, unit},
                                   {h.real(), h.imag(), h.cwiseAbs()});
  out.comments.push_back("stagefit disturbance sensitivity: receptance from " + f.source + " to " + f.output +
                         " in " + unit);
  sd::WriteCsvTable(f.out, out);
  std::printf("wrote %s: %s -> %s at %d frequencies, |H| from %.3g to %.3g\n", f.out.c_str(), f.source.c_str(),
              f.output.c_str(), static_cast<int>(frequency.size()), h.cwiseAbs().minCoeff(), h.cwiseAbs().maxCoeff());
  if (!f.common.report_path.empty()) {
    WriteReport(f.common.report_path,
                {{"source", f.source}, {"output", f.output}, {"unit", unit}, {"frequencies", frequency.size()},
                 {"abs_min", h.cwiseAbs().minCoeff()}, {"abs_max", h.cwiseAbs().maxCoeff()}, {"out", f.out}},
                {f.at, f.common.model_path});
  }
}

}  // namespace

void RegisterDisturbanceCommand(CLI::App& app) {
  auto* command = app.add_subcommand(
      "disturbance", "disturbance PSDs, synthesised time signals with a given PSD, force PSDs");
  command->require_subcommand(1);

  auto* psd = command->add_subcommand("psd", "Welch PSD of a record (CSV), corrected for its kind");
  auto p = std::make_shared<PsdFlags>();
  psd->add_option("record", p->record, "record CSV (time_s or position_m first)")->required();
  psd->add_option("--kind", p->kind, "raw (default), ground-geophone, straightness, spindle");
  psd->add_option("--out", p->out, "PSD CSV to write")->required();
  psd->add_option("--report", p->report, "write a JSON report to this file");
  psd->add_option("--geophone", p->geophone, "ground-geophone: L-4C (default) or L-22");
  psd->add_option("--gain", p->gain, "ground-geophone: amplifier gain, V/V (default 1)");
  psd->add_option("--speed", p->speed,
                  "straightness: scan speed (\"1 mm/s\"; PSD versus Hz instead of 1/m); "
                  "spindle: rotation speed (\"60 rpm\") when the record has no angle_rad column");
  psd->add_option("--z1", p->z1, "spindle: height of sphere 1 (default 0 m)");
  psd->add_option("--z2", p->z2, "spindle: height of sphere 2 (default 0.1 m)");
  psd->add_option("--z-ref", p->z_ref, "spindle: height where Dx, Dy, Dz are given (default 0.1 m)");
  psd->add_flag("--keep-axial-once-per-rev", p->keep_axial_once_per_rev,
                "spindle: do not remove the once-per-revolution part of z");
  psd->add_option("--residuals", p->residuals, "spindle: also write the residual motions (CSV)");
  AddWelchOptions(psd, p->welch);
  psd->callback([p] { RunPsd(*p); });

  auto* synth = command->add_subcommand("synth", "time signals (or scans) whose PSD is a given PSD");
  auto s = std::make_shared<SynthFlags>();
  synth->add_option("--psd", s->psd, "target PSD CSV (frequency_hz or spatial_frequency_per_m first)")
      ->required();
  synth->add_option("--out", s->out, "record CSV to write")->required();
  synth->add_option("--as", s->as, "raw (default), ground-geophone, straightness, spindle");
  synth->add_option("--duration", s->duration, "record length (\"60 s\"; default 10 s)");
  synth->add_option("--rate", s->rate, "sample rate (\"256 Hz\"; default 1000 Hz)");
  synth->add_option("--seed", s->seed, "seed of the phases (std::mt19937_64; default 1)");
  synth->add_option("--report", s->report, "write a JSON report to this file");
  synth->add_option("--geophone", s->geophone, "ground-geophone: L-4C (default) or L-22");
  synth->add_option("--gain", s->gain, "ground-geophone: amplifier gain, V/V (default 1)");
  synth->add_option("--scan-from", s->scan_from, "straightness: first position (default -4.5 mm)");
  synth->add_option("--scan-to", s->scan_to, "straightness: last position (default 4.5 mm)");
  synth->add_option("--points", s->points, "straightness: number of positions (default 901)");
  synth->add_option("--tilt", s->tilt, "straightness: added line slope (\"20 urad\")");
  synth->add_option("--offset", s->offset, "straightness: added constant (\"100 nm\")");
  synth->add_option("--speed", s->speed, "spindle: rotation speed (default 60 rpm)");
  synth->add_option("--z1", s->z1, "spindle: height of sphere 1 (default 0 m)");
  synth->add_option("--z2", s->z2, "spindle: height of sphere 2 (default 0.1 m)");
  synth->add_option("--z-ref", s->z_ref, "spindle: height of the motions Dx, Dy, Dz (default 0.1 m)");
  synth->add_option("--eccentricity1", s->ecc1, "spindle: sphere 1 eccentricity (\"1 um\")");
  synth->add_option("--phase1", s->phase1, "spindle: sphere 1 eccentricity angle (\"30 deg\")");
  synth->add_option("--eccentricity2", s->ecc2, "spindle: sphere 2 eccentricity");
  synth->add_option("--phase2", s->phase2, "spindle: sphere 2 eccentricity angle");
  synth->add_option("--axial-once-per-rev", s->axial, "spindle: once-per-revolution axial amplitude");
  synth->add_option("--axial-phase", s->axial_phase, "spindle: its phase");
  synth->callback([s] { RunSynth(*s); });

  auto* force = command->add_subcommand("force", "force PSD = motion PSD / |sensitivity|^2");
  auto fo = std::make_shared<ForceFlags>();
  force->add_option("--psd", fo->psd, "motion PSD CSV (frequency_hz first)")->required();
  force->add_option("--sensitivity", fo->sensitivity,
                    "sensitivity CSV frequency_hz,re,im (motion/force) at the PSD's frequencies")
      ->required();
  force->add_option("--column", fo->column, "PSD column to use (default: the first)");
  force->add_option("--min-relative", fo->min_relative,
                    "flag bins where |H| < this fraction of its peak (default 1e-3)");
  force->add_option("--out", fo->out, "force PSD CSV to write")->required();
  force->add_option("--report", fo->report, "write a JSON report to this file");
  force->callback([fo] { RunForce(*fo); });

  auto* sensitivity = command->add_subcommand(
      "sensitivity", "the model's sensitivity from a disturbance source to {X} relative to the granite (CSV for `force`)");
  auto se = std::make_shared<SensitivityFlags>();
  AddCommonOptions(*sensitivity, se->common);
  AddWithOption(*sensitivity, se->common);
  sensitivity->add_option("--source", se->source,
                          "ground.Dx|Dy|Dz, ty.F.Dz|Dx (force inside the translation stage), rz.F.Dz|Dx|Dy (spindle)")
      ->capture_default_str();
  sensitivity->add_option("--output", se->output, "X_rel.Dx ... X_rel.Rz")->capture_default_str();
  sensitivity->add_option("--at", se->at, "compute at the frequency_hz of this CSV (e.g. the motion PSD)");
  sensitivity->add_option("--fmin", se->fmin, "lowest frequency, Hz (without --at)")->capture_default_str();
  sensitivity->add_option("--fmax", se->fmax, "highest frequency, Hz")->capture_default_str();
  sensitivity->add_option("--points", se->points, "log-spaced frequencies")->capture_default_str();
  sensitivity->add_option("--out", se->out, "CSV to write: frequency_hz,re,im,abs")->required();
  sensitivity->callback([se] { RunSensitivity(*se); });
}

}  // namespace stagefit::cli
