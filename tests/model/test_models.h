#pragma once
// Small models built in code for the model-layer tests.

#include "stagefit/model/model_spec.h"

namespace stagefit::model::testing {

/// One body (mass m, diagonal inertia) on a 6-DoF joint at `joint_origin`, CoM at `com`.
inline ModelSpec SingleBody(double m, const Eigen::Vector3d& inertia, const Eigen::Vector3d& com,
                            const Eigen::Vector3d& joint_origin, const std::array<double, 6>& k) {
  ModelSpec spec;
  spec.name = "single body";
  spec.compliance_frame = "";
  BodySpec b;
  b.name = "body";
  b.mass_kg = m;
  b.com_W = com;
  b.inertia_com_W = inertia.asDiagonal();
  spec.bodies.push_back(b);
  JointSpec j;
  j.name = "joint";
  j.parent = kGroundName;
  j.child = "body";
  j.origin_W = joint_origin;
  j.stiffness = k;
  spec.joints.push_back(j);
  return spec;
}

}  // namespace stagefit::model::testing
