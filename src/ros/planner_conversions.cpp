#include "pedicle_drilling/ros/planner_conversions.hpp"

#include <ros/console.h>
#include <std_srvs/Trigger.h>
#include <urdf_model/model.h>
#include <urdf_parser/urdf_parser.h>

#include <cmath>
#include <iomanip>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

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

std::unique_ptr<core::PlannerRuntime> makePlannerRuntime(
    const CompensationPlannerNodeParams& params, const ParamLoader& loader,
    const ros::NodeHandle& nh, CompensatorLoader* compensators) {
  core::ForceAxis thrust;
  thrust.index = params.thrustAxisIndex();
  thrust.sign = params.thrustAxisSign();
  auto runtime = std::make_unique<core::PlannerRuntime>(makeSequencer(params, loader, nh),
                                                        params.heartbeat_period_s, thrust);
  runtime->setTidalVolumeSource(nh.resolveName("tidal_volume"), params.breath_timeout_periods);
  const std::string name = params.compensator_class;
  const core::TextPairs config = params.compensator_params;
  try {
    compensators->create(name, config);
  } catch (const std::exception& e) {
    loader.fail("compensator", "= '" + name + "': " + e.what());
  }
  if (name == "pedicle_drilling/PaperCompensator") return runtime;  // the default
  runtime->sequencer().setCompensatorFactory(
      [compensators, name, config]() { return compensators->create(name, config); });
  return runtime;
}

void checkTrajectoryInterface(const CompensationPlannerNodeParams& params,
                              const ros::NodeHandle& pnh, bool lockstep) {
  if (!params.useAction() || !lockstep) return;
  throw std::invalid_argument("parameter '" + pnh.resolveName("trajectory_interface") +
                              "' = 'action' is not available under the lockstep "
                              "(/use_sim_lockstep): its goals and results are not steps; use "
                              "'topic'");
}

std::string startSummary(const CompensationPlannerNodeParams& params,
                         const core::TrialSequencer& sequencer, const std::string& patient_id,
                         const std::string& first_route) {
  const core::CompensationParams& c = sequencer.params().compensation;
  std::ostringstream os;
  os << std::fixed << std::setprecision(3) << "patient '" << patient_id << "', drill axis ("
     << c.drill_axis.x() << " " << c.drill_axis.y() << " " << c.drill_axis.z() << "), latency "
     << c.latency_s << " s, compensator " << params.compensator_class
     << ", depth limit from the drill tip '" << params.tip_link << "' and the thrust on "
     << params.thrust_axis << ", trajectories to " << first_route
     << (sequencer.controllers().size() > 1 ? " ..." : "");
  return os.str();
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

core::PatientModel loadPatientModel(const ros::NodeHandle& pnh, const std::string& default_path) {
  std::string path = default_path;
  XmlRpc::XmlRpcValue value;
  if (pnh.getParam("patient_model_path", value)) {
    if (value.getType() != XmlRpc::XmlRpcValue::TypeString) {
      throw std::invalid_argument("parameter '" + pnh.resolveName("patient_model_path") +
                                  "' must be a string (a file path)");
    }
    path = static_cast<std::string>(value);
  }
  try {
    return core::readModelYaml(path);
  } catch (const std::exception& e) {
    throw std::runtime_error("patient model file '" + path + "' (parameter '" +
                             pnh.resolveName("patient_model_path") + "'): " + e.what());
  }
}

core::FrameLookup tfFrameLookup(const tf2_ros::Buffer& buffer, const std::string& world_frame) {
  return [&buffer, world_frame](const std::string& frame, Eigen::Isometry3d* x) {
    if (!buffer.canTransform(frame, world_frame, ros::Time(0))) return false;
    const geometry_msgs::Transform& tr =
        buffer.lookupTransform(frame, world_frame, ros::Time(0)).transform;
    const auto& q = tr.rotation;
    x->linear() = Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized().toRotationMatrix();
    x->translation() = Eigen::Vector3d(tr.translation.x, tr.translation.y, tr.translation.z);
    return true;
  };
}

core::TrialRequest fromMsg(const StartTrial::Request& req) {
  core::TrialRequest request;
  request.mode = req.mode;
  request.spindle_rpm = req.spindle_rpm;
  request.feed_rate_mm_s = req.feed_rate_mm_s;
  request.max_duration_s = req.max_duration_s;
  request.segment_profile = req.segment_profile;
  return request;
}

core::SequencerLog setPlan(const DrillingPlan& msg, core::TrialSequencer* sequencer) {
  std::string why;
  std::optional<core::DrillingPlan> plan = fromMsg(msg, &why);
  core::SequencerLog line;
  if (!plan) {
    line.level = core::SequencerLog::Level::kError;
    line.text = "drilling plan refused: " + why +
                "; the planner has no plan now (fail closed): the next trials are refused until "
                "a usable plan comes";
    sequencer->setPlan(std::nullopt);
    return line;
  }
  line.text = "drilling plan: " + describe(*plan);
  sequencer->setPlan(std::move(plan));
  return line;
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
