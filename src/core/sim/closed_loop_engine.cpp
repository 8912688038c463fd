#include "pedicle_drilling/core/sim/closed_loop_engine.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <functional>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "pedicle_drilling/core/control/compensation_planner.hpp"
#include "pedicle_drilling/core/control/drill_guard.hpp"
#include "pedicle_drilling/core/control/monitor_runtime.hpp"
#include "pedicle_drilling/core/control/planner_runtime.hpp"
#include "pedicle_drilling/core/drilling/bone_specimen.hpp"
#include "pedicle_drilling/core/drilling/recognizer_adapter.hpp"
#include "pedicle_drilling/core/drilling/sample_rate_check.hpp"
#include "pedicle_drilling/core/robot/kinematics.hpp"
#include "pedicle_drilling/core/sim/bench_session.hpp"
#include "pedicle_drilling/core/sim/normal_source.hpp"
#include "pedicle_drilling/core/sim/stream_schedule.hpp"

namespace pedicle_drilling::core {

const ParamTable<EngineDelays>& EngineDelays::table() {
  static const ParamTable<EngineDelays> t = [] {
    using P = EngineDelays;
    const Range delay = Range::closed(0, 1);
    ParamTable<P> d;
    d.number("force_to_recognizer_s", &P::force_to_recognizer_s, delay, "s")
        .number("stop_to_planner_s", &P::stop_to_planner_s, delay, "s")
        .number("command_to_arm_s", &P::command_to_arm_s, delay, "s")
        .number("command_jitter_s", &P::command_jitter_s, delay, "s")
        .number("tracker_to_pipeline_s", &P::tracker_to_pipeline_s, delay, "s");
    return d;
  }();
  return t;
}

void EngineDelays::validate() const { table().validate(*this); }

namespace {

/** @brief The fault's trigger depth as a fraction of the inner layer's start: its own stream. */
double faultDepthFraction(std::uint64_t seed) {
  return uniformFromSeed(seed + 0x2545f4914f6cdd1dULL);
}

/** @brief A message in transit: handled at the first step at or after `t`. */
struct Event {
  double t;
  std::uint64_t seq;  // emission order: ties are handled in the order they were sent
  std::function<void()> handle;
};

/** @brief The trial's start phase in [0, 1): its own stream of the seed. */
double startPhaseFraction(std::uint64_t seed) {
  return uniformFromSeed(seed + 0x5851f42d4c957f2dULL);
}

}  // namespace

void checkSensorRate(const EngineConfig& config) {
  const RecognizerParams& r = config.recognizer;
  const double simulated = config.simulation.sensor.output_rate_hz;
  if (ratesAgree(r.sensor_rate_hz, simulated, kDefaultRateTolerance)) return;
  std::ostringstream os;
  os << "sensor_rate_hz: the recognizer is declared " << r.sensor_rate_hz
     << " Hz, the simulated force sensor runs at " << simulated
     << " Hz (force_sensor_rate_hz): more than " << 100.0 * kDefaultRateTolerance
     << " % apart, its block of " << r.blockSamples() << " samples would last "
     << r.blockSamples() / simulated << " s instead of pre_average_s " << r.pre_average_s
     << " s (trial_engine declares the simulated rate)";
  throw std::invalid_argument(os.str());
}

double commandJitterFraction(std::uint64_t seed, std::uint64_t index) {
  return uniformFromSeed((seed + 0x9e3779b97f4a7c15ULL) * 0xbf58476d1ce4e5b9ULL + index);
}

double CommandTransport::delay(double now) {
  if (jitter_s_ <= 0.0) return delay_s_;
  const double jitter = jitter_s_ * commandJitterFraction(seed_, count_++);
  last_due_ = std::max(now + delay_s_ + jitter, last_due_);
  return last_due_ - now;
}

double CommandTransport::undrawnDelay(double now) {
  if (jitter_s_ <= 0.0) return delay_s_;
  last_due_ = std::max(now + delay_s_, last_due_);
  return last_due_ - now;
}

double CommandTransport::spindleDelay(double now, double rpm) {
  const bool repeat = rpm > 0.0 && rpm == last_spindle_rpm_;
  last_spindle_rpm_ = rpm;
  return repeat ? undrawnDelay(now) : delay(now);
}

double trialStartTime(std::uint64_t seed, double reset_time, double pre_trial_s, double breath_s,
                      bool draw_phase) {
  return reset_time + pre_trial_s + (draw_phase ? startPhaseFraction(seed) * breath_s : 0.0);
}

const char* toString(TrialProtocol protocol) {
  return protocol == TrialProtocol::kPeakForces ? "peak_forces" : "recognition";
}

TrialProtocol parseTrialProtocol(const std::string& name) {
  if (name == "recognition") return TrialProtocol::kRecognition;
  if (name == "peak_forces") return TrialProtocol::kPeakForces;
  throw std::invalid_argument("protocol '" + name + "' is not one of: recognition, peak_forces");
}

struct ClosedLoopEngine::Impl {
  EngineConfig config;
  std::unique_ptr<ArmCompensation> arm;
  StreamSchedule streams;  ///< the streams of a step: the Simulator nodelet's schedule

  // Per trial (all rebuilt by run(), so that no trial depends on another).
  std::unique_ptr<DrillingSimulation> sim;
  /// The planner's runtime (its timers, its heartbeat), as the CompensationPlanner nodelet's.
  std::unique_ptr<PlannerRuntime> planner;
  TrialSequencer* sequencer = nullptr;            ///< planner's sequencer
  std::unique_ptr<RecognizerAdapter> recognizer;  ///< the StateRecognizer nodelet's glue
  std::unique_ptr<SafetySupervisor> monitor;
  std::vector<Event> events;
  std::uint64_t event_seq = 0;
  std::string planner_error;  ///< the sequencer's last error-level log line (why it failed)
  EngineTrialRecord record;
  BreathWatch breaths;  ///< the planner hears the ventilator's settings at each breath
  double now = 0.0;
  bool stop_truth_recorded = false;  // the truth sample at the first stop command was taken
  bool record_samples = false;       // the trial has started and its samples are recorded

  // Fault injection (record.fault holds the kind, trigger depth, and when it took effect).
  bool fault_armed = false;                   // the drilling has started: the trigger is watched
  TrialPhase last_phase = TrialPhase::kIdle;  // the sequencer's phase, as the monitor hears it
  bool fault_pending = false;                 // triggered, waiting for the next breath or command
  AtNextBreath fault_breath;  // a breathing fault's (amplitude) factor, from the next breath
  FaultInjector injector;     // the force, tracker and command faults (as the nodelet applies them)

  // The drill guard in the monitor's process and the heartbeats between the processes (the
  // pipeline's layout: planner + recognizer, monitor + guard, the drivers); a process-kill fault
  // silences one of the two processes of ours.
  DrillGuard guard;
  bool planner_alive = true;
  bool monitor_alive = true;
  double killed_at = -1.0;       // when a process was killed (-1: none)
  double next_guard_beat = 0.0;  // the guard's drill_guard/enable
  bool last_enable = true;
  bool drives_halted = false;  // as of the last step (a halt is recorded as a stop)

  // Transport (config.delays): the command path (its jitter drawn from the trial's seed) and
  // the tracker samples in transit.
  CommandTransport command_transport;
  struct TrackedMarker {
    double stamp;
    Eigen::Vector3d position;
    Eigen::Quaterniond orientation;
  };
  DelayLine<TrackedMarker> delayed_markers;  ///< tracker_to_pipeline_s

  // The protocol and the ground-truth peaks (record.truth_peak_*).
  TrialProtocol protocol = TrialProtocol::kRecognition;
  bool protocol_stopped = false;  // kPeakForces: the stop after the breakthrough was sent
  double truth_block_sum = 0.0;   // true thrust over the current pre-average block
  int truth_block_count = 0;
  int truth_block_steps = 1;  // the recognizer's block in physics steps

  /** @brief Block means of the true thrust, their peaks per layer up to the first stop. */
  void updateTruthPeaks(double thrust) {
    truth_block_sum += thrust;
    if (++truth_block_count < truth_block_steps) return;
    const double mean = truth_block_sum / truth_block_count;
    truth_block_sum = 0.0;
    truth_block_count = 0;
    if (!record.stops.empty()) return;
    const SimulationGroundTruth g = sim->groundTruth();
    double& peak = g.max_depth_cut_m > g.inner_cortical_start_m ? record.truth_peak_inner_n
                                                                : record.truth_peak_outer_n;
    peak = std::max(peak, mean);
  }

  /** @brief kPeakForces: once the tip is through the inner layer, stop with retreat. */
  void updateProtocol() {
    if (protocol != TrialProtocol::kPeakForces || protocol_stopped) return;
    if (!sim->groundTruth().breakthrough) return;
    protocol_stopped = true;
    const std::string reason = "protocol peak_forces: through the inner cortical layer";
    record.stops.push_back({now, "/protocol", reason, true});
    sequencer->onStop(now, true, reason);
    carryOut();
  }

  void injectFault() {
    record.fault.injected = true;
    record.fault.t = now;
    fault_pending = false;
    if (record.fault.kind == FaultKind::kPlannerKilled) killProcess(true);
    if (record.fault.kind == FaultKind::kMonitorKilled) killProcess(false);
    // The controller that carries the feed and the compensation (it owns feed_joint) drops
    // its trajectory and holds.
    if (record.fault.kind == FaultKind::kControllerAborted) {
      for (const ControllerSpec& c : sim->controllers()) {
        if (std::count(c.joints.begin(), c.joints.end(), "feed_joint") > 0) {
          sim->abortController(c.name);
        }
      }
    }
  }

  /** @brief Watches the trigger and applies the pending faults (once per step). */
  void updateFault() {
    const FaultKind kind = record.fault.kind;
    if (kind == FaultKind::kNone || !fault_armed || record.fault.injected) return;
    if (!fault_pending) {
      if (sim->groundTruth().max_depth_cut_m < record.fault.trigger_depth_m) return;
      fault_pending = true;
      if (isBreathingFault(kind)) {
        fault_breath.arm(sim->ventilator().breathIndex(), config.faults.amplitude_factor);
      }
      if (kind == FaultKind::kBreathingRateUp || kind == FaultKind::kBreathingRateDown) {
        // The ventilator takes new settings at its next breath; its settings stream tells the
        // planner then, as the Ventilator nodelet publishes them. The model is not re-fit.
        VentilatorSettings v = sim->ventilator().model().settings();
        const double change = config.faults.rate_change_bpm;
        v.rate_bpm =
            std::max(1.0, v.rate_bpm + (kind == FaultKind::kBreathingRateUp ? change : -change));
        sim->requestVentilatorSettings(v);
      }
      injector.inject(now);  // a command fault waits for the next command
      if (!isBreathingFault(kind) && !isCommandFault(kind)) injectFault();
      return;
    }
    if (!isBreathingFault(kind)) return;
    if (const std::optional<double> factor =
            fault_breath.takeDue(sim->ventilator().breathIndex())) {
      if (kind == FaultKind::kBreathingAmplitude) sim->setPatientAmplitudeFactor(*factor);
      injectFault();
    }
  }

  /** @brief The force sample as the faulty sensor delivers it; false: nothing delivered. */
  bool faultyForce(Eigen::Vector3d* force) { return injector.force(now, force); }

  /** @brief Extra delay of a trajectory command, or < 0 when the command is lost. */
  double commandFault() {
    if (!isCommandFault(record.fault.kind) || !injector.pending()) return 0.0;
    const double extra = injector.command(now);
    if (fault_pending) injectFault();  // the first of its commands (command_fault_count)
    return extra;
  }

  void send(double delay, std::function<void()> fn) {
    events.push_back({now + delay, event_seq++, std::move(fn)});
  }

  void deliverDue() {
    // Handle every event due by now, in time then emission order; handlers may send more.
    for (;;) {
      auto best = events.end();
      for (auto it = events.begin(); it != events.end(); ++it) {
        if (it->t <= now + 1e-12 && (best == events.end() || it->t < best->t ||
                                     (it->t == best->t && it->seq < best->seq))) {
          best = it;
        }
      }
      if (best == events.end()) return;
      const std::function<void()> fn = std::move(best->handle);
      events.erase(best);
      fn();
    }
  }

  /**
   * @brief The heartbeats at `now`: the planner's to the guard (while its trial runs), the
   *        guard's enable to the drivers (every period, at once when it turns false), and a
   *        halt of the drivers recorded as a stop of the drives (the pipeline's 1 ms transport
   *        is below the 20 ms periods and is not modelled).
   */
  void beatGuard() {
    if (planner_alive && planner->beatDue(now)) guard.onPlannerHeartbeat(now);
    if (monitor_alive) {
      const bool enable = guard.enabled(now);
      if (enable != last_enable || now + 1e-9 >= next_guard_beat) {
        if (!enable && last_enable)
          record.stops.push_back({now, "/drill_guard", guard.reason(), false});
        sim->onDriveEnable(enable);
        last_enable = enable;
        next_guard_beat = now + guard.params().heartbeat_period_s;
      }
    }
    if (sim->drivesHalted() && !drives_halted && monitor_alive == false) {
      record.stops.push_back({now, "/drive_guard",
                              "drive_guard: no drill_guard/enable for the drivers' timeout: the "
                              "drives hold, the spindle stops",
                              false});
    }
    drives_halted = sim->drivesHalted();
  }

  /** @brief A process-kill fault: the planner's (planner and recognizer) or the monitor's. */
  void killProcess(bool planner) {
    (planner ? planner_alive : monitor_alive) = false;
    killed_at = now;
  }

  void fireTimers() {
    if (!planner_alive) return;  // its timers died with it
    planner->fireDueTimers(now, [this]() { carryOut(); });
  }

  /** @brief Carries out what the sequencer produced, as the nodelet publishes it. */
  void carryOut() {
    SequencerOutput out = sequencer->takeOutput();
    if (!planner_alive) return;  // a dead process publishes nothing
    for (const SequencerLog& line : out.log) {
      if (line.level == SequencerLog::Level::kError) planner_error = line.text;
    }
    for (const std::string& why : out.stops) {
      record.stops.push_back({now, "/compensation_planner", why, true});
    }
    for (double rpm : out.spindle_rpm) {
      send(command_transport.spindleDelay(now, rpm), [this, rpm]() { sim->commandSpindle(rpm); });
    }
    for (const TareRequest& r : out.tare_requests) {
      send(command_transport.undrawnDelay(now), [this, r]() { sim->requestTare(r); });
    }
    for (JointTrajectoryCommand& c : out.trajectories) {
      const double delay = command_transport.delay(now);
      const double extra = commandFault();
      if (extra < 0.0) continue;  // lost
      const TrajectoryCommand command = toExecutorCommand(c);
      send(delay + extra, [this, command]() { sim->commandTrajectory(command); });
    }
    for (const PredictedMarker& m : out.predicted) {
      monitor->onPredicted(now, {m.stamp, m.frame, m.position});  // paired by the supervisor
      evaluateMonitor();
    }
    for (TrialPhase p : out.phases) {
      // The fault's trigger is watched from the start of the drilling (a bone that touches the
      // spinning drill at the drilling pose must not inject it during the move or the
      // registration: the fault campaign's faults hit while drilling).
      if (p == TrialPhase::kDrilling) fault_armed = true;
      record.status.emplace_back(now, toString(p));
      monitor->setTrialRunning(isRunning(p));  // the status the monitor subscribes to
      monitor->setDrilling(now, p == TrialPhase::kDrilling || p == TrialPhase::kStopped);
      guard.onPlannerPhase(now, isRunning(p),
                           p == TrialPhase::kDrilling || p == TrialPhase::kStopped);
      planner->onPhase(p, now);  // its heartbeat
      // The retreat ended: the drill is out, the spindle off; the sensor should read its tare.
      if (p == TrialPhase::kDone && last_phase == TrialPhase::kRetreating) {
        record.retare = monitor->retareCheck(now);
      }
      last_phase = p;
    }
    planner->applyTimers(out, now);
  }

  void evaluateMonitor() {
    if (!monitor_alive) return;  // a dead monitor says nothing
    const std::optional<SafetyVerdict> v = monitor->takeNewStop();
    if (!v) return;
    const std::string reason = describe(*v);
    record.stops.push_back({now, "/safety_monitor", reason, true});
    guard.onMonitorStop(now);
    if (injector.stop()) {  // stop_lost: published, never heard by the planner
      send(config.delays.stop_to_planner_s, [this, reason]() {
        sequencer->onStop(now, true, reason);
        carryOut();
      });
    }
    // Its ERROR on /diagnostics, published right after the stop: the planner stops on it too
    // (the nodelet's rule), so a lost stop is still heard; after the stop itself, a no-op.
    const std::string error = PlannerRuntime::monitorErrorReason(monitorStopMessage(*v));
    send(config.delays.stop_to_planner_s, [this, error]() {
      sequencer->onStop(now, true, error);
      carryOut();
    });
  }

  /**
   * @brief The drill's context for the recognizer from the joint states, as the
   *        StateRecognizer nodelet hears them on joint_states.
   */
  void onJointStates() {
    const Eigen::VectorXd q = sim->armJointPositions();
    const Eigen::VectorXd qd = sim->armJointVelocities();
    recognizer->setContextFromJoints(sim->armJointNames(),
                                     std::vector<double>(q.data(), q.data() + q.size()),
                                     std::vector<double>(qd.data(), qd.data() + qd.size()));
  }

  void onRecognizerSample(const RecognizerSample& sample) {
    if (!planner_alive) return;  // the recognizer runs in the planner's process
    const double t = sample.t;
    ComponentLaps laps(config.profile);
    const RecognizerStep pushed = recognizer->push(sample);
    const RecognizerOutput& out = recognizer->output();
    laps.mark(Component::kRecognizer);
    // Under kPeakForces the recognizer observes: its stop is recorded, never delivered.
    const bool deliver = protocol == TrialProtocol::kRecognition;
    if (pushed.new_average) {
      record.states.push_back(
          {t, out.averaged_force, out.feature, toString(out.state), out.last_key_point});
      const int previous = record.key_points.empty() ? 0 : record.key_points.back().first;
      for (int k = previous + 1; k <= out.last_key_point; ++k) record.key_points.emplace_back(k, t);
      const bool stop = out.stop && deliver;
      const std::string name = toString(out.state);
      const int kp = out.last_key_point;
      send(config.delays.stop_to_planner_s, [this, stop, name, kp]() {
        sequencer->onRecognizerState(now, stop, name, kp);
        carryOut();
      });
    }
    if (pushed.new_stop) record.recognizer_stop_t = t;
    if (pushed.new_stop && deliver) {
      const std::string text = pushed.stop_reason;
      record.stops.push_back({t, "/state_recognizer", text, false});
      if (!injector.stop()) return;  // stop_lost: drilling_state's stop flag still reaches it
      send(config.delays.stop_to_planner_s, [this, text]() {
        sequencer->onStop(now, false, text);
        carryOut();
      });
    }
  }

  /** @brief A tracker sample: to the pipeline now, or tracker_to_pipeline_s later (its stamp
   *         kept), handled where a sample is (before the step's timers). */
  void onMarker() {
    const Eigen::Isometry3d pose = sim->measureMarkerPose();
    Eigen::Vector3d marker = pose.translation();
    Eigen::Quaterniond orientation(pose.linear());
    double stamp = now;
    if (!injector.trackedPose(&marker, &orientation, &stamp)) return;  // silent tracker
    if (!delayed_markers.delays()) {
      deliverMarker(stamp, marker, orientation);
      return;
    }
    delayed_markers.push(now, {stamp, marker, orientation});
  }

  void deliverDelayedMarkers() {
    delayed_markers.deliverDue(
        now, [this](const TrackedMarker& m) { deliverMarker(m.stamp, m.position, m.orientation); });
  }

  void deliverMarker(double stamp, const Eigen::Vector3d& marker,
                     const Eigen::Quaterniond& orientation) {
    recognizer->setTracker(stamp, marker);  // as its nodelet hears tracker/marker_pose
    monitor->onTracked(now, {stamp, "tracker_camera", marker});
    evaluateMonitor();
    // The registered camera pose (the URDF's), not the true one (registration_error_mm).
    const Eigen::Isometry3d cam_from_world = sim->linkPose("tracker_camera").inverse();
    const FrameLookup lookup = [cam_from_world](const std::string& frame, Eigen::Isometry3d* x) {
      if (frame != "tracker_camera") return false;
      *x = cam_from_world;
      return true;
    };
    sequencer->onMarker(now, stamp, "tracker_camera", marker, orientation, lookup);
    carryOut();
  }

  /** @brief Each controller's state to the planner (its closed loop), as <name>/state. */
  void onControllerStates() {
    for (std::size_t i = 0; i < sim->controllers().size(); ++i) {
      const ControllerStateSample state = sim->controllerState(i);
      sequencer->onControllerState(now, sim->controllers()[i].name, state);
      // The recognizer's commanded feed, as its nodelet hears feed_controller/state (only the
      // controller of the feed joint has it).
      recognizer->setFeedCommandFromController(state.joint_names, state.desired_positions);
    }
    carryOut();
  }

  void onTidalVolume() {
    const BreathScheduler& ventilator = sim->ventilator();
    if (breaths.newBreath(ventilator)) sequencer->setVentilator(ventilator.model().settings());
    planner->onTidalVolume(now, sim->sensedTimeInBreath());
  }

  /** @brief One row of the dataset (EngineSample), at a force-sensor sample. */
  void recordSample(const RecognizerSample& sample, double true_force) {
    const SimulationGroundTruth g = sim->groundTruth();
    EngineSample x;
    x.t = now;
    x.given = sample;
    x.true_force_n = true_force;
    x.averaged_force_n = record.states.empty() ? 0.0 : record.states.back().averaged_force;
    x.tip_depth_m = g.tip_depth_m;
    x.max_depth_cut_m = g.max_depth_cut_m;
    x.layer = static_cast<int>(g.layer);
    x.contact = g.contact;
    x.bone_ap_m = g.bone_displacement_m.z();
    const CompensationPlanner* planner = sequencer->planner();
    x.predicted_ap_m = planner ? planner->boneDisplacementSinceStart(now).z() : std::nan("");
    const BreathScheduler& v = sim->ventilator();
    const double breath_s = 60.0 / v.model().settings().rate_bpm;
    x.breath_phase = std::clamp((now - v.breathStart()) / breath_s, 0.0, 1.0);
    x.tidal_volume_ml = g.tidal_volume_ml;
    record.samples.push_back(x);
  }

  /** @brief The depth limit's estimate of the tip's depth against the hole's true depth, while
   *         drilling, in contact, after the sensed contact (the hole's bottom is where the tip
   *         cuts; EngineTrialRecord::depth_estimate_error_max_m). */
  /// A hold at the depth limit lasts until the stop at the next segment tick (0.125 s) and the
  /// retreat's start: two ticks bound it.
  static constexpr double kDepthWindowS = 0.25;
  double depth_window_start = 0.0;

  void watchDepthEstimate(double cut_depth_m) {
    const DepthLimit& limit = sequencer->depthLimit();
    const CompensationPlanner* planner = sequencer->planner();
    if (!planner || !limit.active() || !limit.contact() ||
        sequencer->phase() != TrialPhase::kDrilling) {
      return;
    }
    const double estimate = sequencer->limitAdvance(now) + limit.correction() - limit.entry();
    const double error = cut_depth_m - estimate;
    double& worst = record.depth_estimate_error_max_m;
    if (std::isnan(worst) || error > worst) worst = error;
    std::vector<double>& windows = record.depth_estimate_window_errors_m;
    if (windows.empty() || now >= depth_window_start + kDepthWindowS) {
      windows.push_back(error);
      depth_window_start = now;
    } else {
      windows.back() = std::max(windows.back(), error);
    }
  }

  void recordTruth() {
    const SimulationGroundTruth g = sim->groundTruth();
    record.truth.push_back({now, materialName(g.layer), g.max_depth_cut_m,
                            g.residual_inner_cortical_m, g.breakthrough, g.relative_ap_m, g.contact,
                            g.contact_loss_count});
    record.last_truth = g;
  }

  /**
   * @brief The planner's trial-start chain (~trial_start_services of the pipeline): the
   *        simulator's start_trial, then the recognizer's and the monitor's resets. The reset
   *        recognizer announces its cleared state, as the StateRecognizer nodelet publishes it.
   */
  void startComponents() {
    sim->startTrial();
    resetRecognizer();
    monitor->reset();
  }

  /** @brief The recognizer starts afresh and announces its cleared state (StateRecognizer's
   *         ~reset and its reset on a successful tare). */
  void resetRecognizer() {
    recognizer->reset();
    const RecognizerOutput& r = recognizer->output();
    const std::string name = toString(r.state);
    const int kp = r.last_key_point;
    const bool stop = r.stop;
    send(config.delays.stop_to_planner_s, [this, stop, name, kp]() {
      sequencer->onRecognizerState(now, stop, name, kp);
      carryOut();
    });
  }

  /**
   * @brief The sensor driver's tare result (ft_sensor/tare_result), after the sample that
   *        completed it: the recognizer restarts on the tared force (on success), the planner
   *        hears it.
   */
  void onTareResult() {
    const std::optional<TareResult> r = sim->takeTareResult();
    if (!r) return;
    record.tare = *r;
    if (r->success) {
      if (config.delays.force_to_recognizer_s > 0.0) {  // after the samples in transit
        send(config.delays.force_to_recognizer_s, [this]() { resetRecognizer(); });
      } else {
        resetRecognizer();
      }
    }
    const TareResult result = *r;
    send(config.delays.stop_to_planner_s, [this, result]() {
      sequencer->onTareResult(now, result);
      carryOut();
    });
  }

  /** @brief One 1 ms physics step and everything the pipeline does in it. */
  void step(std::uint64_t n) {
    const ScopedComponentTimer timer(config.profile, Component::kEngineStep);
    const SimulationStep s = sim->stepOnce();
    now = s.time_s;
    const StreamsDue due = streams.at(n, s, *sim);
    updateTruthPeaks(s.force.thrust_N);
    updateProtocol();
    Eigen::Vector3d force = s.measured_wrench.head<3>();
    if (monitor_alive) sequencer->onMonitorAlive(now);  // its /diagnostics, every step
    updateFault();
    if (due.joint_states) onJointStates();
    if (due.force && faultyForce(&force)) {
      // The whole sample: the thrust along config/recognizer.yaml's axis (z), the wrench, the
      // drill's context as the joint states last gave it.
      const RecognizerSample sample = recognizer->sample(now, force, s.measured_wrench.tail<3>());
      const double thrust = sample.thrust_n;
      const double t = now;
      // A non-finite sample is dropped (counted) as the StateRecognizer nodelet drops it; the
      // monitor stops on it.
      const bool admitted = recognizer->admit(t, thrust);
      if (admitted && config.delays.force_to_recognizer_s > 0.0) {
        send(config.delays.force_to_recognizer_s, [this, sample]() { onRecognizerSample(sample); });
      } else if (admitted) {
        onRecognizerSample(sample);
      }
      ComponentLaps laps(config.profile);
      if (monitor_alive) {
        monitor->onForce(now, force);
        evaluateMonitor();
      }
      laps.mark(Component::kMonitor);
      // The planner hears ft_sensor/wrench too: the contact its depth limit counts from.
      if (planner_alive) sequencer->onForce(now, t, thrust);
      if (s.force.contact) watchDepthEstimate(sim->process().maxDepthCut());
      if (record_samples) recordSample(sample, s.force.thrust_N);
    }
    if (due.force) onTareResult();
    if (due.ground_truth) recordTruth();
    if (due.tracker) onMarker();
    deliverDelayedMarkers();
    if (due.tidal_volume) onTidalVolume();
    if (due.controller_states) onControllerStates();
    if (due.safety_check && monitor_alive) {
      ComponentLaps laps(config.profile);
      monitor->check(now);
      evaluateMonitor();
      laps.mark(Component::kMonitor);
    }
    beatGuard();
    fireTimers();
    deliverDue();
    // The ground truth at the first stop command (a breakthrough before it from one after it,
    // the stop's depth: pd_campaign.outcome), besides the 20 Hz samples and the layer changes.
    if (!stop_truth_recorded && !record.stops.empty()) {
      stop_truth_recorded = true;
      recordTruth();
    }
  }
};

ClosedLoopEngine::ClosedLoopEngine(const EngineConfig& config) : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.config = config;
  config.delays.validate();
  config.recognizer.validate();
  checkSensorRate(config);
  config.safety.validate();
  config.guard.validate();
  config.faults.validate();
  StreamRates rates;
  rates.tracker_hz = config.tracker_rate_hz;
  rates.controller_state_hz = config.controller_state_rate_hz;
  rates.ground_truth_hz = config.ground_truth_rate_hz;
  rates.joint_state_hz = config.joint_state_rate_hz;
  rates.tidal_volume_hz = config.tidal_volume_rate_hz;
  rates.safety_check_hz = config.safety_check_rate_hz;
  s.streams = StreamSchedule(rates);
  // The planner needs the breath, the monitor checks: neither stream may be off here.
  if (!s.streams.tidalVolumeOn() || !s.streams.safetyCheckOn()) {
    throw std::invalid_argument(
        "tidal_volume_rate_hz and safety_check_rate_hz: must be > 0 Hz in the engine");
  }
  // The recognizer's block: its blockSamples() sensor samples, in physics steps.
  const long decimation =
      std::lround(config.simulation.physics_rate_hz / config.simulation.sensor.output_rate_hz);
  s.truth_block_steps = static_cast<int>(config.recognizer.blockSamples() * decimation);
  if (!(config.pre_trial_s >= 0.0 && config.pre_trial_s <= 60.0)) {
    throw std::invalid_argument("pre_trial_s: must be in [0, 60] s");
  }
  if (!(config.trial_timeout_s > 0.0)) {
    throw std::invalid_argument("trial_timeout_s: must be > 0 s");
  }
  const KinematicChain chain =
      KinematicChain::fromUrdfString(config.urdf_xml, config.arm_base_link, config.arm_tip_link);
  if (config.drilling_pose.size() != chain.jointNames().size()) {
    throw std::invalid_argument("drilling_pose: needs one value per arm joint (" +
                                std::to_string(chain.jointNames().size()) + ")");
  }
  const Eigen::VectorXd q =
      Eigen::Map<const Eigen::VectorXd>(config.drilling_pose.data(), config.drilling_pose.size());
  s.arm = std::make_unique<ArmCompensation>(chain, q, config.feed_home_m);
  s.arm->setTipAtPose(ArmCompensation::tipAt(config.urdf_xml, config.arm_base_link,
                                             config.simulation.tip_link, chain.jointNames(), q));
  s.config.sequencer.arm_joints = chain.jointNames();
  // Checks the sequencer's parameters once, before any trial.
  TrialSequencer check(s.config.sequencer, *s.arm);
  (void)check;
}

ClosedLoopEngine::~ClosedLoopEngine() = default;

const EngineConfig& ClosedLoopEngine::config() const { return impl_->config; }

EngineTrialRecord ClosedLoopEngine::run(const EngineTrialSpec& spec) {
  Impl& s = *impl_;
  const bool moving = spec.mode != "stationary";
  // Everything new for every trial: its record depends on its seed and nothing else.
  // The drivers watch the drill guard as the pipeline's simulated drivers do (a lab's too).
  DrillingSimulationParams sim_params = s.config.simulation;
  sim_params.drive_guard_timeout_s = kDriveGuardTimeoutS;
  s.sim = std::make_unique<DrillingSimulation>(s.config.urdf_xml, sim_params, spec.seed);
  s.sim->setProfile(s.config.profile);
  s.sim->setBoneMotionModel(moving ? spec.bone_motion : std::nullopt);
  s.sim->reset(spec.seed, moving);
  TrialSequencerParams sequencer_params = s.config.sequencer;
  if (spec.protocol == TrialProtocol::kPeakForces) {
    // The protocol drills through the inner layer on purpose, with the recognizer observing:
    // the planner's plausibility bounds on the recognizer's layers do not apply.
    sequencer_params.outer_cortical_max_mm = 0.0;
    sequencer_params.cancellous_max_mm = 0.0;
    sequencer_params.depth_limit.require_plan = false;  // nor the plan's depth limit
  }
  s.planner = std::make_unique<PlannerRuntime>(
      std::make_unique<TrialSequencer>(sequencer_params, *s.arm), kPlannerHeartbeatPeriodS);
  s.sequencer = &s.planner->sequencer();
  s.sequencer->setCompensatorFactory(s.config.make_compensator);
  if (spec.protocol == TrialProtocol::kRecognition && sequencer_params.depth_limit.require_plan) {
    s.sequencer->setPlan(s.sim->imagingPlan().plan);  // the planning step's, as the bench's
  }
  std::unique_ptr<RecognizerInterface> recognizer =
      s.config.make_recognizer ? s.config.make_recognizer()
                               : std::make_unique<PaperRecognizer>(s.config.recognizer);
  if (!recognizer) throw std::runtime_error("make_recognizer returned no recognizer");
  // What the class throws while running is its stop, naming the error (as on the nodelet):
  // the adapter guards it.
  s.recognizer = std::make_unique<RecognizerAdapter>(std::move(recognizer));
  s.monitor = std::make_unique<SafetySupervisor>(s.config.safety);
  s.events.clear();
  s.event_seq = 0;
  s.planner_error.clear();
  s.record = EngineTrialRecord();
  s.breaths.clear();
  s.stop_truth_recorded = false;
  s.record_samples = false;
  s.fault_armed = false;
  s.last_phase = TrialPhase::kIdle;
  s.fault_pending = false;
  s.fault_breath.clear();
  s.injector = FaultInjector(s.config.faults, spec.seed ^ 0x6661756c74ULL);  // its own stream
  s.command_transport = CommandTransport(s.config.delays.command_to_arm_s,
                                         s.config.delays.command_jitter_s, spec.seed);
  s.delayed_markers.clear();
  s.delayed_markers.setDelay(s.config.delays.tracker_to_pipeline_s);
  s.injector.arm(spec.fault);
  s.guard = DrillGuard(s.config.guard);
  s.planner_alive = true;
  s.monitor_alive = true;
  s.killed_at = -1.0;
  s.next_guard_beat = 0.0;
  s.last_enable = true;
  s.drives_halted = false;
  s.protocol = spec.protocol;
  s.protocol_stopped = false;
  s.truth_block_sum = 0.0;
  s.truth_block_count = 0;
  s.now = s.sim->time();
  const double sim_start = s.now;
  const BoneSpecimen& specimen = s.sim->process().specimen();
  s.record.conditions = s.sim->trialConditions();
  s.record.plan_far_side_error_m = s.sim->imagingPlan().far_side_error_m;
  s.record.outer_cortical_thickness_m = specimen.outerCorticalThickness();
  s.record.cancellous_thickness_m = specimen.cancellousThickness();
  s.record.inner_cortical_thickness_m = specimen.innerCorticalThickness();
  s.record.fault.kind = spec.fault;
  if (spec.fault != FaultKind::kNone) {
    s.record.fault.trigger_depth_m =
        faultDepthFraction(spec.seed) * s.sim->groundTruth().inner_cortical_start_m;
  }

  std::uint64_t n = 0;
  // Before the trial: the ventilator's settings and breath phase reach the planner. Then the
  // trial starts at a breath phase drawn from the seed (uniform over one breath), as an operator
  // starts at an arbitrary moment of the breathing: a fixed start would put every trial's first
  // contact at the same phase.
  const double breath_s = 60.0 / s.record.conditions.ventilator_rate_bpm;
  const double t_start =
      trialStartTime(spec.seed, s.now, s.config.pre_trial_s, breath_s, s.config.draw_start_phase);
  while (s.now < t_start - 1e-9) s.step(++n);
  s.startComponents();
  s.record_samples = spec.record_samples;
  TrialRequest request;
  request.mode = spec.mode;
  request.spindle_rpm = spec.spindle_rpm;
  request.feed_rate_mm_s = spec.feed_rate_mm_s;
  request.max_duration_s = spec.max_duration_s;
  const TrialStartAnswer started = s.planner->start(request, spec.model, s.now, s.now);
  if (!started.success) throw std::runtime_error("start_trial refused: " + started.message);
  s.carryOut();
  const double deadline = s.now + s.config.trial_timeout_s;
  while (s.sequencer->phase() != TrialPhase::kDone) {
    // A killed process: the trial ends kProcessKillWatchS after it (the bone breathing into
    // the held drill meanwhile), whatever the planner's phase (a retreat the held drives
    // refused may fail it).
    if (s.killed_at >= 0.0 && s.now >= s.killed_at + kProcessKillWatchS) break;
    if (s.sequencer->phase() == TrialPhase::kFailed && s.killed_at < 0.0) {
      std::string statuses;
      for (const auto& st : s.record.status) statuses += (statuses.empty() ? "" : " ") + st.second;
      throw std::runtime_error("the planner failed the trial (statuses: " + statuses + ")" +
                               (s.planner_error.empty() ? "" : ": " + s.planner_error));
    }
    if (s.now > deadline) {
      std::ostringstream os;
      os << "trial did not finish within " << s.config.trial_timeout_s << " s of sim time (status "
         << toString(s.sequencer->phase()) << ")";
      throw std::runtime_error(os.str());
    }
    s.step(++n);
  }
  s.recordTruth();
  s.record.watch_desired_ratio = s.sequencer->controllerWatch().worstDesiredRatio();
  s.record.watch_following_ratio = s.sequencer->controllerWatch().worstFollowingRatio();
  s.record.fault.counts = s.injector.counts();
  if (s.config.profile) s.config.profile->addTrial(s.now - sim_start);
  return s.record;
}

}  // namespace pedicle_drilling::core
