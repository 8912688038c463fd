// The safety monitor as a component with streams (paper Algorithm 1, Sec. IV-B): pairs each
// predicted bone position with the tracked one of the same time stamp, arms the watchdog once
// both sensor streams were heard or a trial runs, and reports a stop once. The SafetyMonitor
// nodelet and the closed-loop engine both drive this very object; neither pairs or latches
// anything itself.
#ifndef PEDICLE_DRILLING_CORE_SAFETY_SUPERVISOR_HPP_
#define PEDICLE_DRILLING_CORE_SAFETY_SUPERVISOR_HPP_

#include <Eigen/Core>

#include <deque>
#include <limits>
#include <optional>
#include <string>

#include "pedicle_drilling/core/common/param_table.hpp"
#include "pedicle_drilling/core/control/safety_monitor.hpp"

namespace pedicle_drilling::core {

/** @brief Parameters of the supervisor: the monitor's thresholds and the pairing. */
struct SupervisorParams {
  /** @brief H1, H2 and the timeouts. */
  SafetyParams safety;
  /**
   * @brief Max stamp difference [s] of a predicted and a tracked position compared by H1.
   * Default 0.02 s: the planner stamps its prediction with the tracker sample's own stamp, so
   * a pair differs by 0; anything within a fifth of the 8 Hz tracker period is the same sample.
   */
  double pair_tolerance_s = 0.02;
  /** @brief Positions kept per stream for the pairing (64 = 8 s of an 8 Hz tracker). */
  int history = 64;

  /** @brief Check all fields. @throws std::invalid_argument whose message starts with the field. */
  void validate() const;
  /** @brief The declaration of every field (the SafetyMonitor's parameters include it). */
  static const ParamTable<SupervisorParams>& table();
};

/** @brief A position of one stream with its stamp [s] and frame. */
struct StampedPosition {
  double stamp = 0.0;        ///< Time the position refers to [s].
  std::string frame;         ///< Frame of the position.
  Eigen::Vector3d position;  ///< [m]
};

/**
 * @brief The latest samples of the predicted and the tracked stream, each paired with the other
 *        stream's sample nearest in stamp within a tolerance: the SafetySupervisor's H1 pairing,
 *        and the DrillingPanel's readout of the same quantity (core::TrialView).
 */
class StampPairer {
 public:
  /** @brief tolerance_s: max stamp difference of a pair (0: the same stamp only); history:
   *         samples kept per stream. */
  StampPairer(double tolerance_s, int history) : tolerance_s_(tolerance_s), history_(history) {}

  /**
   * @brief Keeps `sample` in its stream and returns the other stream's sample nearest in stamp
   *        within the tolerance, or nullptr. The pointer is valid until the next add() or clear().
   */
  const StampedPosition* add(const StampedPosition& sample, bool is_predicted);
  /** @brief Forgets both streams. */
  void clear();

 private:
  double tolerance_s_;
  int history_;
  std::deque<StampedPosition> tracked_;
  std::deque<StampedPosition> predicted_;
};

/** @brief What a position sample led to. */
enum class PairResult {
  kUnpaired,       ///< No sample of the other stream within the tolerance (yet).
  kCompared,       ///< Compared with H1.
  kFrameMismatch,  ///< The partner is in another frame: not compared (a configuration error;
                   ///< a stop while drilling, see setDrilling()).
  kStale,          ///< A tracked sample whose stamp is not newer than the last: ignored.
};

/**
 * @brief The grid index k (the check at k / rate_hz) of a monitor's next check after time `t`
 *        that can change anything, given its quietUntil() `quiet`: the next grid step, or the
 *        one a period before `quiet` when that is later (a margin far above the rounding of
 *        the timeouts' sums); +infinity when no check can (stopped, or not checking).
 */
double nextUsefulCheckTick(double t, double rate_hz, double quiet);

/** @brief Streams in, one stop out: SafetyMonitor plus pairing, arming and the stop report. */
class SafetySupervisor {
 public:
  /** @brief Construct. @throws std::invalid_argument if params.validate() fails. */
  explicit SafetySupervisor(const SupervisorParams& params = SupervisorParams());

  /** @brief A force sample [N] received at `now` (H2 acts on this very sample). */
  void onForce(double now, const Eigen::Vector3d& force);

  /**
   * @brief A tracked marker position received at `now`; feeds the watchdog and the NaN check.
   *        A sample whose stamp is not newer than the last fresh one (a stale tf or a tracker
   *        driver repeating its last pose) is ignored: it neither feeds the watchdog nor is
   *        compared, so a tracker that only repeats itself times out like a silent one.
   */
  PairResult onTracked(double now, const StampedPosition& tracked);

  /** @brief A predicted marker position received at `now`; a non-finite one is a stop. */
  PairResult onPredicted(double now, const StampedPosition& predicted);

  /** @brief The planner's phase: while a trial runs, a stream never heard times out too. */
  void setTrialRunning(bool running) { trial_running_ = running; }
  /** @brief What setTrialRunning() last said (false before any). */
  bool trialRunning() const { return trial_running_; }

  /**
   * @brief The drill may be in bone (the planner's drilling and stopped phases) from `now` on:
   *        H1 fails closed. A pair must then be compared at least every prediction_timeout_s
   *        (a missing, stale or unpaired prediction is a stop, SafetyVerdict::kPredictionLost)
   *        and a pair in two frames is a stop at once.
   */
  void setDrilling(double now, bool drilling) { monitor_.expectPredictions(now, drilling); }
  /** @brief What setDrilling() last said (false before any and after reset()). */
  bool drilling() const { return monitor_.predictionsExpected(); }

  /** @brief Evaluates the timeouts at `now` if armed (both streams heard, or a trial runs). */
  void check(double now);

  /**
   * @brief Without a new input (sample, prediction or trial phase), check() changes nothing
   *        up to and including the returned time (SafetyMonitor::quietUntil; +infinity while
   *        check() does not evaluate).
   */
  double quietUntil() const {
    return heardBoth() || trial_running_ ? monitor_.quietUntil()
                                         : std::numeric_limits<double>::infinity();
  }

  /**
   * @brief The verdict the first time it is a stop, then never again until reset(): the one
   *        stop command to send.
   */
  std::optional<SafetyVerdict> takeNewStop();

  /** @brief The latched verdict. */
  const SafetyVerdict& verdict() const { return monitor_.verdict(); }

  /** @brief The re-tare check at the end of a retreat (SafetyMonitor::retareCheck). */
  RetareCheck retareCheck(double now) const { return monitor_.retareCheck(now); }

  /** @brief True once both sensor streams were heard since construction or reset(). */
  bool heardBoth() const { return have_force_ && have_tracker_; }

  /** @brief Tracked samples ignored as stale since construction or reset(). */
  long staleTrackedCount() const { return stale_tracked_; }

  /** @brief Clears the latch, the streams and the report. */
  void reset();

  /** @brief Parameters in use. */
  const SupervisorParams& params() const { return params_; }

 private:
  PairResult compare(double now, const StampedPosition& sample, const StampedPosition* partner,
                     bool sample_is_predicted);

  SupervisorParams params_;
  SafetyMonitor monitor_;
  StampPairer pairer_;
  bool have_force_ = false;
  bool have_tracker_ = false;
  double last_tracked_stamp_ = 0.0;
  long stale_tracked_ = 0;
  bool trial_running_ = false;
  bool stop_reported_ = false;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_SAFETY_SUPERVISOR_HPP_
