/**
 * @file node_params.cpp
 * @brief The declarations of every nodelet's parameters (node_params.hpp).
 */
#include "pedicle_drilling/ros/node_params.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace pedicle_drilling {

using core::ParamTable;
using core::Range;

// ---------------------------------------------------------------------------------------------

const ParamTable<VentilatorNodeParams>& VentilatorNodeParams::table() {
  static const ParamTable<VentilatorNodeParams> t = [] {
    using P = VentilatorNodeParams;
    ParamTable<P> d;
    d.include(core::VentilatorSettings::table(), &P::settings)
        .number("publish_rate_hz", &P::publish_rate_hz, Range::aboveUpTo(0, 1000), "Hz")
        .text("frame_id", &P::frame_id)
        .parsed(
            "breath_source", {"internal", "flow"}, "", [](const P& v) { return v.breath_source; },
            [](P& v, const std::string& x) { v.breath_source = x; })
        .include(core::FlowPhaseParams::table(), &P::flow);
    return d;
  }();
  return t;
}

void VentilatorNodeParams::validate() const {
  table().validate(*this);
  settings.validate();
  flow.validate();
}

// ---------------------------------------------------------------------------------------------

const ParamTable<SimulatorNodeParams>& SimulatorNodeParams::table() {
  static const ParamTable<SimulatorNodeParams> t = [] {
    using P = SimulatorNodeParams;
    const Range stream = Range::aboveUpTo(0, 1000);
    ParamTable<P> d;
    d.text("urdf_path", &P::urdf_path)
        .integer("seed", &P::seed, Range::closed(0, 2147483647))
        .number("real_time_factor", &P::real_time_factor, Range::closed(0, 1000))
        .flag("publish_clock", &P::publish_clock)
        .integer("clock_period_ms", &P::clock_period_ms, Range::closed(1, 100), "ms")
        .number("command_wait_s", &P::command_wait_s, Range::closed(0, 60), "s")
        .number("lockstep_timeout_s", &P::lockstep_timeout_s, Range::closed(0.01, 600), "s")
        .flag("lockstep_every_step", &P::lockstep_every_step)
        .flag("follow_joint_trajectory", &P::follow_joint_trajectory)
        .number("command_delay_s", &P::command_delay_s, Range::closed(0.001, 1), "s")
        .number("command_jitter_s", &P::command_jitter_s, Range::closed(0, 1), "s")
        .number("tracker_delay_s", &P::tracker_delay_s, Range::closed(0, 1), "s")
        .number("joint_state_rate_hz", &P::joint_state_rate_hz, stream, "Hz")
        .number("tf_rate_hz", &P::tf_rate_hz, stream, "Hz")
        .number("ground_truth_rate_hz", &P::ground_truth_rate_hz, stream, "Hz")
        .number("controller_state_rate_hz", &P::controller_state_rate_hz, stream, "Hz")
        .number("tracker_rate_hz", &P::tracker_rate_hz, stream, "Hz")
        .number("tidal_volume_rate_hz", &P::tidal_volume_rate_hz, Range::closed(0, 1000), "Hz")
        .text("bone_motion_model_path", &P::bone_motion_model_path, true)
        .text("tracker_tf_frame", &P::tracker_tf_frame, true)
        .flag("publish_joint_frames", &P::publish_joint_frames)
        .include(core::DrillingSimulationParams::table(), &P::sim);
    return d;
  }();
  return t;
}

void SimulatorNodeParams::validate() const {
  table().validate(*this);
  sim.validate();
}

// ---------------------------------------------------------------------------------------------

const ParamTable<TfPoseRelayNodeParams>& TfPoseRelayNodeParams::table() {
  static const ParamTable<TfPoseRelayNodeParams> t = [] {
    using P = TfPoseRelayNodeParams;
    ParamTable<P> d;
    d.text("tracker_frame", &P::tracker_frame).text("marker_frame", &P::marker_frame);
    return d;
  }();
  return t;
}

void TfPoseRelayNodeParams::validate() const {
  table().validate(*this);
  if (tracker_frame == marker_frame) {
    throw std::invalid_argument("marker_frame: must differ from tracker_frame ('" + tracker_frame +
                                "')");
  }
}

// ---------------------------------------------------------------------------------------------

const ParamTable<TrialActionNodeParams>& TrialActionNodeParams::table() {
  static const ParamTable<TrialActionNodeParams> t = [] {
    using P = TrialActionNodeParams;
    ParamTable<P> d;
    d.text("start_service", &P::start_service)
        .number("service_timeout_s", &P::service_timeout_s, Range::aboveUpTo(0, 600), "s")
        .text("feed_joint", &P::feed_joint)
        .number("feedback_period_s", &P::feedback_period_s, Range::aboveUpTo(0, 10), "s")
        .number("planner_lost_s", &P::planner_lost_s, Range::aboveUpTo(0, 60), "s");
    return d;
  }();
  return t;
}

void TrialActionNodeParams::validate() const { table().validate(*this); }

// ---------------------------------------------------------------------------------------------

const ParamTable<ForceTareNodeParams>& ForceTareNodeParams::table() {
  static const ParamTable<ForceTareNodeParams> t = [] {
    using P = ForceTareNodeParams;
    ParamTable<P> d;
    d.text("zero_service", &P::zero_service, true)
        .number("zero_tolerance_n", &P::zero_tolerance_n, Range::aboveUpTo(0, 100), "N")
        .number("zero_service_timeout_s", &P::zero_service_timeout_s, Range::aboveUpTo(0, 60), "s");
    return d;
  }();
  return t;
}

void ForceTareNodeParams::validate() const { table().validate(*this); }

// ---------------------------------------------------------------------------------------------

const ParamTable<MotionIdentificationParams>& MotionIdentificationParams::table() {
  static const ParamTable<MotionIdentificationParams> t = [] {
    using P = MotionIdentificationParams;
    const std::vector<std::string> axes{"+x", "-x", "+y", "-y", "+z", "-z"};
    const auto axis = [&axes](std::string P::*field) {
      return std::make_pair([field](const P& v) { return v.*field; },
                            [field](P& v, const std::string& x) { v.*field = x; });
    };
    ParamTable<P> d;
    d.text("tracker_frame", &P::tracker_frame)
        .text("patient_frame", &P::patient_frame, true)
        .text("marker_frame", &P::marker_frame)
        .number("marker_rate_hz", &P::marker_rate_hz, Range::aboveUpTo(0, 1000), "Hz")
        .number("tf_delay_s", &P::tf_delay_s, Range::closed(0, 10), "s")
        .flag("use_pose_topic", &P::use_pose_topic)
        .number("window_s", &P::window_s, Range::aboveUpTo(0, 3600), "s");
    for (const auto& [name, field] :
         {std::make_pair("ap_axis", &P::ap_axis), std::make_pair("si_axis", &P::si_axis),
          std::make_pair("lr_axis", &P::lr_axis)}) {
      const auto [get, set] = axis(field);
      d.parsed(name, axes, "", get, set);
    }
    d.include(core::PipelineOptions::table(), &P::defaults)
        .text("output_path", &P::output_path)
        .text("model_folder", &P::model_folder, true)
        .text("patient_id", &P::patient_id);
    return d;
  }();
  return t;
}

core::AxisMapping MotionIdentificationParams::mapping() const {
  try {
    return core::parseAxisMapping(ap_axis, si_axis, lr_axis);
  } catch (const std::invalid_argument& e) {
    // The message starts with the axis ("ap", "si" or "lr"): name that parameter.
    throw std::invalid_argument(std::string(e.what()).substr(0, 2) + "_axis: " + e.what());
  }
}

void MotionIdentificationParams::validate() const {
  table().validate(*this);
  mapping();
  defaults.validate();
}

// ---------------------------------------------------------------------------------------------

const std::vector<std::string>& forceAxes() {
  static const std::vector<std::string> axes{"x", "y", "z", "-x", "-y", "-z"};
  return axes;
}

int forceAxisIndex(const std::string& axis) { return axis.back() - 'x'; }

double forceAxisSign(const std::string& axis) { return axis.front() == '-' ? -1.0 : 1.0; }

const ParamTable<StateRecognizerNodeParams>& StateRecognizerNodeParams::table() {
  static const ParamTable<StateRecognizerNodeParams> t = [] {
    using P = StateRecognizerNodeParams;
    ParamTable<P> d;
    d.parsed(
         "axis", forceAxes(), "", [](const P& v) { return v.axis; },
         [](P& v, const std::string& x) { v.axis = x; })
        .include(core::RecognizerParams::table(), &P::recognizer)
        .number("rate_tolerance", &P::rate_tolerance, Range::open(0, 1))
        .number("rate_window_s", &P::rate_window_s, Range::aboveUpTo(0, 60), "s")
        .integer("queue_size", &P::queue_size, Range::closed(1, 100000))
        .parsed(
            "feed_joint", {}, "", [](const P& v) { return v.joints.feed; },
            [](P& v, const std::string& x) { v.joints.feed = x; })
        .parsed(
            "spindle_joint", {}, "", [](const P& v) { return v.joints.spindle; },
            [](P& v, const std::string& x) { v.joints.spindle = x; })
        .text("recognizer", &P::recognizer_class)
        .pairs("recognizer_params", &P::recognizer_params)
        .flag("unsafe_allow_disabled_watchdogs", &P::unsafe_allow_disabled_watchdogs);
    return d;
  }();
  return t;
}

int StateRecognizerNodeParams::axisIndex() const { return forceAxisIndex(axis); }

double StateRecognizerNodeParams::axisSign() const { return forceAxisSign(axis); }

bool StateRecognizerNodeParams::paperClass() const {
  return recognizer_class == "pedicle_drilling/PaperRecognizer";
}

std::vector<std::string> StateRecognizerNodeParams::paperSettingNames() const {
  std::vector<std::string> names;
  if (!paperClass()) return names;
  for (const auto& [name, value] : recognizer_params) names.push_back(name);
  return names;
}

core::RecognizerParams StateRecognizerNodeParams::recognizerInUse() const {
  core::RecognizerParams p = recognizer;
  for (const auto& [name, value] : paperClass() ? recognizer_params : core::TextPairs()) {
    try {
      p.set(name, value);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("recognizer_params/" + std::string(e.what()));
    }
  }
  return p;
}

std::vector<std::string> StateRecognizerNodeParams::disabledWatchdogs() const {
  std::vector<std::string> off;
  if (recognizerInUse().cancellous_deadline == 0) {
    off.push_back("cancellous_deadline = 0 (no bound on the cancellous layer's confirmation)");
  }
  return off;
}

void StateRecognizerNodeParams::validate() const {
  table().validate(*this);
  if (joints.feed.empty()) throw std::invalid_argument("feed_joint: must name a joint");
  if (joints.spindle.empty()) throw std::invalid_argument("spindle_joint: must name a joint");
  const core::RecognizerParams in_use = recognizerInUse();
  refuseDisabledWatchdogs(disabledWatchdogs(), unsafe_allow_disabled_watchdogs);
  try {
    in_use.validate();
  } catch (const std::invalid_argument& e) {
    // A check between fields names the first field: its key in recognizer_params if set there.
    const std::string what = e.what();
    const std::string field = what.substr(0, what.find_first_of(" :="));
    const std::vector<std::string> mapped = paperSettingNames();
    if (std::find(mapped.begin(), mapped.end(), field) == mapped.end()) throw;
    throw std::invalid_argument("recognizer_params/" + what);
  }
}

// ---------------------------------------------------------------------------------------------

const ParamTable<SafetyMonitorNodeParams>& SafetyMonitorNodeParams::table() {
  static const ParamTable<SafetyMonitorNodeParams> t = [] {
    using P = SafetyMonitorNodeParams;
    ParamTable<P> d;
    d.include(core::SupervisorParams::table(), &P::supervisor)
        .number("check_rate_hz", &P::check_rate_hz, Range::aboveUpTo(0, 10000), "Hz")
        .number("diagnostic_period_s", &P::diagnostic_period_s, Range::aboveUpTo(0, 60), "s")
        .number("expected_force_rate_hz", &P::expected_force_rate_hz, Range::aboveUpTo(0, 100000),
                "Hz")
        .number("expected_tracker_rate_hz", &P::expected_tracker_rate_hz,
                Range::aboveUpTo(0, 10000), "Hz")
        .number("rate_tolerance", &P::rate_tolerance, Range::fromBelow(0, 1))
        .include(core::DrillGuardParams::table(), &P::guard)
        .flag("unsafe_allow_disabled_watchdogs", &P::unsafe_allow_disabled_watchdogs);
    return d;
  }();
  return t;
}

std::vector<std::string> SafetyMonitorNodeParams::disabledWatchdogs() const {
  const core::SafetyParams& s = supervisor.safety;
  std::vector<std::string> off;
  const auto inf = [&off](double value, const char* name, const char* what) {
    if (std::isinf(value)) off.push_back(std::string(name) + " = inf (" + what + ")");
  };
  inf(s.force_timeout_s, "force_timeout_s", "a silent F/T sensor goes unnoticed");
  inf(s.tracker_timeout_s, "tracker_timeout_s", "a silent tracker goes unnoticed");
  inf(s.prediction_timeout_s, "prediction_timeout_s",
      "a missing prediction skips the position check H1");
  inf(s.force_stuck_s, "force_stuck_s", "a frozen F/T sensor goes unnoticed");
  return off;
}

void SafetyMonitorNodeParams::validate() const {
  table().validate(*this);
  refuseDisabledWatchdogs(disabledWatchdogs(), unsafe_allow_disabled_watchdogs);
  supervisor.validate();
  guard.validate();
  if (1.0 / check_rate_hz > 0.5 * supervisor.safety.force_timeout_s) {
    throw std::invalid_argument(
        "check_rate_hz is too low to check force_timeout_s (needs at least 2 checks per "
        "timeout)");
  }
}

// ---------------------------------------------------------------------------------------------

const ParamTable<CompensationPlannerNodeParams>& CompensationPlannerNodeParams::table() {
  static const ParamTable<CompensationPlannerNodeParams> t = [] {
    using P = CompensationPlannerNodeParams;
    ParamTable<P> d;
    d.text("patient_model_path", &P::patient_model_path)
        .text("urdf_path", &P::urdf_path, true)
        .text("arm_base_link", &P::arm_base_link)
        .text("arm_tip_link", &P::arm_tip_link)
        .include(core::TrialSequencerParams::table(), &P::sequencer)
        .number("feed_home_m", &P::feed_home_m, Range::closed(0, 0.5), "m")
        .text("world_frame", &P::world_frame)
        .text("tip_link", &P::tip_link)
        .parsed(
            "thrust_axis", forceAxes(), "", [](const P& v) { return v.thrust_axis; },
            [](P& v, const std::string& x) { v.thrust_axis = x; })
        .names("trial_start_services", &P::trial_start_services)
        .number("trial_start_timeout_s", &P::trial_start_timeout_s, Range::aboveUpTo(0, 60), "s")
        .text("monitor_status_name", &P::monitor_status_name)
        .text("compensator", &P::compensator_class)
        .pairs("compensator_params", &P::compensator_params)
        .number("heartbeat_period_s", &P::heartbeat_period_s, Range::closed(0.001, 0.1), "s")
        .number("breath_timeout_periods", &P::breath_timeout_periods, Range::aboveUpTo(1, 10),
                "breath periods")
        .parsed(
            "trajectory_interface", {"topic", "action"}, "",
            [](const P& v) { return v.trajectory_interface; },
            [](P& v, const std::string& x) { v.trajectory_interface = x; })
        .number("action_server_timeout_s", &P::action_server_timeout_s, Range::aboveUpTo(0, 60),
                "s")
        .flag("unsafe_allow_disabled_watchdogs", &P::unsafe_allow_disabled_watchdogs);
    return d;
  }();
  return t;
}

std::vector<std::string> CompensationPlannerNodeParams::disabledWatchdogs() const {
  const core::TrialSequencerParams& s = sequencer;
  std::vector<std::string> off;
  const auto zero = [&off](double value, const char* name, const char* what) {
    if (value == 0.0) off.push_back(std::string(name) + " = 0 (" + what + ")");
  };
  zero(s.recognizer_timeout_s, "recognizer_timeout_s", "a silent recognizer goes unnoticed");
  zero(s.monitor_timeout_s, "monitor_timeout_s", "a silent safety monitor goes unnoticed");
  if (!s.controller_watch.enabled) {
    off.push_back("controller_watch/enabled = false (no closed loop on the controllers)");
  }
  zero(s.outer_cortical_max_mm, "outer_cortical_max_mm", "no bound on the outer layer");
  zero(s.cancellous_max_mm, "cancellous_max_mm", "no bound on the cancellous layer");
  if (!s.depth_limit.require_plan) {
    off.push_back(
        "depth_limit/require_plan = false (a trial without a drilling plan has no depth limit)");
  }
  return off;
}

void CompensationPlannerNodeParams::validate() const {
  // Every sequencer field a parameter sets is in the table (included); the sequencer's other
  // checks need the URDF (joints, feed limits, drill axis) and run when makeSequencer makes it.
  table().validate(*this);
  refuseDisabledWatchdogs(disabledWatchdogs(), unsafe_allow_disabled_watchdogs);
}

void refuseDisabledWatchdogs(const std::vector<std::string>& disabled, bool allowed) {
  if (allowed || disabled.empty()) return;
  throw std::invalid_argument(disabled.front() +
                              ": switches a watchdog off; refused unless "
                              "unsafe_allow_disabled_watchdogs is true (never where a patient is "
                              "drilled)");
}

// ---------------------------------------------------------------------------------------------

const ParamTable<FaultInjectorNodeParams>& FaultInjectorNodeParams::table() {
  static const ParamTable<FaultInjectorNodeParams> t = [] {
    ParamTable<FaultInjectorNodeParams> d;
    d.include(core::FaultParams::table(), &FaultInjectorNodeParams::faults)
        .names("controllers", &FaultInjectorNodeParams::controllers);
    return d;
  }();
  return t;
}

void FaultInjectorNodeParams::validate() const {
  table().validate(*this);
  faults.validate();
}

// ---------------------------------------------------------------------------------------------

std::vector<std::pair<std::string, std::vector<core::ParamInfo>>> nodeParameterDocs() {
  const CompensationPlannerNodeParams planner_defaults;
  std::vector<core::ParamInfo> planner =
      CompensationPlannerNodeParams::table().describe(planner_defaults);
  // The one parameter whose names come from the URDF (the arm's joints): read by the nodelet
  // once it knows them.
  core::ParamInfo pose;
  pose.name = "drilling_pose/<joint>";
  pose.kind = core::ParamKind::kDouble;
  pose.range = Range::closed(-2.0 * M_PI, 2.0 * M_PI);
  pose.unit = "rad";
  pose.default_text = "(required)";
  planner.insert(planner.begin() + 4, pose);
  // Each default from a named, default-constructed struct.
  const VentilatorNodeParams ventilator;
  const SimulatorNodeParams simulator;
  const MotionIdentificationParams identification;
  const StateRecognizerNodeParams recognizer;
  const SafetyMonitorNodeParams monitor;
  const FaultInjectorNodeParams faults;
  const TfPoseRelayNodeParams relay;
  const ForceTareNodeParams tare;
  const TrialActionNodeParams action;
  return {
      {"pedicle_drilling/Ventilator", VentilatorNodeParams::table().describe(ventilator)},
      {"pedicle_drilling/Simulator", SimulatorNodeParams::table().describe(simulator)},
      {"pedicle_drilling/MotionIdentification",
       MotionIdentificationParams::table().describe(identification)},
      {"pedicle_drilling/StateRecognizer", StateRecognizerNodeParams::table().describe(recognizer)},
      {"pedicle_drilling/SafetyMonitor", SafetyMonitorNodeParams::table().describe(monitor)},
      {"pedicle_drilling/CompensationPlanner", planner},
      {"pedicle_drilling/FaultInjector", FaultInjectorNodeParams::table().describe(faults)},
      {"pedicle_drilling/TfPoseRelay", TfPoseRelayNodeParams::table().describe(relay)},
      {"pedicle_drilling/ForceTare", ForceTareNodeParams::table().describe(tare)},
      {"pedicle_drilling/TrialAction", TrialActionNodeParams::table().describe(action)},
  };
}

}  // namespace pedicle_drilling
