// What the CompensationPlanner nodelet runs around core::TrialSequencer, with no ROS: the trial's
// bookkeeping (its start stamp, the stops heard since), the heartbeat the drill guard watches
// (when it is due on explicit time), the sequencer's timers on explicit time and the step they
// need next, the safety monitor's status (alive; an ERROR during the trial is a stop), the breath
// source and phase, and the thrust along the sensor's axis. ClosedLoopEngine keeps the same
// object for its planner, so that the timers fire and the heartbeat beats by one rule in both.
#ifndef PEDICLE_DRILLING_CORE_CONTROL_PLANNER_RUNTIME_HPP_
#define PEDICLE_DRILLING_CORE_CONTROL_PLANNER_RUNTIME_HPP_

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "pedicle_drilling/core/breathing/motion_model.hpp"
#include "pedicle_drilling/core/control/trial_sequencer.hpp"
#include "pedicle_drilling/core/drilling/recognizer_adapter.hpp"

namespace pedicle_drilling::core {

/** @brief What a trial start answered (PlannerRuntime::start). */
struct TrialStartAnswer {
  bool success = false;  ///< the trial runs
  /// "trial started: <mode>, spindle <rpm> rpm" when it runs, else why not (nothing started).
  std::string message;
};

/**
 * @brief The planner's state between its callbacks, around its TrialSequencer: one driver calls
 *        it (the nodelet under its mutex, the engine on its one thread). Times are seconds on the
 *        planner's clock; stamps are the messages' (the same clock under sim time).
 */
class PlannerRuntime {
 public:
  /**
   * @brief Takes the trial's sequencer.
   * @param heartbeat_period_s the heartbeat's period while a trial runs [s], > 0.
   * @param thrust the force sensor's axis along which the thrust shows the contact.
   * @throws std::invalid_argument for no sequencer, a period <= 0 or an invalid axis.
   */
  PlannerRuntime(std::unique_ptr<TrialSequencer> sequencer, double heartbeat_period_s,
                 ForceAxis thrust = ForceAxis());

  /** @brief The trial sequence (Algorithm 1). */
  TrialSequencer& sequencer() { return *sequencer_; }
  /** @brief The trial sequence, read only. */
  const TrialSequencer& sequencer() const { return *sequencer_; }

  /**
   * @brief Starts a trial at @p now whose start is stamped @p stamp (stops and monitor errors
   *        stamped before it belong to an earlier trial): the stops heard count from zero, then
   *        the sequencer starts. The answer's message names the mode and the spindle speed as a
   *        person reads them (12000, not 12000.000000), or the sequencer's refusal.
   */
  TrialStartAnswer start(const TrialRequest& request, const MotionModel& model, double now,
                         double stamp);
  /** @brief The latest trial's start stamp (start()); 0 before the first. */
  double trialStartStamp() const { return trial_start_stamp_; }
  /** @brief The stop commands heard (onStop) stamped at or after the latest trial's start. */
  std::uint32_t stopsHeard() const { return stops_heard_; }

  /** @brief A stop command stamped @p stamp, heard at @p now: counted when it belongs to the
   *         latest trial (stopsHeard), then handed to the sequencer whatever its stamp. */
  void onStop(double now, double stamp, bool retreat, const std::string& reason);
  /**
   * @brief The safety monitor's status, heard at @p now: it is alive; an ERROR (@p error)
   *        stamped during the latest trial is a stop and retreat as its drill/stop is, so that a
   *        lost stop command is still heard (after the stop itself, a no-op).
   */
  void onMonitorStatus(double now, double stamp, bool error, const std::string& message);
  /** @brief The stop reason of the monitor's ERROR status whose message is @p message. */
  static std::string monitorErrorReason(const std::string& message);

  /**
   * @brief The breath phase from a tidal volume sample stamped @p stamp, @p time_in_breath_s
   *        into its breath: the breath started at their difference. False (nothing changes)
   *        when that start is not finite.
   */
  bool onTidalVolume(double stamp, double time_in_breath_s);
  /**
   * @brief The breath phase comes from the tidal volume on @p tidal_topic (resolved), and a
   *        moving trial needs a breath start at most @p timeout_periods breath periods old
   *        (TrialSequencer::setBreathSource; 0: no bound).
   */
  void setTidalVolumeSource(const std::string& tidal_topic, double timeout_periods);
  /**
   * @brief The ventilator's report on its breath source: @p source on @p topic ("" for none:
   *        the tidal volume topic alone) is named in a refusal or a stop, and its @p problem
   *        quoted while it is not @p ready.
   */
  void onBreathSourceStatus(const std::string& source, const std::string& topic, bool ready,
                            const std::string& problem);
  /**
   * @brief Where the breath phase comes from, named in a refusal or a stop: @p tidal_topic (the
   *        resolved tidal volume topic) alone when the ventilator names no @p topic, else "<source>
   *        on <topic> (via <tidal_topic>)".
   */
  static std::string breathSourceName(const std::string& tidal_topic, const std::string& source,
                                      const std::string& topic);
  /** @brief A force sample of the F/T sensor stamped @p stamp: its thrust along the axis shows
   *         the contact the depth limit counts from. */
  void onForce(double now, double stamp, const Eigen::Vector3d& force);
  /** @brief The axis the thrust is read along. */
  const ForceAxis& thrustAxis() const { return thrust_; }

  /**
   * @brief A phase the planner published at @p now: while it is a running trial's, the
   *        heartbeat is due from now (a trial's first beat is at its first phase), then every
   *        period.
   */
  void onPhase(TrialPhase phase, double now);
  /** @brief The latest phase published is a running trial's. */
  bool running() const { return running_; }
  /**
   * @brief Whether the heartbeat is due at @p t on explicit time (1e-9 s of rounding allowed):
   *        true while a trial runs and its time has come, and then the next is one period later.
   */
  bool beatDue(double t);
  /** @brief When the next heartbeat is due (while running()). */
  double nextBeat() const { return next_beat_; }

  /** @brief Applies an output's timer requests made at @p now (on explicit time). */
  void applyTimers(const SequencerOutput& out, double now) { timers_.apply(out, now); }
  /**
   * @brief Fires every sequencer timer due at @p now, earliest first, calling @p carry_out after
   *        each (what a timer produced is carried out before the next fires, as its own
   *        callback would be).
   */
  void fireDueTimers(double now, const std::function<void()>& carry_out);
  /** @brief The earliest time something of the planner is due on explicit time: a timer, or
   *         the heartbeat while a trial runs; nullopt when nothing is. */
  std::optional<double> nextDue() const;

  /**
   * @brief Rank of a stop command among the messages of one step, by its @p source: the
   *        planner's own (@p own_name, heard back) 2, the safety monitor's 1, others 0 (the
   *        engine's order of emission, kept under the simulator's lockstep).
   */
  static int stopRank(const std::string& source, const std::string& own_name);

 private:
  std::unique_ptr<TrialSequencer> sequencer_;
  SequencerTimers timers_;
  double heartbeat_period_s_;
  ForceAxis thrust_;
  std::string tidal_topic_ = "tidal_volume";  // setTidalVolumeSource
  double breath_timeout_periods_ = 0.0;
  double trial_start_stamp_ = 0.0;
  std::uint32_t stops_heard_ = 0;
  bool running_ = false;    // the latest phase published is a running trial's
  double next_beat_ = 0.0;  // the next heartbeat's time
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_CONTROL_PLANNER_RUNTIME_HPP_
