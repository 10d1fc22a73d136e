#include "stagefit/compare/parameter_probes.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <optional>
#include <string>

#include "stagefit/common/error.h"
#include "stagefit/common/parallel.h"
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

std::vector<double> ErrorsOfStiffnessVariants(const Comparison& comparison, const std::vector<model::ModelSpec>& specs,
                                              int* num_by_update) {
  using Entry = response::DynamicStiffnessDerivative::Entry;
  const int n = static_cast<int>(specs.size());
  std::vector<double> errors(specs.size(), std::numeric_limits<double>::infinity());
  if (n == 0) return errors;

  // The reference: the model nearest the middle of the list that can be built.
  std::optional<model::SecondOrderSystem> reference;
  for (int d = 0; d <= n / 2 && !reference; ++d) {
    for (const int k : {n / 2 - d, n / 2 + d}) {
      if (k < 0 || k >= n || reference) continue;
      try {
        reference = comparison.ModelSystem(specs[static_cast<size_t>(k)]);
      } catch (const std::exception&) {
      }
    }
  }

  // Each model's change of the reference's dynamic stiffness, when it is one the update takes.
  std::vector<std::vector<Entry>> changes(specs.size());
  std::vector<char> by_update(specs.size(), 0);
  if (reference) {
    const model::SecondOrderSystem& a = *reference;
    ParallelFor(n, [&](int k, int) {
      try {
        const model::SecondOrderSystem b = comparison.ModelSystem(specs[static_cast<size_t>(k)]);
        if (!model::SameCoordinatesAndChannels(a, b) || a.M != b.M || a.K.size() != b.K.size() ||
            a.C.size() != b.C.size() || a.K_loss.size() != b.K_loss.size()) {
          return;
        }
        model::SystemDerivative d;
        d.dK = b.K - a.K;
        d.dC = b.C - a.C;
        d.dK_loss = b.K_loss - a.K_loss;
        std::vector<Entry> entries = response::MakeDynamicStiffnessDerivative(d, "").entries;
        std::vector<int> coordinates;
        for (const Entry& e : entries) {
          for (const int c : {e.row, e.col}) {
            if (std::find(coordinates.begin(), coordinates.end(), c) == coordinates.end()) coordinates.push_back(c);
          }
        }
        if (coordinates.size() > static_cast<size_t>(response::StiffnessUpdate::kMaxChanged)) return;
        changes[static_cast<size_t>(k)] = std::move(entries);
        by_update[static_cast<size_t>(k)] = 1;
      } catch (const std::exception&) {
        // Not a model: the full evaluation below says so.
      }
    });
  }
  // One set-up for them all, on the coordinates any of them changes (as few as one change may touch).
  std::vector<char> touched(reference ? static_cast<size_t>(reference->num_dofs()) : 0, 0);
  for (size_t k = 0; k < specs.size(); ++k) {
    for (const Entry& e : changes[k]) touched[static_cast<size_t>(e.row)] = touched[static_cast<size_t>(e.col)] = 1;
  }
  std::vector<int> coordinates;
  for (size_t c = 0; c < touched.size(); ++c) {
    if (touched[c]) coordinates.push_back(static_cast<int>(c));
  }
  std::optional<response::StiffnessUpdate> update;
  if (std::find(by_update.begin(), by_update.end(), 1) != by_update.end() &&
      coordinates.size() <= static_cast<size_t>(response::StiffnessUpdate::kMaxChanged)) {
    try {
      update = response::StiffnessUpdate::Create(*reference, comparison.frequency_hz(), comparison.response_quantity(),
                                                 coordinates, comparison.frf_options());
    } catch (const std::exception&) {
    }
  }

  std::atomic<int> updated{0};
  ParallelFor(n, [&](int k, int) {
    const model::ModelSpec& spec = specs[static_cast<size_t>(k)];
    try {
      if (update && by_update[static_cast<size_t>(k)]) {
        Eigen::MatrixXcd values;
        if (update->Evaluate(changes[static_cast<size_t>(k)], &values)) {
          ++updated;
          Eigen::VectorXd r;
          comparison.ResidualsWithModelResponse(spec, values, &r);
          const double error = r.norm();
          if (std::isfinite(error)) errors[static_cast<size_t>(k)] = error;
          return;
        }
      }
      const double error = comparison.Error(spec);  // set up anew
      if (std::isfinite(error)) errors[static_cast<size_t>(k)] = error;
    } catch (const std::exception&) {
      // A model that cannot be built or evaluated: left at +infinity.
    }
  });
  if (num_by_update) *num_by_update = updated;
  return errors;
}

}  // namespace stagefit::compare
