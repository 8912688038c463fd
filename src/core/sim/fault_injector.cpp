#include "pedicle_drilling/core/sim/fault_injector.hpp"

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {

namespace {

struct FaultName {
  FaultKind kind;
  const char* name;
};

constexpr FaultName kFaultNames[] = {
    {FaultKind::kNone, "none"},
    {FaultKind::kForceSilent, "force_silent"},
    {FaultKind::kForceNaN, "force_nan"},
    {FaultKind::kForceInf, "force_inf"},
    {FaultKind::kForceSpike, "force_spike"},
    {FaultKind::kForceStuck, "force_stuck"},
    {FaultKind::kForceDrift, "force_drift"},
    {FaultKind::kTrackerSilent, "tracker_silent"},
    {FaultKind::kTrackerJump, "tracker_jump"},
    {FaultKind::kTrackerStale, "tracker_stale"},
    {FaultKind::kBreathingAmplitude, "breathing_amplitude"},
    {FaultKind::kBreathingRateUp, "breathing_rate_up"},
    {FaultKind::kBreathingRateDown, "breathing_rate_down"},
    {FaultKind::kCommandLost, "command_lost"},
    {FaultKind::kCommandDelayed, "command_delayed"},
    {FaultKind::kForceSaturated, "force_saturated"},
    {FaultKind::kForceAxisNaN, "force_axis_nan"},
    {FaultKind::kForceNegInf, "force_neg_inf"},
    {FaultKind::kTrackerOcclusion, "tracker_occlusion"},
    {FaultKind::kStopLost, "stop_lost"},
    {FaultKind::kPlannerKilled, "planner_killed"},
    {FaultKind::kMonitorKilled, "monitor_killed"},
    {FaultKind::kControllerAborted, "controller_aborted"},
};

}  // namespace

const char* toString(FaultKind kind) {
  for (const FaultName& f : kFaultNames) {
    if (f.kind == kind) return f.name;
  }
  return "unknown";
}

std::vector<std::string> faultNames() {
  std::vector<std::string> names;
  for (const FaultName& f : kFaultNames) names.emplace_back(f.name);
  return names;
}

FaultKind parseFaultKind(const std::string& name) {
  std::string known;
  for (const FaultName& f : kFaultNames) {
    if (name == f.name) return f.kind;
    known += (known.empty() ? "" : ", ") + std::string(f.name);
  }
  throw std::invalid_argument("fault '" + name + "' is not one of: " + known);
}

const ParamTable<FaultParams>& FaultParams::table() {
  static const ParamTable<FaultParams> t = [] {
    ParamTable<FaultParams> d;
    d.number("spike_n", &FaultParams::spike_n, Range::closed(0, 1e4), "N")
        .number("drift_n_per_s", &FaultParams::drift_n_per_s, Range::closed(-100, 100), "N/s")
        .number("tracker_jump_m", &FaultParams::tracker_jump_m, Range::closed(-0.1, 0.1), "m")
        .number("command_delay_s", &FaultParams::command_delay_s, Range::closed(0, 10), "s")
        .integer("command_fault_count", &FaultParams::command_fault_count,
                 Range::closed(1, 1000000))
        .number("saturation_n", &FaultParams::saturation_n, Range::aboveUpTo(0, 1e4), "N")
        .number("saturation_noise_sd_n", &FaultParams::saturation_noise_sd_n, Range::closed(0, 10),
                "N")
        .integer("nan_axis", &FaultParams::nan_axis, Range::closed(0, 2))
        .integer("occlusion_samples", &FaultParams::occlusion_samples, Range::closed(1, 1000))
        .integer("occlusion_period_samples", &FaultParams::occlusion_period_samples,
                 Range::closed(2, 100000));
    return d;
  }();
  return t;
}

void FaultParams::validate() const {
  table().validate(*this);
  const auto check = [](double v, double low, double high, const char* name) {
    if (!(std::isfinite(v) && v >= low && v <= high)) {
      std::ostringstream os;
      os << name << ": must be in [" << low << ", " << high << "] (got " << v << ")";
      throw std::invalid_argument(os.str());
    }
  };
  // The breathing faults act in the closed-loop engine only (no ROS parameter).
  check(amplitude_factor, 0.0, 10.0, "amplitude_factor");
  check(rate_change_bpm, 0.0, 30.0, "rate_change_bpm");
  if (occlusion_samples >= occlusion_period_samples) {
    throw std::invalid_argument(
        "occlusion_samples: must be below occlusion_period_samples (a burst that recovers)");
  }
}

bool isForceFault(FaultKind k) {
  return k == FaultKind::kForceSilent || k == FaultKind::kForceNaN || k == FaultKind::kForceInf ||
         k == FaultKind::kForceSpike || k == FaultKind::kForceStuck ||
         k == FaultKind::kForceDrift || k == FaultKind::kForceSaturated ||
         k == FaultKind::kForceAxisNaN || k == FaultKind::kForceNegInf;
}

bool isTrackerFault(FaultKind k) {
  return k == FaultKind::kTrackerSilent || k == FaultKind::kTrackerJump ||
         k == FaultKind::kTrackerStale || k == FaultKind::kTrackerOcclusion;
}

bool isBreathingFault(FaultKind k) {
  return k == FaultKind::kBreathingAmplitude || k == FaultKind::kBreathingRateUp ||
         k == FaultKind::kBreathingRateDown;
}

bool isCommandFault(FaultKind k) {
  return k == FaultKind::kCommandLost || k == FaultKind::kCommandDelayed;
}

bool isStopFault(FaultKind k) { return k == FaultKind::kStopLost; }

bool isProcessFault(FaultKind k) {
  return k == FaultKind::kPlannerKilled || k == FaultKind::kMonitorKilled;
}

FaultInjector::FaultInjector(FaultParams params, std::uint64_t noise_seed)
    : params_(params), noise_(noise_seed) {
  params_.validate();
}

void FaultInjector::arm(FaultKind kind) {
  kind_ = kind;
  pending_ = false;
  injected_ = false;
  spent_ = false;
  t_injected_ = 0.0;
  counts_ = FaultCounts();
  tracker_samples_ = 0;
}

void FaultInjector::inject(double t) {
  if (kind_ == FaultKind::kNone || injected_ || pending_) return;
  t_injected_ = t;
  if (isCommandFault(kind_)) {
    pending_ = true;
    remaining_commands_ = params_.command_fault_count;
  } else {
    injected_ = true;
  }
}

bool FaultInjector::force(double t, Eigen::Vector3d* force) {
  if (!injected_ || !isForceFault(kind_)) return true;
  ++counts_.force_altered;  // undone below for the samples a fault leaves as they are
  switch (kind_) {
    case FaultKind::kForceSilent:
      --counts_.force_altered;
      ++counts_.force_dropped;
      return false;
    case FaultKind::kForceNaN:
      force->setConstant(std::numeric_limits<double>::quiet_NaN());
      return true;
    case FaultKind::kForceInf:
      force->z() = std::numeric_limits<double>::infinity();
      return true;
    case FaultKind::kForceNegInf:
      force->z() = -std::numeric_limits<double>::infinity();
      return true;
    case FaultKind::kForceAxisNaN:
      (*force)[params_.nan_axis] = std::numeric_limits<double>::quiet_NaN();
      return true;
    case FaultKind::kForceSaturated:
      return saturate(force);
    case FaultKind::kForceSpike:
      if (spent_) --counts_.force_altered;
      if (!spent_) force->z() = params_.spike_n;
      spent_ = true;
      return true;
    case FaultKind::kForceStuck:
      if (!spent_) last_force_ = *force;  // the frozen sensor repeats the first faulty sample
      spent_ = true;
      *force = last_force_;
      return true;
    case FaultKind::kForceDrift:
      force->z() += params_.drift_n_per_s * (t - t_injected_);
      return true;
    default:
      return true;
  }
}

bool FaultInjector::saturate(Eigen::Vector3d* force) {
  const double range = params_.saturation_n;
  if (std::abs(force->z()) <= range) {  // within the range: the sample as it is
    --counts_.force_altered;
    return true;
  }
  force->z() = std::copysign(range, force->z()) + params_.saturation_noise_sd_n * noise_.normal();
  return true;
}

bool FaultInjector::occluded() {
  // A burst of occlusion_samples lost samples at the start of every occlusion_period_samples,
  // the first at the injection.
  return tracker_samples_++ % params_.occlusion_period_samples < params_.occlusion_samples;
}

bool FaultInjector::trackedPose(Eigen::Vector3d* position, Eigen::Quaterniond* orientation,
                                double* stamp) {
  const bool active = injected_ && isTrackerFault(kind_);
  const bool lost = active && (kind_ == FaultKind::kTrackerSilent ||
                               (kind_ == FaultKind::kTrackerOcclusion && occluded()));
  if (lost) {
    ++counts_.tracker_dropped;
    return false;
  }
  if (active && kind_ == FaultKind::kTrackerJump) {
    position->x() += params_.tracker_jump_m;
    ++counts_.tracker_altered;
  }
  if (active && kind_ == FaultKind::kTrackerStale && have_pose_) {
    *stamp = last_stamp_;  // the last pose again, with its old stamp
    *position = last_position_;
    *orientation = last_orientation_;
    ++counts_.tracker_altered;
  }
  have_pose_ = true;
  last_stamp_ = *stamp;
  last_position_ = *position;
  last_orientation_ = *orientation;
  return true;
}

double FaultInjector::command(double t) {
  if (!pending_ || spent_) return 0.0;
  if (!injected_) t_injected_ = t;  // the fault's time: its first command
  injected_ = true;
  if (--remaining_commands_ <= 0) {
    pending_ = false;
    spent_ = true;
  }
  if (kind_ == FaultKind::kCommandLost) {
    ++counts_.commands_lost;
    return -1.0;
  }
  ++counts_.commands_delayed;
  return params_.command_delay_s;
}

bool FaultInjector::stop() {
  if (!injected_ || kind_ != FaultKind::kStopLost) return true;
  ++counts_.stops_lost;
  return false;
}

}  // namespace pedicle_drilling::core
