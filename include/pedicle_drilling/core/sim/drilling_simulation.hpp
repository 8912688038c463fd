/**
 * @file drilling_simulation.hpp
 * @brief The whole simulated workcell without ROS: RSSSII arm (BulletArm), SPMS platform
 *        (SpmsKinematics with rate-limited lead-screw sliders), virtual patient driven by an
 *        internal ventilator, bone specimen, drilling-force process and force sensor.
 *
 * Multi-rate stepping (see doc/simulator_physics.md, section 5):
 *  - physics step dt = 1 ms: ventilator -> patient AP displacement -> SPMS IK -> slider motion
 *    (rate limited) -> SPMS FK -> bone pose; drill-tip position (interpolated from the arm, see
 *    below) -> tip depth = bone top z - tip z (drill axis vertical) -> DrillingProcess -> thrust
 *    -> ForceSensor (one 1 kHz sample per physics step).
 *  - arm block = N physics steps (N = physics rate / arm rate, default 4: 250 Hz). At the start
 *    of a block the arm is advanced by N dt in one Bullet sub-step, with the latest thrust applied
 *    at the tip (zero-order hold) and the servo reference ramping over the block to the
 *    commanded trajectory. Inside the block the tip position used by the drilling physics is
 *    interpolated linearly between the arm states at the block start and end, so the thrust
 *    deflects the tip (finite joint stiffness) and the deflection reduces the depth.
 *
 * Time: the simulation has its own clock, time() [s], starting at 0 and never going back
 * (reset() starts a new trial but does not rewind time). Trajectory times are absolute sim times.
 *
 * No ROS headers; C++17, Eigen, Bullet and urdfdom only.
 */
#ifndef PEDICLE_DRILLING_CORE_DRILLING_SIMULATION_HPP
#define PEDICLE_DRILLING_CORE_DRILLING_SIMULATION_HPP

#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "pedicle_drilling/core/breathing/ventilator.hpp"
#include "pedicle_drilling/core/breathing/virtual_volunteer.hpp"
#include "pedicle_drilling/core/drilling/bone_specimen.hpp"
#include "pedicle_drilling/core/drilling/drilling_force.hpp"
#include "pedicle_drilling/core/drilling/force_sensor.hpp"
#include "pedicle_drilling/core/drilling/force_tare.hpp"
#include "pedicle_drilling/core/robot/bullet_arm.hpp"
#include "pedicle_drilling/core/robot/controller_layout.hpp"
#include "pedicle_drilling/core/robot/spms_kinematics.hpp"
#include "pedicle_drilling/core/robot/trajectory_executor.hpp"
#include "pedicle_drilling/core/sim/imaging_plan.hpp"
#include "pedicle_drilling/core/sim/patient_population.hpp"

namespace pedicle_drilling::core {

/** @brief The virtual patient: how tidal volume moves the vertebra (and the SPMS) in AP. */
struct VirtualPatient {
  int volunteer_id = 1;           ///< virtual volunteer whose truth model is used (1..5)
  double q1_ap_mm_per_ml = 0.01;  ///< AP slope [mm/ml] (5 mm peak-to-peak at 500 ml)
  double lag_s = 0.08;            ///< hysteresis lag of displacement behind volume [s]
  double drift_mm = 0.15;         ///< amplitude of the slow AP drift [mm]
  double drift_period_s = 60.0;   ///< period of the slow AP drift [s]
  double drift_phase_rad = 0.0;   ///< phase of the slow AP drift [rad]
  /// Small unpredictable movements (AP component used), as the volunteers' recordings have.
  std::vector<PatientMovement> movements;
  /// Phase-lead term on the flow [mm s/ml] (d = q1 Tv + q2 dTv/dt), 0 for a virtual volunteer;
  /// set when the bone plays a displacement model (BoneMotionModel).
  double q2_ap_mm_s_per_ml = 0.0;
  double cardiac_mm = 0.0;         ///< cardiac AP amplitude [mm] (0: none)
  double heart_rate_bpm = 68.0;    ///< heart rate [beats/min]
  double cardiac_phase_rad = 0.0;  ///< cardiac phase at t = 0 [rad]
  /// Breath-to-breath CV of the delivered volume around the ventilator's setting (0: exact).
  double delivered_volume_cv = 0.0;
  /// Delivered / set volume of every breath (the ventilator's systematic error; 1: exact).
  double delivered_volume_bias = 1.0;
  /**
   * @brief True AP displacement [mm] for a lagged tidal volume [ml] and flow [ml/s] at time
   *        t [s]: q1 Tv + q2 dTv/dt + drift + movements + cardiac.
   */
  double apDisplacementMm(double lagged_tv_ml, double t, double lagged_flow_ml_s = 0.0) const;
};

/**
 * @brief A displacement model for the bone to play instead of a virtual patient: the SPMS
 *        moves the bone by d_AP = q1 Tv(t) + q2 dTv/dt(t), nothing else (no lag, drift or
 *        movements). This is the paper's bench protocol: Algorithm 1 computes the predicted
 *        displacement y_AP(t) and then "SPMS and RSSSII do move", the SPMS playing the
 *        patient's identified model (Sec. II-B, IV-B, V-C).
 */
struct BoneMotionModel {
  double q1_ap_mm_per_ml = 0.0;    ///< AP slope [mm/ml], finite
  double q2_ap_mm_s_per_ml = 0.0;  ///< AP flow term [mm s/ml], finite (0 for a linear model)
};

/**
 * @brief Draws a virtual patient from a seed: the truth model (q1_AP, lag, drift) of virtual
 *        volunteer 1 + seed % 5 (virtual_volunteer.hpp), drift period and phase from the seed,
 *        and the volunteer's small movements (Poisson onsets at its rate, AP size SD times
 *        `movement_scale`, the recordings' shapes) over the hour after `start_time_s`.
 */
VirtualPatient drawVirtualPatient(std::uint64_t seed, double start_time_s = 0.0,
                                  double movement_scale = 1.0);

/**
 * @brief The surgery state of the population's patient of `seed` (drawPopulationPatient): the
 *        identification state's AP slope times the gain change, its lag plus the lag change
 *        (at least 0), its drift, its small movements (its rate, the volunteers' shapes and AP
 *        size SD 0.1 mm times `movement_scale`), the cardiac component and the delivered
 *        volume's bias and breath-to-breath CV. volunteer_id is 0.
 */
VirtualPatient populationVirtualPatient(std::uint64_t seed, const PopulationPatient& patient,
                                        double start_time_s = 0.0, double movement_scale = 1.0);

/**
 * @brief Per-trial spread of the patient, ventilator, sensor and arm, drawn at every
 *        reset(seed) (the specimen's spread is SpecimenDistribution). Every SD defaults to 0:
 *        the paper's conditions (one ventilator setting, one sensor, one arm; patients differ
 *        through the five virtual volunteers). Draws are normal, truncated at +-3 SD.
 */
struct TrialVariability {
  /// Relative SD of the patient's AP displacement per ml (inter-patient amplitude), [0, 0.3].
  double patient_amplitude_scale_sd = 0.0;
  /// SD of the breathing rate around the configured ventilator rate [breaths/min], [0, 5].
  double ventilator_rate_sd_bpm = 0.0;
  /// SD of the tidal volume around the configured Tv_max [ml], [0, 200].
  double ventilator_tidal_volume_sd_ml = 0.0;
  /// Relative SD of the force/torque sensor's white-noise level, [0, 0.5].
  double sensor_noise_scale_sd = 0.0;
  /// Relative SD of every arm joint's servo stiffness (pose, payload, gear wear), [0, 0.3].
  double arm_stiffness_scale_sd = 0.0;
  /// Factor on every arm joint's servo stiffness for every trial (the arm's class: 1 = 25 N/mm at
  /// the tool, doc/simulator_physics.md §5), [0.1, 4]; the per-trial spread multiplies it.
  double arm_stiffness_scale = 1.0;
  /// Factor on the size of the volunteer's small movements, [0, 5]; 0: none. Not a spread: 1
  /// keeps the movements the virtual volunteers' recordings show (virtual_volunteer.hpp).
  double patient_movement_scale = 1.0;
  /// A model error for every trial: factor on the bone's AP slope against the patient's
  /// (robustness curves), [0.3, 3]. Not a spread.
  double patient_gain_error = 1.0;
  /// A model error for every trial: added to the bone's lag behind the volume [s] (the result at
  /// least 0), [-0.2, 0.2]; needs the bone to move as the patient (not the paper's bench).
  double patient_lag_error_s = 0.0;
  /** @brief @throws std::invalid_argument naming the field when a value is out of range. */
  void validate() const;

  /** @brief The declaration of every field (ROS names under ~trial_distribution/). */
  static const ParamTable<TrialVariability>& table();
};

/** @brief What reset(seed) drew for one trial (reported with the trial's results). */
struct TrialConditions {
  int volunteer_id = 1;                       ///< virtual volunteer of the patient (1..5)
  double patient_amplitude_scale = 1.0;       ///< factor on the volunteer's AP slope q1
  double ventilator_rate_bpm = 12.0;          ///< breathing rate of the trial [breaths/min]
  double ventilator_tidal_volume_ml = 500.0;  ///< Tv_max of the trial [ml]
  double force_noise_sd_n = 0.03;             ///< sensor white noise per force axis [N]
  double arm_stiffness_scale = 1.0;           ///< factor on every arm joint's servo stiffness
  /// The bone's AP slope [mm/ml] and lag [s] in the trial (the patient's, with the model errors).
  double patient_ap_slope_mm_per_ml = 0.0;
  double patient_lag_s = 0.0;
  /// Population patients: the slope's change from identification to surgery (1 otherwise).
  double patient_gain_change = 1.0;
};

/**
 * @brief The registration error of a trial of `seed`: the tracker camera's true pose relative
 *        to the registered one, a translation of `translation_mm` and a rotation of
 *        `rotation_deg`, each in a direction uniform on the sphere drawn from the seed's own
 *        streams (doc/simulator_physics.md section 5, "Registration error").
 */
Eigen::Isometry3d registrationError(std::uint64_t seed, double translation_mm, double rotation_deg);

/**
 * @brief Draws the trial conditions of `seed` around the configured ventilator settings and
 *        sensor noise. Deterministic for a seed; with every SD 0 it returns the configured
 *        values and scale factors of 1 (only volunteer_id depends on the seed).
 * @throws std::invalid_argument if `variability` is out of range.
 */
TrialConditions drawTrialConditions(std::uint64_t seed, const TrialVariability& variability,
                                    const VentilatorSettings& ventilator, double force_noise_sd_n);

/** @brief Parameters of the simulated workcell. Defaults and sources: simulator_physics.md. */
struct DrillingSimulationParams {
  std::string base_link = "world";     ///< root of the arm chain and of every pose
  std::string tip_link = "drill_tip";  ///< end of the arm chain (drill point)
  double physics_rate_hz = 1000.0;     ///< drilling physics and force-sensor rate
  double arm_rate_hz = 1000.0;         ///< Bullet arm rate; physics_rate / arm_rate integer
  /// @brief The arm's rate while the drill is in air, clear of the bone (arm_air_clearance_m);
  /// equal to (or above) arm_rate_hz: one rate throughout. physics_rate / it must be an integer.
  /// Chosen on
  /// calibration seeds by trace accuracy against one rate (doc/benchmarks.md).
  double arm_rate_in_air_hz = 250.0;
  /// @brief A block runs at arm_rate_in_air_hz only with the tip out of contact and at least this
  /// far above the bone's top surface, plus twice the block's approach at the last block's
  /// speed [m]. Chosen on calibration seeds by trace accuracy against one rate (doc/benchmarks.md).
  double arm_air_clearance_m = 2.0e-4;
  /// @brief The arm's BulletArmParams::inverse_inertia_tolerance [rad or m]; 0 = every step.
  double arm_inverse_inertia_tolerance = 1.0e-4;
  BulletArmParams arm;  ///< servo model (substep, inverse_inertia_tolerance set from the above)
  /// Home joint positions (joints not listed stay at 0); arm returns here on reset().
  std::map<std::string, double> home_pose = {{"rsssii_joint1", 0.0},      {"rsssii_joint2", 0.2},
                                             {"rsssii_joint3", 1.2},      {"rsssii_joint4", 0.0},
                                             {"rsssii_joint5", 1.741593}, {"rsssii_joint6", 0.0},
                                             {"feed_joint", 0.0},         {"spindle_joint", 0.0}};
  /// SPMS geometry. Defaults match urdf/workcell.urdf (checked against the URDF at startup).
  SpmsGeometry spms = urdfSpmsGeometry();
  double spms_slider_joint_offset_m = 0.05;  ///< URDF slider joint value = s - this offset
  double slider_max_speed_m_s = 0.05;        ///< lead-screw slider speed limit (URDF: 50 mm/s)
  double slider_max_accel_m_s2 = 2.0;        ///< slider drive's acceleration limit [m/s^2]
  double slider_bandwidth_hz = 20.0;         ///< slider drive's position-loop bandwidth [Hz]
  /// The drill device's feed drive (feed_joint; speed: its URDF limit): acceleration [m/s^2]
  /// and position-loop bandwidth [Hz] of a lead-screw axis like the sliders'.
  double feed_max_accel_m_s2 = 2.0;
  double feed_bandwidth_hz = 20.0;  ///< see feed_max_accel_m_s2
  /// Paper's bench (a BoneMotionModel): the SPMS controller streams the model's displacement
  /// one period ahead, every bench_period_s (the planner's 125 ms), to the slider trajectory.
  double bench_period_s = 0.125;
  double spindle_max_rpm = 21000.0;      ///< URDF spindle_joint limit 2200 rad/s
  double spindle_accel_rpm_s = 40000.0;  ///< spindle run-up rate (0 -> 12000 rpm in 0.3 s)
  /// The spindle driver's command watchdog [s], 0 = off: a running spindle that hears no
  /// speed command for this long stops (commanded to 0, counted in spindleWatchdogTrips()). A
  /// client keeps it alive by repeating its command (the planner's ~spindle_keepalive_s). 0.5 s:
  /// ros_controllers' diff_drive_controller `cmd_vel_timeout` default, a drive-side command
  /// timeout as ROS drivers set it.
  double spindle_watchdog_s = 0.5;
  /// The drivers' drill-guard timeout [s] (core::DriveGuardWatch), 0 = the drivers take no
  /// guard input. With it, every controller holds where its reference is and the spindle stops
  /// (commanded to 0) as soon as the latest onDriveEnable() is false or older than this, and
  /// commands are refused until an enable comes again (counted in driveGuardTrips()); before
  /// the first enable the drives are held (fails closed). The pipeline's simulator sets 0.08 s
  /// (config/simulator.yaml), the rule a lab's drivers follow (doc/hardware.md).
  double drive_guard_timeout_s = 0.0;
  double bone_half_x_m = 0.02;    ///< bone footprint half size along the bone frame x [m]
  double bone_half_y_m = 0.015;   ///< bone footprint half size along the bone frame y [m]
  bool moving_bone = true;        ///< initial trial: bone follows the patient (reset() sets)
  VentilatorSettings ventilator;  ///< internal ventilator driving the patient
  SpecimenDistribution specimen;  ///< specimen distribution for reset(seed)
  /// The planning step's errors and margin: the plan each reset makes (imagingPlan()).
  PlanImagingParams plan;
  TrialVariability variability;  ///< patient/ventilator/sensor/arm spread for reset(seed)
  /// The population of patients (population/enabled: a patient per seed instead of the five
  /// virtual volunteers; patient_population.hpp).
  PopulationParams population;
  DrillParameters drill;  ///< drill and force-law constants
  /// Force/torque sensor model, at the DAQ rate calibrated against the paper's Fig. 16 and 18
  /// (calibratedSensor()).
  ForceSensorParams sensor = calibratedSensor();
  /// The sensor tared at every reset, its bias gone before the trial (true: the benches as the
  /// paper's results were simulated). false: the sensor keeps its bias (force_bias_sd_n per
  /// axis, plus sensor_bias_offset_n) until a tare request (requestTare) takes it, as a real F/T
  /// sensor does (hardware.launch's trials tare with the spindle running).
  bool sensor_tared_at_reset = true;
  /// A constant offset of the untared thrust axis (z) [N]: the weight of the tool beyond the
  /// sensor (spindle motor and bit; 4.9 N for 0.5 kg, an assumption, doc/simulator_physics.md).
  /// Only with sensor_tared_at_reset false. [-50, 50].
  double sensor_bias_offset_n = 0.0;
  double tracker_noise_rms_mm = 0.25;  ///< 3-D RMS position noise of the marker (NDI Polaris)
  /// Registration error between the tracker and the robot: the camera's true pose
  /// is the registered one (the URDF's tracker_camera) moved by this much in a direction drawn
  /// from each trial's seed [mm] ...
  double registration_error_mm = 0.0;
  /// ... and turned by this much about an axis drawn from the seed [deg].
  double registration_error_deg = 0.0;
  /// The breath phase as a bench senses it: each breath's start is detected on a
  /// flow sensor sampled at this rate (the nearest whole number of physics steps), at its first
  /// sample whose flow exceeds breath_trigger_flow_ml_s; the paper records with a gas-flow sensor
  /// at 64 Hz. 0: the ventilator's own breath start, exact (the paper's bench as simulated).
  double breath_sensor_rate_hz = 0.0;
  /// Inspiratory flow that marks a breath's start on the sensed signal [ml/s] (2 L/min).
  double breath_trigger_flow_ml_s = 100.0 / 3.0;
  /// Latency from the flow sensor's sample to the pipeline [s]: a detected breath start
  /// arrives this much later and is stamped on its arrival (sensor response and export path).
  double breath_sensor_latency_s = 0.0;
  /// Offset of the breath sensor's clock against the pipeline's [s] (two PCs), added to each
  /// sensed breath start; with breath_sensor_rate_hz 0 it is not used.
  double breath_clock_offset_s = 0.0;
  /// The arm controllers' clock against the pipeline's (two PCs): the controllers
  /// read a command's stamps on a clock c(t) = t + arm_clock_offset_s + arm_clock_drift_ppm
  /// 1e-6 t (t: sim time since the trial's reset), so a stamp s takes effect at the true time
  /// (s - offset) / (1 + drift). NTP on a LAN keeps the offset to tens of us (bench_sources
  /// item 3); unsynchronised PCs drift apart by up to tens of ppm (crystal tolerance).
  double arm_clock_offset_s = 0.0;
  double arm_clock_drift_ppm = 0.0;  ///< see arm_clock_offset_s
  /// The arm's controllers as a lab wires them: names and joint sets.
  ControllerLayoutParams controllers;
  /// The rules the simulated controllers apply: ros_control's (strict) by default.
  ControllerRules controller_rules;
  /** @brief SPMS geometry that matches urdf/workcell.urdf. */
  static SpmsGeometry urdfSpmsGeometry();
  /**
   * @brief The sensor model with the DAQ rate calibrated against the paper's force figures:
   *        1000/3 Hz, every third physics step (doc/simulator_physics.md, "Measurement chain").
   */
  static ForceSensorParams calibratedSensor();

  /**
   * @brief Checks the declared fields, the arm rate (a divisor of the physics rate) and the
   *        ventilator, specimen and variability settings.
   * @throws std::invalid_argument whose message starts with the parameter name.
   */
  void validate() const;

  /**
   * @brief The declaration of the fields a node sets (the Simulator's ROS parameters): its own,
   *        ventilator/... and trial_distribution/... (specimen/... in mm).
   */
  static const ParamTable<DrillingSimulationParams>& table();
};

/**
 * @brief Physics steps between two samples of a stream published at `rate_hz` (at least 1):
 *        round(physics_rate_hz / rate_hz). Shared by the Simulator nodelet and the closed-loop
 *        engine so that both sample every stream at the same steps.
 * @throws std::invalid_argument naming `name` unless 0 < rate_hz <= physics_rate_hz.
 */
std::uint64_t streamPeriodSteps(double physics_rate_hz, double rate_hz, const std::string& name);

/** @brief Output of one physics step. */
struct SimulationStep {
  double time_s = 0.0;                      ///< simulation time at the end of the step
  Wrench measured_wrench = Wrench::Zero();  ///< force-sensor sample (sensor frame)
  /** @brief A force-sensor sample was taken in this step (every step at the default 1 kHz
   *         sensor; else every physics / sensor rate steps); measured_wrench is valid only then. */
  bool force_sampled = true;
  ForceSample force;           ///< true drilling output of the step
  double tip_depth_m = 0.0;    ///< tip depth below the bone top surface (negative: above)
  bool layer_changed = false;  ///< the layer at the deepest cut changed in this step
};

/** @brief Ground truth of the simulated trial (what no sensor sees). */
struct SimulationGroundTruth {
  std::uint64_t seed = 0;                  ///< seed of the current specimen / patient
  Material layer = Material::kAir;         ///< material at the deepest cut (air before any cut)
  double tip_depth_m = 0.0;                ///< current tip depth below the bone top surface [m]
  double max_depth_cut_m = 0.0;            ///< deepest point cut [m]
  double outer_cortical_end_m = 0.0;       ///< depth of the outer-cortical / cancellous boundary
  double inner_cortical_start_m = 0.0;     ///< depth of the cancellous / inner-cortical boundary
  double inner_cortical_end_m = 0.0;       ///< depth of the canal wall
  double residual_inner_cortical_m = 0.0;  ///< inner cortex left below the deepest cut
  bool breakthrough = false;               ///< the tip passed the canal wall
  double thrust_n = 0.0;                   ///< true thrust [N]
  bool contact = false;                    ///< lips cutting
  /** @brief Separations of drill and bone since reset() or startTrial(): gaps of at least 10 ms
   *  without contact after a contact (shorter ones are the lips' chatter at first contact). */
  std::uint32_t contact_loss_count = 0;
  double feed_per_rev_m = 0.0;  ///< actual feed per revolution [m]
  Eigen::Vector3d bone_displacement_m = Eigen::Vector3d::Zero();  ///< (LR, SI, AP) from home
  double tidal_volume_ml = 0.0;  ///< patient tidal volume (unlagged) [ml]
  double relative_ap_m =
      0.0;  ///< AP motion of tip relative to bone since reset() or startTrial() [m]
  double spindle_rpm = 0.0;             ///< spindle speed actually running [rpm]
  double feed_joint_m = 0.0;            ///< the feed joint's position [m]
  bool drives_halted = false;           ///< the drivers hold: no drill-guard enable (see params)
  std::uint32_t drive_guard_trips = 0;  ///< halts by the drill guard since construction
  std::uint32_t controller_aborts = 0;  ///< abortController() calls since construction
};

/** @brief A parent -> child transform of the URDF tree. */
struct FrameTransform {
  std::string parent;           ///< parent frame (URDF link)
  std::string child;            ///< child frame (URDF link)
  Eigen::Isometry3d transform;  ///< child pose in the parent frame
};

/**
 * @brief The simulated workcell. Not thread-safe: callers serialise access.
 */
class DrillingSimulation {
 public:
  /**
   * @brief Builds everything from URDF XML text and draws specimen / patient from `seed`.
   * @throws std::runtime_error for an unusable URDF (parse error, missing chain or SPMS links,
   *         SPMS geometry not matching params.spms) or std::invalid_argument for bad params.
   */
  DrillingSimulation(const std::string& urdf_xml, const DrillingSimulationParams& params,
                     std::uint64_t seed = 1);
  ~DrillingSimulation();
  DrillingSimulation(const DrillingSimulation&) = delete;
  DrillingSimulation& operator=(const DrillingSimulation&) = delete;

  /**
   * @brief New trial: specimen sample(seed), patient drawVirtualPatient(seed), new tared
   *        sensor, drilling state cleared, arm teleported to the home pose (targets too), spindle
   *        stopped, trajectory cleared. Time and the ventilator keep running; the platform moves
   *        (rate limited) to its new target.
   */
  void reset(std::uint64_t seed, bool moving_bone);

  /**
   * @brief Replaces the distributions the next reset(seed) draws from (the current trial is
   *        not changed). @throws std::invalid_argument if a value is out of range; nothing
   *        changes then.
   */
  void setTrialDistribution(const SpecimenDistribution& specimen,
                            const TrialVariability& variability);
  /**
   * @brief From the next reset on, the bone plays `model` (the paper's bench protocol) instead
   *        of the virtual volunteer's truth; std::nullopt goes back to the virtual patient. The
   *        volunteer id and the other draws are unchanged.
   * @throws std::invalid_argument for a non-finite coefficient; nothing changes then.
   */
  void setBoneMotionModel(const std::optional<BoneMotionModel>& model);
  /**
   * @brief Fault injection: the patient's AP displacement is multiplied by `factor` from the
   *        next step until the next reset (a change of the patient's breathing that the
   *        identified model does not know). @throws std::invalid_argument outside [0, 10].
   */
  void setPatientAmplitudeFactor(double factor);
  /**
   * @brief The drilling plan of the current specimen, made at its reset (makeImagingPlan with
   *        params().plan and the seed), in the tracker_marker frame.
   */
  const ImagingPlan& imagingPlan() const;
  /** @brief What the last reset (or the constructor) drew. */
  const TrialConditions& trialConditions() const;

  /** @brief Advances one physics step (1 / physics_rate_hz). */
  SimulationStep stepOnce();
  /**
   * @brief Times the steps' components into @p profile (nullptr: off, no clock read).
   *        Not owned: it must outlive the simulation or be reset to nullptr.
   */
  void setProfile(ComponentProfile* profile);
  /** @brief Advances by at least `dt` seconds (whole physics steps); returns steps run. */
  int step(double dt);

  /**
   * @brief A new trajectory for the controller named @p controller, with its rules
   *        (JointTrajectoryExecutor: ros_control's JointTrajectoryController semantics; strict
   *        by default). An unknown controller is rejected.
   */
  TargetResult commandTrajectory(const std::string& controller, const TrajectoryCommand& command);
  /**
   * @brief A planner's command over any commandable joints, split by controller
   *        (splitByController) and sent to each, as the planner nodelet publishes it. A joint no
   *        controller owns (or spindle_joint) rejects the whole command before any part is sent.
   * @return the first part's result that is not kAccepted, else kAccepted.
   */
  TargetResult commandTrajectory(const TrajectoryCommand& command);
  /**
   * @brief A drive fault: the commandable @p joint stops following its controller and holds
   *        where it is (a brake engaged, a stalled motor) until the next reset, or until called
   *        with @p stalled false. Its controller's error (desired - actual) grows.
   * @throws std::invalid_argument for a joint that is not commandable.
   */
  void setJointStalled(const std::string& joint, bool stalled);
  /**
   * @brief Controller @p controller aborts its trajectory (ros_control's
   *        JointTrajectoryController on a path or goal tolerance violation): it drops it and
   *        holds its joints where its reference is now; the next command is taken as usual.
   *        Counted in controllerAborts(). @throws std::invalid_argument for an unknown name.
   */
  void abortController(const std::string& controller);
  /**
   * @brief Controller @p controller drops its trajectory and holds where its reference is (a
   *        canceled FollowJointTrajectory goal: ros_control's JointTrajectoryController holds).
   *        Not an abort. @throws std::invalid_argument for an unknown name.
   */
  void holdController(const std::string& controller);
  /** @brief Time [s] of the last point of controller @p index's trajectory (-inf: it holds). */
  double controllerTrajectoryEnd(std::size_t index) const;
  /** @brief Controller aborts (abortController()) since construction. */
  int controllerAborts() const;
  /** @brief The controllers (names and joints, the order of controllerState()'s index). */
  const std::vector<ControllerSpec>& controllers() const;
  /**
   * @brief The state of controller @p index now, as ros_control's controller publishes it on
   *        `state`: joint names, desired (the trajectory's reference), actual (the measured
   *        joints) and error = desired - actual.
   */
  ControllerStateSample controllerState(std::size_t index) const;
  /** @brief Time [s] of the last point of any controller's trajectory (-inf: all hold). */
  double armTrajectoryEnd() const;
  /**
   * @brief Spindle speed command [rpm]; NaN/inf/negative rejected, above the limit clamped. Any
   *        accepted command, a repeated one too, feeds the driver's watchdog
   *        (DrillingSimulationParams::spindle_watchdog_s).
   */
  TargetResult commandSpindle(double rpm);
  /** @brief How often the spindle driver's watchdog stopped the spindle since the last reset. */
  int spindleWatchdogTrips() const;
  /**
   * @brief The drill guard's enable (drill_guard/enable) received now: the drivers' input of
   *        DrillingSimulationParams::drive_guard_timeout_s (ignored when that is 0).
   */
  void onDriveEnable(bool enable);
  /** @brief Whether the drivers hold for want of the drill guard's enable (as of the last step). */
  bool drivesHalted() const;
  /** @brief Halts by the drill guard since construction. */
  int driveGuardTrips() const;
  /**
   * @brief The sensor driver's tare (ForceTare): the next request.samples output samples are
   *        averaged into the bias subtracted from then on. @throws std::invalid_argument for a
   *        bad request.
   */
  void requestTare(const TareRequest& request);
  /** @brief The result of the tare window that completed since the last call, if any. */
  std::optional<TareResult> takeTareResult();
  /** @brief Queues new ventilator settings (take effect at the next breath); throws if bad. */
  void requestVentilatorSettings(const VentilatorSettings& settings);

  /** @brief Simulation time [s]. */
  double time() const;
  /** @brief Physics step [s]. */
  double physicsDt() const;
  /** @brief All simulated arm joints (commandable ones plus spindle_joint), base to tip. */
  const std::vector<std::string>& armJointNames() const;
  /** @brief Arm joint positions / velocities (order of armJointNames()). */
  Eigen::VectorXd armJointPositions() const;
  /** @brief Arm joint velocities (order of armJointNames()). */
  Eigen::VectorXd armJointVelocities() const;
  /** @brief Servo stiffness of every arm joint (order of armJointNames()), after the trial's
   *         stiffness scale [Nm/rad or N/m]. */
  Eigen::VectorXd armJointStiffness() const;
  /** @brief Arm joint efforts of the last Bullet step. */
  Eigen::VectorXd armJointEfforts() const;
  /** @brief SPMS joint names (slider1..3_joint, rod1..3_joint) and their URDF values. */
  std::vector<std::pair<std::string, double>> spmsJointStates() const;
  /** @brief Actual slider positions along the rails [m] (SpmsKinematics convention). */
  Eigen::Vector3d sliderPositions() const;
  /** @brief Platform pose from the FK of the actual sliders. */
  const PlatformFullPose& platformPose() const;
  /** @brief Desired platform heave (patient AP displacement) [m]. */
  double desiredHeave() const;
  /** @brief Pose of the drill tip in the base frame (last arm state). */
  Eigen::Isometry3d tipPose() const;
  /** @brief Pose of any URDF link in the base frame (world). @throws std::out_of_range. */
  Eigen::Isometry3d linkPose(const std::string& link) const;
  /** @brief World z of the bone top surface (bone frame origin). */
  double boneTopZ() const;
  /** @brief Spindle speed actually running [rpm] (rate limited). */
  double spindleRpm() const;
  /** @brief Ground truth now. */
  SimulationGroundTruth groundTruth() const;
  /** @brief Current drilling process (specimen, depth cut, ...). */
  const DrillingProcess& process() const;
  /** @brief Current patient. */
  const VirtualPatient& patient() const;
  /**
   * @brief Marks the start of a trial: ground truth's relative AP motion is measured from now,
   *        and the trial counter increments. A specimen is never drilled twice: if the current
   *        one has been cut, the bench mounts a fresh one first, as reset(seed() + 1,
   *        movingBone()) with the same distributions and bone motion model (arm at home).
   * @return true when a fresh specimen was mounted.
   */
  bool startTrial();
  /** @brief Trials started since construction (reset() does not count). */
  int trialCount() const;
  /** @brief Physics steps in the arm block under way (arm_rate_in_air_hz's in air). */
  int armBlockSteps() const;
  /** @brief Arm blocks run at arm_rate_in_air_hz since construction. */
  std::uint64_t armBlocksInAir() const;
  /** @brief Internal ventilator sample of the last step (unlagged). */
  const VentilatorSample& ventilatorSample() const;
  /**
   * @brief Time since the current breath's start as the pipeline senses it (>= 0): from the
   *        ventilator's own start with breath_sensor_rate_hz 0, else from the last breath start
   *        detected on the flow sensor (the previous breath's until the new one is detected),
   *        shifted by breath_clock_offset_s. The TidalVolume stream's time_in_breath_s and the
   *        core engine's breath phase, one rule for both.
   */
  double sensedTimeInBreath() const;
  /**
   * @brief Whether the last step took a sample of the breath sensor (every physics rate /
   *        breath_sensor_rate_hz steps; never at 0 Hz): its flow, the airway flow into the
   *        patient in ml/s, is ventilatorSample().flow_ml_s, taken at time(). The Simulator
   *        nodelet publishes these samples (breath_sensor/flow).
   */
  bool breathFlowSampled() const;
  /** @brief The internal ventilator (breath index and start, current settings). */
  const BreathScheduler& ventilator() const;
  /**
   * @brief The patient's breathing, which moves the bone: the ventilator's, sampled the
   *        patient's lag_s late (its breath index and settings follow the ventilator's).
   */
  const BreathScheduler& patientBreathing() const;
  /** @brief Whether the bone follows the patient. */
  bool movingBone() const;
  /** @brief Seed of the current trial. */
  std::uint64_t seed() const;

  /**
   * @brief True when the optical tracker samples at the end of the last step: every
   *        period_steps steps (125 at 8 Hz), at a phase drawn from the trial's seed. The tracker
   *        and the ventilator are independent devices: with both grids starting at 0, a 5 s
   *        breath is exactly 40 tracker periods and every 125 ms segment end would fall on
   *        every inspiration start in every trial (the worst case for a dTv/dt step).
   */
  bool trackerDue(std::uint64_t period_steps) const;

  /**
   * @brief Tracker measurement of tracker_marker in the tracker_camera frame, with isotropic
   *        Gaussian position noise (tracker_noise_rms_mm 3-D RMS); orientation exact.
   */
  Eigen::Isometry3d measureMarkerPose();

  /**
   * @brief Transforms of the URDF tree. `fixed` true: the constant transforms of fixed joints
   *        (publish once, tf_static); false: every moving joint (arm from Bullet link poses,
   *        sliders / rods / floating platform from the SPMS state).
   */
  std::vector<FrameTransform> frameTransforms(bool fixed) const;

  /** @brief The arm (for tests and benchmarks). */
  const BulletArm& arm() const;
  /** @brief The parameters in use. */
  const DrillingSimulationParams& params() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_DRILLING_SIMULATION_HPP
