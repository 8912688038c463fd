/**
 * @file simulator_nodelet.cpp
 * @brief pedicle_drilling/Simulator: the simulated workcell (core::DrillingSimulation) behind
 *        the ROS interfaces a real setup would have. A dedicated thread steps the 1 kHz physics,
 *        owns /clock (when ~publish_clock) and paces the simulation at ~real_time_factor.
 *
 * Interfaces (see README "pedicle_drilling/Simulator"): publishes /clock, joint_states,
 * ft_sensor/wrench (1 kHz), tf + tf_static, tracker/marker_pose (8 Hz), simulator/ground_truth;
 * subscribes arm_controller/command (trajectory_msgs/JointTrajectory), spindle/command
 * (std_msgs/Float64, rpm); service simulator/reset (ResetSimulation).
 */
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/JointState.h>
#include <std_msgs/Float64.h>
#include <std_srvs/Trigger.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <trajectory_msgs/JointTrajectory.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "pedicle_drilling/GroundTruth.h"
#include "pedicle_drilling/ResetSimulation.h"
#include "pedicle_drilling/TidalVolume.h"
#include "pedicle_drilling/VentilatorSettings.h"
#include "pedicle_drilling/core/drilling_simulation.hpp"
#include "pedicle_drilling/core/motion_model_io.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"
#include "pedicle_drilling/ros/startup_status.hpp"
#include "pedicle_drilling/ros/trial_distribution_params.hpp"
#include "pedicle_drilling/ros/ventilator_conversions.hpp"

namespace pedicle_drilling {

namespace {

// Number of physics steps between two publications at rate_hz (at least 1).
int periodSteps(double physics_rate_hz, double rate_hz) {
  return std::max(1, static_cast<int>(std::lround(physics_rate_hz / rate_hz)));
}

}  // namespace

/** @brief Nodelet wrapper of core::DrillingSimulation with its own stepping thread. */
class SimulatorNodelet : public nodelet::Nodelet {
 public:
  ~SimulatorNodelet() override {
    running_ = false;
    if (thread_.joinable()) thread_.join();
  }

 private:
  void onInit() override {
    ros::NodeHandle nh = getNodeHandle();
    ros::NodeHandle pnh = getPrivateNodeHandle();
    std::string urdf_path;
    try {
      const ParamLoader params(pnh);
      urdf_path = params.getString("urdf_path", "", true);
      if (urdf_path.empty()) {
        params.fail("urdf_path", "must name the workcell URDF file (urdf/workcell.urdf)");
      }
      core::DrillingSimulationParams sp;
      sp.arm_rate_hz = params.getDouble("arm_rate_hz", 250.0, 1.0, 1000.0);
      if (std::abs(1000.0 / sp.arm_rate_hz - std::round(1000.0 / sp.arm_rate_hz)) > 1e-9) {
        params.fail("arm_rate_hz", "must divide the 1000 Hz physics rate (e.g. 1000, 500, 250)");
      }
      sp.slider_max_speed_m_s = params.getDouble("slider_max_speed_m_s", 0.05, 0.0, 1.0, true);
      sp.spindle_accel_rpm_s =
          params.getDouble("spindle_accel_rpm_s", 40000.0, 0.0, 1.0e6, true);
      sp.tracker_noise_rms_mm = params.getDouble("tracker_noise_rms_mm", 0.25, 0.0, 10.0);
      sp.sensor.force_noise_sd_n = params.getDouble("force_noise_sd_n", 0.03, 0.0, 10.0);
      sp.moving_bone = params.getBool("moving_bone", true);
      sp.ventilator = loadVentilatorSettings(ParamLoader(ros::NodeHandle(pnh, "ventilator")));
      const TrialDistributionParams distribution = loadTrialDistribution(pnh);
      sp.specimen = distribution.specimen;
      sp.variability = distribution.variability;
      const int seed = params.getInt("seed", 1, 0, 2147483647);
      real_time_factor_ = params.getDouble("real_time_factor", 1.0, 0.0, 1000.0);
      publish_clock_ = params.getBool("publish_clock", true);
      clock_period_steps_ = params.getInt("clock_period_ms", 1, 1, 100);
      joint_state_period_ =
          periodSteps(1000.0, params.getDouble("joint_state_rate_hz", 100.0, 0.0, 1000.0, true));
      tf_period_ = periodSteps(1000.0, params.getDouble("tf_rate_hz", 100.0, 0.0, 1000.0, true));
      ground_truth_period_ = periodSteps(
          1000.0, params.getDouble("ground_truth_rate_hz", 100.0, 0.0, 1000.0, true));
      tracker_period_ =
          periodSteps(1000.0, params.getDouble("tracker_rate_hz", 8.0, 0.0, 1000.0, true));
      // The simulated ventilator is the device that drives the patient: it publishes what the
      // Ventilator nodelet publishes on hardware-free setups (0 disables it).
      const double tv_rate = params.getDouble("tidal_volume_rate_hz", 64.0, 0.0, 1000.0);
      tidal_volume_period_ = tv_rate > 0.0 ? periodSteps(1000.0, tv_rate) : 0;

      std::ifstream in(urdf_path);
      if (!in) {
        throw std::runtime_error("cannot read the URDF file '" + urdf_path +
                                 "' (parameter '" + pnh.resolveName("urdf_path") + "')");
      }
      std::stringstream xml;
      xml << in.rdbuf();
      try {
        sim_ = std::make_unique<core::DrillingSimulation>(xml.str(), sp,
                                                          static_cast<std::uint64_t>(seed));
      } catch (const std::exception& e) {
        throw std::runtime_error("URDF '" + urdf_path + "' is not a usable workcell: " +
                                 e.what());
      }
    } catch (const std::exception& e) {
      // Safe state: nothing is advertised, the error names the parameter or the file.
      startup_status_.fail(nh, getName(), e.what());
      return;
    }
    if (publish_clock_) {
      clock_pub_ = nh.advertise<rosgraph_msgs::Clock>("/clock", 10);
    } else {
      time_offset_ = ros::Time::now().toSec();
    }
    joint_state_pub_ = nh.advertise<sensor_msgs::JointState>("joint_states", 100);
    wrench_pub_ = nh.advertise<geometry_msgs::WrenchStamped>("ft_sensor/wrench", 2000);
    marker_pub_ = nh.advertise<geometry_msgs::PoseStamped>("tracker/marker_pose", 20);
    ground_truth_pub_ = nh.advertise<GroundTruth>("simulator/ground_truth", 200);
    if (tidal_volume_period_ > 0) {
      tidal_volume_pub_ = nh.advertise<TidalVolume>("tidal_volume", 200);
      ventilator_settings_pub_ = nh.advertise<VentilatorSettings>("ventilator/settings", 1, true);
      ventilator_settings_pub_.publish(toMsg(sim_->ventilator().model().settings()));
    }
    tf_broadcaster_ = std::make_unique<tf2_ros::TransformBroadcaster>();
    static_broadcaster_ = std::make_unique<tf2_ros::StaticTransformBroadcaster>();
    trajectory_sub_ = nh.subscribe("arm_controller/command", 10,
                                   &SimulatorNodelet::onTrajectory, this);
    spindle_sub_ = nh.subscribe("spindle/command", 10, &SimulatorNodelet::onSpindle, this);
    reset_srv_ = nh.advertiseService("simulator/reset", &SimulatorNodelet::onReset, this);
    start_trial_srv_ =
        nh.advertiseService("simulator/start_trial", &SimulatorNodelet::onStartTrial, this);
    publishStaticTransforms();
    NODELET_INFO("Simulator: workcell '%s', arm at %.0f Hz, physics at 1 kHz, real-time "
                 "factor %s, %s /clock",
                 urdf_path.c_str(), sim_->params().arm_rate_hz,
                 real_time_factor_ > 0.0 ? std::to_string(real_time_factor_).c_str() : "max",
                 publish_clock_ ? "publishing" : "not publishing");
    running_ = true;
    thread_ = std::thread(&SimulatorNodelet::loop, this);
  }

  ros::Time stampOf(double sim_time) const { return ros::Time(sim_time + time_offset_); }

  void publishStaticTransforms() {
    std::vector<geometry_msgs::TransformStamped> out;
    for (const core::FrameTransform& f : sim_->frameTransforms(true)) {
      geometry_msgs::TransformStamped t = tf2::eigenToTransform(f.transform);
      t.header.stamp = stampOf(0.0);
      t.header.frame_id = f.parent;
      t.child_frame_id = f.child;
      out.push_back(t);
    }
    static_broadcaster_->sendTransform(out);
  }

  void loop() {
    using Clock = std::chrono::steady_clock;
    const Clock::time_point wall0 = Clock::now();
    double sim0 = 0.0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      sim0 = sim_->time();
    }
    std::uint64_t n = 0;
    while (running_ && ros::ok()) {
      double t = 0.0;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        const core::SimulationStep step = sim_->stepOnce();
        t = step.time_s;
        ++n;
        publishWrench(step);
        if (n % joint_state_period_ == 0) publishJointStates(t);
        if (n % tf_period_ == 0) publishTf(t);
        if (n % ground_truth_period_ == 0 || step.layer_changed) publishGroundTruth(t);
        if (n % tracker_period_ == 0) publishMarker(t);
        if (tidal_volume_period_ > 0 && n % tidal_volume_period_ == 0) publishTidalVolume(t);
      }
      if (publish_clock_ && n % clock_period_steps_ == 0) {
        rosgraph_msgs::ClockPtr c = boost::make_shared<rosgraph_msgs::Clock>();
        c->clock = stampOf(t);
        clock_pub_.publish(c);
      }
      if (real_time_factor_ > 0.0) {
        const Clock::time_point due =
            wall0 + std::chrono::duration_cast<Clock::duration>(
                        std::chrono::duration<double>((t - sim0) / real_time_factor_));
        // Sleep only when ahead by more than a millisecond (fewer system calls).
        if (due - Clock::now() > std::chrono::milliseconds(1)) std::this_thread::sleep_until(due);
      } else if (n % 1000 == 0) {
        std::this_thread::yield();  // as fast as possible, but let callbacks in
      }
    }
  }

  void publishWrench(const core::SimulationStep& step) {
    if (wrench_pub_.getNumSubscribers() == 0) return;
    geometry_msgs::WrenchStampedPtr w = boost::make_shared<geometry_msgs::WrenchStamped>();
    w->header.stamp = stampOf(step.time_s);
    w->header.frame_id = "ft_sensor";
    w->wrench.force.x = step.measured_wrench[0];
    w->wrench.force.y = step.measured_wrench[1];
    w->wrench.force.z = step.measured_wrench[2];
    w->wrench.torque.x = step.measured_wrench[3];
    w->wrench.torque.y = step.measured_wrench[4];
    w->wrench.torque.z = step.measured_wrench[5];
    wrench_pub_.publish(w);
  }

  void publishTidalVolume(double t) {
    const core::BreathScheduler& ventilator = sim_->ventilator();
    TidalVolumePtr m = boost::make_shared<TidalVolume>();
    m->header.stamp = stampOf(t);
    m->header.frame_id = "ventilator";
    m->volume_ml = sim_->ventilatorSample().volume_ml;
    m->flow_ml_s = sim_->ventilatorSample().flow_ml_s;
    m->breath_index = static_cast<uint32_t>(ventilator.breathIndex());
    m->time_in_breath_s = std::max(0.0, sim_->ventilatorSample().t - ventilator.breathStart());
    tidal_volume_pub_.publish(m);
    if (ventilator.breathIndex() != last_breath_index_) {
      last_breath_index_ = ventilator.breathIndex();
      const VentilatorSettings settings = toMsg(ventilator.model().settings());
      if (settings != last_settings_msg_) {
        ventilator_settings_pub_.publish(settings);
        last_settings_msg_ = settings;
      }
    }
  }

  void publishJointStates(double t) {
    sensor_msgs::JointStatePtr js = boost::make_shared<sensor_msgs::JointState>();
    js->header.stamp = stampOf(t);
    const Eigen::VectorXd q = sim_->armJointPositions();
    const Eigen::VectorXd qd = sim_->armJointVelocities();
    const Eigen::VectorXd tau = sim_->armJointEfforts();
    for (size_t k = 0; k < sim_->armJointNames().size(); ++k) {
      js->name.push_back(sim_->armJointNames()[k]);
      js->position.push_back(q[k]);
      js->velocity.push_back(qd[k]);
      js->effort.push_back(k < static_cast<size_t>(tau.size()) ? tau[k] : 0.0);
    }
    for (const auto& kv : sim_->spmsJointStates()) {
      js->name.push_back(kv.first);
      js->position.push_back(kv.second);
      js->velocity.push_back(0.0);
      js->effort.push_back(0.0);
    }
    joint_state_pub_.publish(js);
  }

  void publishTf(double t) {
    std::vector<geometry_msgs::TransformStamped> out;
    for (const core::FrameTransform& f : sim_->frameTransforms(false)) {
      geometry_msgs::TransformStamped m = tf2::eigenToTransform(f.transform);
      m.header.stamp = stampOf(t);
      m.header.frame_id = f.parent;
      m.child_frame_id = f.child;
      out.push_back(m);
    }
    tf_broadcaster_->sendTransform(out);
  }

  void publishGroundTruth(double t) {
    const core::SimulationGroundTruth g = sim_->groundTruth();
    GroundTruthPtr m = boost::make_shared<GroundTruth>();
    m->header.stamp = stampOf(t);
    m->header.frame_id = "bone";
    m->seed = g.seed;
    m->specimen_layer = core::materialName(g.layer);
    m->tip_depth_m = g.tip_depth_m;
    m->max_depth_cut_m = g.max_depth_cut_m;
    m->outer_cortical_end_m = g.outer_cortical_end_m;
    m->inner_cortical_start_m = g.inner_cortical_start_m;
    m->inner_cortical_end_m = g.inner_cortical_end_m;
    m->residual_inner_cortical_m = g.residual_inner_cortical_m;
    m->breakthrough = g.breakthrough;
    m->thrust_n = g.thrust_n;
    m->contact = g.contact;
    m->feed_per_rev_m = g.feed_per_rev_m;
    m->bone_displacement_m.x = g.bone_displacement_m.x();
    m->bone_displacement_m.y = g.bone_displacement_m.y();
    m->bone_displacement_m.z = g.bone_displacement_m.z();
    m->tidal_volume_ml = g.tidal_volume_ml;
    m->relative_ap_m = g.relative_ap_m;
    ground_truth_pub_.publish(m);
  }

  void publishMarker(double t) {
    const Eigen::Isometry3d pose = sim_->measureMarkerPose();
    geometry_msgs::PoseStampedPtr m = boost::make_shared<geometry_msgs::PoseStamped>();
    m->header.stamp = stampOf(t);
    m->header.frame_id = "tracker_camera";
    m->pose = tf2::toMsg(pose);
    marker_pub_.publish(m);
  }

  /**
   * @brief simulator/start_trial: ground truth measures the relative AP motion from now; a
   *        specimen already drilled is replaced by a fresh one (seed + 1), as on the bench.
   */
  bool onStartTrial(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
    bool remounted = false;
    try {
      remounted = sim_->startTrial();
    } catch (const std::exception& e) {
      response.success = false;
      response.message = std::string("start_trial failed: ") + e.what();
      return true;
    }
    response.success = true;
    response.message = "trial " + std::to_string(sim_->trialCount()) + " started at t=" +
                       std::to_string(sim_->time()) + " s";
    if (remounted) {
      response.message += "; the specimen was drilled, a fresh one from seed " +
                          std::to_string(sim_->seed()) + " is mounted (arm at home)";
      NODELET_INFO("Simulator: %s", response.message.c_str());
    }
    publishGroundTruth(sim_->time());
    return true;
  }

  void onTrajectory(const trajectory_msgs::JointTrajectory::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const double now = sim_->time();
    const double start =
        msg->header.stamp.isZero() ? now : msg->header.stamp.toSec() - time_offset_;
    core::TrajectoryCommand command;
    command.joint_names = msg->joint_names;
    // The new trajectory takes over at its stamp (JointTrajectoryController); zero: now.
    if (!msg->header.stamp.isZero()) command.start_time_s = start;
    for (const trajectory_msgs::JointTrajectoryPoint& p : msg->points) {
      command.points.push_back({start + p.time_from_start.toSec(), p.positions, p.velocities});
    }
    const core::TargetResult r = sim_->commandTrajectory(command);
    if (r.status == core::TargetStatus::kRejected) {
      NODELET_WARN_THROTTLE(1.0, "Simulator: arm_controller/command rejected, previous "
                                 "trajectory kept: %s", r.message.c_str());
    } else if (r.status == core::TargetStatus::kClamped) {
      NODELET_WARN_THROTTLE(1.0, "Simulator: arm_controller/command clamped: %s",
                            r.message.c_str());
    }
  }

  void onSpindle(const std_msgs::Float64::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const core::TargetResult r = sim_->commandSpindle(msg->data);
    if (r.status == core::TargetStatus::kRejected) {
      NODELET_WARN_THROTTLE(1.0, "Simulator: spindle/command rejected, speed kept: %s",
                            r.message.c_str());
    } else if (r.status == core::TargetStatus::kClamped) {
      NODELET_WARN_THROTTLE(1.0, "Simulator: spindle/command clamped: %s", r.message.c_str());
    }
  }

  /**
   * @brief ~bone_motion_model_path (re-read at every reset): "" = the virtual patient; else the
   *        patient model YAML whose AP axis the bone plays (the paper's bench protocol).
   */
  std::optional<core::BoneMotionModel> loadBoneMotionModel() const {
    const ParamLoader params(getPrivateNodeHandle());
    const std::string path = params.getString("bone_motion_model_path", "", true);
    if (path.empty()) return std::nullopt;
    try {
      const core::PatientModel patient = core::readModelYaml(path);
      const core::AxisModelRecord& ap = patient.axes[static_cast<int>(core::Axis::kAP)];
      core::BoneMotionModel model;
      model.q1_ap_mm_per_ml = ap.model.q1;
      model.q2_ap_mm_s_per_ml = ap.model.q2;
      return model;
    } catch (const std::exception& e) {
      throw ParameterError("parameter " + getPrivateNodeHandle().resolveName(
                                              "bone_motion_model_path") +
                           " = '" + path + "': " + e.what());
    }
  }

  bool onReset(ResetSimulation::Request& req, ResetSimulation::Response& res) {
    // The distributions are re-read at every reset, so that a campaign (or a user with
    // `rosparam set`) can change them between trials; a bad value refuses the reset.
    TrialDistributionParams distribution;
    std::optional<core::BoneMotionModel> bone_motion;
    try {
      distribution = loadTrialDistribution(getPrivateNodeHandle());
      bone_motion = loadBoneMotionModel();
    } catch (const std::exception& e) {
      res.success = false;
      res.message = std::string(e.what()) + "; nothing was reset";
      return true;
    }
    // An explicit specimen: the given thicknesses with no spread.
    const struct {
      const char* field;
      double mm;
      double* mean_m;
      double* sd_m;
    } layers[] = {
        {"outer_cortical_thickness_mm", req.outer_cortical_thickness_mm,
         &distribution.specimen.outer_cortical_thickness_mean_m,
         &distribution.specimen.outer_cortical_thickness_sd_m},
        {"cancellous_thickness_mm", req.cancellous_thickness_mm,
         &distribution.specimen.cancellous_thickness_mean_m,
         &distribution.specimen.cancellous_thickness_sd_m},
        {"inner_cortical_thickness_mm", req.inner_cortical_thickness_mm,
         &distribution.specimen.inner_cortical_thickness_mean_m,
         &distribution.specimen.inner_cortical_thickness_sd_m},
    };
    const double min_mm = distribution.specimen.min_layer_thickness_m * 1e3;
    for (const auto& layer : layers) {
      if (layer.mm == 0.0) continue;
      if (!(layer.mm >= min_mm && layer.mm <= 100.0)) {
        std::ostringstream os;
        os << "request field " << layer.field << " = " << layer.mm << " is not 0 (drawn) or in ["
           << min_mm << ", 100] mm; nothing was reset";
        res.success = false;
        res.message = os.str();
        return true;
      }
      *layer.mean_m = layer.mm * 1e-3;
      *layer.sd_m = 0.0;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      sim_->setTrialDistribution(distribution.specimen, distribution.variability);
      sim_->setBoneMotionModel(bone_motion);
      sim_->reset(req.seed, req.moving_bone);
    } catch (const std::exception& e) {
      res.success = false;
      res.message = std::string("reset failed: ") + e.what();
      return true;
    }
    const core::BoneSpecimen& s = sim_->process().specimen();
    res.success = true;
    std::ostringstream os;
    os << "new specimen and patient from seed " << req.seed << " (virtual volunteer "
       << sim_->patient().volunteer_id << "), bone " << (req.moving_bone ? "moving" : "stationary")
       << ", arm at home";
    if (bone_motion) {
      os << "; the bone plays the model AP d = " << bone_motion->q1_ap_mm_per_ml << " Tv + "
         << bone_motion->q2_ap_mm_s_per_ml << " dTv/dt (bone_motion_model_path)";
    }
    res.message = os.str();
    res.outer_cortical_thickness_m = s.outerCorticalThickness();
    res.cancellous_thickness_m = s.cancellousThickness();
    res.inner_cortical_thickness_m = s.innerCorticalThickness();
    const core::TrialConditions& c = sim_->trialConditions();
    res.volunteer_id = c.volunteer_id;
    res.patient_amplitude_scale = c.patient_amplitude_scale;
    res.ventilator_rate_bpm = c.ventilator_rate_bpm;
    res.ventilator_tidal_volume_ml = c.ventilator_tidal_volume_ml;
    res.force_noise_sd_n = c.force_noise_sd_n;
    res.arm_stiffness_scale = c.arm_stiffness_scale;
    publishGroundTruth(sim_->time());
    return true;
  }

  std::mutex mutex_;
  std::unique_ptr<core::DrillingSimulation> sim_;
  StartupStatus startup_status_;
  std::atomic<bool> running_{false};
  std::thread thread_;
  double real_time_factor_ = 1.0;
  bool publish_clock_ = true;
  double time_offset_ = 0.0;
  int clock_period_steps_ = 1;
  int joint_state_period_ = 10;
  int tf_period_ = 10;
  int ground_truth_period_ = 10;
  int tracker_period_ = 125;
  int tidal_volume_period_ = 0;  // 0: the simulated ventilator publishes nothing
  long last_breath_index_ = -1;
  VentilatorSettings last_settings_msg_;
  ros::Publisher tidal_volume_pub_;
  ros::Publisher ventilator_settings_pub_;
  ros::Publisher clock_pub_;
  ros::Publisher joint_state_pub_;
  ros::Publisher wrench_pub_;
  ros::Publisher marker_pub_;
  ros::Publisher ground_truth_pub_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
  std::unique_ptr<tf2_ros::StaticTransformBroadcaster> static_broadcaster_;
  ros::Subscriber trajectory_sub_;
  ros::Subscriber spindle_sub_;
  ros::ServiceServer reset_srv_;
  ros::ServiceServer start_trial_srv_;
};

}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::SimulatorNodelet, nodelet::Nodelet)
