/**
 * @file simulator_outputs.hpp
 * @brief The Simulator's outputs (doc/nodes.md, "pedicle_drilling/Simulator"): its publishers
 *        and tf broadcasters, and a step's streams (core::StreamSchedule's choice) as messages,
 *        with the tracker's and the breath sensor's latencies (core::DelayLine); the state the
 *        nodelet's callbacks share with its stepping thread (SimulatorShared). The nodelet keeps
 *        the threads; the services are SimulatorServices', the command path SimulatorCommands'.
 */
#pragma once

#include <geometry_msgs/PoseStamped.h>
#include <ros/ros.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>

#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "pedicle_drilling/AirwayFlow.h"
#include "pedicle_drilling/GroundTruth.h"
#include "pedicle_drilling/VentilatorSettings.h"
#include "pedicle_drilling/core/sim/bench_commands.hpp"
#include "pedicle_drilling/core/sim/bench_session.hpp"
#include "pedicle_drilling/core/sim/drilling_simulation.hpp"
#include "pedicle_drilling/core/sim/simulated_bench.hpp"
#include "pedicle_drilling/core/sim/stream_schedule.hpp"
#include "pedicle_drilling/ros/node_params.hpp"

namespace pedicle_drilling {

/** @brief The child links of the URDF's floating joints (robot_state_publisher skips them).
 *  @throws std::runtime_error when the URDF does not parse. */
std::set<std::string> floatingChildren(const std::string& urdf_xml);

/** @brief The Simulator's publishers and the messages of its steps. Not thread-safe: the
 *         nodelet calls it under its simulation's mutex. */
class SimulatorOutputs {
 public:
  /**
   * @brief Advertises every output of @p params on @p nh for @p sim (its controllers, its
   *        breath sensor), latches the plan (and the ventilator's settings when the tidal
   *        volume is on), sends the static frames. @p floating: the frames robot_state_publisher
   *        does not publish (~publish_joint_frames false; empty: every frame).
   */
  void advertise(ros::NodeHandle& nh, const SimulatorNodeParams& params, bool lockstep,
                 bool tidal_volume, const core::DrillingSimulation& sim,
                 std::set<std::string> floating);

  /** @brief The ROS time of sim time @p sim_time. */
  ros::Time stampOf(double sim_time) const { return ros::Time(sim_time + time_offset_); }
  /** @brief ROS time minus sim time [s]. */
  double timeOffset() const { return time_offset_; }

  /**
   * @brief A new trial (a reset): sim time 0 is ROS time @p time_offset; the messages held back
   *        are dropped, the tracker's latency is @p tracker_delay_s, the new breathing is
   *        announced.
   */
  void resetTrial(double time_offset, double tracker_delay_s);

  /** @brief What publishStep published. */
  struct StepOutput {
    bool published = false;                ///< a stream a lockstep participant may read
    std::optional<core::TareResult> tare;  ///< the sensor driver's tare result, published
  };
  /**
   * @brief The streams @p due of @p step (in a fixed order: a participant's queue is FIFO),
   *        the tracker samples and breath-sensor samples whose latency ran out;
   *        @p ground_truth publishes the ground truth when due.
   */
  StepOutput publishStep(const core::StreamsDue& due, const core::SimulationStep& step,
                         core::DrillingSimulation& sim, const std::function<void()>& ground_truth);
  /** @brief The step's stamp on /clock. */
  void publishClock(const ros::Time& stamp);
  /** @brief simulator/step: the lockstep's step at @p stamp (after the step's messages). */
  void publishLockstepStep(const ros::Time& stamp);
  /** @brief A delayed tracker sample is due by @p t (its step waits for the participants). */
  bool markerDue(double t) const { return delayed_markers_.due(t); }

  /** @brief simulator/ground_truth at @p t with the trial's transport counters. */
  void publishGroundTruth(const core::DrillingSimulation& sim, const core::BenchCounters& counters,
                          double t);
  /** @brief drilling_plan: the mounted specimen's plan (latched), stamped @p t. */
  void publishPlan(const core::DrillingSimulation& sim, double t);
  /** @brief ft_sensor/tare_result, stamped @p t. */
  void publishTareResult(const core::TareResult& result, double t);

 private:
  void publishWrench(const core::SimulationStep& step);
  void publishTidalVolume(const core::DrillingSimulation& sim, double t);
  void publishControllerStates(const core::DrillingSimulation& sim, double t);
  void publishTf(const core::DrillingSimulation& sim, double t);
  void publishFlow(const core::DrillingSimulation& sim, double t);
  void publishMarker(core::DrillingSimulation& sim, double t);
  void sendMarker(const geometry_msgs::PoseStamped& m);

  double time_offset_ = 0.0;
  std::string tracker_tf_frame_;           ///< ~tracker_tf_frame ("" = tracker/marker_pose only)
  std::set<std::string> floating_frames_;  ///< ~publish_joint_frames false: the only ones sent
  /// tracker/marker_pose held back ~tracker_delay_s (re-read at every reset)
  core::DelayLine<geometry_msgs::PoseStamped> delayed_markers_;
  core::DelayLine<AirwayFlow> delayed_flow_;  ///< breath_sensor/flow, its latency
  core::BreathWatch breaths_;                 ///< the settings stream is checked at each breath
  VentilatorSettings last_settings_msg_;
  ros::Publisher clock_pub_, step_pub_, joint_state_pub_, wrench_pub_, tare_result_pub_;
  ros::Publisher marker_pub_, ground_truth_pub_, flow_pub_, plan_pub_;
  ros::Publisher tidal_volume_pub_, ventilator_settings_pub_;
  std::vector<ros::Publisher> controller_state_pubs_;  ///< <controller>/state
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
  std::unique_ptr<tf2_ros::StaticTransformBroadcaster> static_broadcaster_;
};

/**
 * @brief What the Simulator nodelet's callbacks (SimulatorServices, SimulatorCommands) share with
 *        its stepping thread; the nodelet owns each of them.
 */
struct SimulatorShared {
  std::string name;               ///< the nodelet's name: the logger of their messages
  std::mutex& mutex;              ///< guards the bench and the outputs
  core::SimulatedBench& bench;    ///< the simulation and its trial
  SimulatorOutputs& out;          ///< the publishers and the time offset
  std::function<bool()> running;  ///< false: the nodelet shuts down (waits end)
};

/** @brief simulator/ground_truth at @p t, and a warning at each new trip of the drivers; under
 *         @p shared's mutex. */
void publishGroundTruth(const SimulatorShared& shared, double t);

}  // namespace pedicle_drilling
