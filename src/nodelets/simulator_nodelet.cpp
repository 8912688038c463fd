/**
 * @file simulator_nodelet.cpp
 * @brief pedicle_drilling/Simulator: the simulated workcell (core::DrillingSimulation) behind
 *        the ROS interfaces a real setup would have. A dedicated thread steps the 1 kHz physics,
 *        owns /clock (when ~publish_clock) and paces the simulation at ~real_time_factor.
 *
 * Interfaces (see README "pedicle_drilling/Simulator"): publishes /clock, joint_states,
 * ft_sensor/wrench (at ~force_sensor_rate_hz, 1000/3 Hz), tf + tf_static, tracker/marker_pose (8
 * Hz), simulator/ground_truth; subscribes arm_controller/command (trajectory_msgs/JointTrajectory),
 * spindle/command (std_msgs/Float64, rpm); service simulator/reset (ResetSimulation).
 */
#include <geometry_msgs/PoseStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <std_msgs/Float64.h>
#include <std_srvs/Trigger.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <trajectory_msgs/JointTrajectory.h>
#include <pluginlib/class_list_macros.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "pedicle_drilling/ResetSimulation.h"
#include "pedicle_drilling/SetPatientAmplitude.h"
#include "pedicle_drilling/SetVentilatorSettings.h"
#include "pedicle_drilling/TrialStatus.h"
#include "pedicle_drilling/VentilatorSettings.h"
#include "pedicle_drilling/core/sim/drilling_simulation.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/simulator_conversions.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"
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
    command_cv_.notify_all();  // a loop waiting for a trajectory ends now
    if (thread_.joinable()) thread_.join();
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
      // Re-read at every reset; checked here too, so that a bad value refuses the start.
      loadBoneMotionModel(params, loader);
      urdf_path = params.urdf_path;
      real_time_factor_ = params.real_time_factor;
      publish_clock_ = params.publish_clock;
      clock_period_steps_ = params.clock_period_ms;
      command_wait_s_ = params.command_wait_s;
      const auto period = [](const std::string& name, double hz) {
        return core::streamPeriodSteps(1000.0, hz, name);
      };
      joint_state_period_ = period("joint_state_rate_hz", params.joint_state_rate_hz);
      tf_period_ = period("tf_rate_hz", params.tf_rate_hz);
      ground_truth_period_ = period("ground_truth_rate_hz", params.ground_truth_rate_hz);
      tracker_period_ = period("tracker_rate_hz", params.tracker_rate_hz);
      // The simulated ventilator is the device that drives the patient: it publishes what the
      // Ventilator nodelet publishes on hardware-free setups (0 disables it).
      const double tv_rate = params.tidal_volume_rate_hz;
      tidal_volume_period_ =
          tv_rate > 0.0 ? core::streamPeriodSteps(1000.0, tv_rate, "tidal_volume_rate_hz") : 0;
    } catch (const std::exception& e) {
      // Safe state: nothing is advertised, the error names the parameter or the file.
      failStartup(getName(), e.what());  // throws: the load fails
    }
    if (publish_clock_) {
      clock_pub_ = nh.advertise<rosgraph_msgs::Clock>("/clock", 10);
    } else {
      time_offset_ = ros::Time::now().toSec();
    }
    joint_state_pub_ = nh.advertise<sensor_msgs::JointState>("joint_states", 100);
    wrench_pub_ = nh.advertise<geometry_msgs::WrenchStamped>("ft_sensor/wrench", 2000);
    marker_pub_ = nh.advertise<geometry_msgs::PoseStamped>("tracker/marker_pose", 20);
    ground_truth_pub_ = nh.advertise<GroundTruth>("simulator/ground_truth", 200);
    if (tidal_volume_period_ > 0) {
      tidal_volume_pub_ = nh.advertise<TidalVolume>("tidal_volume", 200);
      ventilator_settings_pub_ = nh.advertise<VentilatorSettings>("ventilator/settings", 1, true);
      ventilator_settings_pub_.publish(toMsg(sim_->ventilator().model().settings()));
    }
    tf_broadcaster_ = std::make_unique<tf2_ros::TransformBroadcaster>();
    static_broadcaster_ = std::make_unique<tf2_ros::StaticTransformBroadcaster>();
    trajectory_sub_ =
        nh.subscribe("arm_controller/command", 10, &SimulatorNodelet::onTrajectory, this);
    spindle_sub_ = nh.subscribe("spindle/command", 10, &SimulatorNodelet::onSpindle, this);
    // The planner's phase says when trajectories stream (drilling, stopped, retreating): then
    // sim time does not run past the last one received (waitForCommand).
    status_sub_ = nh.subscribe("compensation/status", 10, &SimulatorNodelet::onPlannerStatus, this);
    reset_srv_ = nh.advertiseService("simulator/reset", &SimulatorNodelet::onReset, this);
    start_trial_srv_ =
        nh.advertiseService("simulator/start_trial", &SimulatorNodelet::onStartTrial, this);
    set_ventilator_srv_ = nh.advertiseService("simulator/set_ventilator_settings",
                                              &SimulatorNodelet::onSetVentilatorSettings, this);
    set_amplitude_srv_ = nh.advertiseService("simulator/set_patient_amplitude",
                                             &SimulatorNodelet::onSetPatientAmplitude, this);
    publishStaticTransforms();
    NODELET_INFO(
        "Simulator: workcell '%s', arm at %.0f Hz, physics at 1 kHz, real-time "
        "factor %s, %s /clock",
        urdf_path.c_str(), sim_->params().arm_rate_hz,
        real_time_factor_ > 0.0 ? std::to_string(real_time_factor_).c_str() : "max",
        publish_clock_ ? "publishing" : "not publishing");
    running_ = true;
    thread_ = std::thread(&SimulatorNodelet::loop, this);
  }

  ros::Time stampOf(double sim_time) const { return ros::Time(sim_time + time_offset_); }

  void publishStaticTransforms() {
    static_broadcaster_->sendTransform(toMsg(sim_->frameTransforms(true), stampOf(0.0)));
  }

  void loop() {
    using Clock = std::chrono::steady_clock;
    const Clock::time_point wall0 = Clock::now();
    double sim0 = 0.0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      sim0 = sim_->time();
    }
    std::uint64_t n = 0;
    Clock::time_point pace_wall0 = wall0;
    while (running_ && ros::ok()) {
      double t = 0.0;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        if (waitForCommand(&lock)) {
          // Machine load changes wall time, not the trial: the pacing restarts from here
          // instead of catching up flat out.
          pace_wall0 = Clock::now();
          sim0 = sim_->time();
        }
        const core::SimulationStep step = sim_->stepOnce();
        t = step.time_s;
        if (pending_amplitude_ && sim_->ventilator().breathIndex() != amplitude_breath_) {
          sim_->setPatientAmplitudeFactor(*pending_amplitude_);  // from this breath's start
          NODELET_WARN("Simulator: the patient's AP displacement x %.3f from now",
                       *pending_amplitude_);
          pending_amplitude_.reset();
        }
        ++n;
        if (step.force_sampled) publishWrench(step);
        if (n % joint_state_period_ == 0) publishJointStates(t);
        if (n % tf_period_ == 0) publishTf(t);
        if (n % ground_truth_period_ == 0 || step.layer_changed) publishGroundTruth(t);
        if (sim_->trackerDue(tracker_period_)) publishMarker(t);
        if (tidal_volume_period_ > 0 && n % tidal_volume_period_ == 0) publishTidalVolume(t);
      }
      if (publish_clock_ && n % clock_period_steps_ == 0) {
        rosgraph_msgs::ClockPtr c = boost::make_shared<rosgraph_msgs::Clock>();
        c->clock = stampOf(t);
        clock_pub_.publish(c);
      }
      if (real_time_factor_ > 0.0) {
        const Clock::time_point due =
            pace_wall0 + std::chrono::duration_cast<Clock::duration>(
                             std::chrono::duration<double>((t - sim0) / real_time_factor_));
        // Sleep only when ahead by more than a millisecond (fewer system calls).
        if (due - Clock::now() > std::chrono::milliseconds(1)) std::this_thread::sleep_until(due);
      } else if (n % 1000 == 0) {
        std::this_thread::yield();  // as fast as possible, but let callbacks in
      }
    }
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
    if (command_wait_s_ <= 0.0 || !starved()) return false;
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

  void publishWrench(const core::SimulationStep& step) {
    if (wrench_pub_.getNumSubscribers() == 0) return;
    wrench_pub_.publish(wrenchMsg(step, stampOf(step.time_s)));
  }

  void publishTidalVolume(double t) {
    tidal_volume_pub_.publish(tidalVolumeMsg(*sim_, stampOf(t)));
    const core::BreathScheduler& ventilator = sim_->ventilator();
    if (ventilator.breathIndex() != last_breath_index_) {
      last_breath_index_ = ventilator.breathIndex();
      const VentilatorSettings settings = toMsg(ventilator.model().settings());
      if (settings != last_settings_msg_) {
        ventilator_settings_pub_.publish(settings);
        last_settings_msg_ = settings;
      }
    }
  }

  void publishJointStates(double t) { joint_state_pub_.publish(jointStateMsg(*sim_, stampOf(t))); }

  void publishTf(double t) {
    tf_broadcaster_->sendTransform(toMsg(sim_->frameTransforms(false), stampOf(t)));
  }

  void publishGroundTruth(double t) {
    GroundTruth msg = toMsg(sim_->groundTruth(), stampOf(t));
    msg.late_commands = late_commands_;
    msg.max_command_lateness_s = max_command_lateness_s_;
    msg.command_waits = command_waits_;
    msg.command_wait_wall_s = command_wait_wall_s_;
    msg.command_wait_expired = command_wait_expired_;
    ground_truth_pub_.publish(msg);
  }

  void clearTransportCounters() {
    late_commands_ = 0;
    max_command_lateness_s_ = 0.0;
    command_waits_ = 0;
    command_wait_wall_s_ = 0.0;
    command_wait_expired_ = 0;
  }

  void publishMarker(double t) {
    geometry_msgs::PoseStamped m;
    m.header.stamp = stampOf(t);
    m.header.frame_id = "tracker_camera";
    m.pose = tf2::toMsg(sim_->measureMarkerPose());
    marker_pub_.publish(m);
  }

  /**
   * @brief simulator/start_trial: ground truth measures the relative AP motion from now; a
   *        specimen already drilled is replaced by a fresh one (seed + 1), as on the bench.
   */
  bool onStartTrial(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
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

  void onTrajectory(const trajectory_msgs::JointTrajectory::ConstPtr& msg) {
    std::unique_lock<std::mutex> lock(mutex_);
    const core::TrajectoryCommand command = fromMsg(*msg, sim_->time(), time_offset_);
    // Late: its start passed before it arrived (half a physics step of rounding allowed).
    const double half_step = 0.5 / sim_->params().physics_rate_hz;
    if (std::isfinite(command.start_time_s) && command.start_time_s < sim_->time() - half_step) {
      ++late_commands_;  // a ros_control controller would start it now, as the executor does
      max_command_lateness_s_ =
          std::max(max_command_lateness_s_, sim_->time() - command.start_time_s);
    }
    const core::TargetResult r = sim_->commandTrajectory(command);
    wait_given_up_ = false;
    lock.unlock();
    command_cv_.notify_all();
    if (r.status == core::TargetStatus::kRejected) {
      NODELET_WARN_THROTTLE(1.0,
                            "Simulator: arm_controller/command rejected, previous "
                            "trajectory kept: %s",
                            r.message.c_str());
    } else if (r.status == core::TargetStatus::kClamped) {
      NODELET_WARN_THROTTLE(1.0, "Simulator: arm_controller/command clamped: %s",
                            r.message.c_str());
    }
  }

  void onSpindle(const std_msgs::Float64::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const core::TargetResult r = sim_->commandSpindle(msg->data);
    if (r.status == core::TargetStatus::kRejected) {
      NODELET_WARN_THROTTLE(1.0, "Simulator: spindle/command rejected, speed kept: %s",
                            r.message.c_str());
    } else if (r.status == core::TargetStatus::kClamped) {
      NODELET_WARN_THROTTLE(1.0, "Simulator: spindle/command clamped: %s", r.message.c_str());
    }
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
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      sim_->setTrialDistribution(distribution.sim.specimen, distribution.sim.variability);
      sim_->setBoneMotionModel(bone_motion);
      sim_->reset(req.seed, req.moving_bone);
      streaming_ = false;  // an aborted trial's phase does not hold the next one's time
      wait_given_up_ = false;
      pending_amplitude_.reset();
    } catch (const std::exception& e) {
      res.success = false;
      res.message = std::string("reset failed: ") + e.what();
      return true;
    }
    res.success = true;
    res.message = resetSummary(*sim_, req, bone_motion);
    fillResetResponse(*sim_, &res);
    publishGroundTruth(sim_->time());
    return true;
  }

  std::mutex mutex_;
  std::condition_variable command_cv_;  ///< a trajectory or a planner phase arrived
  std::unique_ptr<core::DrillingSimulation> sim_;
  double command_wait_s_ = 1.0;
  bool streaming_ = false;      ///< the planner streams trajectories (under mutex_)
  bool wait_given_up_ = false;  ///< a wait ran out; no other until a trajectory or phase comes
  std::uint32_t late_commands_ = 0;
  double max_command_lateness_s_ = 0.0;
  std::uint32_t command_waits_ = 0;
  double command_wait_wall_s_ = 0.0;
  std::uint32_t command_wait_expired_ = 0;
  std::atomic<bool> running_{false};
  std::thread thread_;
  double real_time_factor_ = 1.0;
  bool publish_clock_ = true;
  double time_offset_ = 0.0;
  int clock_period_steps_ = 1;
  std::uint64_t joint_state_period_ = 10;
  std::uint64_t tf_period_ = 10;
  std::uint64_t ground_truth_period_ = 10;
  std::uint64_t tracker_period_ = 125;
  std::uint64_t tidal_volume_period_ = 0;  // 0: the simulated ventilator publishes nothing
  long last_breath_index_ = -1;
  VentilatorSettings last_settings_msg_;
  std::optional<double> pending_amplitude_;  // set_patient_amplitude, from the next breath
  long amplitude_breath_ = 0;
  ros::ServiceServer set_ventilator_srv_, set_amplitude_srv_;
  ros::Publisher tidal_volume_pub_;
  ros::Publisher ventilator_settings_pub_;
  ros::Publisher clock_pub_;
  ros::Publisher joint_state_pub_;
  ros::Publisher wrench_pub_;
  ros::Publisher marker_pub_;
  ros::Publisher ground_truth_pub_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
  std::unique_ptr<tf2_ros::StaticTransformBroadcaster> static_broadcaster_;
  ros::Subscriber trajectory_sub_;
  ros::Subscriber spindle_sub_;
  ros::Subscriber status_sub_;
  ros::ServiceServer reset_srv_;
  ros::ServiceServer start_trial_srv_;
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::SimulatorNodelet, nodelet::Nodelet)
