#include "stagefit/response/io_sets.h"

#include "stagefit/common/error.h"

namespace stagefit::response {

IoSet ParseIoSet(const std::string& text, const std::string& context) {
  if (text == "compliance") return IoSet::kCompliance;
  if (text == "raw") return IoSet::kRaw;
  if (text == "stages") return IoSet::kStages;
  if (text == "disturbance") return IoSet::kDisturbance;
  throw InputError(context + " = '" + text + "', expected compliance, raw, stages or disturbance");
}

std::string ToString(IoSet set) {
  switch (set) {
    case IoSet::kCompliance: return "compliance";
    case IoSet::kRaw: return "raw";
    case IoSet::kStages: return "stages";
    case IoSet::kDisturbance: return "disturbance";
  }
  return "compliance";
}

std::vector<model::InputSpec> StageHammerInputs(const model::ModelSpec& spec) {
  const int b = model::FindBody(spec, kStageHammerBody);
  if (b < 0) {
    throw InputError(std::string("stages study: the model has no body '") + kStageHammerBody +
                     "' (the translation stage that receives the hammer impacts)");
  }
  std::vector<model::InputSpec> inputs;
  for (int axis = 0; axis < 3; ++axis) {
    inputs.push_back(model::ForceInput(std::string(kStageHammerBody) + ".hammer.F" + "xyz"[axis], kStageHammerBody,
                                       spec.bodies[b].com_W + kStageHammerOffset, Eigen::Vector3d::Unit(axis)));
  }
  return inputs;
}

std::vector<model::OutputSpec> AllBodyCoMOutputs(const model::ModelSpec& spec) {
  std::vector<model::OutputSpec> outputs;
  for (const auto& body : spec.bodies) {
    for (auto& out : model::BodyCoMOutputs(spec, body.name)) outputs.push_back(out);
  }
  return outputs;
}

model::SecondOrderSystem BuildStagesSystem(const model::AssembledModel& model) {
  return model::BuildSystem(model, StageHammerInputs(model.spec()), AllBodyCoMOutputs(model.spec()));
}

model::SecondOrderSystem BuildDisturbanceSystem(const model::AssembledModel& model) {
  model::ModelSpec spec = model.spec();
  const int x = model::FindFrame(spec, spec.compliance_frame);
  if (x < 0) throw InputError("disturbance study: the model has no compliance frame '" + spec.compliance_frame + "'");
  if (model::FindBody(spec, "granite") < 0) {
    throw InputError("disturbance study: the model has no body 'granite' to measure {X} against");
  }
  if (model::FindFrame(spec, kGraniteReferenceFrame) < 0) {
    model::FrameSpec reference;
    reference.name = kGraniteReferenceFrame;
    reference.body = "granite";
    reference.origin_W = spec.frames[x].origin_W;
    reference.R_WF = spec.frames[x].R_WF;
    spec.frames.push_back(reference);
  }
  const model::AssembledModel with_frame = model::AssembledModel::Assemble(spec, "disturbance study");

  std::vector<model::InputSpec> inputs = model::GroundInputs(with_frame);
  struct JointInput {
    const char* joint;
    Dof dof;
  };
  for (JointInput ji : {JointInput{"ty", Dof::kDz}, JointInput{"ty", Dof::kDx}, JointInput{"rz", Dof::kDz},
                        JointInput{"rz", Dof::kDx}, JointInput{"rz", Dof::kDy}}) {
    const int j = model::FindJoint(spec, ji.joint);
    if (j < 0 || with_frame.dof_index(j, ji.dof) < 0) continue;
    model::InputSpec in;
    in.kind = model::InputSpec::Kind::kJointForce;
    in.name = std::string(ji.joint) + ".F." + std::string(name(ji.dof));
    in.joint = ji.joint;
    in.dof = ji.dof;
    inputs.push_back(in);
  }
  std::vector<model::OutputSpec> outputs;
  for (Dof d : kAllDofs) {
    model::OutputSpec out;
    out.kind = model::OutputSpec::Kind::kRelativeMotion;
    out.name = spec.compliance_frame + "_rel." + std::string(name(d));
    out.frame = spec.compliance_frame;
    out.reference_frame = kGraniteReferenceFrame;
    out.dof = d;
    outputs.push_back(out);
  }
  return model::BuildSystem(with_frame, inputs, outputs);
}

model::SecondOrderSystem BuildIoSetSystem(const model::AssembledModel& model, IoSet set) {
  switch (set) {
    case IoSet::kCompliance: return model::BuildComplianceSystem(model);
    case IoSet::kRaw:
      return model::BuildSystem(model, model::ExcitationInputs(model.spec()), model::SensorOutputs(model.spec()));
    case IoSet::kStages: return BuildStagesSystem(model);
    case IoSet::kDisturbance: return BuildDisturbanceSystem(model);
  }
  return model::BuildComplianceSystem(model);
}

}  // namespace stagefit::response
