#pragma once
// Residuals of models that differ from one model only in parameters that enter its dynamic stiffness
// linearly (joint stiffnesses, dampings and coupling terms: model/parameters.h), from one set-up of
// that model (response::StiffnessUpdate, the Woodbury identity) instead of a set-up per model: what the
// basin probes of a fit (fit::SolveWithProbes) evaluate by the hundred, each model with one or two such
// parameters changed by a factor. The residuals equal Comparison::Residuals() of the changed model to
// rounding (tests/compare/parameter_probes_test.cc).

#include <Eigen/Core>

#include <memory>
#include <utility>
#include <vector>

#include "stagefit/compare/residuals.h"
#include "stagefit/model/model_spec.h"
#include "stagefit/model/parameters.h"
#include "stagefit/response/stiffness_update.h"

namespace stagefit::compare {

class ParameterProbes {
 public:
  /// Probes around `spec` (the model at the point probed, of the layout `comparison` was created for)
  /// of `parameters` (of `spec`): those of kind stiffness, damping, coupling stiffness or coupling
  /// damping whose system derivative is constant (model::HasAnalyticDerivative) can be probed; a loss
  /// factor (K_loss = eta k is bilinear), a mass (it also moves the ground-input term) and an effect's
  /// parameter cannot. `comparison` must outlive the probes. Throws as Comparison::Residuals() does when
  /// `spec` cannot be evaluated.
  ParameterProbes(const Comparison& comparison, const model::ModelSpec& spec,
                  const std::vector<model::ParameterInfo>& parameters);

  /// Whether parameters[k] can be probed.
  bool CanProbe(int k) const { return probed_[static_cast<size_t>(k)] != 0; }
  /// Whether any parameter can.
  bool any() const { return update_ != nullptr; }

  /// r (Comparison::Residuals(), resized to num_residuals()) of `spec` with parameters[k] set to
  /// `value` for each (k, value) of `changes` (each CanProbe(k)). Returns false when the changed model
  /// cannot be evaluated so (a pole of it on the grid, or more coordinates changed than
  /// response::StiffnessUpdate::kMaxChanged). Throws as Residuals() of the changed model does: InputError
  /// when it is not a valid model (a coupling beyond its joint's stiffnesses), NumericalError when its
  /// response is zero or not finite at a used point; and InputError for a k that cannot be probed.
  /// Safe to call from several threads at once.
  bool Residuals(const std::vector<std::pair<int, double>>& changes, Eigen::VectorXd* r) const;

 private:
  const Comparison* comparison_;
  model::ModelSpec spec_;
  std::vector<model::ParameterInfo> parameters_;
  std::vector<double> values_;     // the parameters' values in spec_
  std::vector<char> probed_;       // per parameter: can be probed (its change may have no entries)
  std::vector<std::vector<response::DynamicStiffnessDerivative::Entry>> entries_;  // dZ/dp per parameter
  std::shared_ptr<const response::StiffnessUpdate> update_;
};

/// The errors (Comparison::Error()) of `specs`, models of `comparison`'s layout, +infinity where a
/// model cannot be built or evaluated: what a scan of one effect parameter across a grid asks
/// (diagnose::ScanErrors). Models whose systems differ from that of the grid's middle model only in K,
/// C and K_loss, in at most response::StiffnessUpdate::kMaxChanged coordinates each (a servo's or an
/// extra body's spring, a coupling term), are evaluated from one set-up of that model by the Woodbury
/// identity (response::StiffnessUpdate), when all of them together touch at most kMaxChanged
/// coordinates; the others, and any whose update fails (a pole on the grid), are set up anew. The errors equal Comparison::Error() to rounding (kAgreement in
/// tests/compare/parameter_probes_test.cc). Runs on every core. `num_by_update`, when given, is set
/// to the number of models evaluated by the update.
std::vector<double> ErrorsOfStiffnessVariants(const Comparison& comparison, const std::vector<model::ModelSpec>& specs,
                                              int* num_by_update = nullptr);

}  // namespace stagefit::compare
