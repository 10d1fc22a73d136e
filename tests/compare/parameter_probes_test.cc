#include "stagefit/compare/parameter_probes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "compare_test_util.h"
#include "stagefit/common/error.h"
#include "stagefit/model/effects.h"
#include "stagefit/model/model_file.h"
#include "stagefit/model/parameters.h"

namespace stagefit::compare {
namespace {

using testing::LogFrequencies;
using testing::MakeSyntheticMeasurement;

// The probed residuals and those of the changed model set up anew agree to this fraction of the
// residuals' norm: the responses agree to ~1e-13 of each element's peak (response::StiffnessUpdate),
// and ln(H_model / H_measured) carries that over.
constexpr double kAgreement = 1e-9;

// A measurement of the micro-station with its stiffnesses changed, a 6 kg payload on the hexapod, and
// the model compared with it: the micro-station with a payload of 4 kg and a correction of one
// channel's geometry (which re-projects the measured side in compliance space).
struct ProbeCase {
  model::ModelSpec spec;
  measurement::FrfData data;
};

ProbeCase MakeCase() {
  ProbeCase c;
  model::ModelSpec truth = model::DefaultModelSpec();
  for (auto& joint : truth.joints) {
    for (double& k : joint.stiffness) k *= 1.3;
  }
  model::ApplyEffect(truth, model::ParseEffect("payload@hexapod:mass=6,z=0.06", truth));
  c.data = MakeSyntheticMeasurement(truth, LogFrequencies(5.0, 400.0, 150));
  c.spec = model::DefaultModelSpec();
  model::ApplyEffect(c.spec, model::ParseEffect("payload@hexapod:mass=4,z=0.05", c.spec));
  return c;
}

TEST(ParameterProbes, AgreeWithTheResidualsOfTheChangedModelInBothSpaces) {
  ProbeCase base = MakeCase();
  for (const ComparisonSpace space : {ComparisonSpace::kCompliance, ComparisonSpace::kRaw}) {
    ComparisonOptions options;
    options.space = space;
    const Comparison comparison = Comparison::Create(base.spec, base.data, options);
    model::ModelSpec spec = base.spec;
    model::ApplyEffect(spec, model::ParseEffect("sensor-geometry@" + comparison.CorrectableChannels()[2] + ":rz=4 deg", spec,
                                                comparison.CorrectableChannels()));
    const std::vector<model::ParameterInfo> params = model::MatchParameters(spec, model::WithEffectParameters({"*.k.*", "*.c.*", "*.m"}, spec));
    const ParameterProbes probes(comparison, spec, params);
    ASSERT_TRUE(probes.any());
    int probed = 0;
    for (int k = 0; k < static_cast<int>(params.size()); ++k) {
      const model::ParameterInfo& p = params[static_cast<size_t>(k)];
      const bool joint_term = p.kind == model::ParameterKind::kStiffness || p.kind == model::ParameterKind::kDamping;
      EXPECT_EQ(probes.CanProbe(k), joint_term) << p.name;
      if (!probes.CanProbe(k)) {
        Eigen::VectorXd r;
        EXPECT_THROW(probes.Residuals({{k, 1.0}}, &r), InputError) << p.name;
        continue;
      }
      const double value = model::GetParameter(spec, p);
      for (const double factor : {0.125, 4.0}) {
        Eigen::VectorXd r_probe, r;
        ASSERT_TRUE(probes.Residuals({{k, value * factor}}, &r_probe)) << p.name;
        model::ModelSpec changed = spec;
        model::SetParameter(changed, p, value * factor);
        comparison.Residuals(changed, &r);
        EXPECT_LT((r_probe - r).norm(), kAgreement * r.norm()) << ToString(space) << " " << p.name << " x " << factor;
        ++probed;
      }
    }
    EXPECT_EQ(probed, 2 * (27 + 27)) << ToString(space);

    // Two springs at once (a series probe), and no change at all.
    const int a = static_cast<int>(std::find_if(params.begin(), params.end(), [](const auto& p) { return p.name == "ry.k.Dz"; }) - params.begin());
    const int b = static_cast<int>(std::find_if(params.begin(), params.end(), [](const auto& p) { return p.name == "hexapod.k.Dz"; }) - params.begin());
    ASSERT_LT(b, static_cast<int>(params.size()));
    model::ModelSpec changed = spec;
    const double va = 3.0 * model::GetParameter(spec, params[a]), vb = 0.4 * model::GetParameter(spec, params[b]);
    model::SetParameter(changed, params[a], va);
    model::SetParameter(changed, params[b], vb);
    Eigen::VectorXd r_probe, r;
    ASSERT_TRUE(probes.Residuals({{a, va}, {b, vb}}, &r_probe));
    comparison.Residuals(changed, &r);
    EXPECT_LT((r_probe - r).norm(), kAgreement * r.norm()) << ToString(space);
    ASSERT_TRUE(probes.Residuals({}, &r_probe));
    comparison.Residuals(spec, &r);
    EXPECT_LT((r_probe - r).norm(), kAgreement * r.norm()) << ToString(space);
  }
}

TEST(ParameterProbes, RefuseAChangedModelThatIsNoModel) {
  // A coupling beyond sqrt(k_aa k_bb) makes its joint's stiffness indefinite: the set-up of the changed
  // model would refuse it (InputError), and so do the probes.
  const ProbeCase base = MakeCase();
  model::ModelSpec spec = model::DefaultModelSpec();
  for (auto& joint : spec.joints) {
    if (joint.name == "hexapod") joint.couplings.push_back({Dof::kDy, Dof::kRx, 1e3, 0.0});
  }
  const Comparison comparison = Comparison::Create(spec, base.data);
  const std::vector<model::ParameterInfo> params = model::MatchParameters(spec, {"hexapod.k.*"});
  const ParameterProbes probes(comparison, spec, params);
  const int k = static_cast<int>(std::find_if(params.begin(), params.end(), [](const auto& p) { return p.name == "hexapod.k.Dy-Rx"; }) - params.begin());
  ASSERT_LT(k, static_cast<int>(params.size()));
  ASSERT_TRUE(probes.CanProbe(k));
  Eigen::VectorXd r;
  EXPECT_TRUE(probes.Residuals({{k, 2e3}}, &r));
  EXPECT_THROW(probes.Residuals({{k, 1e12}}, &r), InputError);
}

TEST(ParameterProbes, NoneWithoutAJointTermAmongTheParameters) {
  ProbeCase base = MakeCase();
  const Comparison comparison = Comparison::Create(base.spec, base.data);
  const ParameterProbes probes(comparison, base.spec, model::MatchParameters(base.spec, {"payload@*"}));
  EXPECT_FALSE(probes.any());
  Eigen::VectorXd r;
  EXPECT_THROW(probes.Residuals({{0, 5.0}}, &r), InputError);
}

// The errors of a scan's models, each from the update of the list's middle model, against each model
// set up anew: a servo's spring (one coordinate, and its damping with it), a coupling term of the
// hexapod's joint across and beyond the range where the joint stays a model, and an extra body's
// spring across the band (its six coordinates). A model that also changes a mass is set up anew.
TEST(ErrorsOfStiffnessVariants, AgreeWithTheErrorOfEachModelSetUpAnew) {
  const ProbeCase base = MakeCase();
  auto scan = [&](const std::string& effect, const std::vector<std::pair<std::string, double>>& values) {
    std::vector<model::ModelSpec> specs;
    for (const auto& [parameter, value] : values) {
      model::ModelSpec spec = base.spec;
      model::Effect e = model::ParseEffect(effect, spec);
      e.parameters[parameter] = value;
      if (e.name == "extra-body") e.parameters["kr"] = value * 1e-3;
      model::ApplyEffect(spec, e);
      specs.push_back(spec);
    }
    return specs;
  };
  std::vector<std::pair<std::string, double>> servo, coupling, body;
  for (int i = 0; i <= 20; ++i) servo.push_back({"k", 2e8 * std::pow(10.0, -2.0 + 0.2 * i)});
  for (int i = 0; i <= 20; ++i) coupling.push_back({"k", -3e8 + 3e7 * i});
  for (int i = 0; i <= 20; ++i) body.push_back({"k", 1.0 * std::pow(2 * M_PI * 10.0 * std::pow(40.0, i / 20.0), 2)});
  std::vector<model::ModelSpec> mixed = scan("extra-body@hexapod:mass=1", body);
  model::ApplyEffect(mixed[3], model::ParseEffect("payload@ry:mass=2", mixed[3]));  // a mass changes too

  for (const ComparisonSpace space : {ComparisonSpace::kCompliance, ComparisonSpace::kRaw}) {
    ComparisonOptions options;
    options.space = space;
    const Comparison comparison = Comparison::Create(base.spec, base.data, options);
    struct Case {
      std::string name;
      std::vector<model::ModelSpec> specs;
      int expect_updated;
    };
    const std::vector<Case> cases = {{"servo", scan("servo-stiffness@ty.Dy", servo), 21},
                                     {"coupling", scan("coupled-stiffness@hexapod.Dx-Ry", coupling), -1},
                                     {"body", scan("extra-body@hexapod:mass=1", body), 21},
                                     {"mixed", mixed, 20}};
    for (const Case& c : cases) {
      int updated = -1;
      const std::vector<double> errors = ErrorsOfStiffnessVariants(comparison, c.specs, &updated);
      ASSERT_EQ(errors.size(), c.specs.size());
      int invalid = 0;
      for (size_t k = 0; k < c.specs.size(); ++k) {
        double anew = std::numeric_limits<double>::infinity();
        try {
          anew = comparison.Error(c.specs[k]);
        } catch (const InputError&) {
          ++invalid;
        }
        if (std::isinf(anew)) {
          EXPECT_TRUE(std::isinf(errors[k])) << c.name << " " << k;
        } else {
          EXPECT_LT(std::abs(errors[k] - anew), kAgreement * anew) << ToString(space) << " " << c.name << " " << k;
        }
      }
      if (c.name == "coupling") {
        EXPECT_GT(invalid, 0);  // the ends of the list make the joint indefinite
        EXPECT_EQ(updated, 21 - invalid) << ToString(space);
      } else {
        EXPECT_EQ(invalid, 0) << c.name;
        EXPECT_EQ(updated, c.expect_updated) << ToString(space) << " " << c.name;
      }
    }
  }
}

}  // namespace
}  // namespace stagefit::compare
