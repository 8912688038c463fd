#include "pedicle_drilling/core/control/monitor_runtime.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace pedicle_drilling::core {

std::string monitorStopMessage(const SafetyVerdict& v) {
  return "stop and retreat: " + describe(v);
}

MonitorRuntime::MonitorRuntime(const SupervisorParams& supervisor, const DrillGuardParams& guard)
    : supervisor_(supervisor), guard_(guard) {}

void MonitorRuntime::onForce(double now, double stamp_s, double handled_s,
                             const Eigen::Vector3d& force) {
  force_stats_.observe(stamp_s, handled_s);
  supervisor_.onForce(now, force);
}

PairResult MonitorRuntime::onTracked(double now, double handled_s, const StampedPosition& tracked) {
  tracker_stats_.observe(tracked.stamp, handled_s);
  return supervisor_.onTracked(now, tracked);
}

std::optional<EnableBeat> MonitorRuntime::beat(double t) {
  const bool enable = guard_.enabled(t);
  if (enable == last_enable_ && t < next_beat_) return std::nullopt;
  EnableBeat beat;
  beat.enable = enable;
  beat.turned_off = !enable && last_enable_;
  last_enable_ = enable;
  next_beat_ = t + guard_.params().heartbeat_period_s;
  return beat;
}

PhaseChange MonitorRuntime::onPlannerPhase(double now, TrialPhase phase, bool running) {
  supervisor_.setTrialRunning(running);
  const bool drilling = phase == TrialPhase::kDrilling || phase == TrialPhase::kStopped;
  supervisor_.setDrilling(now, drilling);
  guard_.onPlannerPhase(now, running, drilling);
  PhaseChange change;
  change.trial_ended = phase == TrialPhase::kDone && last_phase_ != TrialPhase::kDone;
  change.retreat_ended = change.trial_ended && last_phase_ == TrialPhase::kRetreating;
  last_phase_ = phase;
  return change;
}

RetareCheck MonitorRuntime::checkRetare(double now) {
  last_retare_ = supervisor_.retareCheck(now);
  return *last_retare_;
}

std::optional<SafetyVerdict> MonitorRuntime::takeNewStop(double now) {
  std::optional<SafetyVerdict> v = supervisor_.takeNewStop();
  if (v) guard_.onMonitorStop(now);
  return v;
}

MonitorStatus MonitorRuntime::status() const {
  MonitorStatus s;
  const SafetyVerdict& v = supervisor_.verdict();
  if (v.stop) {
    s.level = MonitorStatus::Level::kError;
    s.message = monitorStopMessage(v);
  } else if (last_retare_ && last_retare_->drift) {
    // Stays until reset (the next trial's start): the last trial's force is not trusted.
    s.level = MonitorStatus::Level::kWarn;
    s.message = "re-tare check: " + last_retare_->message;
  } else {
    s.message = supervisor_.heardBoth() ? "monitoring" : "waiting for force/tracker";
  }
  s.values.emplace_back("reason", toString(v.reason));
  s.values.emplace_back("drives_enabled", last_enable_ ? "true" : "false");
  if (!guard_.reason().empty()) s.values.emplace_back("drill_guard", guard_.reason());
  // The planner's trial as this monitor last heard it: the status published when it heard the
  // trial end is the first "false" after a "true" (a campaign's record of its inputs).
  s.values.emplace_back("trial_running", supervisor_.trialRunning() ? "true" : "false");
  for (const auto& [name, stats] :
       {std::pair<std::string, const StreamStats*>("force", &force_stats_),
        {"tracker", &tracker_stats_}}) {
    s.values.emplace_back(name + "_samples", std::to_string(stats->count()));
    s.values.emplace_back(name + "_samples_missing", std::to_string(stats->missing()));
    s.values.emplace_back(name + "_delay_max_ms", std::to_string(1e3 * stats->maxDelay()));
  }
  if (last_retare_ && last_retare_->done) {
    s.values.emplace_back("retare_offset_n", std::to_string(last_retare_->offset_n));
  }
  return s;
}

std::string MonitorRuntime::resetRefusal() const {
  if (!guard_.plannerRunning()) return "";
  return "refused: the planner's trial is running; the monitor resets at the next trial's start";
}

void MonitorRuntime::reset(double now) {
  supervisor_.reset();
  supervisor_.setDrilling(now, guard_.plannerDrilling());  // the planner's phase stays
  guard_.reset();
  last_retare_.reset();
  force_stats_.reset();
  tracker_stats_.reset();
}

double MonitorRuntime::nextUsefulTime(double t, double check_rate_hz) const {
  const double tick = nextUsefulCheckTick(t, check_rate_hz, supervisor_.quietUntil());
  // The guard's next heartbeat, and its next deadline (the enable turns false there).
  const double guard_due = std::min(next_beat_, guard_.quietUntil() + 1e-3);
  return std::isfinite(tick) ? std::min(tick / check_rate_hz, guard_due) : guard_due;
}

bool MonitorRuntime::onCheckGrid(double t, double rate_hz) {
  const double x = t * rate_hz;
  return std::abs(x - std::round(x)) < 1e-6;
}

}  // namespace pedicle_drilling::core
