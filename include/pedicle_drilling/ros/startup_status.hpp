/**
 * @file startup_status.hpp
 * @brief Reports why a nodelet refused to start: a FATAL log line and a latched
 *        diagnostic_msgs/DiagnosticArray on /diagnostics (level ERROR, the message names the bad
 *        parameter or file), so that a late subscriber or a supervisor still sees it.
 */
#pragma once

#include <diagnostic_msgs/DiagnosticArray.h>
#include <ros/ros.h>

#include <string>

namespace pedicle_drilling {

/** @brief Holds the latched publisher of a startup failure for the nodelet's lifetime. */
class StartupStatus {
 public:
  /**
   * @brief Logs @p what as FATAL and latches an ERROR diagnostic named after @p node_name.
   *        The nodelet then stays in its safe state: no outputs advertised.
   */
  void fail(ros::NodeHandle& nh, const std::string& node_name, const std::string& what) {
    ROS_FATAL_STREAM(node_name << " not started: " << what);
    publisher_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 1, true);
    diagnostic_msgs::DiagnosticArray array;
    array.header.stamp = ros::Time::now();
    diagnostic_msgs::DiagnosticStatus status;
    status.level = diagnostic_msgs::DiagnosticStatus::ERROR;
    status.name = node_name + ": startup";
    status.hardware_id = node_name;
    status.message = "not started: " + what;
    array.status.push_back(status);
    publisher_.publish(array);
  }

 private:
  ros::Publisher publisher_;
};

}  // namespace pedicle_drilling
