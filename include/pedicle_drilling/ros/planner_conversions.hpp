/**
 * @file planner_conversions.hpp
 * @brief The CompensationPlanner's parameters into core::TrialSequencerParams, the trial
 *        sequencer's outputs as ROS messages, and drilling_plan as the core's plan.
 */
#pragma once

#include <geometry_msgs/PoseStamped.h>
#include <trajectory_msgs/JointTrajectory.h>

#include <ros/service_client.h>

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "pedicle_drilling/DrillingPlan.h"
#include "pedicle_drilling/TrialStatus.h"
#include "pedicle_drilling/core/control/trial_sequencer.hpp"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"

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
 * @brief drilling_plan as the core's plan; nullopt with the reason in @p why when it is not
 *        usable (an empty header.frame_id, or what core::DrillingPlan::check() refuses).
 */
std::optional<core::DrillingPlan> fromMsg(const DrillingPlan& msg, std::string* why);

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
