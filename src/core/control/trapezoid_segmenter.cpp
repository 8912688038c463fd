// Time-segmented trapezoidal approximation of the compensation trajectory (paper Sec. IV-B).
#include "pedicle_drilling/core/control/trapezoid_segmenter.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace pedicle_drilling::core {

namespace {

void require(bool ok, const char* name, const char* why, double value) {
  if (ok) return;
  std::ostringstream os;
  os << name << ": " << why << " (got " << value << ")";
  throw std::invalid_argument(os.str());
}

}  // namespace

TrapezoidProfile TrapezoidProfile::fixedDuration(double length, double duration,
                                                 double accel_ratio) {
  require(std::isfinite(length) && length >= 0.0, "length", "must be finite and >= 0", length);
  require(std::isfinite(duration) && duration > 0.0, "duration", "must be finite and > 0",
          duration);
  require(std::isfinite(accel_ratio) && accel_ratio > 0.0, "accel_ratio", "must be finite and > 0",
          accel_ratio);
  const double r = std::max(accel_ratio, 2.0 / duration);
  TrapezoidProfile p;
  p.length = length;
  p.duration = duration;
  p.t_acc = std::min(1.0 / r, 0.5 * duration);
  p.v_peak = length / (duration - p.t_acc);
  p.accel = p.v_peak / p.t_acc;
  return p;
}

TrapezoidProfile TrapezoidProfile::minimumTime(double length, double v_max, double a_max) {
  require(std::isfinite(length) && length >= 0.0, "length", "must be finite and >= 0", length);
  require(std::isfinite(v_max) && v_max > 0.0, "v_max", "must be finite and > 0", v_max);
  require(std::isfinite(a_max) && a_max > 0.0, "a_max", "must be finite and > 0", a_max);
  TrapezoidProfile p;
  p.length = length;
  p.accel = a_max;
  if (length == 0.0) return p;
  if (length >= v_max * v_max / a_max) {  // reaches v_max
    p.v_peak = v_max;
    p.t_acc = v_max / a_max;
    p.duration = 2.0 * p.t_acc + (length - v_max * v_max / a_max) / v_max;
  } else {  // triangular
    p.v_peak = std::sqrt(length * a_max);
    p.t_acc = p.v_peak / a_max;
    p.duration = 2.0 * p.t_acc;
  }
  return p;
}

double TrapezoidProfile::distance(double tau) const {
  if (tau <= 0.0) return 0.0;
  if (tau >= duration) return length;
  if (tau < t_acc) return 0.5 * accel * tau * tau;
  const double t_dec = duration - t_acc;
  if (tau <= t_dec) return 0.5 * accel * t_acc * t_acc + v_peak * (tau - t_acc);
  const double r = duration - tau;
  return std::max(0.0, length - 0.5 * accel * r * r);
}

double TrapezoidProfile::speed(double tau) const {
  if (tau <= 0.0 || tau >= duration) return 0.0;
  if (tau < t_acc) return accel * tau;
  if (tau <= duration - t_acc) return v_peak;
  return accel * (duration - tau);
}

double TrapezoidProfile::acceleration(double tau) const {
  if (tau <= 0.0 || tau >= duration) return 0.0;
  if (tau < t_acc) return accel;
  if (tau <= duration - t_acc) return 0.0;
  return -accel;
}

Segment::Segment(double t0, const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                 const TrapezoidProfile& profile)
    : t0_(t0), p0_(p0), p1_(p1), dir_(Eigen::Vector3d::Zero()), profile_(profile) {
  const double len = (p1 - p0).norm();
  if (len > 0.0) dir_ = (p1 - p0) / len;
}

Eigen::Vector3d Segment::position(double t) const {
  const double tau = t - t0_;
  if (tau <= 0.0) return p0_;
  if (tau >= profile_.duration) return p1_;
  return p0_ + dir_ * profile_.distance(tau);
}

Eigen::Vector3d Segment::velocity(double t) const { return dir_ * profile_.speed(t - t0_); }

Eigen::Vector3d Segment::acceleration(double t) const {
  return dir_ * profile_.acceleration(t - t0_);
}

TrapezoidSegmenter::TrapezoidSegmenter(double period_s, double accel_ratio)
    : period_(period_s), accel_ratio_(accel_ratio) {
  require(std::isfinite(period_s) && period_s > 0.0, "period_s", "must be finite and > 0",
          period_s);
  require(std::isfinite(accel_ratio) && accel_ratio > 0.0, "accel_ratio", "must be finite and > 0",
          accel_ratio);
}

double TrapezoidSegmenter::effectiveAccelRatio() const {
  return std::max(accel_ratio_, 2.0 / period_);
}

Segment TrapezoidSegmenter::plan(double t0, const Eigen::Vector3d& p0,
                                 const Eigen::Vector3d& p1) const {
  if (!std::isfinite(t0) || !p0.allFinite() || !p1.allFinite()) {
    throw std::invalid_argument("plan: t0, p0 and p1 must be finite");
  }
  return Segment(t0, p0, p1,
                 TrapezoidProfile::fixedDuration((p1 - p0).norm(), period_, accel_ratio_));
}

Segment TrapezoidSegmenter::segmentAt(const Reference& ref, double t_start, double t) const {
  const double k = std::max(0.0, std::floor((t - t_start) / period_));
  const double ts = t_start + k * period_;
  return plan(ts, ref(ts), ref(ts + period_));
}

Eigen::Vector3d TrapezoidSegmenter::sample(const Reference& ref, double t_start, double t) const {
  return segmentAt(ref, t_start, t).position(t);
}

const char* toString(SegmentProfile profile) {
  switch (profile) {
    case SegmentProfile::kExact:
      return "exact";
    case SegmentProfile::kRestToRest:
      break;
  }
  return "rest_to_rest";
}

bool parseSegmentProfile(const std::string& name, SegmentProfile* profile) {
  if (name == "exact") {
    *profile = SegmentProfile::kExact;
    return true;
  }
  if (name == "rest_to_rest") {
    *profile = SegmentProfile::kRestToRest;
    return true;
  }
  return false;
}

double TrapezoidSegmenter::trackingErrorBound(double v_max, double a_max) const {
  const double T = period_;
  const double ta = std::min(1.0 / effectiveAccelRatio(), 0.5 * T);
  const double delta = ta * (T - ta) / (2.0 * T * T);
  return delta * v_max * T + a_max * T * T / 8.0;
}

}  // namespace pedicle_drilling::core
