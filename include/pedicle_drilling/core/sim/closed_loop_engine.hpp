// The closed-loop trial engine: one drilling trial on the simulation, with the very objects the
// nodelets run (TrialSequencer, StateRecognizer, SafetySupervisor, DrillingSimulation), called at
// the rates of the ROS pipeline and with its transport delays as explicit parameters. No ROS,
// no wall clock, no threads: one seed gives a bit-identical trial record on any machine, at any
// load and in any process.
#ifndef PEDICLE_DRILLING_CORE_CLOSED_LOOP_ENGINE_HPP_
#define PEDICLE_DRILLING_CORE_CLOSED_LOOP_ENGINE_HPP_

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/motion_model.hpp"
#include "pedicle_drilling/core/common/param_table.hpp"
#include "pedicle_drilling/core/control/drill_guard.hpp"
#include "pedicle_drilling/core/control/safety_supervisor.hpp"
#include "pedicle_drilling/core/control/trial_sequencer.hpp"
#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"
#include "pedicle_drilling/core/drilling/state_recognizer.hpp"
#include "pedicle_drilling/core/sim/drilling_simulation.hpp"
#include "pedicle_drilling/core/sim/fault_injector.hpp"

namespace pedicle_drilling::core {

/**
 * @brief Transport delays of the ROS pipeline, made explicit [s]. A message sent at t is handled
 *        at the first 1 ms simulation step at or after t + delay (0: within the same step).
 *        Defaults: the nodelets share one manager (intra-process), and bench_force_to_stop_latency
 *        measures force sample -> planner stop at 374 us p50 / 520 us p99; rounded up to 1 ms.
 */
struct EngineDelays {
  double force_to_recognizer_s = 0.0;  ///< ft_sensor/wrench -> StateRecognizer
  double stop_to_planner_s = 1e-3;     ///< drill/stop and drilling_state -> CompensationPlanner
  double command_to_arm_s = 1e-3;      ///< arm_controller/command and spindle -> controller
  /** @brief Extra command delay, uniform in [0, command_jitter_s] per command, drawn from the
   *         trial's seed (commandJitterFraction); commands keep their order (TCP). */
  double command_jitter_s = 0.0;
  /** @brief tracker/marker_pose -> planner and monitor (the sample keeps its stamp). */
  double tracker_to_pipeline_s = 0.0;
  /** @brief Check every field (finite, in [0, 1] s). @throws std::invalid_argument naming it. */
  void validate() const;
  /** @brief The declaration of every field (the campaign's scenario key engine_delays). */
  static const ParamTable<EngineDelays>& table();
};

/**
 * @brief The sim time at which a trial of `seed` starts after a reset at `reset_time`:
 *        `pre_trial_s` later, then a breath phase drawn from the seed (uniform over one breath
 *        of `breath_s`) unless `draw_phase` is false. The engine's rule, and the Simulator
 *        nodelet's hold (ResetSimulation's pre_trial_s), so that both start a seed's trial at the
 *        same step.
 */
double trialStartTime(std::uint64_t seed, double reset_time, double pre_trial_s, double breath_s,
                      bool draw_phase);

/**
 * @brief The `index`-th command's jitter of the trial of `seed`, as a fraction in [0, 1) of
 *        EngineDelays::command_jitter_s: its own stream of the seed, drawn in the order the
 *        commands are sent, by the engine and by the Simulator nodelet (~command_jitter_s).
 */
double commandJitterFraction(std::uint64_t seed, std::uint64_t index);

/**
 * @brief The command path's transport, one rule for the engine and the Simulator nodelet: each
 *        command takes effect `delay_s` after it was sent, plus its jitter (uniform in
 *        [0, jitter_s], commandJitterFraction of the trial's seed, in sending order), and never
 *        before the command sent before it (the order kept, as TCP keeps it).
 */
class CommandTransport {
 public:
  CommandTransport() = default;
  /** @brief For a trial of `seed`: the draws start again. */
  CommandTransport(double delay_s, double jitter_s, std::uint64_t seed)
      : delay_s_(delay_s), jitter_s_(jitter_s), seed_(seed) {}
  /** @brief The delay of a command sent at `now` (the next draw when there is jitter). */
  double delay(double now);
  /**
   * @brief The delay of a message of the command path that draws no jitter, sent at `now`: a
   *        spindle keepalive or a tare request. The same path and order, so that they leave
   *        every other command's jitter as it was.
   */
  double undrawnDelay(double now);
  /**
   * @brief The delay of a spindle speed command of @p rpm sent at `now`: a keepalive (running,
   *        > 0, and equal to the latest speed sent: the planner repeats only a running speed,
   *        spindle_keepalive_s) takes undrawnDelay(); every change, a stop included, delay().
   */
  double spindleDelay(double now, double rpm);

 private:
  double delay_s_ = 1e-3;
  double jitter_s_ = 0.0;
  std::uint64_t seed_ = 0;
  std::uint64_t count_ = 0;
  double last_due_ = 0.0;
  double last_spindle_rpm_ = 0.0;  ///< the latest spindle speed sent (spindleDelay)
};

/** @brief Configuration of the engine (the pipeline's parameters; doc/nodes.md, config/). */
struct EngineConfig {
  std::string urdf_xml;                 ///< the workcell (urdf/workcell.urdf)
  DrillingSimulationParams simulation;  ///< config/simulator.yaml
  double tracker_rate_hz = 8.0;         ///< optical tracker (Sec. III-A)
  /// The controllers' `state` to the planner (ros_control's state_publish_rate default, 50 Hz).
  double controller_state_rate_hz = 50.0;
  double tidal_volume_rate_hz = 64.0;  ///< the simulated ventilator's tidal_volume stream
  double ground_truth_rate_hz = 20.0;  ///< recorded ground truth (plus every layer change)
  /// The joint states the recognizer's context (feed joint, spindle) comes from, as the
  /// StateRecognizer nodelet hears them (config/simulator.yaml's joint_state_rate_hz; 0: off,
  /// the context unknown).
  double joint_state_rate_hz = 100.0;
  /**
   * @brief config/recognizer.yaml (thrust = +z of the sensor). Its `sensor_rate_hz` must be the
   *        simulated sensor's `simulation.sensor.output_rate_hz` within 10 % (checkSensorRate;
   *        trial_engine declares that rate); its block also sizes the truth peaks' blocks.
   */
  RecognizerParams recognizer;
  /**
   * @brief The recognizer of each trial: empty = the paper's (PaperRecognizer with
   *        `recognizer`); trial_engine --recognizer sets a built-in or a pluginlib class.
   */
  std::function<std::unique_ptr<RecognizerInterface>()> make_recognizer;
  /**
   * @brief The compensator of each trial: empty = the paper's (PaperCompensator);
   *        trial_engine --compensator sets a built-in or a pluginlib class.
   */
  CompensatorFactory make_compensator;
  SupervisorParams safety;              ///< config/safety_monitor.yaml
  DrillGuardParams guard;               ///< config/safety_monitor.yaml guard_* (the drill guard)
  double safety_check_rate_hz = 200.0;  ///< the monitor's watchdog timer
  TrialSequencerParams sequencer;       ///< config/compensation_planner.yaml; joints from URDF
  std::vector<double> drilling_pose;    ///< config/drilling_pose.yaml, arm joint order
  double feed_home_m = 0.01;
  std::string arm_base_link = "world";
  std::string arm_tip_link = "device_base";
  EngineDelays delays;
  /**
   * @brief Where the trials' wall time goes (trial_engine --profile): each trial adds
   *        its time by component and its simulated time. nullptr (default): nothing is timed.
   *        Not owned; must outlive the engine's runs.
   */
  ComponentProfile* profile = nullptr;
  /** @brief Sim time between the reset and the earliest trial start: the ventilator's
   *         settings and breath phase reach the planner. The start then waits a fraction of one
   *         breath drawn from the seed, so that trials start at every phase of the breathing. */
  double pre_trial_s = 1.0;
  /** @brief false: start exactly pre_trial_s after the reset (no drawn breath phase). */
  bool draw_start_phase = true;
  /** @brief A trial not done this long after its start is an error (never silently cut). */
  double trial_timeout_s = 600.0;
  /** @brief Sizes of the faults a trial may inject (EngineTrialSpec::fault). */
  FaultParams faults;
};

/**
 * @brief The recognizer's declared rate against the simulated sensor's: the engine's form of
 *        the StateRecognizer nodelet's check of the measured rate (the same 10 % tolerance).
 * @throws std::invalid_argument, its message starting with "sensor_rate_hz" and naming both
 *         rates, when config.recognizer.sensor_rate_hz is more than 10 % from
 *         config.simulation.sensor.output_rate_hz.
 */
void checkSensorRate(const EngineConfig& config);

/** @brief How a trial ends (EngineTrialSpec::protocol). */
enum class TrialProtocol {
  kRecognition,  ///< the recognizer stops the drill (paper Sec. V-E)
  kPeakForces,   ///< the recognizer observes; the drill goes through the inner layer (Sec. V-D)
};

/** @brief "recognition" or "peak_forces". */
const char* toString(TrialProtocol protocol);
/** @brief Parses "recognition" or "peak_forces". @throws std::invalid_argument naming both. */
TrialProtocol parseTrialProtocol(const std::string& name);

/** @brief What one trial is run with. */
struct EngineTrialSpec {
  std::uint64_t seed = 1;
  std::string mode = "stationary";  ///< stationary | uncompensated | compensated
  double spindle_rpm = 12000.0;
  double feed_rate_mm_s = 0.5;
  double max_duration_s = 60.0;
  MotionModel model;  ///< the patient model the planner predicts with
  /** @brief The paper's bench: the SPMS plays this model's AP displacement (else the patient). */
  std::optional<BoneMotionModel> bone_motion;
  /**
   * @brief The fault to inject. It is triggered when, once the drilling has started, the
   *        deepest cut first reaches u times the depth of the inner cortical layer's start, u
   *        uniform in [0, 1) from the seed's own stream: a random moment between the start of
   *        the drilling and the inner layer, where a missed stop would break through (a bone
   *        that touched the drill at the drilling pose triggers it when the drilling starts). The
   * breathing faults take effect at the next breath's start (no step of the bone), the command
   * faults with the next command.
   */
  FaultKind fault = FaultKind::kNone;
  /**
   * @brief The trial protocol. kRecognition (the default): the recognizer's stop ends the
   *        drilling (paper Sec. V-E). kPeakForces: the paper's Sec. V-D force trials, whose
   *        F_out and F_in (Fig. 16) need the drill through the inner layer: the recognizer
   *        observes (its states and key points are recorded) but its stop is not delivered, and
   *        the trial is stopped with retreat once the tip has broken through the inner layer.
   *        The planner's plausibility bounds on the recognizer's layers (outer_cortical_max_mm,
   *        cancellous_max_mm) are off under it.
   */
  TrialProtocol protocol = TrialProtocol::kRecognition;
  /** @brief Record every force-sensor sample from the trial's start (EngineTrialRecord::samples,
   *         the labelled dataset, doc/dataset.md). */
  bool record_samples = false;
};

/** @brief When and how a fault was injected. */
struct EngineFaultRecord {
  FaultKind kind = FaultKind::kNone;
  double trigger_depth_m = 0.0;  ///< depth of the deepest cut that triggers it
  bool injected = false;         ///< false: the trial ended before the trigger
  double t = 0.0;                ///< sim time it took effect [s] (if injected)
  FaultCounts counts;            ///< what it did to the streams (FaultInjector::counts)
};

/** @brief A recognizer state as the ROS pipeline publishes it (DrillingState). */
struct EngineStateSample {
  double t = 0.0;
  double averaged_force = 0.0;
  double feature = 0.0;
  std::string state_name;
  int last_key_point = 0;
};

/** @brief A ground-truth sample (GroundTruth). */
struct EngineTruthSample {
  double t = 0.0;
  std::string layer;
  double max_depth_cut_m = 0.0;
  double residual_inner_cortical_m = 0.0;
  bool breakthrough = false;
  double relative_ap_m = 0.0;
  bool contact = false;
  std::uint32_t contact_loss_count = 0;  ///< separations since the trial started
};

/**
 * @brief One force-sensor sample with what was true and what the pipeline knew at that moment
 *        (EngineTrialSpec::record_samples): a row of the labelled dataset (doc/dataset.md).
 */
struct EngineSample {
  double t = 0.0;  ///< sim time [s]
  /// The whole sample the recognizer was given: the thrust (tared, faults applied), the
  /// wrench and the drill's context, the last delivered tracker sample among it
  RecognizerSample given;
  double true_force_n = 0.0;      ///< the simulator's true thrust, no sensor [N]
  double averaged_force_n = 0.0;  ///< the recognizer's latest averaged force (held) [N]
  double tip_depth_m = 0.0;       ///< tip depth below the bone's top surface [m]
  double max_depth_cut_m = 0.0;   ///< deepest point cut [m]
  int layer = 0;                  ///< Material under the tip's deepest cut (the label)
  bool contact = false;           ///< lips cutting
  double bone_ap_m = 0.0;         ///< true vertebra AP displacement from its home [m]
  double predicted_ap_m = 0.0;    ///< planner's predicted AP displacement since start (NaN: none)
  double breath_phase = 0.0;      ///< fraction of the current breath elapsed, [0, 1)
  double tidal_volume_ml = 0.0;   ///< patient tidal volume [ml]
};

/** @brief A stop command (StopCommand). */
struct EngineStop {
  double t = 0.0;
  std::string source;  ///< /state_recognizer | /safety_monitor (the nodelets' names)
  std::string reason;
  bool retreat = false;
};

/** @brief Everything the campaign records of a trial (what its ROS worker subscribes to). */
struct EngineTrialRecord {
  TrialConditions conditions;
  double outer_cortical_thickness_m = 0.0;
  double cancellous_thickness_m = 0.0;
  double inner_cortical_thickness_m = 0.0;
  std::vector<EngineStateSample> states;
  std::vector<EngineSample> samples;  ///< every sensor sample (if EngineTrialSpec::record_samples)
  std::vector<std::pair<int, double>> key_points;  ///< (id, t) as last_key_point rises
  std::vector<EngineTruthSample> truth;
  SimulationGroundTruth last_truth;
  std::vector<EngineStop> stops;
  std::vector<std::pair<double, std::string>> status;  ///< (t, phase)
  EngineFaultRecord fault;
  /**
   * @brief Ground-truth peak thrust [N] before / after the tip's deepest cut enters the inner
   *        cortical layer, up to the first stop command: the simulator's true thrust (no sensor,
   *        no noise) averaged in blocks of EngineConfig::recognizer's pre-average (its
   *        blockSamples() sensor samples, in 1 ms physics steps: 150 for 0.15 s), the quantity
   *        the recognizer's averaged force estimates. 0 when the layer was not
   *        reached. The sensor chain's effect is the difference to the recognizer's peaks.
   */
  double truth_peak_outer_n = 0.0;
  double truth_peak_inner_n = 0.0;  ///< see truth_peak_outer_n
  /** @brief The recognizer's own stop time [s] (also under kPeakForces, where it is not
   *         delivered); NaN when it never stopped. */
  double recognizer_stop_t = std::numeric_limits<double>::quiet_NaN();
  /** @brief The monitor's re-tare check when the retreat ended (done false: no retreat ended). */
  RetareCheck retare;
  /** @brief The F/T tare's result (samples 0: no tare was requested, tare_samples 0). */
  TareResult tare;
  /** @brief The planner's controller watch over the trial: the largest |desired - commanded|
   *         and |error| of any joint, each as a fraction of its tolerance (1: the threshold). */
  double watch_desired_ratio = 0.0;
  double watch_following_ratio = 0.0;  ///< see watch_desired_ratio
  /**
   * @brief The depth limit's estimate against the truth (for the margin's choice): the largest
   *        true depth of the hole's bottom below the bone's surface minus the limit's estimate
   *        of the tip's depth (the tracked and predicted advance less the surface it took), at
   *        the force samples in contact while drilling after the sensed contact [m]; positive:
   *        deeper than the planner believed. NaN: no contact.
   */
  double depth_estimate_error_max_m = std::numeric_limits<double>::quiet_NaN();
  /**
   * @brief The same error's maximum in each kDepthWindowS of that drilling [m], in time order:
   *        what the margin must cover when the limit acts at a random moment (the tip holds at
   *        the limit from the hold until the stop's retreat, at most about one window).
   */
  std::vector<double> depth_estimate_window_errors_m;
  /** @brief The plan's far-side error before its margin (ImagingPlan::far_side_error_m) [m]. */
  double plan_far_side_error_m = 0.0;
};

/**
 * @brief Runs closed-loop trials. One engine per thread or process; trials are independent
 *        (everything is reset from the seed), so the order and the grouping of trials into
 *        processes do not change any record.
 */
class ClosedLoopEngine {
 public:
  /** @brief Builds the simulation and checks the configuration. @throws std::invalid_argument. */
  explicit ClosedLoopEngine(const EngineConfig& config);
  ~ClosedLoopEngine();
  ClosedLoopEngine(const ClosedLoopEngine&) = delete;
  ClosedLoopEngine& operator=(const ClosedLoopEngine&) = delete;

  /**
   * @brief Runs one trial to its end (done) and returns its record.
   * @throws std::runtime_error when the trial fails (the planner's reason) or times out.
   */
  EngineTrialRecord run(const EngineTrialSpec& spec);

  /** @brief Configuration in use. */
  const EngineConfig& config() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_CLOSED_LOOP_ENGINE_HPP_
