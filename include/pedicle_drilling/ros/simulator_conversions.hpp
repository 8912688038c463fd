/**
 * @file simulator_conversions.hpp
 * @brief The Simulator's parameters into core::DrillingSimulationParams, its reset request into
 *        the trial distribution, and core::DrillingSimulation's state (and its specimen's
 *        drilling plan) as ROS messages.
 */
#pragma once

#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <ros/node_handle.h>
#include <sensor_msgs/JointState.h>
#include <trajectory_msgs/JointTrajectory.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "pedicle_drilling/DrillingPlan.h"
#include "pedicle_drilling/GroundTruth.h"
#include "pedicle_drilling/JointTrajectoryControllerState.h"
#include "pedicle_drilling/ResetSimulation.h"
#include "pedicle_drilling/TareRequest.h"
#include "pedicle_drilling/TareResult.h"
#include "pedicle_drilling/TidalVolume.h"
#include "pedicle_drilling/core/drilling/force_tare.hpp"
#include "pedicle_drilling/core/sim/drilling_simulation.hpp"
#include "pedicle_drilling/core/sim/simulated_bench.hpp"
#include "pedicle_drilling/core/sim/stream_schedule.hpp"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"

namespace pedicle_drilling {

/**
 * @brief Every parameter of the Simulator (doc/nodes.md), loaded once: a key under
 *        ~trial_distribution or ~ventilator that is not declared is refused too.
 * @throws ParameterError naming the parameter.
 */
SimulatorNodeParams loadSimulatorParams(const ros::NodeHandle& private_nh);

/**
 * @brief The simulation from ~urdf_path (the workcell URDF), ~seed and the parameters.
 * @throws ParameterError naming the parameter, or std::runtime_error for an unusable URDF.
 */
std::unique_ptr<core::DrillingSimulation> makeSimulation(const SimulatorNodeParams& params,
                                                         const ParamLoader& loader);

/** @brief The streams' rates (the engine's schedule); the simulated ventilator publishes what
 *         the Ventilator nodelet publishes on hardware-free setups (0 disables it). */
core::StreamRates streamRates(const SimulatorNodeParams& params);

/** @brief The command path's transport of the trial of @p seed (under the lockstep). */
core::BenchTransport benchTransport(const SimulatorNodeParams& params, std::uint64_t seed);

/**
 * @brief A JointTrajectory as the simulated controller's command: it takes over at its header
 *        stamp (zero: now), points at stamp + time_from_start; `time_offset` maps ROS time to
 *        simulation time.
 */
/** @brief A controller's state as ros_control publishes it on <name>/state. */
JointTrajectoryControllerState toMsg(const core::ControllerStateSample& state,
                                     const ros::Time& stamp);

/** @brief A controller state message in the core's form (its stamp minus @p time_offset). */
core::ControllerStateSample fromMsg(const JointTrajectoryControllerState& msg, double time_offset);

core::TrajectoryCommand fromMsg(const trajectory_msgs::JointTrajectory& msg, double now,
                                double time_offset);

/**
 * @brief ~bone_motion_model_path: "" = the virtual patient (nullopt); else the patient model
 *        YAML whose AP axis the bone plays (the paper's bench protocol).
 * @throws ParameterError naming the parameter and the file's error.
 */
std::optional<core::BoneMotionModel> loadBoneMotionModel(const SimulatorNodeParams& params,
                                                         const ParamLoader& loader);

/**
 * @brief Applies the explicit layer thicknesses of a reset request (0 = drawn) to the specimen
 *        distribution (that thickness, no spread).
 * @return "" or the reason the request is refused (naming the request field).
 */
std::string applySpecimenRequest(const ResetSimulation::Request& request,
                                 core::SpecimenDistribution* specimen);

/** @brief The reset's one-line summary for the response message (seed, volunteer, bone). */
std::string resetSummary(const core::DrillingSimulation& sim,
                         const ResetSimulation::Request& request,
                         const std::optional<core::BoneMotionModel>& bone_motion);

/** @brief The drawn specimen and trial conditions into a reset response (success untouched). */
void fillResetResponse(const core::DrillingSimulation& sim, ResetSimulation::Response* response);

/** @brief A drilling plan (the simulated planning step's, core::DrillingSimulation::imagingPlan)
 *         as drilling_plan, stamped @p stamp, header.frame_id = the plan's frame. */
DrillingPlan toMsg(const core::DrillingPlan& plan, const ros::Time& stamp);

/** @brief Ground truth at `stamp` (frame "bone"). */
GroundTruth toMsg(const core::SimulationGroundTruth& truth, const ros::Time& stamp);

/** @brief A wrench [Fx, Fy, Fz, Tx, Ty, Tz] as geometry_msgs/Wrench. */
geometry_msgs::Wrench toWrenchMsg(const Eigen::Matrix<double, 6, 1>& wrench);
/** @brief geometry_msgs/Wrench as [Fx, Fy, Fz, Tx, Ty, Tz]. */
Eigen::Matrix<double, 6, 1> fromWrenchMsg(const geometry_msgs::Wrench& msg);
/** @brief ft_sensor/tare_request as the core's (samples above 10^6 kept out of range, not
 *         wrapped: TareRequest::validate() refuses them). */
core::TareRequest fromMsg(const TareRequest& msg);
/** @brief A tare result as ft_sensor/tare_result (frame ft_sensor), stamped @p stamp. */
TareResult toMsg(const core::TareResult& result, const ros::Time& stamp);
/** @brief ft_sensor/tare_result as the core's (t: its stamp). */
core::TareResult fromMsg(const TareResult& msg);

/** @brief The measured 6-axis wrench of a step, frame "ft_sensor". */
geometry_msgs::WrenchStamped wrenchMsg(const core::SimulationStep& step, const ros::Time& stamp);

/** @brief Arm and SPMS joint states. */
sensor_msgs::JointState jointStateMsg(const core::DrillingSimulation& sim, const ros::Time& stamp);

/** @brief The simulated ventilator's tidal volume sample, frame "ventilator". */
TidalVolume tidalVolumeMsg(const core::DrillingSimulation& sim, const ros::Time& stamp);

/** @brief URDF frame transforms as tf messages stamped `stamp`. */
std::vector<geometry_msgs::TransformStamped> toMsg(const std::vector<core::FrameTransform>& frames,
                                                   const ros::Time& stamp);

}  // namespace pedicle_drilling
