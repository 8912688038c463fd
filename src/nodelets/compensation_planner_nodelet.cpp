/**
 * @file compensation_planner_nodelet.cpp
 * @brief pedicle_drilling/CompensationPlanner: Algorithm 1 of the paper (Sec. IV-B). Per trial
 *        (`~start_trial`): spindle on, arm to the drilling pose, marker registration, then every
 *        125 ms the next trapezoidal segment of feed (+ predicted displacement in compensated
 *        mode) as a JointTrajectory on `arm_controller/command`; stops on `drill/stop` (hold,
 *        or retreat along the drill axis). Thin wrapper of core::CompensationPlanner and
 *        core::ArmCompensation.
 */
#include <geometry_msgs/PoseStamped.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <std_msgs/Float64.h>
#include <std_msgs/String.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <trajectory_msgs/JointTrajectory.h>
#include <urdf_model/model.h>
#include <urdf_parser/urdf_parser.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "pedicle_drilling/DrillingState.h"
#include "pedicle_drilling/StartTrial.h"
#include "pedicle_drilling/StopCommand.h"
#include "pedicle_drilling/TidalVolume.h"
#include "pedicle_drilling/VentilatorSettings.h"
#include "pedicle_drilling/core/compensation_planner.hpp"
#include "pedicle_drilling/core/motion_model_io.hpp"
#include "pedicle_drilling/core/safety_monitor.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"
#include "pedicle_drilling/ros/ventilator_conversions.hpp"

namespace pedicle_drilling {

/** @brief Nodelet wrapper of core::CompensationPlanner. */
class CompensationPlannerNodelet : public nodelet::Nodelet {
 public:
  ~CompensationPlannerNodelet() override {
    // Join the start thread before any member it may use goes away.
    if (start_spinner_) start_spinner_->stop();
  }

 private:
  enum class Phase { kIdle, kMovingToPose, kRegistering, kDrilling, kStopped, kRetreating, kDone,
                     kFailed };

  static const char* phaseName(Phase p) {
    switch (p) {
      case Phase::kIdle: return "idle";
      case Phase::kMovingToPose: return "moving_to_pose";
      case Phase::kRegistering: return "registering";
      case Phase::kDrilling: return "drilling";
      case Phase::kStopped: return "stopped";
      case Phase::kRetreating: return "retreating";
      case Phase::kDone: return "done";
      case Phase::kFailed: return "failed";
    }
    return "unknown";
  }

  static std::string readTextFile(const std::string& path, const std::string& what) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error(what + " '" + path + "' cannot be opened");
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }

  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    ros::NodeHandle pnh = getPrivateNodeHandle();
    try {
      const ParamLoader params(pnh);
      const std::string model_path = params.getString("patient_model_path", "");
      try {
        patient_ = core::readModelYaml(model_path);
      } catch (const std::exception& e) {
        throw std::runtime_error("patient model file '" + model_path + "' (parameter '" +
                                 pnh.resolveName("patient_model_path") + "'): " + e.what());
      }
      // Robot description: a URDF file, or the robot_description parameter.
      const std::string urdf_path = params.getString("urdf_path", "", true);
      std::string urdf_xml;
      if (!urdf_path.empty()) {
        urdf_xml = readTextFile(urdf_path, "URDF file (parameter ~urdf_path)");
      } else if (!nh.getParam("robot_description", urdf_xml)) {
        params.fail("urdf_path", "is empty and there is no robot_description parameter");
      }
      const std::string base = params.getString("arm_base_link", "world");
      const std::string tip = params.getString("arm_tip_link", "device_base");
      feed_joint_ = params.getString("feed_joint", "feed_joint");
      const core::KinematicChain arm = core::KinematicChain::fromUrdfString(urdf_xml, base, tip);
      const urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(urdf_xml);
      const auto feed = model ? model->getJoint(feed_joint_) : nullptr;
      if (!feed || !feed->limits) params.fail("feed_joint", "'" + feed_joint_ +
                                              "' is not a limited joint of the URDF");
      feed_lower_ = feed->limits->lower;
      feed_upper_ = feed->limits->upper;
      arm_joints_ = arm.jointNames();
      Eigen::VectorXd q(arm_joints_.size());
      for (std::size_t i = 0; i < arm_joints_.size(); ++i) {
        const std::string key = "drilling_pose/" + arm_joints_[i];
        if (!pnh.hasParam(key)) params.fail(key, "is missing (load config/drilling_pose.yaml)");
        q[i] = params.getDouble(key, 0.0, -2.0 * M_PI, 2.0 * M_PI);
      }
      const double feed_home =
          params.getDouble("feed_home_m", 0.01, feed_lower_, 0.5 * feed_upper_);
      arm_comp_ = std::make_unique<core::ArmCompensation>(arm, q, feed_home);

      default_feed_rate_mm_s_ = params.getDouble("feed_rate_mm_s", 0.5, 0.0, 10.0, true);
      default_spindle_rpm_ = params.getDouble("spindle_rpm", 12000.0, 0.0, 60000.0, true);
      default_max_duration_s_ = params.getDouble("max_duration_s", 120.0, 0.0, 3600.0, true);
      base_params_.latency_s = params.getDouble("latency_s", 0.0, 0.0, 1.0);
      base_params_.period_s = params.getDouble("period_s", 0.125, 0.0, 1.0, true);
      base_params_.accel_ratio = params.getDouble("accel_ratio", 10.0, 0.0, 1000.0, true);
      base_params_.points_per_segment = params.getInt("points_per_segment", 5, 1, 100);
      const std::string profile = params.getString("segment_profile", "rest_to_rest");
      if (!core::parseSegmentProfile(profile, &base_params_.segment_profile)) {
        params.fail("segment_profile", "= '" + profile + "' is not blended or rest_to_rest");
      }
      base_params_.compensate_lateral = params.getBool("compensate_si_lr", false);
      base_params_.predict_axis = {{false, false, false}};
      std::stringstream axes(params.getString("predicted_axes", "ap"));
      std::string name;
      while (std::getline(axes, name, ',')) {
        core::Axis a;
        if (!core::parseAxis(name, &a)) {
          params.fail("predicted_axes", "has unknown axis '" + name + "' (use ap, si, lr)");
        }
        base_params_.predict_axis[static_cast<int>(a)] = true;
      }
      base_params_.drill_axis = arm_comp_->drillAxis();
      base_params_.validate();
      move_duration_s_ = params.getDouble("move_duration_s", 2.0, 0.0, 60.0, true);
      settle_s_ = params.getDouble("settle_s", 0.5, 0.0, 60.0);
      registration_samples_ = params.getInt("registration_samples", 4, 1, 100);
      registration_timeout_s_ = params.getDouble("registration_timeout_s", 3.0, 0.0, 60.0, true);
      stop_hold_s_ = params.getDouble("stop_hold_s", 1.0, 0.0, 60.0);
      core::RetreatParams rp;
      rp.distance_m = params.getDouble("retreat_distance_m", 0.025, 0.0, 0.1, true);
      rp.speed_m_s = params.getDouble("retreat_speed_m_s", 0.005, 0.0, 0.05, true);
      rp.accel_m_s2 = params.getDouble("retreat_accel_m_s2", 0.05, 0.0, 1.0, true);
      retreat_planner_ = std::make_unique<core::RetreatPlanner>(rp);
      world_frame_ = params.getString("world_frame", "world");
      trial_start_services_ = params.getStringList(
          "trial_start_services", {"state_recognizer/reset", "safety_monitor/reset"});
      trial_start_timeout_s_ = params.getDouble("trial_start_timeout_s", 2.0, 0.0, 60.0, true);
    } catch (const std::exception& e) {
      startup_status_.fail(nh, getName(), e.what());
      return;
    }
    tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
    tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_);
    trajectory_pub_ = nh.advertise<trajectory_msgs::JointTrajectory>("arm_controller/command", 10);
    spindle_pub_ = nh.advertise<std_msgs::Float64>("spindle/command", 10, true);
    predicted_pub_ =
        nh.advertise<geometry_msgs::PoseStamped>("compensation/predicted_marker_pose", 50);
    status_pub_ = nh.advertise<std_msgs::String>("compensation/status", 10, true);
    const ros::TransportHints hints = ros::TransportHints().tcpNoDelay();
    tidal_sub_ = nh.subscribe("tidal_volume", 10, &CompensationPlannerNodelet::onTidalVolume,
                              this, hints);
    settings_sub_ = nh.subscribe("ventilator/settings", 1,
                                 &CompensationPlannerNodelet::onSettings, this);
    marker_sub_ = nh.subscribe("tracker/marker_pose", 10, &CompensationPlannerNodelet::onMarker,
                               this, hints);
    stop_sub_ = nh.subscribe("drill/stop", 10, &CompensationPlannerNodelet::onStop, this, hints);
    state_sub_ = nh.subscribe("drilling_state", 100, &CompensationPlannerNodelet::onDrillingState,
                              this, hints);
    for (const std::string& name : trial_start_services_) {
      trial_start_clients_.push_back(nh.serviceClient<std_srvs::Trigger>(name));
    }
    // ~start_trial calls other nodelets' services and waits for them: it gets a callback queue
    // and a thread of its own, so that it never blocks the manager's worker threads.
    ros::NodeHandle start_nh(pnh);
    start_nh.setCallbackQueue(&start_queue_);
    start_srv_ = start_nh.advertiseService("start_trial", &CompensationPlannerNodelet::onStartTrial,
                                           this);
    start_spinner_ = std::make_unique<ros::AsyncSpinner>(1, &start_queue_);
    start_spinner_->start();
    setPhase(Phase::kIdle);
    NODELET_INFO("CompensationPlanner: patient '%s', drill axis (%.3f %.3f %.3f), feed home "
                 "%.1f mm, latency %.3f s",
                 patient_.patient_id.c_str(), base_params_.drill_axis.x(),
                 base_params_.drill_axis.y(), base_params_.drill_axis.z(),
                 arm_comp_->feedHome() * 1e3, base_params_.latency_s);
  }

  // ------------------------------------------------------------------------------- inputs

  void onSettings(const VentilatorSettings::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      settings_ = fromMsg(*msg);
      have_settings_ = true;
      if (planner_) planner_->predictor().setVentilator(settings_);
    } catch (const std::exception& e) {
      NODELET_ERROR("CompensationPlanner: ignored invalid ventilator settings: %s", e.what());
    }
  }

  void onTidalVolume(const TidalVolume::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const double start = msg->header.stamp.toSec() - msg->time_in_breath_s;
    if (!std::isfinite(start)) {
      NODELET_WARN_THROTTLE(1.0, "CompensationPlanner: non-finite tidal volume phase ignored");
      return;
    }
    breath_start_ = start;
    have_phase_ = true;
    if (planner_) planner_->predictor().setBreathStart(start);
  }

  void onMarker(const geometry_msgs::PoseStamped::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const double t = msg->header.stamp.toSec();
    const auto& p = msg->pose.position;
    const Eigen::Vector3d pos(p.x, p.y, p.z);
    if (phase_ == Phase::kRegistering) {
      registerSample(*msg, t, pos);
      return;
    }
    if (!registered_ || !planner_ ||
        (phase_ != Phase::kDrilling && phase_ != Phase::kStopped &&
         phase_ != Phase::kRetreating)) {
      return;
    }
    // Predicted marker pose at the tracker's own time stamp, for the SafetyMonitor.
    geometry_msgs::PoseStamped out;
    out.header.stamp = msg->header.stamp;
    out.header.frame_id = marker_frame_;
    const Eigen::Vector3d predicted = marker_reg_ + rotation_ * boneDisplacementSinceMarker(t);
    out.pose.position.x = predicted.x();
    out.pose.position.y = predicted.y();
    out.pose.position.z = predicted.z();
    out.pose.orientation = marker_orientation_;
    predicted_pub_.publish(out);
  }

  /** @brief Predicted bone displacement (world, m) since the registration marker time. */
  Eigen::Vector3d boneDisplacementSinceMarker(double t) const {
    // mode_, not planner_->mode(): the planner only starts after the registration.
    if (mode_ == core::CompensationMode::kStationary) return Eigen::Vector3d::Zero();
    return planner_->predictor().displacement(t) - y_marker_reg_;
  }

  void registerSample(const geometry_msgs::PoseStamped& msg, double t,
                       const Eigen::Vector3d& pos) {
    const double now = ros::Time::now().toSec();
    if (now > registration_deadline_) {
      fail("no usable tracker/marker_pose message for registration");
      return;
    }
    if (msg.header.stamp < registration_open_) return;  // measured before the arm settled
    if (!pos.allFinite()) {
      fail("non-finite marker pose during registration");
      return;
    }
    if (reg_count_ == 0) {
      marker_frame_ = msg.header.frame_id;
      if (marker_frame_.empty() || marker_frame_ == world_frame_) {
        rotation_ = Eigen::Matrix3d::Identity();
      } else {
        if (!tf_buffer_->canTransform(marker_frame_, world_frame_, ros::Time(0))) {
          NODELET_WARN_THROTTLE(1.0, "CompensationPlanner: waiting for tf %s -> %s",
                                world_frame_.c_str(), marker_frame_.c_str());
          return;
        }
        const auto tf = tf_buffer_->lookupTransform(marker_frame_, world_frame_, ros::Time(0));
        const auto& r = tf.transform.rotation;
        rotation_ = Eigen::Quaterniond(r.w, r.x, r.y, r.z).normalized().toRotationMatrix();
      }
      t_marker_reg_ = t;
      y_marker_reg_ = mode_ == core::CompensationMode::kStationary
                          ? Eigen::Vector3d::Zero()
                          : planner_->predictor().displacement(t);
      marker_orientation_ = msg.pose.orientation;
      marker_sum_.setZero();
    } else if (msg.header.frame_id != marker_frame_) {
      fail("marker frame changed during registration");
      return;
    }
    // Average the samples, each moved back to the first sample's time by the prediction.
    const Eigen::Vector3d moved = rotation_ * boneDisplacementSinceMarker(t);
    NODELET_DEBUG("CompensationPlanner: registration sample %d at t=%.3f: (%.5f %.5f %.5f) m, "
                  "predicted motion since the first (%.5f %.5f %.5f) m",
                  reg_count_, t, pos.x(), pos.y(), pos.z(), moved.x(), moved.y(), moved.z());
    marker_sum_ += pos - moved;
    if (++reg_count_ < registration_samples_) return;
    marker_reg_ = marker_sum_ / reg_count_;
    registered_ = true;
    startDrilling(now);
  }

  // ------------------------------------------------------------------------------- trial

  bool onStartTrial(StartTrial::Request& req, StartTrial::Response& res) {
    // Runs on the planner's own start thread (see onInit), so the blocking calls below never
    // hold a worker thread of the nodelet manager that the reset services themselves need.
    std::unique_lock<std::mutex> lock(mutex_);
    res.success = false;
    if (phase_ != Phase::kIdle && phase_ != Phase::kDone && phase_ != Phase::kFailed) {
      res.message = std::string("a trial is running (status ") + phaseName(phase_) + ")";
      return true;
    }
    core::CompensationMode mode;
    if (!core::parseCompensationMode(req.mode, &mode)) {
      res.message = "mode: unknown mode '" + req.mode +
                    "' (use stationary, uncompensated or compensated)";
      return true;
    }
    auto pick = [&res](double requested, double fallback, double max, const char* name,
                       double* out) {
      if (requested == 0.0) {
        *out = fallback;
      } else if (!(std::isfinite(requested) && requested > 0.0 && requested <= max)) {
        res.message = std::string(name) + ": must be 0 (default) or in (0, " +
                      std::to_string(max) + "]";
        return false;
      } else {
        *out = requested;
      }
      return true;
    };
    double feed_mm_s = 0.0;
    if (!pick(req.feed_rate_mm_s, default_feed_rate_mm_s_, 10.0, "feed_rate_mm_s", &feed_mm_s) ||
        !pick(req.spindle_rpm, default_spindle_rpm_, 60000.0, "spindle_rpm", &spindle_rpm_) ||
        !pick(req.max_duration_s, default_max_duration_s_, 3600.0, "max_duration_s",
              &max_duration_s_)) {
      return true;
    }
    if (mode != core::CompensationMode::kStationary && !(have_settings_ && have_phase_)) {
      res.message = std::string(core::toString(mode)) +
                    " mode needs the ventilator: no ventilator/settings or tidal_volume received";
      return true;
    }
    // Every component of the trial starts afresh, here and nowhere else, so that no caller
    // can forget one: a component that cannot be reset refuses the trial, nothing drills.
    // No lock held while calling: the components' answers may need this nodelet's callbacks.
    lock.unlock();
    const bool started = startComponents(&res.message);
    lock.lock();
    if (!started) return true;
    // The patient model is read again for every trial, so a new identification (a new
    // ~patient_model_path, or a rewritten file) applies to the next trial.
    std::string model_path;
    if (getPrivateNodeHandle().getParam("patient_model_path", model_path)) {
      try {
        patient_ = core::readModelYaml(model_path);
      } catch (const std::exception& e) {
        res.message = "patient model file '" + model_path + "' (parameter '" +
                      getPrivateNodeHandle().resolveName("patient_model_path") + "'): " + e.what();
        return true;
      }
    }
    core::CompensationParams params = base_params_;
    params.feed_rate_m_s = feed_mm_s * 1e-3;
    try {
      planner_ = std::make_unique<core::CompensationPlanner>(params, patient_.motionModel());
      if (have_settings_) planner_->predictor().setVentilator(settings_);
      if (have_phase_) planner_->predictor().setBreathStart(breath_start_);
    } catch (const std::exception& e) {
      res.message = e.what();
      return true;
    }
    mode_ = mode;
    registered_ = false;
    reg_count_ = 0;
    arm_q_ = arm_comp_->homeJoints();
    publishSpindle(spindle_rpm_);
    sendMoveToPose();
    setPhase(Phase::kMovingToPose);
    const ros::NodeHandle& nh = getNodeHandle();
    pose_timer_ = nh.createTimer(ros::Duration(move_duration_s_ + settle_s_),
                                  &CompensationPlannerNodelet::onPoseReached, this, true);
    res.success = true;
    res.message = std::string("trial started: ") + core::toString(mode) + ", feed " +
                  std::to_string(feed_mm_s) + " mm/s, spindle " + std::to_string(spindle_rpm_) +
                  " rpm";
    NODELET_INFO("CompensationPlanner: %s", res.message.c_str());
    return true;
  }

  /**
   * @brief Calls every service of ~trial_start_services (std_srvs/Trigger) in order: the
   *        recognizer's and the safety monitor's ~reset, and on the simulator its start_trial.
   * @return false with the reason in *why when one is missing or refuses.
   */
  bool startComponents(std::string* why) {
    for (ros::ServiceClient& client : trial_start_clients_) {
      const std::string name = client.getService();
      if (!client.waitForExistence(ros::Duration(trial_start_timeout_s_))) {
        *why = "trial refused: service " + name + " is not available (is its nodelet loaded? "
               "parameter ~trial_start_services); nothing was started";
        return false;
      }
      std_srvs::Trigger srv;
      if (!client.call(srv)) {
        *why = "trial refused: the call to " + name + " failed; nothing was started";
        return false;
      }
      if (!srv.response.success) {
        *why = "trial refused: " + name + " answered: " + srv.response.message +
               "; nothing was started";
        return false;
      }
      NODELET_INFO("CompensationPlanner: %s: %s", name.c_str(), srv.response.message.c_str());
    }
    return true;
  }

  /**
   * @brief The recognizer's state. A stop it reports (latched) is a stop here too, so that a
   *        lost drill/stop, or a recognizer whose latch survived from an earlier trial, never
   *        lets the drill feed on.
   */
  void onDrillingState(const DrillingState::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    recognizer_reports_stop_ = msg->stop;
    if (msg->stop && phase_ == Phase::kDrilling) {
      handleStop(ros::Time::now().toSec(), false,
                 "drilling_state reports a recognizer stop (state " + msg->state_name +
                     ", key point " + std::to_string(msg->last_key_point) + ")");
    }
  }

  void sendMoveToPose() {
    trajectory_msgs::JointTrajectory traj;
    traj.header.stamp = ros::Time::now();
    traj.joint_names = arm_joints_;
    traj.joint_names.push_back(feed_joint_);
    trajectory_msgs::JointTrajectoryPoint goal;
    for (int i = 0; i < arm_q_.size(); ++i) goal.positions.push_back(arm_q_[i]);
    goal.positions.push_back(arm_comp_->feedHome());
    goal.velocities.assign(goal.positions.size(), 0.0);
    goal.time_from_start = ros::Duration(move_duration_s_);
    // One point: the controller moves from its own current state (JointTrajectoryController
    // semantics), which stays right when a component reset the robot before this trial.
    traj.points.push_back(goal);
    trajectory_pub_.publish(traj);
  }

  void onPoseReached(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (phase_ != Phase::kMovingToPose) return;
    registration_open_ = ros::Time::now();
    registration_deadline_ = registration_open_.toSec() + registration_timeout_s_;
    setPhase(Phase::kRegistering);
    registration_timer_ = getNodeHandle().createTimer(ros::Duration(registration_timeout_s_),
                                               &CompensationPlannerNodelet::onRegistrationTimeout,
                                               this, true);
  }

  void onRegistrationTimeout(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (phase_ == Phase::kRegistering) {
      fail("no tracker/marker_pose message for registration within " +
           std::to_string(registration_timeout_s_) + " s");
    }
  }

  void startDrilling(double now) {
    registration_timer_.stop();
    if (recognizer_reports_stop_) {
      fail("refusing to feed: the StateRecognizer reports a stop latched from an earlier trial "
           "(drilling_state.stop); reset it (~reset, or list it in ~trial_start_services)");
      return;
    }
    planner_->start(mode_, now);
    t_end_ = now + max_duration_s_;
    next_k_ = 0;
    retreat_.reset();
    setPhase(Phase::kDrilling);
    NODELET_INFO("CompensationPlanner: marker registered (%d samples), drilling (%s)",
                 reg_count_, core::toString(mode_));
    sendDueSegments(now);
    segment_timer_ = getNodeHandle().createTimer(
        ros::Duration(planner_->params().period_s), &CompensationPlannerNodelet::onSegmentTimer,
        this);
  }

  void onSegmentTimer(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    const double now = ros::Time::now().toSec();
    if (phase_ == Phase::kDrilling && now >= t_end_) {
      NODELET_WARN("CompensationPlanner: max duration reached, retracting");
      startRetreat(now, "max duration");
    } else if (phase_ == Phase::kStopped && now >= hold_end_) {
      startRetreat(now, "stop hold elapsed");
    } else if (phase_ == Phase::kRetreating && retreat_ && retreat_->finished(now)) {
      segment_timer_.stop();
      setPhase(Phase::kDone);
      return;
    }
    if (phase_ == Phase::kDrilling || phase_ == Phase::kStopped ||
        phase_ == Phase::kRetreating) {
      sendDueSegments(now);
    }
  }

  /** @brief Feed-joint and arm command at time t (segmented trajectory, hold, retreat). */
  double feedCommandAt(double t, double segmented_feed) const {
    double feed = arm_comp_->feedHome() + segmented_feed;
    if (retreat_) feed -= retreat_->position(t).x();
    return std::clamp(feed, feed_lower_, feed_upper_);
  }

  /** @brief Send every segment starting within one period from now (one period ahead). */
  void sendDueSegments(double now) {
    const double period = planner_->params().period_s;
    while (planner_->registrationTime() + next_k_ * period <= now + period) {
      const core::PlannedSegment seg = planner_->segment(next_k_);
      ++next_k_;
      if (seg.t1 <= now) continue;  // late timer: skip segments already over
      std::vector<double> times;
      std::vector<double> feeds;
      std::vector<double> feed_velocities;
      std::vector<Eigen::Vector3d> lateral;
      const auto add = [&](const core::PlannedPoint& pt) {
        times.push_back(pt.t);
        feeds.push_back(pt.feed_m);
        feed_velocities.push_back(pt.feed_velocity_m_s);
        lateral.push_back(pt.lateral_m);
      };
      // A trajectory message replaces what remains of the one running (JointTrajectory
      // semantics). Blended: repeat the rest of the running segment, so that the velocity-
      // continuous path runs as planned, with the planned velocities while drilling (a hold
      // or retreat adds to the feed; its velocities then come from the points). Rest to rest
      // (the paper's default): segment k alone, ending at rest; the joint goes from where it
      // is to segment k's first point.
      const bool blended = planner_->params().segment_profile == core::SegmentProfile::kBlended;
      if (blended && seg.index > 0) {
        for (const core::PlannedPoint& pt : planner_->segment(seg.index - 1).points) {
          if (pt.t > now) add(pt);
        }
      }
      for (const core::PlannedPoint& pt : seg.points) add(pt);
      publishTrajectory(ros::Time(blended ? seg.t0 - period : seg.t0), times, feeds, lateral,
                        blended && phase_ == Phase::kDrilling ? &feed_velocities : nullptr);
      if (phase_ == Phase::kDrilling &&
          arm_comp_->feedHome() + seg.feed_end_m > feed_upper_ - 1e-3) {
        NODELET_WARN("CompensationPlanner: feed axis travel exhausted, retracting");
        startRetreat(now, "feed travel exhausted");
        return;
      }
    }
  }

  /**
   * @brief One JointTrajectory of the arm joints and the feed joint. Feed velocities are
   *        `feed_velocities` when given (the planned ones), else differences of the points.
   */
  void publishTrajectory(const ros::Time& start, const std::vector<double>& times,
                         const std::vector<double>& feeds,
                         const std::vector<Eigen::Vector3d>& lateral,
                         const std::vector<double>* feed_velocities = nullptr) {
    trajectory_msgs::JointTrajectory traj;
    traj.header.stamp = start;
    traj.joint_names = arm_joints_;
    traj.joint_names.push_back(feed_joint_);
    double prev_t = start.toSec();
    double prev_feed = times.empty() ? 0.0 : feedCommandAt(prev_t, feeds.front());
    Eigen::VectorXd prev_q = arm_q_;
    for (std::size_t i = 0; i < times.size(); ++i) {
      Eigen::VectorXd q = arm_q_;
      if (planner_->params().compensate_lateral && lateral[i].norm() > 1e-9) {
        try {
          q = arm_comp_->lateral(lateral[i], arm_q_);
          arm_q_ = q;
        } catch (const std::exception& e) {
          NODELET_ERROR_THROTTLE(1.0, "CompensationPlanner: %s; arm held", e.what());
        }
      }
      const double feed = feedCommandAt(times[i], feeds[i]);
      const double dt = std::max(1e-6, times[i] - prev_t);
      trajectory_msgs::JointTrajectoryPoint pt;
      for (int j = 0; j < q.size(); ++j) {
        pt.positions.push_back(q[j]);
        pt.velocities.push_back(i + 1 == times.size() ? 0.0 : (q[j] - prev_q[j]) / dt);
      }
      pt.positions.push_back(feed);
      pt.velocities.push_back(feed_velocities != nullptr ? (*feed_velocities)[i]
                              : i + 1 == times.size()    ? 0.0
                                                         : (feed - prev_feed) / dt);
      pt.time_from_start = ros::Duration(times[i] - start.toSec());
      traj.points.push_back(pt);
      prev_t = times[i];
      prev_feed = feed;
      prev_q = q;
    }
    last_feed_command_ = prev_feed;
    trajectory_pub_.publish(traj);
  }

  /** @brief Replace the trajectory from now to the next segment boundary (after a stop). */
  void resendFromNow(double now) {
    const double period = planner_->params().period_s;
    const int k = planner_->segmentIndexAt(now);
    const double t_end = planner_->registrationTime() + (k + 1) * period;
    const int n = planner_->params().points_per_segment;
    std::vector<double> times;
    std::vector<double> feeds;
    std::vector<Eigen::Vector3d> lateral;
    for (int i = 1; i <= n; ++i) {
      const double t = now + (t_end - now) * i / n;
      const Eigen::Vector3d r = planner_->segmentedReference(t);
      const double f = r.dot(planner_->axis());
      times.push_back(t);
      feeds.push_back(f);
      lateral.push_back(r - f * planner_->axis());
    }
    publishTrajectory(ros::Time(now), times, feeds, lateral);
    next_k_ = k + 1;
    sendDueSegments(now);
  }

  void onStop(const StopCommand::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    NODELET_WARN("CompensationPlanner: stop from %s (retreat %s): %s", msg->source.c_str(),
                 msg->retreat ? "yes" : "no", msg->reason.c_str());
    handleStop(ros::Time::now().toSec(), msg->retreat, msg->reason);
  }

  /** @brief A stop (recognizer: hold then retract; monitor: retreat at once). */
  void handleStop(double now, bool retreat, const std::string& reason) {
    switch (phase_) {
      case Phase::kMovingToPose:
      case Phase::kRegistering:
        fail("stopped before drilling began: " + reason);
        return;
      case Phase::kDrilling:
      case Phase::kStopped:
        publishSpindle(0.0);
        planner_->holdFeed(now);
        if (retreat) {
          startRetreat(now, reason);
        } else if (phase_ == Phase::kDrilling) {
          hold_end_ = now + stop_hold_s_;
          setPhase(Phase::kStopped);
          resendFromNow(now);
        }
        return;
      default:
        return;  // idle, already retreating, done: nothing to stop
    }
  }

  void startRetreat(double now, const std::string& why) {
    publishSpindle(0.0);
    planner_->holdFeed(now);
    // The held feed the trajectory settles at (the segment in progress ends there).
    const double feed_now = feedCommandAt(now, planner_->referenceFeed(now));
    // Back along the drill axis (feed coordinate), clamped at the retracted end of the feed.
    const double distance =
        std::min(retreat_planner_->params().distance_m, feed_now - feed_lower_);
    const core::RetreatParams& rp = retreat_planner_->params();
    retreat_ = std::make_unique<core::RetreatMotion>(
        now, Eigen::Vector3d::Zero(), Eigen::Vector3d(std::max(distance, 0.0), 0, 0),
        core::TrapezoidProfile::minimumTime(std::max(distance, 0.0), rp.speed_m_s,
                                            rp.accel_m_s2));
    NODELET_WARN("CompensationPlanner: retreating %.1f mm (%s)", distance * 1e3, why.c_str());
    setPhase(Phase::kRetreating);
    resendFromNow(now);
  }

  void fail(const std::string& why) {
    NODELET_ERROR("CompensationPlanner: trial failed: %s", why.c_str());
    publishSpindle(0.0);
    segment_timer_.stop();
    pose_timer_.stop();
    registration_timer_.stop();
    setPhase(Phase::kFailed);
  }

  void publishSpindle(double rpm) {
    std_msgs::Float64 msg;
    msg.data = rpm;
    spindle_pub_.publish(msg);
  }

  void setPhase(Phase p) {
    phase_ = p;
    std_msgs::String msg;
    msg.data = phaseName(p);
    status_pub_.publish(msg);
  }

  std::mutex mutex_;
  StartupStatus startup_status_;
  core::PatientModel patient_;
  std::unique_ptr<core::ArmCompensation> arm_comp_;
  std::unique_ptr<core::CompensationPlanner> planner_;
  std::unique_ptr<core::RetreatPlanner> retreat_planner_;
  std::unique_ptr<core::RetreatMotion> retreat_;
  core::CompensationParams base_params_;
  core::CompensationMode mode_ = core::CompensationMode::kStationary;
  std::vector<std::string> arm_joints_;
  std::string feed_joint_;
  std::string world_frame_;
  double feed_lower_ = 0.0;
  double feed_upper_ = 0.06;
  double default_feed_rate_mm_s_ = 0.5;
  double default_spindle_rpm_ = 12000.0;
  double default_max_duration_s_ = 120.0;
  double spindle_rpm_ = 0.0;
  double max_duration_s_ = 0.0;
  double move_duration_s_ = 2.0;
  double settle_s_ = 0.5;
  int registration_samples_ = 4;
  double registration_timeout_s_ = 3.0;
  double stop_hold_s_ = 1.0;
  std::vector<std::string> trial_start_services_;
  double trial_start_timeout_s_ = 2.0;
  bool recognizer_reports_stop_ = false;

  core::VentilatorSettings settings_;
  bool have_settings_ = false;
  double breath_start_ = 0.0;
  bool have_phase_ = false;

  Phase phase_ = Phase::kIdle;
  ros::Time registration_open_;
  double registration_deadline_ = 0.0;
  int reg_count_ = 0;
  bool registered_ = false;
  std::string marker_frame_;
  Eigen::Matrix3d rotation_ = Eigen::Matrix3d::Identity();
  double t_marker_reg_ = 0.0;
  Eigen::Vector3d y_marker_reg_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d marker_sum_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d marker_reg_ = Eigen::Vector3d::Zero();
  geometry_msgs::Quaternion marker_orientation_;
  Eigen::VectorXd arm_q_;
  double last_feed_command_ = 0.0;
  double t_end_ = 0.0;
  double hold_end_ = 0.0;
  int next_k_ = 0;

  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  ros::Publisher trajectory_pub_;
  ros::Publisher spindle_pub_;
  ros::Publisher predicted_pub_;
  ros::Publisher status_pub_;
  ros::Subscriber tidal_sub_;
  ros::Subscriber settings_sub_;
  ros::Subscriber marker_sub_;
  ros::Subscriber stop_sub_;
  ros::Subscriber state_sub_;
  std::vector<ros::ServiceClient> trial_start_clients_;
  ros::CallbackQueue start_queue_;
  std::unique_ptr<ros::AsyncSpinner> start_spinner_;
  ros::ServiceServer start_srv_;
  ros::Timer pose_timer_;
  ros::Timer registration_timer_;
  ros::Timer segment_timer_;
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::CompensationPlannerNodelet, nodelet::Nodelet)
