/**
 * @file state_recognizer_nodelet.cpp
 * @brief pedicle_drilling/StateRecognizer: force-based drilling-state recognition (paper
 *        Sec. IV-C/D) on the thrust of `ft_sensor/wrench`; publishes `drilling_state` on every
 *        averaged sample (state `stopped` from the stop until `~reset`) and one `drill/stop`
 *        (retreat = false) when the inner cortical layer is reached. Thin wrapper of
 *        core::StateRecognizer (doc/state_machine.md). An exception of the recognizer class is
 *        such a stop too, naming the error (core::GuardedRecognizer). While the planner's trial
 *        has the drill in bone (compensation/status), `~reset` is refused and a tare result does
 *        not restart the recognizer. The rate of `ft_sensor/wrench` is measured from its stamps
 *        against the declared `~sensor_rate_hz` (core::SampleRateCheck): off by more than
 *        `~rate_tolerance`, an ERROR on /diagnostics and in the log naming both rates, `~reset`
 *        refused (the planner's trial is refused) and a running trial stopped with retreat.
 */
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <std_srvs/Trigger.h>
#include <pluginlib/class_list_macros.hpp>

#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>

#include "pedicle_drilling/DrillingState.h"
#include "pedicle_drilling/JointTrajectoryControllerState.h"
#include "pedicle_drilling/StopCommand.h"
#include "pedicle_drilling/TareResult.h"
#include "pedicle_drilling/TrialStatus.h"
#include "pedicle_drilling/core/drilling/recognizer_adapter.hpp"
#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"
#include "pedicle_drilling/core/drilling/sample_rate_check.hpp"
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
      const core::RecognizerParams paper = loadParams(loader, &params);
      core::ForceAxis axis;
      axis.index = params.axisIndex();
      axis.sign = params.axisSign();
      // What the class throws while running is a stop naming it, never an escaped exception
      // (which would end the manager and every nodelet in it): the adapter guards it.
      recognizer_ = std::make_unique<core::RecognizerAdapter>(makeRecognizer(loader, params), axis);
      core::SampleRateCheckParams rate;
      rate.declared_hz = paper.sensor_rate_hz;
      rate.tolerance = params.rate_tolerance;
      rate.window_s = params.rate_window_s;
      rate_check_ = std::make_unique<core::SampleRateCheck>(rate);
      block_samples_ = paper.blockSamples();
      pre_average_s_ = paper.pre_average_s;
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
    wrench_topic_ = nh.resolveName("ft_sensor/wrench");
    NODELET_INFO("StateRecognizer: axis %s%c, %s; %s declared at %g Hz (~sensor_rate_hz)",
                 recognizer_->axis().sign < 0 ? "-" : "", "xyz"[recognizer_->axis().index],
                 recognizer_ -> describe().c_str(), wrench_topic_.c_str(),
                 rate_check_->params().declared_hz);
    for (const std::string& off : params.disabledWatchdogs()) {
      NODELET_WARN("StateRecognizer: UNSAFE (~unsafe_allow_disabled_watchdogs): %s", off.c_str());
    }
    // The nodelet manager runs this nodelet's callbacks while onInit still runs (nodelet
    // 1.10.2): the publishers exist before the callbacks that use them are registered.
    state_pub_ = nh.advertise<DrillingState>("drilling_state", 100);
    stop_pub_ = nh.advertise<StopCommand>("drill/stop", 10);
    diagnostics_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
    // The planner's phase (latched): no reset while its drill is in bone.
    status_sub_ =
        nh.subscribe("compensation/status", 10, &StateRecognizerNodelet::onTrialStatus, this);
    reset_srv_ = pnh.advertiseService("reset", &StateRecognizerNodelet::onReset, this);
    // A new tare: the samples before it were untared; the recognizer starts afresh.
    tare_sub_ = nh.subscribe("ft_sensor/tare_result", 10, &StateRecognizerNodelet::onTare, this);
    // The drill's context for a class that reads it (its feed and spindle joints).
    joints_ = params.joints;
    joint_state_sub_ =
        nh.subscribe("joint_states", 10, &StateRecognizerNodelet::onJointStates, this);
    feed_state_sub_ = nh.subscribe("feed_controller/state", 10,
                                   &StateRecognizerNodelet::onFeedControllerState, this);
    tracker_sub_ =
        nh.subscribe("tracker/marker_pose", 50, &StateRecognizerNodelet::onTracked, this);
    wrench_sub_ =
        nh.subscribe("ft_sensor/wrench", params.queue_size, &StateRecognizerNodelet::onWrench, this,
                     ros::TransportHints().tcpNoDelay());
    lockstep_->start();  // last
  }

  /**
   * @brief Reads and checks the parameters into @p params; returns the paper recognizer's in use
   *        (its own keys with ~recognizer_params over them for the paper class). A paper
   *        recognizer's parameter is given one way: a key both the node's own (~window) and in
   *        ~recognizer_params is refused naming it.
   */
  static core::RecognizerParams loadParams(const ParamLoader& loader,
                                           StateRecognizerNodeParams* params) {
    loader.read(StateRecognizerNodeParams::table(), params);
    for (const std::string& name : params->paperSettingNames()) {
      if (!loader.has(name)) continue;
      const std::string why = "is set as ~" + name + " too: give the paper recognizer's " +
                              "parameter once, as ~" + name + " or in ~recognizer_params";
      loader.fail("recognizer_params/" + name, why);
    }
    loader.check(*params);
    return params->recognizerInUse();
  }

  /** @brief The class of @p params, configured with its settings. @throws ParameterError. */
  std::unique_ptr<core::RecognizerInterface> makeRecognizer(
      const ParamLoader& loader, const StateRecognizerNodeParams& params) {
    if (params.paperClass()) {
      return std::make_unique<core::PaperRecognizer>(params.recognizerInUse());
    }
    try {
      return loader_.create(params.recognizer_class, params.recognizer_params);
    } catch (const std::exception& e) {
      loader.fail("recognizer", "= '" + params.recognizer_class + "': " + e.what());
    }
  }

  void onJointStates(const sensor_msgs::JointState::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    recognizer_->setContextFromJoints(msg->name, msg->position, msg->velocity, joints_);
  }

  void onFeedControllerState(const JointTrajectoryControllerState::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    recognizer_->setFeedCommandFromController(msg->joint_names, msg->desired.positions, joints_);
  }

  void onTracked(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const geometry_msgs::Point& p = msg->pose.position;
    recognizer_->setTracker(msg->header.stamp.toSec(), Eigen::Vector3d(p.x, p.y, p.z));
  }

  void onWrench(const geometry_msgs::WrenchStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const geometry_msgs::Vector3& f = msg->wrench.force;
    const double t =
        msg->header.stamp.isZero() ? ros::Time::now().toSec() : msg->header.stamp.toSec();
    // The stream's rate counts every message, whatever its force.
    if (rate_check_->observe(t)) onRateMeasured(ros::Time(t));
    // The core's glue: the axis, non-finite samples dropped and counted, the latch.
    const geometry_msgs::Vector3& m = msg->wrench.torque;
    const core::RecognizerStep step =
        recognizer_->onSample(t, Eigen::Vector3d(f.x, f.y, f.z), Eigen::Vector3d(m.x, m.y, m.z));
    if (!step.accepted) {
      // Skipping one keeps the block means honest. The SafetyMonitor stops the drill on NaN
      // input, so this only has to stay alive.
      NODELET_WARN_THROTTLE(1.0, "StateRecognizer: ignored %lu non-finite force sample(s) so far",
                            static_cast<unsigned long>(recognizer_->nonFiniteCount()));
      return;
    }
    if (step.new_average) publishState(msg->header.stamp, recognizer_->output());
    if (step.new_stop) {
      StopCommand stop;
      stop.header.stamp = msg->header.stamp;
      stop.header.frame_id = msg->header.frame_id;
      stop.source = getName();
      stop.retreat = false;
      stop.reason = step.stop_reason;
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
    trial_running_ = msg->running;
    if (!trial_running_) rate_stop_sent_ = false;  // the next trial's own
  }

  /** @brief The rate check's verdict as one line naming both rates and the block's length. */
  std::string rateText() const {
    std::ostringstream os;
    os << wrench_topic_ << " " << rate_check_->describe();
    if (rate_check_->verdict() == core::RateVerdict::kMismatch) {
      os << ": the block of " << block_samples_ << " samples lasts "
         << block_samples_ / rate_check_->measuredHz() << " s instead of pre_average_s "
         << pre_average_s_ << " s; set ~sensor_rate_hz to the sensor's rate (hardware.launch "
         << "force_rate_hz)";
    } else {
      os << "; block " << block_samples_ << " samples = " << pre_average_s_ << " s";
    }
    return os.str();
  }

  /**
   * @brief A window of the rate check completed: its status on /diagnostics, a log line when the
   *        verdict changes (ERROR while off, throttled), and the stop of a running trial.
   */
  void onRateMeasured(const ros::Time& stamp) {
    const bool mismatch = rate_check_->verdict() == core::RateVerdict::kMismatch;
    const std::string text = rateText();
    publishRateStatus(stamp, mismatch, text);
    if (mismatch && !rate_mismatch_logged_) {
      NODELET_ERROR("StateRecognizer: sensor rate: %s", text.c_str());
    } else if (mismatch) {
      NODELET_ERROR_THROTTLE(10.0, "StateRecognizer: sensor rate: %s", text.c_str());
    } else if (rate_mismatch_logged_ || !rate_logged_) {
      NODELET_INFO("StateRecognizer: sensor rate: %s", text.c_str());
    }
    rate_logged_ = true;
    rate_mismatch_logged_ = mismatch;
    if (!mismatch || !trial_running_ || rate_stop_sent_) return;
    // A filter of the wrong length in time is no recognizer to drill on: fail closed.
    rate_stop_sent_ = true;
    StopCommand stop;
    stop.header.stamp = stamp;
    stop.source = getName();
    stop.retreat = true;
    stop.reason = "sensor rate mismatch, stop and retreat: " + text;
    publishInOrder(stop_pub_, stop);
    lockstep_->noteSent();
    NODELET_ERROR("StateRecognizer: STOP: %s", stop.reason.c_str());
  }

  void publishRateStatus(const ros::Time& stamp, bool mismatch, const std::string& text) {
    diagnostic_msgs::DiagnosticArray array;
    array.header.stamp = stamp;
    diagnostic_msgs::DiagnosticStatus status;
    status.name = getName() + ": sensor rate";
    status.hardware_id = wrench_topic_;
    status.level =
        mismatch ? diagnostic_msgs::DiagnosticStatus::ERROR : diagnostic_msgs::DiagnosticStatus::OK;
    status.message = text;
    const auto value = [&status](const std::string& key, double v) {
      diagnostic_msgs::KeyValue kv;
      kv.key = key;
      kv.value = core::Range::format(v);
      status.values.push_back(kv);
    };
    value("measured_rate_hz", rate_check_->measuredHz());
    value("sensor_rate_hz", rate_check_->params().declared_hz);
    value("rate_tolerance", rate_check_->params().tolerance);
    value("rate_window_s", rate_check_->params().window_s);
    value("block_samples", block_samples_);
    value("block_s", block_samples_ / rate_check_->measuredHz());
    array.status.push_back(status);
    publishInOrder(diagnostics_pub_, array);
    lockstep_->noteSent();
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
    if (rate_check_->verdict() == core::RateVerdict::kMismatch) {
      // The planner calls ~reset to start a trial: no trial on a filter of the wrong length.
      response.success = false;
      response.message = "reset refused, no trial starts: sensor rate mismatch: " + rateText();
      NODELET_ERROR("StateRecognizer: %s", response.message.c_str());
      return true;
    }
    recognizer_->reset();
    // Say at once that the latch is cleared (a planner refuses to feed while the latest state
    // reports a stop).
    publishState(lockstep_->now(), recognizer_->output());
    response.success = true;
    response.message = "recognizer reset (" + std::to_string(recognizer_->nonFiniteCount()) +
                       " non-finite samples ignored since start)";
    return true;
  }

  std::mutex mutex_;
  RecognizerLoader loader_;  // before recognizer_: outlives the instance it made
  std::unique_ptr<core::RecognizerAdapter> recognizer_;  ///< force sample in, state and stop out
  std::unique_ptr<LockstepParticipant> lockstep_;
  std::unique_ptr<core::SampleRateCheck> rate_check_;  ///< ft_sensor/wrench against sensor_rate_hz
  std::string wrench_topic_;                           ///< its resolved name, for the messages
  core::DrillJointNames joints_;                       ///< ~feed_joint, ~spindle_joint
  int block_samples_ = 0;                              ///< the paper recognizer's block
  double pre_average_s_ = 0.0;
  bool rate_logged_ = false;           ///< a verdict was logged
  bool rate_mismatch_logged_ = false;  ///< the latest verdict logged was a mismatch
  bool trial_running_ = false;         ///< compensation/status running
  bool rate_stop_sent_ = false;        ///< this trial was stopped for its sensor rate
  ros::Publisher state_pub_;
  ros::Publisher stop_pub_;
  ros::Publisher diagnostics_pub_;
  ros::Subscriber wrench_sub_;
  ros::Subscriber joint_state_sub_;
  ros::Subscriber feed_state_sub_;
  ros::Subscriber tracker_sub_;
  ros::ServiceServer reset_srv_;
  ros::Subscriber tare_sub_;
  ros::Subscriber status_sub_;
  std::uint8_t trial_phase_ = TrialStatus::IDLE;  ///< the planner's, from compensation/status
  std::string trial_phase_name_ = "idle";
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::StateRecognizerNodelet, nodelet::Nodelet)
