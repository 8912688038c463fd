// The drill guard (see drill_guard.hpp).
#include "pedicle_drilling/core/control/drill_guard.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace pedicle_drilling::core {

namespace {

std::string fmt(const char* f, double a, double b) {
  char buf[200];
  std::snprintf(buf, sizeof(buf), f, a, b);
  return buf;
}

}  // namespace

const ParamTable<DrillGuardParams>& DrillGuardParams::table() {
  static const ParamTable<DrillGuardParams> t = [] {
    ParamTable<DrillGuardParams> d;
    d.number("guard_heartbeat_period_s", &DrillGuardParams::heartbeat_period_s,
             Range::closed(0.001, 0.1), "s")
        .number("guard_planner_timeout_s", &DrillGuardParams::planner_timeout_s,
                Range::closed(0.002, 1.0), "s")
        .number("guard_stop_ack_timeout_s", &DrillGuardParams::stop_ack_timeout_s,
                Range::closed(0.001, 1.0), "s");
    return d;
  }();
  return t;
}

void DrillGuardParams::validate() const {
  table().validate(*this);
  if (!(planner_timeout_s > heartbeat_period_s)) {
    throw std::invalid_argument(
        "guard_planner_timeout_s: must be longer than guard_heartbeat_period_s (the planner "
        "beats at the guard's period)");
  }
}

DrillGuard::DrillGuard(const DrillGuardParams& params) : params_(params) { params_.validate(); }

void DrillGuard::onPlannerHeartbeat(double now) {
  if (std::isfinite(now)) last_planner_t_ = std::max(last_planner_t_, now);
}

void DrillGuard::onPlannerPhase(double now, bool running, bool drilling) {
  if (running && !running_) last_planner_t_ = now;  // the heartbeat is watched from now on
  running_ = running;
  drilling_ = drilling;
  if (!drilling) {
    stop_pending_ = false;  // the planner answered the stop (or has none)
  } else if (stopped_ && !stop_pending_) {
    // Drilling after the monitor's stop (a stop that came before the drilling, or one the
    // planner left the drilling for and came back): it must end within the same bound.
    stop_pending_ = true;
    stop_t_ = now;
  }
}

void DrillGuard::onMonitorStop(double now) {
  stopped_ = true;
  if (!drilling_ || stop_pending_) return;
  stop_pending_ = true;
  stop_t_ = now;
}

void DrillGuard::disable(const std::string& why) {
  if (disabled_) return;
  disabled_ = true;
  reason_ = why;
}

bool DrillGuard::enabled(double now) {
  if (disabled_) return false;
  if (!std::isfinite(now)) {
    disable("non-finite guard time");
    return false;
  }
  if (running_ && now - last_planner_t_ > params_.planner_timeout_s) {
    disable(fmt("planner_lost: no planner heartbeat for %.3f s > %.3f s while its trial runs",
                now - last_planner_t_, params_.planner_timeout_s));
  } else if (stop_pending_ && now - stop_t_ > params_.stop_ack_timeout_s) {
    disable(
        fmt("stop_unanswered: the planner still drills %.3f s after the monitor's stop "
            "(> %.3f s)",
            now - stop_t_, params_.stop_ack_timeout_s));
  }
  return !disabled_;
}

double DrillGuard::quietUntil() const {
  double t = std::numeric_limits<double>::infinity();
  if (disabled_) return t;
  if (running_) t = last_planner_t_ + params_.planner_timeout_s;
  if (stop_pending_) t = std::min(t, stop_t_ + params_.stop_ack_timeout_s);
  return t;
}

void DrillGuard::reset() {
  // The planner's phase and heartbeat are its own, not the monitor's: they stay watched.
  stopped_ = false;
  stop_pending_ = false;
  disabled_ = false;
  reason_.clear();
}

DriveGuardWatch::DriveGuardWatch(double timeout_s) : timeout_s_(timeout_s) {
  if (!(timeout_s > 0.0 && timeout_s <= 1.0)) {
    throw std::invalid_argument("drive_guard_timeout_s: must be in (0, 1] s");
  }
}

void DriveGuardWatch::onEnable(double now, bool enable) {
  heard_ = true;
  enable_ = enable;
  last_t_ = now;
}

bool DriveGuardWatch::allows(double now) const {
  return heard_ && enable_ && now - last_t_ <= timeout_s_;
}

std::string DriveGuardWatch::why(double now) const {
  if (!heard_) return "no drill_guard/enable heard yet";
  if (!enable_) return "the drill guard disabled the drives";
  if (now - last_t_ > timeout_s_) {
    return fmt("no drill_guard/enable for %.3f s > %.3f s", now - last_t_, timeout_s_);
  }
  return "";
}

void DriveGuardWatch::reset() {
  heard_ = false;
  enable_ = false;
  last_t_ = 0.0;
}

}  // namespace pedicle_drilling::core
