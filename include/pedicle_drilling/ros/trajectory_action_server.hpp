/**
 * @file trajectory_action_server.hpp
 * @brief The Simulator's FollowJointTrajectory servers (~follow_joint_trajectory): one per
 *        controller on `<controller>/follow_joint_trajectory`, with ros_control's
 *        JointTrajectoryController semantics.
 */
#pragma once

#include <actionlib/server/action_server.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>

#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "pedicle_drilling/FollowJointTrajectoryAction.h"
#include "pedicle_drilling/core/robot/target_result.hpp"

namespace pedicle_drilling {

/**
 * @brief FollowJointTrajectory action servers for simulated controllers.
 *
 * A goal is the controller's new trajectory (the same as on `<controller>/command`): rejected
 * with INVALID_GOAL and the controller's reason when the
 * controller refuses the trajectory, else accepted, the running goal preempted (the new one
 * replaces it from its start time). The running goal succeeds once the controller's time passes
 * its trajectory's end; abort() aborts it (PATH_TOLERANCE_VIOLATED, as a
 * JointTrajectoryController on a tolerance violation); a cancel makes the controller hold where
 * it is (its goal canceled). The servers run on a queue and thread of their own; the hooks are
 * called there, never while a lock of the caller's is held by this class.
 */
class TrajectoryActionServer {
 public:
  /** @brief The simulation's side, called on the servers' thread. */
  struct Hooks {
    /// A goal's trajectory for controller @p controller: the controller's answer and, when taken,
    /// the time its trajectory ends (@p end_s; -inf: it holds at once).
    std::function<core::TargetResult(const std::string& controller,
                                     const trajectory_msgs::JointTrajectory& trajectory,
                                     double* end_s)>
        command;
    /// A canceled goal: the controller holds where it is.
    std::function<void(const std::string& controller)> hold;
    /// The controllers' time [s] (the trajectory ends' clock).
    std::function<double()> now;
  };

  /** @brief Serves `<name>/follow_joint_trajectory` for each of @p controllers. */
  TrajectoryActionServer(const ros::NodeHandle& nh, const std::vector<std::string>& controllers,
                         Hooks hooks);
  /** @brief Stops the thread and the servers. */
  ~TrajectoryActionServer();
  TrajectoryActionServer(const TrajectoryActionServer&) = delete;
  TrajectoryActionServer& operator=(const TrajectoryActionServer&) = delete;

  /** @brief Controller @p controller aborted its trajectory: its running goal aborts with @p why
   *         (at the servers' next check, 10 ms). Safe from any thread. */
  void abort(const std::string& controller, const std::string& why);

 private:
  using Server = actionlib::ActionServer<FollowJointTrajectoryAction>;
  struct Controller {
    std::string name;
    std::unique_ptr<Server> server;
    std::optional<Server::GoalHandle> running;  ///< the accepted goal not ended yet
    double end_s = 0.0;                         ///< its trajectory's end
  };
  void onGoal(std::size_t index, Server::GoalHandle goal);
  void onCancel(std::size_t index, Server::GoalHandle goal);
  void check();

  Hooks hooks_;
  ros::CallbackQueue queue_;
  ros::NodeHandle nh_;
  std::vector<Controller> controllers_;  ///< touched on the servers' thread only
  ros::WallTimer check_timer_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
  std::mutex aborts_mutex_;
  std::map<std::string, std::string> aborts_;  ///< controller -> why, not handled yet
};

}  // namespace pedicle_drilling
