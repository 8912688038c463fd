// The stream schedule of a simulated bench, one rule for the closed-loop engine and the
// Simulator nodelet: at a 1 ms physics step, which of the bench's streams publish (the force
// sample, the tracker, the tidal volume and the breath, the controllers' states, the ground
// truth, the joint states and tf, the monitor's checks), and the tracker samples held back by
// the tracker's latency until they are due.
#ifndef PEDICLE_DRILLING_CORE_SIM_STREAM_SCHEDULE_HPP_
#define PEDICLE_DRILLING_CORE_SIM_STREAM_SCHEDULE_HPP_

#include <cstdint>
#include <deque>
#include <utility>

#include "pedicle_drilling/core/sim/drilling_simulation.hpp"

namespace pedicle_drilling::core {

/**
 * @brief The rates of a bench's streams [Hz]. Each becomes a period in physics steps
 *        (streamPeriodSteps, the error naming the rate's parameter). The streams marked
 *        "0: off" are published by one engine only, or may be switched off.
 */
struct StreamRates {
  double physics_rate_hz = 1000.0;
  double tracker_hz = 8.0;            ///< tracker/marker_pose (tracker_rate_hz)
  double controller_state_hz = 50.0;  ///< <controller>/state (controller_state_rate_hz)
  double ground_truth_hz = 20.0;      ///< simulator/ground_truth (ground_truth_rate_hz)
  double tidal_volume_hz = 64.0;      ///< tidal_volume and the breath (0: off)
  double joint_state_hz = 0.0;        ///< joint_states (joint_state_rate_hz; 0: off)
  double tf_hz = 0.0;                 ///< tf (tf_rate_hz; 0: off)
  double safety_check_hz = 0.0;       ///< the monitor's checks (safety_check_rate_hz; 0: off)
};

/** @brief The streams a step publishes (StreamSchedule::at). */
struct StreamsDue {
  bool force = false;              ///< a force-sensor sample (ft_sensor/wrench)
  bool tracker = false;            ///< a tracker sample is measured
  bool tidal_volume = false;       ///< the ventilator's tidal volume and breath start
  bool controller_states = false;  ///< each controller's state
  bool ground_truth = false;       ///< the ground truth (its period, or a layer change)
  bool joint_states = false;       ///< joint_states
  bool tf = false;                 ///< the workcell's frames
  bool safety_check = false;       ///< the monitor's periodic checks
  /** @brief A stream a participant of the pipeline may read is published (not the checks). */
  bool any() const {
    return force || tracker || tidal_volume || controller_states || ground_truth || joint_states ||
           tf;
  }
};

/**
 * @brief Messages held back by a latency: each pushed at `now` is due `delay` later, and due
 *        ones leave in the order they came (the tracker's latency; a breath sensor's).
 */
template <class T>
class DelayLine {
 public:
  /** @brief The latency [s] of what is pushed from now on (<= 0: none, send at once). */
  void setDelay(double delay_s) { delay_s_ = delay_s; }
  /** @brief A message is held back (a latency > 0). */
  bool delays() const { return delay_s_ > 0.0; }
  /** @brief Holds @p value, sent at @p now, until now + the latency. */
  void push(double now, T value) { queue_.emplace_back(now + delay_s_, std::move(value)); }
  /** @brief A held message is due by @p t (within 1 ns). */
  bool due(double t) const { return !queue_.empty() && queue_.front().first <= t + 1e-9; }
  /** @brief Hands every message due by @p t to @p send, oldest first. */
  template <class F>
  void deliverDue(double t, F&& send) {
    while (due(t)) {
      const T value = std::move(queue_.front().second);
      queue_.pop_front();
      send(value);
    }
  }
  /** @brief Drops every held message (a new trial). */
  void clear() { queue_.clear(); }

 private:
  double delay_s_ = 0.0;
  std::deque<std::pair<double, T>> queue_;
};

/**
 * @brief Which streams a physics step publishes: the periods of StreamRates counted from the
 *        reset (step index n, the first step after the reset is 1), the tracker at its own phase
 *        (DrillingSimulation::trackerDue), the ground truth also at a layer change. The tracker
 *        samples its latency holds back are a DelayLine's (DelayLine::due at the step's end).
 */
class StreamSchedule {
 public:
  StreamSchedule() = default;
  /** @brief @throws std::invalid_argument naming a rate out of (0, physics rate] (0 allowed
   *         where the stream may be off). */
  explicit StreamSchedule(const StreamRates& rates);

  /** @brief The step index of the step ending at @p t s after the reset. */
  static std::uint64_t stepIndex(double t, double physics_rate_hz);

  /** @brief The streams of step @p n, which ended as @p step says, on @p sim. */
  StreamsDue at(std::uint64_t n, const SimulationStep& step, const DrillingSimulation& sim) const;

  /** @brief The tidal volume stream is on (its rate > 0). */
  bool tidalVolumeOn() const { return tidal_volume_period_ > 0; }
  /** @brief The monitor's checks are on (their rate > 0). */
  bool safetyCheckOn() const { return safety_check_period_ > 0; }

 private:
  std::uint64_t tracker_period_ = 125;
  std::uint64_t controller_state_period_ = 20;
  std::uint64_t ground_truth_period_ = 50;
  std::uint64_t tidal_volume_period_ = 16;
  std::uint64_t joint_state_period_ = 0;  // 0: off
  std::uint64_t tf_period_ = 0;
  std::uint64_t safety_check_period_ = 0;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_SIM_STREAM_SCHEDULE_HPP_
