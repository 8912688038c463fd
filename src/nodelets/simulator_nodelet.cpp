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
 * rules), spindle/command (std_msgs/Float64, rad/s); service simulator/reset (ResetSimulation).
 *
 * The nodelet keeps its lifecycle: the parameters, the stepping thread, the lockstep's waits and
 * the callback queues. What is not ROS glue lives in the core: the simulation with its trial
 * (core::SimulatedBench), the trial's hold and phases (core::BenchTrial), the commands in transit
 * and the transport counters (core::BenchCommandQueue, core::BenchCounters), the lockstep's
 * participants (core::LockstepRoster), the streams of a step (core::StreamSchedule). The ROS glue
 * lives in src/ros: the messages of a step and the ground truth are SimulatorOutputs' (with the
 * state the callbacks share, SimulatorShared), the services SimulatorServices', the command
 * topics, the planner's phase, the lockstep's answers and the action servers SimulatorCommands',
 * the parameters and the message conversions simulator_conversions'.
 */
#include <nodelet/nodelet.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <pluginlib/class_list_macros.hpp>

#include <atomic>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "pedicle_drilling/core/sim/closed_loop_engine.hpp"
#include "pedicle_drilling/core/sim/lockstep_roster.hpp"
#include "pedicle_drilling/core/sim/simulated_bench.hpp"
#include "pedicle_drilling/core/sim/stream_schedule.hpp"
#include "pedicle_drilling/ros/lockstep.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/simulator_commands.hpp"
#include "pedicle_drilling/ros/simulator_conversions.hpp"
#include "pedicle_drilling/ros/simulator_outputs.hpp"
#include "pedicle_drilling/ros/simulator_services.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"

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
    // Its thread ends: no goal reaches the simulation after this.
    if (commands_) commands_->shutdownActions();
  }

 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    SimulatorNodeParams params;
    std::set<std::string> floating;
    std::string urdf_xml;  // a reset builds a new simulation from it
    try {
      const ParamLoader loader(getPrivateNodeHandle());
      params = loadSimulatorParams(getPrivateNodeHandle());
      std::unique_ptr<core::DrillingSimulation> sim = makeSimulation(params, loader);
      if (params.sim.drive_guard_timeout_s == 0.0) {
        NODELET_WARN(
            "Simulator: ~drive_guard_timeout_s 0: the simulated drivers take no drill guard "
            "input (drill_guard/enable); only for a simulator with no SafetyMonitor on the graph");
      }
      urdf_xml = loader.readFile("urdf_path", params.urdf_path);
      lockstep_ = useSimLockstep();
      if (params.follow_joint_trajectory && lockstep_) {
        throw std::invalid_argument(
            "parameter '" + getPrivateNodeHandle().resolveName("follow_joint_trajectory") +
            "' true is not available under the lockstep (/use_sim_lockstep): an action's goals "
            "and results are not steps");
      }
      if (!params.publish_joint_frames) floating = floatingChildren(urdf_xml);
      // Re-read at every reset; checked here too, so that a bad value refuses the start.
      loadBoneMotionModel(params, loader);
      bench_ = std::make_unique<core::SimulatedBench>(
          std::move(sim), core::StreamSchedule(streamRates(params)), lockstep_,
          benchTransport(params, static_cast<std::uint64_t>(params.seed)),
          simulatorReports(getName()));
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
    registerCallbacks(nh, std::move(urdf_xml));
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

  core::DrillingSimulation& sim() { return bench_->sim(); }

  /** @brief onInit's subscriptions, services and action servers (their callbacks may run at
   *         once); a reset builds its simulation from @p urdf_xml. */
  void registerCallbacks(ros::NodeHandle& nh, std::string urdf_xml) {
    // From here on, callbacks: the nodelet manager runs them while onInit still runs (nodelet
    // 1.10.2), on its threads (this nodelet's queue) and on this nodelet's own queues once
    // their spinners start, at the end. They touch bench_ under mutex_ only; onInit no longer
    // reads it.
    std::vector<std::string> controllers;
    for (const core::ControllerSpec& c : sim().controllers()) controllers.push_back(c.name);
    shared_ = std::make_unique<SimulatorShared>(SimulatorShared{
        getName(), mutex_, *bench_, out_, [this] { return running_ && ros::ok(); }});
    // Under the lockstep, the commands, the participants' answers and simulator/resume share
    // one queue and its own thread: a participant publishes its commands before its answer, so
    // a command is handled before the answer that lets the simulator step (one nodelet manager:
    // both are queued in publishing order), and the planner's first commands before the resume
    // that ends the hold. The stepping thread waits for them whatever this nodelet's queue is
    // doing.
    ros::NodeHandle cmd(nh);
    if (lockstep_) cmd.setCallbackQueue(&lockstep_queue_);
    // The trial services have a queue and threads of their own: start_trial waits for the hold,
    // a reset builds a new simulation, and a nodelet must not hold the manager's worker threads
    // (the other nodelets' callbacks wait behind them).
    ros::NodeHandle trial_nh(nh);
    trial_nh.setCallbackQueue(&trial_queue_);
    commands_ = std::make_unique<SimulatorCommands>(*shared_, lockstep_, *gate_);
    commands_->subscribe(nh, cmd, controllers);
    SimulatorServices::Hooks hooks;
    hooks.reset = [this](const SimulatorNodeParams& p) {
      params_.lockstep_every_step = p.lockstep_every_step;
    };
    hooks.aborted = [this](const std::string& controller, const std::string& why) {
      commands_->abortGoal(controller, why);
    };
    services_ = std::make_unique<SimulatorServices>(
        *shared_, getPrivateNodeHandle(), std::move(urdf_xml), lockstep_, std::move(hooks));
    services_->advertise(nh, cmd, trial_nh);
    if (params_.follow_joint_trajectory) commands_->advertiseActions(nh, controllers);
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
        const bool waited =
            waitForCommand(lock) ||
            bench_->holdAtTrialStart(
                lock, [this] { publishGroundTruth(*shared_, sim().time()); }, running);
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
        out_.publishStep(s.due, s.step, sim(), [this, now] { publishGroundTruth(*shared_, now); });
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

  /** @brief The sensor driver's tare result, published after the sample that completed it. */
  void logTare(const core::TareResult& r) {
    if (r.success) {
      NODELET_INFO("Simulator: F/T %s", r.message.c_str());
    } else {
      NODELET_WARN("Simulator: F/T %s", r.message.c_str());
    }
  }

  std::mutex mutex_;  ///< guards everything below but the lockstep's gate
  std::unique_ptr<core::SimulatedBench> bench_;  ///< the simulation and its trial
  SimulatorNodeParams params_;  ///< as loaded (lockstep_every_step re-read at every reset)
  bool lockstep_ = false;       ///< /use_sim_lockstep
  SimulatorOutputs out_;        ///< the publishers and the time offset
  bool sync_next_ = true;       ///< the next step waits for the participants
  std::unique_ptr<core::LockstepGate> gate_;  ///< the lockstep's participants
  std::atomic<bool> running_{false};
  std::thread thread_;
  ros::CallbackQueue lockstep_queue_;  ///< commands, answers and resume under the lockstep
  ros::CallbackQueue trial_queue_;     ///< reset, start_trial
  std::unique_ptr<ros::AsyncSpinner> trial_spinner_;
  std::unique_ptr<ros::AsyncSpinner> lockstep_spinner_;
  std::unique_ptr<SimulatorShared> shared_;      ///< what the callbacks share with loop()
  std::unique_ptr<SimulatorCommands> commands_;  ///< the command path, the action servers
  std::unique_ptr<SimulatorServices> services_;  ///< the simulator/ services
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::SimulatorNodelet, nodelet::Nodelet)
