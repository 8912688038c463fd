#include "pedicle_drilling/core/sim/stream_schedule.hpp"

#include <cmath>

namespace pedicle_drilling::core {

namespace {

/** @brief The period of a stream that may be off: 0 for a rate of 0. */
std::uint64_t optionalPeriod(double physics_rate_hz, double rate_hz, const char* name) {
  return rate_hz == 0.0 ? 0 : streamPeriodSteps(physics_rate_hz, rate_hz, name);
}

bool dueAt(std::uint64_t n, std::uint64_t period) { return period > 0 && n % period == 0; }

}  // namespace

StreamSchedule::StreamSchedule(const StreamRates& r) {
  const double physics = r.physics_rate_hz;
  tracker_period_ = streamPeriodSteps(physics, r.tracker_hz, "tracker_rate_hz");
  controller_state_period_ =
      streamPeriodSteps(physics, r.controller_state_hz, "controller_state_rate_hz");
  ground_truth_period_ = streamPeriodSteps(physics, r.ground_truth_hz, "ground_truth_rate_hz");
  tidal_volume_period_ = optionalPeriod(physics, r.tidal_volume_hz, "tidal_volume_rate_hz");
  joint_state_period_ = optionalPeriod(physics, r.joint_state_hz, "joint_state_rate_hz");
  tf_period_ = optionalPeriod(physics, r.tf_hz, "tf_rate_hz");
  safety_check_period_ = optionalPeriod(physics, r.safety_check_hz, "safety_check_rate_hz");
}

std::uint64_t StreamSchedule::stepIndex(double t, double physics_rate_hz) {
  return static_cast<std::uint64_t>(std::llround(t * physics_rate_hz));
}

StreamsDue StreamSchedule::at(std::uint64_t n, const SimulationStep& step,
                              const DrillingSimulation& sim) const {
  StreamsDue due;
  due.force = step.force_sampled;
  due.tracker = sim.trackerDue(tracker_period_);
  due.tidal_volume = dueAt(n, tidal_volume_period_);
  due.controller_states = dueAt(n, controller_state_period_);
  due.ground_truth = dueAt(n, ground_truth_period_) || step.layer_changed;
  due.joint_states = dueAt(n, joint_state_period_);
  due.tf = dueAt(n, tf_period_);
  due.safety_check = dueAt(n, safety_check_period_);
  return due;
}

}  // namespace pedicle_drilling::core
