/**
 * @file trial_action_nodelet.cpp
 * @brief pedicle_drilling/TrialAction: one drilling trial as the `drill_trial` action
 *        (DrillTrial.action), over the CompensationPlanner's standard interfaces: a goal calls
 *        its `~start_trial` (a refusal rejects the goal with the planner's reason), the
 *        feedback follows `compensation/status`, `drilling_state` and the feed joint on
 *        `joint_states`, the result comes with the trial's DONE or FAILED, and a cancel is a
 *        `drill/stop` with retreat. One goal at a time; a second is rejected.
 *
 *        Nothing here is a safety function: the trial is the planner's. Its recognizer, the
 *        safety monitor and the plan's depth limit stop it whether or not anyone follows the
 *        action, and a TrialAction that dies leaves the trial running to its own stop. A goal
 *        whose planner goes silent (no publisher of `compensation/status` for
 *        ~planner_lost_s) is aborted: the drill guard has stopped the drives by then.
 */
#include <actionlib/server/action_server.h>
#include <nodelet/nodelet.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <pluginlib/class_list_macros.hpp>

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "pedicle_drilling/DrillTrialAction.h"
#include "pedicle_drilling/DrillingState.h"
#include "pedicle_drilling/StartTrial.h"
#include "pedicle_drilling/StopCommand.h"
#include "pedicle_drilling/TrialStatus.h"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/publish_in_order.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"

namespace pedicle_drilling {

/** @brief The `drill_trial` action server over the planner's service and topics. */
class TrialActionNodelet : public nodelet::Nodelet {
 public:
  ~TrialActionNodelet() override {
    if (spinner_) spinner_->stop();  // no callback of ours runs after this
    watch_timer_.stop();
    std::lock_guard<std::mutex> lock(mutex_);
    if (goal_) {
      DrillTrialResult result = resultNow();
      result.message = "the TrialAction stopped; the trial goes on under the planner";
      goal_->setAborted(result, result.message);
      goal_.reset();
    }
  }

 private:
  using Server = actionlib::ActionServer<DrillTrialAction>;

  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    try {
      ParamLoader(getPrivateNodeHandle()).load(TrialActionNodeParams::table(), &params_);
    } catch (const std::exception& e) {
      failStartup(getName(), e.what());  // throws: the load fails
    }
    // Its own queue: a goal waits for the planner's service, which must not hold a worker
    // thread of the manager; two threads, so that a cancel is heard during that wait.
    nh_ = nh;
    nh_.setCallbackQueue(&queue_);
    start_client_ = nh_.serviceClient<StartTrial>(params_.start_service);
    stop_pub_ = nh_.advertise<StopCommand>("drill/stop", 10);
    status_sub_ = nh_.subscribe("compensation/status", 10, &TrialActionNodelet::onStatus, this);
    stop_sub_ = nh_.subscribe("drill/stop", 10, &TrialActionNodelet::onStop, this);
    state_sub_ = nh_.subscribe("drilling_state", 10, &TrialActionNodelet::onState, this);
    joint_sub_ = nh_.subscribe("joint_states", 10, &TrialActionNodelet::onJoints, this);
    server_ = std::make_unique<Server>(
        nh_, "drill_trial", [this](Server::GoalHandle g) { onGoal(g); },
        [this](Server::GoalHandle g) { onCancel(g); }, false);
    server_->start();
    watch_timer_ = nh_.createSteadyTimer(ros::WallDuration(params_.feedback_period_s),
                                         [this](const ros::SteadyTimerEvent&) { onWatch(); });
    spinner_ = std::make_unique<ros::AsyncSpinner>(2, &queue_);
    spinner_->start();
    NODELET_INFO("TrialAction: %s through %s", nh_.resolveName("drill_trial").c_str(),
                 start_client_.getService().c_str());
  }

  // ------------------------------------------------------------------------------- goals

  void onGoal(Server::GoalHandle goal) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (goal_ || starting_) {
        reject(goal, "a trial is running (one goal at a time; cancel it first)");
        return;
      }
      starting_ = true;
    }
    StartTrial call;
    const DrillTrialGoal& g = *goal.getGoal();
    call.request.mode = g.mode;
    call.request.spindle_rpm = g.spindle_rpm;
    call.request.feed_rate_mm_s = g.feed_rate_mm_s;
    call.request.max_duration_s = g.max_duration_s;
    call.request.segment_profile = g.segment_profile;
    const ros::Time asked = ros::Time::now();
    std::string why;
    if (!start_client_.waitForExistence(ros::Duration(params_.service_timeout_s))) {
      why = "no start service " + start_client_.getService() + " within " +
            core::Range::format(params_.service_timeout_s) +
            " s (is the CompensationPlanner running?)";
    } else if (!start_client_.call(call)) {
      why = "the call of " + start_client_.getService() + " failed";
    } else if (!call.response.success) {
      why = "the planner refused the trial: " + call.response.message;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    starting_ = false;
    if (!why.empty()) {
      reject(goal, why);
      return;
    }
    goal.setAccepted(call.response.message);
    goal_ = goal;
    started_ = asked;
    seen_running_ = false;
    stops_ = 0;
    first_stop_.reset();
    phase_ = TrialStatus::MOVING_TO_POSE;
    phase_name_ = "moving_to_pose";
    last_status_ = ros::WallTime::now();
    if (cancel_early_) {  // canceled while the planner was starting it
      cancel_early_ = false;
      cancelTrial();
    }
    sendFeedback();
  }

  void reject(Server::GoalHandle goal, const std::string& why) {
    DrillTrialResult result;
    result.message = why;
    goal.setRejected(result, why);
    NODELET_WARN("TrialAction: goal rejected: %s", why.c_str());
  }

  void onCancel(Server::GoalHandle goal) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (starting_ && !goal_) {
      cancel_early_ = true;  // the goal is still pending: stop the trial once it has started
      return;
    }
    if (!goal_ || *goal_ != goal) return;  // not ours any more: actionlib ends it
    cancelTrial();
  }

  /** @brief A stop with retreat, as any node may send it; the result comes with DONE. */
  void cancelTrial() {
    canceled_ = true;
    StopCommand stop;
    stop.header.stamp = ros::Time::now();
    stop.source = getName();
    stop.retreat = true;
    stop.reason = "drill_trial goal canceled by its client: stop and retreat";
    publishInOrder(stop_pub_, stop);
    NODELET_WARN("TrialAction: %s", stop.reason.c_str());
  }

  // ------------------------------------------------------------------------------- inputs

  void onStatus(const TrialStatus::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    last_status_ = ros::WallTime::now();
    if (!goal_ || msg->header.stamp < started_) return;  // an earlier trial's (latched)
    phase_ = msg->phase;
    phase_name_ = msg->phase_name;
    stops_ = msg->stops;
    seen_running_ = seen_running_ || msg->running;
    const bool ended = msg->phase == TrialStatus::DONE || msg->phase == TrialStatus::FAILED;
    if (!seen_running_ || !ended) {
      sendFeedback();
      return;
    }
    DrillTrialResult result = resultNow();
    result.done = msg->phase == TrialStatus::DONE;
    result.final_phase = msg->phase_name;
    if (canceled_) {
      result.message = "canceled: the drill stopped and retracted";
      goal_->setCanceled(result, result.message);
    } else if (result.done) {
      result.message = "trial done" + (first_stop_ ? ": " + first_stop_->reason : "");
      goal_->setSucceeded(result, result.message);
    } else {
      result.message = "trial failed" + (first_stop_ ? ": " + first_stop_->reason : "");
      goal_->setAborted(result, result.message);
    }
    goal_.reset();
    canceled_ = false;
  }

  void onStop(const StopCommand::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (goal_ && !first_stop_ && msg->header.stamp >= started_) first_stop_ = *msg;
  }

  void onState(const DrillingState::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    layer_ = msg->state_name;
  }

  void onJoints(const sensor_msgs::JointState::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (std::size_t i = 0; i < msg->name.size() && i < msg->position.size(); ++i) {
      if (msg->name[i] == params_.feed_joint) feed_m_ = msg->position[i];
    }
  }

  /** @brief The periodic feedback, and a goal whose planner is gone. */
  void onWatch() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!goal_) return;
    const double silent = (ros::WallTime::now() - last_status_).toSec();
    if (status_sub_.getNumPublishers() == 0 && silent > params_.planner_lost_s) {
      DrillTrialResult result = resultNow();
      result.message = "planner lost: no publisher of " + status_sub_.getTopic() + " for " +
                       core::Range::format(silent) + " s (the drill guard stops the drives)";
      goal_->setAborted(result, result.message);
      NODELET_ERROR("TrialAction: %s", result.message.c_str());
      goal_.reset();
      canceled_ = false;
      return;
    }
    sendFeedback();
  }

  // ------------------------------------------------------------------------------- outputs

  void sendFeedback() {
    DrillTrialFeedback feedback;
    feedback.phase = phase_;
    feedback.phase_name = phase_name_;
    feedback.layer = layer_;
    feedback.feed_m = feed_m_;
    feedback.elapsed_s = (ros::Time::now() - started_).toSec();
    goal_->publishFeedback(feedback);
  }

  DrillTrialResult resultNow() const {
    DrillTrialResult result;
    result.final_phase = phase_name_;
    result.stops = stops_;
    if (first_stop_) {
      result.stop_source = first_stop_->source;
      result.stop_reason = first_stop_->reason;
    }
    return result;
  }

  TrialActionNodeParams params_;
  std::mutex mutex_;
  ros::NodeHandle nh_;
  ros::CallbackQueue queue_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
  std::unique_ptr<Server> server_;
  ros::ServiceClient start_client_;
  ros::Publisher stop_pub_;
  ros::Subscriber status_sub_;
  ros::Subscriber stop_sub_;
  ros::Subscriber state_sub_;
  ros::Subscriber joint_sub_;
  ros::SteadyTimer watch_timer_;
  std::optional<Server::GoalHandle> goal_;  ///< the running goal
  bool starting_ = false;                   ///< a goal waits for the planner's answer
  bool cancel_early_ = false;               ///< that goal was canceled meanwhile
  bool canceled_ = false;                   ///< the running goal was canceled
  bool seen_running_ = false;               ///< its trial has published a running phase
  ros::Time started_;                       ///< when its start was asked (ROS time)
  ros::WallTime last_status_;               ///< the latest compensation/status heard
  std::uint8_t phase_ = TrialStatus::IDLE;
  std::string phase_name_ = "idle";
  std::uint32_t stops_ = 0;
  std::optional<StopCommand> first_stop_;  ///< the first drill/stop of the trial
  std::string layer_;
  double feed_m_ = 0.0;
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::TrialActionNodelet, nodelet::Nodelet)
