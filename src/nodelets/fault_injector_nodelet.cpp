/**
 * @file fault_injector_nodelet.cpp
 * @brief pedicle_drilling/FaultInjector: relays the force sensor, the tracker and the arm's
 *        trajectory commands, and injects one fault into them on request (`~inject`), as the
 *        core engine's fault campaign does (core::FaultInjector, the same class). Put it between
 *        a real or simulated sensor and the pipeline to prove that the pipeline fails safe.
 *        Relays: ft_sensor/wrench_raw -> ft_sensor/wrench, tracker/marker_pose_raw ->
 *        tracker/marker_pose, and for each of ~controllers (arm_controller, feed_controller)
 *        <name>/command -> <name>/command_delivered, and drill/stop -> drill/stop_delivered (the
 *        stop_lost fault; the planner hears the relayed stops when its drill/stop subscription is
 *        remapped to drill/stop_delivered). The parts of one planner command (the messages with
 *        one header stamp, one per controller) share one fault decision, as the core engine
 *        applies a fault to the planner's whole command. What the fault did (core::FaultCounts)
 *        is published latched on ~status (diagnostic_msgs/DiagnosticStatus, key-values).
 */
#include <diagnostic_msgs/DiagnosticStatus.h>
#include <diagnostic_msgs/KeyValue.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <trajectory_msgs/JointTrajectory.h>
#include <pluginlib/class_list_macros.hpp>

#include <cmath>
#include <list>
#include <memory>
#include <mutex>
#include <string>

#include "pedicle_drilling/InjectFault.h"
#include "pedicle_drilling/StopCommand.h"
#include "pedicle_drilling/core/sim/fault_injector.hpp"
#include "pedicle_drilling/ros/lockstep.hpp"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/publish_in_order.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"

namespace pedicle_drilling {

/** @brief Nodelet wrapper of core::FaultInjector on three ROS streams. */
class FaultInjectorNodelet : public nodelet::Nodelet {
 public:
  /** @brief No relay callback runs once the members go (an unload from a running manager). */
  ~FaultInjectorNodelet() override {
    wrench_sub_.shutdown();
    marker_sub_.shutdown();
    for (ros::Subscriber& sub : command_subs_) sub.shutdown();
    stop_sub_.shutdown();
    inject_srv_.shutdown();
    status_timer_.stop();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (ros::Timer& t : delayed_) t.stop();
    }
    // roscpp does not wait for a callback already queued on a queue the nodelet manager does
    // not own: let the participants' thread run past whatever it holds of ours.
    if (shared_queue_) LockstepParticipant::drainSharedQueue();
  }

 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    ros::NodeHandle pnh = getPrivateNodeHandle();
    try {
      FaultInjectorNodeParams params;
      ParamLoader(pnh).load(FaultInjectorNodeParams::table(), &params);
      injector_ = std::make_unique<core::FaultInjector>(params.faults);
      controllers_ = params.controllers;
      shared_queue_ = useSimLockstep();
    } catch (const std::exception& e) {
      failStartup(getName(), e.what());  // throws: the load fails
    }
    wrench_pub_ = nh.advertise<geometry_msgs::WrenchStamped>("ft_sensor/wrench", 2000);
    marker_pub_ = nh.advertise<geometry_msgs::PoseStamped>("tracker/marker_pose", 20);
    for (const std::string& c : controllers_) {
      command_pubs_.push_back(
          nh.advertise<trajectory_msgs::JointTrajectory>(c + "/command_delivered", 10));
    }
    // Under the simulator's lockstep the relays run on the participants' thread, in the order
    // the simulator's messages arrived, before its next step: a relayed sample reaches the
    // safety monitor before the monitor's next check, whatever the load of the machine. On the
    // nodelet manager's worker threads a 50 ms scheduling gap at real_time_factor 2 was a
    // force timeout (0.1 s sim time) before any fault was injected.
    if (shared_queue_) {
      nh.setCallbackQueue(LockstepParticipant::sharedQueue());
      pnh.setCallbackQueue(LockstepParticipant::sharedQueue());
    }
    relay_nh_ = nh;
    const ros::TransportHints hints = ros::TransportHints().tcpNoDelay();
    wrench_sub_ =
        nh.subscribe("ft_sensor/wrench_raw", 2000, &FaultInjectorNodelet::onWrench, this, hints);
    marker_sub_ =
        nh.subscribe("tracker/marker_pose_raw", 20, &FaultInjectorNodelet::onMarker, this, hints);
    for (std::size_t i = 0; i < controllers_.size(); ++i) {
      command_subs_.push_back(nh.subscribe<trajectory_msgs::JointTrajectory>(
          controllers_[i] + "/command", 10,
          [this, i](const trajectory_msgs::JointTrajectory::ConstPtr& msg) { onCommand(i, msg); },
          ros::VoidConstPtr(), hints));
    }
    stop_pub_ = nh.advertise<StopCommand>("drill/stop_delivered", 10);
    stop_sub_ = nh.subscribe("drill/stop", 10, &FaultInjectorNodelet::onStop, this, hints);
    status_pub_ = pnh.advertise<diagnostic_msgs::DiagnosticStatus>("status", 1, true);
    publishStatus();
    status_timer_ = nh.createWallTimer(ros::WallDuration(0.2),
                                       [this](const ros::WallTimerEvent&) { publishStatus(); });
    inject_srv_ = pnh.advertiseService("inject", &FaultInjectorNodelet::onInject, this);
    NODELET_INFO(
        "FaultInjector: relaying ft_sensor/wrench_raw, tracker/marker_pose_raw and the "
        "controllers' commands; faults through %s",
        inject_srv_.getService().c_str());
  }

  void onWrench(const geometry_msgs::WrenchStamped::ConstPtr& msg) {
    geometry_msgs::WrenchStamped out = *msg;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      Eigen::Vector3d f(msg->wrench.force.x, msg->wrench.force.y, msg->wrench.force.z);
      if (!injector_->force(msg->header.stamp.toSec(), &f)) return;  // silent sensor
      out.wrench.force.x = f.x();
      out.wrench.force.y = f.y();
      out.wrench.force.z = f.z();
      if (injector_->kind() == core::FaultKind::kForceNaN && injector_->injected()) {
        // a NaN sensor gives NaN on every axis
        out.wrench.torque.x = out.wrench.torque.y = out.wrench.torque.z = f.x();
      }
    }
    publishInOrder(wrench_pub_, out);
  }

  void onMarker(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    geometry_msgs::PoseStamped out = *msg;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      const auto& p = msg->pose.position;
      const auto& q = msg->pose.orientation;
      Eigen::Vector3d position(p.x, p.y, p.z);
      Eigen::Quaterniond orientation(q.w, q.x, q.y, q.z);
      double stamp = msg->header.stamp.toSec();
      if (!injector_->trackedPose(&position, &orientation, &stamp)) return;  // silent tracker
      out.header.stamp = ros::Time(stamp);
      out.pose.position.x = position.x();
      out.pose.position.y = position.y();
      out.pose.position.z = position.z();
      out.pose.orientation.w = orientation.w();
      out.pose.orientation.x = orientation.x();
      out.pose.orientation.y = orientation.y();
      out.pose.orientation.z = orientation.z();
    }
    publishInOrder(marker_pub_, out);
  }

  void onCommand(std::size_t controller, const trajectory_msgs::JointTrajectory::ConstPtr& msg) {
    double extra = 0.0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      // One decision per planner command: its parts carry one header stamp.
      if (!have_decision_ || msg->header.stamp != decided_stamp_) {
        decided_extra_ = injector_->command(ros::Time::now().toSec());
        decided_stamp_ = msg->header.stamp;
        have_decision_ = true;
      }
      extra = decided_extra_;
    }
    if (extra < 0.0) {
      NODELET_WARN("FaultInjector: command_lost: a trajectory command was dropped");
      return;
    }
    if (extra == 0.0) {
      command_pubs_[controller].publish(msg);  // a ConstPtr: shared, in order
      return;
    }
    // Delivered late with its own stamp: the controller treats its points as a late message's.
    NODELET_WARN("FaultInjector: command_delayed: a trajectory command held %.3f s", extra);
    std::lock_guard<std::mutex> lock(mutex_);
    delayed_.push_back(relay_nh_.createTimer(
        ros::Duration(extra),
        [this, controller, msg](const ros::TimerEvent&) {
          command_pubs_[controller].publish(msg);  // a ConstPtr: shared, in order
        },
        true));
  }

  void onStop(const StopCommand::ConstPtr& msg) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!injector_->stop()) {
        NODELET_WARN("FaultInjector: stop_lost: a drill/stop from %s was dropped",
                     msg->source.c_str());
        return;
      }
    }
    stop_pub_.publish(msg);
  }

  /** @brief ~status: the armed fault, whether it acted and what it did (when it changed). */
  void publishStatus() {
    diagnostic_msgs::DiagnosticStatus status;
    status.name = getName();
    status.hardware_id = "fault_injector";
    {
      std::lock_guard<std::mutex> lock(mutex_);
      const core::FaultCounts& c = injector_->counts();
      const auto add = [&status](const std::string& key, const std::string& value) {
        diagnostic_msgs::KeyValue kv;
        kv.key = key;
        kv.value = value;
        status.values.push_back(kv);
      };
      add("fault", core::toString(injector_->kind()));
      add("injected", injector_->injected() ? "true" : "false");
      add("injection_time", std::to_string(injector_->injectionTime()));
      add("force_dropped", std::to_string(c.force_dropped));
      add("force_altered", std::to_string(c.force_altered));
      add("tracker_dropped", std::to_string(c.tracker_dropped));
      add("tracker_altered", std::to_string(c.tracker_altered));
      add("commands_lost", std::to_string(c.commands_lost));
      add("commands_delayed", std::to_string(c.commands_delayed));
      add("stops_lost", std::to_string(c.stops_lost));
    }
    const bool active = injected(status);
    status.level =
        active ? diagnostic_msgs::DiagnosticStatus::WARN : diagnostic_msgs::DiagnosticStatus::OK;
    status.message = active ? "fault injected" : "relaying";
    if (have_status_ && status.values == last_status_.values) return;
    last_status_ = status;
    have_status_ = true;
    status_pub_.publish(status);
  }

  static bool injected(const diagnostic_msgs::DiagnosticStatus& s) {
    return s.values.size() > 1 && s.values[1].value == "true";
  }

  bool onInject(InjectFault::Request& req, InjectFault::Response& res) {
    std::lock_guard<std::mutex> lock(mutex_);
    core::FaultKind kind = core::FaultKind::kNone;
    try {
      kind = core::parseFaultKind(req.fault);
    } catch (const std::exception& e) {
      res.success = false;
      res.message = e.what();
      return true;
    }
    if (!ros::Time::isSimTime()) {
      // On hardware (no /use_sim_time) a fault injected into the real sensor streams would
      // act on a patient: refused, whatever the caller.
      res.success = false;
      res.message =
          "refused: the FaultInjector injects on the simulator only (/use_sim_time is "
          "not true)";
      NODELET_ERROR("FaultInjector: inject '%s' %s", req.fault.c_str(), res.message.c_str());
      return true;
    }
    if (core::isProcessFault(kind)) {
      res.success = false;
      res.message = "fault '" + req.fault +
                    "' kills a process: the core engine's; on the ROS pipeline kill the "
                    "process with a signal (rostests fault_planner_killed, fault_monitor_killed)";
      return true;
    }
    if (kind == core::FaultKind::kControllerAborted) {
      res.success = false;
      res.message =
          "fault '" + req.fault + "' is a controller's: the simulator's simulator/abort_controller";
      return true;
    }
    if (core::isBreathingFault(kind)) {
      res.success = false;
      res.message = "fault '" + req.fault +
                    "' is the patient's, not a stream's: the FaultInjector relays the force, "
                    "tracker and command streams only";
      return true;
    }
    if (kind != core::FaultKind::kNone && injector_->kind() == kind &&
        (injector_->injected() || injector_->pending())) {
      res.success = false;
      res.message = "fault '" + req.fault + "' is already injected; inject 'none' to clear it";
      return true;
    }
    injector_->arm(kind);
    injector_->inject(ros::Time::now().toSec());
    res.success = true;
    res.message = kind == core::FaultKind::kNone ? "faults cleared" : "injected " + req.fault;
    NODELET_WARN("FaultInjector: %s", res.message.c_str());
    return true;
  }

  bool shared_queue_ = false;  ///< the relays run on LockstepParticipant::sharedQueue()
  ros::NodeHandle relay_nh_;   ///< the relays' node handle (its queue)
  std::mutex mutex_;
  std::unique_ptr<core::FaultInjector> injector_;
  ros::Publisher wrench_pub_, marker_pub_;
  ros::Subscriber wrench_sub_, marker_sub_;
  std::vector<std::string> controllers_;       ///< ~controllers
  std::vector<ros::Publisher> command_pubs_;   ///< <controller>/command_delivered
  std::vector<ros::Subscriber> command_subs_;  ///< <controller>/command
  bool have_decision_ = false;
  ros::Time decided_stamp_;     ///< the planner command the last decision was for
  double decided_extra_ = 0.0;  ///< and the decision (injector_->command())
  ros::ServiceServer inject_srv_;
  std::list<ros::Timer> delayed_;
  ros::Publisher stop_pub_;    ///< drill/stop_delivered
  ros::Subscriber stop_sub_;   ///< drill/stop
  ros::Publisher status_pub_;  ///< ~status
  ros::WallTimer status_timer_;
  bool have_status_ = false;
  diagnostic_msgs::DiagnosticStatus last_status_;  ///< the last one published (timer thread)
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::FaultInjectorNodelet, nodelet::Nodelet)
