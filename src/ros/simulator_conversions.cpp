#include "pedicle_drilling/ros/simulator_conversions.hpp"

#include <tf2_eigen/tf2_eigen.h>

#include <algorithm>
#include <cmath>
#include <sstream>

#include "pedicle_drilling/core/breathing/motion_model_io.hpp"

namespace pedicle_drilling {

core::StreamRates streamRates(const SimulatorNodeParams& params) {
  core::StreamRates rates;
  rates.joint_state_hz = params.joint_state_rate_hz;
  rates.tf_hz = params.tf_rate_hz;
  rates.ground_truth_hz = params.ground_truth_rate_hz;
  rates.tracker_hz = params.tracker_rate_hz;
  rates.controller_state_hz = params.controller_state_rate_hz;
  rates.tidal_volume_hz = params.tidal_volume_rate_hz;
  return rates;
}

core::BenchTransport benchTransport(const SimulatorNodeParams& params, std::uint64_t seed) {
  return {params.command_delay_s, params.command_jitter_s, seed};
}

SimulatorNodeParams loadSimulatorParams(const ros::NodeHandle& private_nh) {
  const ParamLoader loader(private_nh);
  const auto& table = SimulatorNodeParams::table();
  loader.rejectUndeclared(table, "trial_distribution");
  loader.rejectUndeclared(table, "ventilator");
  SimulatorNodeParams params;
  loader.load(table, &params);
  return params;
}

std::unique_ptr<core::DrillingSimulation> makeSimulation(const SimulatorNodeParams& params,
                                                         const ParamLoader& loader) {
  const std::string xml = loader.readFile("urdf_path", params.urdf_path);
  try {
    return std::make_unique<core::DrillingSimulation>(xml, params.sim,
                                                      static_cast<std::uint64_t>(params.seed));
  } catch (const std::exception& e) {
    throw std::runtime_error("URDF '" + params.urdf_path +
                             "' is not a usable workcell: " + e.what());
  }
}

core::TrajectoryCommand fromMsg(const trajectory_msgs::JointTrajectory& msg, double now,
                                double time_offset) {
  const double start = msg.header.stamp.isZero() ? now : msg.header.stamp.toSec() - time_offset;
  core::TrajectoryCommand command;
  command.joint_names = msg.joint_names;
  // The new trajectory takes over at its stamp (JointTrajectoryController); zero: now.
  if (!msg.header.stamp.isZero()) command.start_time_s = start;
  for (const trajectory_msgs::JointTrajectoryPoint& p : msg.points) {
    command.points.push_back(
        {start + p.time_from_start.toSec(), p.positions, p.velocities, p.accelerations});
  }
  return command;
}

std::optional<core::BoneMotionModel> loadBoneMotionModel(const SimulatorNodeParams& node,
                                                         const ParamLoader& params) {
  const std::string& path = node.bone_motion_model_path;
  if (path.empty()) return std::nullopt;
  try {
    const core::PatientModel patient = core::readModelYaml(path);
    const core::AxisModelRecord& ap = patient.axes[static_cast<int>(core::Axis::kAP)];
    core::BoneMotionModel model;
    model.q1_ap_mm_per_ml = ap.model.q1;
    model.q2_ap_mm_s_per_ml = ap.model.q2;
    return model;
  } catch (const std::exception& e) {
    params.fail("bone_motion_model_path", "= '" + path + "': " + e.what());
  }
}

std::string applySpecimenRequest(const ResetSimulation::Request& request,
                                 core::SpecimenDistribution* specimen) {
  const struct {
    const char* field;
    double mm;
    double* mean_m;
    double* sd_m;
  } layers[] = {
      {"outer_cortical_thickness_mm", request.outer_cortical_thickness_mm,
       &specimen->outer_cortical_thickness_mean_m, &specimen->outer_cortical_thickness_sd_m},
      {"cancellous_thickness_mm", request.cancellous_thickness_mm,
       &specimen->cancellous_thickness_mean_m, &specimen->cancellous_thickness_sd_m},
      {"inner_cortical_thickness_mm", request.inner_cortical_thickness_mm,
       &specimen->inner_cortical_thickness_mean_m, &specimen->inner_cortical_thickness_sd_m},
  };
  const double min_mm = specimen->min_layer_thickness_m * 1e3;
  for (const auto& layer : layers) {
    if (layer.mm == 0.0) continue;
    if (!(layer.mm >= min_mm && layer.mm <= 100.0)) {
      std::ostringstream os;
      os << "request field " << layer.field << " = " << layer.mm << " is not 0 (drawn) or in ["
         << min_mm << ", 100] mm";
      return os.str();
    }
    *layer.mean_m = layer.mm * 1e-3;
    *layer.sd_m = 0.0;
  }
  return "";
}

std::string resetSummary(const core::DrillingSimulation& sim,
                         const ResetSimulation::Request& request,
                         const std::optional<core::BoneMotionModel>& bone_motion) {
  std::ostringstream os;
  os << "new specimen and patient from seed " << request.seed << " (virtual volunteer "
     << sim.patient().volunteer_id << "), bone " << (request.moving_bone ? "moving" : "stationary")
     << ", arm at home";
  if (bone_motion) {
    os << "; the bone plays the model AP d = " << bone_motion->q1_ap_mm_per_ml << " Tv + "
       << bone_motion->q2_ap_mm_s_per_ml << " dTv/dt (bone_motion_model_path)";
  }
  return os.str();
}

void fillResetResponse(const core::DrillingSimulation& sim, ResetSimulation::Response* response) {
  const core::BoneSpecimen& s = sim.process().specimen();
  response->outer_cortical_thickness_m = s.outerCorticalThickness();
  response->cancellous_thickness_m = s.cancellousThickness();
  response->inner_cortical_thickness_m = s.innerCorticalThickness();
  const core::TrialConditions& c = sim.trialConditions();
  response->volunteer_id = c.volunteer_id;
  response->patient_amplitude_scale = c.patient_amplitude_scale;
  response->ventilator_rate_bpm = c.ventilator_rate_bpm;
  response->ventilator_tidal_volume_ml = c.ventilator_tidal_volume_ml;
  response->force_noise_sd_n = c.force_noise_sd_n;
  response->arm_stiffness_scale = c.arm_stiffness_scale;
}

DrillingPlan toMsg(const core::DrillingPlan& plan, const ros::Time& stamp) {
  DrillingPlan msg;
  msg.header.stamp = stamp;
  msg.header.frame_id = plan.frame;
  msg.entry.x = plan.entry.x();
  msg.entry.y = plan.entry.y();
  msg.entry.z = plan.entry.z();
  msg.direction.x = plan.direction.x();
  msg.direction.y = plan.direction.y();
  msg.direction.z = plan.direction.z();
  msg.depth_m = plan.depth_m;
  msg.entry_tolerance_m = plan.entry_tolerance_m;
  return msg;
}

GroundTruth toMsg(const core::SimulationGroundTruth& g, const ros::Time& stamp) {
  GroundTruth m;
  m.header.stamp = stamp;
  m.header.frame_id = "bone";
  m.seed = g.seed;
  m.specimen_layer = core::materialName(g.layer);
  m.tip_depth_m = g.tip_depth_m;
  m.max_depth_cut_m = g.max_depth_cut_m;
  m.outer_cortical_end_m = g.outer_cortical_end_m;
  m.inner_cortical_start_m = g.inner_cortical_start_m;
  m.inner_cortical_end_m = g.inner_cortical_end_m;
  m.residual_inner_cortical_m = g.residual_inner_cortical_m;
  m.breakthrough = g.breakthrough;
  m.thrust_n = g.thrust_n;
  m.contact = g.contact;
  m.contact_loss_count = g.contact_loss_count;
  m.feed_per_rev_m = g.feed_per_rev_m;
  m.bone_displacement_m.x = g.bone_displacement_m.x();
  m.bone_displacement_m.y = g.bone_displacement_m.y();
  m.bone_displacement_m.z = g.bone_displacement_m.z();
  m.tidal_volume_ml = g.tidal_volume_ml;
  m.relative_ap_m = g.relative_ap_m;
  m.spindle_rpm = g.spindle_rpm;
  m.feed_joint_m = g.feed_joint_m;
  m.drives_halted = g.drives_halted;
  m.drive_guard_trips = g.drive_guard_trips;
  m.controller_aborts = g.controller_aborts;
  return m;
}

geometry_msgs::Wrench toWrenchMsg(const Eigen::Matrix<double, 6, 1>& wrench) {
  geometry_msgs::Wrench msg;
  msg.force.x = wrench[0];
  msg.force.y = wrench[1];
  msg.force.z = wrench[2];
  msg.torque.x = wrench[3];
  msg.torque.y = wrench[4];
  msg.torque.z = wrench[5];
  return msg;
}

Eigen::Matrix<double, 6, 1> fromWrenchMsg(const geometry_msgs::Wrench& msg) {
  Eigen::Matrix<double, 6, 1> wrench;
  wrench << msg.force.x, msg.force.y, msg.force.z, msg.torque.x, msg.torque.y, msg.torque.z;
  return wrench;
}

core::TareRequest fromMsg(const TareRequest& msg) {
  return {static_cast<int>(std::min<std::uint32_t>(msg.samples, 1000000)), msg.max_spread_n};
}

TareResult toMsg(const core::TareResult& result, const ros::Time& stamp) {
  TareResult msg;
  msg.header.stamp = stamp;
  msg.header.frame_id = "ft_sensor";
  msg.success = result.success;
  msg.samples = static_cast<std::uint32_t>(std::max(0, result.samples));
  msg.bias = toWrenchMsg(result.bias);
  msg.spread_n = result.spread_n;
  msg.message = result.message;
  return msg;
}

core::TareResult fromMsg(const TareResult& msg) {
  core::TareResult r;
  r.success = msg.success;
  r.t = msg.header.stamp.toSec();
  r.samples = static_cast<int>(msg.samples);
  r.bias = fromWrenchMsg(msg.bias);
  r.spread_n = msg.spread_n;
  r.message = msg.message;
  return r;
}

geometry_msgs::WrenchStamped wrenchMsg(const core::SimulationStep& step, const ros::Time& stamp) {
  geometry_msgs::WrenchStamped w;
  w.header.stamp = stamp;
  w.header.frame_id = "ft_sensor";
  w.wrench = toWrenchMsg(step.measured_wrench);
  return w;
}

JointTrajectoryControllerState toMsg(const core::ControllerStateSample& state,
                                     const ros::Time& stamp) {
  JointTrajectoryControllerState msg;
  msg.header.stamp = stamp;
  msg.joint_names = state.joint_names;
  msg.desired.positions = state.desired_positions;
  msg.desired.velocities = state.desired_velocities;
  msg.actual.positions = state.actual_positions;
  msg.actual.velocities = state.actual_velocities;
  msg.error.positions = state.error_positions;
  msg.error.velocities = state.error_velocities;
  return msg;
}

core::ControllerStateSample fromMsg(const JointTrajectoryControllerState& msg, double time_offset) {
  core::ControllerStateSample state;
  state.stamp = msg.header.stamp.toSec() - time_offset;
  state.joint_names = msg.joint_names;
  state.desired_positions = msg.desired.positions;
  state.desired_velocities = msg.desired.velocities;
  state.actual_positions = msg.actual.positions;
  state.actual_velocities = msg.actual.velocities;
  state.error_positions = msg.error.positions;
  state.error_velocities = msg.error.velocities;
  return state;
}

sensor_msgs::JointState jointStateMsg(const core::DrillingSimulation& sim, const ros::Time& stamp) {
  sensor_msgs::JointState js;
  js.header.stamp = stamp;
  const Eigen::VectorXd q = sim.armJointPositions();
  const Eigen::VectorXd qd = sim.armJointVelocities();
  const Eigen::VectorXd tau = sim.armJointEfforts();
  for (std::size_t k = 0; k < sim.armJointNames().size(); ++k) {
    js.name.push_back(sim.armJointNames()[k]);
    js.position.push_back(q[k]);
    js.velocity.push_back(qd[k]);
    js.effort.push_back(k < static_cast<std::size_t>(tau.size()) ? tau[k] : 0.0);
  }
  for (const auto& kv : sim.spmsJointStates()) {
    js.name.push_back(kv.first);
    js.position.push_back(kv.second);
    js.velocity.push_back(0.0);
    js.effort.push_back(0.0);
  }
  return js;
}

TidalVolume tidalVolumeMsg(const core::DrillingSimulation& sim, const ros::Time& stamp) {
  const core::BreathScheduler& ventilator = sim.ventilator();
  TidalVolume m;
  m.header.stamp = stamp;
  m.header.frame_id = "ventilator";
  m.volume_ml = sim.ventilatorSample().volume_ml;
  m.flow_ml_s = sim.ventilatorSample().flow_ml_s;
  m.breath_index = static_cast<uint32_t>(ventilator.breathIndex());
  m.time_in_breath_s = sim.sensedTimeInBreath();
  return m;
}

std::vector<geometry_msgs::TransformStamped> toMsg(const std::vector<core::FrameTransform>& frames,
                                                   const ros::Time& stamp) {
  std::vector<geometry_msgs::TransformStamped> out;
  for (const core::FrameTransform& f : frames) {
    geometry_msgs::TransformStamped t = tf2::eigenToTransform(f.transform);
    t.header.stamp = stamp;
    t.header.frame_id = f.parent;
    t.child_frame_id = f.child;
    out.push_back(t);
  }
  return out;
}

}  // namespace pedicle_drilling
