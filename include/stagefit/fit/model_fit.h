#pragma once
// Fitting model parameters (model/parameters.h) to a measurement through a compare::Comparison:
// the least-squares core (least_squares.h) minimises the comparison's residuals r, whose norm is the
// SPEC §4 error scalar, with the analytic Jacobian J = dr/dp of the response layer.
//
// Parameterisation and bounds. Positive parameters (ParameterInfo::positive: stiffness, damping, loss
// factor) with a positive value are fitted as ln p. Bounds are natural units; without a rule they are
// [p0 / kDefaultBoundFactor, p0 * kDefaultBoundFactor] around the initial value p0 for positive
// parameters (a factor 100 is far beyond the uncertainty of a catalogue stiffness yet keeps the model
// physical), [0, +inf) for a positive parameter that starts at 0, and unbounded for the others.

#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "stagefit/compare/parameter_probes.h"
#include "stagefit/compare/residuals.h"
#include "stagefit/fit/least_squares.h"
#include "stagefit/model/model_spec.h"
#include "stagefit/model/parameters.h"
#include "stagefit/response/frf_evaluator.h"

namespace stagefit::fit {

/// The default bound factor around the initial value of a positive parameter.
inline constexpr double kDefaultBoundFactor = 100.0;

/// Bounds for the parameters whose names match `pattern` (shell globbing, as for --params). Rules apply
/// in order; a later matching rule overrides the fields it sets.
struct BoundRule {
  std::string pattern;
  std::optional<double> lower;    ///< natural SI units of the matched parameters
  std::optional<double> upper;
  std::optional<double> factor;   ///< [p0 / factor, p0 * factor] (> 1); lower/upper override it
  /// The dimension `lower` and `upper` were given in (from a unit string); unset for bare SI numbers.
  /// A matched parameter of another dimension is an error.
  std::optional<Dimension> dimension;
  std::string source;             ///< "file:line" for messages; empty when built in code
};

/// How a parameter's Jacobian column is computed.
///  - kAnalytic: CalcSystemDerivative() (model/parameters.h: HasAnalyticDerivative);
///  - kSystemDifference: the parameter changes only the model's M, C, K and K_loss (an effect's mass,
///    position or stiffness; a body's mass under a payload): the central difference of those matrices
///    is a derivative of the dynamic stiffness, whose FRF derivative is analytic and comes out of the
///    same modal evaluation as the others' (no eigen-decomposition of its own);
///  - kMeasuredDifference: it changes only the measured side (a channel's geometry in compliance
///    space: the data are re-projected, the model is not touched): the residuals at p +- h with the
///    model's responses at p;
///  - kDelayDifference: it changes only the system's delay (a delay in the acquisition chain): the
///    residuals at p +- h with the model's responses at p delayed by the change, e^{-j omega dtau}
///    (the responses are s^p e^{-s tau} H0, response/frf_evaluator.h), with no evaluation of its own;
///  - kResidualDifference: anything else (a joint's origin moves the generalised coordinates the
///    channels are read in; a channel's geometry in raw space): the central difference of the
///    residuals.
enum class ColumnRoute { kAnalytic, kSystemDifference, kMeasuredDifference, kDelayDifference, kResidualDifference };

/// (plus - minus) / (2 h) of the dynamic stiffness, as a derivative named `name`.
response::DynamicStiffnessDerivative SystemDifference(const model::SecondOrderSystem& plus,
                                                      const model::SecondOrderSystem& minus, double h,
                                                      const std::string& name);
/// The route of a differenced column from the specs at p (`at`, its system `at_system`) and p +- h;
/// fills the systems at p +- h.
ColumnRoute ChooseColumnRoute(const compare::Comparison& comparison, const model::ModelSpec& at,
                              const model::SecondOrderSystem& at_system, const model::ModelSpec& plus,
                              const model::ModelSpec& minus, model::SecondOrderSystem* plus_system,
                              model::SecondOrderSystem* minus_system);
/// The residuals at p + h and p - h of a column on a differencing route: from the model's responses
/// at p (`values_at`, the workspace's frf.values after the evaluation at p) on kMeasuredDifference and
/// kDelayDifference (delayed by the systems' delay changes `delay_plus_s`, `delay_minus_s`), evaluated
/// afresh in `workspace` on kResidualDifference.
void ResidualsAtSteps(const compare::Comparison& comparison, ColumnRoute route, const model::ModelSpec& plus,
                      const model::ModelSpec& minus, double delay_plus_s, double delay_minus_s,
                      const Eigen::MatrixXcd& values_at, compare::ModelWorkspace* workspace,
                      Eigen::VectorXd* r_plus, Eigen::VectorXd* r_minus);

/// The step of a differenced column at `value`: 1e-5 |value| for a log-scale parameter, a millionth of
/// the catalogue range of an effect parameter without a log scale.
double DifferenceStep(const model::ModelSpec& spec, const model::ParameterInfo& parameter, double value);

/// The least-squares problem "parameters of `spec` -> residuals of `comparison`". The parameters may
/// include a body's mass and the effects' parameters (model/parameters.h); their columns come by the
/// routes of ColumnRoute. Holds a copy of `spec` as its workspace: not thread-safe (use one per thread).
/// ProbeCosts (least_squares.h) from compare::ParameterProbes: the problem's parameters first ..
/// first + n - 1 are the probes' n parameters; a point that changes another parameter from `at`, or
/// one the probes cannot, is left to Evaluate().
class ParameterProbeCosts final : public ProbeCosts {
 public:
  ParameterProbeCosts(std::unique_ptr<const compare::ParameterProbes> probes, Eigen::VectorXd at, int first);
  bool Cost(const Eigen::VectorXd& q, double* cost) const override;

 private:
  std::unique_ptr<const compare::ParameterProbes> probes_;
  Eigen::VectorXd at_;
  int first_ = 0;
};

/// ParameterProbeCosts of `parameters` around `spec` (the model at `p`, whose entries first .. are
/// those parameters): nullptr when none of them can be probed or `spec` cannot be evaluated. What a
/// problem's LeastSquaresProblem::PrepareProbeCosts() returns.
std::unique_ptr<const ProbeCosts> MakeParameterProbeCosts(const compare::Comparison& comparison, const model::ModelSpec& spec,
                                                          const std::vector<model::ParameterInfo>& parameters,
                                                          const Eigen::VectorXd& p, int first);

class ModelFitProblem final : public LeastSquaresProblem {
 public:
  /// `parameters` from model::MatchParameters(spec, ...) (or ListParameters). `comparison` must outlive
  /// the problem.
  ModelFitProblem(const model::ModelSpec& spec, const compare::Comparison& comparison,
                  std::vector<model::ParameterInfo> parameters);
  int num_parameters() const override { return static_cast<int>(parameters_.size()); }
  int num_residuals() const override { return comparison_->num_residuals(); }
  bool has_jacobian() const override { return true; }
  /// Sets the parameters to `p` (natural units) with model::SetParameter and evaluates
  /// comparison.ResidualsAndJacobian(). Returns false when the model is invalid at `p` or its response
  /// is not finite (InputError / NumericalError from the comparison).
  bool Evaluate(const Eigen::VectorXd& p, Eigen::VectorXd* residuals, Eigen::MatrixXd* jacobian) const override;
  /// A copy with its own workspace (the comparison is shared: it is immutable).
  std::unique_ptr<LeastSquaresProblem> Clone() const override;
  /// The probes of the joint stiffnesses, dampings and couplings among the parameters
  /// (compare::ParameterProbes) around `p`; nullptr when there are none or the model is invalid at `p`.
  std::unique_ptr<const ProbeCosts> PrepareProbeCosts(const Eigen::VectorXd& p) const override;

  const std::vector<model::ParameterInfo>& parameters() const { return parameters_; }
  /// The route of each differenced parameter's column at the last Evaluate() with a Jacobian, in the
  /// order of the parameters without an analytic derivative.
  const std::vector<ColumnRoute>& routes() const { return routes_; }

 private:
  mutable model::ModelSpec spec_;
  mutable compare::ModelWorkspace workspace_;  // reused by every evaluation
  mutable compare::ModelWorkspace difference_workspace_;
  const compare::Comparison* comparison_;
  std::vector<model::ParameterInfo> parameters_;
  std::vector<int> analytic_, differenced_;   // indices into parameters_
  std::vector<model::ParameterInfo> analytic_params_;
  mutable std::vector<ColumnRoute> routes_;
  mutable Eigen::MatrixXd columns_;
  mutable Eigen::VectorXd r_plus_, r_minus_;
};

/// The ParameterSpec of each parameter: name, SI unit, initial value from `spec`, log scale for
/// positive parameters with a positive value, bounds from the defaults (header) and `bounds`.
/// Throws InputError (naming the rule's source, pattern and value) when a rule matches none of
/// `parameters`, gives a factor <= 1, lower > upper, a unit of another dimension than a matched
/// parameter, a non-positive lower bound for a log-scale parameter, or bounds that exclude the
/// initial value.
std::vector<ParameterSpec> MakeParameterSpecs(const model::ModelSpec& spec,
                                              const std::vector<model::ParameterInfo>& parameters,
                                              const std::vector<BoundRule>& bounds = {});

/// The stiffness parameters of `parameters` that act in series (SolveWithProbes' series probes): the
/// same DoF of two joints one above the other on a chain, with parallel joint axes. The upper joint's
/// parent is the lower joint's child and the only joint on that body; a joint whose DoF is imposed is
/// walked through, one whose DoF is free but not fitted ends the chain.
std::vector<SeriesPair> SeriesPairs(const model::ModelSpec& spec, const std::vector<model::ParameterInfo>& parameters);

/// Fits `parameters` of `spec` to the measurement of `comparison`, with the series probes of
/// SeriesPairs(). On return `spec` holds the values
/// of the kept optimum (also when the fit did not converge: the status says so) and one more history
/// entry {"fit", error after, detail}; summary.initial_error is comparison.Error() of the model as
/// given and summary.final_error is comparison.Error(spec) of the returned spec, so that writing
/// `spec` (model::WriteModelFile) and loading it again reproduces final_error exactly.
/// Throws InputError as MakeParameterSpecs() and Solve() do; numerical failure is in the status.
FitSummary FitModel(model::ModelSpec& spec, const compare::Comparison& comparison,
                    const std::vector<model::ParameterInfo>& parameters, const FitOptions& options,
                    const std::vector<BoundRule>& bounds = {});

/// FitModel() with a continuation in band, and the better of it and a direct fit kept. Stages: the
/// comparison band cut at 8 x its lowest frequency, then x2.5 per stage, then the whole band; each stage
/// starts from the previous one's result. A stiffness fitted on the whole band at once can stop in a
/// basin where modes are paired with the wrong ones (a whole-stack test: 2 of 4 cases at 2.8x and 6.5x
/// the noise floor); the low band holds few modes, each stage adds a few (docs/fitting.md). The direct
/// fit from the model as given runs too, and the lower error is kept: the continuation costs about 3x.
/// `comparison_options` and `measurement` make the stages' comparisons; `comparison` (the whole band,
/// made from them) scores the result. Same result contract as FitModel(); summary.message names the
/// route kept. A stage whose band holds no significant element is skipped.
FitSummary FitModelWithBandContinuation(model::ModelSpec& spec, const measurement::FrfData& measurement,
                                        const compare::ComparisonOptions& comparison_options,
                                        const compare::Comparison& comparison,
                                        const std::vector<model::ParameterInfo>& parameters, const FitOptions& options,
                                        const std::vector<BoundRule>& bounds = {});

/// Matches a parameter name against a shell pattern (fnmatch semantics, as model::MatchParameters).
bool MatchesPattern(const std::string& name, const std::string& pattern);

}  // namespace stagefit::fit
