/**
 * @file safety_monitor_nodelet.cpp
 * @brief pedicle_drilling/SafetyMonitor: the monitor of Algorithm 1 (paper Sec. IV-B). Stops and
 *        retreats the drill (`drill/stop`, retreat = true) when the predicted and tracked marker
 *        positions differ by more than H1, the force exceeds H2, the force or tracker stream
 *        goes silent, or any input is NaN. Reports on /diagnostics (diagnostic_updater: its
 *        status, and the rate and stamps of the F/T and tracker streams); latched until `~reset`.
 *        Thin wrapper of core::MonitorRuntime: core::SafetySupervisor (pairing, arming and the
 *        one stop report) and core::DrillGuard: the drives' enable heartbeat
 *        `drill_guard/enable` (std_msgs/Bool), false when the planner's heartbeat
 *        (`compensation/heartbeat`) is lost during its trial or a stop goes unanswered. Runs in a
 *        process apart from the planner (the launch files' guard manager). On hardware its
 *        timeouts run on the monotonic clock.
 */
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <std_msgs/Bool.h>
#include <std_msgs/Header.h>
#include <std_srvs/Trigger.h>
#include <pluginlib/class_list_macros.hpp>

#include <algorithm>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "pedicle_drilling/RetareCheck.h"
#include "pedicle_drilling/StopCommand.h"
#include "pedicle_drilling/TrialStatus.h"
#include "pedicle_drilling/core/control/monitor_runtime.hpp"
#include "pedicle_drilling/ros/in_order_updater.hpp"
#include "pedicle_drilling/ros/lockstep.hpp"
#include "pedicle_drilling/ros/monitor_conversions.hpp"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"

namespace pedicle_drilling {

/** @brief Nodelet wrapper of core::MonitorRuntime. */
class SafetyMonitorNodelet : public nodelet::Nodelet {
 public:
  ~SafetyMonitorNodelet() override {
    // Unloaded from a running manager: every callback ends before any member it may use goes
    // away (the lockstep's steps run on the participants' thread, the rest on the manager's).
    if (lockstep_) lockstep_->stop();
    for (ros::Subscriber* sub :
         {&wrench_sub_, &tracker_sub_, &predicted_sub_, &status_sub_, &heartbeat_sub_}) {
      sub->shutdown();
    }
    reset_srv_.shutdown();
    check_timer_.stop();
    diagnostic_timer_.stop();
    steady_check_timer_.stop();
    steady_diagnostic_timer_.stop();
    if (diagnostics_) diagnostics_->shutdown();  // its connection callback
    if (lockstep_) lockstep_->drain();  // a ~reset call or connection callback running ends
  }

 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    ros::NodeHandle pnh = getPrivateNodeHandle();
    SafetyMonitorNodeParams params;
    try {
      ParamLoader(pnh).load(SafetyMonitorNodeParams::table(), &params);
      if (params.unsafe_allow_disabled_watchdogs) warnDisabledWatchdogs(params);
      monitor_ = std::make_unique<core::MonitorRuntime>(params.supervisor, params.guard);
      check_rate_hz_ = params.check_rate_hz;
      diagnostic_period_s_ = params.diagnostic_period_s;
      // Under the simulator's lockstep the checks and the diagnostics run on its steps: a check
      // at every step whose time is a multiple of 1 / check_rate_hz (the engine's), after the
      // predicted poses and statuses sent in the step before. Its steps come from start(), at
      // the end; it exists before anything that reads the monitor's time (now()).
      lockstep_ = std::make_unique<LockstepParticipant>(
          nh, getName(), [this](const ros::Time& t) { onStep(t); }, true,
          [this](const ros::Time& t) { return nextStep(t); });
      lockstep_->shareQueue({&nh, &pnh});  // under the lockstep: the participants' thread
    } catch (const std::exception& e) {
      failStartup(getName(), e.what());  // throws: the load fails, nothing advertised yet
    }
    // The nodelet manager runs this nodelet's callbacks while onInit still runs (nodelet
    // 1.10.2): everything a callback touches exists before the callback can be registered.
    setupDiagnostics(nh, params);
    // Latched: a planner that (re)connects during the trial still hears the stop (it ignores a
    // stop stamped before its trial's start).
    stop_pub_ = nh.advertise<StopCommand>("drill/stop", 10, true);
    enable_pub_ = nh.advertise<std_msgs::Bool>("drill_guard/enable", 10);
    retare_pub_ = pnh.advertise<RetareCheck>("retare_check", 10, true);
    reset_srv_ = pnh.advertiseService("reset", &SafetyMonitorNodelet::onReset, this);
    const ros::TransportHints hints = ros::TransportHints().tcpNoDelay();
    wrench_sub_ =
        nh.subscribe("ft_sensor/wrench", 1000, &SafetyMonitorNodelet::onWrench, this, hints);
    tracker_sub_ =
        nh.subscribe("tracker/marker_pose", 50, &SafetyMonitorNodelet::onTracked, this, hints);
    predicted_sub_ = nh.subscribe("compensation/predicted_marker_pose", 50,
                                  &SafetyMonitorNodelet::onPredicted, this, hints);
    status_sub_ =
        nh.subscribe("compensation/status", 10, &SafetyMonitorNodelet::onPlannerStatus, this);
    heartbeat_sub_ = nh.subscribe("compensation/heartbeat", 10,
                                  &SafetyMonitorNodelet::onPlannerHeartbeat, this, hints);
    if (!lockstep_->enabled()) createTimers(nh, params);
    const core::SafetyParams& p = monitor_->supervisor().params().safety;
    NODELET_INFO(
        "SafetyMonitor: H1 %.2f mm, H2 %.1f N, force timeout %.3f s, tracker timeout "
        "%.3f s, checks at %.0f Hz",
        p.position_threshold_m * 1e3, p.force_threshold_N, p.force_timeout_s, p.tracker_timeout_s,
        params.check_rate_hz);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      publishDiagnostics();
    }
    lockstep_->start();  // last: the steps call onStep
  }

  /**
   * @brief /diagnostics (InOrderDiagnostics): the monitor's status, named "<nodelet name>:
   *        monitor" (the planner's ~monitor_status_name and the rviz plugins read it by name),
   *        and a rate and stamp check of the F/T and the tracker stream as their drivers publish
   *        them; published wherever this nodelet published before, and every
   *        diagnostic_period_s. A new subscriber gets a fresh status (latching, the latest).
   */
  void setupDiagnostics(ros::NodeHandle& nh, const SafetyMonitorNodeParams& params) {
    std::lock_guard<std::mutex> lock(mutex_);  // a subscriber may connect before the end
    diagnostics_ =
        std::make_unique<InOrderDiagnostics>(nh, getPrivateNodeHandle(), getName(), [this] {
          std::lock_guard<std::mutex> lock(mutex_);
          if (diagnostics_) publishDiagnostics();
        });
    diagnostics_->updater().add("monitor", this, &SafetyMonitorNodelet::monitorStatus);
    force_stream_ = &diagnostics_->addStream(nh.resolveName("ft_sensor/wrench"),
                                             params.expected_force_rate_hz, params.rate_tolerance);
    tracker_stream_ =
        &diagnostics_->addStream(nh.resolveName("tracker/marker_pose"),
                                 params.expected_tracker_rate_hz, params.rate_tolerance);
  }

  /**
   * @brief The monitor's time: the lockstep's step; on sim time (/clock) ros::Time::now(); on
   *        hardware the monotonic clock, so that a step of the wall clock (NTP) neither
   *        silences nor fires a timeout. Stamps of what it publishes stay ROS time.
   */
  double now() const {
    if (lockstep_->enabled() || ros::Time::isSimTime()) return lockstep_->now().toSec();
    return ros::SteadyTime::now().toSec();
  }

  /** @brief The checks (with the guard's heartbeat) and the diagnostics without the lockstep:
   *         on sim time ROS timers, on hardware steady (monotonic) timers. */
  void createTimers(ros::NodeHandle& nh, const SafetyMonitorNodeParams& params) {
    const double check_period =
        std::min(1.0 / params.check_rate_hz, params.guard.heartbeat_period_s);
    if (ros::Time::isSimTime()) {
      check_timer_ =
          nh.createTimer(ros::Duration(check_period), &SafetyMonitorNodelet::onCheck, this);
      diagnostic_timer_ = nh.createTimer(ros::Duration(params.diagnostic_period_s),
                                         &SafetyMonitorNodelet::onDiagnosticTimer, this);
      return;
    }
    steady_check_timer_ =
        nh.createSteadyTimer(ros::WallDuration(check_period),
                             [this](const ros::SteadyTimerEvent&) { onCheck(ros::TimerEvent()); });
    steady_diagnostic_timer_ = nh.createSteadyTimer(
        ros::WallDuration(params.diagnostic_period_s),
        [this](const ros::SteadyTimerEvent&) { onDiagnosticTimer(ros::TimerEvent()); });
  }

  /** @brief The WARN at load of each watchdog the parameters disable (unsafe_ set). */
  void warnDisabledWatchdogs(const SafetyMonitorNodeParams& params) const {
    for (const std::string& off : params.disabledWatchdogs()) {
      NODELET_WARN("SafetyMonitor: UNSAFE: %s (unsafe_allow_disabled_watchdogs)", off.c_str());
    }
  }

  /** @brief compensation/heartbeat: the planner's process is alive (core::DrillGuard). */
  void onPlannerHeartbeat(const std_msgs::Header::ConstPtr& msg) {
    lockstep_->deliver(msg->stamp, 2, [this] {
      std::lock_guard<std::mutex> lock(mutex_);
      monitor_->guard().onPlannerHeartbeat(now());
    });
  }

  /**
   * @brief The drives' enable, every guard_heartbeat_period_s and at once when it turns false
   *        (mutex_ held). The drivers stop feed and spindle when it is false or silent.
   */
  void beat() {
    const std::optional<core::EnableBeat> beat = monitor_->beat(now());
    if (!beat) return;
    if (beat->turned_off) {
      NODELET_ERROR("SafetyMonitor: drill guard: drives disabled: %s",
                    monitor_->guard().reason().c_str());
    }
    std_msgs::Bool msg;
    msg.data = beat->enable;
    // No noteSent(): the simulator takes it when it arrives, at the step it was sent in.
    publishInOrder(enable_pub_, msg);
  }

  void onWrench(const geometry_msgs::WrenchStamped::ConstPtr& msg) {
    lockstep_->observe(msg->header.stamp);
    std::lock_guard<std::mutex> lock(mutex_);
    force_stream_->tick(msg->header.stamp);
    const auto& f = msg->wrench.force;
    monitor_->onForce(now(), msg->header.stamp.toSec(), lockstep_->now().toSec(),  // ROS time
                      Eigen::Vector3d(f.x, f.y, f.z));
    evaluate();
  }

  void onTracked(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    lockstep_->observe(msg->header.stamp);
    std::lock_guard<std::mutex> lock(mutex_);
    tracker_stream_->tick(msg->header.stamp);
    warnIfMismatch(monitor_->onTracked(now(), lockstep_->now().toSec(), toStamped(*msg)));
    evaluate();
  }

  void onPredicted(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    lockstep_->deliver(msg->header.stamp, 0, [this, msg] { handlePredicted(msg); });
  }

  void handlePredicted(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    warnIfMismatch(monitor_->supervisor().onPredicted(now(), toStamped(*msg)));
    evaluate();
  }

  void warnIfMismatch(core::PairResult r) {
    if (r == core::PairResult::kStale) {
      NODELET_WARN_THROTTLE(1.0,
                            "SafetyMonitor: stale tracker sample (stamp not newer than the last) "
                            "ignored; %ld so far",
                            monitor_->supervisor().staleTrackedCount());
      return;
    }
    if (r != core::PairResult::kFrameMismatch) return;
    NODELET_WARN_THROTTLE(1.0,
                          "SafetyMonitor: the predicted and the tracked marker pose are in "
                          "different frames; position check skipped");
  }

  /**
   * @brief The planner's phase: while a trial runs, a stream never heard is a timeout too; when
   *        a retreat ends (retreating -> done) the re-tare check, published on ~retare_check
   *        (latched); a drift also turns the diagnostics to WARN until ~reset.
   */
  void onPlannerStatus(const TrialStatus::ConstPtr& msg) {
    lockstep_->deliver(msg->header.stamp, 1, [this, msg] { handlePlannerStatus(msg); });
  }

  void handlePlannerStatus(const TrialStatus::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const core::PhaseChange change =
        monitor_->onPlannerPhase(now(), static_cast<core::TrialPhase>(msg->phase), msg->running);
    beat();
    if (change.retreat_ended) checkRetare();
    // At the trial's end (after the re-tare check when it retreated): the verdict and the
    // trial's inputs as received, complete (the campaign records them).
    if (change.trial_ended) publishDiagnostics();
  }

  /** @brief The re-tare check when a retreat ended, on ~retare_check (latched). */
  void checkRetare() {
    const core::RetareCheck check = monitor_->checkRetare(now());
    const double limit_n = monitor_->supervisor().params().safety.retare_max_offset_n;
    publishInOrder(retare_pub_, toMsg(check, limit_n, lockstep_->now()));
    lockstep_->noteSent();
    if (!check.done) {
      NODELET_WARN("SafetyMonitor: re-tare check skipped: no force sample in the window");
    } else if (check.drift) {
      NODELET_ERROR("SafetyMonitor: %s", check.message.c_str());  // diagnostics WARN, to ~reset
    } else {
      NODELET_INFO("SafetyMonitor: re-tare check: %.3f N from the tare after the retreat",
                   check.offset_n);
    }
  }

  /** @brief Under the lockstep: the check when the step is on the check grid, diagnostics every
   *         diagnostic_period_s of sim time. */
  void onStep(const ros::Time& t) {
    std::lock_guard<std::mutex> lock(mutex_);
    // This monitor asks for a step every 1 / check_rate_hz (and the simulator's streams step it
    // more often): a step much later is a new simulation (simulator/reset moved sim time ahead,
    // ResetSimulation.time_zero), not a silent sensor. It starts afresh, as ~reset does,
    // instead of taking the jump for a stream timeout.
    const double reset_gap_s = core::MonitorRuntime::resetGap(check_rate_hz_);
    if (!last_step_.isZero() && (t - last_step_).toSec() > reset_gap_s) resetLocked();
    last_step_ = t;
    if (core::MonitorRuntime::onCheckGrid(t.toSec(), check_rate_hz_)) {
      monitor_->supervisor().check(now());
      evaluate();
    }
    beat();
    if (next_diagnostics_.isZero() || t >= next_diagnostics_) {
      next_diagnostics_ = t + ros::Duration(diagnostic_period_s_);
      publishDiagnostics();
    }
  }

  /** @brief Under the lockstep: the step at which the monitor can next change anything
   *         (core::MonitorRuntime::nextUsefulTime), or of the diagnostics. */
  std::optional<ros::Time> nextStep(const ros::Time& t) {
    std::lock_guard<std::mutex> lock(mutex_);
    ros::Time next =
        LockstepParticipant::stepFor(monitor_->nextUsefulTime(t.toSec(), check_rate_hz_));
    if (!next_diagnostics_.isZero() && next_diagnostics_ < next) next = next_diagnostics_;
    return next;
  }

  /** @brief /diagnostics now (the planner handles the monitor's status at the next step). */
  void publishDiagnostics() {
    // lockstep_ exists before /diagnostics is advertised (onInit), so a subscriber that
    // connects while onInit runs finds it.
    diagnostics_->publish(lockstep_->now());
    lockstep_->noteSent();
  }

  void onCheck(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    monitor_->supervisor().check(now());
    evaluate();
    beat();
  }

  /** @brief Publish the stop and the ERROR diagnostic once, when the verdict turns to stop. */
  void evaluate() {
    const std::optional<core::SafetyVerdict> v = monitor_->takeNewStop(now());
    if (!v) return;
    const StopCommand stop = toStopMsg(*v, getName(), lockstep_->now());
    publishInOrder(stop_pub_, stop);
    lockstep_->noteSent();
    NODELET_ERROR("SafetyMonitor: STOP and retreat: %s", stop.reason.c_str());
    publishDiagnostics();
  }

  void onDiagnosticTimer(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    publishDiagnostics();
  }

  /** @brief The Updater's task "monitor" (run by publishDiagnostics(), mutex_ held):
   *         core::MonitorRuntime::status. */
  void monitorStatus(diagnostic_updater::DiagnosticStatusWrapper& status) {
    fillStatus(monitor_->status(), &status);
  }

  bool onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
    response.message = monitor_->resetRefusal();
    if (!response.message.empty()) {
      response.success = false;
      NODELET_WARN("SafetyMonitor: ~reset %s", response.message.c_str());
      return true;
    }
    const std::string previous = core::toString(monitor_->supervisor().verdict().reason);
    resetLocked();
    response.success = true;
    response.message = "monitor reset (previous verdict: " + previous + ")";
    return true;
  }

  /** @brief ~reset's work (mutex_ held): verdict, retare check and stream statistics. */
  void resetLocked() {
    monitor_->reset(now());
    publishDiagnostics();
  }

  ros::Time last_step_;  ///< the latest lockstep step (zero: none yet)

  std::mutex mutex_;
  std::unique_ptr<core::MonitorRuntime> monitor_;
  // Declared before what calls them (the lockstep, the subscribers, the timers): destroyed after.
  std::unique_ptr<InOrderDiagnostics> diagnostics_;
  diagnostic_updater::TopicDiagnostic* force_stream_ = nullptr;    ///< diagnostics_' own
  diagnostic_updater::TopicDiagnostic* tracker_stream_ = nullptr;  ///< diagnostics_' own
  std::unique_ptr<LockstepParticipant> lockstep_;
  double check_rate_hz_ = 200.0;
  double diagnostic_period_s_ = 1.0;
  ros::Time next_diagnostics_;  ///< under the lockstep
  ros::Publisher retare_pub_;
  ros::Publisher stop_pub_;
  ros::Publisher enable_pub_;
  ros::Subscriber heartbeat_sub_;
  ros::SteadyTimer steady_check_timer_;
  ros::SteadyTimer steady_diagnostic_timer_;
  ros::Subscriber wrench_sub_;
  ros::Subscriber tracker_sub_;
  ros::Subscriber predicted_sub_;
  ros::Subscriber status_sub_;
  ros::ServiceServer reset_srv_;
  ros::Timer check_timer_;
  ros::Timer diagnostic_timer_;
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::SafetyMonitorNodelet, nodelet::Nodelet)
