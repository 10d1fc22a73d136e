#include "stagefit/model/linear_system.h"

#include "stagefit/common/error.h"

namespace stagefit::model {
namespace {

int RequireIoBody(const ModelSpec& spec, const std::string& body, const std::string& what) {
  int b = FindBody(spec, body);
  if (b < 0) throw InputError(what + ": body '" + body + "' is not a body of the model");
  return b;
}

const FrameSpec& RequireFrame(const ModelSpec& spec, const std::string& frame, const std::string& what) {
  int f = FindFrame(spec, frame);
  if (f < 0) throw InputError(what + ": frame '" + frame + "' is not a frame of the model");
  return spec.frames[f];
}

int RequireFreeJointDof(const AssembledModel& model, const std::string& joint, Dof dof, const std::string& what) {
  int j = FindJoint(model.spec(), joint);
  if (j < 0) throw InputError(what + ": joint '" + joint + "' is not a joint of the model");
  int k = model.dof_index(j, dof);
  if (k < 0) {
    throw InputError(what + ": DoF " + std::string(name(dof)) + " of joint '" + joint +
                     "' is imposed (a constraint), so it has no force or motion of its own");
  }
  return k;
}

Matrix6d AxesFromWorld(const Eigen::Matrix3d& R_WF) {
  Matrix6d A = Matrix6d::Zero();
  A.topLeftCorner<3, 3>() = R_WF.transpose();
  A.bottomRightCorner<3, 3>() = R_WF.transpose();
  return A;
}

}  // namespace

bool SameCoordinatesAndChannels(const SecondOrderSystem& a, const SecondOrderSystem& b) {
  return a.num_dofs() == b.num_dofs() && a.dof_names == b.dof_names && a.input_names == b.input_names &&
         a.output_names == b.output_names && a.B0 == b.B0 && a.B2 == b.B2 && a.Cq == b.Cq && a.D0 == b.D0 &&
         a.delay_s == b.delay_s;
}

bool SameSystem(const SecondOrderSystem& a, const SecondOrderSystem& b) {
  return SameCoordinatesAndChannels(a, b) && a.M == b.M && a.C == b.C && a.K == b.K && a.K_loss == b.K_loss;
}

SecondOrderSystem BuildSystem(const AssembledModel& model, const std::vector<InputSpec>& inputs,
                              const std::vector<OutputSpec>& outputs) {
  const ModelSpec& spec = model.spec();
  const int n = model.num_dofs();
  SecondOrderSystem sys;
  sys.M = model.M();
  sys.C = model.C();
  sys.K = model.K();
  sys.K_loss = model.K_loss();
  sys.delay_s = spec.acquisition_delay_s;
  sys.dof_names = model.dof_names();
  const int ni = static_cast<int>(inputs.size());
  const int no = static_cast<int>(outputs.size());
  sys.B0 = Eigen::MatrixXd::Zero(n, ni);
  sys.B2 = Eigen::MatrixXd::Zero(n, ni);
  sys.Cq = Eigen::MatrixXd::Zero(no, n);
  sys.D0 = Eigen::MatrixXd::Zero(no, ni);
  std::vector<int> ground_column(ni, -1);  // which ground translation an input is

  for (int i = 0; i < ni; ++i) {
    const InputSpec& in = inputs[i];
    const std::string what = "input '" + in.name + "'";
    sys.input_names.push_back(in.name);
    switch (in.kind) {
      case InputSpec::Kind::kForce:
      case InputSpec::Kind::kTorque: {
        int b = RequireIoBody(spec, in.body, what);
        if (!in.direction_W.allFinite() || in.direction_W.norm() == 0) {
          throw InputError(what + ": direction is zero or not finite, expected a unit vector");
        }
        Eigen::Matrix<double, 6, 1> wrench = Eigen::Matrix<double, 6, 1>::Zero();
        const Eigen::Vector3d dir = in.direction_W.normalized();
        if (in.kind == InputSpec::Kind::kForce) wrench.head<3>() = dir;
        else wrench.tail<3>() = dir;
        sys.B0.col(i) = model.CalcPointMap(b, in.position_W).transpose() * wrench;
        break;
      }
      case InputSpec::Kind::kJointForce:
        sys.B0(RequireFreeJointDof(model, in.joint, in.dof, what), i) = 1.0;
        break;
      case InputSpec::Kind::kGround: {
        if (is_rotation(in.dof)) throw InputError(what + ": ground motion inputs are translations Dx, Dy, Dz");
        int column = -1;
        for (int g = 0, c = 0; g < 3; ++g) {
          if (!spec.ground_inputs[g]) continue;
          if (g == index(in.dof)) column = c;
          ++c;
        }
        if (column < 0) {
          throw InputError(what + ": the model's [ground] inputs do not include " + std::string(name(in.dof)));
        }
        sys.B2.col(i) = -model.M_zg().col(column);
        ground_column[i] = column;
        break;
      }
    }
  }

  const Eigen::MatrixXd& E = model.ground_translation_map();  // 3 x ng
  for (int o = 0; o < no; ++o) {
    const OutputSpec& out = outputs[o];
    const std::string what = "output '" + out.name + "'";
    sys.output_names.push_back(out.name);
    const int d = index(out.dof);
    // Row of the 6-DoF motion [u; theta] (in the output's axes) that this output reads, and the
    // ground translation seen by it (absolute outputs only).
    Eigen::Matrix<double, 1, Eigen::Dynamic> row;
    Eigen::Matrix<double, 1, 3> ground_row = Eigen::Matrix<double, 1, 3>::Zero();
    switch (out.kind) {
      case OutputSpec::Kind::kFrameMotion: {
        Eigen::Matrix3d R_WF = Eigen::Matrix3d::Identity();
        int b;
        Eigen::Vector3d origin;
        if (!out.frame.empty()) {
          const FrameSpec& f = RequireFrame(spec, out.frame, what);
          b = FindBody(spec, f.body);
          origin = f.origin_W;
          R_WF = f.R_WF;
        } else {
          b = RequireIoBody(spec, out.body, what);
          origin = out.position_W;
        }
        Matrix6Xd motion = AxesFromWorld(R_WF) * model.CalcPointMap(b, origin);
        row = motion.row(d);
        if (d < 3) ground_row = R_WF.transpose().row(d);
        break;
      }
      case OutputSpec::Kind::kRelativeMotion: {
        const FrameSpec& f = RequireFrame(spec, out.frame, what);
        const FrameSpec& r = RequireFrame(spec, out.reference_frame, what);
        Matrix6Xd motion = AxesFromWorld(r.R_WF) * (model.CalcPointMap(FindBody(spec, f.body), f.origin_W) -
                                                    model.CalcPointMap(FindBody(spec, r.body), f.origin_W));
        row = motion.row(d);
        break;
      }
      case OutputSpec::Kind::kSensor: {
        int b = RequireIoBody(spec, out.body, what);
        if (!out.direction_W.allFinite() || out.direction_W.norm() == 0) {
          throw InputError(what + ": direction is zero or not finite, expected a unit vector");
        }
        const Eigen::Vector3d dir = out.direction_W.normalized();
        row = dir.transpose() * model.CalcPointMap(b, out.position_W).topRows<3>();
        ground_row = dir.transpose();
        break;
      }
      case OutputSpec::Kind::kJointMotion:
        row = Eigen::RowVectorXd::Unit(n, RequireFreeJointDof(model, out.joint, out.dof, what));
        break;
    }
    sys.Cq.row(o) = row;
    for (int i = 0; i < ni; ++i) {
      if (ground_column[i] >= 0) sys.D0(o, i) = ground_row * E.col(ground_column[i]);
    }
  }
  return sys;
}

OutputSpec SensorOutput(const std::string& name, const std::string& body, const Eigen::Vector3d& position_W,
                        const Eigen::Vector3d& direction_W) {
  OutputSpec out;
  out.kind = OutputSpec::Kind::kSensor;
  out.name = name;
  out.body = body;
  out.position_W = position_W;
  out.direction_W = direction_W;
  return out;
}

InputSpec ForceInput(const std::string& name, const std::string& body, const Eigen::Vector3d& position_W,
                     const Eigen::Vector3d& direction_W) {
  InputSpec in;
  in.kind = InputSpec::Kind::kForce;
  in.name = name;
  in.body = body;
  in.position_W = position_W;
  in.direction_W = direction_W;
  return in;
}

std::vector<InputSpec> FrameWrenchInputs(const ModelSpec& spec, const std::string& frame) {
  const FrameSpec& f = RequireFrame(spec, frame, "compliance inputs");
  static const char* kNames[6] = {"Fx", "Fy", "Fz", "Mx", "My", "Mz"};
  std::vector<InputSpec> inputs;
  for (int i = 0; i < 6; ++i) {
    InputSpec in;
    in.kind = i < 3 ? InputSpec::Kind::kForce : InputSpec::Kind::kTorque;
    in.name = frame + "." + kNames[i];
    in.body = f.body;
    in.position_W = f.origin_W;
    in.direction_W = f.R_WF.col(i % 3);
    inputs.push_back(in);
  }
  return inputs;
}

std::vector<OutputSpec> FrameMotionOutputs(const ModelSpec& spec, const std::string& frame) {
  RequireFrame(spec, frame, "frame outputs");
  std::vector<OutputSpec> outputs;
  for (Dof d : kAllDofs) {
    OutputSpec out;
    out.kind = OutputSpec::Kind::kFrameMotion;
    out.name = frame + "." + std::string(name(d));
    out.frame = frame;
    out.dof = d;
    outputs.push_back(out);
  }
  return outputs;
}

std::vector<OutputSpec> SensorOutputs(const ModelSpec& spec) {
  std::vector<OutputSpec> outputs;
  for (const auto& s : spec.sensors) outputs.push_back(SensorOutput(s.name, s.body, s.position_W, s.direction_W));
  return outputs;
}

std::vector<InputSpec> ExcitationInputs(const ModelSpec& spec) {
  std::vector<InputSpec> inputs;
  for (const auto& e : spec.excitations) inputs.push_back(ForceInput(e.name, e.body, e.position_W, e.direction_W));
  return inputs;
}

std::vector<InputSpec> GroundInputs(const AssembledModel& model) {
  std::vector<InputSpec> inputs;
  for (int g = 0; g < 3; ++g) {
    if (!model.spec().ground_inputs[g]) continue;
    InputSpec in;
    in.kind = InputSpec::Kind::kGround;
    in.dof = static_cast<Dof>(g);
    in.name = std::string(kGroundName) + "." + std::string(kDofNames[g]);
    inputs.push_back(in);
  }
  return inputs;
}

std::vector<OutputSpec> BodyCoMOutputs(const ModelSpec& spec, const std::string& body) {
  int b = RequireIoBody(spec, body, "body outputs");
  std::vector<OutputSpec> outputs;
  for (Dof d : kAllDofs) {
    OutputSpec out;
    out.kind = OutputSpec::Kind::kFrameMotion;
    out.name = body + "." + std::string(name(d));
    out.body = body;
    out.position_W = spec.bodies[b].com_W;
    out.dof = d;
    outputs.push_back(out);
  }
  return outputs;
}

SecondOrderSystem BuildComplianceSystem(const AssembledModel& model) {
  const std::string& frame = model.spec().compliance_frame;
  if (frame.empty()) throw InputError("the model names no compliance_frame in [model]");
  return BuildSystem(model, FrameWrenchInputs(model.spec(), frame), FrameMotionOutputs(model.spec(), frame));
}

}  // namespace stagefit::model
