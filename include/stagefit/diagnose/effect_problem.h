#pragma once
// The least-squares problem of one candidate effect (diagnose.h): the effect's parameters followed by
// the model's own, against a comparison's residuals.
//
// Jacobian. The model parameters' columns are analytic (compare::Comparison). An effect parameter's
// column comes from the specs at p +- h, by the cheapest route that is exact for it:
//  - it changes only the model's M, C, K and K_loss (a payload's or an extra body's mass, position and
//    stiffness, a servo's spring, a coupling, a loss factor): the central difference of those matrices
//    is a derivative of the dynamic stiffness, whose FRF derivative is analytic and comes out of the
//    same modal evaluation as the model parameters' (no eigen-decomposition of its own);
//  - it changes only the measured side (a channel's geometry in compliance space: the data are
//    re-projected, the model is not touched): the residuals at p +- h with the model's responses at p;
//  - anything else (a joint's origin moves the generalised coordinates the channels are read in; a
//    delay; a channel's geometry in raw space): the central difference of the residuals.
// The routes agree to the accuracy of the differences (tests/diagnose/effect_problem_test.cc).

#include <Eigen/Core>

#include <string>
#include <vector>

#include "stagefit/compare/residuals.h"
#include "stagefit/fit/least_squares.h"
#include "stagefit/fit/model_fit.h"
#include "stagefit/model/effects.h"
#include "stagefit/model/model_spec.h"
#include "stagefit/model/parameters.h"
#include "stagefit/response/frf_evaluator.h"

namespace stagefit::diagnose {

using model::kMaxCorrectionTurn;

/// Search ranges of the effect parameters (natural units), from the model around the location; the
/// parameters named in `held` and those the others make redundant there
/// (model::RedundantEffectParameters) are left out. `positions` (optional) receives each spec's position in the
/// effect definition's parameter list.
std::vector<fit::ParameterSpec> EffectParameterSpecs(const model::ModelSpec& base, const model::Effect& effect,
                                                     const std::vector<std::string>& held = {},
                                                     std::vector<int>* positions = nullptr);

/// How an effect parameter's Jacobian column is computed (header; fit::ColumnRoute).
using EffectColumnRoute = fit::ColumnRoute;

class EffectProblem final : public fit::LeastSquaresProblem {
 public:
  /// effect_index[i]: the position of effect_specs[i] in the effect definition's parameter list.
  /// `comparison` must outlive the problem.
  EffectProblem(const model::ModelSpec& base, const compare::Comparison& comparison, model::Effect effect,
                std::vector<fit::ParameterSpec> effect_specs, std::vector<int> effect_index,
                std::vector<model::ParameterInfo> model_params);
  /// Several effects applied to `base` in order, all fitted together with the model's parameters:
  /// `effect_specs` holds the parameters of every effect in turn, `effect_of[i]` the effect the i-th
  /// belongs to and `effect_index[i]` its position in that effect's definition.
  EffectProblem(const model::ModelSpec& base, const compare::Comparison& comparison, std::vector<model::Effect> effects,
                std::vector<fit::ParameterSpec> effect_specs, std::vector<int> effect_of, std::vector<int> effect_index,
                std::vector<model::ParameterInfo> model_params);

  int num_parameters() const override { return static_cast<int>(effect_specs_.size() + model_params_.size()); }
  int num_residuals() const override { return comparison_->num_residuals(); }
  bool has_jacobian() const override { return true; }
  bool Evaluate(const Eigen::VectorXd& p, Eigen::VectorXd* r, Eigen::MatrixXd* J) const override;
  /// The probes of the model's joint stiffnesses, dampings and couplings (fit::ParameterProbeCosts)
  /// around `p`; a point that changes an effect's parameter is left to Evaluate().
  std::unique_ptr<const fit::ProbeCosts> PrepareProbeCosts(const Eigen::VectorXd& p) const override;
  /// The same problem with its own workspaces (fit::SolveWithProbes runs its probes and bound resets on
  /// clones side by side).
  std::unique_ptr<fit::LeastSquaresProblem> Clone() const override;

  /// The (first) effect with the effect parameters of `p`.
  model::Effect EffectAt(const Eigen::VectorXd& p) const;
  /// Every effect with the effect parameters of `p`, in order.
  std::vector<model::Effect> EffectsAt(const Eigen::VectorXd& p) const;
  /// The base model with the effect and the model parameters of `p`; false when they are invalid.
  bool SpecAt(const Eigen::VectorXd& p, model::ModelSpec* spec) const;
  /// The route of each effect parameter's column at the last Evaluate() with a Jacobian.
  const std::vector<EffectColumnRoute>& routes() const { return routes_; }

 private:
  double Step(int i, double value) const;

  model::ModelSpec base_;
  const compare::Comparison* comparison_;
  std::vector<model::Effect> effects_;
  std::vector<fit::ParameterSpec> effect_specs_;
  std::vector<int> effect_of_;
  std::vector<int> effect_index_;
  std::vector<model::ParameterInfo> model_params_;
  // Reused from evaluation to evaluation (one problem per thread): fresh arrays of this size cost more
  // in page faults than the response itself.
  mutable compare::ModelWorkspace workspace_;
  // The responses at p +- h (workspace_ keeps p's for the measured-difference route).
  mutable compare::ModelWorkspace difference_workspace_;
  mutable Eigen::MatrixXd jacobian_;
  mutable Eigen::VectorXd r_plus_, r_minus_;
  mutable std::vector<EffectColumnRoute> routes_;
};

}  // namespace stagefit::diagnose
