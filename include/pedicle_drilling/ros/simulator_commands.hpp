/**
 * @file simulator_commands.hpp
 * @brief The Simulator's command path (doc/nodes.md, "pedicle_drilling/Simulator"): each
 *        controller's <name>/command, spindle/command, drill_guard/enable,
 *        ft_sensor/tare_request, the planner's compensation/status, the lockstep's
 *        simulator/step_ack and ~follow_joint_trajectory's action servers, into
 *        core::SimulatedBench; and the commands' outcomes, logged.
 */
#pragma once

#include <ros/ros.h>
#include <std_msgs/Bool.h>
#include <std_msgs/Float64.h>
#include <trajectory_msgs/JointTrajectory.h>

#include <memory>
#include <string>
#include <vector>

#include "pedicle_drilling/StepAck.h"
#include "pedicle_drilling/TareRequest.h"
#include "pedicle_drilling/TrialStatus.h"
#include "pedicle_drilling/core/sim/lockstep_roster.hpp"
#include "pedicle_drilling/core/sim/simulated_bench.hpp"
#include "pedicle_drilling/ros/simulator_outputs.hpp"
#include "pedicle_drilling/ros/trajectory_action_server.hpp"

namespace pedicle_drilling {

/** @brief The commands' outcomes, logged (throttled, logger @p name) when refused or clamped. */
core::BenchReports simulatorReports(const std::string& name);

/**
 * @brief The Simulator's command subscriptions and action servers. Each callback takes the
 *        shared mutex; a command wakes the stepping thread's waits (SimulatedBench::notify).
 */
class SimulatorCommands {
 public:
  /** @brief Into @p shared's bench; under the lockstep (@p lockstep) @p gate takes the answers. */
  SimulatorCommands(const SimulatorShared& shared, bool lockstep, core::LockstepGate& gate)
      : shared_(shared), lockstep_(lockstep), gate_(gate) {}

  /**
   * @brief Subscribes on @p cmd (under the lockstep, its queue: a participant's commands are
   *        handled before its answer) each of @p controllers' <name>/command (ros_control's
   *        rules), spindle/command, drill_guard/enable, ft_sensor/tare_request and, under the
   *        lockstep, simulator/step_ack; on @p nh the planner's compensation/status.
   */
  void subscribe(ros::NodeHandle& nh, ros::NodeHandle& cmd,
                 const std::vector<std::string>& controllers);

  /**
   * @brief ~follow_joint_trajectory: each controller's FollowJointTrajectory server beside its
   *        command topic (a goal's trajectory takes the topic's path: the same rules).
   */
  void advertiseActions(const ros::NodeHandle& nh, const std::vector<std::string>& controllers);

  /** @brief @p controller's running action goal, if any, aborts with @p why (under the mutex). */
  void abortGoal(const std::string& controller, const std::string& why);

  /** @brief Ends the action servers' thread: no goal reaches the simulation after this. */
  void shutdownActions() { actions_.reset(); }

 private:
  void onTrajectory(const std::string& controller,
                    const trajectory_msgs::JointTrajectory::ConstPtr& msg);
  core::TargetResult applyTrajectory(const std::string& controller,
                                     const trajectory_msgs::JointTrajectory& msg, double* end_s);
  void onSpindle(const std_msgs::Float64::ConstPtr& msg);
  void onDriveEnable(const std_msgs::Bool::ConstPtr& msg);
  void onTareRequest(const TareRequest::ConstPtr& msg);
  void onPlannerStatus(const TrialStatus::ConstPtr& msg);
  void onAck(const StepAck::ConstPtr& msg);

  SimulatorShared shared_;
  bool lockstep_;
  core::LockstepGate& gate_;
  std::unique_ptr<TrajectoryActionServer> actions_;  ///< ~follow_joint_trajectory (else null)
  std::vector<ros::Subscriber> subs_;
};

}  // namespace pedicle_drilling
