// Monitor of Algorithm 1 and the retreat planner.
#include "pedicle_drilling/core/control/safety_monitor.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {

namespace {

// Bound of the re-tare window's queue: 10 s (the longest window) at a 1 kHz sensor, also when
// time stands still.
constexpr std::size_t kMaxRetareSamples = 10000;

std::string fmt(const char* f, double a, double b, double c) {
  char buf[160];
  std::snprintf(buf, sizeof(buf), f, a, b, c);
  return buf;
}

}  // namespace

const ParamTable<SafetyParams>& SafetyParams::table() {
  static const ParamTable<SafetyParams> t = [] {
    const double inf = std::numeric_limits<double>::infinity();
    ParamTable<SafetyParams> d;
    d.number("position_threshold_m", &SafetyParams::position_threshold_m, Range::aboveUpTo(0, 0.1),
             "m")
        .number("force_threshold_n", &SafetyParams::force_threshold_N, Range::aboveUpTo(0, 1000),
                "N")
        .number("force_timeout_s", &SafetyParams::force_timeout_s, Range::aboveUpTo(0, inf), "s")
        .number("tracker_timeout_s", &SafetyParams::tracker_timeout_s, Range::aboveUpTo(0, inf),
                "s")
        .number("prediction_timeout_s", &SafetyParams::prediction_timeout_s,
                Range::aboveUpTo(0, inf), "s")
        .number("force_stuck_s", &SafetyParams::force_stuck_s, Range::aboveUpTo(0, inf), "s")
        .number("retare_max_offset_n", &SafetyParams::retare_max_offset_n, Range::closed(0, 100),
                "N")
        .number("retare_window_s", &SafetyParams::retare_window_s, Range::aboveUpTo(0, 10), "s");
    return d;
  }();
  return t;
}

void SafetyParams::validate() const { table().validate(*this); }

std::string describe(const SafetyVerdict& v) {
  return std::string(toString(v.reason)) + ": " + v.message;
}

const char* toString(SafetyVerdict::Reason r) {
  switch (r) {
    case SafetyVerdict::kNone:
      return "none";
    case SafetyVerdict::kPositionError:
      return "position_error";
    case SafetyVerdict::kForceExceeded:
      return "force_exceeded";
    case SafetyVerdict::kForceTimeout:
      return "force_timeout";
    case SafetyVerdict::kTrackerTimeout:
      return "tracker_timeout";
    case SafetyVerdict::kNaNInput:
      return "nan_input";
    case SafetyVerdict::kForceStuck:
      return "force_stuck";
    case SafetyVerdict::kPredictionLost:
      return "prediction_lost";
  }
  return "unknown";
}

SafetyMonitor::SafetyMonitor(const SafetyParams& params) : params_(params) { params_.validate(); }

void SafetyMonitor::reset() {
  verdict_ = SafetyVerdict();
  armed_ = false;
  have_force_ = false;
  have_tracker_ = false;
  expect_predictions_ = false;
  recent_forces_.clear();
}

void SafetyMonitor::expectPredictions(double t, bool expected) {
  if (expected && !expect_predictions_) last_compared_t_ = t;
  expect_predictions_ = expected;
}

bool SafetyMonitor::rejectPair(double t, const std::string& why) {
  if (!expect_predictions_) return false;
  trigger(SafetyVerdict::kPredictionLost, t, why);
  return true;
}

void SafetyMonitor::arm(double t) {
  if (armed_) return;
  armed_ = true;
  armed_t_ = t;
}

void SafetyMonitor::trigger(SafetyVerdict::Reason r, double t, const std::string& msg) {
  if (verdict_.stop) return;  // latched: keep the first cause
  verdict_.stop = true;
  verdict_.reason = r;
  verdict_.t = t;
  verdict_.message = msg;
}

void SafetyMonitor::onForce(double t, const Eigen::Vector3d& force) {
  if (!std::isfinite(t) || !force.allFinite()) {
    trigger(SafetyVerdict::kNaNInput, t, "non-finite force sample or time stamp");
    return;
  }
  arm(t);
  if (!have_force_ || force != last_force_) same_force_since_ = t;
  have_force_ = true;
  last_force_t_ = t;
  last_force_ = force;
  // Time that stands still or goes back (no /clock yet, a looping bag) restarts the window.
  if (!recent_forces_.empty() && t < recent_forces_.back().first) recent_forces_.clear();
  recent_forces_.emplace_back(t, force);
  while (recent_forces_.front().first < t - params_.retare_window_s ||
         recent_forces_.size() > kMaxRetareSamples) {
    recent_forces_.pop_front();
  }
  if (t - same_force_since_ > params_.force_stuck_s) {
    trigger(SafetyVerdict::kForceStuck, t,
            fmt("force unchanged (%.4f N) for %.3f s > %.3f s: sensor frozen", force.norm(),
                t - same_force_since_, params_.force_stuck_s));
  }
  const double n = force.norm();
  if (n > params_.force_threshold_N) {
    trigger(SafetyVerdict::kForceExceeded, t,
            fmt("force %.3f N > %.3f N at t=%.3f s", n, params_.force_threshold_N, t));
  }
}

RetareCheck SafetyMonitor::retareCheck(double t) const {
  RetareCheck c;
  c.t = t;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& [ts, f] : recent_forces_) {
    if (ts < t - params_.retare_window_s || ts > t) continue;
    sum += f;
    ++c.samples;
  }
  if (c.samples == 0) return c;
  c.done = true;
  c.offset_n = (sum / c.samples).norm();
  c.drift = params_.retare_max_offset_n > 0.0 && c.offset_n > params_.retare_max_offset_n;
  if (c.drift) {
    std::ostringstream os;
    os.setf(std::ios::fixed);
    os.precision(3);
    os << "force_offset: " << c.offset_n << " N from the tare after the retreat (mean of "
       << c.samples << " samples) > " << params_.retare_max_offset_n << " N: "
       << (verdict_.reason == SafetyVerdict::kForceStuck ? "the force sensor is frozen"
                                                         : "the force sensor drifted")
       << "; the trial's force-based stop is not to be trusted";
    c.message = os.str();
  }
  return c;
}

bool SafetyMonitor::finiteOrStop(double t, const Eigen::Vector3d& predicted_bone_pos,
                                 const Eigen::Vector3d& tracked_bone_pos) {
  if (std::isfinite(t) && predicted_bone_pos.allFinite() && tracked_bone_pos.allFinite()) {
    return true;
  }
  trigger(SafetyVerdict::kNaNInput, t, "non-finite tracker sample, prediction or time stamp");
  return false;
}

void SafetyMonitor::onTracked(double t, const Eigen::Vector3d& predicted_bone_pos,
                              const Eigen::Vector3d& tracked_bone_pos) {
  if (!finiteOrStop(t, predicted_bone_pos, tracked_bone_pos)) return;
  arm(t);
  const double e = (predicted_bone_pos - tracked_bone_pos).norm();
  if (e > params_.position_threshold_m) {
    trigger(SafetyVerdict::kPositionError, t,
            fmt("bone position error %.3f mm > %.3f mm at t=%.3f s", e * 1e3,
                params_.position_threshold_m * 1e3, t));
  }
  have_tracker_ = true;
  last_tracker_t_ = t;
}

void SafetyMonitor::comparePositions(double t, const Eigen::Vector3d& predicted_bone_pos,
                                     const Eigen::Vector3d& tracked_bone_pos) {
  if (!finiteOrStop(t, predicted_bone_pos, tracked_bone_pos)) return;
  arm(t);
  last_compared_t_ = t;  // H1 was checked (the prediction watch)
  const double e = (predicted_bone_pos - tracked_bone_pos).norm();
  if (e > params_.position_threshold_m) {
    trigger(SafetyVerdict::kPositionError, t,
            fmt("bone position error %.3f mm > %.3f mm at t=%.3f s", e * 1e3,
                params_.position_threshold_m * 1e3, t));
  }
}

const SafetyVerdict& SafetyMonitor::check(double t) {
  if (verdict_.stop) return verdict_;
  if (!std::isfinite(t)) {
    trigger(SafetyVerdict::kNaNInput, t, "non-finite check time");
    return verdict_;
  }
  arm(t);
  const double force_age = t - (have_force_ ? last_force_t_ : armed_t_);
  const double tracker_age = t - (have_tracker_ ? last_tracker_t_ : armed_t_);
  if (force_age > params_.force_timeout_s) {
    trigger(SafetyVerdict::kForceTimeout, t,
            fmt("no force sample for %.3f s > %.3f s at t=%.3f s", force_age,
                params_.force_timeout_s, t));
  } else if (tracker_age > params_.tracker_timeout_s) {
    trigger(SafetyVerdict::kTrackerTimeout, t,
            fmt("no fresh tracker sample for %.3f s > %.3f s at t=%.3f s", tracker_age,
                params_.tracker_timeout_s, t));
  } else if (expect_predictions_ && t - last_compared_t_ > params_.prediction_timeout_s) {
    trigger(SafetyVerdict::kPredictionLost, t,
            fmt("no predicted / tracked pair compared for %.3f s > %.3f s at t=%.3f s while "
                "drilling (prediction missing, stale or in another frame)",
                t - last_compared_t_, params_.prediction_timeout_s, t));
  }
  return verdict_;
}

double SafetyMonitor::quietUntil() const {
  if (verdict_.stop) return std::numeric_limits<double>::infinity();
  if (!armed_) return -std::numeric_limits<double>::infinity();
  // check(t) triggers when t - ref > timeout: not at t <= ref + timeout, up to the rounding of
  // the two sums (a caller keeps a margin: the monitor's nodelet asks for one check early).
  const double streams =
      std::min((have_force_ ? last_force_t_ : armed_t_) + params_.force_timeout_s,
               (have_tracker_ ? last_tracker_t_ : armed_t_) + params_.tracker_timeout_s);
  return expect_predictions_ ? std::min(streams, last_compared_t_ + params_.prediction_timeout_s)
                             : streams;
}

const ParamTable<RetreatParams>& RetreatParams::table() {
  static const ParamTable<RetreatParams> t = [] {
    ParamTable<RetreatParams> d;
    d.number("retreat_distance_m", &RetreatParams::distance_m, Range::aboveUpTo(0, 0.1), "m")
        .number("retreat_speed_m_s", &RetreatParams::speed_m_s, Range::aboveUpTo(0, 0.05), "m/s")
        .number("retreat_accel_m_s2", &RetreatParams::accel_m_s2, Range::aboveUpTo(0, 1), "m/s^2");
    return d;
  }();
  return t;
}

void RetreatParams::validate() const { table().validate(*this); }

RetreatMotion::RetreatMotion(double t0, const Eigen::Vector3d& start, const Eigen::Vector3d& target,
                             const TrapezoidProfile& profile)
    : segment_(t0, start, target, profile) {}

RetreatPlanner::RetreatPlanner(const RetreatParams& params) : params_(params) {
  params_.validate();
}

RetreatMotion RetreatPlanner::plan(double t0, const Eigen::Vector3d& tip,
                                   const Eigen::Vector3d& drill_axis) const {
  if (!std::isfinite(t0) || !tip.allFinite() || !drill_axis.allFinite()) {
    throw std::invalid_argument("RetreatPlanner::plan: non-finite input");
  }
  const double n = drill_axis.norm();
  if (!(n > 1e-12)) throw std::invalid_argument("drill_axis: must be non-zero");
  const Eigen::Vector3d target = tip - (drill_axis / n) * params_.distance_m;
  return RetreatMotion(
      t0, tip, target,
      TrapezoidProfile::minimumTime(params_.distance_m, params_.speed_m_s, params_.accel_m_s2));
}

}  // namespace pedicle_drilling::core
