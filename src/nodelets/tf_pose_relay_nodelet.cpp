/**
 * @file tf_pose_relay_nodelet.cpp
 * @brief pedicle_drilling/TfPoseRelay: an optical tracker on tf (its driver publishes the
 *        marker's frame) as the geometry_msgs/PoseStamped stream that the CompensationPlanner
 *        and the SafetyMonitor take (`tracker/marker_pose`). Event-driven: each tf update of
 *        the marker's frame is looked up in ~tracker_frame at that update's own stamp (the
 *        measurement's time, through any chain of frames) and published once. Nothing is
 *        repeated: a tracker that goes silent or repeats an old stamp stays silent here, so the
 *        monitor's tracker timeout and its stale-sample check see what the tracker did. A
 *        non-finite pose is not published (warned, counted).
 */
#include <geometry_msgs/PoseStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <tf2_msgs/TFMessage.h>
#include <tf2_ros/buffer.h>
#include <pluginlib/class_list_macros.hpp>

#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/publish_in_order.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"

namespace pedicle_drilling {

/** @brief Relays tf (~tracker_frame -> ~marker_frame) to tracker/marker_pose. */
class TfPoseRelayNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    ros::NodeHandle pnh = getPrivateNodeHandle();
    try {
      ParamLoader(pnh).load(TfPoseRelayNodeParams::table(), &params_);
    } catch (const std::exception& e) {
      failStartup(getName(), e.what());  // throws: the load fails
    }
    buffer_ = std::make_unique<tf2_ros::Buffer>(ros::Duration(10.0));
    pose_pub_ = nh.advertise<geometry_msgs::PoseStamped>("tracker/marker_pose", 20);
    // This nodelet fills its own buffer from /tf and /tf_static (no listener thread): an update
    // of the marker is in the buffer when it is looked up, and no lookup ever waits (a
    // nodelet must not block the manager's threads).
    tf_sub_ = nh.subscribe<tf2_msgs::TFMessage>(
        "/tf", 100, [this](const tf2_msgs::TFMessage::ConstPtr& m) { onTf(m, false); });
    tf_static_sub_ = nh.subscribe<tf2_msgs::TFMessage>(
        "/tf_static", 100, [this](const tf2_msgs::TFMessage::ConstPtr& m) { onTf(m, true); });
    NODELET_INFO("TfPoseRelay: tf %s -> %s relayed to %s", params_.tracker_frame.c_str(),
                 params_.marker_frame.c_str(), pose_pub_.getTopic().c_str());
  }

  void onTf(const tf2_msgs::TFMessage::ConstPtr& msg, bool is_static) {
    std::vector<ros::Time> updates;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (const geometry_msgs::TransformStamped& t : msg->transforms) {
        const bool marker = stripSlash(t.child_frame_id) == params_.marker_frame;
        if (!finite(t)) {
          if (marker) {
            ++non_finite_;
            NODELET_WARN_THROTTLE(1.0,
                                  "TfPoseRelay: non-finite marker pose at %.3f s not relayed "
                                  "(%lu so far)",
                                  t.header.stamp.toSec(), static_cast<unsigned long>(non_finite_));
          }
          continue;
        }
        buffer_->setTransform(t, "tf_pose_relay", is_static);
        if (marker) updates.push_back(t.header.stamp);
      }
    }
    for (const ros::Time& stamp : updates) relay(stamp);
  }

  static bool finite(const geometry_msgs::TransformStamped& t) {
    const auto& p = t.transform.translation;
    const auto& q = t.transform.rotation;
    return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) && std::isfinite(q.x) &&
           std::isfinite(q.y) && std::isfinite(q.z) && std::isfinite(q.w);
  }

  static std::string stripSlash(const std::string& frame) {
    return !frame.empty() && frame[0] == '/' ? frame.substr(1) : frame;
  }

  void relay(const ros::Time& stamp) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!last_stamp_.isZero() && stamp <= last_stamp_) return;  // not newer: not repeated
    geometry_msgs::TransformStamped t;
    try {
      t = buffer_->lookupTransform(params_.tracker_frame, params_.marker_frame, stamp);
    } catch (const tf2::TransformException& e) {
      NODELET_WARN_THROTTLE(1.0, "TfPoseRelay: %s -> %s at %.3f s: %s",
                            params_.tracker_frame.c_str(), params_.marker_frame.c_str(),
                            stamp.toSec(), e.what());
      return;
    }
    const auto& p = t.transform.translation;
    const auto& q = t.transform.rotation;
    last_stamp_ = stamp;
    geometry_msgs::PoseStamped out;
    out.header.stamp = stamp;
    out.header.frame_id = params_.tracker_frame;
    out.pose.position.x = p.x;
    out.pose.position.y = p.y;
    out.pose.position.z = p.z;
    out.pose.orientation = q;
    publishInOrder(pose_pub_, out);
  }

  TfPoseRelayNodeParams params_;
  std::mutex mutex_;
  std::unique_ptr<tf2_ros::Buffer> buffer_;
  ros::Publisher pose_pub_;
  ros::Subscriber tf_sub_;
  ros::Subscriber tf_static_sub_;
  ros::Time last_stamp_;
  std::uint64_t non_finite_ = 0;
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::TfPoseRelayNodelet, nodelet::Nodelet)
