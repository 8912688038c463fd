// Monitor of Algorithm 1 (paper Sec. IV-B) and the retreat motion it triggers.
//
// Stop conditions (the first one that occurs is latched until reset()):
//   * position error  ||y_pred - P_rec|| > H1 = 1.2 mm   (predicted vs tracked bone position)
//   * force           ||F_rec|| > H2 = 10 N
//   * force timeout   no force sample for more than force_timeout_s
//   * tracker timeout no tracker sample for more than tracker_timeout_s
//   * prediction lost while the drill may be in bone (expectPredictions): no predicted / tracked
//                     pair compared for more than prediction_timeout_s, or a pair in two frames
//   * force stuck     the same force vector, bit for bit, for longer than force_stuck_s
//   * NaN / inf in any input (including its time stamp)
// Timeouts are measured from the last sample of that stream or, if none has arrived since
// reset(), from the first call of any method after reset() (arming time).
#ifndef PEDICLE_DRILLING_CORE_SAFETY_MONITOR_HPP_
#define PEDICLE_DRILLING_CORE_SAFETY_MONITOR_HPP_

#include <deque>
#include <string>
#include <utility>

#include <Eigen/Core>

#include "pedicle_drilling/core/common/param_table.hpp"
#include "pedicle_drilling/core/control/trapezoid_segmenter.hpp"

namespace pedicle_drilling::core {

/** @brief Thresholds of the monitor. */
struct SafetyParams {
  /** @brief H1 [m]: max distance between predicted and tracked bone position (Algorithm 1). */
  double position_threshold_m = 1.2e-3;
  /** @brief H2 [N]: max norm of the measured force (Algorithm 1). */
  double force_threshold_N = 10.0;
  /**
   * @brief Max age [s] of the latest force sample. Default 0.1 s: 100 periods of a 1 kHz
   * force sensor, 2 of the 20 Hz pre-averaged stream; long enough to ride over scheduling
   * jitter, short enough that the drill advances only 50 um at 0.5 mm/s.
   */
  double force_timeout_s = 0.1;
  /**
   * @brief Max age [s] of the latest tracker sample. Default 0.5 s: 4 periods of the 8 Hz
   * optical tracker (Sec. III-A); the bone moves at most about 4 mm in that time at the
   * paper's breathing amplitude, so losing the tracker longer is not acceptable.
   */
  double tracker_timeout_s = 0.5;
  /**
   * @brief Max time [s] without an H1 comparison while the drill may be in bone (the planner's
   * drilling and stopped phases). Default 0.5 s, the tracker's timeout: the planner predicts
   * the marker at every tracker sample (8 Hz), so a live pipeline compares every 0.125 s; a
   * prediction that is missing, stale (no tracked sample within the pairing tolerance) or in
   * another frame stops the drill as a silent tracker does, within this plus one check period.
   */
  double prediction_timeout_s = 0.5;
  /**
   * @brief Max time [s] the force vector may stay bit-identical. Default 0.05 s: a live sensor's
   * noise (0.03 N, about 10 counts of the Nano17's 1/320 N per axis) changes at least one axis in
   * almost every sample (three axes repeating: p ~ 2e-5), so 50 identical 1 kHz samples mean a
   * frozen driver or DAQ that still publishes. +inf disables (a noise-free sensor).
   */
  double force_stuck_s = 0.05;
  /**
   * @brief Re-tare check [N]: at the end of a trial's retreat (the drill out of the bone, the
   * spindle off) the mean force over `retare_window_s` must be within this of the tare. Default
   * 0.3 N: 10 x the sensor's noise SD (0.03 N; the mean of the window's ~80 samples has an SE of
   * 0.003 N, the Nano17's resolution is 1/320 N, its bias random walk 1e-3 N/sqrt(s) adds under
   * 0.01 N in a minute), and a third or less of the forces the recognizer separates (cancellous
   * about 1 N, cortical 2-3 N): a drift that can move its key points is seen. 0: off.
   */
  double retare_max_offset_n = 0.3;
  /** @brief Window [s] of the re-tare check's mean, ending at the retreat's end. */
  double retare_window_s = 0.25;

  /**
   * @brief Check all fields against table() (thresholds finite and > 0; timeouts > 0, +inf
   * disables). @throws std::invalid_argument whose message starts with the parameter name.
   */
  void validate() const;

  /** @brief The declaration of every field: name (as the ROS parameter), range, unit. */
  static const ParamTable<SafetyParams>& table();
};

/** @brief Monitor result. */
struct SafetyVerdict {
  /** @brief Cause of a stop. */
  enum Reason {
    kNone,
    kPositionError,
    kForceExceeded,
    kForceTimeout,
    kTrackerTimeout,
    kNaNInput,
    kForceStuck,
    kPredictionLost,
  };
  bool stop = false;      ///< True: stop drilling and retreat.
  Reason reason = kNone;  ///< First cause (latched).
  double t = 0.0;         ///< Time of the trigger [s] (valid if stop).
  std::string message;    ///< Human-readable explanation (empty if no stop).
};

/** @brief The re-tare check at the end of a trial's retreat (SafetyParams::retare_max_offset_n). */
struct RetareCheck {
  bool done = false;    ///< false: no force sample in the window (nothing to say)
  double t = 0.0;       ///< time of the check [s]
  int samples = 0;      ///< force samples averaged
  double offset_n = 0;  ///< norm of their mean force [N]: the sensor's offset from its tare
  bool drift = false;   ///< offset_n > retare_max_offset_n (and the check on)
  std::string message;  ///< "force_offset: ..." when drift
};

/** @brief Name of a reason, e.g. "position_error". */
const char* toString(SafetyVerdict::Reason r);

/** @brief "reason: message" of a verdict (the StopCommand's reason). */
std::string describe(const SafetyVerdict& v);

/** @brief The monitor system of Algorithm 1, as a plain latched state machine. */
class SafetyMonitor {
 public:
  /**
   * @brief Construct.
   * @throws std::invalid_argument if params.validate() fails.
   */
  explicit SafetyMonitor(const SafetyParams& params = SafetyParams());

  /** @brief Feed a force sample [N] measured at time t [s]. */
  void onForce(double t, const Eigen::Vector3d& force);

  /**
   * @brief Feed a tracker sample at time t: predicted (model) and tracked bone positions [m]
   * in the same frame.
   */
  void onTracked(double t, const Eigen::Vector3d& predicted_bone_pos,
                 const Eigen::Vector3d& tracked_bone_pos);

  /**
   * @brief H1 and the NaN check on a predicted / tracked pair at time t, without feeding the
   *        tracker watchdog: a prediction is not a sign that the tracker is alive.
   */
  void comparePositions(double t, const Eigen::Vector3d& predicted_bone_pos,
                        const Eigen::Vector3d& tracked_bone_pos);

  /**
   * @brief From time t on, a predicted / tracked pair must be compared at least every
   *        prediction_timeout_s (true), or not (false): H1 fails closed while the drill may be
   *        in bone. Turning it on starts the wait at t.
   */
  void expectPredictions(double t, bool expected);
  /** @brief Whether expectPredictions(true) is in force. */
  bool predictionsExpected() const { return expect_predictions_; }
  /**
   * @brief A pair that cannot be compared (its samples in two frames) at time t: a stop while
   *        predictions are expected, nothing otherwise.
   * @return true when it stopped.
   */
  bool rejectPair(double t, const std::string& why);

  /** @brief Evaluate timeouts at time t and return the (latched) verdict. */
  const SafetyVerdict& check(double t);

  /**
   * @brief Without a new input, check(t) changes nothing for any t <= the returned time: the
   *        earlier of the two streams' timeouts (last sample, or the arming time, plus the
   *        timeout); -infinity before arming (the next check arms), +infinity once stopped.
   *        A check that cannot change anything may be skipped (the lockstep's fewer steps).
   */
  double quietUntil() const;

  /** @brief Current verdict without evaluating timeouts. */
  const SafetyVerdict& verdict() const { return verdict_; }

  /** @brief True once a stop has been latched. */
  bool stopped() const { return verdict_.stop; }

  /**
   * @brief The re-tare check at time t, the end of a retreat: the mean of the force samples of
   *        the last retare_window_s against the tare (zero). Does not latch a stop: the drill is
   *        already out; a drift says the trial's force-based decisions are not to be trusted.
   */
  RetareCheck retareCheck(double t) const;
  /** @brief Clear the latch and forget all samples; timeouts re-arm on the next call. */
  void reset();

  /** @brief Thresholds in use. */
  const SafetyParams& params() const { return params_; }

 private:
  void arm(double t);
  /** @brief false (and a kNaNInput stop) when any of them is not finite. */
  bool finiteOrStop(double t, const Eigen::Vector3d& predicted_bone_pos,
                    const Eigen::Vector3d& tracked_bone_pos);
  void trigger(SafetyVerdict::Reason r, double t, const std::string& msg);

  SafetyParams params_;
  SafetyVerdict verdict_;
  bool armed_ = false;
  double armed_t_ = 0.0;
  bool have_force_ = false;
  double last_force_t_ = 0.0;
  Eigen::Vector3d last_force_ = Eigen::Vector3d::Zero();
  double same_force_since_ = 0.0;  ///< time of the first sample of the current identical run
  std::deque<std::pair<double, Eigen::Vector3d>> recent_forces_;  ///< the re-tare window
  bool have_tracker_ = false;
  double last_tracker_t_ = 0.0;
  bool expect_predictions_ = false;
  double last_compared_t_ = 0.0;  ///< the latest H1 comparison, or when the wait started
};

/** @brief Parameters of the retreat motion. */
struct RetreatParams {
  /** @brief Retreat distance along -axis [m]. Default 10 mm: clears the 2-4 mm of bone drilled
   * so far plus the soft-tissue entry, while staying inside the trocar. */
  double distance_m = 10e-3;
  /** @brief Cruise speed [m/s]. Default 5 mm/s (10 x the 0.5 mm/s feed): out in about 2.1 s. */
  double speed_m_s = 5e-3;
  /**
   * @brief Acceleration [m/s^2]. Default 1 m/s^2, half the drill device's feed-drive limit
   * (2 m/s^2, doc/simulator_physics.md): 5 mm/s within 5 ms, so that a bone moving into the
   * stopped drill does not keep cutting while the retreat speeds up. Chosen on calibration seeds
   * against the earlier 50 mm/s^2 (10 x the speed, the paper's segment ratio): the cut after the
   * stop command fell from 0.17 to 0.03 mm at most (doc/campaign_results.md).
   */
  double accel_m_s2 = 1.0;

  /** @brief Check all fields against table(). @throws std::invalid_argument naming the field. */
  void validate() const;

  /** @brief The declaration of every field (ROS names retreat_distance_m, ...). */
  static const ParamTable<RetreatParams>& table();
};

/** @brief A planned retreat: straight line back along the drill axis, trapezoidal speed. */
class RetreatMotion {
 public:
  /** @brief Motion from `start` to `target`, beginning at t0. */
  RetreatMotion(double t0, const Eigen::Vector3d& start, const Eigen::Vector3d& target,
                const TrapezoidProfile& profile);
  /** @brief Tip position at t (start before t0, exactly target after the end). */
  Eigen::Vector3d position(double t) const { return segment_.position(t); }
  /** @brief Tip velocity at t. */
  Eigen::Vector3d velocity(double t) const { return segment_.velocity(t); }
  /** @brief True once t >= end time. */
  bool finished(double t) const { return t >= segment_.endTime(); }
  /** @brief Start time [s]. */
  double startTime() const { return segment_.startTime(); }
  /** @brief End time [s]. */
  double endTime() const { return segment_.endTime(); }
  /** @brief Final tip position. */
  const Eigen::Vector3d& target() const { return segment_.end(); }
  /** @brief The 1-D profile. */
  const TrapezoidProfile& profile() const { return segment_.profile(); }

 private:
  Segment segment_;
};

/** @brief Plans the "retreat" of Algorithm 1 line 9. */
class RetreatPlanner {
 public:
  /** @brief Construct. @throws std::invalid_argument if params.validate() fails. */
  explicit RetreatPlanner(const RetreatParams& params = RetreatParams());

  /**
   * @brief Plan a retreat starting at t0 from the current tip position, moving
   * params.distance_m against `drill_axis` (the drilling direction; normalised internally).
   * @throws std::invalid_argument for a zero or non-finite axis or non-finite inputs.
   */
  RetreatMotion plan(double t0, const Eigen::Vector3d& tip,
                     const Eigen::Vector3d& drill_axis) const;

  /** @brief Parameters in use. */
  const RetreatParams& params() const { return params_; }

 private:
  RetreatParams params_;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_SAFETY_MONITOR_HPP_
