// What the SafetyMonitor nodelet runs around core::SafetySupervisor and core::DrillGuard, with no
// ROS: the input streams' statistics, the drives' enable heartbeat, the planner's phase (the end
// of a trial, of a retreat), the re-tare check kept until the next reset, the monitor's status as
// /diagnostics reports it, and the steps it needs under the simulator's lockstep.
#ifndef PEDICLE_DRILLING_CORE_CONTROL_MONITOR_RUNTIME_HPP_
#define PEDICLE_DRILLING_CORE_CONTROL_MONITOR_RUNTIME_HPP_

#include <Eigen/Core>

#include <algorithm>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "pedicle_drilling/core/common/stream_stats.hpp"
#include "pedicle_drilling/core/control/drill_guard.hpp"
#include "pedicle_drilling/core/control/safety_supervisor.hpp"
#include "pedicle_drilling/core/control/trial_sequencer.hpp"

namespace pedicle_drilling::core {

/** @brief The drives' enable to send (MonitorRuntime::beat). */
struct EnableBeat {
  bool enable = true;       ///< drill_guard/enable's value
  bool turned_off = false;  ///< it turns false with this beat (the guard's reason says why)
};

/** @brief What a phase of the planner ended (MonitorRuntime::onPlannerPhase). */
struct PhaseChange {
  bool trial_ended = false;    ///< the phase turned done
  bool retreat_ended = false;  ///< ... from retreating: the re-tare check is due
};

/** @brief The monitor's status, as its "monitor" diagnostic reports it. */
struct MonitorStatus {
  enum class Level { kOk, kWarn, kError };
  Level level = Level::kOk;
  std::string message;
  std::vector<std::pair<std::string, std::string>> values;  ///< key, value, in order
};

/** @brief The message of the monitor's ERROR status after the stop @p v: "stop and retreat: "
 *         and the stop's description (what the planner quotes when it stops on it). */
std::string monitorStopMessage(const SafetyVerdict& v);

/**
 * @brief The SafetyMonitor's state around its supervisor (H1, H2, the timeouts, NaN) and its
 *        drill guard: what the nodelet does between a message in and a message out.
 */
class MonitorRuntime {
 public:
  /** @brief @throws std::invalid_argument from the supervisor's or the guard's validation. */
  MonitorRuntime(const SupervisorParams& supervisor, const DrillGuardParams& guard);

  /** @brief The supervisor (pairing, arming and the one stop report). */
  SafetySupervisor& supervisor() { return supervisor_; }
  /** @brief The supervisor, read only. */
  const SafetySupervisor& supervisor() const { return supervisor_; }
  /** @brief The drill guard (the planner's heartbeat, the enable of the drives). */
  DrillGuard& guard() { return guard_; }
  /** @brief The drill guard, read only. */
  const DrillGuard& guard() const { return guard_; }

  /** @brief A force sample stamped @p stamp_s, handled at @p handled_s (the stream's
   *         statistics, one clock) and at @p now (the supervisor's clock). */
  void onForce(double now, double stamp_s, double handled_s, const Eigen::Vector3d& force);
  /** @brief A tracker sample, likewise; the supervisor's pairing result. */
  PairResult onTracked(double now, double handled_s, const StampedPosition& tracked);

  /** @brief The enable due at @p t: every heartbeat period, and at once when it changes;
   *         nullopt when nothing is due. */
  std::optional<EnableBeat> beat(double t);
  /** @brief The latest enable sent. */
  bool lastEnable() const { return last_enable_; }
  /** @brief When the next heartbeat of the enable is due. */
  double nextBeat() const { return next_beat_; }

  /** @brief The planner's phase at @p now: the supervisor and the guard hear it. */
  PhaseChange onPlannerPhase(double now, TrialPhase phase, bool running);
  /** @brief The re-tare check at @p now, kept for the status until reset(). */
  RetareCheck checkRetare(double now);
  /** @brief The new stop, if the verdict just turned to stop; the guard hears it. */
  std::optional<SafetyVerdict> takeNewStop(double now);
  /** @brief OK while fine, ERROR from the stop on, WARN after a drift (until reset), and the
   *         inputs as received since the reset. */
  MonitorStatus status() const;
  /**
   * @brief "" while a reset is allowed, else why not: a trial runs (the drill may be in bone, or
   *        about to be), and a reset would clear a stop, the guard's latch or the streams'
   *        watch mid-trial; the planner's next trial start resets the monitor (a restarted
   *        planner says idle first).
   */
  std::string resetRefusal() const;
  /** @brief A new trial's monitor: verdict, guard, re-tare check and statistics (the
   *         planner's phase stays). */
  void reset(double now);

  /**
   * @brief Under the lockstep, the earliest time after the step at @p t [s] at which the
   *        monitor can change anything: the next check on the grid of @p check_rate_hz that can
   *        (a check before the first stream's timeout is due changes nothing,
   *        SafetySupervisor::quietUntil: the grid step one period before it, and every one after
   *        it until a sample comes), the enable's next heartbeat or the guard's next deadline.
   *        Its inputs change only at steps it sees, after which this is asked again. Without it
   *        the steps waited at for the 200 Hz checks alone were a sixth of those the simulator
   *        waited at (51 % -> 43 % of the steps), with nothing to do at almost all of them.
   */
  double nextUsefulTime(double t, double check_rate_hz) const;
  /** @brief A gap between two lockstep steps that only a simulator reset makes [s]: 1 s, at
   *         least two periods of the checks at @p check_rate_hz. */
  static double resetGap(double check_rate_hz) { return std::max(1.0, 2.0 / check_rate_hz); }
  /** @brief Whether @p t [s] is on the grid of the checks at @p rate_hz (1e-6 of a period). */
  static bool onCheckGrid(double t, double rate_hz);

 private:
  SafetySupervisor supervisor_;
  DrillGuard guard_;
  bool last_enable_ = true;  // the latest enable sent
  double next_beat_ = 0.0;   // the next heartbeat's time
  TrialPhase last_phase_ = TrialPhase::kIdle;
  std::optional<RetareCheck> last_retare_;  // until reset()
  StreamStats force_stats_;
  StreamStats tracker_stats_;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_CONTROL_MONITOR_RUNTIME_HPP_
