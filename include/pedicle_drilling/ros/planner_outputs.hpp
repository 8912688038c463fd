/**
 * @file planner_outputs.hpp
 * @brief The CompensationPlanner's side of ROS that is not its callbacks: its publishers and what
 *        a core::SequencerOutput publishes on them, and the sequencer's timers as ROS timers
 *        (when no lockstep runs them on explicit time, core::PlannerRuntime), and a periodic
 *        timer on the node's clock (the heartbeat's).
 */
#pragma once

#include <ros/callback_queue.h>
#include <ros/ros.h>

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "pedicle_drilling/StartTrial.h"
#include "pedicle_drilling/core/control/trial_sequencer.hpp"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/trajectory_route.hpp"

namespace pedicle_drilling {

/** @brief The planner's publishers, and the messages of a sequencer's output in their order. */
class PlannerPublishers {
 public:
  /**
   * @brief Advertises spindle/command (rad/s, not latched: a driver that reconnects must not
   *        get an old speed again), compensation/predicted_marker_pose, compensation/status
   *        (latched), ft_sensor/tare_request, drill/stop and compensation/heartbeat.
   * @param source the name the planner's stop commands carry (the nodelet's).
   */
  PlannerPublishers(ros::NodeHandle& nh, std::string source);

  /**
   * @brief Publishes @p out's spindle speeds, tare requests, trajectories (each split into one
   *        per controller of @p controllers, through @p route when there is one), predicted
   *        marker poses and the stops the planner decided (retreat; announced before the phase
   *        they cause, which the caller publishes after), stamped @p stamp.
   */
  void publish(const core::SequencerOutput& out, const ros::Time& stamp,
               const std::vector<core::ControllerSpec>& controllers, TrajectoryRoute* route) const;
  /** @brief compensation/status: @p phase, stamped @p stamp, with the stops heard this trial. */
  void publishStatus(core::TrialPhase phase, const ros::Time& stamp, std::uint32_t stops) const;
  /** @brief compensation/heartbeat stamped @p stamp (the drill guard's). */
  void publishHeartbeat(const ros::Time& stamp) const;

  /**
   * @brief Waits up to @p timeout_s of wall time for the drill guard (the safety monitor):
   *        @p enabled (its drill_guard/enable) said true and it listens to compensation/heartbeat.
   *        A heartbeat nobody hears protects nothing (a recorder or `rostopic echo` that
   *        subscribes is no guard), so no trial starts before.
   * @return false with the refusal in @p why when it did not come in time.
   */
  bool waitForGuard(const std::atomic<bool>& enabled, double timeout_s, std::string* why) const;

 private:
  std::string source_;
  ros::Publisher spindle_;
  ros::Publisher predicted_;
  ros::Publisher status_;
  ros::Publisher tare_request_;
  ros::Publisher stop_;
  ros::Publisher heartbeat_;
};

/**
 * @brief The planner's ~start_trial on a callback queue and a thread of its own (it calls other
 *        nodelets' services and waits for them: it never blocks the manager's worker threads),
 *        and what a trial start waits for before anything drills, in order: every controller's
 *        action server (~trajectory_interface action), the drill guard
 *        (PlannerPublishers::waitForGuard; not when the planner watches no monitor:
 *        monitor_timeout_s 0, an unsafe bench), then each of ~trial_start_services called
 *        (callTriggerChain: the components start afresh).
 */
class TrialStartService {
 public:
  /** @brief Answers a StartTrial call. */
  using Handler = std::function<bool(StartTrial::Request& req, StartTrial::Response& res)>;
  /** @brief The clients of ~trial_start_services, and the timeouts of @p params. */
  TrialStartService(ros::NodeHandle& nh, const CompensationPlannerNodeParams& params);
  /** @brief stop(). */
  ~TrialStartService() { stop(); }
  TrialStartService(const TrialStartService&) = delete;  // its service calls this object
  TrialStartService& operator=(const TrialStartService&) = delete;
  /** @brief Advertises `start_trial` on @p pnh, answered by @p handler on the thread. */
  void advertise(const ros::NodeHandle& pnh, Handler handler);
  /** @brief The thread ends (a call being answered first); no call is answered after it. */
  void stop();
  /** @brief Runs the chain (blocking, wall time): false with the refusal in @p why at the first
   *         link that fails (nothing after it is called). */
  bool runChain(const TrajectoryRoute& route, const PlannerPublishers& outputs,
                const std::atomic<bool>& guard_enabled, std::string* why);

 private:
  bool onCall(StartTrial::Request& req, StartTrial::Response& res) { return handler_(req, res); }
  double action_server_timeout_s_;
  double trial_start_timeout_s_;
  bool wait_for_guard_;
  std::vector<ros::ServiceClient> clients_;
  Handler handler_;
  ros::CallbackQueue queue_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
  ros::ServiceServer server_;
};

/** @brief The sequencer's timers as ROS timers (sim time or wall time, no lockstep). */
class SequencerRosTimers {
 public:
  /** @brief Called with the timer that fired. */
  using FireFn = std::function<void(core::TimerRequest::Kind kind)>;

  /** @brief Timers created on @p nh call @p fire. */
  SequencerRosTimers(ros::NodeHandle nh, FireFn fire) : nh_(nh), fire_(std::move(fire)) {}
  SequencerRosTimers(const SequencerRosTimers&) = delete;  // its timers call this object
  SequencerRosTimers& operator=(const SequencerRosTimers&) = delete;
  /** @brief Applies an output's timer requests: every timer stopped first if it says so, then
   *         each requested one (re)started. */
  void apply(const core::SequencerOutput& out);
  /** @brief Stops every timer (no callback starts after it). */
  void stop();

 private:
  ros::Timer& timer(core::TimerRequest::Kind kind);
  ros::NodeHandle nh_;
  FireFn fire_;
  ros::Timer pose_;
  ros::Timer registration_;
  ros::Timer segment_;
  ros::Timer keepalive_;
};

/**
 * @brief A periodic timer on the node's clock: a ROS timer under sim time (/clock), else a
 *        steady (monotonic) timer, which a step of the wall clock (NTP) does not pause.
 */
class ClockTimer {
 public:
  /** @brief Calls @p fn every @p period_s from now on (a running timer is replaced). */
  void start(ros::NodeHandle& nh, double period_s, std::function<void()> fn);
  /** @brief Stops it (no callback starts after it). */
  void stop();

 private:
  ros::Timer timer_;
  ros::SteadyTimer steady_;
};

}  // namespace pedicle_drilling
