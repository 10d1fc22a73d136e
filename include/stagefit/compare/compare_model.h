#pragma once
// `stagefit compare` as a library function: the error scalar with its breakdown and the mode pairing
// (Options in, Summary out), and the CSV tables written for plotting (scripts/plot_compare.sh).

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "stagefit/compare/mode_pairing.h"
#include "stagefit/compare/residuals.h"
#include "stagefit/measurement/frf_data.h"
#include "stagefit/model/model_spec.h"

namespace stagefit::compare {

struct CompareOptions {
  ComparisonOptions comparison;
  ModeIdentificationOptions modes;
  /// In the compliance space, also compare the raw channels (for the plots and the breakdown) when
  /// the measurement carries their geometry. The error scalar stays the compliance one.
  bool also_raw = true;
};

struct CompareSummary {
  Comparison comparison;                  ///< the comparison of CompareOptions::comparison
  ComparisonResult result;                ///< its error and breakdown for the model
  ModePairing modes;                      ///< modes of measurement and model, paired by MAC
  std::optional<Comparison> raw;          ///< the raw-channel comparison (compliance space, geometry)
  std::optional<ComparisonResult> raw_result;
  std::string raw_skipped;                ///< why the raw comparison was not made (empty if it was)

  /// The error scalar, the worst elements and bands, and the mode pairing table.
  std::string BriefReport(int max_rows = 8) const;
};

/// Compares the model `spec` with `measurement`. Throws as Comparison::Create() and
/// Comparison::Evaluate() do.
CompareSummary CompareModel(const model::ModelSpec& spec, const measurement::FrfData& measurement,
                            const CompareOptions& options = {});

/// Long-format CSV of the measured and model FRFs of the used elements, side by side, one row per
/// element and frequency, element-major:
/// `freq_hz,element,output,input,meas_re,meas_im,model_re,model_im,meas_abs,model_abs,
///  meas_phase_deg,model_phase_deg,weight` (units of the comparison quantity; phases in (-180, 180]).
std::string FormatFrfTable(const Comparison& comparison, const ComparisonResult& result);

/// `element,output,input,kappa,points,error,share,mean_ln_ratio,mean_phase_deg`, one row per used
/// element in Comparison::used_elements() order.
std::string FormatElementTable(const ComparisonResult& result, const Comparison& comparison);

/// `band_low_hz,band_high_hz,band_centre_hz,points,error,share`, one row per band.
std::string FormatBandTable(const ComparisonResult& result);

/// The element x band error map in long format, a full grid (`nan` where an element has no point in
/// a band): `element_index,band_index,element,band_centre_hz,error`.
std::string FormatElementBandTable(const ComparisonResult& result);

/// `kind,measured,model,f_meas_hz,f_model_hz,df_percent,zeta_meas,zeta_model,mac,model_mode,
///  model_mode_hz,dominant_dof` with kind = pair | measured_only | model_only (empty fields for the
/// missing side).
std::string FormatModeTable(const ModePairing& pairing);

/// Writes into `dir` (created if missing), each file atomically: compare_frf.csv,
/// compare_elements.csv, compare_bands.csv, compare_element_band.csv, compare_modes.csv, and with a
/// raw comparison compare_frf_raw.csv, compare_elements_raw.csv. Refuses to write over any of
/// `inputs`. Returns the paths written. Throws InputError when a file cannot be written.
std::vector<std::filesystem::path> WriteCompareTables(const std::filesystem::path& dir,
                                                      const CompareSummary& summary,
                                                      const std::vector<std::filesystem::path>& inputs = {});

}  // namespace stagefit::compare
