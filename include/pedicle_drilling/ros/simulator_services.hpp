/**
 * @file simulator_services.hpp
 * @brief The Simulator's services (doc/nodes.md, "pedicle_drilling/Simulator"):
 *        simulator/reset (a new simulation, with its hold), simulator/start_trial,
 *        simulator/resume, simulator/set_ventilator_settings, simulator/set_patient_amplitude,
 *        simulator/stall_joint and simulator/abort_controller, served on core::SimulatedBench.
 */
#pragma once

#include <ros/ros.h>
#include <std_srvs/Trigger.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "pedicle_drilling/AbortController.h"
#include "pedicle_drilling/ResetSimulation.h"
#include "pedicle_drilling/SetPatientAmplitude.h"
#include "pedicle_drilling/SetVentilatorSettings.h"
#include "pedicle_drilling/StallJoint.h"
#include "pedicle_drilling/core/sim/drilling_simulation.hpp"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/simulator_outputs.hpp"

namespace pedicle_drilling {

/** @brief The Simulator's services. Each handler takes the shared mutex (start_trial waits on
 *         it for the reset's hold). */
class SimulatorServices {
 public:
  /** @brief What the services tell the nodelet, under the shared mutex. */
  struct Hooks {
    /** @brief A reset took the parameters @p params (re-read from the parameter server). */
    std::function<void(const SimulatorNodeParams& params)> reset;
    /** @brief simulator/abort_controller aborted @p controller's trajectory, for @p why. */
    std::function<void(const std::string& controller, const std::string& why)> aborted;
  };

  /**
   * @brief On @p shared's bench: a reset re-reads the parameters from @p private_nh and builds
   *        its simulation from @p urdf_xml (the workcell); @p lockstep: /use_sim_lockstep.
   */
  SimulatorServices(const SimulatorShared& shared, const ros::NodeHandle& private_nh,
                    std::string urdf_xml, bool lockstep, Hooks hooks);

  /**
   * @brief Advertises simulator/resume on @p cmd (under the lockstep, after the planner's first
   *        commands), simulator/reset and simulator/start_trial on @p trial (a queue with
   *        threads of its own: they wait, a reset builds a simulation), the others on @p nh.
   */
  void advertise(ros::NodeHandle& nh, ros::NodeHandle& cmd, ros::NodeHandle& trial);

 private:
  bool onReset(ResetSimulation::Request& req, ResetSimulation::Response& res);
  std::string prepareReset(const ResetSimulation::Request& req, SimulatorNodeParams* params,
                           std::optional<core::BoneMotionModel>* bone_motion,
                           std::unique_ptr<core::DrillingSimulation>* fresh) const;
  bool onStartTrial(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response);
  bool onResume(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response);
  bool onSetVentilatorSettings(SetVentilatorSettings::Request& request,
                               SetVentilatorSettings::Response& response);
  bool onSetPatientAmplitude(SetPatientAmplitude::Request& request,
                             SetPatientAmplitude::Response& response);
  bool onAbortController(AbortController::Request& request, AbortController::Response& response);
  bool onStallJoint(StallJoint::Request& request, StallJoint::Response& response);

  SimulatorShared shared_;
  ros::NodeHandle private_nh_;  ///< the parameters, re-read at every reset
  std::string urdf_xml_;        ///< the workcell, for the simulation of each reset
  bool lockstep_;
  Hooks hooks_;
  std::vector<ros::ServiceServer> services_;
};

}  // namespace pedicle_drilling
