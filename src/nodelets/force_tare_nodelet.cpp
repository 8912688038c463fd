/**
 * @file force_tare_nodelet.cpp
 * @brief pedicle_drilling/ForceTare: the tare before contact for an F/T sensor whose
 *        driver has none of its own. Relays the driver's `wrench_in` to `ft_sensor/wrench` minus
 *        the bias it measured: on `ft_sensor/tare_request` it averages the next `samples` samples
 *        and subtracts their mean from then on, answering on `ft_sensor/tare_result` (latched) —
 *        the protocol the Simulator's sensor driver speaks, so the planner drives either one.
 *        Thin adapter of core::ForceTare. Event-driven: one output per input, stamp and frame
 *        kept; a non-finite sample is relayed as it is (the SafetyMonitor stops on it) and fails
 *        a window it falls in.
 */
#include <geometry_msgs/WrenchStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <pluginlib/class_list_macros.hpp>

#include <mutex>
#include <optional>

#include "pedicle_drilling/TareRequest.h"
#include "pedicle_drilling/TareResult.h"
#include "pedicle_drilling/core/drilling/force_tare.hpp"
#include "pedicle_drilling/ros/publish_in_order.hpp"
#include "pedicle_drilling/ros/simulator_conversions.hpp"

namespace pedicle_drilling {

/** @brief wrench_in -> ft_sensor/wrench, tared on request. */
class ForceTareNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    wrench_pub_ = nh.advertise<geometry_msgs::WrenchStamped>("ft_sensor/wrench", 2000);
    result_pub_ = nh.advertise<TareResult>("ft_sensor/tare_result", 10, true);
    const ros::TransportHints hints = ros::TransportHints().tcpNoDelay();
    wrench_sub_ = nh.subscribe("wrench_in", 2000, &ForceTareNodelet::onWrench, this, hints);
    request_sub_ = nh.subscribe("ft_sensor/tare_request", 10, &ForceTareNodelet::onRequest, this);
    NODELET_INFO("ForceTare: %s -> %s, tared on %s", wrench_sub_.getTopic().c_str(),
                 wrench_pub_.getTopic().c_str(), request_sub_.getTopic().c_str());
  }

  void onRequest(const TareRequest::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      tare_.request(fromMsg(*msg));
    } catch (const std::exception& e) {
      NODELET_ERROR("ForceTare: tare request refused: %s", e.what());
      core::TareResult refused;
      refused.message = std::string("tare request refused: ") + e.what();
      publishInOrder(result_pub_, toMsg(refused, msg->header.stamp));
    }
  }

  void onWrench(const geometry_msgs::WrenchStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    geometry_msgs::WrenchStamped out;
    out.header = msg->header;
    out.wrench = toWrenchMsg(tare_.apply(msg->header.stamp.toSec(), fromWrenchMsg(msg->wrench)));
    publishInOrder(wrench_pub_, out);
    if (const std::optional<core::TareResult> r = tare_.takeResult()) {
      TareResult result = toMsg(*r, msg->header.stamp);
      result.header.frame_id = msg->header.frame_id;
      publishInOrder(result_pub_, result);
      if (r->success) {
        NODELET_INFO("ForceTare: %s", r->message.c_str());
      } else {
        NODELET_WARN("ForceTare: %s", r->message.c_str());
      }
    }
  }

  std::mutex mutex_;
  core::ForceTare tare_;
  ros::Publisher wrench_pub_;
  ros::Publisher result_pub_;
  ros::Subscriber wrench_sub_;
  ros::Subscriber request_sub_;
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::ForceTareNodelet, nodelet::Nodelet)
