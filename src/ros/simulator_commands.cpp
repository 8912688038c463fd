#include "pedicle_drilling/ros/simulator_commands.hpp"

#include <exception>
#include <utility>

#include "pedicle_drilling/core/common/units.hpp"
#include "pedicle_drilling/ros/simulator_conversions.hpp"

namespace pedicle_drilling {

core::BenchReports simulatorReports(const std::string& name) {
  core::BenchReports r;
  r.trajectory = [name](const std::string& controller, const core::TargetResult& result) {
    if (result.status == core::TargetStatus::kRejected) {
      ROS_WARN_THROTTLE_NAMED(1.0, name,
                              "Simulator: %s/command rejected, previous trajectory kept: %s",
                              controller.c_str(), result.message.c_str());
    } else if (result.status == core::TargetStatus::kClamped) {
      ROS_WARN_THROTTLE_NAMED(1.0, name, "Simulator: %s/command: %s", controller.c_str(),
                              result.message.c_str());
    }
  };
  r.spindle = [name](const core::TargetResult& result) {
    if (result.status == core::TargetStatus::kRejected) {
      ROS_WARN_THROTTLE_NAMED(1.0, name, "Simulator: spindle/command rejected, speed kept: %s",
                              result.message.c_str());
    } else if (result.status == core::TargetStatus::kClamped) {
      ROS_WARN_THROTTLE_NAMED(1.0, name, "Simulator: spindle/command clamped: %s",
                              result.message.c_str());
    }
  };
  return r;
}

void SimulatorCommands::subscribe(ros::NodeHandle& nh, ros::NodeHandle& cmd,
                                  const std::vector<std::string>& controllers) {
  // One command stream per controller (simulator parameters arm_controller, feed_controller
  // and their joints), each with ros_control's rules (controller_rules).
  for (const std::string& name : controllers) {
    subs_.push_back(cmd.subscribe<trajectory_msgs::JointTrajectory>(
        name + "/command", 10, [this, name](const trajectory_msgs::JointTrajectory::ConstPtr& msg) {
          onTrajectory(name, msg);
        }));
  }
  using C = SimulatorCommands;
  subs_.push_back(cmd.subscribe("spindle/command", 10, &C::onSpindle, this));
  // The drivers' drill guard (~drive_guard_timeout_s > 0): the safety monitor's enable.
  subs_.push_back(cmd.subscribe("drill_guard/enable", 10, &C::onDriveEnable, this));
  subs_.push_back(cmd.subscribe("ft_sensor/tare_request", 10, &C::onTareRequest, this));
  // The planner's phase says when trajectories stream (drilling, stopped, retreating): then
  // sim time does not run past the last one received (SimulatedBench::waitForCommand).
  subs_.push_back(nh.subscribe("compensation/status", 10, &C::onPlannerStatus, this));
  if (lockstep_) {
    subs_.push_back(cmd.subscribe("simulator/step_ack", 100, &C::onAck, this,
                                  ros::TransportHints().tcpNoDelay()));
  }
}

void SimulatorCommands::advertiseActions(const ros::NodeHandle& nh,
                                         const std::vector<std::string>& controllers) {
  TrajectoryActionServer::Hooks hooks;
  hooks.command = [this](const std::string& controller, const trajectory_msgs::JointTrajectory& msg,
                         double* end_s) { return applyTrajectory(controller, msg, end_s); };
  hooks.hold = [this](const std::string& controller) {
    std::lock_guard<std::mutex> lock(shared_.mutex);
    shared_.bench.sim().holdController(controller);
  };
  hooks.now = [this]() {
    std::lock_guard<std::mutex> lock(shared_.mutex);
    return shared_.bench.sim().time();
  };
  actions_ = std::make_unique<TrajectoryActionServer>(nh, controllers, std::move(hooks));
}

void SimulatorCommands::abortGoal(const std::string& controller, const std::string& why) {
  if (actions_) actions_->abort(controller, why);
}

void SimulatorCommands::onTrajectory(const std::string& controller,
                                     const trajectory_msgs::JointTrajectory::ConstPtr& msg) {
  {
    std::lock_guard<std::mutex> lock(shared_.mutex);
    shared_.bench.commandTrajectory(
        controller, fromMsg(*msg, shared_.bench.sim().time(), shared_.out.timeOffset()));
  }
  shared_.bench.notify();
}

/**
 * @brief A FollowJointTrajectory goal's trajectory for @p controller, taken now; @p end_s gets
 *        the time the controller's trajectory ends when taken.
 */
core::TargetResult SimulatorCommands::applyTrajectory(const std::string& controller,
                                                      const trajectory_msgs::JointTrajectory& msg,
                                                      double* end_s) {
  std::unique_lock<std::mutex> lock(shared_.mutex);
  const core::TargetResult r = shared_.bench.takeTrajectory(
      controller, fromMsg(msg, shared_.bench.sim().time(), shared_.out.timeOffset()));
  shared_.bench.trajectoryEnd(controller, end_s);
  lock.unlock();
  shared_.bench.notify();
  return r;
}

/** @brief spindle/command: rad/s (REP 103); every message feeds the driver's watchdog. */
void SimulatorCommands::onSpindle(const std_msgs::Float64::ConstPtr& msg) {
  std::lock_guard<std::mutex> lock(shared_.mutex);
  shared_.bench.commandSpindle(core::rpmFromRadPerSec(msg->data));
}

/**
 * @brief drill_guard/enable: the drivers' input of the drill guard, taken at the current step
 *        (under the lockstep the monitor publishes it before it answers the step, so the step it
 *        is taken at is the one it was sent in).
 */
void SimulatorCommands::onDriveEnable(const std_msgs::Bool::ConstPtr& msg) {
  std::lock_guard<std::mutex> lock(shared_.mutex);
  shared_.bench.sim().onDriveEnable(msg->data);
}

/**
 * @brief ft_sensor/tare_request: the sensor driver's tare (the command path, no jitter draw:
 *        core::CommandTransport::undrawnDelay). A bad request is refused: an error and a failed
 *        ft_sensor/tare_result naming the reason.
 */
void SimulatorCommands::onTareRequest(const TareRequest::ConstPtr& msg) {
  std::lock_guard<std::mutex> lock(shared_.mutex);
  const core::TareRequest request = fromMsg(*msg);
  try {
    request.validate();  // before it is queued
  } catch (const std::exception& e) {
    ROS_ERROR_NAMED(shared_.name, "Simulator: ft_sensor/tare_request refused: %s", e.what());
    // The requester waits on the result: a refusal is a failed result, as the relay's.
    core::TareResult refused;
    refused.t = shared_.bench.sim().time();
    refused.message = std::string("tare request refused: ") + e.what();
    shared_.out.publishTareResult(refused, refused.t);
    return;
  }
  shared_.bench.requestTare(request);
}

void SimulatorCommands::onPlannerStatus(const TrialStatus::ConstPtr& msg) {
  {
    std::lock_guard<std::mutex> lock(shared_.mutex);
    shared_.bench.trial().onPhase(msg->phase == TrialStatus::DRILLING ||
                                  msg->phase == TrialStatus::STOPPED ||
                                  msg->phase == TrialStatus::RETREATING);
  }
  shared_.bench.notify();
}

/** @brief simulator/step_ack: a participant joins with its first answer. */
void SimulatorCommands::onAck(const StepAck::ConstPtr& msg) {
  gate_.answer(msg->node, msg->stamp.toNSec(), msg->next_step.toNSec());
}

}  // namespace pedicle_drilling
