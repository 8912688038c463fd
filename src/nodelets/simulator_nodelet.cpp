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
 *
 * What is not ROS glue lives in the core: the trial's hold and phases (core::BenchTrial), the
 * commands in transit and the transport counters (core::BenchCommandQueue, core::BenchCounters),
 * the lockstep's participants (core::LockstepRoster), the streams of a step
 * (core::StreamSchedule); the messages of a step are SimulatorOutputs' (src/ros).
 */
#include <nodelet/nodelet.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <std_msgs/Bool.h>
#include <std_msgs/Float64.h>
#include <std_srvs/Trigger.h>
#include <trajectory_msgs/JointTrajectory.h>
#include <pluginlib/class_list_macros.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "pedicle_drilling/AbortController.h"
#include "pedicle_drilling/ResetSimulation.h"
#include "pedicle_drilling/SetPatientAmplitude.h"
#include "pedicle_drilling/SetVentilatorSettings.h"
#include "pedicle_drilling/StallJoint.h"
#include "pedicle_drilling/StepAck.h"
#include "pedicle_drilling/TareRequest.h"
#include "pedicle_drilling/TrialStatus.h"
#include "pedicle_drilling/core/common/units.hpp"
#include "pedicle_drilling/core/sim/bench_session.hpp"
#include "pedicle_drilling/core/sim/closed_loop_engine.hpp"
#include "pedicle_drilling/core/sim/lockstep_roster.hpp"
#include "pedicle_drilling/core/sim/simulated_bench.hpp"
#include "pedicle_drilling/core/sim/stream_schedule.hpp"
#include "pedicle_drilling/ros/lockstep.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/simulator_conversions.hpp"
#include "pedicle_drilling/ros/simulator_outputs.hpp"
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
    if (bench_) bench_->notify();  // a loop waiting for a trajectory or on a hold ends now
    if (gate_) gate_->wake();      // ... or for the lockstep's answers
    if (thread_.joinable()) thread_.join();
    if (lockstep_spinner_) lockstep_spinner_->stop();
    if (trial_spinner_) trial_spinner_->stop();
    actions_.reset();  // its thread ends: no goal reaches the simulation after this
  }

 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    SimulatorNodeParams params;
    std::set<std::string> floating;
    try {
      const ParamLoader loader(getPrivateNodeHandle());
      params = loadSimulatorParams(getPrivateNodeHandle());
      std::unique_ptr<core::DrillingSimulation> sim = makeSimulation(params, loader);
      if (params.sim.drive_guard_timeout_s == 0.0) {
        NODELET_WARN(
            "Simulator: ~drive_guard_timeout_s 0: the simulated drivers take no drill guard "
            "input (drill_guard/enable); only for a simulator with no SafetyMonitor on the graph");
      }
      urdf_xml_ = loader.readFile("urdf_path", params.urdf_path);  // a reset builds a new one
      lockstep_ = useSimLockstep();
      if (params.follow_joint_trajectory && lockstep_) {
        throw std::invalid_argument(
            "parameter '" + getPrivateNodeHandle().resolveName("follow_joint_trajectory") +
            "' true is not available under the lockstep (/use_sim_lockstep): an action's goals "
            "and results are not steps");
      }
      if (!params.publish_joint_frames) floating = floatingChildren(urdf_xml_);
      // Re-read at every reset; checked here too, so that a bad value refuses the start.
      loadBoneMotionModel(params, loader);
      bench_ = std::make_unique<core::SimulatedBench>(
          std::move(sim), core::StreamSchedule(streamRates(params)), lockstep_,
          transport(params, static_cast<std::uint64_t>(params.seed)), reports());
    } catch (const std::exception& e) {
      // Safe state: nothing is advertised, the error names the parameter or the file.
      failStartup(getName(), e.what());  // throws: the load fails
    }
    params_ = params;
    gate_ = std::make_unique<core::LockstepGate>(params.lockstep_timeout_s);
    out_.advertise(nh, params, lockstep_, bench_->streams().tidalVolumeOn(), sim(),
                   std::move(floating));
    NODELET_INFO(
        "Simulator: workcell '%s', arm at %.0f Hz, physics at 1 kHz, real-time "
        "factor %s, %s /clock%s",
        params.urdf_path.c_str(), sim().params().arm_rate_hz,
        params.real_time_factor > 0.0 ? std::to_string(params.real_time_factor).c_str() : "max",
        params.publish_clock ? "publishing" : "not publishing",
        lockstep_ ? ", in lockstep with the participants of simulator/step" : "");
    registerCallbacks(nh);
    running_ = true;
    thread_ = std::thread(&SimulatorNodelet::loop, this);
    // Last, these two queues' threads: a reset served while onInit still read the simulation (a
    // campaign worker calls it as soon as the service is advertised) replaced the simulation under
    // it.
    if (lockstep_) {
      lockstep_spinner_ = std::make_unique<ros::AsyncSpinner>(1, &lockstep_queue_);
      lockstep_spinner_->start();
    }
    trial_spinner_ = std::make_unique<ros::AsyncSpinner>(2, &trial_queue_);
    trial_spinner_->start();
  }

  /** @brief The streams' rates (the engine's schedule); the simulated ventilator publishes what
   *         the Ventilator nodelet publishes on hardware-free setups (0 disables it). */
  static core::StreamRates streamRates(const SimulatorNodeParams& params) {
    core::StreamRates rates;
    rates.joint_state_hz = params.joint_state_rate_hz;
    rates.tf_hz = params.tf_rate_hz;
    rates.ground_truth_hz = params.ground_truth_rate_hz;
    rates.tracker_hz = params.tracker_rate_hz;
    rates.controller_state_hz = params.controller_state_rate_hz;
    rates.tidal_volume_hz = params.tidal_volume_rate_hz;
    return rates;
  }

  /** @brief The command path's transport of the trial of @p seed (under the lockstep). */
  static core::BenchTransport transport(const SimulatorNodeParams& params, std::uint64_t seed) {
    return {params.command_delay_s, params.command_jitter_s, seed};
  }

  /** @brief The commands' outcomes, logged (throttled) when refused or clamped. */
  core::BenchReports reports() {
    core::BenchReports r;
    r.trajectory = [this](const std::string& controller, const core::TargetResult& result) {
      if (result.status == core::TargetStatus::kRejected) {
        NODELET_WARN_THROTTLE(1.0, "Simulator: %s/command rejected, previous trajectory kept: %s",
                              controller.c_str(), result.message.c_str());
      } else if (result.status == core::TargetStatus::kClamped) {
        NODELET_WARN_THROTTLE(1.0, "Simulator: %s/command: %s", controller.c_str(),
                              result.message.c_str());
      }
    };
    r.spindle = [this](const core::TargetResult& result) {
      if (result.status == core::TargetStatus::kRejected) {
        NODELET_WARN_THROTTLE(1.0, "Simulator: spindle/command rejected, speed kept: %s",
                              result.message.c_str());
      } else if (result.status == core::TargetStatus::kClamped) {
        NODELET_WARN_THROTTLE(1.0, "Simulator: spindle/command clamped: %s",
                              result.message.c_str());
      }
    };
    return r;
  }

  core::DrillingSimulation& sim() { return bench_->sim(); }

  /** @brief onInit's subscriptions and services (their callbacks may run at once). */
  void registerCallbacks(ros::NodeHandle& nh) {
    // From here on, callbacks: the nodelet manager runs them while onInit still runs (nodelet
    // 1.10.2), on its threads (this nodelet's queue) and on this nodelet's own queues once
    // their spinners start, at the end. They touch bench_ under mutex_ only; onInit no longer
    // reads it.
    std::vector<std::string> controllers;
    for (const core::ControllerSpec& c : sim().controllers()) controllers.push_back(c.name);
    // Under the lockstep, the commands, the participants' answers and simulator/resume share
    // one queue and its own thread: a participant publishes its commands before its answer, so
    // a command is handled before the answer that lets the simulator step (one nodelet manager:
    // both are queued in publishing order), and the planner's first commands before the resume
    // that ends the hold. The stepping thread waits for them whatever this nodelet's queue is
    // doing.
    ros::NodeHandle cmd(nh);
    if (lockstep_) cmd.setCallbackQueue(&lockstep_queue_);
    // One command stream per controller (simulator parameters arm_controller, feed_controller
    // and their joints), each with ros_control's rules (controller_rules).
    for (const std::string& name : controllers) {
      subs_.push_back(cmd.subscribe<trajectory_msgs::JointTrajectory>(
          name + "/command", 10,
          [this, name](const trajectory_msgs::JointTrajectory::ConstPtr& msg) {
            onTrajectory(name, msg);
          }));
    }
    using S = SimulatorNodelet;
    subs_.push_back(cmd.subscribe("spindle/command", 10, &S::onSpindle, this));
    // The drivers' drill guard (~drive_guard_timeout_s > 0): the safety monitor's enable.
    subs_.push_back(cmd.subscribe("drill_guard/enable", 10, &S::onDriveEnable, this));
    subs_.push_back(cmd.subscribe("ft_sensor/tare_request", 10, &S::onTareRequest, this));
    services_.push_back(cmd.advertiseService("simulator/resume", &S::onResume, this));
    // The planner's phase says when trajectories stream (drilling, stopped, retreating): then
    // sim time does not run past the last one received (waitForCommand).
    subs_.push_back(nh.subscribe("compensation/status", 10, &S::onPlannerStatus, this));
    // The trial services have a queue and threads of their own: start_trial waits for the hold,
    // a reset builds a new simulation, and a nodelet must not hold the manager's worker threads
    // (the other nodelets' callbacks wait behind them).
    ros::NodeHandle trial_nh(nh);
    trial_nh.setCallbackQueue(&trial_queue_);
    services_.push_back(trial_nh.advertiseService("simulator/reset", &S::onReset, this));
    if (lockstep_) {
      subs_.push_back(cmd.subscribe("simulator/step_ack", 100, &S::onAck, this,
                                    ros::TransportHints().tcpNoDelay()));
    }
    services_.push_back(trial_nh.advertiseService("simulator/start_trial", &S::onStartTrial, this));
    services_.push_back(nh.advertiseService("simulator/set_ventilator_settings",
                                            &S::onSetVentilatorSettings, this));
    services_.push_back(
        nh.advertiseService("simulator/set_patient_amplitude", &S::onSetPatientAmplitude, this));
    services_.push_back(nh.advertiseService("simulator/stall_joint", &S::onStallJoint, this));
    services_.push_back(
        nh.advertiseService("simulator/abort_controller", &S::onAbortController, this));
    if (params_.follow_joint_trajectory) advertiseActions(nh, controllers);
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
      sim().holdController(controller);
    };
    hooks.now = [this]() {
      std::lock_guard<std::mutex> lock(mutex_);
      return sim().time();
    };
    actions_ = std::make_unique<TrajectoryActionServer>(nh, controllers, std::move(hooks));
  }

  /** @brief The stepping thread: a step at a time, paced, in lockstep when asked. */
  void loop() {
    core::BenchPacer pacer(params_.real_time_factor);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      pacer.restart(sim().time());
    }
    const auto running = [this] { return running_ && ros::ok(); };
    while (running()) {
      double t = 0.0;
      ros::Time stamp;
      bool sync = true;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        // Machine load, a hold or a reset change wall time, not the trial: the pacing restarts
        // from here instead of catching up flat out.
        const bool waited = waitForCommand(lock) ||
                            bench_->holdAtTrialStart(
                                lock, [this] { publishGroundTruth(sim().time()); }, running);
        if (bench_->trial().takeRestartPacing() || waited) {
          // After a hold, a reset or a wait, what the participants sent meanwhile (a trial's
          // start) is handled at the first step.
          sync_next_ = true;
          pacer.restart(sim().time());
        }
        if (!running()) break;
        sync = stepLocked(&t, &stamp);
      }
      if (lockstep_ && sync) {
        out_.publishLockstepStep(stamp);  // after the step's messages: FIFO queues
        if (waitForAnswers(stamp)) {
          std::lock_guard<std::mutex> lock(mutex_);
          ++bench_->counters().lockstep_timeouts;
        }
      }
      if (!pacer.pace(t) && !lockstep_ && std::llround(t * 1000.0) % 1000 == 0) {
        std::this_thread::yield();  // as fast as possible, but let callbacks in
      }
    }
  }

  /**
   * @brief One physics step under mutex_: its streams, the commands due at its end, /clock;
   *        @p t and @p stamp get its time. True: under the lockstep, the step waits for the
   *        participants (a stream any of them may read, the hold, a delayed tracker sample next,
   *        the step after a tare result or a hold, or one a participant asked for).
   */
  bool stepLocked(double* t, ros::Time* stamp) {
    const core::SimulatedBench::Step s = bench_->step();
    *t = s.step.time_s;
    *stamp = out_.stampOf(*t);
    if (s.amplitude) {
      NODELET_WARN("Simulator: the patient's AP displacement x %.3f from now", *s.amplitude);
    }
    const double now = *t;
    const SimulatorOutputs::StepOutput out =
        out_.publishStep(s.due, s.step, sim(), [this, now] { publishGroundTruth(now); });
    // The planner handles a tare result at the next step: that one is stepped too.
    const bool forced = sync_next_;
    sync_next_ = out.tare.has_value();
    if (out.tare) logTare(*out.tare);
    // A delayed tracker sample keeps its old stamp: a participant handles it at the time of
    // the last step it saw, which must be the step before it (as when every step waited).
    const double dt = 1.0 / sim().params().physics_rate_hz;
    const bool sync = out.published || bench_->trial().reachesHold(*t) || out_.markerDue(*t + dt) ||
                      forced || lockstepStepWanted(*stamp);
    core::BenchCounters& counters = bench_->counters();
    if (lockstep_) ++(sync ? counters.lockstep_steps : counters.lockstep_skipped);
    bench_->applyDue(*t);  // the commands due by the step's end, in the order received
    if (params_.publish_clock && s.n % params_.clock_period_ms == 0) out_.publishClock(*stamp);
    return sync;
  }

  /** @brief Waits until every participant answered the step (core::LockstepGate::wait); a
   *         silent one is dropped after ~lockstep_timeout_s of wall time, warned. True: one was. */
  bool waitForAnswers(const ros::Time& step) {
    const core::LockstepGate::WaitResult r =
        gate_->wait(step.toNSec(), [this] { return running_ && ros::ok(); });
    if (r.stalled_s > 0.0) {
      NODELET_WARN(
          "Simulator: this process did not run for %.1f s of wall time at the step at "
          "%.3f s (a stalled machine); the lockstep's deadline was moved by as much",
          r.stalled_s, step.toSec());
    }
    for (const std::string& name : r.dropped) {
      NODELET_WARN(
          "Simulator: lockstep participant '%s' did not answer the step at %.3f s "
          "within %.3f s of wall time (~lockstep_timeout_s): stepping on without it "
          "until it answers again",
          name.c_str(), step.toSec(), params_.lockstep_timeout_s);
    }
    return r.timed_out;
  }

  /** @brief simulator/step_ack: a participant joins with its first answer. */
  void onAck(const StepAck::ConstPtr& msg) {
    gate_->answer(msg->node, msg->stamp.toNSec(), msg->next_step.toNSec());
  }

  /** @brief Under the lockstep, whether the step at `stamp` waits for the participants for their
   *         own sake (~lockstep_every_step, or core::LockstepRoster::wantsStep). */
  bool lockstepStepWanted(const ros::Time& stamp) {
    if (!lockstep_) return false;
    return params_.lockstep_every_step || gate_->wantsStep(stamp.toNSec());
  }

  /** @brief SimulatedBench::waitForCommand (~command_wait_s), warned when it ran out. True if
   *         it waited. */
  bool waitForCommand(std::unique_lock<std::mutex>& lock) {
    const core::SimulatedBench::CommandWait wait = bench_->waitForCommand(
        lock, params_.command_wait_s, [this] { return running_ && ros::ok(); });
    if (wait == core::SimulatedBench::CommandWait::kExpired) {
      NODELET_WARN_THROTTLE(1.0,
                            "Simulator: no arm trajectory beyond t=%.3f s after %.3f s of wall "
                            "time (~command_wait_s): stepping on, the arm holds",
                            sim().armTrajectoryEnd(), params_.command_wait_s);
    }
    return wait != core::SimulatedBench::CommandWait::kNone;
  }

  void onPlannerStatus(const TrialStatus::ConstPtr& msg) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      bench_->trial().onPhase(msg->phase == TrialStatus::DRILLING ||
                              msg->phase == TrialStatus::STOPPED ||
                              msg->phase == TrialStatus::RETREATING);
    }
    bench_->notify();
  }

  /** @brief The sensor driver's tare result, published after the sample that completed it. */
  void logTare(const core::TareResult& r) {
    if (r.success) {
      NODELET_INFO("Simulator: F/T %s", r.message.c_str());
    } else {
      NODELET_WARN("Simulator: F/T %s", r.message.c_str());
    }
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
      refused.t = sim().time();
      refused.message = std::string("tare request refused: ") + e.what();
      out_.publishTareResult(refused, refused.t);
      return;
    }
    bench_->requestTare(request);
  }

  /** @brief simulator/ground_truth, and a warning at each new trip of the drivers. */
  void publishGroundTruth(double t) {
    const core::NewTrips trips = bench_->newTrips();
    if (trips.spindle_watchdog) {
      NODELET_WARN(
          "Simulator: the spindle driver heard no spindle/command for %.3f s: spindle stopped",
          sim().params().spindle_watchdog_s);
    }
    if (trips.drive_guard) {
      NODELET_ERROR(
          "Simulator: no enable from the drill guard (drill_guard/enable false, or none for "
          "%.3f s): the drivers hold and the spindle stops",
          sim().params().drive_guard_timeout_s);
    }
    out_.publishGroundTruth(sim(), bench_->counters(), t);
  }

  /**
   * @brief simulator/start_trial: ground truth measures the relative AP motion from now; a
   *        specimen already drilled is replaced by a fresh one (seed + 1), as on the bench.
   */
  bool onStartTrial(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    std::unique_lock<std::mutex> lock(mutex_);
    // The trial starts at the hold the reset drew: wait for sim time to get there.
    if (!bench_->waitForHold(lock, std::chrono::seconds(120),
                             [this] { return running_ && ros::ok(); })) {
      response.success = false;
      response.message =
          "start_trial: sim time did not reach the trial's start (the reset's "
          "hold) within 120 s of wall time";
      return true;
    }
    bool remounted = false;
    try {
      remounted = bench_->startTrial();
    } catch (const std::exception& e) {
      response.success = false;
      response.message = std::string("start_trial failed: ") + e.what();
      return true;
    }
    response.success = true;
    response.message = "trial " + std::to_string(sim().trialCount()) +
                       " started at t=" + std::to_string(sim().time()) + " s";
    if (remounted) {
      response.message += "; the specimen was drilled, a fresh one from seed " +
                          std::to_string(sim().seed()) + " is mounted (arm at home)";
      NODELET_INFO("Simulator: %s", response.message.c_str());
    }
    publishGroundTruth(sim().time());
    out_.publishPlan(sim(), sim().time());
    return true;
  }

  /** @brief The simulated ventilator takes new settings at its next breath (the settings
   *         stream tells the planner then); the identified model is not re-fit. */
  bool onSetVentilatorSettings(SetVentilatorSettings::Request& request,
                               SetVentilatorSettings::Response& response) {
    serveSetVentilatorSettings(request, response, [this](const core::VentilatorSettings& s) {
      std::lock_guard<std::mutex> lock(mutex_);
      sim().requestVentilatorSettings(s);
    });
    return true;
  }

  /** @brief The patient's AP displacement x factor from the next breath until the next reset. */
  bool onSetPatientAmplitude(SetPatientAmplitude::Request& request,
                             SetPatientAmplitude::Response& response) {
    response.message = core::checkAmplitudeFactor(request.factor);
    response.success = response.message.empty();
    if (!response.success) return true;
    std::lock_guard<std::mutex> lock(mutex_);
    bench_->setPatientAmplitude(request.factor);
    response.message = "the patient's AP displacement x " + std::to_string(request.factor) +
                       " from the next breath until the next reset";
    return true;
  }

  /** @brief simulator/abort_controller: the controller drops its trajectory and holds
   *         (core::DrillingSimulation::abortController), at the current step. */
  bool onAbortController(AbortController::Request& request, AbortController::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      sim().abortController(request.controller);
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
      sim().setJointStalled(request.joint, request.stalled);
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
    {
      std::lock_guard<std::mutex> lock(mutex_);
      bench_->commandTrajectory(controller, fromMsg(*msg, sim().time(), out_.timeOffset()));
    }
    bench_->notify();
  }

  /**
   * @brief A FollowJointTrajectory goal's trajectory for @p controller, taken now; @p end_s
   *        gets the time the controller's trajectory ends when taken.
   */
  core::TargetResult applyTrajectory(const std::string& controller,
                                     const trajectory_msgs::JointTrajectory& msg, double* end_s) {
    std::unique_lock<std::mutex> lock(mutex_);
    const core::TargetResult r =
        bench_->takeTrajectory(controller, fromMsg(msg, sim().time(), out_.timeOffset()));
    bench_->trajectoryEnd(controller, end_s);
    lock.unlock();
    bench_->notify();
    return r;
  }

  /**
   * @brief drill_guard/enable: the drivers' input of the drill guard, taken at the current
   *        step (under the lockstep the monitor publishes it before it answers the step, so
   *        the step it is taken at is the one it was sent in).
   */
  void onDriveEnable(const std_msgs::Bool::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    sim().onDriveEnable(msg->data);
  }

  /** @brief spindle/command: rad/s (REP 103); every message feeds the driver's watchdog. */
  void onSpindle(const std_msgs::Float64::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    bench_->commandSpindle(core::rpmFromRadPerSec(msg->data));
  }

  /** @brief simulator/resume: ends the hold at the trial's start (nothing else to do without
   *         one). */
  bool onResume(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      response.success = true;
      response.message = bench_->trial().resume();
    }
    bench_->notify();
    return true;
  }

  /**
   * @brief A reset's new simulation, built before the old one is touched: the distributions
   *        are re-read at every reset, so that a campaign (or a user with `rosparam set`) can
   *        change them between trials; an explicit specimen has the given thicknesses with no
   *        spread. A simulation as the closed-loop engine builds one for every trial: sim time,
   *        the breathing, the tracker's phase and the physics all start again from the seed.
   * @return "" or why the reset is refused.
   */
  std::string prepareReset(const ResetSimulation::Request& req, SimulatorNodeParams* params,
                           std::optional<core::BoneMotionModel>* bone_motion,
                           std::unique_ptr<core::DrillingSimulation>* fresh) {
    try {
      *params = loadSimulatorParams(getPrivateNodeHandle());
      *bone_motion = loadBoneMotionModel(*params, ParamLoader(getPrivateNodeHandle()));
    } catch (const std::exception& e) {
      return e.what();
    }
    std::string refused = applySpecimenRequest(req, &params->sim.specimen);
    if (refused.empty()) {
      refused =
          core::checkResetTiming(req.time_zero.toNSec(), req.hold_at_trial_start, req.pre_trial_s);
    }
    if (!refused.empty()) return refused;
    try {
      *fresh = std::make_unique<core::DrillingSimulation>(urdf_xml_, params->sim, req.seed);
      (*fresh)->setBoneMotionModel(*bone_motion);
      (*fresh)->reset(req.seed, req.moving_bone);
    } catch (const std::exception& e) {
      return std::string("reset failed: ") + e.what();
    }
    return "";
  }

  bool onReset(ResetSimulation::Request& req, ResetSimulation::Response& res) {
    SimulatorNodeParams params;
    std::optional<core::BoneMotionModel> bone_motion;
    std::unique_ptr<core::DrillingSimulation> fresh;
    const std::string refused = prepareReset(req, &params, &bone_motion, &fresh);
    if (!refused.empty()) {
      res.success = false;
      res.message = refused + "; nothing was reset";
      return true;
    }
    std::unique_lock<std::mutex> lock(mutex_);
    // Stamps go on from the present: the new trial's time 0 is the requested time_zero when it
    // is ahead, else the next multiple of 0.1 s (either way on the 0.1 s grid, so that the
    // periodic checks of the nodes fall on the same steps as in the engine). The nodes take the
    // jump as the gap between two trials (the planner's start_trial resets the recognizer and
    // the monitor).
    const std::uint64_t present_ns = out_.stampOf(sim().time()).toNSec();
    const std::uint64_t zero_ns = core::trialTimeZeroNs(present_ns, req.time_zero.toNSec());
    if (!req.time_zero.isZero() && zero_ns != req.time_zero.toNSec()) {
      NODELET_WARN(
          "Simulator: reset: time_zero %.1f s is not ahead of the present %.3f s; the "
          "trial starts at %.1f s instead",
          req.time_zero.toSec(), present_ns * 1e-9, zero_ns * 1e-9);
    }
    const core::BenchCounters& last = bench_->counters();
    if (lockstep_ && last.lockstep_steps + last.lockstep_skipped > 0) {
      NODELET_INFO(
          "Simulator: the last trial ran %lu steps under the lockstep, %lu of them "
          "waiting for the participants",
          static_cast<unsigned long>(last.lockstep_steps + last.lockstep_skipped),
          static_cast<unsigned long>(last.lockstep_steps));
    }
    const std::optional<double> hold_at = bench_->reset(
        std::move(fresh), transport(params, req.seed), req.hold_at_trial_start, req.pre_trial_s);
    out_.resetTrial(static_cast<double>(zero_ns) * 1e-9, params.tracker_delay_s);
    params_.lockstep_every_step = params.lockstep_every_step;
    if (hold_at) res.trial_start = out_.stampOf(*hold_at);
    res.reset_time = out_.stampOf(sim().time());
    bench_->notify();
    res.success = true;
    res.message = resetSummary(sim(), req, bone_motion);
    fillResetResponse(sim(), &res);
    publishGroundTruth(sim().time());
    out_.publishPlan(sim(), sim().time());
    return true;
  }

  std::mutex mutex_;  ///< guards everything below but the lockstep's gate
  std::unique_ptr<core::SimulatedBench> bench_;  ///< the simulation and its trial
  SimulatorNodeParams params_;  ///< as loaded (lockstep_every_step re-read at every reset)
  std::string urdf_xml_;        ///< the workcell, for the simulation of each reset
  bool lockstep_ = false;       ///< /use_sim_lockstep
  SimulatorOutputs out_;        ///< the publishers and the time offset
  bool sync_next_ = true;       ///< the next step waits for the participants
  std::unique_ptr<core::LockstepGate> gate_;  ///< the lockstep's participants
  std::atomic<bool> running_{false};
  std::thread thread_;
  std::unique_ptr<TrajectoryActionServer> actions_;  ///< ~follow_joint_trajectory (else null)
  ros::CallbackQueue lockstep_queue_;  ///< commands, answers and resume under the lockstep
  ros::CallbackQueue trial_queue_;     ///< reset, start_trial
  std::unique_ptr<ros::AsyncSpinner> trial_spinner_;
  std::unique_ptr<ros::AsyncSpinner> lockstep_spinner_;
  std::vector<ros::Subscriber> subs_;
  std::vector<ros::ServiceServer> services_;
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::SimulatorNodelet, nodelet::Nodelet)
