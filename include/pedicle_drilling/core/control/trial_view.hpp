// What the rviz plugins show of a trial, without Qt, Ogre or ROS: the DrillingPanel's
// settings and their validation, the live readouts and the verdict of a trial built from the
// pipeline's messages, and the placement of the force plot's labels. The plugins feed these
// classes from their subscriptions and draw what they answer; gtest covers them.
#ifndef PEDICLE_DRILLING_CORE_TRIAL_VIEW_HPP_
#define PEDICLE_DRILLING_CORE_TRIAL_VIEW_HPP_

#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "pedicle_drilling/core/control/safety_supervisor.hpp"

namespace pedicle_drilling::core {

/** @brief What the DrillingPanel starts a trial with (saved in the rviz configuration). */
struct PanelSettings {
  std::string mode = "compensated";  ///< stationary | uncompensated | compensated
  std::string segment_profile;       ///< "" (the planner's ~segment_profile), rest_to_rest, exact
  double spindle_rpm = 12000.0;      ///< (0, 60000]
  double feed_rate_mm_s = 0.5;       ///< (0, 10]
  std::uint64_t seed = 5;            ///< specimen and patient of the simulator's reset

  /** @brief Check every field. @throws std::invalid_argument whose message starts with it. */
  void validate() const;
  /** @brief The fields as text, for the rviz configuration (Mode, Profile, Rpm, Feed, Seed). */
  std::map<std::string, std::string> toConfig() const;
  /**
   * @brief Settings from a saved configuration: missing keys keep their defaults; a bad value
   *        keeps the default too and is named in *problems (one line each).
   */
  static PanelSettings fromConfig(const std::map<std::string, std::string>& config,
                                  std::vector<std::string>* problems);
};

/** @brief The verdict of a trial (the campaign's rule, paper Sec. V-C/E). */
enum class TrialVerdict { kNone, kRunning, kSuccess, kFailure };

/**
 * @brief The paper's success (Sec. V-C/E), the rule of the campaign's trials.csv: stopped by the
 *        recognizer inside the inner cortical layer (entered: deepest cut past its start; not
 *        broken through) with a residual thickness in (0, 2 mm].
 */
bool paperSuccess(bool recognizer_stop, bool breakthrough, double max_depth_cut_m,
                  double inner_cortical_start_m, double residual_m);

/** @brief One labelled readout of the panel. */
struct Readout {
  std::string label;
  std::string value;
  bool alarm = false;  ///< drawn in red (a limit exceeded, a stop by the monitor, a failure)
};

/**
 * @brief The live state of one trial, from the pipeline's messages: phase, recognizer state and
 *        last key point, averaged force and A*, predicted vs tracked marker (the H1 quantity),
 *        the force magnitude (H2), the safety monitor's status, the stops, and at the end the
 *        residual and the verdict. Times are the messages' stamps [s].
 */
class TrialView {
 public:
  /** @brief Thresholds shown beside the values (the SafetyMonitor's defaults). */
  TrialView(double h1_m = 1.2e-3, double h2_n = 10.0) : h1_m_(h1_m), h2_n_(h2_n) {}

  /** @brief Forget the trial (a new one starts; the panel's Reset). */
  void reset();
  /** @brief compensation/status. A new trial (moving_to_pose after an end) resets the rest. */
  void onPhase(const std::string& phase_name, bool running);
  /** @brief drilling_state. */
  void onRecognizer(const std::string& state_name, int last_key_point, double averaged_force,
                    double feature, bool stop);
  /** @brief drill/stop: the first stop of the trial is its stop. */
  void onStop(const std::string& source, const std::string& reason, bool retreat);
  /** @brief simulator/ground_truth (absent on hardware: no residual, no verdict). */
  void onGroundTruth(double max_depth_cut_m, double inner_cortical_start_m,
                     double inner_cortical_end_m, double residual_m, bool breakthrough);
  /** @brief compensation/predicted_marker_pose: the planner's prediction at a tracker stamp. */
  void onPredictedMarker(double stamp, const Eigen::Vector3d& position);
  /** @brief tracker/marker_pose: paired with the prediction of the same stamp (H1). */
  void onTrackedMarker(double stamp, const Eigen::Vector3d& position);
  /** @brief ft_sensor/wrench: the force magnitude [N] (H2). */
  void onForce(double force_n);
  /** @brief The safety monitor's DiagnosticStatus: level 0 OK, 1 WARN, 2 ERROR, 3 STALE. */
  void onMonitorStatus(int level, const std::string& message);

  /** @brief The phase's name ("" before any). */
  const std::string& phase() const { return phase_; }
  /** @brief True once the trial is done or failed. */
  bool ended() const { return phase_ == "done" || phase_ == "failed"; }
  /** @brief The verdict: none before a trial, running, then success or failure. */
  TrialVerdict verdict() const;
  /** @brief The latest H1 error [m] (NaN before a pair of samples). */
  double positionError() const { return h1_error_m_; }
  /** @brief The safety monitor's level (-1: none heard). */
  int monitorLevel() const { return monitor_level_; }
  /** @brief The residual thickness at the end [m] (NaN without ground truth). */
  double residual() const { return residual_m_; }
  /** @brief The readouts, in display order. */
  std::vector<Readout> readouts() const;
  /** @brief One line: phase, stop, residual, verdict (the panel's log and its summary topic). */
  std::string summary() const;

 private:
  double h1_m_;
  double h2_n_;
  std::string phase_;
  bool running_ = false;
  std::string state_name_;
  int key_point_ = 0;
  double averaged_force_ = std::numeric_limits<double>::quiet_NaN();
  double feature_ = std::numeric_limits<double>::quiet_NaN();
  bool recognizer_stop_ = false;
  std::string stop_source_;
  std::string stop_reason_;
  bool stop_retreat_ = false;
  bool have_truth_ = false;
  double max_cut_m_ = 0.0;
  double inner_start_m_ = 0.0;
  double inner_end_m_ = 0.0;
  double residual_m_ = std::numeric_limits<double>::quiet_NaN();
  bool breakthrough_ = false;
  /** @brief Prediction and tracker paired by the same stamp (the planner stamps its prediction
   *         with the tracker sample's own), as the SafetySupervisor pairs them. */
  StampPairer markers_{0.0, 64};
  void onMarker(double stamp, const Eigen::Vector3d& position, bool predicted);
  double h1_error_m_ = std::numeric_limits<double>::quiet_NaN();
  double h1_max_m_ = 0.0;
  double force_n_ = std::numeric_limits<double>::quiet_NaN();
  double force_max_n_ = 0.0;
  int monitor_level_ = -1;
  std::string monitor_message_;
};

/** @brief One averaged sample of the force plot. */
struct TraceSample {
  double t = 0.0;        ///< stamp [s]
  double force = 0.0;    ///< averaged force [N]
  double feature = 0.0;  ///< A*
};

/** @brief One sample of the F/T sensor's thrust, for the force plot. */
struct ThrustSample {
  double t = 0.0;       ///< stamp [s]
  double thrust = 0.0;  ///< the wrench's component along the recognizer's axis [N]
};

/** @brief A key point or the stop, for the force plot. */
struct TraceEvent {
  double t = 0.0;
  std::string label;  ///< K1..K6, STOP
  bool stop = false;
};

/**
 * @brief The force plot's record of one trial, from drilling_state (and the simulator's ground
 *        truth for the depth axis): from `lead_in_s` before the bone contact (the recognizer
 *        leaving idle) to `tail_s` after the stop; later samples are not kept, so the stop stays
 *        in view. The stop is the recognizer's (drilling_state.stop) or any other stop command
 *        (drill/stop: the safety monitor's). The recognizer's reset (its stop or its key point
 *        falling back to none), or time going backwards (a new simulation, a bag loop), starts
 *        a new trial.
 */
class ForceTrace {
 public:
  /** @brief lead_in_s before the contact, tail_s after the stop [s]. */
  explicit ForceTrace(double lead_in_s = 2.0, double tail_s = 3.0)
      : lead_in_s_(lead_in_s), tail_s_(tail_s) {}

  /** @brief One drilling_state; non-finite force or A* are not plotted (events still are). */
  void add(double t, const std::string& state_name, int last_key_point, double averaged_force,
           double feature, bool stop);
  /** @brief A stop command at t from `source` (drill/stop); the first stop is marked. */
  void addStop(double t, const std::string& source);
  /** @brief The deepest cut [m] at t (simulator/ground_truth), for the depth axis. */
  void addDepth(double t, double depth_m);
  /**
   * @brief The F/T sensor's thrust [N] at t (the wrench the recognizer reads, along its axis):
   *        kept by the rules of the averaged samples (the lead-in before the contact, frozen
   *        tail_s after the stop); non-finite values are dropped, time going backwards starts
   *        the thrust record over. Without drilling_state it is a strip chart of the last
   *        lead_in_s.
   */
  void addThrust(double t, double thrust_n);
  /** @brief Forget everything. */
  void clear();

  /** @brief The kept samples, in time order. */
  const std::vector<TraceSample>& samples() const { return samples_; }
  /** @brief The kept thrust samples, in time order. */
  const std::vector<ThrustSample>& thrust() const { return thrust_; }
  /** @brief Key points and the stop, in time order. */
  const std::vector<TraceEvent>& events() const { return events_; }
  /** @brief Time of the bone contact (NaN before). */
  double contactTime() const { return contact_t_; }
  /** @brief True once the stop was seen (the trace is frozen tail_s after it). */
  bool stopped() const { return !std::isnan(stop_t_); }
  /** @brief The largest A* since key point 4 (NaN before it): C3 applies to it. */
  double innerPeak() const { return inner_peak_; }
  /** @brief The state name of the newest sample. */
  const std::string& stateName() const { return state_name_; }
  /** @brief Depth [m] of the deepest cut at t, interpolated (NaN without ground truth). */
  double depthAt(double t) const;

 private:
  double lead_in_s_;
  double tail_s_;
  std::vector<TraceSample> samples_;
  std::vector<ThrustSample> thrust_;
  std::vector<TraceEvent> events_;
  std::vector<std::pair<double, double>> depth_;  // (t, depth)
  std::string state_name_;
  double last_t_ = -std::numeric_limits<double>::infinity();
  double contact_t_ = std::numeric_limits<double>::quiet_NaN();
  double stop_t_ = std::numeric_limits<double>::quiet_NaN();
  double inner_peak_ = std::numeric_limits<double>::quiet_NaN();
  int last_key_point_ = 0;
  bool recognizer_stop_ = false;
};

/** @brief One label of a chart: where it points and how wide it is [px]. */
struct ChartLabel {
  double x = 0.0;
  double width = 0.0;
};

/**
 * @brief Rows for chart labels so that no two on a row overlap (`gap` px apart at least): each
 *        label, in order of x, takes the first row whose last label ends before it; at most
 *        `max_rows` rows (then the row with the most room). Returns the row of each label.
 */
std::vector<int> layoutLabels(const std::vector<ChartLabel>& labels, double gap = 4.0,
                              int max_rows = 4);

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_TRIAL_VIEW_HPP_
