#include "pedicle_drilling/ros/simulator_outputs.hpp"

#include <rosgraph_msgs/Clock.h>
#include <tf2_eigen/tf2_eigen.h>
#include <urdf_parser/urdf_parser.h>

#include <stdexcept>
#include <utility>

#include "pedicle_drilling/ros/publish_in_order.hpp"
#include "pedicle_drilling/ros/simulator_conversions.hpp"
#include "pedicle_drilling/ros/ventilator_conversions.hpp"

namespace pedicle_drilling {

std::set<std::string> floatingChildren(const std::string& urdf_xml) {
  std::set<std::string> children;
  const urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(urdf_xml);
  if (!model) throw std::runtime_error("urdf_path: the workcell URDF does not parse");
  for (const auto& joint : model->joints_) {
    if (joint.second->type == urdf::Joint::FLOATING) children.insert(joint.second->child_link_name);
  }
  return children;
}

void SimulatorOutputs::advertise(ros::NodeHandle& nh, const SimulatorNodeParams& params,
                                 bool lockstep, bool tidal_volume,
                                 const core::DrillingSimulation& sim,
                                 std::set<std::string> floating) {
  tracker_tf_frame_ = params.tracker_tf_frame;
  floating_frames_ = std::move(floating);
  delayed_markers_.setDelay(params.tracker_delay_s);
  if (params.publish_clock) {
    clock_pub_ = nh.advertise<rosgraph_msgs::Clock>("/clock", 10);
  } else {
    time_offset_ = ros::Time::now().toSec();
  }
  joint_state_pub_ = nh.advertise<sensor_msgs::JointState>("joint_states", 100);
  for (const core::ControllerSpec& c : sim.controllers()) {
    controller_state_pubs_.push_back(
        nh.advertise<JointTrajectoryControllerState>(c.name + "/state", 10));
  }
  wrench_pub_ = nh.advertise<geometry_msgs::WrenchStamped>("ft_sensor/wrench", 2000);
  tare_result_pub_ = nh.advertise<TareResult>("ft_sensor/tare_result", 10, true);
  marker_pub_ = nh.advertise<geometry_msgs::PoseStamped>("tracker/marker_pose", 20);
  ground_truth_pub_ = nh.advertise<GroundTruth>("simulator/ground_truth", 200);
  // The bench's breath sensor (~breath_sensor_rate_hz > 0): the raw flow it samples, as a
  // lab's flow sensor feeds the Ventilator's `flow` breath source.
  if (sim.params().breath_sensor_rate_hz > 0.0) {
    flow_pub_ = nh.advertise<AirwayFlow>("breath_sensor/flow", 200);
  }
  // The bench's planning tool: the plan of the mounted specimen, latched.
  plan_pub_ = nh.advertise<DrillingPlan>("drilling_plan", 1, true);
  publishPlan(sim, sim.time());
  // The simulated ventilator is the device that drives the patient: it publishes what the
  // Ventilator nodelet publishes on hardware-free setups.
  if (tidal_volume) {
    tidal_volume_pub_ = nh.advertise<TidalVolume>("tidal_volume", 200);
    ventilator_settings_pub_ = nh.advertise<VentilatorSettings>("ventilator/settings", 1, true);
    publishInOrder(ventilator_settings_pub_, toMsg(sim.ventilator().model().settings()));
  }
  tf_broadcaster_ = std::make_unique<tf2_ros::TransformBroadcaster>();
  static_broadcaster_ = std::make_unique<tf2_ros::StaticTransformBroadcaster>();
  if (lockstep) step_pub_ = nh.advertise<rosgraph_msgs::Clock>("simulator/step", 10);
  static_broadcaster_->sendTransform(
      toMsg(core::ownFrames(sim.frameTransforms(true), tracker_tf_frame_, floating_frames_),
            stampOf(0.0)));
}

void SimulatorOutputs::resetTrial(double time_offset, double tracker_delay_s) {
  time_offset_ = time_offset;
  delayed_markers_.setDelay(tracker_delay_s);
  delayed_markers_.clear();
  delayed_flow_.clear();
  breaths_.clear();
  last_settings_msg_ = VentilatorSettings();  // the new breathing is announced
}

SimulatorOutputs::StepOutput SimulatorOutputs::publishStep(
    const core::StreamsDue& due, const core::SimulationStep& step, core::DrillingSimulation& sim,
    const std::function<void()>& ground_truth) {
  StepOutput out;
  const double t = step.time_s;
  const auto stream = [&out](bool due) { return out.published |= due, due; };
  if (stream(due.force)) publishWrench(step);
  // The tare result after the sample that completed its window.
  if (step.force_sampled) out.tare = sim.takeTareResult();
  if (out.tare) publishTareResult(*out.tare, t);
  if (stream(due.joint_states)) publishInOrder(joint_state_pub_, jointStateMsg(sim, stampOf(t)));
  if (stream(due.tf)) publishTf(sim, t);
  if (stream(due.controller_states)) publishControllerStates(sim, t);
  if (stream(due.ground_truth)) ground_truth();
  if (stream(due.tracker)) publishMarker(sim, t);
  if (stream(delayed_markers_.due(t))) {
    delayed_markers_.deliverDue(t, [this](const geometry_msgs::PoseStamped& m) { sendMarker(m); });
  }
  if (stream(due.tidal_volume)) publishTidalVolume(sim, t);
  // Not a lockstep stream: its reader, the Ventilator, is not a participant.
  if (sim.breathFlowSampled()) publishFlow(sim, t);
  delayed_flow_.deliverDue(t, [this](const AirwayFlow& m) { publishInOrder(flow_pub_, m); });
  return out;
}

void SimulatorOutputs::publishClock(const ros::Time& stamp) {
  rosgraph_msgs::ClockPtr c = boost::make_shared<rosgraph_msgs::Clock>();
  c->clock = stamp;
  clock_pub_.publish(c);
}

void SimulatorOutputs::publishLockstepStep(const ros::Time& stamp) {
  rosgraph_msgs::ClockPtr c = boost::make_shared<rosgraph_msgs::Clock>();
  c->clock = stamp;
  step_pub_.publish(c);
}

void SimulatorOutputs::publishGroundTruth(const core::DrillingSimulation& sim,
                                          const core::BenchCounters& counters, double t) {
  GroundTruth msg = toMsg(sim.groundTruth(), stampOf(t));
  msg.breath_index = static_cast<std::uint32_t>(sim.ventilator().breathIndex());
  msg.breath_start = stampOf(sim.ventilator().breathStart());
  msg.late_commands = counters.late_commands;
  msg.rejected_commands = counters.rejected_commands;
  msg.max_command_lateness_s = counters.max_command_lateness_s;
  msg.command_waits = counters.command_waits;
  msg.command_wait_wall_s = counters.command_wait_wall_s;
  msg.command_wait_expired = counters.command_wait_expired;
  msg.lockstep_timeouts = counters.lockstep_timeouts;
  msg.lockstep_steps = static_cast<std::uint32_t>(counters.lockstep_steps);
  msg.lockstep_steps_run =
      static_cast<std::uint32_t>(counters.lockstep_steps + counters.lockstep_skipped);
  msg.spindle_watchdog_trips = static_cast<std::uint32_t>(sim.spindleWatchdogTrips());
  publishInOrder(ground_truth_pub_, msg);
}

void SimulatorOutputs::publishPlan(const core::DrillingSimulation& sim, double t) {
  publishInOrder(plan_pub_, toMsg(sim.imagingPlan().plan, stampOf(t)));
}

void SimulatorOutputs::publishTareResult(const core::TareResult& result, double t) {
  publishInOrder(tare_result_pub_, toMsg(result, stampOf(t)));
}

void SimulatorOutputs::publishWrench(const core::SimulationStep& step) {
  if (wrench_pub_.getNumSubscribers() == 0) return;
  publishInOrder(wrench_pub_, wrenchMsg(step, stampOf(step.time_s)));
}

void SimulatorOutputs::publishTidalVolume(const core::DrillingSimulation& sim, double t) {
  publishInOrder(tidal_volume_pub_, tidalVolumeMsg(sim, stampOf(t)));
  if (!breaths_.newBreath(sim.ventilator())) return;
  const VentilatorSettings settings = toMsg(sim.ventilator().model().settings());
  if (settings != last_settings_msg_) {
    publishInOrder(ventilator_settings_pub_, settings);
    last_settings_msg_ = settings;
  }
}

void SimulatorOutputs::publishControllerStates(const core::DrillingSimulation& sim, double t) {
  for (std::size_t i = 0; i < controller_state_pubs_.size(); ++i) {
    publishInOrder(controller_state_pubs_[i], toMsg(sim.controllerState(i), stampOf(t)));
  }
}

void SimulatorOutputs::publishTf(const core::DrillingSimulation& sim, double t) {
  tf_broadcaster_->sendTransform(
      toMsg(core::ownFrames(sim.frameTransforms(false), tracker_tf_frame_, floating_frames_),
            stampOf(t)));
}

/**
 * A breath-sensor sample: stamped with its time on the sensor's clock (+
 * ~breath_clock_offset_s), published ~breath_sensor_latency_s later.
 */
void SimulatorOutputs::publishFlow(const core::DrillingSimulation& sim, double t) {
  if (flow_pub_.getNumSubscribers() == 0) return;
  AirwayFlow m;
  m.header.stamp = stampOf(t + sim.params().breath_clock_offset_s);
  m.header.frame_id = "breath_sensor";
  m.flow_ml_s = sim.ventilatorSample().flow_ml_s;
  delayed_flow_.setDelay(sim.params().breath_sensor_latency_s);  // the simulation's
  delayed_flow_.push(t, m);
}

/** A tracker sample: now, or ~tracker_delay_s later (its stamp kept). */
void SimulatorOutputs::publishMarker(core::DrillingSimulation& sim, double t) {
  geometry_msgs::PoseStamped m;
  m.header.stamp = stampOf(t);
  m.header.frame_id = "tracker_camera";
  m.pose = tf2::toMsg(sim.measureMarkerPose());
  if (delayed_markers_.delays()) {
    delayed_markers_.push(t, m);
    return;
  }
  sendMarker(m);
}

/** A tracker sample out: tracker/marker_pose, and tf with ~tracker_tf_frame. */
void SimulatorOutputs::sendMarker(const geometry_msgs::PoseStamped& m) {
  publishInOrder(marker_pub_, m);
  if (tracker_tf_frame_.empty()) return;
  geometry_msgs::TransformStamped t;
  t.header = m.header;
  t.child_frame_id = tracker_tf_frame_;
  t.transform.translation.x = m.pose.position.x;
  t.transform.translation.y = m.pose.position.y;
  t.transform.translation.z = m.pose.position.z;
  t.transform.rotation = m.pose.orientation;
  tf_broadcaster_->sendTransform(t);
}

void publishGroundTruth(const SimulatorShared& shared, double t) {
  const core::DrillingSimulation& sim = shared.bench.sim();
  const core::NewTrips trips = shared.bench.newTrips();
  if (trips.spindle_watchdog) {
    ROS_WARN_NAMED(
        shared.name,
        "Simulator: the spindle driver heard no spindle/command for %.3f s: spindle stopped",
        sim.params().spindle_watchdog_s);
  }
  if (trips.drive_guard) {
    ROS_ERROR_NAMED(
        shared.name,
        "Simulator: no enable from the drill guard (drill_guard/enable false, or none for "
        "%.3f s): the drivers hold and the spindle stops",
        sim.params().drive_guard_timeout_s);
  }
  shared.out.publishGroundTruth(sim, shared.bench.counters(), t);
}

}  // namespace pedicle_drilling
