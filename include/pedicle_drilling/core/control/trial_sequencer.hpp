// The trial sequence of Algorithm 1 (paper Sec. IV-B), with no ROS and explicit time: spindle
// on, arm to the drilling pose, marker registration, 125 ms trapezoidal segments of feed (+ the
// predicted displacement in compensated mode), stop and hold, retreat, done. The
// CompensationPlanner nodelet and the closed-loop engine drive the very same object: they feed
// it their inputs, fire the timers it asks for, and carry out the commands it emits.
#ifndef PEDICLE_DRILLING_CORE_TRIAL_SEQUENCER_HPP_
#define PEDICLE_DRILLING_CORE_TRIAL_SEQUENCER_HPP_

#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/motion_model.hpp"
#include "pedicle_drilling/core/breathing/ventilator.hpp"
#include "pedicle_drilling/core/control/compensation_planner.hpp"
#include "pedicle_drilling/core/control/controller_watch.hpp"
#include "pedicle_drilling/core/control/depth_limit.hpp"
#include "pedicle_drilling/core/control/safety_monitor.hpp"
#include "pedicle_drilling/core/drilling/force_tare.hpp"

namespace pedicle_drilling::core {

/** @brief Phase of a trial (the planner's status; the values of msg/TrialStatus.msg). */
enum class TrialPhase : std::uint8_t {
  kIdle = 0,
  kMovingToPose = 1,
  kRegistering = 2,
  kDrilling = 3,
  kStopped = 4,
  kRetreating = 5,
  kDone = 6,
  kFailed = 7,
};

/** @brief Status text of a phase: idle, moving_to_pose, ..., done, failed. */
const char* toString(TrialPhase p);

/** @brief True while a trial runs (moving_to_pose .. retreating). */
bool isRunning(TrialPhase p);

/** @brief Parameters of the sequence (the CompensationPlanner's, doc/nodes.md). */
struct TrialSequencerParams {
  /** @brief Segmentation and prediction; feed_rate_m_s is set per trial. drill_axis is set from
   *         the arm by the constructor. */
  CompensationParams compensation;
  double default_feed_rate_mm_s = 0.5;   ///< StartTrial 0 means this, (0, max_feed_rate_mm_s]
  double default_spindle_rpm = 12000.0;  ///< (0, max_spindle_rpm]
  /**
   * @brief The drill's declared spindle limit [rpm], (0, 60000]: a StartTrial (or default)
   *        speed above it is refused. 20000 rpm: the highest speed the paper drilled with its
   *        device (Sec. V-C: 12000, 16000 and 20000 rpm); above it nothing was tried.
   */
  double max_spindle_rpm = 20000.0;
  /**
   * @brief The drill's declared feed limit [mm/s], (0, 10]: a StartTrial (or default) feed rate
   *        above it is refused. 3 mm/s is an assumption: six times the paper's 0.5 mm/s (Sec.
   *        V-A), the highest feed of the bone-drilling thrust study with the paper's 2.5 mm bit
   *        that the simulator's force law draws on (0.5 to 3 mm/s, doc/bench_sources.md).
   */
  double max_feed_rate_mm_s = 3.0;
  /// While the spindle runs, its speed command is repeated every this many seconds, so that the
  /// driver's watchdog (a drive-side command timeout; the simulator's spindle_watchdog_s, 0.5 s)
  /// keeps it running and stops it when the planner dies. [0 (one command per change), 10] s.
  double spindle_keepalive_s = 0.1;
  double default_max_duration_s = 120.0;  ///< (0, 3600]
  double move_duration_s = 2.0;           ///< arm motion to the drilling pose, (0, 60]
  double settle_s = 0.5;                  ///< wait before the registration, [0, 60]
  int registration_samples = 4;           ///< tracker samples averaged, [1, 100]
  /**
   * @brief Where the arm drills from: false, the configured drilling pose (joint values);
   *        true, a pose aimed at the drilling plan at each start(): the drill axis along the
   *        plan's direction, the tip target_standoff_m before its entry, both placed in the world
   *        by the latest tracked marker pose (at most target_marker_age_s old), solved by the
   *        arm's IK from the configured pose (ArmCompensation::aimedAt). A plan the arm cannot
   *        reach refuses the trial, naming why.
   */
  bool target_from_plan = false;
  /** @brief With target_from_plan: the tip's distance before the planned entry at the drilling
   *         pose [m], [0, 0.05]: 5 mm, where the shipped drilling pose leaves the tip above the
   *         simulated bone's surface. */
  double target_standoff_m = 0.005;
  /** @brief With target_from_plan: the oldest tracked marker pose that places the plan [s],
   *         (0, 10]: 1 s, eight samples of the 8 Hz tracker. */
  double target_marker_age_s = 1.0;
  /**
   * @brief The F/T tare before contact, in samples of the sensor [0, 100000]; 0 (the
   *        benches, whose simulated sensor is tared at reset): none. Else, when the arm reached
   *        the drilling pose (spindle running, tool free), a TareRequest goes to the sensor's
   *        driver (`ft_sensor/tare_request`) and the drilling waits for its successful result as
   *        well as for the registration, both within registration_timeout_s.
   */
  int tare_samples = 0;
  /// The largest force spread over the tare window [N] (else the tare fails, and the trial):
  /// far above a running spindle's noise on the sensor (about 0.05 N), far below a tool
  /// touching something (newtons). (0, 100].
  double tare_max_spread_n = 0.5;
  double registration_timeout_s = 3.0;  ///< (0, 60]
  /// Hold [s] after a recognizer stop before the retreat, [0, 60]; 0 (default): retreat at once
  /// (chosen on calibration seeds, doc/campaign_results.md "Constants chosen on simulated
  /// outcomes").
  double stop_hold_s = 0.0;
  /**
   * @brief While drilling, the recognizer's drilling_state (every averaged sample, 20 Hz) must
   *        not be silent longer than this, else stop and retreat (its nodelet was unloaded or
   *        died: nothing would stop the feed at the inner layer). [0 (off), 60] s.
   */
  double recognizer_timeout_s = 0.5;
  /**
   * @brief While drilling, the safety monitor must have been heard (onMonitorAlive: its
   *        /diagnostics, every 1 s and at once on a stop) within this, else stop and retreat.
   *        [0 (off), 60] s.
   */
  double monitor_timeout_s = 2.5;
  /**
   * @brief Geometric plausibility of the outer cortical layer [mm], 0 = off. Once the
   *        tip's deepest predicted advance into the bone (feed relative to the bone: the
   *        commanded feed minus the predicted bone displacement along the drill axis) exceeds
   *        this much past where the recognizer first reported contact, the outer cortex must
   *        have been cut through; if the recognizer still reports `outer_cortical`
   *        `recognizer_delay_s` later, the force is implausible (a drifting sensor keeps
   *        Algorithm 2 from ending the layer) and the drill stops with retreat. Default 3.5 mm:
   *        the thickest outer cortex of the simulated specimens' documented range (2.0 mm + 4 x
   *        0.3 mm) plus 0.3 mm for the prediction error of the linear model on the virtual
   *        patient (doc/state_machine.md). Set it from the specimen's range, never from
   *        observed durations.
   */
  double outer_cortical_max_mm = 3.5;
  /**
   * @brief The same bound for the cancellous layer [mm], 0 = off: from the recognizer's first
   *        report of `cancellous` (key point 3), once the deepest predicted advance is this much
   *        further and `recognizer_delay_s` has passed, a recognizer still reporting
   *        `cancellous` has missed the inner layer: stop with retreat, reason `implausible
   *        force`. By then the cut has passed the thickest cancellous layer of the range, so it
   *        is in the inner layer or through it: the bound limits the damage of a missed inner
   *        layer, it does not prevent it. Default 8.3 mm: the thickest cancellous layer of the
   * documented range (4.0 mm + 4 x 1.0 mm) plus 0.3 mm of prediction error.
   */
  double cancellous_max_mm = 8.3;
  /**
   * @brief The recognizer's averaging delay [s]: how long after the force changes its
   *        averaged force shows it (window x pre_average_s; 10 x 0.15 s = 1.5 s with the
   *        shipped recognizer, at any sensor rate). [0, 60].
   */
  double recognizer_delay_s = 1.5;
  RetreatParams retreat;  ///< retreat along the drill axis
  /// The drilling plan's depth limit (depth_limit/..., DepthLimit): the last line against a
  /// perforation, whichever recognizer or compensator runs.
  DepthLimitParams depth_limit;
  /// The controllers the commands go to (arm_controller, feed_controller and their joints).
  ControllerLayoutParams controllers;
  /// The closed loop on them (controller_watch/..., ControllerWatch).
  ControllerWatchParams controller_watch;
  std::vector<std::string> arm_joints;  ///< the arm's joints, in command order
  std::string feed_joint = "feed_joint";
  double feed_lower_m = 0.0;  ///< feed joint limits (URDF)
  double feed_upper_m = 0.06;

  /** @brief Check every field. @throws std::invalid_argument naming the field first. */
  void validate() const;

  /** @brief The declaration of the fields a node sets (names as the ROS parameters). */
  static const ParamTable<TrialSequencerParams>& table();
};

/** @brief What a trial is started with; 0 in a number means the parameter's default. */
struct TrialRequest {
  std::string mode;  ///< stationary | uncompensated | compensated
  double spindle_rpm = 0.0;
  double feed_rate_mm_s = 0.0;
  double max_duration_s = 0.0;
  /** @brief rest_to_rest | exact for this trial; "" means params().compensation's. */
  std::string segment_profile;
};

/** @brief One joint trajectory command (trajectory_msgs/JointTrajectory semantics). */
struct JointTrajectoryCommand {
  /** @brief One point: time from the start time, positions and velocities per joint. */
  struct Point {
    double time_from_start = 0.0;
    std::vector<double> positions;
    std::vector<double> velocities;
  };
  double start_time = 0.0;  ///< header stamp [s]
  std::vector<std::string> joint_names;
  std::vector<Point> points;
};

/** @brief The command as the executor takes it: absolute point times (start + from start). */
TrajectoryCommand toExecutorCommand(const JointTrajectoryCommand& command);

/** @brief The predicted marker pose at a tracker sample's stamp (for the safety monitor). */
struct PredictedMarker {
  double stamp = 0.0;
  std::string frame;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
};

/** @brief A timer the driver must run: call the matching on*() method when it fires. */
struct TimerRequest {
  enum class Kind { kPoseReached, kRegistrationTimeout, kSegment, kSpindleKeepalive };
  Kind kind = Kind::kSegment;
  double delay_s = 0.0;   ///< first firing after this much time from the request
  bool periodic = false;  ///< then every delay_s
};

/** @brief A message for the driver's log. */
struct SequencerLog {
  enum class Level { kInfo, kWarn, kError };
  Level level = Level::kInfo;
  std::string text;
};

/** @brief Everything one call produced, in order of emission within each list. */
struct SequencerOutput {
  std::vector<JointTrajectoryCommand> trajectories;
  std::vector<double> spindle_rpm;
  std::vector<TrialPhase> phases;
  std::vector<PredictedMarker> predicted;
  std::vector<TimerRequest> start_timers;
  bool stop_timers = false;  ///< stop every timer started before (applied before start_timers)
  std::vector<SequencerLog> log;
  /** @brief Stops the sequencer itself decided (a silent component): the driver announces each
   *         as a StopCommand with retreat = true. */
  std::vector<std::string> stops;
  /** @brief Tare requests for the F/T sensor's driver (TrialSequencerParams::tare_samples). */
  std::vector<TareRequest> tare_requests;

  /** @brief True if nothing was produced. */
  bool empty() const;
  /** @brief True if it holds something a node publishes (not the timers or the log). */
  bool publishesAnything() const;
};

/**
 * @brief The timers a TrialSequencer asked for, run on explicit time: the closed-loop engine's
 *        and, under the simulator's lockstep, the CompensationPlanner nodelet's (one rule, so
 *        that both fire the same timer at the same step).
 */
class SequencerTimers {
 public:
  /** @brief Applies an output's timer requests made at `now` (stop_timers first). */
  void apply(const SequencerOutput& out, double now);
  /**
   * @brief The earliest timer due at `now` (1e-9 s of rounding allowed), advanced by its period
   *        or removed when one-shot; nullopt when none is due.
   */
  std::optional<TimerRequest::Kind> popDue(double now);
  /** @brief When the earliest pending timer is due (popDue() returns it from then, less its
   *         1e-9 s of rounding); nullopt when none is pending. */
  std::optional<double> nextDue() const;
  /** @brief Forget every timer. */
  void clear() { timers_.clear(); }
  /** @brief No timer is pending. */
  bool empty() const { return timers_.empty(); }

 private:
  struct Timer {
    TimerRequest::Kind kind;
    double due;
    double period;  // 0: one shot
  };
  std::vector<Timer> timers_;
};

/** @brief Makes the compensator of a trial; configured, one per trial. */
using CompensatorFactory = std::function<std::unique_ptr<CompensatorInterface>()>;

/**
 * @brief World -> tracker-frame lookup: true and *frame_from_world (the transform that takes
 *        world coordinates into the frame's, tf's lookupTransform(frame, world)) when known,
 *        false to wait (the sample is skipped). An empty frame or the world frame never calls it.
 */
using FrameLookup =
    std::function<bool(const std::string& frame, Eigen::Isometry3d* frame_from_world)>;

/**
 * @brief The trial sequence, driven by explicit time. Not thread-safe: one driver calls it.
 *
 * Every call appends to an output that the driver takes with takeOutput() and carries out
 * (publishes, or hands to the simulation), in order.
 */
class TrialSequencer {
 public:
  /**
   * @brief Construct.
   * @param params validated here (throws std::invalid_argument naming the field).
   * @param arm the arm's drilling pose and feed home.
   * @param world_frame frame in which the planner works; markers in it need no rotation.
   */
  TrialSequencer(const TrialSequencerParams& params, const ArmCompensation& arm,
                 std::string world_frame = "world");

  /**
   * @brief The compensator class of the next trials: empty (the default) is the
   *        paper's, PaperCompensator. The factory is called by start(); an exception it throws
   *        is start()'s refusal.
   */
  void setCompensatorFactory(CompensatorFactory factory) { make_compensator_ = std::move(factory); }

  /**
   * @brief New ventilator settings (from the ventilator; applied to a running prediction).
   *        @throws std::invalid_argument for invalid settings (nothing changes). An error of the
   *        compensator class here (or in setBreathStart) stops the trial at the next segment tick.
   */
  void setVentilator(const VentilatorSettings& settings);
  /** @brief Start time of the current breath (tidal volume stamp - time in breath). */
  void setBreathStart(double t);
  /**
   * @brief Where the breath phase comes from, for the reasons below (default "tidal_volume"),
   *        and how old the latest breath start may be in a moving trial, in breath periods of
   *        the current settings (0, the default: no bound). Beyond it a moving trial is refused
   *        and a drilling one stopped with retreat, the reason naming @p source.
   */
  void setBreathSource(const std::string& source, double timeout_periods);
  /** @brief The breath source's own report that its phase is unusable ("": it is usable), e.g.
   *         the Ventilator's flow source before its first detected breath; quoted the same way. */
  void setBreathSourceProblem(const std::string& problem);
  /** @brief Why the breath phase is unusable for a moving trial at @p now ("": it is usable). */
  std::string breathProblem(double now) const;

  /**
   * @brief Start a trial at `now` with the patient's motion model.
   * @return "" when started, else the reason (nothing was started; the phase is unchanged).
   */
  std::string start(const TrialRequest& request, const MotionModel& model, double now);

  /** @brief What start() would answer about the request alone ("" = acceptable). */
  std::string check(const TrialRequest& request) const;

  /** @brief A tracked marker sample (stamp = measurement time). */
  void onMarker(double now, double stamp, const std::string& frame, const Eigen::Vector3d& p,
                const Eigen::Quaterniond& orientation, const FrameLookup& lookup);
  /**
   * @brief The drilling plan of the next trials (nullopt: none). start() refuses a trial without
   *        one when depth_limit.require_plan, and one that DrillingPlan::check() refuses; the
   *        registration places it (DepthLimit::begin).
   */
  void setPlan(std::optional<DrillingPlan> plan) { plan_ = std::move(plan); }
  /** @brief The plan of the next trials. */
  const std::optional<DrillingPlan>& plan() const { return plan_; }
  /** @brief The arm of the current (or last) trial: the configured drilling pose, or the one
   *         aimed at the plan (target_from_plan). */
  const ArmCompensation& arm() const { return arm_; }
  /** @brief The current trial's depth limit (inactive without a plan). */
  const DepthLimit& depthLimit() const { return depth_; }
  /**
   * @brief The tip's advance into the bone along the drill axis since the registration as the
   *        depth limit measures it [m]: CompensationPlanner::predictedAdvance (the commanded
   *        reference less the bone the compensator predicts; zero bone when stationary); its
   *        tracker correction is DepthLimit::correction(). 0 before the drilling.
   */
  double limitAdvance(double t) const;
  /**
   * @brief A force sample: the thrust along the drill axis [N] measured at @p stamp (the F/T
   *        sensor's tared z). While drilling it shows the contact with the bone (DepthLimit).
   */
  void onForce(double now, double stamp, double thrust_n);

  /** @brief A stop command (retreat = true from the safety monitor, false from the recognizer). */
  void onStop(double now, bool retreat, const std::string& reason);
  /**
   * @brief The recognizer's latest state. A reported stop is a stop while drilling; a stop it
   *        still reports when the registration ends (latched from an earlier trial) fails the
   *        trial before the first feed.
   */
  void onRecognizerState(double now, bool stop, const std::string& state_name, int key_point);

  /**
   * @brief A controller's state (`<name>/state`, received at @p now): the closed loop on what
   *        the arm does (ControllerWatch). A command refused or late, a joint that does not
   *        follow: a stop with retreat, announced in SequencerOutput::stops with the reason.
   */
  void onControllerState(double now, const std::string& name, const ControllerStateSample& state);

  /**
   * @brief A controller refused or dropped a command (a follow_joint_trajectory goal rejected or
   *        aborted): the same fault as the controller watch's (onControllerState) while a trial
   *        runs, a stop with retreat announced in SequencerOutput::stops with @p why. Nothing
   *        when no trial runs.
   */
  void onControllerFault(double now, const std::string& why);

  /** @brief The controllers the commands go to (the layout of params().controllers). */
  const std::vector<ControllerSpec>& controllers() const { return controllers_; }
  /** @brief The closed loop's watch (its worst ratios since the trial's start). */
  const ControllerWatch& controllerWatch() const { return *watch_; }

  /**
   * @brief The sensor driver's tare result (`ft_sensor/tare_result`). While the trial waits for
   *        it, a success lets the drilling start (once registered), a failure fails the trial;
   *        otherwise it is ignored.
   */
  void onTareResult(double now, const TareResult& result);

  /** @brief The safety monitor is alive (a /diagnostics status of it, or in-process). */
  void onMonitorAlive(double now);

  /** @brief TimerRequest::kPoseReached fired. */
  void onPoseReached(double now);
  /** @brief TimerRequest::kRegistrationTimeout fired. */
  void onRegistrationTimeout(double now);
  /** @brief TimerRequest::kSegment fired. */
  void onSegmentTimer(double now);
  /** @brief TimerRequest::kSpindleKeepalive fired: the running spindle's command again. */
  void onSpindleKeepalive(double now);

  /** @brief Current phase. */
  TrialPhase phase() const { return phase_; }
  /** @brief Whether the ventilator's settings and breath phase are known. */
  bool haveVentilator() const { return have_settings_ && have_phase_; }
  /** @brief Mode of the current (or last) trial. */
  CompensationMode mode() const { return mode_; }
  /** @brief Spindle speed of the current trial [rpm]. */
  double spindleRpm() const { return spindle_rpm_; }
  /** @brief Parameters in use. */
  const TrialSequencerParams& params() const { return params_; }
  /** @brief The current trial's planner (nullptr before the first trial). */
  const CompensationPlanner* planner() const { return planner_.get(); }

  /** @brief Take (and clear) what the calls since the last take produced. */
  SequencerOutput takeOutput();
  /** @brief Calls the on*() method of a timer that fired (SequencerTimers::popDue). */
  void onTimer(TimerRequest::Kind kind, double now);

 private:
  struct ResolvedRequest {
    CompensationMode mode = CompensationMode::kStationary;
    double feed_mm_s = 0.0;
    double rpm = 0.0;
    double max_duration_s = 0.0;
    SegmentProfile profile = SegmentProfile::kRestToRest;
  };
  std::string resolve(const TrialRequest& request, ResolvedRequest* out) const;
  void setPhase(TrialPhase p);
  void log(SequencerLog::Level level, const std::string& text);
  void fail(const std::string& why);
  void spindle(double rpm);
  Eigen::Vector3d boneDisplacementSinceMarker(double t) const;
  void registerSample(double now, double stamp, const std::string& frame,
                      const Eigen::Vector3d& pos, const Eigen::Quaterniond& orientation,
                      const FrameLookup& lookup);
  void startDrilling(double now, double t_reg);
  double feedCommandAt(double t, double segmented_feed) const;
  void sendMoveToPose(double now);
  void sendDueSegments(double now);
  void emitTrajectory(double now, double start, const std::vector<double>& times,
                      const std::vector<double>& feeds, const std::vector<Eigen::Vector3d>& lateral,
                      const std::vector<double>* feed_velocities);
  void resendFromNow(double now);
  struct LayerWatch;
  /// Samples the deepest predicted advance into the bone up to now (while drilling).
  void updateDeepest(double now);
  /// Follows the recognizer's reported state in the layer watches (while drilling, after
  /// updateDeepest).
  void watchLayers(const std::string& state_name);
  /// Stops with retreat when a watched layer outlasts its bound in mm (while drilling, after
  /// updateDeepest).
  void checkLayers(double now);
  /// checkLayers for one layer; true if it stopped the drill.
  bool checkLayer(double now, LayerWatch* watch, double bound_mm, const char* param);
  void handleStop(double now, bool retreat, const std::string& reason);
  /// Holds the feed where segment k would take the tip past the depth limit (while drilling).
  void limitDepth(int k);
  /// The depth limit's stop, once the held feed is reached (while drilling).
  void checkDepthLimit(double now);
  void startRetreat(double now, const std::string& why);

  TrialSequencerParams params_;
  ArmCompensation configured_arm_;  ///< the configured drilling pose
  ArmCompensation arm_;             ///< this trial's: the configured one, or aimed at the plan
  /// The latest tracked marker pose in the world frame, heard outside a trial, and its stamp.
  std::optional<std::pair<double, Eigen::Isometry3d>> idle_marker_;
  /** @brief Aims arm_ at the plan (target_from_plan) at @p now: "" or why not. */
  std::string aimAtPlan(double now);
  std::string world_frame_;
  RetreatPlanner retreat_planner_;
  CompensatorFactory make_compensator_;
  std::unique_ptr<CompensationPlanner> planner_;
  GuardedCompensator* compensator_ = nullptr;  ///< planner_'s compensator, behind its guard
  bool compensator_reported_ = false;          ///< its error was turned into a stop
  std::vector<ControllerSpec> controllers_;
  std::unique_ptr<ControllerWatch> watch_;
  /** @brief Queues a trajectory and tells the watch (every trajectory goes through here). */
  void send(JointTrajectoryCommand traj, double now);
  /** @brief A fault of the closed loop: a stop with retreat, announced. */
  void controllerFault(double now, const std::string& why);
  /**
   * @brief An error the compensator class threw (GuardedCompensator), first seen: a stop with
   *        retreat naming it, announced (before the drilling: the trial fails). True if so.
   */
  bool compensatorFailed(double now);
  std::unique_ptr<RetreatMotion> retreat_;
  CompensationMode mode_ = CompensationMode::kStationary;
  TrialPhase phase_ = TrialPhase::kIdle;
  SequencerOutput out_;

  VentilatorSettings settings_;
  bool have_settings_ = false;
  double breath_start_ = 0.0;
  bool have_phase_ = false;
  std::string breath_source_ = "tidal_volume";  // setBreathSource()
  double breath_timeout_periods_ = 0.0;
  std::string breath_source_problem_;
  bool recognizer_reports_stop_ = false;
  /// Geometric plausibility of one layer the recognizer reports (outer_cortical_max_mm,
  /// cancellous_max_mm): how much deeper the cut went after its first report.
  struct LayerWatch {
    const char* state = "";      // the recognizer's state name of the layer
    bool started = false;        // the layer was reported (the outer one: any state after idle)
    bool done = false;           // ... and later a state after it (or the stop came)
    double start_advance = 0.0;  // deepest predicted advance at its first report [m]
    double through_t = -1.0;     // when the deepest advance passed the bound (< 0: not yet)
  };
  double deepest_advance_ = 0.0;  // deepest predicted advance into the bone while drilling [m]
  double deepest_t_ = -1.0;       // up to when it was sampled (< 0: not yet)
  LayerWatch outer_watch_{"outer_cortical"};
  LayerWatch cancellous_watch_{"cancellous"};
  double last_recognizer_t_ = -1e300;  // last drilling_state
  double last_monitor_t_ = -1e300;     // last sign of the safety monitor
  double drilling_since_ = 0.0;        // start of the drilling phase (the watchdogs' origin)

  double spindle_rpm_ = 0.0;
  double spindle_commanded_rpm_ = 0.0;  // the latest speed sent (0: off)
  double max_duration_s_ = 0.0;
  double registration_open_ = 0.0;
  double registration_deadline_ = 0.0;
  int reg_count_ = 0;
  bool registered_ = false;
  double t_registered_ = 0.0;  // the registration's last sample stamp
  bool tare_pending_ = false;  // a tare was requested, no result yet
  std::string marker_frame_;
  Eigen::Matrix3d rotation_ = Eigen::Matrix3d::Identity();  // frame_from_world_'s rotation
  Eigen::Isometry3d frame_from_world_ = Eigen::Isometry3d::Identity();
  std::optional<DrillingPlan> plan_;
  DepthLimit depth_{DepthLimitParams{}};
  double depth_hold_t_ = -1.0;  // when the held feed reaches the depth limit (< 0: no hold)

  Eigen::Vector3d y_marker_reg_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d marker_sum_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d marker_reg_ = Eigen::Vector3d::Zero();
  Eigen::Quaterniond marker_orientation_ = Eigen::Quaterniond::Identity();
  Eigen::VectorXd arm_q_;
  double t_end_ = 0.0;
  double hold_end_ = 0.0;
  int next_k_ = 0;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_TRIAL_SEQUENCER_HPP_
