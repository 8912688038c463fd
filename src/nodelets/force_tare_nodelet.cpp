/**
 * @file force_tare_nodelet.cpp
 * @brief pedicle_drilling/ForceTare: the tare before contact for an F/T sensor whose driver
 *        does not speak our TareRequest/TareResult (the protocol the Simulator's sensor driver
 *        speaks, so the planner drives either one). Two ways, by `~zero_service`:
 *        - "" (the relay): relays the driver's `wrench_in` to `ft_sensor/wrench` minus the bias
 *          it measured: on `ft_sensor/tare_request` it averages the next `samples` samples and
 *          subtracts their mean from then on, answering on `ft_sensor/tare_result` (latched);
 *        - a service name (the driver's own zero, std_srvs/Trigger): on `ft_sensor/tare_request`
 *          it calls the service, then checks the zero on `wrench_in` (the mean force of the next
 *          `samples` samples within `~zero_tolerance_n` of zero) and answers the same way; it
 *          relays nothing (the pipeline reads the driver's stream itself). A service that does
 *          not exist, refuses, or does not zero is a failed result naming it.
 *        Thin adapter of core::ForceTare. Event-driven: one output per input, stamp and frame
 *        kept; a non-finite sample is relayed as it is (the SafetyMonitor stops on it) and fails
 *        a window it falls in.
 */
#include <geometry_msgs/WrenchStamped.h>
#include <nodelet/nodelet.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>
#include <pluginlib/class_list_macros.hpp>

#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>

#include "pedicle_drilling/TareRequest.h"
#include "pedicle_drilling/TareResult.h"
#include "pedicle_drilling/core/drilling/force_tare.hpp"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/publish_in_order.hpp"
#include "pedicle_drilling/ros/simulator_conversions.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"

namespace pedicle_drilling {

/** @brief wrench_in -> ft_sensor/wrench, tared on request; or the driver's zero, checked. */
class ForceTareNodelet : public nodelet::Nodelet {
 public:
  ~ForceTareNodelet() override {
    // The zero's thread first: it may be waiting for the service.
    if (zero_spinner_) zero_spinner_->stop();
    request_sub_.shutdown();
    wrench_sub_.shutdown();
  }

 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    try {
      ParamLoader(getPrivateNodeHandle()).load(ForceTareNodeParams::table(), &params_);
    } catch (const std::exception& e) {
      failStartup(getName(), e.what());  // throws: the load fails
    }
    result_pub_ = nh.advertise<TareResult>("ft_sensor/tare_result", 10, true);
    const ros::TransportHints hints = ros::TransportHints().tcpNoDelay();
    if (params_.zero_service.empty()) {
      wrench_pub_ = nh.advertise<geometry_msgs::WrenchStamped>("ft_sensor/wrench", 2000);
    } else {
      zero_client_ = nh.serviceClient<std_srvs::Trigger>(params_.zero_service);
      zero_name_ = "'" + zero_client_.getService() + "' (~zero_service)";
    }
    wrench_sub_ = nh.subscribe("wrench_in", 2000, &ForceTareNodelet::onWrench, this, hints);
    if (params_.zero_service.empty()) {
      request_sub_ = nh.subscribe("ft_sensor/tare_request", 10, &ForceTareNodelet::onRequest, this);
      NODELET_INFO("ForceTare: %s -> %s, tared on %s", wrench_sub_.getTopic().c_str(),
                   wrench_pub_.getTopic().c_str(), request_sub_.getTopic().c_str());
      return;
    }
    // The call waits for the driver: a thread of its own, never one of the manager's.
    ros::NodeHandle zero_nh(nh);
    zero_nh.setCallbackQueue(&zero_queue_);
    request_sub_ = zero_nh.subscribe("ft_sensor/tare_request", 10, &ForceTareNodelet::onZero, this);
    zero_spinner_ = std::make_unique<ros::AsyncSpinner>(1, &zero_queue_);
    zero_spinner_->start();
    NODELET_INFO(
        "ForceTare: on %s, the driver's zero service %s (std_srvs/Trigger), checked on %s "
        "within %g N",
        request_sub_.getTopic().c_str(), zeroName().c_str(), wrench_sub_.getTopic().c_str(),
        params_.zero_tolerance_n);
  }

  /** @brief The zero service's resolved name and the parameter that names it. */
  const std::string& zeroName() const { return zero_name_; }

  /** @brief A failed result on ft_sensor/tare_result (the planner fails the trial with it). */
  void refuse(const std::string& why, const ros::Time& stamp) {
    NODELET_ERROR("ForceTare: %s", why.c_str());
    core::TareResult refused;
    refused.message = why;
    publishInOrder(result_pub_, toMsg(refused, stamp));
  }

  void onRequest(const TareRequest::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      tare_.request(fromMsg(*msg));
    } catch (const std::exception& e) {
      refuse(std::string("tare request refused: ") + e.what(), msg->header.stamp);
    }
  }

  /**
   * @brief A tare request with ~zero_service: the driver zeroes (the service), then the next
   *        samples on wrench_in must read zero (core::ForceTare::checkZero). On the zero's own
   *        thread: the call may wait up to ~zero_service_timeout_s for the service to exist.
   */
  void onZero(const TareRequest::ConstPtr& msg) {
    const core::TareRequest request = fromMsg(*msg);
    try {
      request.validate();
    } catch (const std::exception& e) {
      refuse(std::string("tare request refused: ") + e.what(), msg->header.stamp);
      return;
    }
    if (!zero_client_.waitForExistence(ros::Duration(params_.zero_service_timeout_s))) {
      std::ostringstream os;
      os << "zero service " << zeroName() << " does not exist (waited "
         << params_.zero_service_timeout_s
         << " s): is the sensor's driver running, and is this its zero service "
            "(std_srvs/Trigger)? No tare";
      refuse(os.str(), msg->header.stamp);
      return;
    }
    std_srvs::Trigger call;
    if (!zero_client_.call(call)) {
      refuse("zero service " + zeroName() + ": the call failed; no tare", msg->header.stamp);
      return;
    }
    if (!call.response.success) {
      refuse("zero service " + zeroName() + " refused: '" + call.response.message + "'",
             msg->header.stamp);
      return;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    // The driver has zeroed: the samples stamped from now on must read zero.
    tare_.checkZero(request, params_.zero_tolerance_n, ros::Time::now().toSec());
    zero_answer_ = call.response.message;
  }

  void onWrench(const geometry_msgs::WrenchStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const core::ForceTare::Wrench tared =
        tare_.apply(msg->header.stamp.toSec(), fromWrenchMsg(msg->wrench));
    if (params_.zero_service.empty()) {
      geometry_msgs::WrenchStamped out;
      out.header = msg->header;
      out.wrench = toWrenchMsg(tared);
      publishInOrder(wrench_pub_, out);
    }
    if (std::optional<core::TareResult> r = tare_.takeResult()) {
      if (!params_.zero_service.empty()) {
        const std::string answer = zero_answer_.empty() ? "" : ", answer '" + zero_answer_ + "'";
        r->message = "zero service " + zeroName() + answer + ": " + r->message;
      }
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

  ForceTareNodeParams params_;  ///< every parameter, loaded once
  std::mutex mutex_;            ///< tare_ and zero_answer_
  core::ForceTare tare_;
  std::string zero_answer_;  ///< the zero service's message, for the result
  ros::Publisher wrench_pub_;
  ros::Publisher result_pub_;
  ros::Subscriber wrench_sub_;
  ros::Subscriber request_sub_;
  ros::ServiceClient zero_client_;
  std::string zero_name_;  ///< the zero service's resolved name, for the messages
  ros::CallbackQueue zero_queue_;
  std::unique_ptr<ros::AsyncSpinner> zero_spinner_;
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::ForceTareNodelet, nodelet::Nodelet)
