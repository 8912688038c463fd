/**
 * @file planner_conversions.hpp
 * @brief The CompensationPlanner's parameters into core::TrialSequencerParams, the trial
 *        sequencer's outputs as ROS messages, and drilling_plan as the core's plan.
 */
#pragma once

#include <geometry_msgs/PoseStamped.h>
#include <trajectory_msgs/JointTrajectory.h>

#include <ros/service_client.h>
#include <tf2_ros/buffer.h>

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "pedicle_drilling/DrillingPlan.h"
#include "pedicle_drilling/StartTrial.h"
#include "pedicle_drilling/TrialStatus.h"
#include "pedicle_drilling/core/breathing/motion_model_io.hpp"
#include "pedicle_drilling/core/control/planner_runtime.hpp"
#include "pedicle_drilling/core/control/trial_sequencer.hpp"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/plugin_loader.hpp"

namespace pedicle_drilling {

/**
 * @brief The planner's trial sequencer from its parameters, the URDF (~urdf_path or
 *        ~robot_description: the arm chain, the feed joint's limits and the drill tip of
 *        ~tip_link) and the drilling pose (~drilling_pose/<joint> for every arm joint of the
 *        URDF, required).
 * @throws ParameterError naming the parameter, or std::runtime_error.
 */
std::unique_ptr<core::TrialSequencer> makeSequencer(const CompensationPlannerNodeParams& params,
                                                    const ParamLoader& loader,
                                                    const ros::NodeHandle& nh);

/**
 * @brief The planner's runtime: its sequencer (makeSequencer), the heartbeat's period, the
 *        thrust along ~thrust_axis, the breath phase from `tidal_volume` as @p nh resolves it
 *        (at most ~breath_timeout_periods old), and ~compensator with ~compensator_params: the
 *        class is loaded and configured once here by @p compensators (a bad one fails the load),
 *        then made afresh for every trial by it (which must outlive the runtime).
 * @throws what makeSequencer throws, ParameterError naming ~compensator.
 */
std::unique_ptr<core::PlannerRuntime> makePlannerRuntime(
    const CompensationPlannerNodeParams& params, const ParamLoader& loader,
    const ros::NodeHandle& nh, CompensatorLoader* compensators);

/**
 * @brief Refuses ~trajectory_interface `action` under the simulator's lockstep (@p lockstep):
 *        its goals and results are not steps.
 * @throws std::invalid_argument naming the parameter as @p pnh resolves it.
 */
void checkTrajectoryInterface(const CompensationPlannerNodeParams& params,
                              const ros::NodeHandle& pnh, bool lockstep);

/** @brief The line the planner logs at start: patient, drill axis, latency, compensator, the
 *         depth limit's inputs and where the first controller's trajectories go. */
std::string startSummary(const CompensationPlannerNodeParams& params,
                         const core::TrialSequencer& sequencer, const std::string& patient_id,
                         const std::string& first_route);

/**
 * @brief drilling_plan as the core's plan; nullopt with the reason in @p why when it is not
 *        usable (an empty header.frame_id, or what core::DrillingPlan::check() refuses).
 */
std::optional<core::DrillingPlan> fromMsg(const DrillingPlan& msg, std::string* why);

/**
 * @brief The patient model of the file ~patient_model_path names (@p pnh's parameter as it is
 *        now, else @p default_path): read at start and again for every trial, so that a new
 *        identification (a campaign sets each trial's model there) applies to the next trial.
 * @throws std::invalid_argument when the parameter is not a string, std::runtime_error naming
 *         the file and the parameter when the file cannot be read.
 */
core::PatientModel loadPatientModel(const ros::NodeHandle& pnh, const std::string& default_path);

/**
 * @brief The sequencer's world -> tracker-frame lookup from tf (@p buffer's latest transform
 *        from @p world_frame into the frame; false while tf does not know it yet). @p buffer
 *        must outlive the lookup.
 */
core::FrameLookup tfFrameLookup(const tf2_ros::Buffer& buffer, const std::string& world_frame);

/** @brief A StartTrial request as the core's trial request (0 means the default). */
core::TrialRequest fromMsg(const StartTrial::Request& req);

/**
 * @brief drilling_plan to @p sequencer: the plan of the next trials (the latest at a trial's
 *        registration is its plan). One that is not usable (fromMsg) is no plan: the next trials
 *        are refused (fail closed) until a usable one comes.
 * @return the line to log: the plan (info), or why it was refused (error).
 */
core::SequencerLog setPlan(const DrillingPlan& msg, core::TrialSequencer* sequencer);

/** @brief One line on a plan for the log (frame, entry and depth in mm). */
std::string describe(const core::DrillingPlan& plan);

/** @brief A trial phase as the typed status message, stamped `stamp`. */
TrialStatus toMsg(core::TrialPhase phase, const ros::Time& stamp);

/** @brief A trajectory command as trajectory_msgs/JointTrajectory (header stamp = start time). */
trajectory_msgs::JointTrajectory toMsg(const core::JointTrajectoryCommand& command);

/** @brief A predicted marker pose as geometry_msgs/PoseStamped. */
geometry_msgs::PoseStamped toMsg(const core::PredictedMarker& marker);

/**
 * @brief Calls every std_srvs/Trigger service of `clients` in order (the planner's
 *        ~trial_start_services: the recognizer's and the safety monitor's ~reset, on the
 *        simulator its start_trial), waiting up to `timeout_s` for each to exist.
 * @return false with the reason in *why when one is missing, fails or refuses; the answers of
 *         those that accepted are logged.
 */
bool callTriggerChain(std::vector<ros::ServiceClient>* clients, double timeout_s, std::string* why);

/** @brief Logs the sequencer's messages at their levels, prefixed with `who`. */
void logSequencerMessages(const std::vector<core::SequencerLog>& log, const std::string& who);

}  // namespace pedicle_drilling
