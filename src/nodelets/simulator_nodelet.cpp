/**
 * @file simulator_nodelet.cpp
 * @brief pedicle_drilling/Simulator: the simulated workcell (core::DrillingSimulation) behind
 *        the ROS interfaces a real setup would have. A dedicated thread steps the 1 kHz physics,
 *        owns /clock (when ~publish_clock) and paces the simulation at ~real_time_factor.
 *
 * Interfaces (see doc/nodes.md, "pedicle_drilling/Simulator"): publishes /clock, joint_states,
 * ft_sensor/wrench (at ~force_sensor_rate_hz, 1000/3 Hz), tf + tf_static, tracker/marker_pose (8
 * Hz), simulator/ground_truth, drilling_plan (latched: the specimen's plan, at start and at every
 * reset or start_trial); subscribes each controller's <name>/command
 * (trajectory_msgs/JointTrajectory; arm_controller and feed_controller by default, ros_control's
 * rules), spindle/command (std_msgs/Float64, rpm); service simulator/reset (ResetSimulation).
 */
#include <geometry_msgs/PoseStamped.h>
#include <nodelet/nodelet.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <std_msgs/Bool.h>
#include <std_msgs/Float64.h>
#include <std_srvs/Trigger.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <trajectory_msgs/JointTrajectory.h>
#include <urdf_parser/urdf_parser.h>
#include <pluginlib/class_list_macros.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "pedicle_drilling/AbortController.h"
#include "pedicle_drilling/AirwayFlow.h"
#include "pedicle_drilling/ResetSimulation.h"
#include "pedicle_drilling/SetPatientAmplitude.h"
#include "pedicle_drilling/SetVentilatorSettings.h"
#include "pedicle_drilling/StallJoint.h"
#include "pedicle_drilling/StepAck.h"
#include "pedicle_drilling/TareRequest.h"
#include "pedicle_drilling/TareResult.h"
#include "pedicle_drilling/TrialStatus.h"
#include "pedicle_drilling/VentilatorSettings.h"
#include "pedicle_drilling/core/common/units.hpp"
#include "pedicle_drilling/core/common/wait_deadline.hpp"
#include "pedicle_drilling/core/sim/closed_loop_engine.hpp"
#include "pedicle_drilling/core/sim/drilling_simulation.hpp"
#include "pedicle_drilling/core/sim/stream_schedule.hpp"
#include "pedicle_drilling/ros/lockstep.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/simulator_conversions.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"
#include "pedicle_drilling/ros/trajectory_action_server.hpp"
#include "pedicle_drilling/ros/ventilator_conversions.hpp"

namespace pedicle_drilling {

/** @brief Nodelet wrapper of core::DrillingSimulation with its own stepping thread. */
class SimulatorNodelet : public nodelet::Nodelet {
 public:
  ~SimulatorNodelet() override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      running_ = false;
    }
    command_cv_.notify_all();  // a loop waiting for a trajectory or on a hold ends now
    ack_cv_.notify_all();      // ... or for the lockstep's answers
    if (thread_.joinable()) thread_.join();
    if (lockstep_spinner_) lockstep_spinner_->stop();
    if (trial_spinner_) trial_spinner_->stop();
    actions_.reset();  // its thread ends: no goal reaches sim_ after this
  }

 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    ros::NodeHandle pnh = getPrivateNodeHandle();
    std::string urdf_path;
    try {
      const ParamLoader loader(pnh);
      const SimulatorNodeParams params = loadSimulatorParams(pnh);
      sim_ = makeSimulation(params, loader);
      if (params.sim.drive_guard_timeout_s == 0.0) {
        NODELET_WARN(
            "Simulator: ~drive_guard_timeout_s 0: the simulated drivers take no drill guard "
            "input (drill_guard/enable); only for a simulator with no SafetyMonitor on the graph");
      }
      urdf_xml_ = loader.readFile("urdf_path", params.urdf_path);  // a reset builds a new one
      lockstep_ = useSimLockstep();
      follow_joint_trajectory_ = params.follow_joint_trajectory;
      if (follow_joint_trajectory_ && lockstep_) {
        throw std::invalid_argument(
            "parameter '" + pnh.resolveName("follow_joint_trajectory") +
            "' true is not available under the lockstep (/use_sim_lockstep): an action's goals "
            "and results are not steps");
      }
      lockstep_timeout_s_ = params.lockstep_timeout_s;
      lockstep_every_step_ = params.lockstep_every_step;
      command_transport_ = core::CommandTransport(params.command_delay_s, params.command_jitter_s,
                                                  static_cast<std::uint64_t>(params.seed));
      delayed_markers_.setDelay(params.tracker_delay_s);
      tracker_tf_frame_ = params.tracker_tf_frame;
      if (!params.publish_joint_frames) floating_frames_ = floatingChildren(urdf_xml_);
      // Re-read at every reset; checked here too, so that a bad value refuses the start.
      loadBoneMotionModel(params, loader);
      urdf_path = params.urdf_path;
      real_time_factor_ = params.real_time_factor;
      publish_clock_ = params.publish_clock;
      clock_period_steps_ = params.clock_period_ms;
      command_wait_s_ = params.command_wait_s;
      core::StreamRates rates;  // the engine's schedule
      rates.joint_state_hz = params.joint_state_rate_hz;
      rates.tf_hz = params.tf_rate_hz;
      rates.ground_truth_hz = params.ground_truth_rate_hz;
      rates.tracker_hz = params.tracker_rate_hz;
      rates.controller_state_hz = params.controller_state_rate_hz;
      // The simulated ventilator is the device that drives the patient: it publishes what the
      // Ventilator nodelet publishes on hardware-free setups (0 disables it).
      rates.tidal_volume_hz = params.tidal_volume_rate_hz;
      streams_ = core::StreamSchedule(rates);
    } catch (const std::exception& e) {
      // Safe state: nothing is advertised, the error names the parameter or the file.
      failStartup(getName(), e.what());  // throws: the load fails
    }
    advertiseOutputs(nh, urdf_path);
    registerCallbacks(nh);
    running_ = true;
    thread_ = std::thread(&SimulatorNodelet::loop, this);
    // Last, these two queues' threads: a reset served while onInit still read sim_ (a campaign
    // worker calls it as soon as the service is advertised) replaced the simulation under it.
    if (lockstep_) {
      lockstep_spinner_ = std::make_unique<ros::AsyncSpinner>(1, &lockstep_queue_);
      lockstep_spinner_->start();
    }
    trial_spinner_ = std::make_unique<ros::AsyncSpinner>(2, &trial_queue_);
    trial_spinner_->start();
  }

  /** @brief onInit's publishers, the static frames and the start-up line: before any callback. */
  void advertiseOutputs(ros::NodeHandle& nh, const std::string& urdf_path) {
    if (publish_clock_) {
      clock_pub_ = nh.advertise<rosgraph_msgs::Clock>("/clock", 10);
    } else {
      time_offset_ = ros::Time::now().toSec();
    }
    joint_state_pub_ = nh.advertise<sensor_msgs::JointState>("joint_states", 100);
    for (const core::ControllerSpec& c : sim_->controllers()) {
      controller_state_pubs_.push_back(
          nh.advertise<JointTrajectoryControllerState>(c.name + "/state", 10));
    }
    wrench_pub_ = nh.advertise<geometry_msgs::WrenchStamped>("ft_sensor/wrench", 2000);
    tare_result_pub_ = nh.advertise<TareResult>("ft_sensor/tare_result", 10, true);
    marker_pub_ = nh.advertise<geometry_msgs::PoseStamped>("tracker/marker_pose", 20);
    ground_truth_pub_ = nh.advertise<GroundTruth>("simulator/ground_truth", 200);
    // The bench's breath sensor (~breath_sensor_rate_hz > 0): the raw flow it samples, as a
    // lab's flow sensor feeds the Ventilator's `flow` breath source.
    if (sim_->params().breath_sensor_rate_hz > 0.0) {
      flow_pub_ = nh.advertise<AirwayFlow>("breath_sensor/flow", 200);
    }
    // The bench's planning tool: the plan of the mounted specimen, latched.
    plan_pub_ = nh.advertise<DrillingPlan>("drilling_plan", 1, true);
    publishPlan(sim_->time());
    if (streams_.tidalVolumeOn()) {
      tidal_volume_pub_ = nh.advertise<TidalVolume>("tidal_volume", 200);
      ventilator_settings_pub_ = nh.advertise<VentilatorSettings>("ventilator/settings", 1, true);
      publishInOrder(ventilator_settings_pub_, toMsg(sim_->ventilator().model().settings()));
    }
    tf_broadcaster_ = std::make_unique<tf2_ros::TransformBroadcaster>();
    static_broadcaster_ = std::make_unique<tf2_ros::StaticTransformBroadcaster>();
    if (lockstep_) step_pub_ = nh.advertise<rosgraph_msgs::Clock>("simulator/step", 10);
    publishStaticTransforms();
    NODELET_INFO(
        "Simulator: workcell '%s', arm at %.0f Hz, physics at 1 kHz, real-time "
        "factor %s, %s /clock%s",
        urdf_path.c_str(), sim_->params().arm_rate_hz,
        real_time_factor_ > 0.0 ? std::to_string(real_time_factor_).c_str() : "max",
        publish_clock_ ? "publishing" : "not publishing",
        lockstep_ ? ", in lockstep with the participants of simulator/step" : "");
  }

  /** @brief onInit's subscriptions and services (their callbacks may run at once). */
  void registerCallbacks(ros::NodeHandle& nh) {
    // From here on, callbacks: the nodelet manager runs them while onInit still runs (nodelet
    // 1.10.2), on its threads (this nodelet's queue) and on this nodelet's own queues once
    // their spinners start, at the end. They touch sim_ under mutex_ only; onInit no longer
    // reads it.
    std::vector<std::string> controller_names;
    for (const core::ControllerSpec& c : sim_->controllers()) controller_names.push_back(c.name);
    // Under the lockstep, the commands, the participants' answers and simulator/resume share
    // one queue and its own thread: a participant publishes its commands before its answer, so
    // a command is handled before the answer that lets the simulator step (one nodelet manager:
    // both are queued in publishing order), and the planner's first commands before the resume
    // that ends the hold. The stepping thread waits for them whatever this nodelet's queue is
    // doing.
    ros::NodeHandle command_nh(nh);
    if (lockstep_) command_nh.setCallbackQueue(&lockstep_queue_);
    // One command stream per controller (simulator parameters arm_controller, feed_controller
    // and their joints), each with ros_control's rules (controller_rules).
    for (const std::string& name : controller_names) {
      trajectory_subs_.push_back(command_nh.subscribe<trajectory_msgs::JointTrajectory>(
          name + "/command", 10,
          [this, name](const trajectory_msgs::JointTrajectory::ConstPtr& msg) {
            onTrajectory(name, msg);
          }));
    }
    spindle_sub_ = command_nh.subscribe("spindle/command", 10, &SimulatorNodelet::onSpindle, this);
    // The drivers' drill guard (~drive_guard_timeout_s > 0): the safety monitor's enable.
    enable_sub_ =
        command_nh.subscribe("drill_guard/enable", 10, &SimulatorNodelet::onDriveEnable, this);
    tare_sub_ =
        command_nh.subscribe("ft_sensor/tare_request", 10, &SimulatorNodelet::onTareRequest, this);
    resume_srv_ =
        command_nh.advertiseService("simulator/resume", &SimulatorNodelet::onResume, this);
    // The planner's phase says when trajectories stream (drilling, stopped, retreating): then
    // sim time does not run past the last one received (waitForCommand).
    status_sub_ = nh.subscribe("compensation/status", 10, &SimulatorNodelet::onPlannerStatus, this);
    // The trial services have a queue and threads of their own: start_trial waits for the hold,
    // a reset builds a new simulation, and a nodelet must not hold the manager's worker threads
    // (the other nodelets' callbacks wait behind them).
    ros::NodeHandle trial_nh(nh);
    trial_nh.setCallbackQueue(&trial_queue_);
    reset_srv_ = trial_nh.advertiseService("simulator/reset", &SimulatorNodelet::onReset, this);
    if (lockstep_) {
      ack_sub_ = command_nh.subscribe("simulator/step_ack", 100, &SimulatorNodelet::onAck, this,
                                      ros::TransportHints().tcpNoDelay());
    }
    start_trial_srv_ =
        trial_nh.advertiseService("simulator/start_trial", &SimulatorNodelet::onStartTrial, this);
    set_ventilator_srv_ = nh.advertiseService("simulator/set_ventilator_settings",
                                              &SimulatorNodelet::onSetVentilatorSettings, this);
    set_amplitude_srv_ = nh.advertiseService("simulator/set_patient_amplitude",
                                             &SimulatorNodelet::onSetPatientAmplitude, this);
    stall_joint_srv_ =
        nh.advertiseService("simulator/stall_joint", &SimulatorNodelet::onStallJoint, this);
    abort_controller_srv_ = nh.advertiseService("simulator/abort_controller",
                                                &SimulatorNodelet::onAbortController, this);
    if (follow_joint_trajectory_) advertiseActions(nh, controller_names);
  }

  /**
   * @brief ~follow_joint_trajectory: each controller's FollowJointTrajectory server beside its
   *        command topic (a goal's trajectory takes the topic's path: the same rules).
   */
  void advertiseActions(const ros::NodeHandle& nh, const std::vector<std::string>& controllers) {
    TrajectoryActionServer::Hooks hooks;
    hooks.command = [this](const std::string& controller,
                           const trajectory_msgs::JointTrajectory& msg,
                           double* end_s) { return applyTrajectory(controller, msg, end_s); };
    hooks.hold = [this](const std::string& controller) {
      std::lock_guard<std::mutex> lock(mutex_);
      sim_->holdController(controller);
    };
    hooks.now = [this]() {
      std::lock_guard<std::mutex> lock(mutex_);
      return sim_->time();
    };
    actions_ = std::make_unique<TrajectoryActionServer>(nh, controllers, std::move(hooks));
  }

  ros::Time stampOf(double sim_time) const { return ros::Time(sim_time + time_offset_); }

  void publishStaticTransforms() {
    static_broadcaster_->sendTransform(toMsg(ownFrames(sim_->frameTransforms(true)), stampOf(0.0)));
  }

  /** @brief The child links of the URDF's floating joints (robot_state_publisher skips them). */
  static std::set<std::string> floatingChildren(const std::string& urdf_xml) {
    std::set<std::string> children;
    const urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(urdf_xml);
    if (!model) throw std::runtime_error("urdf_path: the workcell URDF does not parse");
    for (const auto& joint : model->joints_) {
      if (joint.second->type == urdf::Joint::FLOATING)
        children.insert(joint.second->child_link_name);
    }
    return children;
  }

  /**
   * @brief The workcell frames this simulator publishes: with ~tracker_tf_frame, not the ones
   *        the tracker's driver and the lab's registration own (the marker, the camera); with
   *        ~publish_joint_frames false, only the floating joints' children.
   */
  std::vector<core::FrameTransform> ownFrames(std::vector<core::FrameTransform> frames) const {
    frames.erase(std::remove_if(frames.begin(), frames.end(),
                                [this](const core::FrameTransform& f) {
                                  const bool tracker =
                                      !tracker_tf_frame_.empty() &&
                                      (f.child == tracker_tf_frame_ || f.child == "tracker_camera");
                                  const bool by_rsp = !floating_frames_.empty() &&
                                                      floating_frames_.count(f.child) == 0;
                                  return tracker || by_rsp;
                                }),
                 frames.end());
    return frames;
  }

  void loop() {
    using Clock = std::chrono::steady_clock;
    double sim0 = 0.0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      sim0 = sim_->time();
    }
    Clock::time_point pace_wall0 = Clock::now();
    while (running_ && ros::ok()) {
      double t = 0.0;
      ros::Time stamp;
      bool sync = true;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        // Machine load, a hold or a reset change wall time, not the trial: the pacing restarts
        // from here instead of catching up flat out.
        if (waitForCommand(&lock) || holdAtTrialStart(&lock) || restart_pacing_) {
          restart_pacing_ = false;
          // After a hold, a reset or a wait, what the participants sent meanwhile (a trial's
          // start) is handled at the first step.
          sync_next_ = true;
          pace_wall0 = Clock::now();
          sim0 = sim_->time();
        }
        if (!running_ || !ros::ok()) break;
        const core::SimulationStep step = sim_->stepOnce();
        t = step.time_s;
        stamp = stampOf(t);
        if (pending_amplitude_ && sim_->ventilator().breathIndex() != amplitude_breath_) {
          sim_->setPatientAmplitudeFactor(*pending_amplitude_);  // from this breath's start
          NODELET_WARN("Simulator: the patient's AP displacement x %.3f from now",
                       *pending_amplitude_);
          pending_amplitude_.reset();
        }
        // The step's index since the reset: the streams' phases are the engine's.
        const std::uint64_t n = core::StreamSchedule::stepIndex(t, sim_->params().physics_rate_hz);
        const core::StreamsDue due = streams_.at(n, step, *sim_);
        // Under the lockstep, a step that publishes one of the streams is a step every
        // participant sees (any of them may listen to it); /clock is not one.
        bool published = false;
        const auto stream = [&published](bool due) { return published |= due, due; };
        if (stream(due.force)) publishWrench(step);
        // The planner handles a tare result at the next step: that one is stepped too.
        const bool forced = sync_next_;
        sync_next_ = step.force_sampled && publishTareResult(step.time_s);
        if (stream(due.joint_states)) publishJointStates(t);
        if (stream(due.tf)) publishTf(t);
        if (stream(due.controller_states)) publishControllerStates(t);
        if (stream(due.ground_truth)) publishGroundTruth(t);
        if (stream(due.tracker)) publishMarker(t);
        if (stream(delayed_markers_.due(t))) publishDelayedMarkers(t);
        if (stream(due.tidal_volume)) publishTidalVolume(t);
        // Not a lockstep stream: its reader, the Ventilator, is not a participant.
        if (sim_->breathFlowSampled()) publishFlow(t);
        publishDelayedFlow(t);
        // The step that reaches the trial's hold: the participants are at it while it holds
        // (the planner starts the trial at its time).
        const bool holds_next = hold_at_ && t >= *hold_at_ - 1e-9;
        // A delayed tracker sample keeps its old stamp: a participant handles it at the time of
        // the last step it saw, which must be the step before it (as when every step waited).
        const double dt = 1.0 / sim_->params().physics_rate_hz;
        const bool marker_next = delayed_markers_.due(t + dt);
        sync = published || holds_next || marker_next || forced || lockstepStepWanted(stamp);
        if (lockstep_) ++(sync ? lockstep_steps_ : lockstep_skipped_);
        applyDueCommands(t);
        if (publish_clock_ && n % clock_period_steps_ == 0) {
          rosgraph_msgs::ClockPtr c = boost::make_shared<rosgraph_msgs::Clock>();
          c->clock = stamp;
          clock_pub_.publish(c);
        }
      }
      if (lockstep_ && sync) {
        rosgraph_msgs::ClockPtr c = boost::make_shared<rosgraph_msgs::Clock>();
        c->clock = stamp;
        step_pub_.publish(c);  // after the step's messages: a participant's queue is FIFO
        waitForAnswers(stamp);
      }
      if (real_time_factor_ > 0.0) {
        const Clock::time_point due =
            pace_wall0 + std::chrono::duration_cast<Clock::duration>(
                             std::chrono::duration<double>((t - sim0) / real_time_factor_));
        // Sleep only when ahead by more than a millisecond (fewer system calls).
        if (due - Clock::now() > std::chrono::milliseconds(1)) std::this_thread::sleep_until(due);
      } else if (!lockstep_ && static_cast<std::uint64_t>(std::llround(t * 1000.0)) % 1000 == 0) {
        std::this_thread::yield();  // as fast as possible, but let callbacks in
      }
    }
  }

  /** @brief An arm or spindle command received under the lockstep, applied at the end of the
   *         first step at or after `due` (~command_delay_s after the step it was sent in). */
  struct PendingCommand {
    double due = 0.0;
    std::optional<core::TrajectoryCommand> trajectory;
    double spindle_rpm = 0.0;
    std::string controller;                 ///< the trajectory's controller
    std::optional<core::TareRequest> tare;  ///< a tare request (neither of the above)
  };

  /** @brief The end of the step at `t`: the commands due by then, in the order received (the
   *         engine's transport: its events due at a step are handled after the step's
   *         measurements). */
  void applyDueCommands(double t) {
    std::vector<PendingCommand> later;
    for (const PendingCommand& c : pending_) {
      if (c.due <= t + 1e-9) {
        apply(c);
      } else {
        later.push_back(c);
      }
    }
    pending_.swap(later);
  }

  /** @brief Waits until every participant answered the step; a silent one is dropped (until
   *         it answers again) after ~lockstep_timeout_s of wall time, counted and warned. */
  void waitForAnswers(const ros::Time& step) {
    using Clock = std::chrono::steady_clock;
    std::unique_lock<std::mutex> lock(ack_mutex_);
    const auto answered = [this, &step] {
      for (const auto& participant : participants_) {
        if (participant.second.answered < step) return false;
      }
      return true;
    };
    // A freeze of the machine stops this thread and the participants alike: the time this
    // thread did not run (a wake-up over 0.5 s late) is not counted against them.
    core::WaitDeadline deadline(Clock::now(),
                                std::chrono::duration_cast<Clock::duration>(
                                    std::chrono::duration<double>(lockstep_timeout_s_)),
                                std::chrono::milliseconds(500));
    while (running_ && ros::ok() && !answered() && !deadline.expired(Clock::now())) {
      const Clock::time_point due = deadline.sliceEnd(Clock::now(), std::chrono::milliseconds(50));
      ack_cv_.wait_until(lock, due);
      deadline.woke(due, Clock::now());
    }
    if (deadline.stalled() > Clock::duration(0)) {
      NODELET_WARN(
          "Simulator: this process did not run for %.1f s of wall time at the step at "
          "%.3f s (a stalled machine); the lockstep's deadline was moved by as much",
          std::chrono::duration<double>(deadline.stalled()).count(), step.toSec());
    }
    if (!running_ || !ros::ok() || answered()) return;
    for (auto it = participants_.begin(); it != participants_.end();) {
      if (it->second.answered < step) {
        NODELET_WARN(
            "Simulator: lockstep participant '%s' did not answer the step at %.3f s "
            "within %.3f s of wall time (~lockstep_timeout_s): stepping on without it "
            "until it answers again",
            it->first.c_str(), step.toSec(), lockstep_timeout_s_);
        it = participants_.erase(it);
      } else {
        ++it;
      }
    }
    ++lockstep_timeouts_;
  }

  /** @brief simulator/step_ack: a participant joins with its first answer. */
  void onAck(const StepAck::ConstPtr& msg) {
    {
      std::lock_guard<std::mutex> lock(ack_mutex_);
      Participant& p = participants_[msg->node];
      if (msg->stamp >= p.answered) {
        p.answered = msg->stamp;
        p.next_step = msg->next_step;
      }
    }
    ack_cv_.notify_all();
  }

  /**
   * @brief Under the lockstep, whether the step at `stamp` waits for the participants for their
   *        own sake: ~lockstep_every_step, no participant yet (one joins with its first answer),
   *        one that needs every step (next_step zero), or one whose next step it is. The steps
   *        that publish a stream, or come after the simulator's tare result, or reach the hold,
   *        are stepped anyway. The previous step's answers are all in (it waited for them).
   */
  bool lockstepStepWanted(const ros::Time& stamp) {
    if (!lockstep_) return false;
    if (lockstep_every_step_) return true;
    std::lock_guard<std::mutex> lock(ack_mutex_);
    if (participants_.empty()) return true;
    for (const auto& [name, p] : participants_) {
      if (p.next_step.isZero() || p.next_step <= stamp) return true;
    }
    return false;
  }

  /**
   * @brief At the trial's start drawn by the last reset (ResetSimulation hold_at_trial_start):
   *        sim time stops until simulator/resume. True if it held.
   */
  bool holdAtTrialStart(std::unique_lock<std::mutex>* lock) {
    if (!hold_at_ || sim_->time() < *hold_at_ - 1e-9) return false;
    held_ = true;
    publishGroundTruth(sim_->time());  // the worker sees the hold
    command_cv_.notify_all();          // start_trial waits for it
    // Until resumed, or until a reset replaced the simulation (its own hold is still ahead).
    const std::uint64_t generation = reset_generation_;
    while (running_ && ros::ok() && hold_at_ && generation == reset_generation_) {
      command_cv_.wait_for(*lock, std::chrono::milliseconds(50));
    }
    held_ = false;
    return true;
  }

  /** @brief Carries out a command received under the lockstep. */
  void apply(const PendingCommand& c) {
    if (c.tare) {
      sim_->requestTare(*c.tare);
      return;
    }
    if (!c.trajectory) {
      reportSpindle(sim_->commandSpindle(c.spindle_rpm));
      return;
    }
    noteLateness(*c.trajectory);
    reportTrajectory(c.controller, sim_->commandTrajectory(c.controller, *c.trajectory));
  }

  /**
   * @brief While a trial streams trajectories, waits (wall time, at most ~command_wait_s) for
   *        the next one rather than step past the end of the last one received: sim time waits
   *        for the planner, as a lockstep would, so that a loaded machine slows the trial down
   *        instead of making the arm hold and then rush. True if it waited.
   */
  bool waitForCommand(std::unique_lock<std::mutex>* lock) {
    const double step = 1.0 / sim_->params().physics_rate_hz;
    const auto starved = [this, step] {
      return streaming_ && !wait_given_up_ && sim_->armTrajectoryEnd() < sim_->time() + step - 1e-9;
    };
    if (lockstep_ || command_wait_s_ <= 0.0 || !starved()) return false;
    using Clock = std::chrono::steady_clock;
    const Clock::time_point start = Clock::now();
    const Clock::time_point deadline = start + std::chrono::duration_cast<Clock::duration>(
                                                   std::chrono::duration<double>(command_wait_s_));
    // Woken by a trajectory, a phase or the destructor; a 50 ms slice sees a ROS shutdown.
    while (running_ && ros::ok() && starved() && Clock::now() < deadline) {
      command_cv_.wait_until(*lock,
                             std::min(deadline, Clock::now() + std::chrono::milliseconds(50)));
    }
    const bool expired = running_ && ros::ok() && starved();
    ++command_waits_;
    command_wait_wall_s_ += std::chrono::duration<double>(Clock::now() - start).count();
    if (expired) {
      wait_given_up_ = true;  // until the next trajectory or phase: one wait, not one per step
      ++command_wait_expired_;
      NODELET_WARN_THROTTLE(1.0,
                            "Simulator: no arm trajectory beyond t=%.3f s after %.3f s of wall "
                            "time (~command_wait_s): stepping on, the arm holds",
                            sim_->armTrajectoryEnd(), command_wait_s_);
    }
    return true;
  }

  void onPlannerStatus(const TrialStatus::ConstPtr& msg) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      streaming_ = msg->phase == TrialStatus::DRILLING || msg->phase == TrialStatus::STOPPED ||
                   msg->phase == TrialStatus::RETREATING;
      wait_given_up_ = false;
    }
    command_cv_.notify_all();
  }

  /** @brief The sensor driver's tare result, after the sample that completed its window. */
  bool publishTareResult(double t) {
    const std::optional<core::TareResult> r = sim_->takeTareResult();
    if (!r) return false;
    publishInOrder(tare_result_pub_, toMsg(*r, stampOf(t)));
    if (r->success) {
      NODELET_INFO("Simulator: F/T %s", r->message.c_str());
    } else {
      NODELET_WARN("Simulator: F/T %s", r->message.c_str());
    }
    return true;
  }

  /**
   * @brief ft_sensor/tare_request: the sensor driver's tare (the command path, no jitter draw:
   *        core::CommandTransport::undrawnDelay). A bad request is refused: an error and a
   *        failed ft_sensor/tare_result naming the reason.
   */
  void onTareRequest(const TareRequest::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const core::TareRequest request = fromMsg(*msg);
    try {
      request.validate();  // before it is queued
    } catch (const std::exception& e) {
      NODELET_ERROR("Simulator: ft_sensor/tare_request refused: %s", e.what());
      // The requester waits on the result: a refusal is a failed result, as the relay's.
      core::TareResult refused;
      refused.t = sim_->time();
      refused.message = std::string("tare request refused: ") + e.what();
      publishInOrder(tare_result_pub_, toMsg(refused, stampOf(refused.t)));
      return;
    }
    if (lockstep_) {
      const double t = sim_->time();
      pending_.push_back({t + command_transport_.undrawnDelay(t), std::nullopt, 0.0, "", request});
      return;
    }
    sim_->requestTare(request);
  }

  void publishWrench(const core::SimulationStep& step) {
    if (wrench_pub_.getNumSubscribers() == 0) return;
    publishInOrder(wrench_pub_, wrenchMsg(step, stampOf(step.time_s)));
  }

  void publishTidalVolume(double t) {
    publishInOrder(tidal_volume_pub_, tidalVolumeMsg(*sim_, stampOf(t)));
    const core::BreathScheduler& ventilator = sim_->ventilator();
    if (ventilator.breathIndex() != last_breath_index_) {
      last_breath_index_ = ventilator.breathIndex();
      const VentilatorSettings settings = toMsg(ventilator.model().settings());
      if (settings != last_settings_msg_) {
        publishInOrder(ventilator_settings_pub_, settings);
        last_settings_msg_ = settings;
      }
    }
  }

  void publishJointStates(double t) {
    publishInOrder(joint_state_pub_, jointStateMsg(*sim_, stampOf(t)));
  }

  void publishControllerStates(double t) {
    for (std::size_t i = 0; i < controller_state_pubs_.size(); ++i) {
      publishInOrder(controller_state_pubs_[i], toMsg(sim_->controllerState(i), stampOf(t)));
    }
  }

  void publishTf(double t) {
    tf_broadcaster_->sendTransform(toMsg(ownFrames(sim_->frameTransforms(false)), stampOf(t)));
  }

  void publishGroundTruth(double t) {
    GroundTruth msg = toMsg(sim_->groundTruth(), stampOf(t));
    msg.breath_index = static_cast<std::uint32_t>(sim_->ventilator().breathIndex());
    msg.breath_start = stampOf(sim_->ventilator().breathStart());
    msg.late_commands = late_commands_;
    msg.rejected_commands = rejected_commands_;
    msg.max_command_lateness_s = max_command_lateness_s_;
    msg.command_waits = command_waits_;
    msg.command_wait_wall_s = command_wait_wall_s_;
    msg.command_wait_expired = command_wait_expired_;
    msg.lockstep_timeouts = lockstep_timeouts_;
    msg.lockstep_steps = static_cast<std::uint32_t>(lockstep_steps_);
    msg.lockstep_steps_run = static_cast<std::uint32_t>(lockstep_steps_ + lockstep_skipped_);
    msg.spindle_watchdog_trips = static_cast<std::uint32_t>(sim_->spindleWatchdogTrips());
    if (sim_->spindleWatchdogTrips() > spindle_watchdog_trips_) {
      spindle_watchdog_trips_ = sim_->spindleWatchdogTrips();
      NODELET_WARN(
          "Simulator: the spindle driver heard no spindle/command for %.3f s: spindle stopped",
          sim_->params().spindle_watchdog_s);
    }
    if (sim_->driveGuardTrips() > drive_guard_trips_) {
      drive_guard_trips_ = sim_->driveGuardTrips();
      NODELET_ERROR(
          "Simulator: no enable from the drill guard (drill_guard/enable false, or none for "
          "%.3f s): the drivers hold and the spindle stops",
          sim_->params().drive_guard_timeout_s);
    }
    publishInOrder(ground_truth_pub_, msg);
  }

  /**
   * @brief drilling_plan: the mounted specimen's plan (core::DrillingSimulation::imagingPlan, in
   *        the tracked marker's frame), stamped @p t. After every reset and start_trial, whether
   *        or not the specimen changed (cheap, and latched: the latest is always the specimen's).
   */
  void publishPlan(double t) {
    publishInOrder(plan_pub_, toMsg(sim_->imagingPlan().plan, stampOf(t)));
  }

  void clearTransportCounters() {
    late_commands_ = 0;
    rejected_commands_ = 0;
    max_command_lateness_s_ = 0.0;
    command_waits_ = 0;
    command_wait_wall_s_ = 0.0;
    command_wait_expired_ = 0;
    lockstep_timeouts_ = 0;
    lockstep_steps_ = 0;
    lockstep_skipped_ = 0;
  }

  /**
   * @brief A breath-sensor sample: stamped with its time on the sensor's clock (+
   *        ~breath_clock_offset_s), published ~breath_sensor_latency_s later.
   */
  void publishFlow(double t) {
    if (flow_pub_.getNumSubscribers() == 0) return;
    AirwayFlow m;
    m.header.stamp = stampOf(t + sim_->params().breath_clock_offset_s);
    m.header.frame_id = "breath_sensor";
    m.flow_ml_s = sim_->ventilatorSample().flow_ml_s;
    delayed_flow_.setDelay(sim_->params().breath_sensor_latency_s);  // the simulation's
    delayed_flow_.push(t, m);
  }

  void publishDelayedFlow(double t) {
    delayed_flow_.deliverDue(t, [this](const AirwayFlow& m) { publishInOrder(flow_pub_, m); });
  }

  /** @brief A tracker sample: now, or ~tracker_delay_s later (its stamp kept). */
  void publishMarker(double t) {
    geometry_msgs::PoseStamped m;
    m.header.stamp = stampOf(t);
    m.header.frame_id = "tracker_camera";
    m.pose = tf2::toMsg(sim_->measureMarkerPose());
    if (delayed_markers_.delays()) {
      delayed_markers_.push(t, m);
      return;
    }
    sendMarker(m);
  }

  void publishDelayedMarkers(double t) {
    delayed_markers_.deliverDue(t, [this](const geometry_msgs::PoseStamped& m) { sendMarker(m); });
  }

  /** @brief A tracker sample out: tracker/marker_pose, and tf with ~tracker_tf_frame. */
  void sendMarker(const geometry_msgs::PoseStamped& m) {
    publishInOrder(marker_pub_, m);
    if (tracker_tf_frame_.empty()) return;
    geometry_msgs::TransformStamped t;
    t.header = m.header;
    t.child_frame_id = tracker_tf_frame_;
    t.transform.translation.x = m.pose.position.x;
    t.transform.translation.y = m.pose.position.y;
    t.transform.translation.z = m.pose.position.z;
    t.transform.rotation = m.pose.orientation;
    tf_broadcaster_->sendTransform(t);
  }

  /** @brief When a command received now takes effect (the engine's rule, CommandTransport). */
  double commandDue() { return sim_->time() + command_transport_.delay(sim_->time()); }

  /**
   * @brief simulator/start_trial: ground truth measures the relative AP motion from now; a
   *        specimen already drilled is replaced by a fresh one (seed + 1), as on the bench.
   */
  bool onStartTrial(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (hold_at_ && !held_) {
      // The trial starts at the hold the reset drew: wait for sim time to get there.
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
      while (running_ && ros::ok() && hold_at_ && !held_ &&
             std::chrono::steady_clock::now() < deadline) {
        command_cv_.wait_for(lock, std::chrono::milliseconds(50));
      }
      if (hold_at_ && !held_) {
        response.success = false;
        response.message =
            "start_trial: sim time did not reach the trial's start (the reset's "
            "hold) within 120 s of wall time";
        return true;
      }
    }
    bool remounted = false;
    try {
      remounted = sim_->startTrial();
      clearTransportCounters();
    } catch (const std::exception& e) {
      response.success = false;
      response.message = std::string("start_trial failed: ") + e.what();
      return true;
    }
    response.success = true;
    response.message = "trial " + std::to_string(sim_->trialCount()) +
                       " started at t=" + std::to_string(sim_->time()) + " s";
    if (remounted) {
      response.message += "; the specimen was drilled, a fresh one from seed " +
                          std::to_string(sim_->seed()) + " is mounted (arm at home)";
      NODELET_INFO("Simulator: %s", response.message.c_str());
    }
    publishGroundTruth(sim_->time());
    publishPlan(sim_->time());
    return true;
  }

  /** @brief The simulated ventilator takes new settings at its next breath (the settings
   *         stream tells the planner then); the identified model is not re-fit. */
  bool onSetVentilatorSettings(SetVentilatorSettings::Request& request,
                               SetVentilatorSettings::Response& response) {
    serveSetVentilatorSettings(request, response, [this](const core::VentilatorSettings& s) {
      std::lock_guard<std::mutex> lock(mutex_);
      sim_->requestVentilatorSettings(s);
    });
    return true;
  }

  /** @brief The patient's AP displacement x factor from the next breath until the next reset. */
  bool onSetPatientAmplitude(SetPatientAmplitude::Request& request,
                             SetPatientAmplitude::Response& response) {
    if (!(std::isfinite(request.factor) && request.factor >= 0.0 && request.factor <= 10.0)) {
      response.success = false;
      response.message = "factor must be in [0, 10] (got " + std::to_string(request.factor) + ")";
      return true;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    pending_amplitude_ = request.factor;
    amplitude_breath_ = sim_->ventilator().breathIndex();
    response.success = true;
    response.message = "the patient's AP displacement x " + std::to_string(request.factor) +
                       " from the next breath until the next reset";
    return true;
  }

  /** @brief simulator/abort_controller: the controller drops its trajectory and holds
   *         (core::DrillingSimulation::abortController), at the current step. */
  bool onAbortController(AbortController::Request& request, AbortController::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      sim_->abortController(request.controller);
    } catch (const std::invalid_argument& e) {
      response.success = false;
      response.message = e.what();
      return true;
    }
    NODELET_WARN("Simulator: %s aborted its trajectory: it holds where its reference is",
                 request.controller.c_str());
    if (actions_) {
      actions_->abort(request.controller,
                      request.controller + " aborted its trajectory (simulator/abort_controller)");
    }
    response.success = true;
    response.message = request.controller + " aborted";
    return true;
  }

  bool onStallJoint(StallJoint::Request& request, StallJoint::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      sim_->setJointStalled(request.joint, request.stalled);
    } catch (const std::invalid_argument& e) {
      response.success = false;
      response.message = e.what();
      return true;
    }
    NODELET_WARN("Simulator: %s's drive %s", request.joint.c_str(),
                 request.stalled ? "stalled: it holds where it is" : "released");
    response.success = true;
    response.message = request.joint + (request.stalled ? " stalled" : " released");
    return true;
  }

  void onTrajectory(const std::string& controller,
                    const trajectory_msgs::JointTrajectory::ConstPtr& msg) {
    if (lockstep_) {
      std::lock_guard<std::mutex> lock(mutex_);
      const core::TrajectoryCommand command = fromMsg(*msg, sim_->time(), time_offset_);
      pending_.push_back({commandDue(), command, 0.0, controller, std::nullopt});
      return;
    }
    applyTrajectory(controller, *msg, nullptr);
  }

  /**
   * @brief Without the lockstep: a trajectory for @p controller (its command topic or a
   *        FollowJointTrajectory goal) taken now; @p end_s (if given) gets the time the
   *        controller's trajectory ends when taken.
   */
  core::TargetResult applyTrajectory(const std::string& controller,
                                     const trajectory_msgs::JointTrajectory& msg, double* end_s) {
    std::unique_lock<std::mutex> lock(mutex_);
    const core::TrajectoryCommand command = fromMsg(msg, sim_->time(), time_offset_);
    noteLateness(command);
    const core::TargetResult r = sim_->commandTrajectory(controller, command);
    wait_given_up_ = false;
    reportTrajectory(controller, r);  // counts under mutex_
    if (end_s != nullptr) {
      const std::vector<core::ControllerSpec>& specs = sim_->controllers();
      for (std::size_t i = 0; i < specs.size(); ++i) {
        if (specs[i].name == controller) *end_s = sim_->controllerTrajectoryEnd(i);
      }
    }
    lock.unlock();
    command_cv_.notify_all();
    return r;
  }

  /** @brief Late: its start passed before it arrived (half a physics step of rounding allowed);
   *         a ros_control controller would start it now, as the executor does. */
  void noteLateness(const core::TrajectoryCommand& command) {
    const double half_step = 0.5 / sim_->params().physics_rate_hz;
    if (std::isfinite(command.start_time_s) && command.start_time_s < sim_->time() - half_step) {
      ++late_commands_;
      max_command_lateness_s_ =
          std::max(max_command_lateness_s_, sim_->time() - command.start_time_s);
    }
  }

  void reportTrajectory(const std::string& controller, const core::TargetResult& r) {
    if (r.status == core::TargetStatus::kRejected) {
      ++rejected_commands_;
      NODELET_WARN_THROTTLE(1.0, "Simulator: %s/command rejected, previous trajectory kept: %s",
                            controller.c_str(), r.message.c_str());
    } else if (r.status == core::TargetStatus::kClamped) {
      NODELET_WARN_THROTTLE(1.0, "Simulator: %s/command: %s", controller.c_str(),
                            r.message.c_str());
    }
  }

  /**
   * @brief drill_guard/enable: the drivers' input of the drill guard, taken at the current
   *        step (under the lockstep the monitor publishes it before it answers the step, so
   *        the step it is taken at is the one it was sent in).
   */
  void onDriveEnable(const std_msgs::Bool::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    sim_->onDriveEnable(msg->data);
  }

  /** @brief spindle/command: rad/s (REP 103); every message feeds the driver's watchdog. */
  void onSpindle(const std_msgs::Float64::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const double rpm = core::rpmFromRadPerSec(msg->data);
    if (lockstep_) {
      // A keepalive takes the command path without a jitter draw (the engine's rule).
      const double t = sim_->time();
      pending_.push_back(
          {t + command_transport_.spindleDelay(t, rpm), std::nullopt, rpm, "", std::nullopt});
      return;
    }
    reportSpindle(sim_->commandSpindle(rpm));
  }

  void reportSpindle(const core::TargetResult& r) {
    if (r.status == core::TargetStatus::kRejected) {
      NODELET_WARN_THROTTLE(1.0, "Simulator: spindle/command rejected, speed kept: %s",
                            r.message.c_str());
    } else if (r.status == core::TargetStatus::kClamped) {
      NODELET_WARN_THROTTLE(1.0, "Simulator: spindle/command clamped: %s", r.message.c_str());
    }
  }

  /** @brief simulator/resume: ends the hold at the trial's start (nothing else to do without
   *         one). */
  bool onResume(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      response.success = true;
      response.message = hold_at_ ? (held_ ? "resumed at the trial's start"
                                           : "the hold at the trial's start is cancelled")
                                  : "no hold: sim time was running";
      hold_at_.reset();
    }
    command_cv_.notify_all();
    return true;
  }

  bool onReset(ResetSimulation::Request& req, ResetSimulation::Response& res) {
    // The distributions are re-read at every reset, so that a campaign (or a user with
    // `rosparam set`) can change them between trials; a bad value refuses the reset.
    SimulatorNodeParams distribution;
    std::optional<core::BoneMotionModel> bone_motion;
    try {
      distribution = loadSimulatorParams(getPrivateNodeHandle());
      bone_motion = loadBoneMotionModel(distribution, ParamLoader(getPrivateNodeHandle()));
    } catch (const std::exception& e) {
      res.success = false;
      res.message = std::string(e.what()) + "; nothing was reset";
      return true;
    }
    // An explicit specimen: the given thicknesses with no spread.
    const std::string refused = applySpecimenRequest(req, &distribution.sim.specimen);
    if (!refused.empty()) {
      res.success = false;
      res.message = refused + "; nothing was reset";
      return true;
    }
    const std::uint64_t grid_ns = 100000000ULL;
    if (!req.time_zero.isZero() && req.time_zero.toNSec() % grid_ns != 0) {
      res.success = false;
      res.message = "time_zero must be a multiple of 0.1 s (got " +
                    std::to_string(req.time_zero.toSec()) + " s); nothing was reset";
      return true;
    }
    if (req.hold_at_trial_start &&
        !(std::isfinite(req.pre_trial_s) && req.pre_trial_s >= 0.0 && req.pre_trial_s <= 60.0)) {
      res.success = false;
      res.message = "pre_trial_s must be in [0, 60] s (got " + std::to_string(req.pre_trial_s) +
                    "); nothing was reset";
      return true;
    }
    // A new simulation, as the closed-loop engine builds one for every trial: sim time, the
    // breathing, the tracker's phase and the physics all start again from the seed. Stamps go on
    // from the present: the new trial's time 0 is the requested time_zero when it is ahead, else
    // the next multiple of 0.1 s (either way on the 0.1 s grid, so that the periodic checks of
    // the nodes fall on the same steps as in the engine). The nodes take the jump as the gap
    // between two trials (the planner's start_trial resets the recognizer and the monitor).
    std::unique_ptr<core::DrillingSimulation> fresh;
    try {
      fresh = std::make_unique<core::DrillingSimulation>(urdf_xml_, distribution.sim, req.seed);
      fresh->setBoneMotionModel(bone_motion);
      fresh->reset(req.seed, req.moving_bone);
    } catch (const std::exception& e) {
      res.success = false;
      res.message = std::string("reset failed: ") + e.what() + "; nothing was reset";
      return true;
    }
    std::unique_lock<std::mutex> lock(mutex_);
    const std::uint64_t present_ns = stampOf(sim_->time()).toNSec();
    const std::uint64_t next_ns = (present_ns / grid_ns + 1) * grid_ns;
    const std::uint64_t zero_ns =
        req.time_zero.toNSec() > present_ns ? req.time_zero.toNSec() : next_ns;
    if (!req.time_zero.isZero() && zero_ns != req.time_zero.toNSec()) {
      NODELET_WARN(
          "Simulator: reset: time_zero %.1f s is not ahead of the present %.3f s; the "
          "trial starts at %.1f s instead",
          req.time_zero.toSec(), present_ns * 1e-9, next_ns * 1e-9);
    }
    // The drivers are the same across specimens: an enable they hold carries over.
    if (!sim_->drivesHalted()) fresh->onDriveEnable(true);
    sim_ = std::move(fresh);
    time_offset_ = static_cast<double>(zero_ns) * 1e-9;
    restart_pacing_ = true;
    streaming_ = false;  // an aborted trial's phase does not hold the next one's time
    wait_given_up_ = false;
    pending_amplitude_.reset();
    pending_.clear();  // the last trial's commands do not drive this one
    command_transport_ = core::CommandTransport(distribution.command_delay_s,
                                                distribution.command_jitter_s, req.seed);
    spindle_watchdog_trips_ = 0;
    drive_guard_trips_ = 0;
    delayed_markers_.setDelay(distribution.tracker_delay_s);
    lockstep_every_step_ = distribution.lockstep_every_step;
    delayed_markers_.clear();
    delayed_flow_.clear();
    last_breath_index_ = -1;
    last_settings_msg_ = VentilatorSettings();  // the new breathing is announced
    if (lockstep_ && lockstep_steps_ + lockstep_skipped_ > 0) {
      NODELET_INFO(
          "Simulator: the last trial ran %lu steps under the lockstep, %lu of them "
          "waiting for the participants",
          static_cast<unsigned long>(lockstep_steps_ + lockstep_skipped_),
          static_cast<unsigned long>(lockstep_steps_));
    }
    clearTransportCounters();
    hold_at_.reset();
    held_ = false;  // the new simulation's hold (if any) is still ahead
    ++reset_generation_;
    if (req.hold_at_trial_start) {
      const double breath_s = 60.0 / sim_->trialConditions().ventilator_rate_bpm;
      hold_at_ = core::trialStartTime(req.seed, sim_->time(), req.pre_trial_s, breath_s, true);
      res.trial_start = stampOf(*hold_at_);
    }
    res.reset_time = stampOf(sim_->time());
    command_cv_.notify_all();
    res.success = true;
    res.message = resetSummary(*sim_, req, bone_motion);
    fillResetResponse(*sim_, &res);
    publishGroundTruth(sim_->time());
    publishPlan(sim_->time());
    return true;
  }

  std::mutex mutex_;
  std::condition_variable command_cv_;    ///< a trajectory, a planner phase, a hold or a resume
  std::string urdf_xml_;                  ///< the workcell, for the simulation of each reset
  bool restart_pacing_ = false;           ///< a reset restarted sim time
  std::optional<double> hold_at_;         ///< the trial's start drawn by the reset (sim time)
  bool held_ = false;                     ///< sim time stands at hold_at_
  std::uint64_t reset_generation_ = 0;    ///< counts resets (a hold ends with its simulation)
  bool lockstep_ = false;                 ///< /use_sim_lockstep
  bool follow_joint_trajectory_ = false;  ///< ~follow_joint_trajectory
  std::unique_ptr<TrajectoryActionServer> actions_;  ///< its servers (else null)
  double lockstep_timeout_s_ = 5.0;
  core::CommandTransport command_transport_;  ///< under the lockstep (set at every reset)
  /// tracker/marker_pose held back ~tracker_delay_s (re-read at every reset)
  core::DelayLine<geometry_msgs::PoseStamped> delayed_markers_;
  core::DelayLine<AirwayFlow> delayed_flow_;         ///< breath_sensor/flow, its latency
  std::vector<PendingCommand> pending_;              ///< under the lockstep, for the next step
  std::atomic<std::uint32_t> lockstep_timeouts_{0};  ///< counted on the stepping thread
  std::mutex ack_mutex_;
  std::condition_variable ack_cv_;
  /** @brief A lockstep participant as its latest answer says. */
  struct Participant {
    ros::Time answered;   ///< the latest step it answered
    ros::Time next_step;  ///< the next step it needs (zero: every step)
  };
  std::map<std::string, Participant> participants_;
  bool lockstep_every_step_ = false;    ///< ~lockstep_every_step
  bool sync_next_ = true;               ///< the next step waits for the participants
  std::uint64_t lockstep_steps_ = 0;    ///< steps that waited for the participants
  std::uint64_t lockstep_skipped_ = 0;  ///< steps run without waiting
  ros::CallbackQueue lockstep_queue_;   ///< commands, answers and resume under the lockstep
  ros::CallbackQueue trial_queue_;      ///< reset, start_trial, resume
  std::unique_ptr<ros::AsyncSpinner> trial_spinner_;
  std::unique_ptr<ros::AsyncSpinner> lockstep_spinner_;
  ros::Subscriber ack_sub_;
  ros::Publisher step_pub_;
  ros::ServiceServer resume_srv_;
  std::unique_ptr<core::DrillingSimulation> sim_;
  double command_wait_s_ = 1.0;
  bool streaming_ = false;      ///< the planner streams trajectories (under mutex_)
  bool wait_given_up_ = false;  ///< a wait ran out; no other until a trajectory or phase comes
  std::uint32_t late_commands_ = 0;
  std::uint32_t rejected_commands_ = 0;  ///< trajectories a controller refused this trial
  double max_command_lateness_s_ = 0.0;
  std::uint32_t command_waits_ = 0;
  double command_wait_wall_s_ = 0.0;
  std::uint32_t command_wait_expired_ = 0;
  std::atomic<bool> running_{false};
  std::thread thread_;
  double real_time_factor_ = 1.0;
  bool publish_clock_ = true;
  double time_offset_ = 0.0;
  std::string tracker_tf_frame_;           ///< ~tracker_tf_frame ("" = tracker/marker_pose only)
  std::set<std::string> floating_frames_;  ///< ~publish_joint_frames false: the only ones sent
  int spindle_watchdog_trips_ = 0;         ///< the driver watchdog's stops reported so far
  int drive_guard_trips_ = 0;              ///< the drill guard's halts reported so far
  int clock_period_steps_ = 1;
  core::StreamSchedule streams_;  ///< which streams a step publishes (the engine's rule)
  std::vector<ros::Publisher> controller_state_pubs_;  ///< <controller>/state
  long last_breath_index_ = -1;
  VentilatorSettings last_settings_msg_;
  std::optional<double> pending_amplitude_;  // set_patient_amplitude, from the next breath
  long amplitude_breath_ = 0;
  ros::ServiceServer set_ventilator_srv_, set_amplitude_srv_, stall_joint_srv_;
  ros::ServiceServer abort_controller_srv_;
  ros::Publisher tidal_volume_pub_;
  ros::Publisher flow_pub_;
  ros::Publisher ventilator_settings_pub_;
  ros::Publisher clock_pub_;
  ros::Publisher joint_state_pub_;
  ros::Publisher wrench_pub_;
  ros::Publisher marker_pub_;
  ros::Publisher ground_truth_pub_;
  ros::Publisher plan_pub_;  ///< drilling_plan, latched
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
  std::unique_ptr<tf2_ros::StaticTransformBroadcaster> static_broadcaster_;
  std::vector<ros::Subscriber> trajectory_subs_;  ///< one per controller
  ros::Subscriber spindle_sub_;
  ros::Subscriber enable_sub_;
  ros::Subscriber tare_sub_;
  ros::Publisher tare_result_pub_;
  ros::Subscriber status_sub_;
  ros::ServiceServer reset_srv_;
  ros::ServiceServer start_trial_srv_;
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::SimulatorNodelet, nodelet::Nodelet)
