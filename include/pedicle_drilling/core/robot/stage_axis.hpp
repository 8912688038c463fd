/**
 * @file stage_axis.hpp
 * @brief One servo-driven linear axis (motor, belt, lead screw, slider): a position loop with
 *        velocity feed-forward whose speed and acceleration are limited, as the SPMS's three
 *        sliders are (paper Sec. II-B, Fig. 3). Figures and sources: doc/simulator_physics.md §4.
 *
 * Per step dt, with the set-point r and its velocity r' at the start of the step (a sampled
 * controller reads its set-point, then drives for one period):
 *   u* = clamp(r' + 2 pi f_bw (r - x), -v_max, v_max)   (velocity command of the drive)
 *   u  = u + clamp(u* - u, -a_max dt, a_max dt)          (the motor's torque limit)
 *   x  = x + u dt
 * A reference within the limits is followed with no steady error (the feed-forward), a step in
 * the reference's velocity is rounded by a_max and the position error it leaves decays with the
 * loop's time constant 1 / (2 pi f_bw).
 */
#ifndef PEDICLE_DRILLING_CORE_STAGE_AXIS_HPP
#define PEDICLE_DRILLING_CORE_STAGE_AXIS_HPP

#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling::core {

/** @brief Limits and loop bandwidth of a lead-screw axis. */
struct StageAxisParams {
  double max_speed_m_s = 0.05;  ///< speed limit [m/s] (URDF slider limit: 50 mm/s)
  double max_accel_m_s2 = 2.0;  ///< acceleration limit [m/s^2]
  double bandwidth_hz = 20.0;   ///< position-loop bandwidth [Hz]
  /** @brief Every field finite and > 0. @throws std::invalid_argument naming the field. */
  void validate() const;
  /** @brief The declaration of every field. */
  static const ParamTable<StageAxisParams>& table();
};

/** @brief The axis (StageAxisParams, file comment). */
class StageAxis {
 public:
  /** @brief An axis at rest at `position`. @throws std::invalid_argument for bad params. */
  explicit StageAxis(const StageAxisParams& params = StageAxisParams(), double position = 0.0);
  /** @brief Puts the axis at rest at `position` (a homing). */
  void reset(double position);
  /**
   * @brief Advances by dt > 0 with the set-point (position [m], velocity [m/s]) at the start of
   *        the step; returns the position at its end [m]. A NaN/inf set-point holds.
   */
  double step(double dt, double ref_position, double ref_velocity);
  /** @brief Position [m]. */
  double position() const { return x_; }
  /** @brief Velocity [m/s]. */
  double velocity() const { return u_; }
  /** @brief The parameters. */
  const StageAxisParams& params() const { return params_; }

 private:
  StageAxisParams params_;
  double x_ = 0.0;
  double u_ = 0.0;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_STAGE_AXIS_HPP
