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

/** @brief The error a nodelet's onInit throws after StartupStatus::fail reported it. */
class StartupError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/** @brief Reports startup failures of the nodelets of this process. */
class StartupStatus {
 public:
  /**
   * @brief Logs @p what as FATAL, adds an ERROR status named "<node_name>: startup" to the
   *        process's latched /diagnostics array (every failure of this process so far, so that
   *        two failed nodelets in one manager are both seen by a late subscriber), and throws.
   * @throws StartupError always: the nodelet must not be loaded.
   */
  [[noreturn]] void fail(ros::NodeHandle& /*nh*/, const std::string& node_name,
                         const std::string& what) {
    ROS_FATAL_STREAM(node_name << " not started: " << what);
    Registry& r = registry();
    {
      std::lock_guard<std::mutex> lock(r.mutex);
      if (!r.publisher) {
        // A global handle: the publisher and its latched message outlive the dropped nodelet.
        ros::NodeHandle global;
        r.publisher = global.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 1, true);
      }
      r.failures.header.stamp = ros::Time::now();
      diagnostic_msgs::DiagnosticStatus status;
      status.level = diagnostic_msgs::DiagnosticStatus::ERROR;
      status.name = node_name + ": startup";
      status.hardware_id = node_name;
      status.message = "not started: " + what;
      r.failures.status.push_back(status);
      r.publisher.publish(r.failures);
    }
    throw StartupError(node_name + " not started: " + what);
  }

 private:
  struct Registry {
    std::mutex mutex;
    ros::Publisher publisher;
    diagnostic_msgs::DiagnosticArray failures;
  };
  /** @brief Process-wide, never destroyed (no static destruction after ROS has shut down). */
  static Registry& registry() {
    static Registry* r = new Registry;
    return *r;
  }
};

}  // namespace pedicle_drilling
