#include "pedicle_drilling/ros/planner_conversions.hpp"

#include <ros/console.h>
#include <std_srvs/Trigger.h>
#include <urdf_model/model.h>
#include <urdf_parser/urdf_parser.h>

#include <cmath>
#include <optional>
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

std::unique_ptr<core::TrialSequencer> makeSequencer(const CompensationPlannerNodeParams& params,
                                                    const ParamLoader& loader,
                                                    const ros::NodeHandle& nh) {
  // Robot description: a URDF file, or the robot_description parameter.
  std::string urdf_xml;
  if (!params.urdf_path.empty()) {
    urdf_xml = loader.readFile("urdf_path", params.urdf_path);
  } else if (!nh.getParam("robot_description", urdf_xml)) {
    loader.fail("urdf_path", "is empty and there is no robot_description parameter");
  }
  core::TrialSequencerParams sp = params.sequencer;
  const core::KinematicChain arm =
      core::KinematicChain::fromUrdfString(urdf_xml, params.arm_base_link, params.arm_tip_link);
  const urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(urdf_xml);
  const auto feed = model ? model->getJoint(sp.feed_joint) : nullptr;
  if (!feed || !feed->limits) {
    loader.fail("feed_joint", "'" + sp.feed_joint + "' is not a limited joint of the URDF");
  }
  sp.feed_lower_m = feed->limits->lower;
  sp.feed_upper_m = feed->limits->upper;
  if (params.feed_home_m < sp.feed_lower_m || params.feed_home_m > 0.5 * sp.feed_upper_m) {
    std::ostringstream os;
    os << "= " << params.feed_home_m << " is outside [" << sp.feed_lower_m << ", "
       << 0.5 * sp.feed_upper_m << "] (the feed joint's lower limit to half its upper limit)";
    loader.fail("feed_home_m", os.str());
  }
  sp.arm_joints = arm.jointNames();
  Eigen::VectorXd q(sp.arm_joints.size());
  for (std::size_t i = 0; i < sp.arm_joints.size(); ++i) {
    const std::string key = "drilling_pose/" + sp.arm_joints[i];
    if (!loader.has(key)) loader.fail(key, "is missing (load config/drilling_pose.yaml)");
    q[i] = loader.getDouble(key, 0.0, -2.0 * M_PI, 2.0 * M_PI);
  }
  // The drill tip at the drilling pose (the depth limit's origin): the chain to ~tip_link must
  // run through the arm's joints.
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();
  try {
    tip = core::ArmCompensation::tipAt(urdf_xml, params.arm_base_link, params.tip_link,
                                       sp.arm_joints, q);
  } catch (const std::exception& e) {
    loader.fail("tip_link", "= '" + params.tip_link +
                                "' (the drill tip's link, below ~arm_base_link '" +
                                params.arm_base_link + "' in the URDF): " + e.what());
  }
  try {
    core::ArmCompensation arm_compensation(arm, q, params.feed_home_m);
    arm_compensation.setTipAtPose(tip);
    return std::make_unique<core::TrialSequencer>(sp, arm_compensation, params.world_frame);
  } catch (const std::invalid_argument& e) {
    // The core names the field first ("feed_joint limits must ..."): report it as the parameter.
    const std::string what = e.what();
    loader.fail(what.substr(0, what.find_first_of(" :")), what);
  }
  return nullptr;  // not reached: fail() throws
}

std::optional<core::DrillingPlan> fromMsg(const DrillingPlan& msg, std::string* why) {
  core::DrillingPlan plan;
  plan.frame = msg.header.frame_id;
  plan.entry = Eigen::Vector3d(msg.entry.x, msg.entry.y, msg.entry.z);
  plan.direction = Eigen::Vector3d(msg.direction.x, msg.direction.y, msg.direction.z);
  plan.depth_m = msg.depth_m;
  plan.entry_tolerance_m = msg.entry_tolerance_m;
  *why = plan.frame.empty()
             ? "drilling plan: header.frame_id is empty (the tracked marker's frame the plan is in)"
             : plan.check();
  if (!why->empty()) return std::nullopt;
  return plan;
}

std::string describe(const core::DrillingPlan& plan) {
  std::ostringstream os;
  os.precision(2);
  os << std::fixed << "frame " << plan.frame << ", entry (" << plan.entry.x() * 1e3 << ", "
     << plan.entry.y() * 1e3 << ", " << plan.entry.z() * 1e3 << ") mm, direction ("
     << plan.direction.x() << ", " << plan.direction.y() << ", " << plan.direction.z()
     << "), depth " << plan.depth_m * 1e3 << " mm, entry tolerance " << plan.entry_tolerance_m * 1e3
     << " mm";
  return os.str();
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
