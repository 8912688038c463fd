/**
 * @file state_recognizer_nodelet.cpp
 * @brief pedicle_drilling/StateRecognizer: force-based drilling-state recognition (paper
 *        Sec. IV-C/D) on the thrust of `ft_sensor/wrench`; publishes `drilling_state` on every
 *        averaged sample (state `stopped` from the stop until `~reset`) and one `drill/stop`
 *        (retreat = false) when the inner cortical layer is reached. Thin wrapper of
 *        core::StateRecognizer (doc/state_machine.md). An exception of the recognizer class is
 *        such a stop too, naming the error (core::GuardedRecognizer). While the planner's trial
 *        has the drill in bone (compensation/status), `~reset` is refused and a tare result does
 *        not restart the recognizer.
 */
#include <geometry_msgs/WrenchStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>
#include <pluginlib/class_list_macros.hpp>

#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>

#include "pedicle_drilling/DrillingState.h"
#include "pedicle_drilling/StopCommand.h"
#include "pedicle_drilling/TareResult.h"
#include "pedicle_drilling/TrialStatus.h"
#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"
#include "pedicle_drilling/core/drilling/state_recognizer.hpp"
#include "pedicle_drilling/ros/lockstep.hpp"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/plugin_loader.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"

namespace pedicle_drilling {

/** @brief Nodelet wrapper of core::StateRecognizer. */
class StateRecognizerNodelet : public nodelet::Nodelet {
 public:
  ~StateRecognizerNodelet() override {
    // Unloaded from a running manager (the unloaded-recognizer fault): every callback ends
    // before any member it may use goes away; the steps run on the participants' thread.
    if (lockstep_) lockstep_->stop();
    wrench_sub_.shutdown();
    tare_sub_.shutdown();
    status_sub_.shutdown();
    reset_srv_.shutdown();
    if (lockstep_) lockstep_->drain();  // a ~reset call already running ends first
  }

 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    ros::NodeHandle pnh = getPrivateNodeHandle();
    StateRecognizerNodeParams params;
    try {
      const ParamLoader loader(pnh);
      loader.load(StateRecognizerNodeParams::table(), &params);
      axis_index_ = params.axisIndex();
      axis_sign_ = params.axisSign();
      std::unique_ptr<core::RecognizerInterface> recognizer;
      if (params.recognizer_class == "pedicle_drilling/PaperRecognizer") {
        recognizer = std::make_unique<core::PaperRecognizer>(params.recognizer);
      } else {
        try {
          recognizer = loader_.create(params.recognizer_class, params.recognizer_params);
        } catch (const std::exception& e) {
          loader.fail("recognizer", "= '" + params.recognizer_class + "': " + e.what());
        }
      }
      // What the class throws while running is a stop naming it, never an escaped exception
      // (which would end the manager and every nodelet in it).
      recognizer_ = std::make_unique<core::GuardedRecognizer>(std::move(recognizer));
      // Under the simulator's lockstep it answers each step after the step's force samples.
      // No timers: it needs a step only after it published (its states and stops are handled
      // at the next step); the force samples' steps are stepped anyway.
      lockstep_ = std::make_unique<LockstepParticipant>(
          nh, getName(), nullptr, false,
          [](const ros::Time&) { return std::optional<ros::Time>(); });
      lockstep_->shareQueue({&nh, &pnh});  // under the lockstep: the participants' thread
    } catch (const std::exception& e) {
      failStartup(getName(), e.what());  // throws: the load fails
    }
    NODELET_INFO("StateRecognizer: axis %s%c, %s", axis_sign_ < 0 ? "-" : "", "xyz"[axis_index_],
                 recognizer_ -> describe().c_str());
    for (const std::string& off : params.disabledWatchdogs()) {
      NODELET_WARN("StateRecognizer: UNSAFE (~unsafe_allow_disabled_watchdogs): %s", off.c_str());
    }
    // The nodelet manager runs this nodelet's callbacks while onInit still runs (nodelet
    // 1.10.2): the publishers exist before the callbacks that use them are registered.
    state_pub_ = nh.advertise<DrillingState>("drilling_state", 100);
    stop_pub_ = nh.advertise<StopCommand>("drill/stop", 10);
    // The planner's phase (latched): no reset while its drill is in bone.
    status_sub_ =
        nh.subscribe("compensation/status", 10, &StateRecognizerNodelet::onTrialStatus, this);
    reset_srv_ = pnh.advertiseService("reset", &StateRecognizerNodelet::onReset, this);
    // A new tare: the samples before it were untared; the recognizer starts afresh.
    tare_sub_ = nh.subscribe("ft_sensor/tare_result", 10, &StateRecognizerNodelet::onTare, this);
    wrench_sub_ =
        nh.subscribe("ft_sensor/wrench", params.queue_size, &StateRecognizerNodelet::onWrench, this,
                     ros::TransportHints().tcpNoDelay());
    lockstep_->start();  // last
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
      publishInOrder(stop_pub_, stop);
      lockstep_->noteSent();
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
    publishInOrder(state_pub_, msg);
    lockstep_->noteSent();
  }

  void onTrialStatus(const TrialStatus::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    trial_phase_ = msg->phase;
    trial_phase_name_ = msg->phase_name;
  }

  /** @brief "" while a restart is allowed, else why not: the planner's drill is in bone. */
  std::string drillInBone() const {
    if (trial_phase_ != TrialStatus::DRILLING && trial_phase_ != TrialStatus::STOPPED &&
        trial_phase_ != TrialStatus::RETREATING) {
      return "";
    }
    return "the planner's trial is " + trial_phase_name_ +
           " (compensation/status): no restart while its drill may be in bone";
  }

  void onTare(const TareResult::ConstPtr& msg) {
    if (!msg->success) return;
    std::lock_guard<std::mutex> lock(mutex_);
    const std::string refused = drillInBone();
    if (!refused.empty()) {
      NODELET_WARN("StateRecognizer: ignored a tare result: %s", refused.c_str());
      return;
    }
    recognizer_->reset();
    publishState(msg->header.stamp, recognizer_->output());
    NODELET_INFO("StateRecognizer: restarted on the tared force (%s)", msg->message.c_str());
  }

  bool onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
    response.message = drillInBone();
    if (!response.message.empty()) {
      response.success = false;
      response.message = "reset refused: " + response.message;
      NODELET_WARN("StateRecognizer: %s", response.message.c_str());
      return true;
    }
    recognizer_->reset();
    // Say at once that the latch is cleared (a planner refuses to feed while the latest state
    // reports a stop).
    publishState(lockstep_->now(), recognizer_->output());
    response.success = true;
    response.message = "recognizer reset (" + std::to_string(non_finite_count_) +
                       " non-finite samples ignored since start)";
    return true;
  }

  std::mutex mutex_;
  RecognizerLoader loader_;  // before recognizer_: outlives the instance it made
  std::unique_ptr<core::RecognizerInterface> recognizer_;
  std::unique_ptr<LockstepParticipant> lockstep_;
  int axis_index_ = 2;
  double axis_sign_ = 1.0;
  std::size_t non_finite_count_ = 0;
  ros::Publisher state_pub_;
  ros::Publisher stop_pub_;
  ros::Subscriber wrench_sub_;
  ros::ServiceServer reset_srv_;
  ros::Subscriber tare_sub_;
  ros::Subscriber status_sub_;
  std::uint8_t trial_phase_ = TrialStatus::IDLE;  ///< the planner's, from compensation/status
  std::string trial_phase_name_ = "idle";
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::StateRecognizerNodelet, nodelet::Nodelet)
