// The Simulator nodelet's trial bookkeeping, without ROS: the hold at a trial's start and its
// resume, the planner's streaming phases that sim time waits for, a change that takes effect at
// the next breath, the breaths and the drivers' trips already reported, the checks and the time
// zero of a reset, and the workcell frames the simulator itself publishes. The closed-loop
// engine shares the breath rules (AtNextBreath, BreathWatch).
#ifndef PEDICLE_DRILLING_CORE_SIM_BENCH_SESSION_HPP_
#define PEDICLE_DRILLING_CORE_SIM_BENCH_SESSION_HPP_

#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/ventilator.hpp"
#include "pedicle_drilling/core/sim/drilling_simulation.hpp"

namespace pedicle_drilling::core {

/**
 * @brief A value that takes effect at the start of the next breath: armed in breath i, due at
 *        the first step of a breath other than i (the patient's amplitude factor of
 *        simulator/set_patient_amplitude, the engine's breathing faults).
 */
class AtNextBreath {
 public:
  /** @brief @p value is due from the breath after @p breath_index (replaces an armed one). */
  void arm(long breath_index, double value) {
    breath_index_ = breath_index;
    value_ = value;
  }
  /** @brief A value is armed and not yet taken. */
  bool armed() const { return value_.has_value(); }
  /** @brief The armed value, once, when @p breath_index is no longer the one it was armed in. */
  std::optional<double> takeDue(long breath_index);
  /** @brief Forgets the armed value (a reset). */
  void clear() { value_.reset(); }

 private:
  long breath_index_ = 0;
  std::optional<double> value_;
};

/**
 * @brief Tells each new breath of a ventilator once: the planner hears the ventilator's
 *        settings at every breath (the engine), the settings stream is published at every
 *        breath whose settings changed (the Simulator nodelet).
 */
class BreathWatch {
 public:
  /** @brief True at the first call in a breath not seen before. */
  bool newBreath(const BreathScheduler& ventilator);
  /** @brief The next call reports a new breath (a new simulation). */
  void clear() { last_breath_index_ = -1; }

 private:
  long last_breath_index_ = -1;
};

/** @brief New trips of the simulated drivers since the last DriverTrips::update. */
struct NewTrips {
  bool spindle_watchdog = false;  ///< the spindle driver's watchdog stopped the spindle
  bool drive_guard = false;       ///< the drivers halted for want of the drill guard's enable
};

/** @brief The drivers' trips already reported (each is logged once). */
class DriverTrips {
 public:
  /** @brief The trips of @p sim not reported yet, now reported. */
  NewTrips update(const DrillingSimulation& sim);
  /** @brief Nothing reported (a new simulation counts from 0). */
  void clear() { *this = DriverTrips(); }

 private:
  int spindle_watchdog_ = 0;
  int drive_guard_ = 0;
};

/**
 * @brief The trial's timing on the Simulator: the hold at its start (drawn by the reset,
 *        ResetSimulation hold_at_trial_start) until simulator/resume, and whether the planner
 *        streams trajectories (drilling, stopped, retreating: sim time then waits for the next
 *        one, ~command_wait_s). Not thread-safe: the nodelet serialises access.
 */
class BenchTrial {
 public:
  /** @brief A reset: a new simulation with its hold at @p hold_at (nullopt: none); a hold of
   *         the old one ends, the phase is forgotten, and the pacing restarts. */
  void reset(std::optional<double> hold_at);
  /** @brief The trial's start the reset drew, while not resumed. */
  const std::optional<double>& holdAt() const { return hold_at_; }
  /** @brief Sim time @p t is at or past the hold (1 ns tolerance). */
  bool reachesHold(double t) const { return hold_at_ && t >= *hold_at_ - 1e-9; }
  /** @brief A hold is drawn and sim time has not reached it yet (start_trial waits). */
  bool holdAhead() const { return hold_at_ && !held_; }
  /** @brief Sim time stands at the hold. */
  bool held() const { return held_; }
  /** @brief The stepping thread stands at the hold (true) or left it (false). */
  void setHeld(bool held) { held_ = held; }
  /** @brief Counts resets: a hold ends when its simulation is replaced. */
  std::uint64_t generation() const { return generation_; }
  /** @brief The hold of the simulation of @p generation still stands. */
  bool holds(std::uint64_t generation) const { return hold_at_ && generation == generation_; }
  /** @brief simulator/resume: ends (or cancels) the hold; the service's message. */
  std::string resume();

  /** @brief The planner's phase: it streams trajectories or not; a given-up wait ends. */
  void onPhase(bool streaming);
  /** @brief A trajectory arrived: a given-up wait ends. */
  void onTrajectory() { wait_given_up_ = false; }
  /**
   * @brief The step of @p step_s after @p now would pass the end @p arm_end of the last
   *        trajectory received while the planner streams, and no wait for it ran out.
   */
  bool starved(double arm_end, double now, double step_s) const;
  /** @brief A wait ran out: no other until a trajectory or a phase comes. */
  void giveUpWait() { wait_given_up_ = true; }
  /** @brief A reset asked the pacing to restart; cleared by the call. */
  bool takeRestartPacing();

 private:
  std::optional<double> hold_at_;
  bool held_ = false;
  std::uint64_t generation_ = 0;
  bool streaming_ = false;
  bool wait_given_up_ = false;
  bool restart_pacing_ = false;
};

/** @brief The grid of a reset's time zero [ns]: 0.1 s, so that the nodes' periodic checks
 *         fall on the same steps as the engine's. */
constexpr std::uint64_t kTimeZeroGridNs = 100000000ULL;

/**
 * @brief A reset's timing request checked: @p time_zero_ns (0: none) on the 0.1 s grid, and,
 *        with @p hold, @p pre_trial_s in [0, 60] s.
 * @return "" or the reason it is refused (naming the field).
 */
std::string checkResetTiming(std::uint64_t time_zero_ns, bool hold, double pre_trial_s);

/**
 * @brief The new trial's time 0 after a reset at @p present_ns [ns]: @p requested_ns when it is
 *        ahead of the present, else the next point of the 0.1 s grid.
 */
std::uint64_t trialTimeZeroNs(std::uint64_t present_ns, std::uint64_t requested_ns);

/** @brief simulator/set_patient_amplitude's factor checked: "" or why it is refused. */
std::string checkAmplitudeFactor(double factor);

/**
 * @brief The workcell frames the simulator publishes: with @p tracker_tf_frame not empty, not
 *        the ones the tracker's driver and the lab's registration own (that frame and
 *        tracker_camera); with @p floating not empty (~publish_joint_frames false), only those.
 */
std::vector<FrameTransform> ownFrames(std::vector<FrameTransform> frames,
                                      const std::string& tracker_tf_frame,
                                      const std::set<std::string>& floating);

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_SIM_BENCH_SESSION_HPP_
