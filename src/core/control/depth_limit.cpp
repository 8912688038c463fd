// The depth limit of a drilling plan (see depth_limit.hpp).
#include "pedicle_drilling/core/control/depth_limit.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {

std::string DrillingPlan::check() const {
  if (!entry.allFinite()) return "drilling plan: the entry point is not finite";
  if (!direction.allFinite() || direction.norm() < 1e-9) {
    return "drilling plan: the direction is not a finite non-zero vector";
  }
  if (!(depth_m > 0.0 && depth_m <= 0.2)) {
    return "drilling plan: depth " + std::to_string(depth_m) + " m is outside (0, 0.2] m";
  }
  if (!(entry_tolerance_m >= 0.0 && entry_tolerance_m <= 0.02)) {
    return "drilling plan: entry tolerance " + std::to_string(entry_tolerance_m) +
           " m is outside [0, 0.02] m";
  }
  return "";
}

const ParamTable<DepthLimitParams>& DepthLimitParams::table() {
  static const ParamTable<DepthLimitParams> t = [] {
    using P = DepthLimitParams;
    ParamTable<P> d;
    d.flag("require_plan", &P::require_plan)
        .number("contact_force_n", &P::contact_force_n, Range::aboveUpTo(0, 5), "N")
        .integer("contact_samples", &P::contact_samples, Range::closed(1, 100))
        .number("max_plan_angle_deg", &P::max_plan_angle_deg, Range::aboveUpTo(0, 30), "deg")
        .integer("residual_samples", &P::residual_samples, Range::closed(1, 100));
    return d;
  }();
  return t;
}

void DepthLimitParams::validate() const { table().validate(*this); }

DepthLimit::DepthLimit(const DepthLimitParams& params) : params_(params) { params_.validate(); }

std::string DepthLimit::begin(const DrillingPlan& plan, const Eigen::Isometry3d& world_from_marker,
                              const Eigen::Vector3d& tip_world, const Eigen::Vector3d& drill_axis) {
  active_ = false;
  contact_ = false;
  run_ = 0;
  residuals_.clear();
  const std::string bad = plan.check();
  if (!bad.empty()) return bad;
  if (!world_from_marker.matrix().allFinite() || !tip_world.allFinite() ||
      !drill_axis.allFinite()) {
    return "drilling plan: the marker's pose or the drill tip is not finite";
  }
  const Eigen::Vector3d axis = drill_axis.normalized();
  const Eigen::Vector3d direction = (world_from_marker.linear() * plan.direction).normalized();
  const double angle_deg = std::acos(std::clamp(direction.dot(axis), -1.0, 1.0)) * 180.0 / M_PI;
  if (!(angle_deg <= params_.max_plan_angle_deg)) {
    std::ostringstream os;
    os << "drilling plan: its direction is " << angle_deg << " deg from the drill axis (more than "
       << "depth_limit/max_plan_angle_deg " << params_.max_plan_angle_deg << " deg)";
    return os.str();
  }
  const Eigen::Vector3d entry_world = world_from_marker * plan.entry;
  registered_entry_ = (entry_world - tip_world).dot(axis);
  // The depth along the plan's direction, measured along the drill axis (within the angle).
  depth_ = plan.depth_m * direction.dot(axis);
  tolerance_ = plan.entry_tolerance_m;
  active_ = true;
  return "";
}

void DepthLimit::onThrust(double predicted_advance, double thrust_n) {
  if (!active_ || contact_ || !std::isfinite(predicted_advance)) return;
  const double measured = predicted_advance + correction();
  // A contact before the tolerance's shallow end is no contact with this bone (a spike, a drift
  // of the sensor): the run only counts from there.
  if (!(std::isfinite(thrust_n) && thrust_n >= params_.contact_force_n) ||
      measured < registered_entry_ - tolerance_) {
    run_ = 0;
    return;
  }
  if (run_++ == 0) run_start_advance_ = measured;
  if (run_ >= params_.contact_samples) {
    contact_ = true;
    contact_advance_ = run_start_advance_;
  }
}

void DepthLimit::onResidual(double residual_m) {
  if (!active_ || !std::isfinite(residual_m)) return;
  residuals_.push_back(residual_m);
  while (static_cast<int>(residuals_.size()) > params_.residual_samples) residuals_.pop_front();
}

double DepthLimit::entry() const {
  if (!contact_) return registered_entry_ - tolerance_;
  return std::clamp(contact_advance_, registered_entry_ - tolerance_,
                    registered_entry_ + tolerance_);
}

double DepthLimit::correction() const {
  if (residuals_.empty()) return 0.0;
  return std::accumulate(residuals_.begin(), residuals_.end(), 0.0) /
         static_cast<double>(residuals_.size());
}

double DepthLimit::limit() const { return entry() + depth_ - correction(); }

std::string DepthLimit::describe() const {
  std::ostringstream os;
  os.precision(3);
  os << std::fixed << "planned depth " << depth_ * 1e3 << " mm from the surface at "
     << entry() * 1e3 << " mm of advance ("
     << (contact_ ? "sensed contact" : "no contact sensed: the registration's shallow end")
     << "; registered entry " << registered_entry_ * 1e3 << " +- " << tolerance_ * 1e3
     << " mm), tracker correction " << correction() * 1e3 << " mm";
  return os.str();
}

}  // namespace pedicle_drilling::core
