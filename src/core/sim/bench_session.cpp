#include "pedicle_drilling/core/sim/bench_session.hpp"

#include <algorithm>
#include <cmath>

namespace pedicle_drilling::core {

std::optional<double> AtNextBreath::takeDue(long breath_index) {
  if (!value_ || breath_index == breath_index_) return std::nullopt;
  const std::optional<double> due = value_;
  value_.reset();
  return due;
}

bool BreathWatch::newBreath(const BreathScheduler& ventilator) {
  if (ventilator.breathIndex() == last_breath_index_) return false;
  last_breath_index_ = ventilator.breathIndex();
  return true;
}

NewTrips DriverTrips::update(const DrillingSimulation& sim) {
  NewTrips trips;
  if (sim.spindleWatchdogTrips() > spindle_watchdog_) {
    spindle_watchdog_ = sim.spindleWatchdogTrips();
    trips.spindle_watchdog = true;
  }
  if (sim.driveGuardTrips() > drive_guard_) {
    drive_guard_ = sim.driveGuardTrips();
    trips.drive_guard = true;
  }
  return trips;
}

void BenchTrial::reset(std::optional<double> hold_at) {
  hold_at_ = hold_at;
  held_ = false;  // the new simulation's hold (if any) is still ahead
  ++generation_;
  streaming_ = false;  // an aborted trial's phase does not hold the next one's time
  wait_given_up_ = false;
  restart_pacing_ = true;
}

std::string BenchTrial::resume() {
  const std::string message = hold_at_ ? (held_ ? "resumed at the trial's start"
                                                : "the hold at the trial's start is cancelled")
                                       : "no hold: sim time was running";
  hold_at_.reset();
  return message;
}

void BenchTrial::onPhase(bool streaming) {
  streaming_ = streaming;
  wait_given_up_ = false;
}

bool BenchTrial::starved(double arm_end, double now, double step_s) const {
  return streaming_ && !wait_given_up_ && arm_end < now + step_s - 1e-9;
}

bool BenchTrial::takeRestartPacing() {
  const bool restart = restart_pacing_;
  restart_pacing_ = false;
  return restart;
}

std::string checkResetTiming(std::uint64_t time_zero_ns, bool hold, double pre_trial_s) {
  if (time_zero_ns % kTimeZeroGridNs != 0) {
    return "time_zero must be a multiple of 0.1 s (got " + std::to_string(time_zero_ns * 1e-9) +
           " s)";
  }
  if (hold && !(std::isfinite(pre_trial_s) && pre_trial_s >= 0.0 && pre_trial_s <= 60.0)) {
    return "pre_trial_s must be in [0, 60] s (got " + std::to_string(pre_trial_s) + ")";
  }
  return "";
}

std::uint64_t trialTimeZeroNs(std::uint64_t present_ns, std::uint64_t requested_ns) {
  if (requested_ns > present_ns) return requested_ns;
  return (present_ns / kTimeZeroGridNs + 1) * kTimeZeroGridNs;
}

std::string checkAmplitudeFactor(double factor) {
  if (std::isfinite(factor) && factor >= 0.0 && factor <= 10.0) return "";
  return "factor must be in [0, 10] (got " + std::to_string(factor) + ")";
}

std::vector<FrameTransform> ownFrames(std::vector<FrameTransform> frames,
                                      const std::string& tracker_tf_frame,
                                      const std::set<std::string>& floating) {
  const auto other_owner = [&](const FrameTransform& f) {
    const bool tracker =
        !tracker_tf_frame.empty() && (f.child == tracker_tf_frame || f.child == "tracker_camera");
    const bool by_rsp = !floating.empty() && floating.count(f.child) == 0;
    return tracker || by_rsp;
  };
  frames.erase(std::remove_if(frames.begin(), frames.end(), other_owner), frames.end());
  return frames;
}

}  // namespace pedicle_drilling::core
