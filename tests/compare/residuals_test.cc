#include "stagefit/compare/residuals.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>

#include "compare_test_util.h"
#include "stagefit/common/error.h"
#include "stagefit/measurement/projection.h"
#include "stagefit/model/assembled_model.h"
#include "stagefit/model/effects.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"
#include "stagefit/synthetic/synthetic_measurement.h"

namespace stagefit::compare {
namespace {

using testing::LogFrequencies;
using testing::MakeSyntheticMeasurement;

// The model's own FRF, projected by pinv(J_a) ... pinv(J_F') and compared with the model's compliance,
// differs only by rounding in the modal sums and the pseudo-inverses: relative 1e-12 on the strong
// elements, a little more on a coupling element near an antiresonance. 1e-8 is far below any
// physical discrepancy (|ln 1.0001| = 1e-4) and far above that rounding.
constexpr double kSelfErrorTolerance = 1e-8;

class ResidualsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    spec_ = model::DefaultModelSpec();
    frequency_hz_ = LogFrequencies(5.0, 500.0, 160);
    data_ = MakeSyntheticMeasurement(spec_, frequency_hz_);
  }
  model::ModelSpec spec_;
  Eigen::VectorXd frequency_hz_;
  measurement::FrfData data_;
};

TEST_F(ResidualsTest, ErrorIsZeroForTheModelsOwnFrfInComplianceSpace) {
  const Comparison comparison = Comparison::Create(spec_, data_);
  EXPECT_EQ(comparison.space(), ComparisonSpace::kCompliance);
  EXPECT_EQ(comparison.num_outputs(), 6);
  EXPECT_EQ(comparison.num_frequencies(), 160);
  EXPECT_LT(comparison.Error(spec_), kSelfErrorTolerance);
}

TEST_F(ResidualsTest, ErrorIsZeroForTheModelsOwnFrfInRawSpace) {
  ComparisonOptions options;
  options.space = ComparisonSpace::kRaw;
  const Comparison comparison = Comparison::Create(spec_, data_, options);
  EXPECT_EQ(comparison.num_outputs(), 12);
  EXPECT_EQ(comparison.num_inputs(), 10);
  EXPECT_LT(comparison.Error(spec_), kSelfErrorTolerance);
}

TEST_F(ResidualsTest, RawSpaceNeedsNoSensorEntriesInTheModel) {
  model::ModelSpec bare = spec_;
  bare.sensors.clear();
  bare.excitations.clear();
  ComparisonOptions options;
  options.space = ComparisonSpace::kRaw;
  const Comparison comparison = Comparison::Create(bare, data_, options);
  EXPECT_LT(comparison.Error(bare), kSelfErrorTolerance);
}

TEST_F(ResidualsTest, OnePercentMagnitudeScalingGivesLogOfOnePointZeroOne) {
  for (auto space : {ComparisonSpace::kCompliance, ComparisonSpace::kRaw}) {
    measurement::FrfData scaled = data_;
    for (auto& H : scaled.frf) H *= 1.01;
    ComparisonOptions options;
    options.space = space;
    const Comparison comparison = Comparison::Create(spec_, scaled, options);
    // e = ln(1 / 1.01) at every point, so error = |ln 1.01| = 0.00995033...
    EXPECT_NEAR(comparison.Error(spec_), std::log(1.01), kSelfErrorTolerance) << ToString(space);
  }
}

TEST_F(ResidualsTest, ResidualNormEqualsErrorAndBreakdownAgrees) {
  model::ModelSpec stiffer = spec_;
  model::SetParameter(stiffer, model::FindParameter(stiffer, "hexapod.k.Dx"), 1.3e7);
  const Comparison comparison = Comparison::Create(spec_, data_);
  Eigen::VectorXd r;
  comparison.Residuals(stiffer, &r);
  EXPECT_EQ(r.size(), comparison.num_residuals());
  const double error = comparison.Error(stiffer);
  EXPECT_GT(error, 1e-3);
  EXPECT_NEAR(r.norm(), error, 1e-14);
  const ComparisonResult result = comparison.Evaluate(stiffer);
  EXPECT_NEAR(result.error, error, 1e-12);
  double share = 0.0;
  for (const auto& el : result.elements) share += el.share;
  EXPECT_NEAR(share, 1.0, 1e-12);
  double band_share = 0.0;
  for (const auto& b : result.bands) band_share += b.share;
  EXPECT_NEAR(band_share, 1.0, 1e-12);
  EXPECT_EQ(result.element_band_error.rows(), static_cast<int>(result.elements.size()));
  EXPECT_EQ(result.element_band_error.cols(), static_cast<int>(result.bands.size()));
  EXPECT_FALSE(result.BriefReport().empty());
}

// Every element's own worst band: measured 1 % high everywhere and 11.1 % high in one third-octave
// band, each element's error lies in that band by the share n_b ln(1.111)^2 / (n_b ln(1.111)^2 +
// (N - n_b) ln(1.01)^2) of its N points, n_b of them in the band (uniform weights at coherence 1).
TEST_F(ResidualsTest, EachElementNamesTheBandHoldingMostOfItsError) {
  const auto bands = measurement::MakeFractionalOctaveBands(frequency_hz_(0), frequency_hz_(frequency_hz_.size() - 1), 3);
  const auto in = std::find_if(bands.begin(), bands.end(), [](const auto& b) { return b.low_hz <= 110.0 && 110.0 < b.high_hz; });
  ASSERT_NE(in, bands.end());
  measurement::FrfData scaled = data_;
  int n_b = 0;
  for (int k = 0; k < scaled.num_frequencies(); ++k) {
    const bool hit = scaled.frequency_hz(k) >= in->low_hz && scaled.frequency_hz(k) < in->high_hz;
    scaled.frf[k] *= hit ? 1.01 * 1.1 : 1.01;
    n_b += hit;
  }
  ASSERT_GT(n_b, 3);
  const Comparison comparison = Comparison::Create(spec_, scaled);
  const ComparisonResult result = comparison.Evaluate(spec_);
  const double a = n_b * std::pow(std::log(1.01 * 1.1), 2), b = (comparison.num_frequencies() - n_b) * std::pow(std::log(1.01), 2);
  ASSERT_FALSE(result.elements.empty());
  for (const auto& el : result.elements) {
    EXPECT_EQ(el.worst_band.low_hz, in->low_hz) << el.name;
    EXPECT_NEAR(el.worst_band_share, a / (a + b), 1e-9) << el.name;
  }
}

// Central differences with relative step h = 1e-6 p: truncation error ~ (h/p)^2 = 1e-12 of the column
// (kJacobianTolerance = 1e-6 of the column's largest entry covers it with margin, and still catches a
// wrong sign, factor or missing term, all O(1)). Rounding: each evaluation of r carries a relative
// error up to the response layer's modal/direct agreement (below 1e-12 for these models: checked
// below; bounded here by 1e-10), which the difference
// quotient divides by the step: kEvaluationRounding * max|r| / h. This term dominates for parameters
// with a weak influence (damping, whose effect is confined to the resonances).
constexpr double kFdRelativeStep = 1e-6;
constexpr double kJacobianTolerance = 1e-6;
constexpr double kEvaluationRounding = 1e-10;

void CheckJacobian(const model::ModelSpec& spec, const Comparison& comparison,
                   const std::vector<model::ParameterInfo>& params) {
  EXPECT_LT(response::FrfEvaluator::Create(comparison.ModelSystem(spec)).setup_summary().check_error, 1e-12);
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  comparison.ResidualsAndJacobian(spec, params, &r, &J);
  ASSERT_EQ(J.rows(), comparison.num_residuals());
  ASSERT_EQ(J.cols(), static_cast<int>(params.size()));
  Eigen::VectorXd r0;
  comparison.Residuals(spec, &r0);
  EXPECT_LT((r - r0).lpNorm<Eigen::Infinity>(), 1e-14);
  for (size_t k = 0; k < params.size(); ++k) {
    const double p = model::GetParameter(spec, params[k]);
    const double h = kFdRelativeStep * p;
    model::ModelSpec plus = spec, minus = spec;
    model::SetParameter(plus, params[k], p + h);
    model::SetParameter(minus, params[k], p - h);
    Eigen::VectorXd rp, rm;
    comparison.Residuals(plus, &rp);
    comparison.Residuals(minus, &rm);
    const Eigen::VectorXd fd = (rp - rm) / (2 * h);
    const double scale = J.col(k).lpNorm<Eigen::Infinity>();
    ASSERT_GT(scale, 0.0) << params[k].name;
    const double rounding = kEvaluationRounding * r.lpNorm<Eigen::Infinity>() / h;
    EXPECT_LT((fd - J.col(k)).lpNorm<Eigen::Infinity>(), kJacobianTolerance * scale + rounding)
        << params[k].name;
  }
}

TEST_F(ResidualsTest, JacobianMatchesCentralDifferencesInComplianceSpace) {
  model::ModelSpec perturbed = spec_;
  model::SetParameter(perturbed, model::FindParameter(perturbed, "hexapod.k.Dx"), 1.2e7);
  model::SetParameter(perturbed, model::FindParameter(perturbed, "hexapod.k.Rx"), 1.2e6);
  const Comparison comparison = Comparison::Create(spec_, data_);
  const auto params = model::MatchParameters(
      perturbed, {"hexapod.k.*", "hexapod.c.Dx", "rz.k.Rx", "ty.k.Dz", "hexapod.c.Rz"});
  CheckJacobian(perturbed, comparison, params);
}

TEST_F(ResidualsTest, JacobianMatchesCentralDifferencesInRawSpace) {
  model::ModelSpec perturbed = spec_;
  model::SetParameter(perturbed, model::FindParameter(perturbed, "hexapod.k.Dz"), 0.8e8);
  ComparisonOptions options;
  options.space = ComparisonSpace::kRaw;
  const Comparison comparison = Comparison::Create(spec_, data_, options);
  const auto params = model::MatchParameters(perturbed, {"hexapod.k.D?", "hexapod.c.Dz", "rz.k.Ry"});
  CheckJacobian(perturbed, comparison, params);
}

// Further columns given as dynamic-stiffness derivatives are the same columns as the parameters'
// own: the two paths into the FRF derivatives agree, whichever columns come first.
TEST_F(ResidualsTest, FurtherColumnsFromSystemDerivativesEqualTheParametersColumns) {
  model::ModelSpec perturbed = spec_;
  model::SetParameter(perturbed, model::FindParameter(perturbed, "hexapod.k.Dx"), 1.2e7);
  const Comparison comparison = Comparison::Create(spec_, data_);
  const auto params = model::MatchParameters(perturbed, {"hexapod.k.D?", "ry.c.Dx"});
  const auto assembled = model::AssembledModel::Assemble(perturbed);
  std::vector<response::DynamicStiffnessDerivative> further;
  for (const auto& p : params) {
    further.push_back(response::MakeDynamicStiffnessDerivative(model::CalcSystemDerivative(assembled, p), p.name));
  }
  Eigen::VectorXd r, r_further;
  Eigen::MatrixXd J, J_further;
  ModelWorkspace workspace;
  comparison.ResidualsAndJacobian(perturbed, params, &r, &J);
  comparison.ResidualsAndJacobian(perturbed, {params[0]}, further, &r_further, &J_further, &workspace);
  ASSERT_EQ(J_further.cols(), 1 + J.cols());
  EXPECT_EQ(r, r_further);
  EXPECT_LT((J_further.col(0) - J.col(0)).norm(), 1e-12 * J.col(0).norm());
  EXPECT_LT((J_further.rightCols(J.cols()) - J).norm(), 1e-12 * J.norm());

  // An entry outside the model's coordinates is refused.
  further[0].entries.push_back({assembled.num_dofs(), 0, 1.0, 0.0, 0.0});
  EXPECT_THROW(comparison.ResidualsAndJacobian(perturbed, {}, further, &r_further, &J_further, &workspace), InputError);
}

// The residuals with the model's responses given are the residuals: in compliance space, of a spec
// whose geometry correction re-projects the measurement, with the responses of the uncorrected model.
TEST_F(ResidualsTest, ResidualsWithTheModelsResponsesGivenAreTheResiduals) {
  const Comparison comparison = Comparison::Create(spec_, data_);
  model::ModelSpec corrected = spec_;
  model::ApplyEffect(corrected, model::ParseEffect("sensor-geometry@" + comparison.CorrectableChannels()[1] + ":rz=5 deg",
                                                   corrected, comparison.CorrectableChannels()));
  ASSERT_EQ(comparison.ModelSystem(corrected).Cq, comparison.ModelSystem(spec_).Cq);
  Eigen::VectorXd r, r_given, r_plain;
  ModelWorkspace workspace;
  comparison.ResidualsAndJacobian(spec_, {}, &r_plain, nullptr, &workspace);
  comparison.ResidualsWithModelResponse(corrected, workspace.frf.frf.values, &r_given);
  comparison.Residuals(corrected, &r);
  EXPECT_LT((r_given - r).norm(), 1e-12 * r.norm());
  EXPECT_GT((r - r_plain).norm(), 1e-3 * r.norm());  // the correction does move the residuals
}

// A workspace reuses the set-up of the last model only for the same system with the same options, and
// what it gives then is what a fresh set-up gives, to the bit.
TEST_F(ResidualsTest, AWorkspaceReusesTheSetUpOfTheSameModelOnly) {
  const Comparison comparison = Comparison::Create(spec_, data_);
  model::ModelSpec spec = spec_;
  const auto params = model::MatchParameters(spec, {"hexapod.k.D?", "rz.k.Rx"});
  ModelWorkspace workspace;
  Eigen::VectorXd r1, r2, r_fresh;
  Eigen::MatrixXd J1, J2, J_fresh;
  comparison.ResidualsAndJacobian(spec, {}, &r1, nullptr, &workspace);      // residuals at a point,
  comparison.ResidualsAndJacobian(spec, params, &r2, &J2, &workspace);     // then the Jacobian there
  EXPECT_EQ(workspace.num_setups, 1);
  EXPECT_EQ(workspace.num_reused, 1);
  comparison.ResidualsAndJacobian(spec, params, &r_fresh, &J_fresh);       // a fresh workspace
  EXPECT_EQ(r1, r_fresh);
  EXPECT_EQ(r2, r_fresh);
  EXPECT_EQ(J2, J_fresh);

  // Another stiffness: a new set-up, and the residuals of the new model.
  model::SetParameter(spec, params[0], 1.01 * model::GetParameter(spec, params[0]));
  comparison.ResidualsAndJacobian(spec, params, &r1, &J1, &workspace);
  EXPECT_EQ(workspace.num_setups, 2);
  comparison.ResidualsAndJacobian(spec, params, &r_fresh, &J_fresh);
  EXPECT_EQ(r1, r_fresh);
  EXPECT_EQ(J1, J_fresh);
  EXPECT_NE(r1, r2);

  // The same model on a comparison of fewer frequencies: other options (its lowest frequency), so a
  // new set-up.
  std::vector<int> upper;
  for (int k = comparison.num_frequencies() / 2; k < comparison.num_frequencies(); ++k) upper.push_back(k);
  const Comparison part = comparison.OnFrequencies(upper);
  Eigen::VectorXd r_part, r_part_fresh;
  part.ResidualsAndJacobian(spec, {}, &r_part, nullptr, &workspace);
  EXPECT_EQ(workspace.num_setups, 3);
  part.Residuals(spec, &r_part_fresh);
  EXPECT_EQ(r_part, r_part_fresh);
}

TEST_F(ResidualsTest, CoherenceWeightsReduceTheInfluenceOfALowCoherencePoint) {
  ComparisonOptions options;
  options.space = ComparisonSpace::kRaw;
  measurement::FrfData corrupted = data_;
  testing::SetPerfectCoherence(&corrupted);
  const Comparison clean = Comparison::Create(spec_, corrupted, options);
  // Corrupt one point of the first used element: factor 3 in magnitude, coherence 0.5 (SNR = 1).
  const ElementIndex element = clean.used_elements().front();
  const int f = 40;
  corrupted.frf[f](element.output, element.input) *= 3.0;
  corrupted.coherence[f](element.output, element.input) = 0.5;

  const Comparison weighted = Comparison::Create(spec_, corrupted, options);
  options.use_coherence = false;
  const Comparison unweighted = Comparison::Create(spec_, corrupted, options);
  ASSERT_EQ(weighted.num_points(), unweighted.num_points());
  const int n = weighted.num_points();
  const double cap = kDefaultCoherenceWeightCap;
  // One point with |e| = ln 3; all others exact. Weighted: w = 1 there, cap elsewhere.
  const double expected_weighted = std::log(3.0) / std::sqrt(cap * cap * (n - 1) + 1.0);
  const double expected_unweighted = std::log(3.0) / std::sqrt(static_cast<double>(n));
  EXPECT_NEAR(weighted.Error(spec_), expected_weighted, kSelfErrorTolerance);
  EXPECT_NEAR(unweighted.Error(spec_), expected_unweighted, kSelfErrorTolerance);
  EXPECT_LT(weighted.Error(spec_), unweighted.Error(spec_) / 20.0);
  EXPECT_DOUBLE_EQ(weighted.weights()[f](element.output, element.input), 1.0);
}

TEST_F(ResidualsTest, PerfectCoherenceGivesUniformCappedWeightsInComplianceSpace) {
  measurement::FrfData with_coherence = data_;
  testing::SetPerfectCoherence(&with_coherence);
  const Comparison comparison = Comparison::Create(spec_, with_coherence);
  for (const auto& idx : comparison.used_elements()) {
    EXPECT_DOUBLE_EQ(comparison.weights()[10](idx.output, idx.input), kDefaultCoherenceWeightCap);
  }
}

TEST_F(ResidualsTest, LowRawCoherencePropagatesToTheProjectedElements) {
  measurement::FrfData noisy = data_;
  testing::SetPerfectCoherence(&noisy);
  // Every raw point at gamma^2 = 0.5 (SNR 1) at one frequency: the projected points there get a
  // finite weight below the cap.
  const int f = 20;
  noisy.coherence[f].setConstant(0.5);
  const Comparison comparison = Comparison::Create(spec_, noisy);
  for (const auto& idx : comparison.used_elements()) {
    EXPECT_LT(comparison.weights()[f](idx.output, idx.input), kDefaultCoherenceWeightCap);
    EXPECT_GT(comparison.weights()[f](idx.output, idx.input), 0.0);
    EXPECT_DOUBLE_EQ(comparison.weights()[f + 1](idx.output, idx.input), kDefaultCoherenceWeightCap);
  }
}

TEST_F(ResidualsTest, SignificanceKeepsTheDiagonalAndDropsCrossTalk) {
  // A projected 6x6 (no geometry) of the model's compliance at {X}, with cross-talk added to Dx/Fy
  // and Dy/Fx at 1 % of the diagonal scale, and the strong Dx/My coupling of the stage kept.
  measurement::FrfData projected = measurement::ProjectToFrame(data_, spec_.frames[0].origin_W);
  for (auto& c : projected.outputs) c.body.clear();
  for (auto& c : projected.inputs) c.body.clear();
  for (auto& H : projected.frf) {
    const double scale = std::sqrt(std::abs(H(0, 0)) * std::abs(H(1, 1)));
    H(0, 1) = std::complex<double>(0.01 * scale, 0.003 * scale);
    H(1, 0) = std::complex<double>(0.01 * scale, -0.002 * scale);
  }
  const Comparison comparison = Comparison::Create(spec_, projected);
  const Eigen::MatrixXd& kappa = comparison.significance();
  for (int k = 0; k < 6; ++k) EXPECT_DOUBLE_EQ(kappa(k, k), 1.0);
  EXPECT_LT(kappa(0, 1), 0.02);
  EXPECT_GE(kappa(0, 4), kDefaultSignificanceThreshold);
  EXPECT_GE(kappa(1, 3), kDefaultSignificanceThreshold);
  bool diagonal[6] = {};
  for (const auto& idx : comparison.used_elements()) {
    EXPECT_FALSE(idx.output == 0 && idx.input == 1);
    EXPECT_FALSE(idx.output == 1 && idx.input == 0);
    if (idx.output == idx.input) diagonal[idx.output] = true;
  }
  for (bool d : diagonal) EXPECT_TRUE(d);
  bool dx_my = false;
  for (const auto& idx : comparison.used_elements()) dx_my = dx_my || (idx.output == 0 && idx.input == 4);
  EXPECT_TRUE(dx_my);
}

TEST_F(ResidualsTest, BandLimitsTheComparisonGrid) {
  ComparisonOptions options;
  options.fmin_hz = 20.0;
  options.fmax_hz = 100.0;
  const Comparison comparison = Comparison::Create(spec_, data_, options);
  EXPECT_GE(comparison.frequency_hz()(0), 20.0);
  EXPECT_LE(comparison.frequency_hz()(comparison.num_frequencies() - 1), 100.0);
  options.fmin_hz = 1000.0;
  options.fmax_hz = 2000.0;
  EXPECT_THROW(Comparison::Create(spec_, data_, options), InputError);
}

TEST_F(ResidualsTest, ComplianceSpaceWithoutGeometryIsRejected) {
  measurement::FrfData bare = data_;
  for (auto& c : bare.outputs) c.body.clear();
  EXPECT_THROW(Comparison::Create(spec_, bare), InputError);
}

TEST_F(ResidualsTest, OptionsOutOfRangeAreRejectedByName) {
  auto expect_rejected = [&](const ComparisonOptions& options, const std::string& what) {
    try {
      Comparison::Create(spec_, data_, options);
      ADD_FAILURE() << what << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  ComparisonOptions options;
  options.frf_check_tolerance = -1e-8;
  expect_rejected(options, "FRF check tolerance");
  options = {};
  options.coherence_weight_cap = 0;
  expect_rejected(options, "coherence weight cap");
  options = {};
  options.bands_per_octave = 0;
  expect_rejected(options, "bands per octave");
}

// A comparison on some of its frequencies (OnFrequencies): on all of them it is the comparison itself,
// bit for bit, with a channel's correction or without; on every second one, with a3z corrected in the
// data of seed 33013 of eval_loop, it decides the elements that stop counting as the whole grid does,
// so its error stays near the whole grid's. Compared on its own, a grid of every second frequency kept
// Rx/Fx, noise under that correction: 7.76 against 2.13.
TEST(OnFrequencies, KeepsTheWholeGridsElementsUnderACorrection) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 33013, synthetic::EvalLoopCaseOptions(2, 150, 737));
  model::ModelSpec with_a3z = nominal;
  model::ApplyEffect(with_a3z, model::ParseEffect("sensor-geometry@a3z:dx=0.0143,dy=0.00165,ry=-0.3378", with_a3z));
  const Comparison whole = Comparison::Create(nominal, c.measurement);
  std::vector<int> all(static_cast<size_t>(whole.num_frequencies())), every_second;
  for (int k = 0; k < whole.num_frequencies(); ++k) {
    all[static_cast<size_t>(k)] = k;
    if (k % 2 == 0) every_second.push_back(k);
  }
  const Comparison same = whole.OnFrequencies(all);
  EXPECT_EQ(same.Error(nominal), whole.Error(nominal));
  EXPECT_EQ(same.Error(with_a3z), whole.Error(with_a3z));
  const Comparison half = whole.OnFrequencies(every_second);
  EXPECT_EQ(half.num_frequencies(), static_cast<int>(every_second.size()));
  EXPECT_EQ(half.frequency_hz()(1), whole.frequency_hz()(2));
  EXPECT_NEAR(half.Error(nominal) / whole.Error(nominal), 1.0, 0.05);
  EXPECT_NEAR(half.Error(with_a3z) / whole.Error(with_a3z), 1.0, 0.05) << half.Error(with_a3z) << " against " << whole.Error(with_a3z);
  // The same elements count on both grids: where the whole grid's error of an element is none (its
  // weights zeroed as noise), so is the half grid's.
  const ComparisonResult w = whole.Evaluate(with_a3z), h = half.Evaluate(with_a3z);
  ASSERT_EQ(w.elements.size(), h.elements.size());
  int zeroed = 0;
  for (size_t e = 0; e < w.elements.size(); ++e) {
    EXPECT_EQ(w.elements[e].error == 0.0, h.elements[e].error == 0.0) << w.elements[e].name;
    zeroed += w.elements[e].error == 0.0;
  }
  EXPECT_GT(zeroed, 0);
  EXPECT_THROW(whole.OnFrequencies({}), InputError);
}

// The measured side under a correction (the raw data re-projected, its weights, the elements that
// stop counting) is taken from the sides computed lately for the same projection, and what is taken is
// what a comparison computing it afresh gives, to the bit; a side pushed out by newer ones is computed
// again, the same.
TEST(MeasuredSideReuse, GivesWhatAFreshComparisonComputes) {
  const model::ModelSpec nominal = model::DefaultModelSpec();
  const auto c = synthetic::MakeHiddenEffectCase(nominal, 33013, synthetic::EvalLoopCaseOptions(2, 150, 301));
  auto corrected = [&](double ry) {
    model::ModelSpec spec = nominal;
    model::ApplyEffect(spec, model::ParseEffect("sensor-geometry@a3z:dx=0.0143,ry=" + std::to_string(ry), spec));
    return spec;
  };
  const Comparison comparison = Comparison::Create(nominal, c.measurement);
  ASSERT_TRUE(comparison.weights_are_snr());  // with coherence: the re-projected weights are computed
  EXPECT_EQ(comparison.measured_side_reuse(), std::make_pair(0, 0));
  const double first = comparison.Error(corrected(-0.3378));
  EXPECT_EQ(comparison.measured_side_reuse(), std::make_pair(0, 1));
  // The same correction with other stiffnesses: the same side.
  model::ModelSpec stiffer = corrected(-0.3378);
  const auto k = model::MatchParameters(stiffer, {"hexapod.k.Dz"});
  model::SetParameter(stiffer, k[0], 1.2 * model::GetParameter(stiffer, k[0]));
  const double again = comparison.Error(corrected(-0.3378));
  const double stiffer_error = comparison.Error(stiffer);
  EXPECT_EQ(comparison.measured_side_reuse(), std::make_pair(2, 1));
  EXPECT_EQ(again, first);
  EXPECT_EQ(stiffer_error, Comparison::Create(nominal, c.measurement).Error(stiffer));
  EXPECT_NE(stiffer_error, first);
  // A copy shares what was computed; sixteen other corrections push the first one out.
  const Comparison copy = comparison;
  for (int i = 1; i <= 16; ++i) copy.Error(corrected(-0.3378 + 0.01 * i));
  EXPECT_EQ(comparison.measured_side_reuse(), std::make_pair(2, 17));
  EXPECT_EQ(copy.Error(corrected(-0.3378)), first);
  EXPECT_EQ(comparison.measured_side_reuse(), std::make_pair(2, 18));
  EXPECT_EQ(Comparison::Create(nominal, c.measurement).Error(corrected(-0.3378)), first);
  // A comparison on fewer frequencies keeps its own sides.
  std::vector<int> every_second;
  for (int f = 0; f < comparison.num_frequencies(); f += 2) every_second.push_back(f);
  const Comparison half = comparison.OnFrequencies(every_second);
  half.Error(corrected(-0.3378));
  EXPECT_EQ(half.measured_side_reuse(), std::make_pair(0, 1));
  EXPECT_EQ(comparison.measured_side_reuse(), std::make_pair(2, 18));
}

TEST(ParseComparisonSpace, RejectsUnknownNames) {
  EXPECT_EQ(ParseComparisonSpace("raw", "--space"), ComparisonSpace::kRaw);
  EXPECT_EQ(ParseComparisonSpace("compliance", "--space"), ComparisonSpace::kCompliance);
  EXPECT_THROW(ParseComparisonSpace("modal", "--space"), InputError);
}

}  // namespace
}  // namespace stagefit::compare
