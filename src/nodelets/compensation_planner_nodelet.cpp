/**
 * @file compensation_planner_nodelet.cpp
 * @brief pedicle_drilling/CompensationPlanner: Algorithm 1 of the paper (Sec. IV-B). Per trial
 *        (`~start_trial`): every component started afresh, spindle on, arm to the drilling pose,
 *        marker registration, then every 125 ms the next trapezoidal segment of feed
 *        (+ predicted displacement in compensated mode) as a JointTrajectory on
 *        each controller's `<name>/command`, or as a FollowJointTrajectory goal on its
 *        `<name>/follow_joint_trajectory` (~trajectory_interface; by default arm_controller: the 6
 *        arm joints; feed_controller: feed_joint); stops on `drill/stop` (hold, or retreat along
 * the drill axis); holds the feed at the depth of the drilling plan (`drilling_plan`), from the
 * contact the thrust on `ft_sensor/wrench` shows. Thin ROS adapter of core::TrialSequencer (the
 * trial logic, shared with the closed-loop engine): parameters, message conversion, timers and the
 * component resets.
 */
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <nodelet/nodelet.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <std_msgs/Bool.h>
#include <std_msgs/Float64.h>
#include <std_msgs/Header.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <trajectory_msgs/JointTrajectory.h>
#include <pluginlib/class_list_macros.hpp>

#include <atomic>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "pedicle_drilling/BreathSourceStatus.h"
#include "pedicle_drilling/DrillingPlan.h"
#include "pedicle_drilling/DrillingState.h"
#include "pedicle_drilling/StartTrial.h"
#include "pedicle_drilling/StopCommand.h"
#include "pedicle_drilling/TareRequest.h"
#include "pedicle_drilling/TareResult.h"
#include "pedicle_drilling/TidalVolume.h"
#include "pedicle_drilling/VentilatorSettings.h"
#include "pedicle_drilling/core/breathing/motion_model_io.hpp"
#include "pedicle_drilling/core/common/units.hpp"
#include "pedicle_drilling/core/control/trial_sequencer.hpp"
#include "pedicle_drilling/ros/lockstep.hpp"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/planner_conversions.hpp"
#include "pedicle_drilling/ros/plugin_loader.hpp"
#include "pedicle_drilling/ros/simulator_conversions.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"
#include "pedicle_drilling/ros/trajectory_route.hpp"
#include "pedicle_drilling/ros/ventilator_conversions.hpp"

namespace pedicle_drilling {

/** @brief ROS adapter of core::TrialSequencer. */
class CompensationPlannerNodelet : public nodelet::Nodelet {
 public:
  ~CompensationPlannerNodelet() override {
    // Unloaded from a running manager: every callback ends before any member it may use goes
    // away (members are destroyed in reverse order; a callback runs on another thread). The
    // start thread, the lockstep's steps (the participants' thread), then the rest.
    if (start_spinner_) start_spinner_->stop();
    if (lockstep_) lockstep_->stop();
    for (ros::Subscriber* sub :
         {&tidal_sub_, &settings_sub_, &breath_source_sub_, &marker_sub_, &stop_sub_, &state_sub_,
          &diagnostics_sub_, &tare_result_sub_, &enable_sub_, &plan_sub_, &wrench_sub_}) {
      sub->shutdown();
    }
    for (ros::Subscriber& sub : controller_state_subs_) sub.shutdown();
    for (ros::Timer* timer :
         {&pose_timer_, &registration_timer_, &segment_timer_, &keepalive_timer_}) {
      timer->stop();
    }
    heartbeat_timer_.stop();
    steady_heartbeat_timer_.stop();
    // A running goal is canceled (the controllers hold); a fault handler that runs meanwhile
    // finds no route (mutex_) and does nothing.
    std::unique_ptr<TrajectoryRoute> route;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      route.swap(route_);
    }
    route.reset();
    if (lockstep_) lockstep_->drain();  // a callback already running on the shared queue ends
  }

 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    ros::NodeHandle pnh = getPrivateNodeHandle();
    try {
      const ParamLoader loader(pnh);
      loader.load(CompensationPlannerNodeParams::table(), &params_);
      patient_ = loadPatient();
      sequencer_ = makeSequencer(params_, loader, nh);
      tidal_volume_topic_ = nh.resolveName("tidal_volume");
      sequencer_->setBreathSource(tidal_volume_topic_, params_.breath_timeout_periods);
      thrust_index_ = params_.thrustAxisIndex();
      thrust_sign_ = params_.thrustAxisSign();
      controllers_ = sequencer_->controllers();
      loadCompensator(loader);
      // Under the simulator's lockstep, the sequencer's timers run on its steps (the engine's
      // rule, SequencerTimers), not on ROS timers.
      lockstep_ = std::make_unique<LockstepParticipant>(
          nh, getName(), [this](const ros::Time& t) { onStep(t); }, false,
          [this](const ros::Time&) { return nextStep(); });
      // Under the lockstep: one thread for the participants' callbacks; ~start_trial
      // keeps its own queue and thread below (it waits for the other nodelets' services).
      lockstep_->shareQueue({&nh, &pnh});
      if (params_.useAction() && lockstep_->enabled()) {
        throw std::invalid_argument(
            "parameter '" + pnh.resolveName("trajectory_interface") +
            "' = 'action' is not available under the lockstep (/use_sim_lockstep): its goals "
            "and results are not steps; use 'topic'");
      }
    } catch (const std::exception& e) {
      failStartup(getName(), e.what());  // throws: the load fails
    }
    tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
    tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_);
    // The nodelet manager runs this nodelet's callbacks while onInit still runs (nodelet
    // 1.10.2): every publisher and client exists before the first callback is registered, and
    // the steps of the lockstep come last.
    // ~trajectory_interface: the command topics or the action (one route). A goal the
    // controller rejects or aborts is a controller fault, as the controller watch's.
    std::vector<std::string> controller_names;
    for (const core::ControllerSpec& c : controllers_) controller_names.push_back(c.name);
    route_ = std::make_unique<TrajectoryRoute>(
        nh, controller_names, params_.useAction(),
        [this](const std::string& why) { onControllerFault(why); });
    // rad/s (REP 103), not latched: a driver that reconnects must not get an old speed again;
    // repeated every ~spindle_keepalive_s while it runs, for the driver's watchdog.
    spindle_pub_ = nh.advertise<std_msgs::Float64>("spindle/command", 10);
    predicted_pub_ =
        nh.advertise<geometry_msgs::PoseStamped>("compensation/predicted_marker_pose", 50);
    status_pub_ = nh.advertise<TrialStatus>("compensation/status", 10, true);
    // The F/T tare before contact (~tare_samples > 0): the sensor driver's protocol.
    tare_request_pub_ = nh.advertise<TareRequest>("ft_sensor/tare_request", 10);
    stop_pub_ = nh.advertise<StopCommand>("drill/stop", 10);
    // The safety monitor's drill guard watches it while a trial runs (a lost planner: the
    // drives stop). On hardware a steady timer: a wall-clock step does not pause it.
    heartbeat_pub_ = nh.advertise<std_msgs::Header>("compensation/heartbeat", 10);
    if (!lockstep_->enabled()) createHeartbeatTimer(nh);
    for (const std::string& name : params_.trial_start_services) {
      trial_start_clients_.push_back(nh.serviceClient<std_srvs::Trigger>(name));
    }
    publishStatus(core::TrialPhase::kIdle);
    const core::TrialSequencerParams& p = sequencer_->params();
    NODELET_INFO(
        "CompensationPlanner: patient '%s', drill axis (%.3f %.3f %.3f), latency %.3f s, "
        "compensator %s, depth limit from the drill tip '%s' and the thrust on %s, "
        "trajectories to %s%s",
        patient_.patient_id.c_str(), p.compensation.drill_axis.x(), p.compensation.drill_axis.y(),
        p.compensation.drill_axis.z(), p.compensation.latency_s, params_.compensator_class.c_str(),
        params_.tip_link.c_str(), params_.thrust_axis.c_str(), route_->name(0).c_str(),
        controllers_.size() > 1 ? " ..." : "");
    for (const std::string& off : params_.disabledWatchdogs()) {
      NODELET_WARN("CompensationPlanner: UNSAFE (~unsafe_allow_disabled_watchdogs): %s",
                   off.c_str());
    }
    const ros::TransportHints hints = ros::TransportHints().tcpNoDelay();
    // The closed loop on what the arm does (core::ControllerWatch): the controllers' states.
    for (const core::ControllerSpec& c : controllers_) {
      const std::string name = c.name;
      controller_state_subs_.push_back(nh.subscribe<JointTrajectoryControllerState>(
          name + "/state", 10,
          [this, name](const JointTrajectoryControllerState::ConstPtr& msg) {
            onControllerState(name, msg);
          },
          ros::VoidConstPtr(), hints));
    }
    tidal_sub_ =
        nh.subscribe("tidal_volume", 10, &CompensationPlannerNodelet::onTidalVolume, this, hints);
    settings_sub_ =
        nh.subscribe("ventilator/settings", 1, &CompensationPlannerNodelet::onSettings, this);
    breath_source_sub_ = nh.subscribe("ventilator/breath_source_status", 1,
                                      &CompensationPlannerNodelet::onBreathSource, this);
    marker_sub_ =
        nh.subscribe("tracker/marker_pose", 10, &CompensationPlannerNodelet::onMarker, this, hints);
    // The depth limit's inputs: the plan (latched by its publisher), and the thrust that shows
    // the contact (the F/T stream the safety monitor reads).
    plan_sub_ = nh.subscribe("drilling_plan", 1, &CompensationPlannerNodelet::onPlan, this);
    wrench_sub_ =
        nh.subscribe("ft_sensor/wrench", 1000, &CompensationPlannerNodelet::onWrench, this, hints);
    stop_sub_ = nh.subscribe("drill/stop", 10, &CompensationPlannerNodelet::onStop, this, hints);
    tare_result_sub_ =
        nh.subscribe("ft_sensor/tare_result", 10, &CompensationPlannerNodelet::onTareResult, this);
    state_sub_ = nh.subscribe("drilling_state", 100, &CompensationPlannerNodelet::onDrillingState,
                              this, hints);
    diagnostics_sub_ =
        nh.subscribe("/diagnostics", 50, &CompensationPlannerNodelet::onDiagnostics, this);
    // The drill guard's enable: a trial starts only once a guard has said true (guardListens).
    enable_sub_ = nh.subscribe<std_msgs::Bool>(
        "drill_guard/enable", 10,
        [this](const std_msgs::Bool::ConstPtr& msg) { guard_enabled_ = msg->data; });
    // ~start_trial calls other nodelets' services and waits for them: it gets a callback queue
    // and a thread of its own, so that it never blocks the manager's worker threads.
    ros::NodeHandle start_nh(pnh);
    start_nh.setCallbackQueue(&start_queue_);
    start_srv_ =
        start_nh.advertiseService("start_trial", &CompensationPlannerNodelet::onStartTrial, this);
    start_spinner_ = std::make_unique<ros::AsyncSpinner>(1, &start_queue_);
    start_spinner_->start();
    lockstep_->start();  // last: the steps call onStep
  }

  /**
   * @brief ~compensator and ~compensator_params: the class is loaded and configured
   *        once here (a bad one fails the load), then made afresh for every trial.
   */
  void loadCompensator(const ParamLoader& loader) {
    try {
      compensator_loader_.create(params_.compensator_class, params_.compensator_params);
    } catch (const std::exception& e) {
      loader.fail("compensator", "= '" + params_.compensator_class + "': " + e.what());
    }
    if (params_.compensator_class == "pedicle_drilling/PaperCompensator") return;  // the default
    sequencer_->setCompensatorFactory([this]() {
      return compensator_loader_.create(params_.compensator_class, params_.compensator_params);
    });
  }

  /**
   * @brief The file ~patient_model_path names, read at start and again for every trial: the
   *        parameter as it is then (a campaign sets each trial's patient model there).
   */
  core::PatientModel loadPatient() const {
    const ros::NodeHandle& pnh = getPrivateNodeHandle();
    std::string path = params_.patient_model_path;
    XmlRpc::XmlRpcValue value;
    if (pnh.getParam("patient_model_path", value)) {
      if (value.getType() != XmlRpc::XmlRpcValue::TypeString) {
        throw std::invalid_argument("parameter '" + pnh.resolveName("patient_model_path") +
                                    "' must be a string (a file path)");
      }
      path = static_cast<std::string>(value);
    }
    try {
      return core::readModelYaml(path);
    } catch (const std::exception& e) {
      throw std::runtime_error("patient model file '" + path + "' (parameter '" +
                               pnh.resolveName("patient_model_path") + "'): " + e.what());
    }
  }

  /** @brief The planner's time: the lockstep's step, else ros::Time::now(). */
  double now() const { return lockstep_->now().toSec(); }

  /** @brief Rank of a stop among the messages of one step (the engine's emission order). */
  int stopRank(const std::string& source) const {
    if (source == getName()) return 2;  // the planner's own, heard back
    return source.find("safety_monitor") != std::string::npos ? 1 : 0;
  }

  // ------------------------------------------------------------------------------- inputs

  void onSettings(const VentilatorSettings::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      sequencer_->setVentilator(fromMsg(*msg));
    } catch (const std::exception& e) {
      NODELET_ERROR("CompensationPlanner: ignored invalid ventilator settings: %s", e.what());
    }
  }

  /** @brief The Ventilator's breath source: named in a refusal or a stop, its problem quoted. */
  void onBreathSource(const BreathSourceStatus::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const std::string source = msg->topic.empty() ? tidal_volume_topic_
                                                  : msg->source + " on " + msg->topic + " (via " +
                                                        tidal_volume_topic_ + ")";
    sequencer_->setBreathSource(source, params_.breath_timeout_periods);
    sequencer_->setBreathSourceProblem(msg->ready ? "" : msg->message);
    if (!msg->ready) NODELET_WARN("CompensationPlanner: %s", msg->message.c_str());
  }

  void onControllerState(const std::string& name,
                         const JointTrajectoryControllerState::ConstPtr& msg) {
    lockstep_->observe(msg->header.stamp);
    std::lock_guard<std::mutex> lock(mutex_);
    sequencer_->onControllerState(now(), name, fromMsg(*msg, 0.0));
    carryOut();
  }

  /** @brief A goal the controller rejected, aborted or lost (TrajectoryRoute): a controller
   *         fault while a trial runs. */
  void onControllerFault(const std::string& why) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!route_) return;  // unloading
    sequencer_->onControllerFault(now(), why);
    carryOut();
  }

  void onTidalVolume(const TidalVolume::ConstPtr& msg) {
    lockstep_->observe(msg->header.stamp);
    std::lock_guard<std::mutex> lock(mutex_);
    const double start = msg->header.stamp.toSec() - msg->time_in_breath_s;
    if (!std::isfinite(start)) {
      NODELET_WARN_THROTTLE(1.0, "CompensationPlanner: non-finite tidal volume phase ignored");
      return;
    }
    sequencer_->setBreathStart(start);
  }

  void onMarker(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    lockstep_->observe(msg->header.stamp);
    std::lock_guard<std::mutex> lock(mutex_);
    const auto& p = msg->pose.position;
    const auto& o = msg->pose.orientation;
    const core::FrameLookup lookup = [this](const std::string& frame, Eigen::Isometry3d* x) {
      if (!tf_buffer_->canTransform(frame, params_.world_frame, ros::Time(0))) return false;
      const geometry_msgs::Transform& tr =
          tf_buffer_->lookupTransform(frame, params_.world_frame, ros::Time(0)).transform;
      const auto& q = tr.rotation;
      x->linear() = Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized().toRotationMatrix();
      x->translation() = Eigen::Vector3d(tr.translation.x, tr.translation.y, tr.translation.z);
      return true;
    };
    sequencer_->onMarker(now(), msg->header.stamp.toSec(), msg->header.frame_id,
                         Eigen::Vector3d(p.x, p.y, p.z), Eigen::Quaterniond(o.w, o.x, o.y, o.z),
                         lookup);
    carryOut();
  }

  /**
   * @brief drilling_plan: the plan of the next trials (the latest at a trial's registration is
   *        its plan). One that is not usable is no plan: the next trial is refused (fail closed).
   */
  void onPlan(const DrillingPlan::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    std::string why;
    std::optional<core::DrillingPlan> plan = fromMsg(*msg, &why);
    if (!plan) {
      NODELET_ERROR(
          "CompensationPlanner: drilling plan refused: %s; the planner has no plan now (fail "
          "closed): the next trials are refused until a usable plan comes",
          why.c_str());
      sequencer_->setPlan(std::nullopt);
      return;
    }
    NODELET_INFO("CompensationPlanner: drilling plan: %s", describe(*plan).c_str());
    sequencer_->setPlan(std::move(plan));
  }

  /** @brief ft_sensor/wrench: the thrust (~thrust_axis) that shows the contact with the bone,
   *         as the safety monitor hears the stream (a simulator stream under the lockstep). */
  void onWrench(const geometry_msgs::WrenchStamped::ConstPtr& msg) {
    lockstep_->observe(msg->header.stamp);
    std::lock_guard<std::mutex> lock(mutex_);
    const auto& f = msg->wrench.force;
    const double component = thrust_index_ == 0 ? f.x : (thrust_index_ == 1 ? f.y : f.z);
    sequencer_->onForce(now(), msg->header.stamp.toSec(), thrust_sign_ * component);
    carryOut();
  }

  void onStop(const StopCommand::ConstPtr& msg) {
    lockstep_->deliver(msg->header.stamp, stopRank(msg->source), [this, msg] { handleStop(msg); });
  }

  void handleStop(const StopCommand::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    NODELET_WARN("CompensationPlanner: stop from %s (retreat %s): %s", msg->source.c_str(),
                 msg->retreat ? "yes" : "no", msg->reason.c_str());
    if (msg->header.stamp >= trial_start_stamp_) ++stops_heard_;
    sequencer_->onStop(now(), msg->retreat, msg->reason);
    carryOut();
  }

  void onTareResult(const TareResult::ConstPtr& msg) {
    lockstep_->deliver(msg->header.stamp, 4, [this, msg] {
      std::lock_guard<std::mutex> lock(mutex_);
      sequencer_->onTareResult(now(), fromMsg(*msg));
      carryOut();
    });
  }

  /**
   * @brief The safety monitor's /diagnostics status: it is alive; an ERROR published during
   *        this trial is a stop and retreat as its drill/stop is (a stop that cannot be lost).
   */
  void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& msg) {
    for (const diagnostic_msgs::DiagnosticStatus& status : msg->status) {
      if (status.name != params_.monitor_status_name) continue;
      const bool error = status.level == diagnostic_msgs::DiagnosticStatus::ERROR;
      const ros::Time stamp = msg->header.stamp;
      const std::string message = status.message;
      lockstep_->deliver(stamp, 3, [this, error, stamp, message] {
        std::lock_guard<std::mutex> lock(mutex_);
        sequencer_->onMonitorAlive(now());
        if (!error || stamp < trial_start_stamp_) return;
        sequencer_->onStop(now(), true, "safety monitor ERROR: " + message);
        carryOut();
      });
      return;
    }
  }

  /** @brief The heartbeat's timer without the lockstep (sim time: ROS; hardware: steady). */
  void createHeartbeatTimer(ros::NodeHandle& nh) {
    if (ros::Time::isSimTime()) {
      heartbeat_timer_ =
          nh.createTimer(ros::Duration(params_.heartbeat_period_s),
                         [this](const ros::TimerEvent&) { beatIfRunning(now(), true); });
      return;
    }
    steady_heartbeat_timer_ =
        nh.createSteadyTimer(ros::WallDuration(params_.heartbeat_period_s),
                             [this](const ros::SteadyTimerEvent&) { beatIfRunning(now(), true); });
  }

  /**
   * @brief compensation/heartbeat while a trial runs: every heartbeat_period_s under the
   *        lockstep (its steps), at each timer event else. Takes mutex_: a planner stuck in a
   *        callback stops beating.
   */
  void beatIfRunning(double t, bool take_lock) {
    std::unique_lock<std::mutex> lock(mutex_, std::defer_lock);
    if (take_lock) lock.lock();
    if (!running_ || (lockstep_->enabled() && t < next_heartbeat_)) return;
    next_heartbeat_ = t + params_.heartbeat_period_s;
    std_msgs::Header msg;
    msg.stamp = lockstep_->now();
    // No noteSent(): the monitor takes it at its next step, in stamp order, whenever that is
    // (its guard's deadline is a step it asks for).
    publishInOrder(heartbeat_pub_, msg);
  }

  void onDrillingState(const DrillingState::ConstPtr& msg) {
    lockstep_->deliver(msg->header.stamp, 0, [this, msg] { handleDrillingState(msg); });
  }

  void handleDrillingState(const DrillingState::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    sequencer_->onRecognizerState(now(), msg->stop, msg->state_name, msg->last_key_point);
    carryOut();
  }

  // ------------------------------------------------------------------------------- trial

  bool onStartTrial(StartTrial::Request& req, StartTrial::Response& res) {
    // Runs on the planner's own start thread (see onInit), so the blocking calls below never
    // hold a worker thread of the nodelet manager that the reset services themselves need.
    std::unique_lock<std::mutex> lock(mutex_);
    res.success = false;
    core::TrialRequest request;
    request.mode = req.mode;
    request.spindle_rpm = req.spindle_rpm;
    request.feed_rate_mm_s = req.feed_rate_mm_s;
    request.max_duration_s = req.max_duration_s;
    request.segment_profile = req.segment_profile;
    res.message = sequencer_->check(request);  // a bad request resets nothing
    if (!res.message.empty()) return true;
    // The patient model is read again for every trial, so a new identification (a new
    // ~patient_model_path, or a rewritten file) applies to the next trial.
    try {
      patient_ = loadPatient();
    } catch (const std::exception& e) {
      res.message = e.what();
      return true;
    }
    // Every component of the trial starts afresh, here and nowhere else, so that no caller can
    // forget one: a component that cannot be reset refuses the trial, nothing drills. No lock
    // is held while calling: the components' answers may need this nodelet's callbacks.
    lock.unlock();
    const bool started =
        route_->waitForServers(params_.action_server_timeout_s, &res.message) &&
        guardListens(&res.message) &&
        callTriggerChain(&trial_start_clients_, params_.trial_start_timeout_s, &res.message);
    lock.lock();
    if (!started) return true;
    trial_start_stamp_ = lockstep_->now();
    stops_heard_ = 0;
    res.message = sequencer_->start(request, patient_.motionModel(), now());
    res.success = res.message.empty();
    if (res.success) {
      // Numbers as a person reads them: "spindle 12000 rpm" (%g), not std::to_string's
      // "12000.000000".
      res.message = "trial started: " + req.mode + ", spindle " +
                    core::Range::format(sequencer_->spindleRpm()) + " rpm";
    }
    carryOut();
    return true;
  }

  /**
   * @brief Waits up to ~trial_start_timeout_s of wall time for the drill guard (the safety
   *        monitor): its drill_guard/enable said true and it listens to compensation/heartbeat.
   *        A heartbeat nobody hears protects nothing (a recorder or `rostopic echo` that
   *        subscribes is no guard), so no trial starts before. A planner that watches no
   *        monitor (monitor_timeout_s 0, an unsafe bench) does not wait.
   */
  bool guardListens(std::string* why) const {
    if (params_.sequencer.monitor_timeout_s == 0.0) return true;
    const ros::WallTime deadline =
        ros::WallTime::now() + ros::WallDuration(params_.trial_start_timeout_s);
    while (heartbeat_pub_.getNumSubscribers() == 0 || !guard_enabled_) {
      if (ros::WallTime::now() > deadline || !ros::ok()) {
        *why =
            "trial refused: no drill guard (drill_guard/enable true, listening to "
            "compensation/heartbeat) within " +
            core::Range::format(params_.trial_start_timeout_s) +
            " s (is the SafetyMonitor running?); nothing was started";
        return false;
      }
      ros::WallDuration(0.01).sleep();
    }
    return true;
  }

  // ------------------------------------------------------------------------------- outputs

  /** @brief Publishes what the sequencer produced and runs the timers it asked for. */
  void carryOut() {
    core::SequencerOutput out = sequencer_->takeOutput();
    // What the monitor, the recognizer or this planner handle at the next step (a predicted
    // pose, a stop, a phase; the commands to the simulator too, harmlessly).
    if (out.publishesAnything()) {
      lockstep_->noteSent();
    }
    logSequencerMessages(out.log, "CompensationPlanner");
    for (double rpm : out.spindle_rpm) {
      std_msgs::Float64 msg;
      msg.data = core::radPerSecFromRpm(rpm);
      publishInOrder(spindle_pub_, msg);
    }
    for (const core::TareRequest& r : out.tare_requests) {
      TareRequest msg;
      msg.header.stamp = lockstep_->now();
      msg.samples = static_cast<std::uint32_t>(r.samples);
      msg.max_spread_n = r.max_spread_n;
      publishInOrder(tare_request_pub_, msg);
    }
    for (const core::JointTrajectoryCommand& c : out.trajectories) {
      // One stream per controller, each naming its own joints (as a lab's controllers take it).
      for (const auto& [index, part] : core::splitByController(c, controllers_)) {
        if (route_) route_->send(index, toMsg(part));
      }
    }
    for (const core::PredictedMarker& m : out.predicted) publishInOrder(predicted_pub_, toMsg(m));
    // A stop the planner decided is announced before the phase it causes (a listener that
    // waits for 'failed' or 'retreating' has the reason by then).
    for (const std::string& why : out.stops) {
      StopCommand stop;
      stop.header.stamp = lockstep_->now();
      stop.source = getName();
      stop.reason = why;
      stop.retreat = true;
      publishInOrder(stop_pub_, stop);
    }
    for (core::TrialPhase p : out.phases) publishStatus(p);
    if (lockstep_->enabled()) {
      timers_.apply(out, now());
      return;
    }
    if (out.stop_timers) {
      pose_timer_.stop();
      registration_timer_.stop();
      segment_timer_.stop();
      keepalive_timer_.stop();
    }
    for (const core::TimerRequest& t : out.start_timers) startTimer(t);
  }

  void startTimer(const core::TimerRequest& t) {
    ros::NodeHandle nh = getNodeHandle();
    using Kind = core::TimerRequest::Kind;
    const ros::Duration delay(t.delay_s);
    switch (t.kind) {
      case Kind::kPoseReached:
        pose_timer_ = nh.createTimer(delay, &CompensationPlannerNodelet::onPoseTimer, this, true);
        break;
      case Kind::kRegistrationTimeout:
        registration_timer_ =
            nh.createTimer(delay, &CompensationPlannerNodelet::onRegistrationTimer, this, true);
        break;
      case Kind::kSegment:
        segment_timer_ =
            nh.createTimer(delay, &CompensationPlannerNodelet::onSegmentTimer, this, !t.periodic);
        break;
      case Kind::kSpindleKeepalive:
        keepalive_timer_ =
            nh.createTimer(delay, &CompensationPlannerNodelet::onKeepaliveTimer, this, !t.periodic);
        break;
    }
  }

  void onPoseTimer(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    sequencer_->onPoseReached(now());
    carryOut();
  }

  void onRegistrationTimer(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    sequencer_->onRegistrationTimeout(now());
    carryOut();
  }

  void onKeepaliveTimer(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    sequencer_->onSpindleKeepalive(now());
    carryOut();
  }

  void onSegmentTimer(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    sequencer_->onSegmentTimer(now());
    carryOut();
  }

  /** @brief Under the lockstep: the sequencer's timers due at the step (before the stops and
   *         states sent in the step before, which the lockstep hands over next). */
  void onStep(const ros::Time& t) {
    std::lock_guard<std::mutex> lock(mutex_);
    while (const std::optional<core::TimerRequest::Kind> kind = timers_.popDue(t.toSec())) {
      sequencer_->onTimer(*kind, t.toSec());
      carryOut();
    }
    beatIfRunning(t.toSec(), false);
  }

  /** @brief Under the lockstep: the step the next timer fires at (LockstepParticipant::stepFor:
   *         the timers' rounding is 1 ns). */
  std::optional<ros::Time> nextStep() {
    std::lock_guard<std::mutex> lock(mutex_);
    std::optional<double> due = timers_.nextDue();
    if (running_ && (!due || next_heartbeat_ < *due)) due = next_heartbeat_;
    if (!due) return std::nullopt;
    return LockstepParticipant::stepFor(*due);
  }

  void publishStatus(core::TrialPhase p) {
    const bool was_running = running_;
    running_ = core::isRunning(p);
    if (running_ && !was_running) next_heartbeat_ = now();  // beat from the trial's first step
    TrialStatus msg = toMsg(p, lockstep_->now());
    msg.stops = stops_heard_;
    publishInOrder(status_pub_, msg);
    lockstep_->noteSent();
  }

  ros::Time trial_start_stamp_;    ///< the latest trial's start (start_trial)
  std::uint32_t stops_heard_ = 0;  ///< drill/stop commands handled since, stamped at or after it
  std::mutex mutex_;
  CompensationPlannerNodeParams params_;  ///< every parameter, loaded once
  core::PatientModel patient_;
  CompensatorLoader compensator_loader_;  // before sequencer_: outlives what it made
  std::unique_ptr<core::TrialSequencer> sequencer_;
  std::unique_ptr<LockstepParticipant> lockstep_;
  core::SequencerTimers timers_;  ///< under the lockstep
  int thrust_index_ = 2;          ///< ~thrust_axis's component of ft_sensor/wrench
  double thrust_sign_ = 1.0;      ///< ~thrust_axis's sign

  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  std::vector<core::ControllerSpec> controllers_;       ///< params_.controllers, checked
  std::unique_ptr<TrajectoryRoute> route_;              ///< the trajectories' route
  std::vector<ros::Subscriber> controller_state_subs_;  ///< <controller>/state, one each
  ros::Publisher spindle_pub_;
  ros::Publisher predicted_pub_;
  ros::Publisher status_pub_;
  ros::Subscriber tidal_sub_;
  ros::Subscriber breath_source_sub_;
  std::string tidal_volume_topic_;  // resolved: named when the breath phase is missing
  ros::Subscriber settings_sub_;
  ros::Subscriber marker_sub_;
  ros::Subscriber stop_sub_;
  ros::Subscriber state_sub_;
  ros::Subscriber diagnostics_sub_;
  ros::Subscriber plan_sub_;
  ros::Subscriber wrench_sub_;
  ros::Publisher stop_pub_;
  ros::Publisher tare_request_pub_;
  ros::Subscriber tare_result_sub_;
  std::vector<ros::ServiceClient> trial_start_clients_;
  ros::Timer pose_timer_;
  ros::Timer registration_timer_;
  ros::Timer segment_timer_;
  ros::Timer keepalive_timer_;
  ros::Timer heartbeat_timer_;
  ros::SteadyTimer steady_heartbeat_timer_;
  ros::Publisher heartbeat_pub_;
  ros::Subscriber enable_sub_;
  std::atomic<bool> guard_enabled_{false};  ///< the latest drill_guard/enable
  bool running_ = false;                    ///< the latest phase published is a running trial's
  double next_heartbeat_ = 0.0;             ///< under the lockstep: the next heartbeat's step
  ros::CallbackQueue start_queue_;
  std::unique_ptr<ros::AsyncSpinner> start_spinner_;
  ros::ServiceServer start_srv_;
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::CompensationPlannerNodelet, nodelet::Nodelet)
