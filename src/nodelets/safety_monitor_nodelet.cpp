/**
 * @file safety_monitor_nodelet.cpp
 * @brief pedicle_drilling/SafetyMonitor: the monitor of Algorithm 1 (paper Sec. IV-B). Stops and
 *        retreats the drill (`drill/stop`, retreat = true) when the predicted and tracked marker
 *        positions differ by more than H1, the force exceeds H2, the force or tracker stream
 *        goes silent, or any input is NaN. Reports on /diagnostics; latched until `~reset`.
 *        Thin wrapper of core::SafetyMonitor.
 */
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <std_msgs/String.h>
#include <std_srvs/Trigger.h>

#include <cmath>
#include <deque>
#include <memory>
#include <mutex>
#include <set>
#include <string>

#include "pedicle_drilling/StopCommand.h"
#include "pedicle_drilling/core/safety_monitor.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"

namespace pedicle_drilling {

/** @brief Nodelet wrapper of core::SafetyMonitor. */
class SafetyMonitorNodelet : public nodelet::Nodelet {
 private:
  struct StampedPosition {
    ros::Time stamp;
    std::string frame;
    Eigen::Vector3d p;
  };

  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    ros::NodeHandle pnh = getPrivateNodeHandle();
    double check_rate_hz = 0.0;
    double diagnostic_period_s = 0.0;
    try {
      const ParamLoader params(pnh);
      core::SafetyParams p;
      p.position_threshold_m =
          params.getDouble("position_threshold_m", p.position_threshold_m, 0.0, 0.1, true);
      p.force_threshold_N =
          params.getDouble("force_threshold_n", p.force_threshold_N, 0.0, 1000.0, true);
      p.force_timeout_s = params.getDouble("force_timeout_s", p.force_timeout_s, 0.0, 60.0, true);
      p.tracker_timeout_s =
          params.getDouble("tracker_timeout_s", p.tracker_timeout_s, 0.0, 60.0, true);
      check_rate_hz = params.getDouble("check_rate_hz", 200.0, 0.0, 10000.0, true);
      pair_tolerance_s_ = params.getDouble("pair_tolerance_s", 0.02, 0.0, 1.0);
      diagnostic_period_s = params.getDouble("diagnostic_period_s", 1.0, 0.0, 60.0, true);
      if (1.0 / check_rate_hz > 0.5 * p.force_timeout_s) {
        params.fail("check_rate_hz", "is too low to check force_timeout_s (needs at least 2 "
                    "checks per timeout)");
      }
      monitor_ = std::make_unique<core::SafetyMonitor>(p);
    } catch (const std::exception& e) {
      startup_status_.fail(nh, getName(), e.what());
      return;
    }
    stop_pub_ = nh.advertise<StopCommand>("drill/stop", 10);
    diagnostics_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10, true);
    reset_srv_ = pnh.advertiseService("reset", &SafetyMonitorNodelet::onReset, this);
    const ros::TransportHints hints = ros::TransportHints().tcpNoDelay();
    wrench_sub_ = nh.subscribe("ft_sensor/wrench", 1000, &SafetyMonitorNodelet::onWrench, this,
                               hints);
    tracker_sub_ = nh.subscribe("tracker/marker_pose", 50, &SafetyMonitorNodelet::onTracked, this,
                                hints);
    predicted_sub_ = nh.subscribe("compensation/predicted_marker_pose", 50,
                                  &SafetyMonitorNodelet::onPredicted, this, hints);
    status_sub_ = nh.subscribe("compensation/status", 10, &SafetyMonitorNodelet::onPlannerStatus,
                               this);
    check_timer_ = nh.createTimer(ros::Duration(1.0 / check_rate_hz),
                                  &SafetyMonitorNodelet::onCheck, this);
    diagnostic_timer_ = nh.createTimer(ros::Duration(diagnostic_period_s),
                                       &SafetyMonitorNodelet::onDiagnosticTimer, this);
    const core::SafetyParams& p = monitor_->params();
    NODELET_INFO("SafetyMonitor: H1 %.2f mm, H2 %.1f N, force timeout %.3f s, tracker timeout "
                 "%.3f s, checks at %.0f Hz",
                 p.position_threshold_m * 1e3, p.force_threshold_N, p.force_timeout_s,
                 p.tracker_timeout_s, check_rate_hz);
    publishDiagnostics();
  }

  static double now() { return ros::Time::now().toSec(); }

  void onWrench(const geometry_msgs::WrenchStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto& f = msg->wrench.force;
    have_force_ = true;
    monitor_->onForce(now(), Eigen::Vector3d(f.x, f.y, f.z));  // H2 acts on this very sample
    evaluate();
  }

  static StampedPosition toPosition(const geometry_msgs::PoseStamped& msg) {
    const auto& p = msg.pose.position;
    return {msg.header.stamp, msg.header.frame_id, Eigen::Vector3d(p.x, p.y, p.z)};
  }

  void onTracked(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const StampedPosition tracked = toPosition(*msg);
    have_tracker_ = true;
    // Feeds the watchdog (and the NaN check) even when no prediction exists (no trial running).
    monitor_->onTracked(now(), tracked.p, tracked.p);
    remember(&tracked_, tracked);
    const StampedPosition* predicted = nearest(predicted_, tracked.stamp);
    if (predicted != nullptr) compare(*predicted, tracked);
    evaluate();
  }

  void onPredicted(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const StampedPosition predicted = toPosition(*msg);
    if (!predicted.p.allFinite()) {
      monitor_->onTracked(now(), predicted.p, predicted.p);  // NaN prediction: stop
    } else {
      remember(&predicted_, predicted);
      const StampedPosition* tracked = nearest(tracked_, predicted.stamp);
      if (tracked != nullptr) compare(predicted, *tracked);
    }
    evaluate();
  }

  void compare(const StampedPosition& predicted, const StampedPosition& tracked) {
    if (predicted.frame != tracked.frame) {
      NODELET_WARN_THROTTLE(1.0, "SafetyMonitor: predicted pose frame '%s' differs from tracked "
                            "frame '%s'; position check skipped",
                            predicted.frame.c_str(), tracked.frame.c_str());
      return;
    }
    monitor_->onTracked(now(), predicted.p, tracked.p);
  }

  static void remember(std::deque<StampedPosition>* buffer, const StampedPosition& s) {
    buffer->push_back(s);
    while (buffer->size() > 64) buffer->pop_front();
  }

  const StampedPosition* nearest(const std::deque<StampedPosition>& buffer,
                                 const ros::Time& stamp) const {
    const StampedPosition* best = nullptr;
    double best_dt = pair_tolerance_s_;
    for (const StampedPosition& s : buffer) {
      const double dt = std::abs((s.stamp - stamp).toSec());
      if (dt <= best_dt) {
        best_dt = dt;
        best = &s;
      }
    }
    return best;
  }

  /** @brief The planner's phase: while a trial runs, a stream never heard is a timeout too. */
  void onPlannerStatus(const std_msgs::String::ConstPtr& msg) {
    static const std::set<std::string> kTrialPhases = {"moving_to_pose", "registering",
                                                       "drilling", "stopped", "retreating"};
    std::lock_guard<std::mutex> lock(mutex_);
    trial_running_ = kTrialPhases.count(msg->data) > 0;
  }

  void onCheck(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    // The watchdog is armed once both streams have been heard since start or reset, or as soon
    // as a trial runs: then a sensor that never published times out from the arming time.
    if ((have_force_ && have_tracker_) || trial_running_) monitor_->check(now());
    evaluate();
  }

  /** @brief Publish the stop and the ERROR diagnostic once, when the verdict turns to stop. */
  void evaluate() {
    if (!monitor_->stopped() || stop_sent_) return;
    stop_sent_ = true;
    const core::SafetyVerdict& v = monitor_->verdict();
    StopCommand stop;
    stop.header.stamp = ros::Time::now();
    stop.source = getName();
    stop.retreat = true;
    stop.reason = core::describe(v);
    stop_pub_.publish(stop);
    NODELET_ERROR("SafetyMonitor: STOP and retreat: %s", stop.reason.c_str());
    publishDiagnostics();
  }

  void onDiagnosticTimer(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    publishDiagnostics();
  }

  void publishDiagnostics() {
    diagnostic_msgs::DiagnosticArray array;
    array.header.stamp = ros::Time::now();
    diagnostic_msgs::DiagnosticStatus status;
    status.name = getName() + ": monitor";
    status.hardware_id = getName();
    const core::SafetyVerdict& v = monitor_->verdict();
    if (v.stop) {
      status.level = diagnostic_msgs::DiagnosticStatus::ERROR;
      status.message = "stop and retreat: " + core::describe(v);
    } else {
      status.level = diagnostic_msgs::DiagnosticStatus::OK;
      status.message = have_force_ && have_tracker_ ? "monitoring" : "waiting for force/tracker";
    }
    diagnostic_msgs::KeyValue kv;
    kv.key = "reason";
    kv.value = core::toString(v.reason);
    status.values.push_back(kv);
    array.status.push_back(status);
    diagnostics_pub_.publish(array);
  }

  bool onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
    const std::string previous = core::toString(monitor_->verdict().reason);
    monitor_->reset();
    stop_sent_ = false;
    have_force_ = false;
    have_tracker_ = false;
    tracked_.clear();
    predicted_.clear();
    publishDiagnostics();
    response.success = true;
    response.message = "monitor reset (previous verdict: " + previous + ")";
    return true;
  }

  std::mutex mutex_;
  StartupStatus startup_status_;
  std::unique_ptr<core::SafetyMonitor> monitor_;
  double pair_tolerance_s_ = 0.02;
  bool have_force_ = false;
  bool have_tracker_ = false;
  bool stop_sent_ = false;
  bool trial_running_ = false;
  std::deque<StampedPosition> tracked_;
  std::deque<StampedPosition> predicted_;
  ros::Publisher stop_pub_;
  ros::Publisher diagnostics_pub_;
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
