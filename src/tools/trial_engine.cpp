// trial_engine: closed-loop drilling trials on the core engine (core::ClosedLoopEngine), the
// campaign's default engine (`campaign --engine core`). Reads a JSON list of trials, runs each
// with the same planner, recognizer, safety monitor and simulation objects as the nodelets, and
// prints one JSON line per trial: {"trial": <the input>, "record": {...}} or
// {"trial": ..., "error": "..."} (an errored trial; the others go on).
//
//   trial_engine --trials FILE --drilling-pose q1,..,q6 [--models-dir DIR --model linear]
//                [--default-model FILE] [--bone-motion model|virtual_patient]
//                [--feed-rate 0.5] [--max-duration 60] [--urdf FILE] [--fault-* VALUE]
//
// --urdf and --default-model default to the package's urdf/workcell.urdf and
// config/patient_default.yaml, found at run time through rospack (the devel or the install
// space whose setup.bash was sourced).
//
// A trial may name a fault to inject ("fault": "force_silent", ...; doc/experiments.md, "Fault
// campaign"); its record then says when it took effect.
//
// `--trials -` reads the trials from stdin instead, one JSON object per line, and runs each as it
// arrives (its output line flushed before the next is read); end of input ends the run. The
// campaign feeds each of its trial_engine processes this way, the next trial to the process that
// finished one (no process idles while the other finishes a fixed half of the design).
// A line that is not a valid trial is exit 2 naming its line number (the trials before it ran).
//
// Command-line parsing: CLI11 (Debian libcli11-dev): header-only, typed options with ranges,
// --help, and a repeated single-value option is an error rather than silently ignored; the
// conventions shared by every tool are in tool_cli.hpp.
// Exit status: 0 (errored trials included), 2 bad options or input (nothing run).
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include <ros/package.h>

#include "pedicle_drilling/core/breathing/motion_model_io.hpp"
#include "pedicle_drilling/core/common/atomic_file.hpp"
#include "pedicle_drilling/core/common/text_parse.hpp"
#include "pedicle_drilling/core/sim/closed_loop_engine.hpp"
#include "pedicle_drilling/core/sim/patient_population.hpp"
#include "pedicle_drilling/ros/plugin_loader.hpp"
#include "tool_cli.hpp"

namespace pd = pedicle_drilling::core;
namespace tools = pedicle_drilling::tools;
using nlohmann::json;

namespace {

using pd::UsageError;

std::string readText(const std::string& path, const std::string& what) {
  std::ifstream in(path);
  if (!in) throw UsageError(what + " '" + path + "' cannot be read");
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

json recordToJson(const pd::EngineTrialRecord& r) {
  json states = json::array();
  for (const pd::EngineStateSample& s : r.states) {
    states.push_back({s.t, s.averaged_force, s.feature, s.state_name, s.last_key_point});
  }
  json key_points = json::array();
  for (const auto& kp : r.key_points) key_points.push_back({kp.first, kp.second});
  json truth = json::array();
  for (const pd::EngineTruthSample& s : r.truth) {
    truth.push_back({s.t, s.layer, s.max_depth_cut_m, s.residual_inner_cortical_m, s.breakthrough,
                     s.relative_ap_m, s.contact, s.contact_loss_count});
  }
  json stops = json::array();
  for (const pd::EngineStop& s : r.stops) stops.push_back({s.t, s.source, s.reason, s.retreat});
  json status = json::array();
  for (const auto& s : r.status) status.push_back({s.first, s.second});
  const pd::SimulationGroundTruth& g = r.last_truth;
  return {
      {"conditions",
       {{"volunteer_id", r.conditions.volunteer_id},
        {"amplitude_scale", r.conditions.patient_amplitude_scale},
        {"ventilator_rate_bpm", r.conditions.ventilator_rate_bpm},
        {"tidal_volume_ml", r.conditions.ventilator_tidal_volume_ml},
        {"force_noise_sd_n", r.conditions.force_noise_sd_n},
        {"arm_stiffness_scale", r.conditions.arm_stiffness_scale},
        {"inner_cortical_mm", r.inner_cortical_thickness_m * 1e3},
        {"patient_ap_slope_mm_per_ml", r.conditions.patient_ap_slope_mm_per_ml},
        {"patient_lag_s", r.conditions.patient_lag_s},
        {"patient_gain_change", r.conditions.patient_gain_change}}},
      {"last_truth",
       {{"breakthrough", g.breakthrough},
        {"residual_inner_cortical_m", g.residual_inner_cortical_m},
        {"max_depth_cut_m", g.max_depth_cut_m},
        {"inner_cortical_start_m", g.inner_cortical_start_m}}},
      {"states", states},
      {"key_points", key_points},
      {"truth_peaks_n", {r.truth_peak_outer_n, r.truth_peak_inner_n}},
      {"depth_limit",
       {{"estimate_error_max_m", std::isnan(r.depth_estimate_error_max_m)
                                     ? json(nullptr)
                                     : json(r.depth_estimate_error_max_m)},
        {"window_errors_m", r.depth_estimate_window_errors_m},
        {"plan_far_side_error_m", r.plan_far_side_error_m}}},
      {"controller_watch",
       {{"desired_ratio", r.watch_desired_ratio}, {"following_ratio", r.watch_following_ratio}}},
      {"retare",
       {{"done", r.retare.done},
        {"t", r.retare.t},
        {"samples", r.retare.samples},
        {"offset_n", r.retare.offset_n},
        {"drift", r.retare.drift},
        {"message", r.retare.message}}},
      {"tare",
       {{"samples", r.tare.samples},
        {"success", r.tare.success},
        {"t", r.tare.t},
        {"bias_n", {r.tare.bias[0], r.tare.bias[1], r.tare.bias[2]}},
        {"spread_n", r.tare.spread_n},
        {"message", r.tare.message}}},
      {"recognizer_stop_t",
       std::isnan(r.recognizer_stop_t) ? json(nullptr) : json(r.recognizer_stop_t)},
      {"truth", truth},
      {"stops", stops},
      {"status", status},
      {"fault",
       {{"name", pd::toString(r.fault.kind)},
        {"injected", r.fault.injected},
        {"t", r.fault.injected ? json(r.fault.t) : json(nullptr)},
        {"trigger_depth_m", r.fault.trigger_depth_m}}}};
}

/**
 * @brief The path of a file of the package (`relative` to its folder, as rospack finds it: the
 *        source folder in a devel space, share/pedicle_drilling in an install space), the
 *        default of `option`. @throws UsageError when rospack does not find the package.
 */
std::string packageFile(const std::string& relative, const std::string& option) {
  const std::string dir = ros::package::getPath("pedicle_drilling");
  if (dir.empty()) {
    throw UsageError(option + ": rospack does not find the package pedicle_drilling (for its " +
                     relative + "): source the setup.bash of its workspace, or give " + option);
  }
  return dir + "/" + relative;
}

/** @brief Settings of a recognizer or compensator class, name -> value as text. */
using PluginSettings = std::vector<std::pair<std::string, std::string>>;

/** @brief name=value strings as settings; @throws std::invalid_argument naming the bad one. */
PluginSettings parseSettings(const std::vector<std::string>& items, const std::string& option) {
  PluginSettings out;
  for (const std::string& kv : items) out.push_back(pd::parseNameValue(kv, option));
  return out;
}

const char* const kPaperRecognizer = "pedicle_drilling/PaperRecognizer";

/**
 * @brief The engine declares the simulated sensor's rate to the paper recognizer, as a launch
 *        line's force_rate_hz does for the nodelets: its own sensor_rate_hz is no setting here.
 * @throws std::invalid_argument naming sensor_rate_hz and the setting to use instead.
 */
void refuseDeclaredRate(const std::string& recognizer_class, const PluginSettings& settings) {
  if (recognizer_class != kPaperRecognizer) return;
  for (const auto& [name, value] : settings) {
    if (name == "sensor_rate_hz") {
      throw std::invalid_argument(
          "sensor_rate_hz: the core engine declares the simulated sensor's rate to the "
          "recognizer; set force_sensor_rate_hz (--simulator-param, the scenario's "
          "simulator_params) instead");
    }
  }
}

}  // namespace

namespace {

/** @brief Everything the command line sets. */
struct Options {
  std::string trials_path;
  std::string urdf_path;      // empty: packageFile("urdf/workcell.urdf")
  std::string default_model;  // empty: packageFile("config/patient_default.yaml")
  std::string models_dir;
  std::string model_kind = "linear";
  std::string bone_motion = "virtual_patient";
  std::vector<double> drilling_pose;
  double feed_rate = 0.5;
  double max_duration = 60.0;
  std::string segment_profile = "rest_to_rest";
  bool fixed_start = false;
  std::string recognizer_class = "pedicle_drilling/PaperRecognizer";
  std::vector<std::string> recognizer_params;
  std::string compensator_class = "pedicle_drilling/PaperCompensator";
  std::vector<std::string> compensator_params;
  std::vector<std::string> simulator_params;
  std::vector<std::string> planner_params;
  std::string protocol = "recognition";
  std::string samples_dir;   // empty: no per-sample records
  std::string profile_path;  // empty: no profile
  bool list_faults = false;
};

/** @brief One per-sample field of the dataset (doc/dataset.md): its name, NumPy type and value. */
struct SampleField {
  const char* name;
  const char* numpy_type;  // '<f8', '<i4' or '|u1'
  double (*value)(const pd::EngineSample&);
};
/** @brief The fields in the order they are written (pd_campaign.dataset.SAMPLE_FIELDS). */
constexpr SampleField kSampleFields[] = {
    {"t", "<f8", [](const pd::EngineSample& x) { return x.t; }},
    {"raw_force_n", "<f8", [](const pd::EngineSample& x) { return x.given.thrust_n; }},
    {"true_force_n", "<f8", [](const pd::EngineSample& x) { return x.true_force_n; }},
    {"averaged_force_n", "<f8", [](const pd::EngineSample& x) { return x.averaged_force_n; }},
    {"tip_depth_m", "<f8", [](const pd::EngineSample& x) { return x.tip_depth_m; }},
    {"max_depth_cut_m", "<f8", [](const pd::EngineSample& x) { return x.max_depth_cut_m; }},
    {"layer", "<i4", [](const pd::EngineSample& x) { return static_cast<double>(x.layer); }},
    {"contact", "|u1", [](const pd::EngineSample& x) { return x.contact ? 1.0 : 0.0; }},
    {"bone_ap_m", "<f8", [](const pd::EngineSample& x) { return x.bone_ap_m; }},
    {"predicted_ap_m", "<f8", [](const pd::EngineSample& x) { return x.predicted_ap_m; }},
    {"tracker_x_m", "<f8", [](const pd::EngineSample& x) { return x.given.tracker_m[0]; }},
    {"tracker_y_m", "<f8", [](const pd::EngineSample& x) { return x.given.tracker_m[1]; }},
    {"tracker_z_m", "<f8", [](const pd::EngineSample& x) { return x.given.tracker_m[2]; }},
    {"breath_phase", "<f8", [](const pd::EngineSample& x) { return x.breath_phase; }},
    {"tidal_volume_ml", "<f8", [](const pd::EngineSample& x) { return x.tidal_volume_ml; }},
    {"force_x_n", "<f8", [](const pd::EngineSample& x) { return x.given.force_n[0]; }},
    {"force_y_n", "<f8", [](const pd::EngineSample& x) { return x.given.force_n[1]; }},
    {"torque_x_nm", "<f8", [](const pd::EngineSample& x) { return x.given.torque_nm[0]; }},
    {"torque_y_nm", "<f8", [](const pd::EngineSample& x) { return x.given.torque_nm[1]; }},
    {"torque_z_nm", "<f8", [](const pd::EngineSample& x) { return x.given.torque_nm[2]; }},
    {"feed_depth_m", "<f8", [](const pd::EngineSample& x) { return x.given.feed_depth_m; }},
    {"spindle_rpm", "<f8", [](const pd::EngineSample& x) { return x.given.spindle_rpm; }},
    {"feed_command_m", "<f8", [](const pd::EngineSample& x) { return x.given.feed_command_m; }},
    {"tracker_stamp_s", "<f8", [](const pd::EngineSample& x) { return x.given.tracker_stamp; }},
};

template <typename T>
void appendLittleEndian(std::string* out, T value) {
  static_assert(std::is_trivially_copyable_v<T>);
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if constexpr (sizeof(T) > 1) {
    const std::uint16_t probe = 1;
    if (*reinterpret_cast<const std::uint8_t*>(&probe) == 0) std::reverse(bytes, bytes + sizeof(T));
  }
  out->append(bytes, sizeof(T));
}

/**
 * @brief The trial's samples as a NumPy .npy file (format 1.0) of one structured array whose
 *        fields are kSampleFields: numpy.load reads it, the columns named.
 */
std::string samplesToNpy(const std::vector<pd::EngineSample>& samples) {
  std::string header = "{'descr': [";
  for (const SampleField& f : kSampleFields) {
    header += std::string("('") + f.name + "', '" + f.numpy_type + "'), ";
  }
  header += "], 'fortran_order': False, 'shape': (" + std::to_string(samples.size()) + ",), }";
  // Magic (6) + version (2) + header length (2) + header + '\n', a multiple of 64 bytes.
  const std::size_t unpadded = 10 + header.size() + 1;
  header.append((64 - unpadded % 64) % 64, ' ');
  header += '\n';
  std::string out("\x93NUMPY\x01\x00", 8);
  appendLittleEndian(&out, static_cast<std::uint16_t>(header.size()));
  out += header;
  for (const pd::EngineSample& x : samples) {
    for (const SampleField& f : kSampleFields) {
      const double v = f.value(x);
      switch (f.numpy_type[1]) {
        case 'i':
          appendLittleEndian(&out, static_cast<std::int32_t>(v));
          break;
        case 'u':
          appendLittleEndian(&out, static_cast<std::uint8_t>(v));
          break;
        default:
          appendLittleEndian(&out, v);
      }
    }
  }
  return out;
}

/** @brief Declares every option of the tool (its values go to *o and *config). */
void addOptions(CLI::App* app, Options* o, pd::EngineConfig* config) {
  app->add_option("--trials", o->trials_path,
                  "JSON list of trials: {trial_id, seed, case, rpm, ...}; '-': one trial per "
                  "line on stdin, each run as it arrives")
      ->required();
  app->add_option("--drilling-pose", o->drilling_pose,
                  "arm joint values of config/drilling_pose.yaml, comma-separated (rad)")
      ->required()
      ->delimiter(',')
      ->check(tools::finiteNumber())
      ->default_str("");  // none
  app->add_option("--urdf", o->urdf_path,
                  "workcell URDF (default: the package's urdf/workcell.urdf)");
  app->add_option("--default-model", o->default_model,
                  "patient model of the stationary case (default: the package's "
                  "config/patient_default.yaml)");
  app->add_option("--models-dir", o->models_dir,
                  "identified volunteer models volunteer_<id>_<model>.yaml (moving cases)");
  app->add_option("--model", o->model_kind, "linear | hysteresis")
      ->check(CLI::IsMember({"linear", "hysteresis"}));
  app->add_option("--bone-motion", o->bone_motion, "model | virtual_patient")
      ->check(CLI::IsMember({"model", "virtual_patient"}));
  app->add_option("--segment-profile", o->segment_profile,
                  "the planner's ~segment_profile: rest_to_rest (the paper's) | exact")
      ->check(CLI::IsMember({"rest_to_rest", "exact"}));
  app->add_option("--command-delay-s", config->delays.command_to_arm_s,
                  "planner command -> arm controller transport delay, s")
      ->check(tools::finiteNumber(0.0, 1.0));
  app->add_option("--force-delay-s", config->delays.force_to_recognizer_s,
                  "force sensor -> recognizer transport delay, s")
      ->check(tools::finiteNumber(0.0, 1.0));
  app->add_option("--stop-delay-s", config->delays.stop_to_planner_s,
                  "recognizer/monitor stop -> planner transport delay, s")
      ->check(tools::finiteNumber(0.0, 1.0));
  app->add_option("--command-jitter-s", config->delays.command_jitter_s,
                  "extra command delay, uniform in [0, this] per command (drawn from the seed; "
                  "the order kept), s")
      ->check(tools::finiteNumber(0.0, 1.0));
  app->add_option("--tracker-delay-s", config->delays.tracker_to_pipeline_s,
                  "tracker -> planner and monitor transport delay (the stamp kept), s")
      ->check(tools::finiteNumber(0.0, 1.0));
  app->add_option("--pre-trial-s", config->pre_trial_s,
                  "sim time from the reset to the earliest trial start, s")
      ->check(tools::finiteNumber(0.0, 60.0));
  app->add_option("--truth-rate-hz", config->ground_truth_rate_hz,
                  "rate of the recorded ground truth (plus every layer change), Hz")
      ->check(tools::finiteNumber(1.0, 1000.0));
  app->add_flag(
      "--fixed-start", o->fixed_start,
      "start exactly --pre-trial-s after the reset (no breath phase drawn from the seed)");
  app->add_option("--feed-rate", o->feed_rate, "feed rate, mm/s")
      ->check(tools::finiteNumber(0.01, 10.0));
  app->add_option("--max-duration", o->max_duration, "sim time after which a trial is ended, s")
      ->check(tools::finiteNumber(1.0, 3600.0));
  // Sizes of the injected faults (a trial's "fault" key names the fault; doc/experiments.md).
  pd::FaultParams& faults = config->faults;
  app->add_option("--fault-spike-n", faults.spike_n, "thrust of the force_spike sample, N")
      ->check(tools::finiteNumber());
  app->add_option("--fault-drift-n-per-s", faults.drift_n_per_s, "force_drift rate, N/s")
      ->check(tools::finiteNumber());
  app->add_option("--fault-tracker-jump-m", faults.tracker_jump_m, "tracker_jump size, m")
      ->check(tools::finiteNumber());
  app->add_option("--fault-amplitude-factor", faults.amplitude_factor,
                  "breathing_amplitude factor on the AP displacement")
      ->check(tools::finiteNumber());
  app->add_option("--fault-rate-change-bpm", faults.rate_change_bpm,
                  "breathing_rate_up/down change, breaths/min")
      ->check(tools::finiteNumber());
  app->add_option("--fault-command-delay-s", faults.command_delay_s, "command_delayed delay, s")
      ->check(tools::finiteNumber());
  app->add_option("--fault-command-count", faults.command_fault_count,
                  "consecutive commands a command fault hits (1: the next one)");
  app->add_option("--fault-saturation-n", faults.saturation_n,
                  "force_saturated: the thrust's range, N")
      ->check(tools::finiteNumber());
  app->add_option("--fault-saturation-noise-sd-n", faults.saturation_noise_sd_n,
                  "force_saturated: noise SD of a clipped sample, N")
      ->check(tools::finiteNumber());
  app->add_option("--fault-nan-axis", faults.nan_axis, "force_axis_nan: 0 x, 1 y, 2 z");
  app->add_option("--fault-occlusion-samples", faults.occlusion_samples,
                  "tracker_occlusion: tracker samples lost per burst");
  app->add_option("--fault-occlusion-period-samples", faults.occlusion_period_samples,
                  "tracker_occlusion: tracker samples from one burst's start to the next");
  app->add_option("--recognizer", o->recognizer_class,
                  "drilling-state recognizer class (built-in or pluginlib; doc/plugins.md)");
  app->add_option("--recognizer-param", o->recognizer_params,
                  "name=value for the recognizer (repeatable; the paper recognizer's default: "
                  "config/recognizer.yaml's values are its defaults; its sensor_rate_hz is the "
                  "simulated sensor's, --simulator-param force_sensor_rate_hz)");
  app->add_option("--compensator", o->compensator_class,
                  "motion compensator class (built-in or pluginlib; doc/plugins.md)");
  app->add_option("--compensator-param", o->compensator_params,
                  "name=value for the compensator (repeatable)");
  app->add_option("--protocol", o->protocol,
                  "recognition (the recognizer stops the drill) or peak_forces (it observes; the "
                  "drill goes through the inner layer: the paper's Sec. V-D force trials)")
      ->check(CLI::IsMember({"recognition", "peak_forces"}));
  app->add_option("--simulator-param", o->simulator_params,
                  "name=value for the simulation, named as the Simulator nodelet's parameters "
                  "(repeatable; e.g. trial_distribution/patient/amplitude_scale_sd=0.2; `rosrun "
                  "pedicle_drilling param_docs --node pedicle_drilling/Simulator` lists them)");
  app->add_option("--planner-param", o->planner_params,
                  "name=value for the trial sequence, named as the CompensationPlanner nodelet's "
                  "parameters (repeatable; e.g. stop_hold_s=0; `rosrun pedicle_drilling param_docs "
                  "--node pedicle_drilling/CompensationPlanner` lists them)");
  app->add_option("--profile", o->profile_path,
                  "write where the trials' wall time went, by component, to FILE (JSON: trials, "
                  "sim_s, wall_s per component; the profile of make bench)");
  app->add_option("--samples-dir", o->samples_dir,
                  "write every force-sensor sample of a trial to DIR/<trial_id>.npy (the "
                  "labelled dataset, doc/dataset.md)")
      ->check(CLI::ExistingDirectory);
  app->add_flag("--list-faults", o->list_faults, "print the faults a trial may name, one per line");
  app->footer("Faults: " + [] {
    std::string names;
    for (const std::string& n : pd::faultNames()) names += (names.empty() ? "" : ", ") + n;
    return names;
  }());
}

int printFaults() {
  for (const std::string& n : pd::faultNames()) std::cout << n << "\n";
  return 0;
}

/**
 * @brief --check-recognizer / --check-compensator CLASS [name=value ...]: load and configure it,
 *        nothing run (the campaign asks before it writes anything). Exit code.
 */
int checkPlugin(int argc, char** argv) {
  const bool recognizer = std::string(argv[1]) == "--check-recognizer";
  try {
    const PluginSettings settings =
        parseSettings(std::vector<std::string>(argv + 3, argv + argc), "parameter");
    if (recognizer) {
      refuseDeclaredRate(argv[2], settings);
      pedicle_drilling::RecognizerLoader loader;
      std::cout << loader.create(argv[2], settings)->describe() << "\n";
    } else {
      pedicle_drilling::CompensatorLoader loader;
      std::cout << loader.create(argv[2], settings)->describe() << "\n";
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "trial_engine: --" << (recognizer ? "recognizer " : "compensator ") << argv[2]
              << ": " << e.what() << "\n";
    return 2;
  }
}

/**
 * @brief Sets NAME=VALUE items on *params by P's declaration (P::table(), the nodelet's own).
 * @throws std::exception naming the bad item.
 */
template <class P>
void applySettings(const std::vector<std::string>& items, const std::string& option, P* params) {
  for (const auto& [name, value] : parseSettings(items, option)) {
    P::table().set(*params, name, value);
  }
}

/**
 * @brief `trial_engine --check-simulator|--check-planner NAME=VALUE...`: P's parameters set and
 *        checked by their declaration (as `option` would); exit 0, or 2 naming the bad one.
 */
template <class P, class Validate>
int checkSettings(int argc, char** argv, const std::string& option, Validate validate) {
  try {
    P params;
    applySettings(std::vector<std::string>(argv + 2, argv + argc), argv[1], &params);
    validate(params);
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "trial_engine: " << option << ": " << e.what() << "\n";
    return 2;
  }
}

/** @brief The trial sequence's declared ranges (the arm joints come from the URDF later). */
void validatePlanner(const pd::TrialSequencerParams& p) {
  pd::TrialSequencerParams::table().validate(p);
}

/** @brief One trial of the input checked. @throws UsageError naming what is wrong. */
void checkTrial(const json& t) {
  if (!t.is_object()) throw UsageError("--trials: a trial is not a JSON object");
  for (const char* key : {"trial_id", "seed", "case", "rpm"}) {
    if (!t.contains(key)) {
      throw UsageError("--trials: a trial has no '" + std::string(key) + "'");
    }
  }
  if (t.contains("fault")) {
    if (!t.at("fault").is_string()) throw UsageError("--trials: fault must be a string");
    try {
      pd::parseFaultKind(t.at("fault").get<std::string>());
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--trials: ") + e.what());
    }
  }
  if (!t.at("seed").is_number_unsigned()) {
    throw UsageError("--trials: seed " + t.at("seed").dump() + " is not an integer in [0, 2^64)");
  }
}

/** @brief The --trials file, every trial checked. @throws UsageError naming what is wrong. */
json readTrials(const std::string& path) {
  json trials;
  try {
    trials = json::parse(readText(path, "--trials"));
  } catch (const json::parse_error& e) {
    throw UsageError("--trials '" + path + "' is not JSON: " + e.what());
  }
  if (!trials.is_array()) throw UsageError("--trials '" + path + "' is not a list");
  for (const json& t : trials) checkTrial(t);
  return trials;
}

/** @brief Runs one trial and writes its JSON line (the patient model per volunteer, read once
 * into `models`). */
void runTrial(const json& t, const Options& o, const pd::EngineConfig& config,
              const pd::PatientModel& stationary_model, pd::ClosedLoopEngine* engine,
              std::map<std::string, pd::PatientModel>* models_read) {
  std::map<std::string, pd::PatientModel>& models = *models_read;
  {
    json out = {{"trial", t}};
    try {
      pd::EngineTrialSpec spec;
      spec.seed = t.at("seed").get<std::uint64_t>();
      spec.mode = t.at("case").get<std::string>();
      spec.spindle_rpm = t.at("rpm").get<double>();
      spec.feed_rate_mm_s = o.feed_rate;
      spec.max_duration_s = o.max_duration;
      spec.fault = pd::parseFaultKind(t.value("fault", std::string("none")));
      spec.protocol = pd::parseTrialProtocol(o.protocol);
      spec.record_samples = !o.samples_dir.empty();
      const bool moving = spec.mode != "stationary";
      pd::PatientModel patient = stationary_model;
      if (moving && config.simulation.population.enabled) {
        // A population patient: the model identified from the patient's own identification
        // recording (the paper's pipeline), once per seed (the cases of a seed share it).
        if (o.bone_motion == "model") {
          throw std::runtime_error(
              "population/enabled needs --bone-motion virtual_patient (the paper's bench plays "
              "the model)");
        }
        const std::string key = "population:" + std::to_string(spec.seed);
        auto it = models.find(key);
        if (it == models.end()) {
          const pd::PopulationPatient drawn =
              pd::drawPopulationPatient(spec.seed, config.simulation.population);
          if (models.size() > 64) models.clear();  // a stream of seeds: keep the memory bounded
          it = models.emplace(key, pd::identifyPopulationPatient(drawn).model).first;
        }
        patient = it->second;
      } else if (moving) {
        if (o.models_dir.empty()) {
          throw std::runtime_error("--models-dir is needed for the moving cases");
        }
        // The simulator's patient is the volunteer the seed draws; use that volunteer's model
        // identified beforehand from its own recording, as in the paper.
        const pd::DrillingSimulationParams& sim = config.simulation;
        const int volunteer = pd::drawTrialConditions(spec.seed, sim.variability, sim.ventilator,
                                                      sim.sensor.force_noise_sd_n)
                                  .volunteer_id;
        const std::string path =
            o.models_dir + "/volunteer_" + std::to_string(volunteer) + "_" + o.model_kind + ".yaml";
        auto it = models.find(path);
        if (it == models.end()) it = models.emplace(path, pd::readModelYaml(path)).first;
        patient = it->second;
        if (o.bone_motion == "model") {
          const pd::AxisModelRecord& ap = patient.axes[static_cast<int>(pd::Axis::kAP)];
          spec.bone_motion = pd::BoneMotionModel{ap.model.q1, ap.model.q2};
        }
      }
      spec.model = patient.motionModel();
      const pd::EngineTrialRecord record = engine->run(spec);
      const pd::AxisModelRecord& model_ap = patient.axes[static_cast<int>(pd::Axis::kAP)];
      if (spec.record_samples) {
        const std::string id = t.at("trial_id").get<std::string>();
        if (id.empty() || id.find('/') != std::string::npos || id[0] == '.') {
          throw std::runtime_error("trial_id '" + id + "' cannot name a samples file");
        }
        pd::writeFileAtomically(o.samples_dir + "/" + id + ".npy", samplesToNpy(record.samples));
      }
      out["record"] = recordToJson(record);
      out["record"]["protocol"] = o.protocol;
      // The planner's model of the AP axis: its slope and the R^2 of its identification.
      out["record"]["model_ap"] = {{"q1_mm_per_ml", model_ap.model.q1}, {"r2", model_ap.r2}};
    } catch (const std::exception& e) {
      out["error"] = e.what();
    }
    std::cout << out.dump() << "\n" << std::flush;
  }
}

/** @brief Runs the trials of a --trials file, in order. */
void runTrials(const json& trials, const Options& o, const pd::EngineConfig& config,
               const pd::PatientModel& stationary_model, pd::ClosedLoopEngine* engine) {
  std::map<std::string, pd::PatientModel> models;
  for (const json& t : trials) runTrial(t, o, config, stationary_model, engine, &models);
}

/** @brief `--trials -`: runs each trial as its line arrives on stdin, until the end of input.
 * @throws UsageError naming the first line that is not a valid trial (those before it ran). */
void runStreamedTrials(const Options& o, const pd::EngineConfig& config,
                       const pd::PatientModel& stationary_model, pd::ClosedLoopEngine* engine) {
  std::map<std::string, pd::PatientModel> models;
  std::string line;
  for (long number = 1; std::getline(std::cin, line); ++number) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    json t;
    try {
      t = json::parse(line);
      checkTrial(t);
    } catch (const json::parse_error& e) {
      throw UsageError("--trials -: line " + std::to_string(number) + " is not JSON: " + e.what());
    } catch (const UsageError& e) {
      throw UsageError("line " + std::to_string(number) + ": " + e.what());
    }
    runTrial(t, o, config, stationary_model, engine, &models);
  }
}

/**
 * @brief The classes of --recognizer and --compensator with their settings, loaded and
 *        configured once: the paper recognizer into config->recognizer, declared at the simulated
 *        sensor's rate; another class as the factory of each trial's instance (the loaders must
 *        outlive the engine). @return false, the refusal printed, when a class or a setting is
 *        refused.
 */
bool configureClasses(const Options& o, pd::EngineConfig* config,
                      pedicle_drilling::RecognizerLoader* recognizer_loader,
                      pedicle_drilling::CompensatorLoader* compensator_loader) {
  PluginSettings recognizer_settings;
  PluginSettings compensator_settings;
  std::string option = "--recognizer " + o.recognizer_class;
  try {
    recognizer_settings = parseSettings(o.recognizer_params, "--recognizer-param");
    refuseDeclaredRate(o.recognizer_class, recognizer_settings);
    if (o.recognizer_class == kPaperRecognizer) {
      for (const auto& [name, value] : recognizer_settings) config->recognizer.set(name, value);
      config->recognizer.sensor_rate_hz = config->simulation.sensor.output_rate_hz;
      config->recognizer.validate();
    } else {
      recognizer_loader->create(o.recognizer_class, recognizer_settings);
    }
    option = "--compensator " + o.compensator_class;
    compensator_settings = parseSettings(o.compensator_params, "--compensator-param");
    compensator_loader->create(o.compensator_class, compensator_settings);
  } catch (const std::exception& e) {
    std::cerr << "trial_engine: " << option << ": " << e.what() << "\n";
    return false;
  }
  if (o.recognizer_class != kPaperRecognizer) {
    config->make_recognizer = [recognizer_loader, &o, recognizer_settings]() {
      return recognizer_loader->create(o.recognizer_class, recognizer_settings);
    };
  }
  if (o.compensator_class != "pedicle_drilling/PaperCompensator") {
    config->make_compensator = [compensator_loader, &o, compensator_settings]() {
      return compensator_loader->create(o.compensator_class, compensator_settings);
    };
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Closed-loop drilling trials on the core engine (JSON lines on stdout)",
               "trial_engine"};
  tools::applyConventions(&app);
  Options o;
  pd::EngineConfig config;
  addOptions(&app, &o, &config);
  // Alone, --list-faults needs none of the required options.
  if (argc == 2 && std::string(argv[1]) == "--list-faults") return printFaults();
  if (argc >= 2 && std::string(argv[1]) == "--check-simulator") {
    return checkSettings<pd::DrillingSimulationParams>(
        argc, argv, "--simulator-param",
        [](const pd::DrillingSimulationParams& p) { p.validate(); });
  }
  if (argc >= 2 && std::string(argv[1]) == "--check-planner") {
    return checkSettings<pd::TrialSequencerParams>(argc, argv, "--planner-param", validatePlanner);
  }
  if (argc >= 3 && (std::string(argv[1]) == "--check-recognizer" ||
                    std::string(argv[1]) == "--check-compensator")) {
    return checkPlugin(argc, argv);
  }
  if (const auto exit = tools::parseCommandLine(&app, argc, argv)) return *exit;
  if (o.list_faults) return printFaults();  // never silently ignored beside other options

  pd::parseSegmentProfile(o.segment_profile, &config.sequencer.compensation.segment_profile);
  config.draw_start_phase = !o.fixed_start;
  json trials;
  pd::PatientModel stationary_model;
  try {
    if (o.trials_path != "-") trials = readTrials(o.trials_path);
    if (o.urdf_path.empty()) o.urdf_path = packageFile("urdf/workcell.urdf", "--urdf");
    if (o.default_model.empty()) {
      o.default_model = packageFile("config/patient_default.yaml", "--default-model");
    }
    config.urdf_xml = readText(o.urdf_path, "--urdf");
    config.drilling_pose = o.drilling_pose;
    stationary_model = pd::readModelYaml(o.default_model);
  } catch (const UsageError& e) {
    std::cerr << "trial_engine: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "trial_engine: --default-model: " << e.what() << "\n";
    return 2;
  }
  // The simulation's parameters by the same declaration as the Simulator nodelet's.
  try {
    applySettings(o.simulator_params, "--simulator-param", &config.simulation);
    config.simulation.validate();
  } catch (const std::exception& e) {
    return tools::usageError(app, std::string("--simulator-param: ") + e.what());
  }
  // The trial sequence's parameters by the same declaration as the CompensationPlanner nodelet's.
  try {
    applySettings(o.planner_params, "--planner-param", &config.sequencer);
    validatePlanner(config.sequencer);
  } catch (const std::exception& e) {
    return tools::usageError(app, std::string("--planner-param: ") + e.what());
  }
  // The recognizer and compensator classes, loaded and configured once here so that a bad one is
  // exit 2 before any trial; each trial then gets fresh instances (the loaders outlive them).
  pedicle_drilling::RecognizerLoader recognizer_loader;
  pedicle_drilling::CompensatorLoader compensator_loader;
  if (!configureClasses(o, &config, &recognizer_loader, &compensator_loader)) return 2;
  pd::ComponentProfile profile;
  if (!o.profile_path.empty()) config.profile = &profile;
  std::unique_ptr<pd::ClosedLoopEngine> engine;
  try {
    engine = std::make_unique<pd::ClosedLoopEngine>(config);
  } catch (const std::exception& e) {
    std::cerr << "trial_engine: bad configuration: " << e.what() << "\n";
    return 2;
  }
  if (o.trials_path == "-") {
    try {
      runStreamedTrials(o, config, stationary_model, engine.get());
    } catch (const UsageError& e) {
      std::cerr << "trial_engine: " << e.what() << "\n";
      return 2;
    }
  } else {
    runTrials(trials, o, config, stationary_model, engine.get());
  }
  if (!o.profile_path.empty()) {
    json wall = json::object();
    for (int c = 0; c < static_cast<int>(pd::Component::kCount); ++c) {
      const auto component = static_cast<pd::Component>(c);
      wall[pd::ComponentProfile::name(component)] = profile.seconds(component);
    }
    const json out = {
        {"trials", profile.trials()}, {"sim_s", profile.simSeconds()}, {"wall_s", wall}};
    try {
      pd::writeFileAtomically(o.profile_path, out.dump(1) + "\n");
    } catch (const std::exception& e) {
      std::cerr << "trial_engine: --profile: " << e.what() << "\n";
      return 1;
    }
  }
  return 0;
}
