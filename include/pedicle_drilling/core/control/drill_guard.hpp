// The drill guard: the safety monitor's enable for the drives, and the drivers' side of it.
//
// The guard runs in the safety monitor's process, apart from the planner. It publishes an enable
// heartbeat (drill_guard/enable, std_msgs/Bool) every heartbeat_period_s; the drill's and the
// arm's drivers (DriveGuardWatch) stop the feed, hold the arm and stop the spindle when the
// latest enable is false or older than their timeout. So:
//   * the monitor's process dies or hangs: no heartbeat, the drivers stop after their timeout;
//   * the planner's process dies or hangs while a trial runs: its heartbeat
//     (compensation/heartbeat) stops, the guard sends false after planner_timeout_s;
//   * the monitor stopped the trial and the planner has not left the drilling phase
//     stop_ack_timeout_s later (a lost stop, a planner that ignores it): the guard sends false.
// A false is latched until the guard is reset (the next trial's start).
#ifndef PEDICLE_DRILLING_CORE_CONTROL_DRILL_GUARD_HPP_
#define PEDICLE_DRILLING_CORE_CONTROL_DRILL_GUARD_HPP_

#include <string>

#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling::core {

/**
 * @brief The drivers' timeout [s] on drill_guard/enable, what a lab's drivers must use
 * (doc/hardware.md, "Safe whatever dies"): 8 periods of the guard's 0.01 s heartbeat, so that a
 * process that dies right after a beat stops the feed within 0.08 s and the spindle's run-down
 * starts then, while a scheduling gap of up to 70 ms on a loaded machine does not stop a healthy
 * trial. The simulator's config/simulator.yaml drive_guard_timeout_s and the core engine's drivers
 * use it.
 */
constexpr double kDriveGuardTimeoutS = 0.08;
/** @brief The planner's compensation/heartbeat period [s] while its trial runs (its
 *         ~heartbeat_period_s default; the core engine's planner). */
constexpr double kPlannerHeartbeatPeriodS = 0.01;
/** @brief Sim time [s] a core-engine trial runs on after a process-kill fault: the bone
 *         breathes into the held drill (the rostests fault_*_killed watch as long). */
constexpr double kProcessKillWatchS = 3.0;

/** @brief Timing of the drill guard (the monitor's side). */
struct DrillGuardParams {
  /**
   * @brief Period [s] of the enable heartbeat. Default 0.01 s (100 Hz): 8 periods fit in the
   * drivers' 0.08 s timeout (kDriveGuardTimeoutS).
   */
  double heartbeat_period_s = 0.01;
  /**
   * @brief Max age [s] of the planner's heartbeat while its trial runs. Default 0.06 s: 6 of
   * its 0.01 s periods; at the paper's 0.5 mm/s feed the drill advances 30 um in that time, and
   * the bone (about 5 mm/s peak AP speed at 4-5 mm peak to peak) at most 0.25 mm.
   */
  double planner_timeout_s = 0.06;
  /**
   * @brief Max time [s] from the monitor's stop to the planner's leaving the drilling phase.
   * Default 0.1 s: the planner reacts at its next step (1 ms on the simulator's grid, a few ms
   * on hardware); 0.1 s is the monitor's force timeout, the time a stop may take anywhere else.
   */
  double stop_ack_timeout_s = 0.1;

  /** @brief Check all fields against table(). @throws std::invalid_argument naming the field. */
  void validate() const;
  /** @brief The declaration of every field (ROS names guard_heartbeat_period_s, ...). */
  static const ParamTable<DrillGuardParams>& table();
};

/** @brief The monitor's side: the planner's liveness and its answer to a stop, one enable out. */
class DrillGuard {
 public:
  /** @brief Construct. @throws std::invalid_argument if params.validate() fails. */
  explicit DrillGuard(const DrillGuardParams& params = DrillGuardParams());

  /** @brief The planner's heartbeat received at `now`. */
  void onPlannerHeartbeat(double now);
  /**
   * @brief The planner's phase at `now`: `running` (a trial under way: its heartbeat is
   *        watched from now on) and `drilling` (the drilling or stopped phase: a stop must end
   *        it within stop_ack_timeout_s).
   */
  void onPlannerPhase(double now, bool running, bool drilling);
  /**
   * @brief The monitor stopped the trial at `now`: the planner must not be drilling
   *        stop_ack_timeout_s later (nor from any later drilling phase, until reset()).
   */
  void onMonitorStop(double now);
  /** @brief Evaluates the timeouts at `now`; false once disabled (latched until reset()). */
  bool enabled(double now);
  /** @brief Why the guard disabled the drives (empty while enabled). */
  const std::string& reason() const { return reason_; }
  /** @brief Whether the planner's last phase was a running trial. */
  bool plannerRunning() const { return running_; }
  /** @brief Whether the planner's last phase was drilling (or stopped in the bone). */
  bool plannerDrilling() const { return drilling_; }
  /**
   * @brief Without a new input, enabled(t) changes nothing for t up to the returned time
   *        (+infinity when nothing is watched or already disabled).
   */
  double quietUntil() const;
  /**
   * @brief Enabled again and the stop forgotten (the next trial's start); the planner's phase
   *        and heartbeat stay watched (a reset does not blind the guard to a running trial).
   */
  void reset();
  /** @brief Parameters in use. */
  const DrillGuardParams& params() const { return params_; }

 private:
  void disable(const std::string& why);

  DrillGuardParams params_;
  bool running_ = false;
  bool drilling_ = false;
  double last_planner_t_ = 0.0;  ///< latest heartbeat, or when the trial began to run
  bool stopped_ = false;         ///< the monitor stopped (until reset())
  bool stop_pending_ = false;    ///< the monitor stopped, the planner still drills
  double stop_t_ = 0.0;
  bool disabled_ = false;
  std::string reason_;
};

/** @brief The drivers' side: the enable heartbeat's timeout, one rule for every driver. */
class DriveGuardWatch {
 public:
  /** @brief timeout_s: max age of the latest enable [s] (> 0). @throws on a bad value. */
  explicit DriveGuardWatch(double timeout_s);
  /** @brief An enable message received at `now`. */
  void onEnable(double now, bool enable);
  /**
   * @brief Whether the drives may move at `now`: the latest message is a true no older than
   *        the timeout. False before any message (fails closed).
   */
  bool allows(double now) const;
  /** @brief Why not (empty when allows(now)). */
  std::string why(double now) const;
  /** @brief Forgets every message (a new simulation): disabled until the next true. */
  void reset();
  /** @brief The timeout [s]. */
  double timeout() const { return timeout_s_; }

 private:
  double timeout_s_;
  bool heard_ = false;
  bool enable_ = false;
  double last_t_ = 0.0;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_CONTROL_DRILL_GUARD_HPP_
