#include "pedicle_drilling/ros/planner_outputs.hpp"

#include <geometry_msgs/PoseStamped.h>
#include <std_msgs/Float64.h>
#include <std_msgs/Header.h>
#include <std_srvs/Trigger.h>

#include <cstdint>
#include <utility>

#include "pedicle_drilling/StopCommand.h"
#include "pedicle_drilling/TareRequest.h"
#include "pedicle_drilling/core/common/param_table.hpp"
#include "pedicle_drilling/core/common/units.hpp"
#include "pedicle_drilling/ros/planner_conversions.hpp"
#include "pedicle_drilling/ros/publish_in_order.hpp"

namespace pedicle_drilling {

PlannerPublishers::PlannerPublishers(ros::NodeHandle& nh, std::string source)
    : source_(std::move(source)) {
  // Repeated every ~spindle_keepalive_s while it runs, for the driver's watchdog.
  spindle_ = nh.advertise<std_msgs::Float64>("spindle/command", 10);
  predicted_ = nh.advertise<geometry_msgs::PoseStamped>("compensation/predicted_marker_pose", 50);
  status_ = nh.advertise<TrialStatus>("compensation/status", 10, true);
  // The F/T tare before contact (~tare_samples > 0): the sensor driver's protocol.
  tare_request_ = nh.advertise<TareRequest>("ft_sensor/tare_request", 10);
  stop_ = nh.advertise<StopCommand>("drill/stop", 10);
  // The safety monitor's drill guard watches it while a trial runs (a lost planner: the
  // drives stop).
  heartbeat_ = nh.advertise<std_msgs::Header>("compensation/heartbeat", 10);
}

void PlannerPublishers::publish(const core::SequencerOutput& out, const ros::Time& stamp,
                                const std::vector<core::ControllerSpec>& controllers,
                                TrajectoryRoute* route) const {
  for (double rpm : out.spindle_rpm) {
    std_msgs::Float64 msg;
    msg.data = core::radPerSecFromRpm(rpm);
    publishInOrder(spindle_, msg);
  }
  for (const core::TareRequest& r : out.tare_requests) {
    TareRequest msg;
    msg.header.stamp = stamp;
    msg.samples = static_cast<std::uint32_t>(r.samples);
    msg.max_spread_n = r.max_spread_n;
    publishInOrder(tare_request_, msg);
  }
  for (const core::JointTrajectoryCommand& c : out.trajectories) {
    // One stream per controller, each naming its own joints (as a lab's controllers take it).
    for (const auto& [index, part] : core::splitByController(c, controllers)) {
      if (route) route->send(index, toMsg(part));
    }
  }
  for (const core::PredictedMarker& m : out.predicted) publishInOrder(predicted_, toMsg(m));
  // A stop the planner decided is announced before the phase it causes (a listener that
  // waits for 'failed' or 'retreating' has the reason by then).
  for (const std::string& why : out.stops) {
    StopCommand stop;
    stop.header.stamp = stamp;
    stop.source = source_;
    stop.reason = why;
    stop.retreat = true;
    publishInOrder(stop_, stop);
  }
}

void PlannerPublishers::publishStatus(core::TrialPhase phase, const ros::Time& stamp,
                                      std::uint32_t stops) const {
  TrialStatus msg = toMsg(phase, stamp);
  msg.stops = stops;
  publishInOrder(status_, msg);
}

void PlannerPublishers::publishHeartbeat(const ros::Time& stamp) const {
  std_msgs::Header msg;
  msg.stamp = stamp;
  publishInOrder(heartbeat_, msg);
}

bool PlannerPublishers::waitForGuard(const std::atomic<bool>& enabled, double timeout_s,
                                     std::string* why) const {
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (heartbeat_.getNumSubscribers() == 0 || !enabled) {
    if (ros::WallTime::now() > deadline || !ros::ok()) {
      *why =
          "trial refused: no drill guard (drill_guard/enable true, listening to "
          "compensation/heartbeat) within " +
          core::Range::format(timeout_s) +
          " s (is the SafetyMonitor running?); nothing was started";
      return false;
    }
    ros::WallDuration(0.01).sleep();
  }
  return true;
}

TrialStartService::TrialStartService(ros::NodeHandle& nh,
                                     const CompensationPlannerNodeParams& params)
    : action_server_timeout_s_(params.action_server_timeout_s),
      trial_start_timeout_s_(params.trial_start_timeout_s),
      wait_for_guard_(params.sequencer.monitor_timeout_s != 0.0) {
  for (const std::string& name : params.trial_start_services) {
    clients_.push_back(nh.serviceClient<std_srvs::Trigger>(name));
  }
}

void TrialStartService::advertise(const ros::NodeHandle& pnh, Handler handler) {
  handler_ = std::move(handler);
  ros::NodeHandle nh(pnh);
  nh.setCallbackQueue(&queue_);
  server_ = nh.advertiseService("start_trial", &TrialStartService::onCall, this);
  spinner_ = std::make_unique<ros::AsyncSpinner>(1, &queue_);
  spinner_->start();
}

void TrialStartService::stop() {
  if (spinner_) spinner_->stop();
}

bool TrialStartService::runChain(const TrajectoryRoute& route, const PlannerPublishers& outputs,
                                 const std::atomic<bool>& guard_enabled, std::string* why) {
  return route.waitForServers(action_server_timeout_s_, why) &&
         (!wait_for_guard_ || outputs.waitForGuard(guard_enabled, trial_start_timeout_s_, why)) &&
         callTriggerChain(&clients_, trial_start_timeout_s_, why);
}

void SequencerRosTimers::apply(const core::SequencerOutput& out) {
  if (out.stop_timers) stop();
  using Kind = core::TimerRequest::Kind;
  for (const core::TimerRequest& t : out.start_timers) {
    const Kind kind = t.kind;
    timer(kind) = nh_.createTimer(
        ros::Duration(t.delay_s), [this, kind](const ros::TimerEvent&) { fire_(kind); },
        !t.periodic);
  }
}

void SequencerRosTimers::stop() {
  for (ros::Timer* t : {&pose_, &registration_, &segment_, &keepalive_}) t->stop();
}

ros::Timer& SequencerRosTimers::timer(core::TimerRequest::Kind kind) {
  using Kind = core::TimerRequest::Kind;
  switch (kind) {
    case Kind::kPoseReached:
      return pose_;
    case Kind::kRegistrationTimeout:
      return registration_;
    case Kind::kSegment:
      return segment_;
    case Kind::kSpindleKeepalive:
      break;
  }
  return keepalive_;
}

void ClockTimer::start(ros::NodeHandle& nh, double period_s, std::function<void()> fn) {
  if (ros::Time::isSimTime()) {
    timer_ = nh.createTimer(ros::Duration(period_s),
                            [fn = std::move(fn)](const ros::TimerEvent&) { fn(); });
    return;
  }
  steady_ = nh.createSteadyTimer(ros::WallDuration(period_s),
                                 [fn = std::move(fn)](const ros::SteadyTimerEvent&) { fn(); });
}

void ClockTimer::stop() {
  timer_.stop();
  steady_.stop();
}

}  // namespace pedicle_drilling
