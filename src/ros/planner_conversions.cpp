#include "pedicle_drilling/ros/planner_conversions.hpp"

#include <ros/console.h>
#include <std_srvs/Trigger.h>
#include <urdf_model/model.h>
#include <urdf_parser/urdf_parser.h>

#include <cmath>
#include <sstream>

namespace pedicle_drilling {

static_assert(TrialStatus::IDLE == static_cast<int>(core::TrialPhase::kIdle) &&
                  TrialStatus::MOVING_TO_POSE ==
                      static_cast<int>(core::TrialPhase::kMovingToPose) &&
                  TrialStatus::REGISTERING == static_cast<int>(core::TrialPhase::kRegistering) &&
                  TrialStatus::DRILLING == static_cast<int>(core::TrialPhase::kDrilling) &&
                  TrialStatus::STOPPED == static_cast<int>(core::TrialPhase::kStopped) &&
                  TrialStatus::RETREATING == static_cast<int>(core::TrialPhase::kRetreating) &&
                  TrialStatus::DONE == static_cast<int>(core::TrialPhase::kDone) &&
                  TrialStatus::FAILED == static_cast<int>(core::TrialPhase::kFailed),
              "msg/TrialStatus.msg and core::TrialPhase must share their values");

core::TrialSequencerParams loadSequencerParams(const ParamLoader& params) {
  core::TrialSequencerParams sp;
  sp.default_feed_rate_mm_s = params.getDouble("feed_rate_mm_s", 0.5, 0.0, 10.0, true);
  sp.default_spindle_rpm = params.getDouble("spindle_rpm", 12000.0, 0.0, 60000.0, true);
  sp.default_max_duration_s = params.getDouble("max_duration_s", 120.0, 0.0, 3600.0, true);
  core::CompensationParams& cp = sp.compensation;
  cp.latency_s = params.getDouble("latency_s", 0.0, 0.0, 1.0);
  cp.period_s = params.getDouble("period_s", 0.125, 0.0, 1.0, true);
  cp.accel_ratio = params.getDouble("accel_ratio", 10.0, 0.0, 1000.0, true);
  cp.points_per_segment = params.getInt("points_per_segment", 5, 1, 100);
  const std::string profile = params.getString("segment_profile", "rest_to_rest");
  if (!core::parseSegmentProfile(profile, &cp.segment_profile)) {
    params.fail("segment_profile", "= '" + profile + "' is not rest_to_rest or exact");
  }
  cp.compensate_lateral = params.getBool("compensate_si_lr", false);
  cp.predict_axis = {{false, false, false}};
  std::stringstream axes(params.getString("predicted_axes", "ap"));
  std::string name;
  while (std::getline(axes, name, ',')) {
    core::Axis a;
    if (!core::parseAxis(name, &a)) {
      params.fail("predicted_axes", "has unknown axis '" + name + "' (use ap, si, lr)");
    }
    cp.predict_axis[static_cast<int>(a)] = true;
  }
  sp.move_duration_s = params.getDouble("move_duration_s", 2.0, 0.0, 60.0, true);
  sp.settle_s = params.getDouble("settle_s", 0.5, 0.0, 60.0);
  sp.registration_samples = params.getInt("registration_samples", 4, 1, 100);
  sp.registration_timeout_s = params.getDouble("registration_timeout_s", 3.0, 0.0, 60.0, true);
  sp.stop_hold_s = params.getDouble("stop_hold_s", 1.0, 0.0, 60.0);
  sp.recognizer_timeout_s =
      params.getDouble("recognizer_timeout_s", sp.recognizer_timeout_s, 0.0, 60.0);
  sp.monitor_timeout_s = params.getDouble("monitor_timeout_s", sp.monitor_timeout_s, 0.0, 60.0);
  sp.retreat.distance_m = params.getDouble("retreat_distance_m", 0.025, 0.0, 0.1, true);
  sp.retreat.speed_m_s = params.getDouble("retreat_speed_m_s", 0.005, 0.0, 0.05, true);
  sp.retreat.accel_m_s2 = params.getDouble("retreat_accel_m_s2", 0.05, 0.0, 1.0, true);
  return sp;
}

std::unique_ptr<core::TrialSequencer> makeSequencer(const ParamLoader& params,
                                                    const ros::NodeHandle& nh,
                                                    const std::string& world_frame) {
  // Robot description: a URDF file, or the robot_description parameter.
  const std::string urdf_path = params.getString("urdf_path", "", true);
  std::string urdf_xml;
  if (!urdf_path.empty()) {
    urdf_xml = params.readFile("urdf_path", urdf_path);
  } else if (!nh.getParam("robot_description", urdf_xml)) {
    params.fail("urdf_path", "is empty and there is no robot_description parameter");
  }
  core::TrialSequencerParams sp = loadSequencerParams(params);
  const std::string base = params.getString("arm_base_link", "world");
  const std::string tip = params.getString("arm_tip_link", "device_base");
  sp.feed_joint = params.getString("feed_joint", "feed_joint");
  const core::KinematicChain arm = core::KinematicChain::fromUrdfString(urdf_xml, base, tip);
  const urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(urdf_xml);
  const auto feed = model ? model->getJoint(sp.feed_joint) : nullptr;
  if (!feed || !feed->limits) {
    params.fail("feed_joint", "'" + sp.feed_joint + "' is not a limited joint of the URDF");
  }
  sp.feed_lower_m = feed->limits->lower;
  sp.feed_upper_m = feed->limits->upper;
  sp.arm_joints = arm.jointNames();
  Eigen::VectorXd q(sp.arm_joints.size());
  for (std::size_t i = 0; i < sp.arm_joints.size(); ++i) {
    const std::string key = "drilling_pose/" + sp.arm_joints[i];
    if (!params.has(key)) params.fail(key, "is missing (load config/drilling_pose.yaml)");
    q[i] = params.getDouble(key, 0.0, -2.0 * M_PI, 2.0 * M_PI);
  }
  const double feed_home =
      params.getDouble("feed_home_m", 0.01, sp.feed_lower_m, 0.5 * sp.feed_upper_m);
  try {
    return std::make_unique<core::TrialSequencer>(sp, core::ArmCompensation(arm, q, feed_home),
                                                  world_frame);
  } catch (const std::invalid_argument& e) {
    // The core names the field first ("settle_s: must be ..."): report it as the parameter.
    const std::string what = e.what();
    params.fail(what.substr(0, what.find(':')), what.substr(what.find(':') + 1));
  }
  return nullptr;  // not reached: fail() throws
}

TrialStatus toMsg(core::TrialPhase phase, const ros::Time& stamp) {
  TrialStatus msg;
  msg.header.stamp = stamp;
  msg.phase = static_cast<std::uint8_t>(phase);
  msg.phase_name = core::toString(phase);
  msg.running = core::isRunning(phase);
  return msg;
}

trajectory_msgs::JointTrajectory toMsg(const core::JointTrajectoryCommand& command) {
  trajectory_msgs::JointTrajectory traj;
  traj.header.stamp = ros::Time(command.start_time);
  traj.joint_names = command.joint_names;
  for (const core::JointTrajectoryCommand::Point& p : command.points) {
    trajectory_msgs::JointTrajectoryPoint pt;
    pt.positions = p.positions;
    pt.velocities = p.velocities;
    pt.time_from_start = ros::Duration(p.time_from_start);
    traj.points.push_back(std::move(pt));
  }
  return traj;
}

geometry_msgs::PoseStamped toMsg(const core::PredictedMarker& marker) {
  geometry_msgs::PoseStamped msg;
  msg.header.stamp = ros::Time(marker.stamp);
  msg.header.frame_id = marker.frame;
  msg.pose.position.x = marker.position.x();
  msg.pose.position.y = marker.position.y();
  msg.pose.position.z = marker.position.z();
  msg.pose.orientation.w = marker.orientation.w();
  msg.pose.orientation.x = marker.orientation.x();
  msg.pose.orientation.y = marker.orientation.y();
  msg.pose.orientation.z = marker.orientation.z();
  return msg;
}

bool callTriggerChain(std::vector<ros::ServiceClient>* clients, double timeout_s,
                      std::string* why) {
  for (ros::ServiceClient& client : *clients) {
    const std::string name = client.getService();
    if (!client.waitForExistence(ros::Duration(timeout_s))) {
      *why = "trial refused: service " + name +
             " is not available (is its nodelet loaded? parameter ~trial_start_services); "
             "nothing was started";
      return false;
    }
    std_srvs::Trigger srv;
    if (!client.call(srv)) {
      *why = "trial refused: the call to " + name + " failed; nothing was started";
      return false;
    }
    if (!srv.response.success) {
      *why =
          "trial refused: " + name + " answered: " + srv.response.message + "; nothing was started";
      return false;
    }
    ROS_INFO("CompensationPlanner: %s: %s", name.c_str(), srv.response.message.c_str());
  }
  return true;
}

void logSequencerMessages(const std::vector<core::SequencerLog>& log, const std::string& who) {
  for (const core::SequencerLog& l : log) {
    switch (l.level) {
      case core::SequencerLog::Level::kInfo:
        ROS_INFO("%s: %s", who.c_str(), l.text.c_str());
        break;
      case core::SequencerLog::Level::kWarn:
        ROS_WARN("%s: %s", who.c_str(), l.text.c_str());
        break;
      case core::SequencerLog::Level::kError:
        ROS_ERROR("%s: %s", who.c_str(), l.text.c_str());
        break;
    }
  }
}

}  // namespace pedicle_drilling
