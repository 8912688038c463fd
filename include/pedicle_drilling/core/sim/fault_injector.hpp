// Fault injection: the faults a drilling trial can suffer, their sizes, and the
// FaultInjector that applies the sensor, tracker and command faults to the streams. The core
// engine (ClosedLoopEngine) and the FaultInjector nodelet run the same class, so a fault means
// the same thing in the fault campaign and on a ROS pipeline (simulated or real hardware).
#ifndef PEDICLE_DRILLING_CORE_FAULT_INJECTOR_HPP_
#define PEDICLE_DRILLING_CORE_FAULT_INJECTOR_HPP_

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <string>
#include <vector>

#include "pedicle_drilling/core/common/param_table.hpp"
#include "pedicle_drilling/core/sim/normal_source.hpp"

namespace pedicle_drilling::core {

/**
 * @brief A fault injected into a trial (doc/experiments.md, "Fault campaign"; the core engine
 *        and the FaultInjector nodelet). Each acts where the real fault would: on the force
 *        stream both the recognizer and the monitor receive, on the tracker stream, on the
 *        patient, or on the planner's trajectory commands.
 */
enum class FaultKind {
  kNone,                ///< no fault
  kForceSilent,         ///< the F/T sensor stops publishing
  kForceNaN,            ///< every force sample NaN from then on
  kForceInf,            ///< the thrust +inf from then on
  kForceSpike,          ///< one sample with the thrust at FaultParams::spike_n
  kForceStuck,          ///< the sensor repeats its last sample (frozen driver)
  kForceDrift,          ///< the thrust gains a bias growing at FaultParams::drift_n_per_s
  kTrackerSilent,       ///< the optical tracker stops publishing
  kTrackerJump,         ///< the tracked marker jumps by FaultParams::tracker_jump_m and stays
  kTrackerStale,        ///< the tracker repeats its last pose with its old stamp (stale tf)
  kBreathingAmplitude,  ///< the patient's AP displacement x amplitude_factor (model not re-fit)
  kBreathingRateUp,     ///< the ventilator rate + rate_change_bpm (settings reach the planner)
  kBreathingRateDown,   ///< the ventilator rate - rate_change_bpm
  kCommandLost,         ///< the next trajectory command to the arm is lost
  kCommandDelayed,      ///< the next trajectory command reaches the arm command_delay_s late
  kForceSaturated,      ///< the thrust clipped at +-FaultParams::saturation_n, with its noise
  kForceAxisNaN,        ///< one axis (FaultParams::nan_axis) of every force sample NaN
  kForceNegInf,         ///< the thrust -inf from then on
  kTrackerOcclusion,    ///< repeated short silences of the tracker, each recovering
  kStopLost,            ///< every drill/stop command lost (the planner's own stops are not)
  kPlannerKilled,       ///< the planner's process (planner, recognizer) killed (core engine)
  kMonitorKilled,       ///< the monitor's process (monitor, drill guard) killed (core engine)
  kControllerAborted,   ///< the feed joint's controller aborts its trajectory (the simulator's)
};

/** @brief The fault's name in scenario files and trials.csv ("none", "force_silent", ...). */
const char* toString(FaultKind kind);

/** @brief Every fault's name, kNone first, in declaration order. */
std::vector<std::string> faultNames();

/** @brief The fault of a name. @throws std::invalid_argument listing the known names. */
FaultKind parseFaultKind(const std::string& name);

/** @brief Sizes of the injected faults (scenario key `fault_params`). */
struct FaultParams {
  /** @brief Thrust of the spike [N]: 1.5 x H2, one 1 ms sample (an electrical glitch). */
  double spike_n = 15.0;
  /** @brief Bias drift [N/s]: 2 N over a 10 s drilling, the size of the cancellous thrust; a
   *         fault far beyond a sensor's thermal drift, chosen to disturb the recognition. */
  double drift_n_per_s = 0.2;
  /** @brief Tracker jump [m] along the camera's x axis: 5 mm ("several mm", a marker knocked
   *         or a re-registration), well above H1 = 1.2 mm. */
  double tracker_jump_m = 5e-3;
  /** @brief Factor on the patient's AP displacement (+30 %). */
  double amplitude_factor = 1.3;
  /** @brief Change of the ventilator rate [breaths/min] (+-4 /min). */
  double rate_change_bpm = 4.0;
  /** @brief Delay of the delayed trajectory command [s] (200 ms). */
  double command_delay_s = 0.2;
  /** @brief How many consecutive trajectory commands a command fault hits (1: the next one
   *         only; more: a command path that stays slow, or a link that stays down). */
  int command_fault_count = 1;
  /** @brief The thrust's range [N] (force_saturated): the sensor clips the thrust to
   *         [-saturation_n, +saturation_n]. 2.5 N: a sensor set up for a smaller range than the
   *         drilling needs (a wrong calibration matrix or DAQ gain; the Nano17 SI-12-0.12's own
   *         Fz range is 17 N, never reached below H2 = 10 N). Assumption: chosen below the
   *         outer cortical peaks (median 3.1 N) and above the cancellous thrust, where the clip
   *         hides the layers' contrast from the recognizer. */
  double saturation_n = 2.5;
  /** @brief White noise SD [N] of a clipped sample (force_saturated): the sensor's own noise,
   *         config/simulator.yaml force_noise_sd_n (0.03 N), so that the clipped thrust is not
   *         bit-identical (the frozen-sensor check does not see it). */
  double saturation_noise_sd_n = 0.03;
  /** @brief The force axis that turns NaN (force_axis_nan): 0 x, 1 y, 2 z. 0: a lateral axis,
   *         which the recognizer (thrust: z) does not read; only the monitor sees it. */
  int nan_axis = 0;
  /** @brief Tracker samples lost per occlusion burst (tracker_occlusion): 2 at 8 Hz, a gap of
   *         3 periods (0.375 s) between delivered samples, below the monitor's 0.5 s
   *         tracker_timeout_s (4 periods). Assumption: a hand or an instrument crossing the
   *         camera's line of sight. 3 samples make a 0.5 s gap, the timeout itself. */
  int occlusion_samples = 2;
  /** @brief Tracker samples from one burst's start to the next (tracker_occlusion): 8, one
   *         burst a second at 8 Hz, repeated until the trial ends. Assumption. */
  int occlusion_period_samples = 8;
  /** @brief Check every field. @throws std::invalid_argument naming it. */
  void validate() const;

  /** @brief The declaration of the fields the FaultInjector node sets. */
  static const ParamTable<FaultParams>& table();
};

/** @brief True for the faults on the force stream (force_*). */
bool isForceFault(FaultKind kind);
/** @brief True for the faults on the tracker stream (tracker_*). */
bool isTrackerFault(FaultKind kind);
/** @brief True for the patient's breathing faults (breathing_*). */
bool isBreathingFault(FaultKind kind);
/** @brief True for the faults on the arm's trajectory commands (command_*). */
bool isCommandFault(FaultKind kind);
/** @brief True for the faults on the drill/stop commands (stop_*). */
bool isStopFault(FaultKind kind);
/** @brief True for the process kills (planner_killed, monitor_killed): the core engine's own;
 *         on the ROS pipeline a process is killed by a signal (rostests fault_*_killed). */
bool isProcessFault(FaultKind kind);

/** @brief What an injected fault did to the streams, since arm(): the proof that it acted. */
struct FaultCounts {
  long force_dropped = 0;     ///< force samples not delivered
  long force_altered = 0;     ///< force samples delivered changed
  long tracker_dropped = 0;   ///< tracker samples not delivered
  long tracker_altered = 0;   ///< tracker samples delivered changed
  long commands_lost = 0;     ///< trajectory commands lost
  long commands_delayed = 0;  ///< trajectory commands delayed
  long stops_lost = 0;        ///< drill/stop commands lost
};

/**
 * @brief Applies one fault to the force, tracker and command streams of a trial.
 *
 * Usage: choose the fault (constructor or arm()), pass every sample through force() /
 * trackedPose() and every command through command(); call inject() at the moment the fault
 * begins (the engine at its seeded depth, the nodelet on its service). A command fault waits
 * for the next command after inject(); the others act from inject() on. The breathing faults
 * are the patient's, not a stream's: the injector only records them (the simulation applies
 * them). Not thread-safe.
 */
class FaultInjector {
 public:
  /**
   * @param noise_seed seed of the noise the faults add (force_saturated): the engine gives each
   *        trial its own, from the trial's seed.
   * @throws std::invalid_argument if params are invalid (FaultParams::validate).
   */
  explicit FaultInjector(FaultParams params = FaultParams(), std::uint64_t noise_seed = 0);

  /** @brief Chooses the fault of the coming injection and forgets any earlier one. */
  void arm(FaultKind kind);
  /** @brief The armed fault. */
  FaultKind kind() const { return kind_; }
  /** @brief The sizes. */
  const FaultParams& params() const { return params_; }

  /**
   * @brief The fault begins at time t [s]. A frozen force sensor repeats the first sample
   *        force() gets from then on. A command fault is pending until the next command().
   */
  void inject(double t);
  /** @brief True once inject() was called (a command fault: once its command came). */
  bool injected() const { return injected_; }
  /** @brief True from inject() until a command fault's last command came
   *         (FaultParams::command_fault_count). */
  bool pending() const { return pending_; }
  /** @brief Time of the injection [s] (a command fault: of its command; valid if injected()). */
  double injectionTime() const { return t_injected_; }

  /**
   * @brief The force sample at time t as the faulty sensor delivers it (thrust: z).
   * @return false if nothing is delivered (silent sensor).
   */
  bool force(double t, Eigen::Vector3d* force);

  /**
   * @brief The tracked pose as the faulty tracker delivers it: position, orientation and stamp.
   * @return false if nothing is delivered (silent tracker).
   */
  bool trackedPose(Eigen::Vector3d* position, Eigen::Quaterniond* orientation, double* stamp);

  /**
   * @brief The fate of one trajectory command sent at time t [s]: 0 delivered as usual, > 0 its
   *        extra delay [s], < 0 lost. The first FaultParams::command_fault_count commands after
   *        inject() of a command fault are affected (1 by default: the next one only).
   */
  double command(double t);

  /** @brief The fate of one drill/stop command: false if it is lost (stop_lost, injected). */
  bool stop();

  /** @brief What the fault did since arm(). */
  const FaultCounts& counts() const { return counts_; }

 private:
  bool saturate(Eigen::Vector3d* force);
  bool occluded();

  FaultParams params_;
  FaultKind kind_ = FaultKind::kNone;
  bool pending_ = false;
  bool injected_ = false;
  bool spent_ = false;  // the spike's sample, the stuck sample taken, the one command done
  double t_injected_ = 0.0;
  int remaining_commands_ = 0;  // a command fault's commands still to hit
  Eigen::Vector3d last_force_ = Eigen::Vector3d::Zero();
  bool have_pose_ = false;
  double last_stamp_ = 0.0;
  Eigen::Vector3d last_position_ = Eigen::Vector3d::Zero();
  Eigen::Quaterniond last_orientation_ = Eigen::Quaterniond::Identity();
  FaultCounts counts_;
  NormalSource noise_;
  long tracker_samples_ = 0;  // tracker samples since the injection
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_FAULT_INJECTOR_HPP_
