#include "pedicle_drilling/ros/simulator_services.hpp"

#include <chrono>
#include <cstdint>
#include <exception>
#include <stdexcept>
#include <utility>

#include "pedicle_drilling/core/sim/bench_session.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/simulator_conversions.hpp"
#include "pedicle_drilling/ros/ventilator_conversions.hpp"

namespace pedicle_drilling {

SimulatorServices::SimulatorServices(const SimulatorShared& shared,
                                     const ros::NodeHandle& private_nh, std::string urdf_xml,
                                     bool lockstep, Hooks hooks)
    : shared_(shared),
      private_nh_(private_nh),
      urdf_xml_(std::move(urdf_xml)),
      lockstep_(lockstep),
      hooks_(std::move(hooks)) {}

void SimulatorServices::advertise(ros::NodeHandle& nh, ros::NodeHandle& cmd,
                                  ros::NodeHandle& trial) {
  using S = SimulatorServices;
  services_.push_back(cmd.advertiseService("simulator/resume", &S::onResume, this));
  services_.push_back(trial.advertiseService("simulator/reset", &S::onReset, this));
  services_.push_back(trial.advertiseService("simulator/start_trial", &S::onStartTrial, this));
  services_.push_back(
      nh.advertiseService("simulator/set_ventilator_settings", &S::onSetVentilatorSettings, this));
  services_.push_back(
      nh.advertiseService("simulator/set_patient_amplitude", &S::onSetPatientAmplitude, this));
  services_.push_back(nh.advertiseService("simulator/stall_joint", &S::onStallJoint, this));
  services_.push_back(
      nh.advertiseService("simulator/abort_controller", &S::onAbortController, this));
}

/**
 * @brief A reset's new simulation, built before the old one is touched: the distributions are
 *        re-read at every reset, so that a campaign (or a user with `rosparam set`) can change
 *        them between trials; an explicit specimen has the given thicknesses with no spread. A
 *        simulation as the closed-loop engine builds one for every trial: sim time, the
 *        breathing, the tracker's phase and the physics all start again from the seed.
 * @return "" or why the reset is refused.
 */
std::string SimulatorServices::prepareReset(
    const ResetSimulation::Request& req, SimulatorNodeParams* params,
    std::optional<core::BoneMotionModel>* bone_motion,
    std::unique_ptr<core::DrillingSimulation>* fresh) const {
  try {
    *params = loadSimulatorParams(private_nh_);
    *bone_motion = loadBoneMotionModel(*params, ParamLoader(private_nh_));
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

/** @brief simulator/reset: a new simulation (prepareReset), swapped in under the mutex. */
bool SimulatorServices::onReset(ResetSimulation::Request& req, ResetSimulation::Response& res) {
  SimulatorNodeParams params;
  std::optional<core::BoneMotionModel> bone_motion;
  std::unique_ptr<core::DrillingSimulation> fresh;
  const std::string refused = prepareReset(req, &params, &bone_motion, &fresh);
  if (!refused.empty()) {
    res.success = false;
    res.message = refused + "; nothing was reset";
    return true;
  }
  std::unique_lock<std::mutex> lock(shared_.mutex);
  core::SimulatedBench& bench = shared_.bench;
  SimulatorOutputs& out = shared_.out;
  // Stamps go on from the present: the new trial's time 0 is the requested time_zero when it
  // is ahead, else the next multiple of 0.1 s (either way on the 0.1 s grid, so that the
  // periodic checks of the nodes fall on the same steps as in the engine). The nodes take the
  // jump as the gap between two trials (the planner's start_trial resets the recognizer and
  // the monitor).
  const std::uint64_t present_ns = out.stampOf(bench.sim().time()).toNSec();
  const std::uint64_t zero_ns = core::trialTimeZeroNs(present_ns, req.time_zero.toNSec());
  if (!req.time_zero.isZero() && zero_ns != req.time_zero.toNSec()) {
    ROS_WARN_NAMED(shared_.name,
                   "Simulator: reset: time_zero %.1f s is not ahead of the present %.3f s; the "
                   "trial starts at %.1f s instead",
                   req.time_zero.toSec(), present_ns * 1e-9, zero_ns * 1e-9);
  }
  const core::BenchCounters& last = bench.counters();
  if (lockstep_ && last.lockstep_steps + last.lockstep_skipped > 0) {
    ROS_INFO_NAMED(shared_.name,
                   "Simulator: the last trial ran %lu steps under the lockstep, %lu of them "
                   "waiting for the participants",
                   static_cast<unsigned long>(last.lockstep_steps + last.lockstep_skipped),
                   static_cast<unsigned long>(last.lockstep_steps));
  }
  const std::optional<double> hold_at = bench.reset(
      std::move(fresh), benchTransport(params, req.seed), req.hold_at_trial_start, req.pre_trial_s);
  out.resetTrial(static_cast<double>(zero_ns) * 1e-9, params.tracker_delay_s);
  hooks_.reset(params);
  if (hold_at) res.trial_start = out.stampOf(*hold_at);
  res.reset_time = out.stampOf(bench.sim().time());
  bench.notify();
  res.success = true;
  res.message = resetSummary(bench.sim(), req, bone_motion);
  fillResetResponse(bench.sim(), &res);
  publishGroundTruth(shared_, bench.sim().time());
  out.publishPlan(bench.sim(), bench.sim().time());
  return true;
}

/**
 * @brief simulator/start_trial: ground truth measures the relative AP motion from now; a
 *        specimen already drilled is replaced by a fresh one (seed + 1), as on the bench.
 */
bool SimulatorServices::onStartTrial(std_srvs::Trigger::Request&,
                                     std_srvs::Trigger::Response& response) {
  std::unique_lock<std::mutex> lock(shared_.mutex);
  core::SimulatedBench& bench = shared_.bench;
  // The trial starts at the hold the reset drew: wait for sim time to get there.
  if (!bench.waitForHold(lock, std::chrono::seconds(120), shared_.running)) {
    response.success = false;
    response.message =
        "start_trial: sim time did not reach the trial's start (the reset's "
        "hold) within 120 s of wall time";
    return true;
  }
  bool remounted = false;
  try {
    remounted = bench.startTrial();
  } catch (const std::exception& e) {
    response.success = false;
    response.message = std::string("start_trial failed: ") + e.what();
    return true;
  }
  const core::DrillingSimulation& sim = bench.sim();
  response.success = true;
  response.message = "trial " + std::to_string(sim.trialCount()) +
                     " started at t=" + std::to_string(sim.time()) + " s";
  if (remounted) {
    response.message += "; the specimen was drilled, a fresh one from seed " +
                        std::to_string(sim.seed()) + " is mounted (arm at home)";
    ROS_INFO_NAMED(shared_.name, "Simulator: %s", response.message.c_str());
  }
  publishGroundTruth(shared_, sim.time());
  shared_.out.publishPlan(sim, sim.time());
  return true;
}

/** @brief simulator/resume: ends the hold at the trial's start (nothing else to do without
 *         one). */
bool SimulatorServices::onResume(std_srvs::Trigger::Request&,
                                 std_srvs::Trigger::Response& response) {
  {
    std::lock_guard<std::mutex> lock(shared_.mutex);
    response.success = true;
    response.message = shared_.bench.trial().resume();
  }
  shared_.bench.notify();
  return true;
}

/** @brief The simulated ventilator takes new settings at its next breath (the settings stream
 *         tells the planner then); the identified model is not re-fit. */
bool SimulatorServices::onSetVentilatorSettings(SetVentilatorSettings::Request& request,
                                                SetVentilatorSettings::Response& response) {
  serveSetVentilatorSettings(request, response, [this](const core::VentilatorSettings& s) {
    std::lock_guard<std::mutex> lock(shared_.mutex);
    shared_.bench.sim().requestVentilatorSettings(s);
  });
  return true;
}

/** @brief The patient's AP displacement x factor from the next breath until the next reset. */
bool SimulatorServices::onSetPatientAmplitude(SetPatientAmplitude::Request& request,
                                              SetPatientAmplitude::Response& response) {
  response.message = core::checkAmplitudeFactor(request.factor);
  response.success = response.message.empty();
  if (!response.success) return true;
  std::lock_guard<std::mutex> lock(shared_.mutex);
  shared_.bench.setPatientAmplitude(request.factor);
  response.message = "the patient's AP displacement x " + std::to_string(request.factor) +
                     " from the next breath until the next reset";
  return true;
}

/** @brief simulator/abort_controller: the controller drops its trajectory and holds
 *         (core::DrillingSimulation::abortController), at the current step. */
bool SimulatorServices::onAbortController(AbortController::Request& request,
                                          AbortController::Response& response) {
  std::lock_guard<std::mutex> lock(shared_.mutex);
  try {
    shared_.bench.sim().abortController(request.controller);
  } catch (const std::invalid_argument& e) {
    response.success = false;
    response.message = e.what();
    return true;
  }
  ROS_WARN_NAMED(shared_.name,
                 "Simulator: %s aborted its trajectory: it holds where its reference is",
                 request.controller.c_str());
  hooks_.aborted(request.controller,
                 request.controller + " aborted its trajectory (simulator/abort_controller)");
  response.success = true;
  response.message = request.controller + " aborted";
  return true;
}

/** @brief simulator/stall_joint: the joint's drive stalls (it holds where it is) or is
 *         released, at the current step. */
bool SimulatorServices::onStallJoint(StallJoint::Request& request, StallJoint::Response& response) {
  std::lock_guard<std::mutex> lock(shared_.mutex);
  try {
    shared_.bench.sim().setJointStalled(request.joint, request.stalled);
  } catch (const std::invalid_argument& e) {
    response.success = false;
    response.message = e.what();
    return true;
  }
  ROS_WARN_NAMED(shared_.name, "Simulator: %s's drive %s", request.joint.c_str(),
                 request.stalled ? "stalled: it holds where it is" : "released");
  response.success = true;
  response.message = request.joint + (request.stalled ? " stalled" : " released");
  return true;
}

}  // namespace pedicle_drilling
