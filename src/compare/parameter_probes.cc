#include "stagefit/compare/parameter_probes.h"

#include <algorithm>
#include <string>

#include "stagefit/common/error.h"
#include "stagefit/model/assembled_model.h"

namespace stagefit::compare {

namespace {

bool EntersLinearly(const model::ModelSpec& spec, const model::ParameterInfo& p) {
  switch (p.kind) {
    case model::ParameterKind::kStiffness:
    case model::ParameterKind::kDamping:
    case model::ParameterKind::kCouplingStiffness:
    case model::ParameterKind::kCouplingDamping:
      return model::HasAnalyticDerivative(spec, p);
    case model::ParameterKind::kLossFactor:
    case model::ParameterKind::kMass:
    case model::ParameterKind::kEffect:
      return false;
  }
  return false;
}

}  // namespace

ParameterProbes::ParameterProbes(const Comparison& comparison, const model::ModelSpec& spec,
                                 const std::vector<model::ParameterInfo>& parameters)
    : comparison_(&comparison), spec_(spec), parameters_(parameters) {
  const size_t n = parameters.size();
  values_.resize(n);
  probed_.assign(n, 0);
  entries_.resize(n);
  const auto assembled = model::AssembledModel::Assemble(spec_, "model '" + spec_.name + "'");
  std::vector<char> touched;
  for (size_t k = 0; k < n; ++k) {
    values_[k] = model::GetParameter(spec_, parameters[k]);
    if (!EntersLinearly(spec_, parameters[k])) continue;
    const model::SystemDerivative d = model::CalcSystemDerivative(assembled, parameters[k]);
    if (d.dM.size() && d.dM.cwiseAbs().maxCoeff() != 0.0) continue;
    entries_[k] = response::MakeDynamicStiffnessDerivative(d, parameters[k].name).entries;
    probed_[k] = 1;
    for (const auto& e : entries_[k]) {
      if (touched.size() <= static_cast<size_t>(std::max(e.row, e.col))) touched.resize(std::max(e.row, e.col) + 1, 0);
      touched[e.row] = touched[e.col] = 1;
    }
  }
  std::vector<int> coordinates;
  for (size_t c = 0; c < touched.size(); ++c) {
    if (touched[c]) coordinates.push_back(static_cast<int>(c));
  }
  if (std::find(probed_.begin(), probed_.end(), 1) == probed_.end()) return;
  update_ = std::make_shared<const response::StiffnessUpdate>(response::StiffnessUpdate::Create(
      comparison.ModelSystem(spec_), comparison.frequency_hz(), comparison.response_quantity(), coordinates,
      comparison.frf_options()));
}

bool ParameterProbes::Residuals(const std::vector<std::pair<int, double>>& changes, Eigen::VectorXd* r) const {
  std::vector<response::DynamicStiffnessDerivative::Entry> change;
  // The changed model must be one (a coupling can make its joint's stiffness indefinite): checked as
  // its set-up would check it.
  model::ModelSpec changed = spec_;
  for (const auto& [k, value] : changes) {
    if (k < 0 || static_cast<size_t>(k) >= probed_.size() || !probed_[static_cast<size_t>(k)]) {
      throw InputError("parameter probes: parameter " + std::to_string(k) + " cannot be probed");
    }
    model::SetParameter(changed, parameters_[static_cast<size_t>(k)], value);
    const double delta = value - values_[static_cast<size_t>(k)];
    for (auto e : entries_[static_cast<size_t>(k)]) {
      e.stiffness *= delta;
      e.damping *= delta;
      change.push_back(e);
    }
  }
  if (!changes.empty()) model::CheckModel(changed, "model '" + changed.name + "'");
  Eigen::MatrixXcd values;
  if (!update_ || !update_->Evaluate(change, &values)) return false;
  comparison_->ResidualsWithModelResponse(spec_, values, r);
  return true;
}

}  // namespace stagefit::compare
