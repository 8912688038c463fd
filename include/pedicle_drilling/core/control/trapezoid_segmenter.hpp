// Time-segmented trapezoidal approximation of the compensation trajectory (paper Sec. IV-B).
//
// The reference (feed along the drill axis + predicted bone displacement) is cut into segments
// of `period` (125 ms). Each segment moves in a straight line from the reference at its start
// time to the reference at its end time, starting and ending at rest, with a symmetric
// trapezoidal velocity profile whose acceleration is `accel_ratio` times its cruise velocity
// ("acceleration 10 times the velocity").
//
// Feasibility: with a = r * v_c the ramp time is t_a = v_c / a = 1 / r, independent of the
// distance. Two ramps must fit in the period: 2 / r <= T. The paper's numbers (r = 10 /s,
// T = 0.125 s) give 2 t_a = 0.2 s > 0.125 s, so the literal profile cannot finish inside its
// own period. We therefore use the effective ratio r_eff = max(r, 2 / T): for r >= 2 / T the
// profile is the paper's trapezoid (t_a = 1 / r); otherwise it is the triangular (bang-bang)
// profile with t_a = T / 2, peak velocity 2 L / T and |a| = 4 L / T^2 = r_eff * v_peak, the
// smallest acceleration that still reaches the segment end on time. Every segment therefore
// ends exactly at its end point at t0 + T; positions are continuous across segments, the
// velocity is zero at every boundary.
#ifndef PEDICLE_DRILLING_CORE_TRAPEZOID_SEGMENTER_HPP_
#define PEDICLE_DRILLING_CORE_TRAPEZOID_SEGMENTER_HPP_

#include <functional>
#include <string>

#include <Eigen/Core>

namespace pedicle_drilling::core {

/**
 * @brief 1-D symmetric trapezoidal (or triangular) motion from s = 0 to s = length, at rest at
 * both ends. Time tau is relative to the start of the motion.
 */
struct TrapezoidProfile {
  double length = 0.0;    ///< Distance travelled [m] (>= 0).
  double duration = 0.0;  ///< Total time [s].
  double t_acc = 0.0;     ///< Ramp (acceleration = deceleration) time [s].
  double v_peak = 0.0;    ///< Cruise (peak) speed [m/s].
  double accel = 0.0;     ///< Acceleration magnitude [m/s^2].

  /**
   * @brief Profile of fixed duration whose acceleration is ratio * cruise speed, with the ratio
   * raised to 2 / duration if needed (see file comment).
   * @throws std::invalid_argument for length < 0, duration <= 0, ratio <= 0 or non-finite.
   */
  static TrapezoidProfile fixedDuration(double length, double duration, double accel_ratio);

  /**
   * @brief Minimum-time profile with speed and acceleration limits.
   * @throws std::invalid_argument for length < 0, v_max <= 0, a_max <= 0 or non-finite.
   */
  static TrapezoidProfile minimumTime(double length, double v_max, double a_max);

  /** @brief Distance travelled at tau (clamped to [0, length]). */
  double distance(double tau) const;
  /** @brief Speed at tau (0 outside [0, duration]). */
  double speed(double tau) const;
  /** @brief Signed acceleration at tau (0 outside [0, duration]). */
  double acceleration(double tau) const;
};

/** @brief One straight-line segment of the segmented trajectory. */
class Segment {
 public:
  /** @brief Segment from p0 at t0 to p1 at t0 + profile.duration. */
  Segment(double t0, const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
          const TrapezoidProfile& profile);

  /** @brief Position at absolute time t (p0 before t0, exactly p1 from the end time on). */
  Eigen::Vector3d position(double t) const;
  /** @brief Velocity at absolute time t (zero outside the segment). */
  Eigen::Vector3d velocity(double t) const;
  /** @brief Acceleration at absolute time t (zero outside the segment). */
  Eigen::Vector3d acceleration(double t) const;

  /** @brief Start time [s]. */
  double startTime() const { return t0_; }
  /** @brief End time [s]. */
  double endTime() const { return t0_ + profile_.duration; }
  /** @brief Start point. */
  const Eigen::Vector3d& start() const { return p0_; }
  /** @brief End point. */
  const Eigen::Vector3d& end() const { return p1_; }
  /** @brief The 1-D profile along the segment. */
  const TrapezoidProfile& profile() const { return profile_; }

 private:
  double t0_;
  Eigen::Vector3d p0_;
  Eigen::Vector3d p1_;
  Eigen::Vector3d dir_;  // unit direction (zero for a zero-length segment)
  TrapezoidProfile profile_;
};

/** @brief How the segments join (CompensationParams::segment_profile). */
enum class SegmentProfile {
  /// Each segment is a trapezoid (triangle at the paper's numbers) from rest to rest.
  kRestToRest,
  /// Beyond the paper: the reference itself, sampled densely with its analytic velocities and
  /// with knots at the ventilator's flow steps (CompensationPlanner), no trapezoids.
  kExact,
};

/** @brief Name of a profile: "rest_to_rest" or "exact". */
const char* toString(SegmentProfile profile);
/** @brief Parses "rest_to_rest" or "exact"; false otherwise (also for "blended", a
 *         velocity-continuous profile retired once "exact" beat it: doc/nodes.md). */
bool parseSegmentProfile(const std::string& name, SegmentProfile* profile);

/** @brief Position and velocity of a segmented trajectory at one time. */
struct SegmentSample {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< [m]
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  ///< [m/s]
};

/** @brief Cuts a reference trajectory into fixed-period trapezoidal segments (Sec. IV-B). */
class TrapezoidSegmenter {
 public:
  /** @brief Reference trajectory: time [s] -> 3-D target offset [m]. */
  using Reference = std::function<Eigen::Vector3d(double)>;

  /**
   * @brief Construct.
   * @param period_s segment period T [s] (> 0, paper: 0.125).
   * @param accel_ratio r [1/s]: acceleration = r * cruise velocity (> 0, paper: 10).
   * @throws std::invalid_argument naming the bad parameter.
   */
  explicit TrapezoidSegmenter(double period_s = 0.125, double accel_ratio = 10.0);

  /** @brief Plan one segment from p0 at t0 to p1 at t0 + period. */
  Segment plan(double t0, const Eigen::Vector3d& p0, const Eigen::Vector3d& p1) const;

  /**
   * @brief The segment containing time t of the segmented version of `ref`, whose segments
   * start at t_start + k * period and go from ref(t_start + k T) to ref(t_start + (k + 1) T).
   * Times before t_start use segment 0.
   */
  Segment segmentAt(const Reference& ref, double t_start, double t) const;

  /** @brief Position of the segmented version of `ref` at time t (see segmentAt). */
  Eigen::Vector3d sample(const Reference& ref, double t_start, double t) const;

  /**
   * @brief Upper bound of |segmented(t) - ref(t)| for a reference with speed <= v_max and
   * acceleration <= a_max: delta * v_max * T + a_max * T^2 / 8, where
   * delta = t_a (T - t_a) / (2 T^2) is the largest lag of the profile behind uniform motion
   * (1/8 for the triangular profile) and a_max T^2 / 8 the chord (sagitta) error.
   */
  double trackingErrorBound(double v_max, double a_max) const;

  /** @brief Segment period T [s]. */
  double period() const { return period_; }
  /** @brief Requested acceleration ratio r [1/s]. */
  double accelRatio() const { return accel_ratio_; }
  /** @brief Ratio actually used: max(r, 2 / T). */
  double effectiveAccelRatio() const;

 private:
  double period_;
  double accel_ratio_;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_TRAPEZOID_SEGMENTER_HPP_
