/**
 * @file ventilator_nodelet.cpp
 * @brief pedicle_drilling/Ventilator: publishes the tidal volume and flow of a volume-controlled
 *        ventilator at a fixed rate on ROS time (sim or wall). New settings arrive through the
 *        ~set_settings service and take effect at the start of the next breath.
 */
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <pluginlib/class_list_macros.hpp>

#include <memory>
#include <mutex>

#include "pedicle_drilling/SetVentilatorSettings.h"
#include "pedicle_drilling/TidalVolume.h"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/publish_in_order.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"
#include "pedicle_drilling/ros/ventilator_conversions.hpp"

namespace pedicle_drilling {

/** @brief Nodelet wrapper of core::BreathScheduler. */
class VentilatorNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    ros::NodeHandle pnh = getPrivateNodeHandle();
    double rate_hz = 0.0;
    try {
      VentilatorNodeParams params;
      ParamLoader(pnh).load(VentilatorNodeParams::table(), &params);
      rate_hz = params.publish_rate_hz;
      frame_id_ = params.frame_id;
      scheduler_ =
          std::make_unique<core::BreathScheduler>(params.settings, ros::Time::now().toSec());
    } catch (const std::exception& e) {
      // Safe state: nothing is published, the error names the parameter.
      failStartup(getName(), e.what());  // throws: the load fails
    }
    tidal_volume_pub_ = nh.advertise<TidalVolume>("tidal_volume", 100);
    settings_pub_ = pnh.advertise<VentilatorSettings>("settings", 1, true);
    publishInOrder(settings_pub_, toMsg(scheduler_->model().settings()));
    NODELET_INFO("Ventilator: %.0f ml, %.1f /min, %s, publishing at %.1f Hz",
                 scheduler_->model().settings().tv_max_ml, scheduler_->model().settings().rate_bpm,
                 core::waveformName(scheduler_->model().settings().waveform).c_str(), rate_hz);
    // Last: the nodelet manager runs these callbacks while onInit still runs (nodelet 1.10.2),
    // and they change scheduler_.
    set_settings_srv_ =
        pnh.advertiseService("set_settings", &VentilatorNodelet::onSetSettings, this);
    timer_ = nh.createTimer(ros::Duration(1.0 / rate_hz), &VentilatorNodelet::onTimer, this);
  }

  void onTimer(const ros::TimerEvent& event) {
    std::lock_guard<std::mutex> lock(mutex_);
    const ros::Time stamp = event.current_expected;
    if (stamp.toSec() < scheduler_->lastTime()) {
      // ROS time went back (a bag replayed in a loop, a simulation reset): a ventilator cannot
      // go back in time, so the breath schedule restarts with a new breath now.
      NODELET_WARN("Ventilator: time jumped back from %.3f s to %.3f s; a new breath starts now",
                   scheduler_->lastTime(), stamp.toSec());
      const bool pending = scheduler_->hasPendingSettings();
      scheduler_->restart(stamp.toSec());
      if (pending) publishInOrder(settings_pub_, toMsg(scheduler_->model().settings()));
    }
    const long before = scheduler_->breathIndex();
    const bool pending = scheduler_->hasPendingSettings();
    const core::VentilatorSample sample = scheduler_->sample(stamp.toSec());
    if (pending && !scheduler_->hasPendingSettings() && scheduler_->breathIndex() != before) {
      publishInOrder(settings_pub_, toMsg(scheduler_->model().settings()));
    }
    TidalVolume msg;
    msg.header.stamp = stamp;
    msg.header.frame_id = frame_id_;
    msg.volume_ml = sample.volume_ml;
    msg.flow_ml_s = sample.flow_ml_s;
    msg.breath_index = static_cast<uint32_t>(scheduler_->breathIndex());
    msg.time_in_breath_s = stamp.toSec() - scheduler_->breathStart();
    publishInOrder(tidal_volume_pub_, msg);
  }

  bool onSetSettings(SetVentilatorSettings::Request& request,
                     SetVentilatorSettings::Response& response) {
    serveSetVentilatorSettings(request, response, [this](const core::VentilatorSettings& s) {
      std::lock_guard<std::mutex> lock(mutex_);
      scheduler_->requestSettings(s);
    });
    if (!response.success) NODELET_WARN("Ventilator: %s", response.message.c_str());
    return true;
  }

  std::mutex mutex_;
  std::unique_ptr<core::BreathScheduler> scheduler_;
  std::string frame_id_;
  ros::Publisher tidal_volume_pub_;
  ros::Publisher settings_pub_;
  ros::ServiceServer set_settings_srv_;
  ros::Timer timer_;
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::VentilatorNodelet, nodelet::Nodelet)
