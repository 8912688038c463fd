/**
 * @file breath_detector.hpp
 * @brief The breath phase from an airway flow signal: breath starts detected on a stream of
 *        (stamp, flow) samples (BreathStartDetector), and a ventilator model re-phased by them
 *        (FlowPhasedSchedule). The simulator's modelled breath sensor
 *        (DrillingSimulation::sensedTimeInBreath) and the Ventilator nodelet's `flow` source run
 *        the same detector.
 *
 * Detection: a breath starts at the first sample whose flow exceeds the trigger, once the
 * detector is armed; it is armed by a sample at or below the re-arm flow (the pause or the
 * expiration of the previous breath; hysteresis against noise around the trigger) and, with a
 * minimum interval, no earlier than that interval after the last start. The start is the
 * sample's own stamp, not interpolated between samples: with a square inspiratory flow, which
 * jumps at the breath's start, the detection is late by up to one sample period (uniform).
 */
#pragma once

#include <cstdint>
#include <limits>
#include <string>

#include "pedicle_drilling/core/breathing/ventilator.hpp"
#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling::core {

/** @brief How breath starts are found on a flow signal (ml/s, positive into the patient). */
struct BreathDetectorParams {
  /// A breath starts at the first armed sample whose flow exceeds this (2 L/min: a ventilator's
  /// flow trigger, doc/simulator_physics.md §5 "Breath phase").
  double trigger_flow_ml_s = 100.0 / 3.0;
  /// A sample at or below this arms the detector for the next start (must not exceed the
  /// trigger; 0: the previous breath's pause or expiration).
  double rearm_flow_ml_s = 0.0;
  /// No start is detected sooner than this after the last one (0: no such bound; 0.5 s: half
  /// the shortest breath the settings allow, 1 s at 60 /min).
  double min_interval_s = 0.5;
  /// Whether the first crossing counts before any sample at or below the re-arm flow: true when
  /// the stream is known to start with a breath (the simulator's sensor starts with its
  /// ventilator); false for a stream joined at an unknown phase, whose first rise may be the
  /// middle of an inspiration. Not a parameter.
  bool armed_at_start = false;

  /** @brief Throws std::invalid_argument naming the first bad field. */
  void validate() const;
  /** @brief The declaration of the parameters (breath_trigger_flow_ml_s, ...). */
  static const ParamTable<BreathDetectorParams>& table();
};

/** @brief What one flow sample did. */
enum class FlowSampleStatus {
  kAccepted,           ///< taken, no breath start
  kBreathStart,        ///< taken, a breath starts at its stamp
  kNonFiniteFlow,      ///< dropped: the flow is NaN or infinite
  kNonFiniteStamp,     ///< dropped: the stamp is NaN or infinite
  kStampNotIncreasing  ///< dropped: the stamp is not after the last accepted sample's
};

/** @brief Whether the sample was taken (accepted or a breath start). */
inline bool accepted(FlowSampleStatus s) {
  return s == FlowSampleStatus::kAccepted || s == FlowSampleStatus::kBreathStart;
}

/** @brief Why a sample was dropped, in words ("" when it was taken). */
std::string describe(FlowSampleStatus s);

/** @brief Breath starts on a stream of flow samples; see the file comment. */
class BreathStartDetector {
 public:
  /** @brief @throws std::invalid_argument on bad parameters. */
  explicit BreathStartDetector(const BreathDetectorParams& params);

  /**
   * @brief One sample: stamp @p t (s) and airway flow (ml/s, positive into the patient). A
   *        sample with a non-finite value or a stamp not after the last taken one is dropped
   *        (counted; the detector's state is unchanged) and the reason returned.
   */
  FlowSampleStatus add(double t, double flow_ml_s);

  /** @brief Forgets every sample and start (a stream that starts again). */
  void reset();

  bool armed() const { return armed_; }
  /** @brief Breath starts detected since construction or reset(). */
  long breaths() const { return breaths_; }
  /** @brief The latest breath start (NaN before the first). */
  double lastBreathStart() const { return last_start_; }
  /** @brief The stamp of the last sample taken (NaN before the first). */
  double lastSampleTime() const { return last_t_; }
  /** @brief Samples dropped since construction or reset(). */
  std::uint64_t dropped() const { return dropped_; }
  const BreathDetectorParams& params() const { return params_; }

 private:
  BreathDetectorParams params_;
  bool armed_ = false;
  long breaths_ = 0;
  double last_start_ = std::numeric_limits<double>::quiet_NaN();
  double last_t_ = std::numeric_limits<double>::quiet_NaN();
  std::uint64_t dropped_ = 0;
};

/** @brief The Ventilator's `flow` source: the detector and how long a phase stays usable. */
struct FlowPhaseParams {
  BreathDetectorParams detector;
  /// The phase is usable while the latest breath start is at most this many breath periods (of
  /// the current settings) old; before the first start, and after that, it is not.
  double timeout_periods = 2.0;

  /** @brief Throws std::invalid_argument naming the first bad field. */
  void validate() const;
  /** @brief The declaration (the detector's parameters and breath_timeout_periods). */
  static const ParamTable<FlowPhaseParams>& table();
};

/**
 * @brief A ventilator model whose breath schedule follows the breath starts detected on the
 *        patient's flow: its settings as a BreathScheduler's (a change takes effect at the next
 *        breath), each detected start re-phases it. Between two starts the schedule runs on
 *        its own; when it has already begun a breath that the detection then finds, that breath
 *        is moved to the detected start (its index kept), else a new breath starts there.
 */
class FlowPhasedSchedule {
 public:
  /** @brief @throws std::invalid_argument on bad settings or parameters. */
  FlowPhasedSchedule(const VentilatorSettings& settings, const FlowPhaseParams& params);

  /** @brief New settings, from the next breath on (validated now; throws on bad ones). */
  void requestSettings(const VentilatorSettings& settings);
  /** @brief One flow sample (BreathStartDetector::add); a start re-phases the schedule. */
  FlowSampleStatus addFlow(double t, double flow_ml_s);
  /** @brief Forgets the detected phase: unusable until the next detected start. */
  void reset();

  /** @brief Why the phase is unusable at @p now ("" when it is usable). */
  std::string problem(double now) const;
  /** @brief How old the latest start may be, s (timeout_periods x the current period). */
  double timeout() const;
  /** @brief Whether a breath start was detected since construction or reset(). */
  bool haveBreath() const { return have_breath_; }
  /** @brief The schedule (sample() it only while problem() is empty). */
  BreathScheduler& scheduler() { return scheduler_; }
  const BreathScheduler& scheduler() const { return scheduler_; }
  const BreathStartDetector& detector() const { return detector_; }

 private:
  FlowPhaseParams params_;
  BreathStartDetector detector_;
  VentilatorSettings settings_;  // the latest requested
  BreathScheduler scheduler_;
  bool have_breath_ = false;
  long detected_index_ = -1;  // the scheduler's breath index at the last detected start
};

}  // namespace pedicle_drilling::core
