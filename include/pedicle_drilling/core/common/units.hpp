/**
 * @file units.hpp
 * @brief Spindle speed between the paper's unit (rpm) and ROS's (REP 103: rad/s), as the
 *        planner publishes it and a spindle driver reads it.
 */
#pragma once

#include <cmath>

namespace pedicle_drilling::core {

/** @brief The speed @p rpm in rad/s (the unit of `spindle/command`). */
inline double radPerSecFromRpm(double rpm) { return rpm * (M_PI / 30.0); }

/**
 * @brief The speed @p rad_s in rpm, at the drive's setpoint resolution of 0.001 rpm (a drive
 *        takes a fixed-point speed; the rounding also makes rpm -> rad/s -> rpm give back
 *        12000 exactly). NaN and infinities pass through (the driver rejects them).
 */
inline double rpmFromRadPerSec(double rad_s) {
  if (!std::isfinite(rad_s)) return rad_s;
  return std::round(rad_s * (30.0 / M_PI) * 1000.0) / 1000.0;
}

}  // namespace pedicle_drilling::core
