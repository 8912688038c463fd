/**
 * @file motion_identification_nodelet.cpp
 * @brief pedicle_drilling/MotionIdentification: records the tidal volume and the tracked marker
 *        position over a sliding window and, on request (~identify), identifies the patient's
 *        displacement model with core::identifyPatient() (the identify CLI's pipeline),
 *        publishes it latched on `motion_model` and writes the per-patient YAML atomically,
 *        only inside ~model_folder (core::pathInsideFolder).
 *
 * Marker samples come either from tf2 (default) or from geometry_msgs/PoseStamped on
 * `tracker/marker_pose` (~use_pose_topic). With tf2 the pose of ~marker_frame in
 * ~tracker_frame is sampled on a uniform grid at ~marker_rate_hz (the DWT assumes uniform
 * sampling): at each timer tick t the transform is looked up (tf2 interpolation) at
 * t - ~tf_delay_s, so that the tracker sample after that instant has already arrived. With the
 * pose topic every message is one sample at its own stamp (no resampling).
 *
 * Displacement (mm) = the marker position in the tracker frame mapped to AP / SI / LR by
 * ~ap_axis, ~si_axis, ~lr_axis (signed tracker axes). The intercept q0 is therefore in the
 * tracker frame (it includes the marker's rest position); the slopes do not depend on it.
 */
#include <geometry_msgs/PoseStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <tf2/exceptions.h>
#include <tf2_geometry_msgs/tf2_geometry_msgs.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <pluginlib/class_list_macros.hpp>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>

#include "pedicle_drilling/IdentifyMotion.h"
#include "pedicle_drilling/MotionModel.h"
#include "pedicle_drilling/TidalVolume.h"
#include "pedicle_drilling/core/breathing/identification_window.hpp"
#include "pedicle_drilling/core/breathing/motion_model_io.hpp"
#include "pedicle_drilling/core/breathing/motion_pipeline.hpp"
#include "pedicle_drilling/core/common/output_folder.hpp"
#include "pedicle_drilling/ros/identification_conversions.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/publish_in_order.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"

namespace pedicle_drilling {

/** @brief Nodelet wrapper of core::IdentificationWindow and core::identifyPatient(). */
class MotionIdentificationNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    ros::NodeHandle pnh = getPrivateNodeHandle();
    try {
      const ParamLoader loader(pnh);
      p_ = loadMotionIdentificationParams(loader);
      mapping_ = p_.mapping();
      openModelFolder(loader);
      window_.emplace(p_.window_s);
    } catch (const std::exception& e) {
      failStartup(getName(), e.what());  // throws: the load fails
    }
    model_pub_ = nh.advertise<MotionModel>("motion_model", 1, true);
    if (!p_.use_pose_topic || !p_.patient_frame.empty()) {
      tf_buffer_ =
          std::make_unique<tf2_ros::Buffer>(ros::Duration(std::max(60.0, 2 * p_.window_s)));
      tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_, nh, true);
    }
    // After the buffer: the nodelet manager runs this nodelet's callbacks while onInit still
    // runs (nodelet 1.10.2).
    tv_sub_ = nh.subscribe("tidal_volume", 1000, &MotionIdentificationNodelet::onTidalVolume, this);
    if (p_.use_pose_topic) {
      pose_sub_ = nh.subscribe("tracker/marker_pose", 1000,
                               &MotionIdentificationNodelet::onMarkerPose, this);
    } else {
      timer_ = nh.createTimer(ros::Duration(1.0 / p_.marker_rate_hz),
                              &MotionIdentificationNodelet::onTimer, this);
    }
    identify_srv_ =
        pnh.advertiseService("identify", &MotionIdentificationNodelet::onIdentify, this);
    NODELET_INFO("MotionIdentification: marker from %s, window %.1f s, output %s in %s",
                 markerSource().c_str(), p_.window_s, p_.output_path.c_str(),
                 model_folder_.c_str());
  }

  /** @brief ~model_folder, made if missing; ~output_path must lie in it. */
  void openModelFolder(const ParamLoader& loader) {
    model_folder_ = p_.model_folder.empty() ? core::defaultModelFolder() : p_.model_folder;
    if (model_folder_.empty())
      loader.fail("model_folder", "is empty and neither ROS_HOME nor HOME is set");
    std::error_code ec;
    std::filesystem::create_directories(model_folder_, ec);
    try {
      core::pathInsideFolder(model_folder_, p_.output_path);
    } catch (const std::exception& e) {
      loader.fail(ec ? "model_folder" : "output_path", std::string(": ") + e.what());
    }
  }

  std::string markerSource() const {
    return p_.use_pose_topic ? std::string("tracker/marker_pose")
                             : "tf " + p_.tracker_frame + " -> " + p_.marker_frame;
  }

  // ------------------------------------------------------------------ recording
  void warnJump(double jump_s) {
    if (jump_s > 0.0) {
      NODELET_WARN("MotionIdentification: time jumped back %.3f s, window cleared", jump_s);
    }
  }

  void onTidalVolume(const TidalVolume::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    warnJump(window_->addTidalVolume(msg->header.stamp.toSec(), msg->volume_ml));
  }

  void addMarker(double t, double x_m, double y_m, double z_m) {
    warnJump(window_->addMarker(t, mapping_.map(1e3 * x_m, 1e3 * y_m, 1e3 * z_m)));
  }

  void onMarkerPose(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!msg->header.frame_id.empty() && msg->header.frame_id != p_.tracker_frame) {
      last_marker_error_ =
          "pose in frame '" + msg->header.frame_id + "', expected '" + p_.tracker_frame + "'";
      NODELET_WARN_THROTTLE(5.0, "MotionIdentification: %s", last_marker_error_.c_str());
      return;
    }
    geometry_msgs::Point p = msg->pose.position;
    if (!p_.patient_frame.empty()) {
      try {  // the camera is fixed: its latest transform applies
        const geometry_msgs::TransformStamped tf =
            tf_buffer_->lookupTransform(p_.patient_frame, p_.tracker_frame, ros::Time(0));
        tf2::doTransform(msg->pose.position, p, tf);
      } catch (const tf2::TransformException& e) {
        last_marker_error_ = e.what();
        NODELET_WARN_THROTTLE(5.0, "MotionIdentification: %s", e.what());
        return;
      }
    }
    addMarker(msg->header.stamp.toSec(), p.x, p.y, p.z);
  }

  void onTimer(const ros::TimerEvent& event) {
    // In seconds first: before the first /clock message the expected time is near 0 and a
    // negative ros::Time would throw.
    const double when_s = event.current_expected.toSec() - p_.tf_delay_s;
    if (when_s <= 0.0) return;
    const ros::Time when(when_s);
    geometry_msgs::TransformStamped tf;
    try {
      tf = tf_buffer_->lookupTransform(
          p_.patient_frame.empty() ? p_.tracker_frame : p_.patient_frame, p_.marker_frame, when);
    } catch (const tf2::TransformException& e) {
      std::lock_guard<std::mutex> lock(mutex_);
      last_marker_error_ = e.what();
      return;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    const geometry_msgs::Vector3& p = tf.transform.translation;
    addMarker(when.toSec(), p.x, p.y, p.z);
  }

  // ------------------------------------------------------------------ identification
  bool refuse(IdentifyMotion::Response& response, const std::string& why) {
    response.message = why;
    NODELET_WARN("MotionIdentification: %s", why.c_str());
    return true;
  }

  bool onIdentify(IdentifyMotion::Request& request, IdentifyMotion::Response& response) {
    response.success = false;
    core::PipelineOptions options = p_.defaults;
    if (!request.model.empty() && !core::parseModelKind(request.model, &options.kind)) {
      response.message = "unknown model '" + request.model + "' (expected linear or hysteresis)";
      return true;
    }
    if (!request.method.empty() && !core::parseMethod(request.method, &options.method)) {
      response.message = "unknown method '" + request.method + "' (expected ceres or pso)";
      return true;
    }
    std::string path = request.output_path.empty() ? p_.output_path : request.output_path;
    try {
      path = core::pathInsideFolder(model_folder_, path);  // before the window is taken
    } catch (const std::exception& e) {
      return refuse(response, std::string("output_path refused: ") + e.what());
    }
    core::WindowRecording window;
    std::string marker_error;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      window = window_->take();
      marker_error = last_marker_error_;
    }
    if (!window.ok) {
      std::string why = window.error + " (tidal_volume; markers from " + markerSource() + ")";
      if (!marker_error.empty()) why += "; last marker error: " + marker_error;
      return refuse(response, why);
    }
    const core::Recording& rec = window.recording;
    core::PipelineResult result;
    try {
      const core::PairedSamples paired = core::pairAtMarkerTimes(rec);
      result = core::identifyPatient(paired, options, p_.patient_id, "recorded window");
      result.model.meta = {{"source", "MotionIdentification nodelet"},
                           {"marker_source", markerSource()},
                           {"method", core::methodName(options.method)},
                           {"samples", std::to_string(result.samples)},
                           {"tidal_volume_samples", std::to_string(rec.tv.size())},
                           {"breaths", std::to_string(result.breaths)},
                           {"window_s", std::to_string(result.duration_s)},
                           {"ap_si_lr_from_tracker_axes", p_.axisSpecs()}};
    } catch (const std::exception& e) {
      return refuse(response, std::string("identification failed: ") + e.what());
    }
    try {
      core::writeModelYaml(result.model, path);
    } catch (const std::exception& e) {
      response.message = std::string("model not written: ") + e.what();
      NODELET_ERROR("MotionIdentification: %s", response.message.c_str());
      return true;
    }
    MotionModel msg = toMsg(result, p_.patient_frame.empty() ? p_.tracker_frame : p_.patient_frame,
                            p_.patient_id, core::methodName(options.method), path);
    msg.header.stamp = ros::Time::now();
    publishInOrder(model_pub_, msg);
    response.model = msg;
    response.success = true;
    std::ostringstream text;
    text << "identified " << core::modelKindName(options.kind) << " model with "
         << core::methodName(options.method) << " from " << result.samples << " marker samples, "
         << rec.tv.size() << " tidal-volume samples, " << result.breaths << " breaths over "
         << result.duration_s << " s; wrote " << path;
    response.message = text.str();
    NODELET_INFO("MotionIdentification: %s", response.message.c_str());
    for (const core::AxisReport& r : result.axes) {
      NODELET_INFO("MotionIdentification:   %s", core::formatAxisReport(r).c_str());
    }
    return true;
  }

  std::mutex mutex_;
  MotionIdentificationParams p_;
  std::string model_folder_;   ///< ~model_folder, or its default
  core::AxisMapping mapping_;  ///< ~ap_axis, ~si_axis, ~lr_axis
  std::optional<core::IdentificationWindow> window_;
  std::string last_marker_error_;

  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  ros::Publisher model_pub_;
  ros::Subscriber tv_sub_;
  ros::Subscriber pose_sub_;
  ros::ServiceServer identify_srv_;
  ros::Timer timer_;
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::MotionIdentificationNodelet, nodelet::Nodelet)
