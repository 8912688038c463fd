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
 * contact the thrust on `ft_sensor/wrench` shows. Thin ROS adapter of core::PlannerRuntime (the
 * trial's core::TrialSequencer and the state between callbacks, as the closed-loop engine runs
 * them): parameters, message conversion, timers; publishing in src/ros/planner_outputs.
 */
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <std_msgs/Bool.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <pluginlib/class_list_macros.hpp>

#include <atomic>
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
#include "pedicle_drilling/TareResult.h"
#include "pedicle_drilling/TidalVolume.h"
#include "pedicle_drilling/VentilatorSettings.h"
#include "pedicle_drilling/core/breathing/motion_model_io.hpp"
#include "pedicle_drilling/core/control/planner_runtime.hpp"
#include "pedicle_drilling/ros/lockstep.hpp"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/planner_conversions.hpp"
#include "pedicle_drilling/ros/planner_outputs.hpp"
#include "pedicle_drilling/ros/plugin_loader.hpp"
#include "pedicle_drilling/ros/simulator_conversions.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"
#include "pedicle_drilling/ros/trajectory_route.hpp"
#include "pedicle_drilling/ros/ventilator_conversions.hpp"

namespace pedicle_drilling {

/** @brief ROS adapter of core::PlannerRuntime. */
class CompensationPlannerNodelet : public nodelet::Nodelet {
 public:
  ~CompensationPlannerNodelet() override {
    // Unloaded from a running manager: every callback ends before any member it may use goes
    // away (members are destroyed in reverse order; a callback runs on another thread). The
    // start thread, the lockstep's steps (the participants' thread), then the rest.
    if (start_service_) start_service_->stop();
    if (lockstep_) lockstep_->stop();
    for (ros::Subscriber& sub : subs_) sub.shutdown();
    if (ros_timers_) ros_timers_->stop();
    heartbeat_timer_.stop();
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
      patient_ = loadPatientModel(pnh, params_.patient_model_path);
      runtime_ = makePlannerRuntime(params_, loader, nh, &compensator_loader_);
      controllers_ = sequencer().controllers();
      // Under the simulator's lockstep, the sequencer's timers run on its steps (the engine's
      // rule, PlannerRuntime::fireDueTimers), not on ROS timers.
      lockstep_ = std::make_unique<LockstepParticipant>(
          nh, getName(), [this](const ros::Time& t) { onStep(t); }, false,
          [this](const ros::Time&) { return nextStep(); });
      // Under the lockstep: one thread for the participants' callbacks; ~start_trial
      // keeps its own queue and thread below (it waits for the other nodelets' services).
      lockstep_->shareQueue({&nh, &pnh});
      checkTrajectoryInterface(params_, pnh, lockstep_->enabled());
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
    outputs_ = std::make_unique<PlannerPublishers>(nh, getName());
    ros_timers_ = std::make_unique<SequencerRosTimers>(nh, [this](core::TimerRequest::Kind kind) {
      handle([&] { sequencer().onTimer(kind, now()); });
    });
    // Without the lockstep, the drill guard's heartbeat on the node's clock.
    if (!lockstep_->enabled()) {
      heartbeat_timer_.start(nh, params_.heartbeat_period_s,
                             [this] { beatIfRunning(now(), true); });
    }
    start_service_ = std::make_unique<TrialStartService>(nh, params_);
    publishStatus(core::TrialPhase::kIdle);
    NODELET_INFO("CompensationPlanner: %s",
                 startSummary(params_, sequencer(), patient_.patient_id, route_->name(0)).c_str());
    for (const std::string& off : params_.disabledWatchdogs()) {
      NODELET_WARN("CompensationPlanner: UNSAFE (~unsafe_allow_disabled_watchdogs): %s",
                   off.c_str());
    }
    subscribe(nh);
    start_service_->advertise(pnh, [this](StartTrial::Request& req, StartTrial::Response& res) {
      return onStartTrial(req, res);
    });
    lockstep_->start();  // last: the steps call onStep
  }

  /** @brief Every subscription of the planner (the last of onInit's callbacks to exist). */
  void subscribe(ros::NodeHandle& nh) {
    using N = CompensationPlannerNodelet;
    const ros::TransportHints hints = ros::TransportHints().tcpNoDelay();
    // The closed loop on what the arm does (core::ControllerWatch): the controllers' states.
    for (const core::ControllerSpec& c : controllers_) {
      const std::string name = c.name;
      subs_.push_back(nh.subscribe<JointTrajectoryControllerState>(
          name + "/state", 10,
          [this, name](const JointTrajectoryControllerState::ConstPtr& msg) {
            onControllerState(name, msg);
          },
          ros::VoidConstPtr(), hints));
    }
    subs_.push_back(nh.subscribe("tidal_volume", 10, &N::onTidalVolume, this, hints));
    subs_.push_back(nh.subscribe("ventilator/settings", 1, &N::onSettings, this));
    subs_.push_back(nh.subscribe("ventilator/breath_source_status", 1, &N::onBreathSource, this));
    subs_.push_back(nh.subscribe("tracker/marker_pose", 10, &N::onMarker, this, hints));
    // The depth limit's inputs: the plan (latched by its publisher), and the thrust that shows
    // the contact (the F/T stream the safety monitor reads).
    subs_.push_back(nh.subscribe("drilling_plan", 1, &N::onPlan, this));
    subs_.push_back(nh.subscribe("ft_sensor/wrench", 1000, &N::onWrench, this, hints));
    subs_.push_back(nh.subscribe("drill/stop", 10, &N::onStop, this, hints));
    subs_.push_back(nh.subscribe("ft_sensor/tare_result", 10, &N::onTareResult, this));
    subs_.push_back(nh.subscribe("drilling_state", 100, &N::onDrillingState, this, hints));
    subs_.push_back(nh.subscribe("/diagnostics", 50, &N::onDiagnostics, this));
    // The drill guard's enable: a trial starts only once a guard has said true (onStartTrial).
    subs_.push_back(nh.subscribe<std_msgs::Bool>(
        "drill_guard/enable", 10,
        [this](const std_msgs::Bool::ConstPtr& msg) { guard_enabled_ = msg->data; }));
  }

  core::TrialSequencer& sequencer() { return runtime_->sequencer(); }

  /** @brief The planner's time: the lockstep's step, else ros::Time::now(). */
  double now() const { return lockstep_->now().toSec(); }

  /** @brief Calls @p f under mutex_, then carries out what the sequencer produced. */
  template <class F>
  void handle(F&& f) {
    std::lock_guard<std::mutex> lock(mutex_);
    f();
    carryOut();
  }

  void onSettings(const VentilatorSettings::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      sequencer().setVentilator(fromMsg(*msg));
    } catch (const std::exception& e) {
      NODELET_ERROR("CompensationPlanner: ignored invalid ventilator settings: %s", e.what());
    }
  }

  /** @brief The Ventilator's breath source: named in a refusal or a stop, its problem quoted. */
  void onBreathSource(const BreathSourceStatus::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    runtime_->onBreathSourceStatus(msg->source, msg->topic, msg->ready, msg->message);
    if (!msg->ready) NODELET_WARN("CompensationPlanner: %s", msg->message.c_str());
  }

  void onControllerState(const std::string& name,
                         const JointTrajectoryControllerState::ConstPtr& msg) {
    lockstep_->observe(msg->header.stamp);
    handle([&] { sequencer().onControllerState(now(), name, fromMsg(*msg, 0.0)); });
  }

  /** @brief A goal the controller rejected, aborted or lost (TrajectoryRoute): a controller
   *         fault while a trial runs. */
  void onControllerFault(const std::string& why) {
    handle([&] {
      if (route_) sequencer().onControllerFault(now(), why);  // else unloading
    });
  }

  void onTidalVolume(const TidalVolume::ConstPtr& msg) {
    lockstep_->observe(msg->header.stamp);
    std::lock_guard<std::mutex> lock(mutex_);
    if (!runtime_->onTidalVolume(msg->header.stamp.toSec(), msg->time_in_breath_s)) {
      NODELET_WARN_THROTTLE(1.0, "CompensationPlanner: non-finite tidal volume phase ignored");
    }
  }

  void onMarker(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    lockstep_->observe(msg->header.stamp);
    const auto& p = msg->pose.position;
    const auto& o = msg->pose.orientation;
    handle([&] {
      sequencer().onMarker(now(), msg->header.stamp.toSec(), msg->header.frame_id,
                           Eigen::Vector3d(p.x, p.y, p.z), Eigen::Quaterniond(o.w, o.x, o.y, o.z),
                           tfFrameLookup(*tf_buffer_, params_.world_frame));
    });
  }

  /**
   * @brief drilling_plan: the plan of the next trials (the latest at a trial's registration is
   *        its plan). One that is not usable is no plan: the next trial is refused (fail closed).
   */
  void onPlan(const DrillingPlan::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    logSequencerMessages({setPlan(*msg, &sequencer())}, "CompensationPlanner");
  }

  /** @brief ft_sensor/wrench: the thrust (~thrust_axis) that shows the contact with the bone,
   *         as the safety monitor hears the stream (a simulator stream under the lockstep). */
  void onWrench(const geometry_msgs::WrenchStamped::ConstPtr& msg) {
    lockstep_->observe(msg->header.stamp);
    const auto& f = msg->wrench.force;
    handle([&] {
      runtime_->onForce(now(), msg->header.stamp.toSec(), Eigen::Vector3d(f.x, f.y, f.z));
    });
  }

  void onStop(const StopCommand::ConstPtr& msg) {
    lockstep_->deliver(
        msg->header.stamp, core::PlannerRuntime::stopRank(msg->source, getName()), [this, msg] {
          handle([&] {
            NODELET_WARN("CompensationPlanner: stop from %s (retreat %s): %s", msg->source.c_str(),
                         msg->retreat ? "yes" : "no", msg->reason.c_str());
            runtime_->onStop(now(), msg->header.stamp.toSec(), msg->retreat, msg->reason);
          });
        });
  }

  void onTareResult(const TareResult::ConstPtr& msg) {
    lockstep_->deliver(msg->header.stamp, 4, [this, msg] {
      handle([&] { sequencer().onTareResult(now(), fromMsg(*msg)); });
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
        handle([&] { runtime_->onMonitorStatus(now(), stamp.toSec(), error, message); });
      });
      return;
    }
  }

  void onDrillingState(const DrillingState::ConstPtr& msg) {
    lockstep_->deliver(msg->header.stamp, 0, [this, msg] {
      handle([&] {
        sequencer().onRecognizerState(now(), msg->stop, msg->state_name, msg->last_key_point);
      });
    });
  }

  bool onStartTrial(StartTrial::Request& req, StartTrial::Response& res) {
    // Runs on the planner's own start thread (TrialStartService), so the blocking calls below
    // never hold a worker thread of the nodelet manager that the reset services themselves need.
    std::unique_lock<std::mutex> lock(mutex_);
    res.success = false;
    const core::TrialRequest request = fromMsg(req);
    res.message = sequencer().check(request);  // a bad request resets nothing
    if (!res.message.empty()) return true;
    // The patient model is read again for every trial, so a new identification (a new
    // ~patient_model_path, or a rewritten file) applies to the next trial.
    try {
      patient_ = loadPatientModel(getPrivateNodeHandle(), params_.patient_model_path);
    } catch (const std::exception& e) {
      res.message = e.what();
      return true;
    }
    // Every component of the trial starts afresh, here and nowhere else, so that no caller can
    // forget one: a component that cannot be reset refuses the trial, nothing drills. No lock
    // is held while calling: the components' answers may need this nodelet's callbacks.
    lock.unlock();
    const bool started = start_service_->runChain(*route_, *outputs_, guard_enabled_, &res.message);
    lock.lock();
    if (!started) return true;
    const core::TrialStartAnswer answer =
        runtime_->start(request, patient_.motionModel(), now(), lockstep_->now().toSec());
    res.success = answer.success;
    res.message = answer.message;
    carryOut();
    return true;
  }

  /** @brief Publishes what the sequencer produced and runs the timers it asked for. */
  void carryOut() {
    const core::SequencerOutput out = sequencer().takeOutput();
    // What the monitor, the recognizer or this planner handle at the next step (a predicted
    // pose, a stop, a phase; the commands to the simulator too, harmlessly).
    if (out.publishesAnything()) lockstep_->noteSent();
    logSequencerMessages(out.log, "CompensationPlanner");
    outputs_->publish(out, lockstep_->now(), controllers_, route_.get());
    for (core::TrialPhase p : out.phases) publishStatus(p);
    if (lockstep_->enabled()) {
      runtime_->applyTimers(out, now());
      return;
    }
    ros_timers_->apply(out);
  }

  void publishStatus(core::TrialPhase p) {
    runtime_->onPhase(p, now());
    outputs_->publishStatus(p, lockstep_->now(), runtime_->stopsHeard());
    lockstep_->noteSent();
  }

  /**
   * @brief compensation/heartbeat while a trial runs: every heartbeat_period_s under the
   *        lockstep (its steps), at each timer event else. Takes mutex_: a planner stuck in a
   *        callback stops beating.
   */
  void beatIfRunning(double t, bool take_lock) {
    std::unique_lock<std::mutex> lock(mutex_, std::defer_lock);
    if (take_lock) lock.lock();
    if (lockstep_->enabled() ? !runtime_->beatDue(t) : !runtime_->running()) return;
    // No noteSent(): the monitor takes it at its next step, in stamp order, whenever that is
    // (its guard's deadline is a step it asks for).
    outputs_->publishHeartbeat(lockstep_->now());
  }

  /** @brief Under the lockstep: the sequencer's timers due at the step (before the stops and
   *         states sent in the step before, which the lockstep hands over next). */
  void onStep(const ros::Time& t) {
    std::lock_guard<std::mutex> lock(mutex_);
    runtime_->fireDueTimers(t.toSec(), [this] { carryOut(); });
    beatIfRunning(t.toSec(), false);
  }

  /** @brief Under the lockstep: the step the next timer or heartbeat is due at
   *         (LockstepParticipant::stepFor: the timers' rounding is 1 ns). */
  std::optional<ros::Time> nextStep() {
    std::lock_guard<std::mutex> lock(mutex_);
    const std::optional<double> due = runtime_->nextDue();
    if (!due) return std::nullopt;
    return LockstepParticipant::stepFor(*due);
  }

  std::mutex mutex_;
  CompensationPlannerNodeParams params_;  ///< every parameter, loaded once
  core::PatientModel patient_;
  CompensatorLoader compensator_loader_;           // before runtime_: outlives what it made
  std::unique_ptr<core::PlannerRuntime> runtime_;  ///< the sequencer and its state
  std::unique_ptr<LockstepParticipant> lockstep_;

  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  std::vector<core::ControllerSpec> controllers_;     ///< params_.controllers, checked
  std::unique_ptr<TrajectoryRoute> route_;            ///< the trajectories' route
  std::unique_ptr<PlannerPublishers> outputs_;        ///< every publisher
  std::unique_ptr<SequencerRosTimers> ros_timers_;    ///< without the lockstep
  ClockTimer heartbeat_timer_;                        ///< without the lockstep
  std::vector<ros::Subscriber> subs_;                 ///< every subscription
  std::atomic<bool> guard_enabled_{false};            ///< the latest drill_guard/enable
  std::unique_ptr<TrialStartService> start_service_;  ///< ~start_trial, its thread, its chain
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::CompensationPlannerNodelet, nodelet::Nodelet)
