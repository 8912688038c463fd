/**
 * @file safety_monitor_nodelet.cpp
 * @brief pedicle_drilling/SafetyMonitor: the monitor of Algorithm 1 (paper Sec. IV-B). Stops and
 *        retreats the drill (`drill/stop`, retreat = true) when the predicted and tracked marker
 *        positions differ by more than H1, the force exceeds H2, the force or tracker stream
 *        goes silent, or any input is NaN. Reports on /diagnostics (diagnostic_updater: its
 *        status, and the rate and stamps of the F/T and tracker streams); latched until `~reset`.
 *        Thin wrapper of core::SafetySupervisor (pairing, arming and the one stop report) and
 *        of core::DrillGuard: the drives' enable heartbeat `drill_guard/enable` (std_msgs/Bool),
 *        false when the planner's heartbeat (`compensation/heartbeat`) is lost during its trial
 *        or a stop goes unanswered. Runs in a process apart from the planner (the launch files'
 *        guard manager). On hardware its timeouts run on the monotonic clock.
 */
#include <diagnostic_msgs/DiagnosticArray.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <diagnostic_updater/publisher.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <std_msgs/Bool.h>
#include <std_msgs/Header.h>
#include <std_srvs/Trigger.h>
#include <pluginlib/class_list_macros.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>

#include "pedicle_drilling/RetareCheck.h"
#include "pedicle_drilling/StopCommand.h"
#include "pedicle_drilling/TrialStatus.h"
#include "pedicle_drilling/core/common/stream_stats.hpp"
#include "pedicle_drilling/core/control/drill_guard.hpp"
#include "pedicle_drilling/core/control/safety_supervisor.hpp"
#include "pedicle_drilling/ros/lockstep.hpp"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"

namespace pedicle_drilling {

/**
 * @brief diagnostic_updater::Updater's tasks (added as to any Updater, the TopicDiagnostics
 *        too), collected into one DiagnosticArray that the monitor publishes itself: in order
 *        (publishInOrder; the Updater publishes by value) and stamped with the monitor's time
 *        (the lockstep's step; the Updater stamps ros::Time::now(), the last /clock).
 */
class InOrderUpdater : public diagnostic_updater::Updater {
 public:
  /** @brief @p name: the nodelet's name, the statuses' prefix and hardware id. */
  InOrderUpdater(const ros::NodeHandle& nh, const ros::NodeHandle& pnh, std::string name)
      : diagnostic_updater::Updater(nh, pnh, "/" + name), name_(std::move(name)) {
    setHardwareID(name_);
  }

  /** @brief Every task's status, named "<nodelet name>: <task>", as force_update() names it. */
  diagnostic_msgs::DiagnosticArray collect(const ros::Time& stamp) {
    diagnostic_msgs::DiagnosticArray array;
    array.header.stamp = stamp;
    boost::mutex::scoped_lock lock(lock_);  // the Updater's: no task added meanwhile
    for (const DiagnosticTaskInternal& task : getTasks()) {
      diagnostic_updater::DiagnosticStatusWrapper status;
      status.level = diagnostic_msgs::DiagnosticStatus::ERROR;
      status.message = "No message was set";
      status.hardware_id = name_;
      task.run(status);
      status.name = name_ + ": " + task.getName();
      array.status.push_back(status);
    }
    return array;
  }

 private:
  std::string name_;
};

/** @brief Nodelet wrapper of core::SafetySupervisor. */
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
    diagnostics_pub_.shutdown();        // its connection callback (onSubscriber)
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
      supervisor_ = std::make_unique<core::SafetySupervisor>(params.supervisor);
      guard_ = std::make_unique<core::DrillGuard>(params.guard);
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
    const core::SafetyParams& p = supervisor_->params().safety;
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
   * @brief /diagnostics through diagnostic_updater's tasks: the monitor's status, named
   *        "<nodelet name>: monitor" (the planner's ~monitor_status_name and the rviz plugins
   *        read it by name), and a rate and stamp check of the F/T and the tracker stream as
   *        their drivers publish them. Published by publishDiagnostics() (InOrderUpdater):
   *        wherever this nodelet published before, and every diagnostic_period_s (the
   *        Updater's own ~diagnostic_period is not used: update() is never called).
   *
   * The Updater's own publisher is neither latched nor told of new subscribers. roscpp keeps one
   * publication of /diagnostics per process, latched or not, and with the queue, as its first
   * advertiser says: advertised here first, latched, it keeps the process's /diagnostics latched
   * as before (failStartup()'s report relies on it too), so a late subscriber gets the latest
   * status at once; and a subscriber connecting also gets a fresh one.
   */
  void setupDiagnostics(ros::NodeHandle& nh, const SafetyMonitorNodeParams& params) {
    std::lock_guard<std::mutex> lock(mutex_);  // a subscriber may connect before the end
    diagnostics_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>(
        "/diagnostics", 10, [this](const ros::SingleSubscriberPublisher&) { onSubscriber(); },
        ros::SubscriberStatusCallback(), ros::VoidConstPtr(), true);
    updater_ = std::make_unique<InOrderUpdater>(nh, getPrivateNodeHandle(), getName());
    updater_->add("monitor", this, &SafetyMonitorNodelet::monitorStatus);
    force_rate_hz_ = params.expected_force_rate_hz;
    tracker_rate_hz_ = params.expected_tracker_rate_hz;
    const auto stream = [&](const std::string& topic, double* rate_hz) {
      return std::make_unique<diagnostic_updater::TopicDiagnostic>(
          nh.resolveName(topic), *updater_,
          diagnostic_updater::FrequencyStatusParam(rate_hz, rate_hz, params.rate_tolerance),
          diagnostic_updater::TimeStampStatusParam());
    };
    force_stream_ = stream("ft_sensor/wrench", &force_rate_hz_);
    tracker_stream_ = stream("tracker/marker_pose", &tracker_rate_hz_);
  }

  /** @brief A new /diagnostics subscriber: a fresh status (latching gave it the latest). */
  void onSubscriber() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (updater_) publishDiagnostics();
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
      guard_->onPlannerHeartbeat(now());
    });
  }

  /**
   * @brief The drives' enable, every guard_heartbeat_period_s and at once when it turns false
   *        (mutex_ held). The drivers stop feed and spindle when it is false or silent.
   */
  void beat() {
    const double t = now();
    const bool enable = guard_->enabled(t);
    if (enable == last_enable_ && t < next_beat_) return;
    if (!enable && last_enable_) {
      NODELET_ERROR("SafetyMonitor: drill guard: drives disabled: %s", guard_->reason().c_str());
    }
    last_enable_ = enable;
    next_beat_ = t + guard_->params().heartbeat_period_s;
    std_msgs::Bool msg;
    msg.data = enable;
    // No noteSent(): the simulator takes it when it arrives, at the step it was sent in.
    publishInOrder(enable_pub_, msg);
  }

  void onWrench(const geometry_msgs::WrenchStamped::ConstPtr& msg) {
    lockstep_->observe(msg->header.stamp);
    std::lock_guard<std::mutex> lock(mutex_);
    force_stream_->tick(msg->header.stamp);
    force_stats_.observe(msg->header.stamp.toSec(), lockstep_->now().toSec());  // ROS time
    const auto& f = msg->wrench.force;
    supervisor_->onForce(now(), Eigen::Vector3d(f.x, f.y, f.z));
    evaluate();
  }

  static core::StampedPosition toPosition(const geometry_msgs::PoseStamped& msg) {
    const auto& p = msg.pose.position;
    return {msg.header.stamp.toSec(), msg.header.frame_id, Eigen::Vector3d(p.x, p.y, p.z)};
  }

  void onTracked(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    lockstep_->observe(msg->header.stamp);
    std::lock_guard<std::mutex> lock(mutex_);
    tracker_stream_->tick(msg->header.stamp);
    tracker_stats_.observe(msg->header.stamp.toSec(), lockstep_->now().toSec());  // ROS time
    warnIfMismatch(supervisor_->onTracked(now(), toPosition(*msg)));
    evaluate();
  }

  void onPredicted(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    lockstep_->deliver(msg->header.stamp, 0, [this, msg] { handlePredicted(msg); });
  }

  void handlePredicted(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    warnIfMismatch(supervisor_->onPredicted(now(), toPosition(*msg)));
    evaluate();
  }

  void warnIfMismatch(core::PairResult r) {
    if (r == core::PairResult::kStale) {
      NODELET_WARN_THROTTLE(1.0,
                            "SafetyMonitor: stale tracker sample (stamp not newer than the last) "
                            "ignored; %ld so far",
                            supervisor_->staleTrackedCount());
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
    supervisor_->setTrialRunning(msg->running);
    const bool drilling = msg->phase == TrialStatus::DRILLING || msg->phase == TrialStatus::STOPPED;
    supervisor_->setDrilling(now(), drilling);
    guard_->onPlannerPhase(now(), msg->running, drilling);
    beat();
    const bool trial_ended = msg->phase == TrialStatus::DONE && last_phase_ != TrialStatus::DONE;
    const bool retreat_ended = trial_ended && last_phase_ == TrialStatus::RETREATING;
    last_phase_ = msg->phase;
    if (retreat_ended) checkRetare();
    // At the trial's end (after the re-tare check when it retreated): the verdict and the
    // trial's inputs as received, complete (the campaign records them).
    if (trial_ended) publishDiagnostics();
  }

  /** @brief The re-tare check when a retreat ended, on ~retare_check (latched). */
  void checkRetare() {
    const core::RetareCheck check = supervisor_->retareCheck(now());
    RetareCheck result;
    result.header.stamp = lockstep_->now();
    result.done = check.done;
    result.samples = check.samples;
    result.offset_n = check.offset_n;
    result.limit_n = supervisor_->params().safety.retare_max_offset_n;
    result.drift = check.drift;
    result.message = check.message;
    publishInOrder(retare_pub_, result);
    lockstep_->noteSent();
    last_retare_ = result;
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
    const double reset_gap_s = std::max(kResetGapS, 2.0 / check_rate_hz_);
    if (!last_step_.isZero() && (t - last_step_).toSec() > reset_gap_s) resetLocked();
    last_step_ = t;
    const double x = t.toSec() * check_rate_hz_;
    if (std::abs(x - std::round(x)) < 1e-6) {
      supervisor_->check(now());
      evaluate();
    }
    beat();
    if (next_diagnostics_.isZero() || t >= next_diagnostics_) {
      next_diagnostics_ = t + ros::Duration(diagnostic_period_s_);
      publishDiagnostics();
    }
  }

  /**
   * @brief Under the lockstep: the next step on the check grid at which a check can change
   *        anything, or of the diagnostics (LockstepParticipant::stepFor; the grid test's
   *        rounding is 1e-6 of a period). A check before the first stream's timeout is due
   *        changes nothing (SafetySupervisor::quietUntil): the monitor asks for the grid step
   *        one period before it, and for every one after it until a sample comes. Its inputs
   *        only change at steps it sees (the streams' steps, the steps after a participant
   *        sent), after which this is asked again. Without it the steps waited at for the
   *        200 Hz checks alone were a sixth of those the simulator waited at (51 % -> 43 % of
   *        the steps), with nothing to do at almost all of them.
   */
  std::optional<ros::Time> nextStep(const ros::Time& t) {
    std::lock_guard<std::mutex> lock(mutex_);
    const double tick =
        core::nextUsefulCheckTick(t.toSec(), check_rate_hz_, supervisor_->quietUntil());
    std::optional<ros::Time> next;
    if (std::isfinite(tick)) next = LockstepParticipant::stepFor(tick / check_rate_hz_);
    // The guard's next heartbeat, and its next deadline (the enable turns false there).
    const double guard_due = std::min(next_beat_, guard_->quietUntil() + 1e-3);
    const ros::Time beat_step = LockstepParticipant::stepFor(guard_due);
    if (!next || beat_step < *next) next = beat_step;
    if (!next_diagnostics_.isZero() && (!next || next_diagnostics_ < *next)) {
      next = next_diagnostics_;
    }
    return next;
  }

  /** @brief /diagnostics now (the planner handles the monitor's status at the next step). */
  void publishDiagnostics() {
    // lockstep_ exists before /diagnostics is advertised (onInit), so a subscriber that
    // connects while onInit runs finds it.
    publishInOrder(diagnostics_pub_, updater_->collect(lockstep_->now()));
    lockstep_->noteSent();
  }

  void onCheck(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    supervisor_->check(now());
    evaluate();
    beat();
  }

  /** @brief Publish the stop and the ERROR diagnostic once, when the verdict turns to stop. */
  void evaluate() {
    const std::optional<core::SafetyVerdict> v = supervisor_->takeNewStop();
    if (!v) return;
    StopCommand stop;
    stop.header.stamp = lockstep_->now();
    stop.source = getName();
    stop.retreat = true;
    stop.reason = core::describe(*v);
    publishInOrder(stop_pub_, stop);
    lockstep_->noteSent();
    guard_->onMonitorStop(now());
    NODELET_ERROR("SafetyMonitor: STOP and retreat: %s", stop.reason.c_str());
    publishDiagnostics();
  }

  void onDiagnosticTimer(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    publishDiagnostics();
  }

  /**
   * @brief The monitor's status (the Updater's task "monitor"; run by publishDiagnostics(), always
   *        called with mutex_ held): OK while fine, ERROR with the reason from the stop on, WARN
   *        after a re-tare check that found a drift (until ~reset); the verdict's reason and
   *        each input stream as this monitor received it since ~reset: samples, samples missing
   *        (gaps in the stamps), the largest delay from stamp to handling.
   */
  void monitorStatus(diagnostic_updater::DiagnosticStatusWrapper& status) {
    const core::SafetyVerdict& v = supervisor_->verdict();
    if (v.stop) {
      status.summary(diagnostic_msgs::DiagnosticStatus::ERROR,
                     "stop and retreat: " + core::describe(v));
    } else if (last_retare_ && last_retare_->drift) {
      // Stays until ~reset (the next trial's start): the last trial's force is not trusted.
      status.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                     "re-tare check: " + last_retare_->message);
    } else {
      status.summary(diagnostic_msgs::DiagnosticStatus::OK,
                     supervisor_->heardBoth() ? "monitoring" : "waiting for force/tracker");
    }
    status.add("reason", core::toString(v.reason));
    status.add("drives_enabled", last_enable_ ? "true" : "false");
    if (!guard_->reason().empty()) status.add("drill_guard", guard_->reason());
    // The planner's trial as this monitor last heard it: the status published when it heard
    // the trial end is the first "false" after a "true" (a campaign's record of its inputs).
    status.add("trial_running", supervisor_->trialRunning() ? "true" : "false");
    for (const auto& [name, stats] :
         {std::pair<std::string, const core::StreamStats*>("force", &force_stats_),
          {"tracker", &tracker_stats_}}) {
      status.add(name + "_samples", std::to_string(stats->count()));
      status.add(name + "_samples_missing", std::to_string(stats->missing()));
      status.add(name + "_delay_max_ms", std::to_string(1e3 * stats->maxDelay()));
    }
    if (last_retare_ && last_retare_->done) {
      status.add("retare_offset_n", std::to_string(last_retare_->offset_n));
    }
  }

  bool onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (guard_->plannerRunning()) {
      // A trial runs (the drill may be in bone, or about to be): a reset would clear a stop,
      // the guard's latch or the streams' watch mid-trial. Refused; the planner's next trial
      // start resets it (a restarted planner says IDLE first).
      response.success = false;
      response.message =
          "refused: the planner's trial is running; the monitor resets at the next trial's "
          "start";
      NODELET_WARN("SafetyMonitor: ~reset %s", response.message.c_str());
      return true;
    }
    const std::string previous = core::toString(supervisor_->verdict().reason);
    resetLocked();
    response.success = true;
    response.message = "monitor reset (previous verdict: " + previous + ")";
    return true;
  }

  /** @brief ~reset's work (mutex_ held): verdict, retare check and stream statistics. */
  void resetLocked() {
    supervisor_->reset();
    supervisor_->setDrilling(now(), guard_->plannerDrilling());  // the planner's phase stays
    guard_->reset();
    last_retare_.reset();
    force_stats_.reset();
    tracker_stats_.reset();
    publishDiagnostics();
  }

  /** @brief A gap between two lockstep steps that only a simulator reset makes [s] (at least
   *         two check periods). */
  static constexpr double kResetGapS = 1.0;
  ros::Time last_step_;  ///< the latest lockstep step (zero: none yet)

  std::mutex mutex_;
  std::unique_ptr<core::SafetySupervisor> supervisor_;
  std::unique_ptr<core::DrillGuard> guard_;
  bool last_enable_ = true;  ///< the latest drill_guard/enable sent
  double next_beat_ = 0.0;   ///< the next heartbeat's time (now())
  // Declared before what calls them (the lockstep, the subscribers, the timers): destroyed after.
  std::unique_ptr<InOrderUpdater> updater_;
  double force_rate_hz_ = 1000.0 / 3.0;  ///< the F/T stream's check reads it (a pointer)
  double tracker_rate_hz_ = 8.0;         ///< the tracker stream's check reads it (a pointer)
  std::unique_ptr<diagnostic_updater::TopicDiagnostic> force_stream_;
  std::unique_ptr<diagnostic_updater::TopicDiagnostic> tracker_stream_;
  std::unique_ptr<LockstepParticipant> lockstep_;
  double check_rate_hz_ = 200.0;
  double diagnostic_period_s_ = 1.0;
  ros::Time next_diagnostics_;                   ///< under the lockstep
  std::uint8_t last_phase_ = TrialStatus::IDLE;  ///< the planner's phase before the latest
  ros::Publisher retare_pub_;
  core::StreamStats force_stats_;           ///< the F/T stream since ~reset
  core::StreamStats tracker_stats_;         ///< the tracker stream since ~reset
  std::optional<RetareCheck> last_retare_;  ///< the latest re-tare check, until ~reset
  ros::Publisher stop_pub_;
  ros::Publisher enable_pub_;
  ros::Subscriber heartbeat_sub_;
  ros::SteadyTimer steady_check_timer_;
  ros::SteadyTimer steady_diagnostic_timer_;
  ros::Publisher diagnostics_pub_;  ///< latched /diagnostics, see setupDiagnostics()
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
