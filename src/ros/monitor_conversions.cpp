#include "pedicle_drilling/ros/monitor_conversions.hpp"

namespace pedicle_drilling {

RetareCheck toMsg(const core::RetareCheck& check, double limit_n, const ros::Time& stamp) {
  RetareCheck result;
  result.header.stamp = stamp;
  result.done = check.done;
  result.samples = check.samples;
  result.offset_n = check.offset_n;
  result.limit_n = limit_n;
  result.drift = check.drift;
  result.message = check.message;
  return result;
}

StopCommand toStopMsg(const core::SafetyVerdict& verdict, const std::string& source,
                      const ros::Time& stamp) {
  StopCommand stop;
  stop.header.stamp = stamp;
  stop.source = source;
  stop.retreat = true;
  stop.reason = core::describe(verdict);
  return stop;
}

core::StampedPosition toStamped(const geometry_msgs::PoseStamped& msg) {
  const auto& p = msg.pose.position;
  return {msg.header.stamp.toSec(), msg.header.frame_id, Eigen::Vector3d(p.x, p.y, p.z)};
}

void fillStatus(const core::MonitorStatus& monitor,
                diagnostic_updater::DiagnosticStatusWrapper* status) {
  using Level = core::MonitorStatus::Level;
  status->summary(monitor.level == Level::kError  ? diagnostic_msgs::DiagnosticStatus::ERROR
                  : monitor.level == Level::kWarn ? diagnostic_msgs::DiagnosticStatus::WARN
                                                  : diagnostic_msgs::DiagnosticStatus::OK,
                  monitor.message);
  for (const auto& [key, value] : monitor.values) status->add(key, value);
}

}  // namespace pedicle_drilling
