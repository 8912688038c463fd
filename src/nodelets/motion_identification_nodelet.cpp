/**
 * @file motion_identification_nodelet.cpp
 * @brief pedicle_drilling/MotionIdentification: records the tidal volume and the tracked marker
 *        position over a sliding window and, on request (~identify), identifies the patient's
 *        displacement model with core::identifyPatient() (the identify CLI's pipeline),
 *        publishes it latched on `motion_model` and writes the per-patient YAML atomically.
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
#include <tf2_geometry_msgs/tf2_geometry_msgs.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <tf2/exceptions.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <deque>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "pedicle_drilling/IdentifyMotion.h"
#include "pedicle_drilling/MotionModel.h"
#include "pedicle_drilling/TidalVolume.h"
#include "pedicle_drilling/core/cli_args.hpp"
#include "pedicle_drilling/core/motion_model_io.hpp"
#include "pedicle_drilling/core/motion_pipeline.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"

namespace pedicle_drilling {

namespace {

struct TvSample {
  double t;
  double volume_ml;
};

struct MarkerSample {
  double t;
  std::array<double, 3> d_mm;  // AP, SI, LR
};

std::vector<std::string> splitComma(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(item);
  return out;
}

std::string upper(const std::string& s) {
  std::string u = s;
  for (char& c : u) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return u;
}

}  // namespace

/** @brief Nodelet wrapper of core::identifyPatient() over a sliding window of live data. */
class MotionIdentificationNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    ros::NodeHandle pnh = getPrivateNodeHandle();
    double marker_rate_hz = 8.0;
    try {
      const ParamLoader params(pnh);
      tracker_frame_ = params.getString("tracker_frame", "tracker_camera");
      // Optional frame whose axes are the patient's (e.g. `world` on the simulator, a registered
      // patient frame on hardware): marker positions are expressed in it before the axis
      // mapping, so an oblique camera does not mix AP, SI and LR.
      patient_frame_ = params.getString("patient_frame", "", true);
      marker_frame_ = params.getString("marker_frame", "tracker_marker");
      marker_rate_hz = params.getDouble("marker_rate_hz", 8.0, 0.0, 1000.0, true);
      tf_delay_s_ = params.getDouble("tf_delay_s", 0.25, 0.0, 10.0);
      use_pose_topic_ = params.getBool("use_pose_topic", false);
      window_s_ = params.getDouble("window_s", 30.0, 0.0, 3600.0, true);
      axis_specs_ = params.getString("ap_axis", "+z") + "," + params.getString("si_axis", "+y") +
                    "," + params.getString("lr_axis", "+x");
      try {
        mapping_ = core::parseAxisMapping(params.getString("ap_axis", "+z"),
                                          params.getString("si_axis", "+y"),
                                          params.getString("lr_axis", "+x"));
      } catch (const std::invalid_argument& e) {
        // The message starts with the axis name ("ap", "si" or "lr"): name that parameter.
        params.fail(std::string(e.what()).substr(0, 2) + "_axis", std::string("invalid: ") +
                                                                 e.what());
      }
      const std::string model = params.getString("model", "linear");
      if (!core::parseModelKind(model, &defaults_.kind)) {
        params.fail("model", "= '" + model + "' is not linear or hysteresis");
      }
      const std::string method = params.getString("method", "ceres");
      if (!core::parseMethod(method, &defaults_.method)) {
        params.fail("method", "= '" + method + "' is not ceres or pso");
      }
      defaults_.denoise = params.getBool("denoise", true);
      defaults_.denoise_tv = params.getBool("denoise_tv", false);
      if (defaults_.denoise_tv && !defaults_.denoise) {
        params.fail("denoise_tv", "needs ~denoise true");
      }
      core::DenoiseOptions& d = defaults_.denoise_options;
      d.level = params.getInt("level", 6, 1, 16);
      const std::string keep = params.getString("kept_levels", "3,4,5");
      try {
        d.kept_levels = core::parseIntList(keep, "kept_levels");
      } catch (const std::exception& e) {
        params.fail("kept_levels", "= '" + keep + "' is not a comma-separated list of integers");
      }
      for (int k : d.kept_levels) {
        if (k < 1 || k > d.level) {
          params.fail("kept_levels", "= '" + keep + "' has a level outside 1..~level");
        }
      }
      const std::string wavelets = params.getString("wavelets", "all");
      if (wavelets != "all") {
        d.candidates = splitComma(wavelets);
        for (const std::string& w : d.candidates) {
          if (core::findWavelet(w) == nullptr) {
            params.fail("wavelets", "names an unknown wavelet '" + w + "'");
          }
        }
      }
      d.delta_tv = params.getDouble("delta_tv_ml", 5.0, 0.0, 1000.0);
      defaults_.pso.seed =
          static_cast<std::uint64_t>(params.getInt("pso_seed", 1, 0, 2147483647));
      defaults_.validate();
      output_path_ = params.getString("output_path", "patient_model.yaml");
      patient_id_ = params.getString("patient_id", "patient");
    } catch (const std::exception& e) {
      startup_status_.fail(nh, getName(), e.what());
      return;
    }
    model_pub_ = nh.advertise<MotionModel>("motion_model", 1, true);
    tv_sub_ = nh.subscribe("tidal_volume", 1000, &MotionIdentificationNodelet::onTidalVolume,
                           this);
    if (!use_pose_topic_ || !patient_frame_.empty()) {
      tf_buffer_ = std::make_unique<tf2_ros::Buffer>(ros::Duration(std::max(60.0, 2 * window_s_)));
      tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_, nh, true);
    }
    if (use_pose_topic_) {
      pose_sub_ = nh.subscribe("tracker/marker_pose", 1000,
                               &MotionIdentificationNodelet::onMarkerPose, this);
    } else {
      timer_ = nh.createTimer(ros::Duration(1.0 / marker_rate_hz),
                              &MotionIdentificationNodelet::onTimer, this);
    }
    identify_srv_ =
        pnh.advertiseService("identify", &MotionIdentificationNodelet::onIdentify, this);
    NODELET_INFO("MotionIdentification: %s, window %.1f s, output %s",
                 use_pose_topic_ ? "marker from tracker/marker_pose"
                                 : ("marker from tf " + tracker_frame_ + " -> " + marker_frame_)
                                       .c_str(),
                 window_s_, output_path_.c_str());
  }

  // ------------------------------------------------------------------ recording
  /** Drops everything when time jumps back (bag restarted, simulation reset). */
  void checkTimeJump(double t) {
    if (t + 1.0 < latest_t_) {
      NODELET_WARN("MotionIdentification: time jumped back %.3f s, window cleared",
                   latest_t_ - t);
      tv_.clear();
      marker_.clear();
      latest_t_ = t;
    }
    latest_t_ = std::max(latest_t_, t);
    const double oldest = latest_t_ - window_s_;
    while (!tv_.empty() && tv_.front().t < oldest) tv_.pop_front();
    while (!marker_.empty() && marker_.front().t < oldest) marker_.pop_front();
  }

  void onTidalVolume(const TidalVolume::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const double t = msg->header.stamp.toSec();
    checkTimeJump(t);
    if (!tv_.empty() && !(t > tv_.back().t)) return;  // duplicate or out of order
    tv_.push_back({t, msg->volume_ml});
  }

  void addMarker(double t, double x_m, double y_m, double z_m) {
    checkTimeJump(t);
    if (!marker_.empty() && !(t > marker_.back().t)) return;
    marker_.push_back({t, mapping_.map(1e3 * x_m, 1e3 * y_m, 1e3 * z_m)});
  }

  void onMarkerPose(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!msg->header.frame_id.empty() && msg->header.frame_id != tracker_frame_) {
      ++rejected_frame_;
      last_marker_error_ = "pose in frame '" + msg->header.frame_id + "', expected '" +
                           tracker_frame_ + "'";
      NODELET_WARN_THROTTLE(5.0, "MotionIdentification: %s", last_marker_error_.c_str());
      return;
    }
    geometry_msgs::Point p = msg->pose.position;
    if (!patient_frame_.empty()) {
      try {  // the camera is fixed: its latest transform applies
        const geometry_msgs::TransformStamped tf =
            tf_buffer_->lookupTransform(patient_frame_, tracker_frame_, ros::Time(0));
        tf2::doTransform(msg->pose.position, p, tf);
      } catch (const tf2::TransformException& e) {
        ++rejected_frame_;
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
    const double when_s = event.current_expected.toSec() - tf_delay_s_;
    if (when_s <= 0.0) return;
    const ros::Time when(when_s);
    geometry_msgs::TransformStamped tf;
    try {
      tf = tf_buffer_->lookupTransform(patient_frame_.empty() ? tracker_frame_ : patient_frame_,
                                       marker_frame_, when);
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
  bool onIdentify(IdentifyMotion::Request& request, IdentifyMotion::Response& response) {
    response.success = false;
    core::PipelineOptions options = defaults_;
    if (!request.model.empty() && !core::parseModelKind(request.model, &options.kind)) {
      response.message = "unknown model '" + request.model + "' (expected linear or hysteresis)";
      return true;
    }
    if (!request.method.empty() && !core::parseMethod(request.method, &options.method)) {
      response.message = "unknown method '" + request.method + "' (expected ceres or pso)";
      return true;
    }
    const std::string path = request.output_path.empty() ? output_path_ : request.output_path;

    std::vector<TvSample> tv;
    std::vector<MarkerSample> marker;
    std::string marker_error;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      // Element-wise copy: vector::assign from deque iterators trips GCC 12's -Wnonnull.
      tv.reserve(tv_.size());
      for (const TvSample& s : tv_) tv.push_back(s);
      marker.reserve(marker_.size());
      for (const MarkerSample& m : marker_) marker.push_back(m);
      marker_error = last_marker_error_;
    }
    const std::string source = use_pose_topic_
                                   ? std::string("tracker/marker_pose")
                                   : "tf " + tracker_frame_ + " -> " + marker_frame_;
    if (tv.size() < 2) {
      std::ostringstream text;
      text << "no tidal volume: " << tv.size() << " samples received on 'tidal_volume' in the last "
           << window_s_ << " s";
      response.message = text.str();
      NODELET_WARN("MotionIdentification: %s", response.message.c_str());
      return true;
    }
    for (const TvSample& s : tv) {
      if (!std::isfinite(s.volume_ml)) {
        response.message = "tidal volume sample at t = " + std::to_string(s.t) +
                           " s is not finite (NaN or inf); identification refused";
        NODELET_WARN("MotionIdentification: %s", response.message.c_str());
        return true;
      }
    }
    core::Recording rec;
    for (const TvSample& s : tv) {
      rec.t_tv.push_back(s.t);
      rec.tv.push_back(s.volume_ml);
    }
    for (const MarkerSample& m : marker) {
      if (m.t < tv.front().t || m.t > tv.back().t) continue;  // pairing needs Tv around it
      rec.t_disp.push_back(m.t);
      rec.ap.push_back(m.d_mm[0]);
      rec.si.push_back(m.d_mm[1]);
      rec.lr.push_back(m.d_mm[2]);
    }
    if (rec.t_disp.size() < 16) {
      response.message = "too few marker samples from " + source + ": " +
                         std::to_string(rec.t_disp.size()) +
                         " inside the tidal-volume window (need >= 16)";
      if (!marker_error.empty()) response.message += "; last error: " + marker_error;
      NODELET_WARN("MotionIdentification: %s", response.message.c_str());
      return true;
    }
    core::PipelineResult result;
    try {
      const core::PairedSamples paired = core::pairAtMarkerTimes(rec);
      result = core::identifyPatient(paired, options, patient_id_, "recorded window");
      result.model.meta = {
          {"source", "MotionIdentification nodelet"},
          {"marker_source", source},
          {"method", core::methodName(options.method)},
          {"samples", std::to_string(result.samples)},
          {"tidal_volume_samples", std::to_string(rec.tv.size())},
          {"breaths", std::to_string(result.breaths)},
          {"window_s", std::to_string(result.duration_s)},
          {"ap_si_lr_from_tracker_axes", axis_specs_}};
    } catch (const std::exception& e) {
      response.message = std::string("identification failed: ") + e.what();
      NODELET_WARN("MotionIdentification: %s", response.message.c_str());
      return true;
    }
    try {
      core::writeModelYaml(result.model, path);
    } catch (const std::exception& e) {
      response.message = std::string("model not written: ") + e.what();
      NODELET_ERROR("MotionIdentification: %s", response.message.c_str());
      return true;
    }
    MotionModel msg;
    msg.header.stamp = ros::Time::now();
    msg.header.frame_id = patient_frame_.empty() ? tracker_frame_ : patient_frame_;
    msg.patient_id = patient_id_;
    msg.method = core::methodName(options.method);
    msg.yaml_path = path;
    for (const core::AxisReport& r : result.axes) {
      MotionModelAxis axis;
      axis.axis = upper(core::axisName(r.axis));
      axis.model = core::modelKindName(r.fit.model.kind);
      axis.q1_mm_per_ml = r.fit.model.q1;
      axis.q2_mm_s_per_ml = r.fit.model.q2;
      axis.q0_mm = r.fit.model.q0;
      axis.wavelet = r.wavelet == "none" ? "" : r.wavelet;
      axis.r2 = r.fit.r2;
      axis.rmse_mm = r.fit.rmse;
      axis.equivalent_stiffness = core::equivalentStiffness(r.axis, r.fit.model.q1);
      msg.axes.push_back(axis);
    }
    model_pub_.publish(msg);
    response.model = msg;
    response.success = true;
    std::ostringstream text;
    text << "identified " << core::modelKindName(options.kind) << " model with "
         << core::methodName(options.method) << " from " << result.samples
         << " marker samples, " << rec.tv.size() << " tidal-volume samples, " << result.breaths
         << " breaths over " << result.duration_s << " s; wrote " << path;
    response.message = text.str();
    NODELET_INFO("MotionIdentification: %s", response.message.c_str());
    for (const core::AxisReport& r : result.axes) {
      NODELET_INFO("MotionIdentification:   %s", core::formatAxisReport(r).c_str());
    }
    return true;
  }

  std::mutex mutex_;
  StartupStatus startup_status_;
  std::string tracker_frame_;
  std::string patient_frame_;
  std::string marker_frame_;
  double tf_delay_s_ = 0.25;
  bool use_pose_topic_ = false;
  double window_s_ = 30.0;
  core::AxisMapping mapping_;
  std::string axis_specs_;
  core::PipelineOptions defaults_;
  std::string output_path_;
  std::string patient_id_;

  std::deque<TvSample> tv_;
  std::deque<MarkerSample> marker_;
  double latest_t_ = -1e300;
  std::string last_marker_error_;
  long rejected_frame_ = 0;

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
