/**
 * @file ventilator_nodelet.cpp
 * @brief pedicle_drilling/Ventilator: publishes the tidal volume and flow of a volume-controlled
 *        ventilator at a fixed rate on ROS time (sim or wall). New settings arrive through the
 *        ~set_settings service and take effect at the start of the next breath. The breath
 *        phase (~breath_source): `internal`, a schedule from the nodelet's start; `flow`, the
 *        breath starts detected on breath_sensor/flow (core::FlowPhasedSchedule), nothing
 *        published before the first one or once none came for ~breath_timeout_periods.
 */
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <pluginlib/class_list_macros.hpp>

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

#include "pedicle_drilling/AirwayFlow.h"
#include "pedicle_drilling/BreathSourceStatus.h"
#include "pedicle_drilling/SetVentilatorSettings.h"
#include "pedicle_drilling/TidalVolume.h"
#include "pedicle_drilling/core/breathing/breath_detector.hpp"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/publish_in_order.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"
#include "pedicle_drilling/ros/ventilator_conversions.hpp"

namespace pedicle_drilling {

/** @brief Nodelet wrapper of core::BreathScheduler / core::FlowPhasedSchedule. */
class VentilatorNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    ros::NodeHandle pnh = getPrivateNodeHandle();
    double rate_hz = 0.0;
    try {
      VentilatorNodeParams params;
      ParamLoader(pnh).load(VentilatorNodeParams::table(), &params);
      params.validate();
      rate_hz = params.publish_rate_hz;
      frame_id_ = params.frame_id;
      if (params.breath_source == "flow") {
        flow_ = std::make_unique<core::FlowPhasedSchedule>(params.settings, params.flow);
      } else {
        scheduler_ =
            std::make_unique<core::BreathScheduler>(params.settings, ros::Time::now().toSec());
      }
    } catch (const std::exception& e) {
      // Safe state: nothing is published, the error names the parameter.
      failStartup(getName(), e.what());  // throws: the load fails
    }
    flow_topic_ = nh.resolveName("breath_sensor/flow");
    tidal_volume_pub_ = nh.advertise<TidalVolume>("tidal_volume", 100);
    settings_pub_ = pnh.advertise<VentilatorSettings>("settings", 1, true);
    status_pub_ = pnh.advertise<BreathSourceStatus>("breath_source_status", 1, true);
    publishSettings(toMsg(scheduler().model().settings()));
    publishStatus(ros::Time::now(), flow_ ? flow_->problem(ros::Time::now().toSec()) : "");
    NODELET_INFO("Ventilator: %.0f ml, %.1f /min, %s, publishing at %.1f Hz; breath phase: %s",
                 scheduler().model().settings().tv_max_ml, scheduler().model().settings().rate_bpm,
                 core::waveformName(scheduler().model().settings().waveform).c_str(), rate_hz,
                 flow_ ? ("breath starts on " + flow_topic_).c_str() : "internal schedule");
    // Last: the nodelet manager runs these callbacks while onInit still runs (nodelet 1.10.2),
    // and they change the schedule.
    set_settings_srv_ =
        pnh.advertiseService("set_settings", &VentilatorNodelet::onSetSettings, this);
    if (flow_) {
      flow_sub_ = nh.subscribe("breath_sensor/flow", 200, &VentilatorNodelet::onFlow, this,
                               ros::TransportHints().tcpNoDelay());
    }
    timer_ = nh.createTimer(ros::Duration(1.0 / rate_hz), &VentilatorNodelet::onTimer, this);
  }

  core::BreathScheduler& scheduler() { return flow_ ? flow_->scheduler() : *scheduler_; }

  /** @brief ROS time went back (a bag replayed in a loop, a simulation reset). */
  void onTimeJumpedBack(const ros::Time& stamp) {
    if (flow_) {
      // The detected phase belongs to the old time line: wait for a breath start on the new one.
      NODELET_WARN(
          "Ventilator: time jumped back from %.3f s to %.3f s; waiting for a breath "
          "start on %s",
          last_stamp_.toSec(), stamp.toSec(), flow_topic_.c_str());
      flow_->reset();
      return;
    }
    // A ventilator cannot go back in time, so the breath schedule restarts with a new breath now.
    NODELET_WARN("Ventilator: time jumped back from %.3f s to %.3f s; a new breath starts now",
                 scheduler_->lastTime(), stamp.toSec());
    const bool pending = scheduler_->hasPendingSettings();
    scheduler_->restart(stamp.toSec());
    if (pending) publishSettings(toMsg(scheduler_->model().settings()));
  }

  void onTimer(const ros::TimerEvent& event) {
    std::lock_guard<std::mutex> lock(mutex_);
    const ros::Time stamp = event.current_expected;
    if (stamp < last_stamp_) onTimeJumpedBack(stamp);
    last_stamp_ = stamp;
    if (flow_) {
      const std::string problem = flow_->problem(stamp.toSec());
      if (problem.empty() != ready_) publishStatus(stamp, problem);
      if (!problem.empty()) return;  // nothing the planner could use
    }
    core::BreathScheduler& s = scheduler();
    const long before = s.breathIndex();
    const bool pending = s.hasPendingSettings();
    const core::VentilatorSample sample = s.sample(stamp.toSec());
    if (pending && !s.hasPendingSettings() && s.breathIndex() != before) {
      publishSettings(toMsg(s.model().settings()));
    }
    TidalVolume msg;
    msg.header.stamp = stamp;
    msg.header.frame_id = frame_id_;
    msg.volume_ml = sample.volume_ml;
    msg.flow_ml_s = sample.flow_ml_s;
    msg.breath_index = static_cast<uint32_t>(s.breathIndex());
    msg.time_in_breath_s = sample.t - s.breathStart();
    publishInOrder(tidal_volume_pub_, msg);
  }

  void onFlow(const AirwayFlow::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    // An unset stamp is the sensor driver's error: a breath start needs the sample's time.
    const core::FlowSampleStatus status =
        msg->header.stamp.isZero() ? core::FlowSampleStatus::kNonFiniteStamp
                                   : flow_->addFlow(msg->header.stamp.toSec(), msg->flow_ml_s);
    if (!core::accepted(status)) {
      ++dropped_;
      NODELET_WARN_THROTTLE(5.0, "Ventilator: dropped a sample of %s: %s (%lu dropped so far)",
                            flow_topic_.c_str(),
                            msg->header.stamp.isZero() ? "the stamp is zero (not set)"
                                                       : core::describe(status).c_str(),
                            static_cast<unsigned long>(dropped_));
      return;
    }
    if (status != core::FlowSampleStatus::kBreathStart) return;
    // Settings requested since the last breath take effect with this one.
    const VentilatorSettings settings = toMsg(flow_->scheduler().model().settings());
    if (settings != published_settings_) publishSettings(settings);
  }

  void publishSettings(const VentilatorSettings& settings) {
    published_settings_ = settings;
    publishInOrder(settings_pub_, settings);
  }

  /** @brief ~breath_source_status (latched): the source, and why it is not ready. */
  void publishStatus(const ros::Time& stamp, const std::string& problem) {
    ready_ = problem.empty();
    BreathSourceStatus msg;
    msg.header.stamp = stamp;
    msg.header.frame_id = frame_id_;
    msg.source = flow_ ? "flow" : "internal";
    msg.topic = flow_ ? flow_topic_ : "";
    msg.ready = ready_;
    msg.timeout_s = flow_ ? flow_->timeout() : 0.0;
    if (!flow_) {
      msg.message = "internal: a breath schedule from the ventilator's start (not the patient's)";
    } else {
      msg.message = "breath source flow on " + flow_topic_ + ": " +
                    (ready_ ? "breath starts detected" : problem);
    }
    if (flow_ && !ready_) NODELET_WARN("Ventilator: %s", msg.message.c_str());
    publishInOrder(status_pub_, msg);
  }

  bool onSetSettings(SetVentilatorSettings::Request& request,
                     SetVentilatorSettings::Response& response) {
    serveSetVentilatorSettings(request, response, [this](const core::VentilatorSettings& s) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (flow_) {
        flow_->requestSettings(s);
      } else {
        scheduler_->requestSettings(s);
      }
    });
    if (!response.success) NODELET_WARN("Ventilator: %s", response.message.c_str());
    return true;
  }

  std::mutex mutex_;
  std::unique_ptr<core::BreathScheduler> scheduler_;  // breath_source internal
  std::unique_ptr<core::FlowPhasedSchedule> flow_;    // breath_source flow
  std::string frame_id_;
  std::string flow_topic_;
  ros::Time last_stamp_;
  bool ready_ = false;
  std::uint64_t dropped_ = 0;
  VentilatorSettings published_settings_;  // the latest on ~settings
  ros::Publisher tidal_volume_pub_;
  ros::Publisher settings_pub_;
  ros::Publisher status_pub_;
  ros::Subscriber flow_sub_;
  ros::ServiceServer set_settings_srv_;
  ros::Timer timer_;
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::VentilatorNodelet, nodelet::Nodelet)
