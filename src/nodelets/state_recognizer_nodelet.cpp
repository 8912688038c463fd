/**
 * @file state_recognizer_nodelet.cpp
 * @brief pedicle_drilling/StateRecognizer: force-based drilling-state recognition (paper
 *        Sec. IV-C/D) on the thrust of `ft_sensor/wrench`; publishes `drilling_state` on every
 *        averaged sample (state `stopped` from the stop until `~reset`) and one `drill/stop`
 *        (retreat = false) when the inner cortical layer is reached. Thin wrapper of
 *        core::StateRecognizer (doc/state_machine.md).
 */
#include <geometry_msgs/WrenchStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>
#include <pluginlib/class_list_macros.hpp>

#include <cmath>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>

#include "pedicle_drilling/DrillingState.h"
#include "pedicle_drilling/StopCommand.h"
#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"
#include "pedicle_drilling/core/drilling/state_recognizer.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/plugin_loader.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"

namespace pedicle_drilling {

namespace {

/** @brief Component index (0..2) and sign of an axis name x|y|z|-x|-y|-z. */
bool parseForceAxis(const std::string& name, int* index, double* sign) {
  std::string n = name;
  *sign = 1.0;
  if (!n.empty() && (n[0] == '-' || n[0] == '+')) {
    *sign = n[0] == '-' ? -1.0 : 1.0;
    n = n.substr(1);
  }
  if (n == "x")
    *index = 0;
  else if (n == "y")
    *index = 1;
  else if (n == "z")
    *index = 2;
  else
    return false;
  return true;
}

}  // namespace

/** @brief Nodelet wrapper of core::StateRecognizer. */
class StateRecognizerNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    ros::NodeHandle pnh = getPrivateNodeHandle();
    int queue_size = 0;
    try {
      const ParamLoader params(pnh);
      const std::string axis = params.getString("axis", "z");
      if (!parseForceAxis(axis, &axis_index_, &axis_sign_)) {
        params.fail("axis", "= '" + axis + "' must be one of x, y, z, -x, -y, -z");
      }
      core::RecognizerParams p;
      p.pre_average = params.getInt("pre_average", p.pre_average, 1, 100000);
      p.window = params.getInt("window", p.window, 1, 100000);
      p.k_ratio = params.getDouble("k_ratio", p.k_ratio, 0.0, 1.0, true, true);
      p.f_th = params.getDouble("f_th", p.f_th, 0.0, 1000.0, true);
      p.gain = params.getDouble("gain", p.gain, 1.0, 100.0);
      p.h_g = params.getDouble("h_g", p.h_g, 0.0, 1000.0);
      p.c1 = params.getDouble("c1", p.c1, 0.0, 1000.0, true);
      p.c2 = params.getDouble("c2", p.c2, 0.0, 1000.0, true);
      p.c3 = params.getDouble("c3", p.c3, 0.0, 1.0, true, true);
      p.cancellous_confirm = params.getInt("cancellous_confirm", p.cancellous_confirm, 1, 100000);
      p.outer_cortical_timeout =
          params.getInt("outer_cortical_timeout", p.outer_cortical_timeout, 0, 100000);
      p.cancellous_timeout = params.getInt("cancellous_timeout", p.cancellous_timeout, 0, 100000);
      p.inner_confirm = params.getInt("inner_confirm", p.inner_confirm, 1, 100000);
      p.stop_delay = params.getInt("stop_delay", p.stop_delay, 0, 100000);
      p.normalize_feature = params.getBool("normalize_feature", p.normalize_feature);
      queue_size = params.getInt("queue_size", 1000, 1, 100000);
      try {
        p.validate();
      } catch (const std::invalid_argument& e) {
        // The core names the field first ("c2: must be >= c1"); report it as the parameter.
        const std::string what = e.what();
        params.fail(what.substr(0, what.find(':')), what.substr(what.find(':') + 1));
      }
      const std::string recognizer_class =
          params.getString("recognizer", "pedicle_drilling/PaperRecognizer");
      const core::RecognizerSettings settings = params.getTextMap("recognizer_params");
      if (recognizer_class == "pedicle_drilling/PaperRecognizer") {
        if (!settings.empty()) {
          params.fail("recognizer_params",
                      "is for other recognizer classes; the paper recognizer's parameters are "
                      "this node's own (~pre_average, ~window, ...)");
        }
        recognizer_ = std::make_unique<core::PaperRecognizer>(p);
      } else {
        try {
          recognizer_ = loader_.create(recognizer_class, settings);
        } catch (const std::exception& e) {
          params.fail("recognizer", "= '" + recognizer_class + "': " + e.what());
        }
      }
    } catch (const std::exception& e) {
      failStartup(getName(), e.what());  // throws: the load fails
    }
    state_pub_ = nh.advertise<DrillingState>("drilling_state", 100);
    stop_pub_ = nh.advertise<StopCommand>("drill/stop", 10);
    reset_srv_ = pnh.advertiseService("reset", &StateRecognizerNodelet::onReset, this);
    wrench_sub_ = nh.subscribe("ft_sensor/wrench", queue_size, &StateRecognizerNodelet::onWrench,
                               this, ros::TransportHints().tcpNoDelay());
    NODELET_INFO("StateRecognizer: axis %s%c, %s", axis_sign_ < 0 ? "-" : "", "xyz"[axis_index_],
                 recognizer_ -> describe().c_str());
  }

  void onWrench(const geometry_msgs::WrenchStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const geometry_msgs::Vector3& f = msg->wrench.force;
    const double component = axis_index_ == 0 ? f.x : (axis_index_ == 1 ? f.y : f.z);
    const double thrust = axis_sign_ * component;
    const double t =
        msg->header.stamp.isZero() ? ros::Time::now().toSec() : msg->header.stamp.toSec();
    if (!std::isfinite(thrust) || !std::isfinite(t)) {
      // The core refuses non-finite samples; skipping one keeps the block means honest. The
      // SafetyMonitor stops the drill on NaN input, so this only has to stay alive.
      ++non_finite_count_;
      NODELET_WARN_THROTTLE(1.0, "StateRecognizer: ignored %lu non-finite force sample(s) so far",
                            static_cast<unsigned long>(non_finite_count_));
      return;
    }
    // One latch, the core's: the stop is published on the sample that latches it.
    const bool was_stopped = recognizer_->output().stop;
    const core::RecognizerOutput& out = recognizer_->push(t, thrust);
    if (out.new_average) publishState(msg->header.stamp, out);
    if (out.stop && !was_stopped) {
      StopCommand stop;
      stop.header.stamp = msg->header.stamp;
      stop.header.frame_id = msg->header.frame_id;
      stop.source = getName();
      stop.retreat = false;
      stop.reason = recognizer_->stopReason();
      stop_pub_.publish(stop);
      NODELET_WARN("StateRecognizer: STOP: %s", stop.reason.c_str());
    }
  }

  void publishState(const ros::Time& stamp, const core::RecognizerOutput& out) {
    DrillingState msg;
    msg.header.stamp = stamp;
    msg.state = static_cast<uint8_t>(out.state);
    msg.state_name = core::toString(out.state);
    msg.layer_state = static_cast<uint8_t>(out.layer_state);
    msg.last_key_point = static_cast<uint8_t>(out.last_key_point);
    msg.averaged_force = out.averaged_force;
    msg.feature = out.feature;
    msg.k = out.params_ready ? static_cast<int64_t>(out.k) : -1;
    msg.amplitude_d = out.d;
    msg.stop = out.stop;
    msg.stop_index = out.stop ? static_cast<int64_t>(out.stop_index) : -1;
    msg.stop_time = out.stop ? out.stop_t : 0.0;
    state_pub_.publish(msg);
  }

  bool onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
    recognizer_->reset();
    // Say at once that the latch is cleared (a planner refuses to feed while the latest state
    // reports a stop).
    publishState(ros::Time::now(), recognizer_->output());
    response.success = true;
    response.message = "recognizer reset (" + std::to_string(non_finite_count_) +
                       " non-finite samples ignored since start)";
    return true;
  }

  std::mutex mutex_;
  RecognizerLoader loader_;  // before recognizer_: outlives the instance it made
  std::unique_ptr<core::RecognizerInterface> recognizer_;
  int axis_index_ = 2;
  double axis_sign_ = 1.0;
  std::size_t non_finite_count_ = 0;
  ros::Publisher state_pub_;
  ros::Publisher stop_pub_;
  ros::Subscriber wrench_sub_;
  ros::ServiceServer reset_srv_;
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::StateRecognizerNodelet, nodelet::Nodelet)
