#pragma once
// Named inputs and outputs of the assembled model, and the second-order system they define:
//
//     M z'' + C z' + (K + j K_loss) z = B0 u + B2 u''        (u: the inputs)
//     y = Cq z + D0 u                                         (y: displacement-level outputs)
//
// B2 is non-zero only for ground-motion inputs (ground displacement enters through the inertia of the
// stack: B2 = -M_zg); D0 only for absolute outputs driven by ground motion (the rigid translation).
// Frequency responses follow as H(s) = e^{-s tau} (Cq (M s^2 + C s + K + j K_loss)^-1 (B0 + s^2 B2) + D0),
// with tau the acquisition delay; velocity and acceleration are s H and s^2 H.

#include <Eigen/Core>

#include <string>
#include <vector>

#include "stagefit/model/assembled_model.h"

namespace stagefit::model {

/// An input of the linearised model.
struct InputSpec {
  enum class Kind {
    kForce,        ///< force (N) at `position_W` of `body`, along `direction_W`
    kTorque,       ///< torque (Nm) on `body` about `direction_W`
    kJointForce,   ///< force pair (N or Nm) inside DoF `dof` of `joint` (acts on child, reacts on parent)
    kGround,       ///< ground displacement (m) along `dof` (Dx, Dy or Dz)
  };
  Kind kind = Kind::kForce;
  std::string name;
  std::string body;
  std::string joint;
  Dof dof = Dof::kDx;
  Eigen::Vector3d position_W = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction_W = Eigen::Vector3d::UnitX();
};

/// An output of the linearised model (displacement level: m or rad).
struct OutputSpec {
  enum class Kind {
    kFrameMotion,     ///< absolute motion of `frame` along its DoF `dof`, in frame axes; with `frame`
                      ///< empty, of the point `position_W` of `body`, in W axes
    kRelativeMotion,  ///< motion of `frame` relative to the point of `reference_frame`'s body that
                      ///< coincides with `frame`'s origin, in `reference_frame`'s axes, DoF `dof`
    kSensor,          ///< translation of `position_W` on `body` along `direction_W`
    kJointMotion,     ///< relative motion delta of `joint` in DoF `dof`
  };
  Kind kind = Kind::kFrameMotion;
  std::string name;
  std::string frame;
  std::string reference_frame;
  std::string body;
  std::string joint;
  Dof dof = Dof::kDx;
  Eigen::Vector3d position_W = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction_W = Eigen::Vector3d::UnitX();
};

/// The second-order system of the header comment, for a chosen set of inputs and outputs.
struct SecondOrderSystem {
  Eigen::MatrixXd M, C, K, K_loss;   ///< n x n
  Eigen::MatrixXd B0, B2;            ///< n x num_inputs
  Eigen::MatrixXd Cq, D0;            ///< num_outputs x n, num_outputs x num_inputs
  double delay_s = 0.0;
  std::vector<std::string> input_names, output_names, dof_names;
  int num_dofs() const { return static_cast<int>(M.rows()); }
  int num_inputs() const { return static_cast<int>(B0.cols()); }
  int num_outputs() const { return static_cast<int>(Cq.rows()); }
};

/// Same generalised coordinates, channels and delay (bit for bit): the systems differ at most in M,
/// C, K and K_loss.
bool SameCoordinatesAndChannels(const SecondOrderSystem& a, const SecondOrderSystem& b);
/// The same system, every matrix, the delay and the names equal bit for bit.
bool SameSystem(const SecondOrderSystem& a, const SecondOrderSystem& b);

/// Builds the system. Throws InputError naming the input/output and the unknown body, frame or joint,
/// or an imposed joint DoF used as an input (it does no work) or output.
SecondOrderSystem BuildSystem(const AssembledModel& model, const std::vector<InputSpec>& inputs,
                              const std::vector<OutputSpec>& outputs);

/// A translation sensor: `body`'s point `position_W` read along `direction_W` (OutputSpec::kSensor).
OutputSpec SensorOutput(const std::string& name, const std::string& body, const Eigen::Vector3d& position_W,
                        const Eigen::Vector3d& direction_W);
/// A force at `body`'s point `position_W` along `direction_W` (InputSpec::kForce).
InputSpec ForceInput(const std::string& name, const std::string& body, const Eigen::Vector3d& position_W,
                     const Eigen::Vector3d& direction_W);

// Common input/output sets.

/// Forces Fx Fy Fz and torques Mx My Mz at the origin of `frame`, along its axes ("<frame>.Fx" ...).
std::vector<InputSpec> FrameWrenchInputs(const ModelSpec& spec, const std::string& frame);
/// Absolute motion Dx..Rz of `frame` ("<frame>.Dx" ...).
std::vector<OutputSpec> FrameMotionOutputs(const ModelSpec& spec, const std::string& frame);
/// The model's [[sensor]] entries as outputs and [[excitation]] entries as force inputs.
std::vector<OutputSpec> SensorOutputs(const ModelSpec& spec);
std::vector<InputSpec> ExcitationInputs(const ModelSpec& spec);
/// The ground-motion inputs "ground.Dx" ... that the model declares.
std::vector<InputSpec> GroundInputs(const AssembledModel& model);
/// Motion of the CoM of `body` (Dx..Rz along W), named "<body>.Dx" ...
std::vector<OutputSpec> BodyCoMOutputs(const ModelSpec& spec, const std::string& body);

/// The compliance system: wrench at the compliance frame {X} -> absolute motion of {X} (6 x 6).
SecondOrderSystem BuildComplianceSystem(const AssembledModel& model);

}  // namespace stagefit::model
