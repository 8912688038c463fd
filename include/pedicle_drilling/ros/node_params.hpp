/**
 * @file node_params.hpp
 * @brief One parameter struct per nodelet, each declared once (core::ParamTable): the core
 *        options struct it holds plus the node's own settings (rates, frames, queue sizes).
 *        Loaded once by ParamLoader::load(), validated by the same table, and documented from it
 *        (`rosrun pedicle_drilling param_docs`; test_node_reference checks doc/nodes.md's
 *        tables against it). No ROS type in this header.
 */
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "pedicle_drilling/core/breathing/breath_detector.hpp"
#include "pedicle_drilling/core/breathing/motion_pipeline.hpp"
#include "pedicle_drilling/core/breathing/ventilator.hpp"
#include "pedicle_drilling/core/common/param_table.hpp"
#include "pedicle_drilling/core/control/drill_guard.hpp"
#include "pedicle_drilling/core/control/safety_supervisor.hpp"
#include "pedicle_drilling/core/control/trial_sequencer.hpp"
#include "pedicle_drilling/core/drilling/recognizer_adapter.hpp"
#include "pedicle_drilling/core/drilling/sample_rate_check.hpp"
#include "pedicle_drilling/core/drilling/state_recognizer.hpp"
#include "pedicle_drilling/core/sim/drilling_simulation.hpp"
#include "pedicle_drilling/core/sim/fault_injector.hpp"

namespace pedicle_drilling {

/** @brief pedicle_drilling/Ventilator. */
struct VentilatorNodeParams {
  core::VentilatorSettings settings;  ///< the ventilator's settings (core)
  /// Where the breath phase comes from: "internal", a schedule running from the nodelet's start
  /// (the simulator-only demo); "flow", breath starts detected on breath_sensor/flow.
  std::string breath_source = "internal";
  core::FlowPhaseParams flow;           ///< the detector and its timeout, with breath_source flow
  double publish_rate_hz = 64.0;        ///< tidal_volume rate
  std::string frame_id = "ventilator";  ///< header.frame_id of what it publishes
  /** @brief Checks the declared ranges. @throws std::invalid_argument naming the parameter. */
  void validate() const;
  /** @brief The declaration of every parameter. */
  static const core::ParamTable<VentilatorNodeParams>& table();
};

/** @brief pedicle_drilling/Simulator. */
struct SimulatorNodeParams {
  std::string urdf_path;               ///< the workcell URDF (required)
  int seed = 1;                        ///< specimen and patient of the first trial
  core::DrillingSimulationParams sim;  ///< the simulation (core)
  double real_time_factor = 1.0;       ///< 0: as fast as possible
  bool publish_clock = true;           ///< publish /clock (sim time)
  int clock_period_ms = 1;             ///< /clock every n physics steps
  /// Wall seconds the simulator waits, while a trial streams trajectories, rather than step past
  /// the end of the last one it received (sim time waits for the planner); 0: never waits.
  double command_wait_s = 1.0;
  double lockstep_timeout_s = 5.0;  ///< wall time to wait for a lockstep participant
  /// Serves control_msgs' FollowJointTrajectory on each controller's
  /// `<controller>/follow_joint_trajectory` beside its `<controller>/command` topic, as a lab's
  /// ros_control controllers do (not under the lockstep: the load fails).
  bool follow_joint_trajectory = false;
  /// Under the lockstep: every step waits for every participant (true), instead of the steps
  /// that publish a simulator stream or that a participant's answer asked for (false: the same
  /// trial with fewer hand-offs; StepAck.next_step).
  bool lockstep_every_step = false;
  /// Under the lockstep: sim time from a command's step to its effect on the arm or spindle
  /// (the engine's command_to_arm_s; re-read at every reset).
  double command_delay_s = 1e-3;
  /// Under the lockstep: extra command delay, uniform in [0, this] per command, drawn from the
  /// trial's seed as the engine draws it (the order kept).
  double command_jitter_s = 0.0;
  double tracker_delay_s = 0.0;  ///< tracker/marker_pose published this much later (stamp kept)
  double joint_state_rate_hz = 100.0;   ///< joint_states rate
  double tf_rate_hz = 100.0;            ///< tf rate
  double ground_truth_rate_hz = 100.0;  ///< simulator/ground_truth rate
  /// Each controller's <name>/state rate (ros_control's state_publish_rate default).
  double controller_state_rate_hz = 50.0;
  double tracker_rate_hz = 8.0;        ///< tracker rate (NDI Polaris in the paper: 8 Hz)
  double tidal_volume_rate_hz = 64.0;  ///< the simulated ventilator's tidal_volume (0: off)
  std::string bone_motion_model_path;  ///< identified model driving the bone ("" = built-in)
  /// The tracker as a lab's tracker driver publishes it: "" (default) publishes its
  /// samples on tracker/marker_pose only; a frame name also puts each sample on tf as
  /// tracker_camera -> this frame (the sample's stamp, after tracker_delay_s), and the URDF's
  /// frames of that name and tracker_camera leave the simulator's tf: the tracker's driver and
  /// the lab's registration (hardware.launch's static transform) own them.
  std::string tracker_tf_frame;
  /// true (default): every workcell frame on tf. false: only the frames robot_state_publisher
  /// cannot compute from joint_states (the children of floating joints: the SPMS platform), as
  /// on a lab's bench, where robot_state_publisher publishes the rest (hardware.launch).
  bool publish_joint_frames = true;
  /** @brief Checks the declared ranges and the stream rates (divisors of 1000 Hz). */
  void validate() const;
  /** @brief The declaration of every parameter. */
  static const core::ParamTable<SimulatorNodeParams>& table();
};

/** @brief pedicle_drilling/MotionIdentification. */
struct MotionIdentificationParams {
  std::string tracker_frame = "tracker_camera";    ///< the tracker's frame
  std::string patient_frame;                       ///< frame of the patient's axes ("" = tracker)
  std::string marker_frame = "tracker_marker";     ///< the marker's frame
  double marker_rate_hz = 8.0;                     ///< tf sampling rate
  double tf_delay_s = 0.25;                        ///< how far behind now tf is sampled
  bool use_pose_topic = false;                     ///< tracker/marker_pose instead of tf
  double window_s = 30.0;                          ///< length of the recording window
  std::string ap_axis = "+z";                      ///< tracker axis of AP
  std::string si_axis = "+y";                      ///< tracker axis of SI
  std::string lr_axis = "+x";                      ///< tracker axis of LR
  core::PipelineOptions defaults;                  ///< model, method, de-noising (per request)
  std::string output_path = "patient_model.yaml";  ///< where the model is written (in the folder)
  /// The only folder model files are written in ("" = core::defaultModelFolder()).
  std::string model_folder;
  std::string patient_id = "patient";  ///< written into the model
  /** @brief The three axis parameters as the mapping. @throws std::invalid_argument. */
  core::AxisMapping mapping() const;
  /** @brief "ap,si,lr" axis specs for the model file. */
  std::string axisSpecs() const { return ap_axis + "," + si_axis + "," + lr_axis; }
  /** @brief Checks the declared ranges, the axes and the pipeline options. */
  void validate() const;
  /** @brief The declaration of every parameter. */
  static const core::ParamTable<MotionIdentificationParams>& table();
};

/** @brief pedicle_drilling/TfPoseRelay: the tracker on tf as a PoseStamped stream. */
struct TfPoseRelayNodeParams {
  std::string tracker_frame = "tracker_camera";  ///< frame of the relayed poses
  std::string marker_frame = "tracker_marker";   ///< the tracked marker's frame
  /** @brief Checks that the two frames are named and differ. */
  void validate() const;
  /** @brief The declaration of every parameter. */
  static const core::ParamTable<TfPoseRelayNodeParams>& table();
};

/** @brief pedicle_drilling/TrialAction: a trial as the `drill_trial` action. */
struct TrialActionNodeParams {
  /// The CompensationPlanner's start service (StartTrial), called for each goal.
  std::string start_service = "compensation_planner/start_trial";
  /// How long [s] a goal waits for the start service to exist before it is rejected.
  double service_timeout_s = 5.0;
  /// The feed joint whose position (joint_states) the feedback reports.
  std::string feed_joint = "feed_joint";
  /// Feedback period [s] between the status changes (each change is sent at once).
  double feedback_period_s = 0.1;
  /// A running goal whose planner has published no compensation/status for this long while
  /// the status topic has no publisher [s] is aborted ("planner lost"); the trial is the
  /// planner's, the drill guard stops the drives of a lost planner.
  double planner_lost_s = 1.0;
  /** @brief Checks the declared ranges. @throws std::invalid_argument naming the parameter. */
  void validate() const;
  /** @brief The declaration of every parameter. */
  static const core::ParamTable<TrialActionNodeParams>& table();
};

/**
 * @brief pedicle_drilling/ForceTare: the tare for a sensor driver that does not speak our
 *        TareRequest/TareResult: our own bias (relay), or the driver's zero service, checked.
 */
struct ForceTareNodeParams {
  /// The driver's zero (bias) service, std_srvs/Trigger: "" (default), ForceTare measures and
  /// subtracts the bias itself (the relay); a name, ForceTare calls it at each tare request and
  /// checks the zero on the driver's stream (no relay).
  std::string zero_service;
  /// With zero_service: the largest norm [N] of the mean force over the request's samples
  /// after the call (the monitor's retare_max_offset_n: 10 x the sensor's noise SD).
  double zero_tolerance_n = 0.3;
  /// With zero_service: how long [s] to wait for the service to exist (below the planner's
  /// registration_timeout_s, so that a missing service is named before the planner gives up).
  double zero_service_timeout_s = 1.0;
  /** @brief Checks the declared ranges. @throws std::invalid_argument naming the parameter. */
  void validate() const;
  /** @brief The declaration of every parameter. */
  static const core::ParamTable<ForceTareNodeParams>& table();
};

/** @brief The wrench components a node may read as the thrust: x, y or z, with an optional sign
 *         ("-z": the thrust is -force.z). The StateRecognizer's `axis`, the planner's
 *         `thrust_axis`. */
const std::vector<std::string>& forceAxes();
/** @brief The component (0..2) of a forceAxes() value. */
int forceAxisIndex(const std::string& axis);
/** @brief The sign (+1 or -1) of a forceAxes() value. */
double forceAxisSign(const std::string& axis);

/** @brief pedicle_drilling/StateRecognizer. */
struct StateRecognizerNodeParams {
  std::string axis = "z";             ///< thrust component of the wrench, with sign
  core::RecognizerParams recognizer;  ///< the paper's recognizer (core), its sensor_rate_hz
  /// The measured rate of ft_sensor/wrench may differ from recognizer.sensor_rate_hz by this
  /// fraction (core::SampleRateCheck); more: ERROR on /diagnostics, ~reset refused, and a
  /// running trial stopped.
  double rate_tolerance = core::kDefaultRateTolerance;
  double rate_window_s = 1.0;  ///< the window the rate is measured over [s]
  int queue_size = 1000;       ///< ft_sensor/wrench subscriber queue
  /// The drill's joints in joint_states: the context a recognizer class may read (feed depth,
  /// spindle speed; core::RecognizerSample)
  core::DrillJointNames joints;
  std::string recognizer_class = "pedicle_drilling/PaperRecognizer";  ///< plugin class
  /// The class's parameters as text, checked by it: another class's own, or the paper
  /// recognizer's (RecognizerParams by name, set over `recognizer`: recognizerInUse()).
  core::TextPairs recognizer_params;
  /// Allows the parameters that switch a watchdog off (disabledWatchdogs()); else refused.
  bool unsafe_allow_disabled_watchdogs = false;
  /** @brief True when the class is the paper recognizer (PaperRecognizer). */
  bool paperClass() const;
  /**
   * @brief The keys of recognizer_params that set the paper recognizer's parameters: every key
   *        with the paper class, none with another. Each may not be set as the node's own key
   *        too (`~window` and `~recognizer_params/window`): the nodelet refuses that naming it.
   */
  std::vector<std::string> paperSettingNames() const;
  /**
   * @brief The paper recognizer's parameters in use: `recognizer` (the node's own keys
   *        ~pre_average_s, ~window, ...) with, for the paper class, recognizer_params set over
   *        it from text (RecognizerParams::set). Another class runs with its own parameters; the
   *        node's sensor_rate_hz (the rate check) and block are taken from these for any class.
   * @throws std::invalid_argument "recognizer_params/<name> ..." for a setting it refuses.
   */
  core::RecognizerParams recognizerInUse() const;
  /** @brief The watchdogs the parameters switch off, one "name = value (what)" each. */
  std::vector<std::string> disabledWatchdogs() const;
  /** @brief Component index (0..2) of axis. */
  int axisIndex() const;
  /** @brief Sign (+1 or -1) of axis. */
  double axisSign() const;
  /** @brief Checks the declared ranges and the recognizer's own checks (recognizerInUse()). */
  void validate() const;
  /** @brief The declaration of every parameter. */
  static const core::ParamTable<StateRecognizerNodeParams>& table();
};

/** @brief pedicle_drilling/SafetyMonitor. */
struct SafetyMonitorNodeParams {
  core::SupervisorParams supervisor;  ///< H1, H2, timeouts and the pairing (core)
  double check_rate_hz = 200.0;       ///< watchdog timer rate
  double diagnostic_period_s = 1.0;   ///< /diagnostics period
  /** @brief Rate the F/T driver publishes at (its /diagnostics rate check): the simulator's. */
  double expected_force_rate_hz = 1000.0 / 3.0;
  double expected_tracker_rate_hz = 8.0;  ///< rate the tracker publishes at (rate check)
  double rate_tolerance = 0.1;            ///< a measured rate off by more than this fraction: WARN
  core::DrillGuardParams guard;           ///< the drives' enable heartbeat (core::DrillGuard)
  /** @brief true: a timeout set to +inf (a disabled watchdog) is taken, with a WARN at load. */
  bool unsafe_allow_disabled_watchdogs = false;
  /** @brief Checks the declared ranges, that the checks are fast enough for the timeouts, and
   *         that no watchdog is disabled (unless unsafe_allow_disabled_watchdogs). */
  void validate() const;
  /** @brief The watchdogs these parameters disable, each with why it matters. */
  std::vector<std::string> disabledWatchdogs() const;
  /** @brief The declaration of every parameter. */
  static const core::ParamTable<SafetyMonitorNodeParams>& table();
};

/** @brief pedicle_drilling/CompensationPlanner (apart from the URDF-dependent drilling pose). */
struct CompensationPlannerNodeParams {
  std::string patient_model_path;            ///< the identified patient model (required)
  std::string urdf_path;                     ///< the workcell URDF ("" = ~robot_description)
  std::string arm_base_link = "world";       ///< root of the arm chain
  std::string arm_tip_link = "device_base";  ///< end of the arm chain
  core::TrialSequencerParams sequencer;      ///< the trial (core)
  double feed_home_m = 0.01;                 ///< feed joint at the start
  std::string world_frame = "world";         ///< frame of the predicted marker pose
  /// The drill tip's link (URDF): where the depth limit measures the tip from at the drilling
  /// pose (core::ArmCompensation::tipAt).
  std::string tip_link = "drill_tip";
  /// The thrust component of ft_sensor/wrench (forceAxes(); the StateRecognizer's `axis`): the
  /// contact the depth limit counts from.
  std::string thrust_axis = "z";
  std::vector<std::string> trial_start_services{"state_recognizer/reset",
                                                "safety_monitor/reset"};  ///< called at start
  double trial_start_timeout_s = 2.0;                                     ///< wait for each of them
  std::string monitor_status_name = "/safety_monitor: monitor";           ///< its DiagnosticStatus
  std::string compensator_class = "pedicle_drilling/PaperCompensator";    ///< plugin class
  core::TextPairs compensator_params;  ///< the class's own parameters
  /// Allows the parameters that switch a watchdog off (disabledWatchdogs()); else refused.
  bool unsafe_allow_disabled_watchdogs = false;
  /**
   * @brief Period [s] of compensation/heartbeat while a trial runs, which the safety monitor's
   * drill guard watches (guard_planner_timeout_s, default 0.06 s). Default 0.01 s: 6 beats per
   * guard timeout, so a late beat does not stop a healthy trial.
   */
  double heartbeat_period_s = core::kPlannerHeartbeatPeriodS;
  /**
   * @brief How the segments reach the controllers: `topic` (a trajectory_msgs/JointTrajectory on
   *        `<controller>/command`) or `action` (a FollowJointTrajectory goal on
   *        `<controller>/follow_joint_trajectory`, each goal replacing the running one; a goal
   *        rejected or aborted is a controller fault). One route; `action` is refused under the
   *        lockstep.
   */
  std::string trajectory_interface = "topic";
  /// With trajectory_interface `action`: a trial is refused unless every controller's action
  /// server is connected within this wall time [s].
  double action_server_timeout_s = 5.0;
  /** @brief Whether the segments go as FollowJointTrajectory goals. */
  bool useAction() const { return trajectory_interface == "action"; }
  /// A moving trial needs a breath start at most this many breath periods old
  /// (core::TrialSequencer::setBreathSource): refused before, stopped with retreat while
  /// drilling. The Ventilator's `flow` source stops publishing at its own
  /// breath_timeout_periods (the same default).
  double breath_timeout_periods = 2.0;
  /** @brief The watchdogs the parameters switch off, one "name = value (what)" each. */
  std::vector<std::string> disabledWatchdogs() const;
  /** @brief Component index (0..2) of thrust_axis. */
  int thrustAxisIndex() const { return forceAxisIndex(thrust_axis); }
  /** @brief Sign (+1 or -1) of thrust_axis. */
  double thrustAxisSign() const { return forceAxisSign(thrust_axis); }
  /** @brief Checks the declared ranges (the URDF-dependent checks come with the sequencer). */
  void validate() const;
  /** @brief The declaration of every parameter. */
  static const core::ParamTable<CompensationPlannerNodeParams>& table();
};

/** @brief pedicle_drilling/FaultInjector. */
struct FaultInjectorNodeParams {
  core::FaultParams faults;  ///< fault magnitudes (core)
  /// The controllers whose `<name>/command` is relayed to `<name>/command_delivered`.
  std::vector<std::string> controllers{"arm_controller", "feed_controller"};
  /** @brief Checks the declared ranges. */
  void validate() const;
  /** @brief The declaration of every parameter. */
  static const core::ParamTable<FaultInjectorNodeParams>& table();
};

/**
 * @brief Refuses the first of @p disabled (a disabledWatchdogs() list) unless @p allowed.
 * @throws std::invalid_argument starting with the parameter's name.
 */
void refuseDisabledWatchdogs(const std::vector<std::string>& disabled, bool allowed);

/** @brief Every nodelet's declared parameters with their defaults, by nodelet class name. */
std::vector<std::pair<std::string, std::vector<core::ParamInfo>>> nodeParameterDocs();

}  // namespace pedicle_drilling
