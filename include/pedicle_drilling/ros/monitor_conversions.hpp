// The SafetyMonitor's conversions between the core's types (core::MonitorRuntime) and messages.
#ifndef PEDICLE_DRILLING_ROS_MONITOR_CONVERSIONS_HPP_
#define PEDICLE_DRILLING_ROS_MONITOR_CONVERSIONS_HPP_

#include <diagnostic_updater/DiagnosticStatusWrapper.h>
#include <geometry_msgs/PoseStamped.h>
#include <ros/time.h>

#include <string>

#include "pedicle_drilling/RetareCheck.h"
#include "pedicle_drilling/StopCommand.h"
#include "pedicle_drilling/core/control/monitor_runtime.hpp"

namespace pedicle_drilling {

/** @brief The re-tare check @p check against the limit @p limit_n [N], stamped @p stamp. */
RetareCheck toMsg(const core::RetareCheck& check, double limit_n, const ros::Time& stamp);

/** @brief The monitor's stop and retreat for @p verdict, from @p source, stamped @p stamp. */
StopCommand toStopMsg(const core::SafetyVerdict& verdict, const std::string& source,
                      const ros::Time& stamp);

/** @brief A marker pose as the supervisor pairs it: its stamp, frame and position. */
core::StampedPosition toStamped(const geometry_msgs::PoseStamped& msg);

/** @brief The monitor's status into a diagnostic task's @p status: level, message, values. */
void fillStatus(const core::MonitorStatus& monitor,
                diagnostic_updater::DiagnosticStatusWrapper* status);

}  // namespace pedicle_drilling

#endif  // PEDICLE_DRILLING_ROS_MONITOR_CONVERSIONS_HPP_
