/**
 * @file trajectory_route.hpp
 * @brief How the CompensationPlanner's trajectories reach the controllers (~trajectory_interface):
 *        a trajectory_msgs/JointTrajectory on `<controller>/command`, or a
 *        pedicle_drilling/FollowJointTrajectory goal (control_msgs' fields and md5sums) on
 *        `<controller>/follow_joint_trajectory`.
 */
#pragma once

#include <actionlib/client/action_client.h>
#include <ros/ros.h>
#include <trajectory_msgs/JointTrajectory.h>

#include <atomic>
#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "pedicle_drilling/FollowJointTrajectoryAction.h"

namespace pedicle_drilling {

/**
 * @brief One route for the trajectories of a list of controllers: the command topics, or the
 *        FollowJointTrajectory action (ros_control's JointTrajectoryController semantics).
 *
 * With the action, every trajectory is a new goal that replaces the controller's running one (the
 * controller splices it in at its start time and preempts the old goal): a hold or a retreat
 * after a stop is such a goal too. The route never cancels a goal while it runs (a canceled
 * JointTrajectoryController holds where it is, which is not the retreat); cancelAll() at the
 * planner's unload only. A goal the controller rejects or aborts, or one it loses, and a running
 * goal preempted by another client, is reported to the fault handler with the controller, the
 * action and the result's error code and string. The handler runs on the queue of the node
 * handle given, never inside actionlib's callbacks (it may take the caller's locks and send
 * goals).
 */
class TrajectoryRoute {
 public:
  /** @brief Called with the reason of a controller fault (see the class comment). */
  using FaultHandler = std::function<void(const std::string& why)>;

  /**
   * @brief The route for @p controllers (names, in the planner's controller order).
   * @param use_action false: `<controller>/command` topics; true: the action clients.
   */
  TrajectoryRoute(ros::NodeHandle& nh, const std::vector<std::string>& controllers, bool use_action,
                  FaultHandler on_fault);
  /** @brief Cancels the running goals (the controllers hold), then shuts the clients down. */
  ~TrajectoryRoute();
  TrajectoryRoute(const TrajectoryRoute&) = delete;
  TrajectoryRoute& operator=(const TrajectoryRoute&) = delete;

  /** @brief Sends @p trajectory to controller @p index (its header stamp is its start). */
  void send(std::size_t index, const trajectory_msgs::JointTrajectory& trajectory);

  /**
   * @brief With the action: waits up to @p timeout_s of wall time for every controller's action
   *        server; false with the refusal in @p why (naming the action) when one is missing.
   *        Always true with the topics.
   */
  bool waitForServers(double timeout_s, std::string* why) const;

  /** @brief Whether the trajectories go as action goals. */
  bool usesAction() const { return use_action_; }

  /** @brief The resolved action (or topic) name of controller @p index. */
  const std::string& name(std::size_t index) const { return controllers_[index].name; }

 private:
  using Client = actionlib::ActionClient<FollowJointTrajectoryAction>;
  struct Controller {
    std::string name;          ///< resolved `<controller>/command` or `.../follow_joint_trajectory`
    ros::Publisher publisher;  ///< the topic route
    std::unique_ptr<Client> client;       ///< the action route
    std::list<Client::GoalHandle> goals;  ///< goals sent and not seen done (the last: running)
    /// The running goal's serial (read in actionlib's callbacks without goals_mutex_).
    std::shared_ptr<std::atomic<std::uint64_t>> running =
        std::make_shared<std::atomic<std::uint64_t>>(0);
  };
  /** @brief actionlib's transition callback of goal @p serial of controller @p index. */
  void onTransition(std::size_t index, std::uint64_t serial, Client::GoalHandle goal);
  /** @brief Hands @p why to the fault handler on the node handle's queue. */
  void defer(const std::string& why);

  bool use_action_;
  ros::NodeHandle nh_;
  FaultHandler on_fault_;
  std::vector<Controller> controllers_;
  /// Controller::goals. Never taken in actionlib's callbacks: send() takes it, then actionlib's
  /// own lock (sendGoal); the other order would deadlock.
  std::mutex goals_mutex_;
};

}  // namespace pedicle_drilling
