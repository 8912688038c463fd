/**
 * @file startup_status.hpp
 * @brief Reports why a nodelet refused to start, and refuses the load: a FATAL log line, a
 *        latched diagnostic_msgs/DiagnosticArray on /diagnostics (level ERROR, the message names
 *        the bad parameter or file) that outlives the nodelet, and an exception out of onInit,
 *        so that the nodelet loader drops the nodelet: the manager's load service answers
 *        failure, `nodelet load` and `nodelet standalone` exit non-zero, and a launch file's
 *        required="true" or a supervisor sees it (nodelet's Loader::load catches the exception
 *        thrown by init and returns false).
 */
#pragma once

#include <diagnostic_msgs/DiagnosticArray.h>
#include <ros/ros.h>

#include <mutex>
#include <stdexcept>
#include <string>

namespace pedicle_drilling {

/** @brief The error a nodelet's onInit throws after failStartup reported it. */
class StartupError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/**
 * @brief Logs @p what as FATAL, adds an ERROR status named "<node_name>: startup" to the
 *        process's latched /diagnostics array (every startup failure of this process so far, so
 *        that two failed nodelets in one manager are both seen by a late subscriber), and throws.
 * @throws StartupError always: the nodelet must not be loaded.
 */
[[noreturn]] inline void failStartup(const std::string& node_name, const std::string& what) {
  ROS_FATAL_STREAM(node_name << " not started: " << what);
  struct Registry {
    std::mutex mutex;
    ros::Publisher publisher;
    diagnostic_msgs::DiagnosticArray failures;
  };
  // Process-wide and never destroyed (no static destruction after ROS has shut down); a global
  // handle, so the publisher and its latched message outlive the dropped nodelet.
  static Registry* registry = new Registry;
  {
    std::lock_guard<std::mutex> lock(registry->mutex);
    if (!registry->publisher) {
      registry->publisher =
          ros::NodeHandle().advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 1, true);
    }
    registry->failures.header.stamp = ros::Time::now();
    diagnostic_msgs::DiagnosticStatus status;
    status.level = diagnostic_msgs::DiagnosticStatus::ERROR;
    status.name = node_name + ": startup";
    status.hardware_id = node_name;
    status.message = "not started: " + what;
    registry->failures.status.push_back(status);
    registry->publisher.publish(registry->failures);
  }
  throw StartupError(node_name + " not started: " + what);
}

}  // namespace pedicle_drilling
