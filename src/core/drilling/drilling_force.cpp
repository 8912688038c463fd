/**
 * @file drilling_force.cpp
 * @brief Mechanistic thrust-force law with material removal (see drilling_force.hpp).
 */
#include "pedicle_drilling/core/drilling/drilling_force.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace pedicle_drilling::core {

namespace {
constexpr double kPi = 3.14159265358979323846;
}  // namespace

DrillingProcess::DrillingProcess(BoneSpecimen specimen, DrillParameters params)
    : specimen_(std::move(specimen)), params_(params) {
  if (!(params_.bit_diameter_m > 0.0) || !(params_.point_angle_deg > 0.0) ||
      !(params_.point_angle_deg < 180.0) || !(params_.ref_feed_per_rev_m > 0.0) ||
      !(params_.ref_spindle_rpm > 0.0) || !(params_.contact_stiffness_n_per_m > 0.0) ||
      !(params_.chisel_edge_share >= 0.0 && params_.chisel_edge_share < 1.0) ||
      !(params_.thrust_coefficient_n_per_m > 0.0) ||
      !(params_.feed_exponent > 0.0 && params_.feed_exponent <= 1.0) ||
      !std::isfinite(params_.speed_exponent)) {
    throw std::invalid_argument("DrillingProcess: invalid drill parameters");
  }
  if (!std::isfinite(params_.torque_thrust_ratio) || !(params_.torque_thrust_ratio >= 0.0)) {
    throw std::invalid_argument("DrillingProcess: torque_thrust_ratio must be finite and >= 0");
  }
  const double half_angle = 0.5 * params_.point_angle_deg * kPi / 180.0;
  cone_length_m_ = 0.5 * params_.bit_diameter_m / std::tan(half_angle);
}

void DrillingProcess::reset() {
  max_depth_cut_m_ = 0.0;
  thrust_N_ = 0.0;
  torque_Nm_ = 0.0;
}

double DrillingProcess::cuttingTorque(double thrust_n, double spindle_rpm) const {
  if (!(thrust_n > 0.0) || !(spindle_rpm > 0.0)) return 0.0;  // no rotation or no contact
  return params_.torque_thrust_ratio * 0.5 * params_.bit_diameter_m * thrust_n;
}

double DrillingProcess::steadyThrust(double engaged_fraction, double feed_per_rev_m,
                                     double spindle_rpm) const {
  if (engaged_fraction <= 0.0 || feed_per_rev_m <= 0.0 || spindle_rpm <= 0.0) return 0.0;
  const double s = params_.chisel_edge_share;
  const double lips = std::pow(feed_per_rev_m / params_.ref_feed_per_rev_m, params_.feed_exponent);
  return params_.thrust_coefficient_n_per_m * params_.bit_diameter_m * engaged_fraction *
         (s + (1.0 - s) * lips) *
         std::pow(spindle_rpm / params_.ref_spindle_rpm, -params_.speed_exponent);
}

double DrillingProcess::engagedFraction(double tip_depth_m) const {
  // Lip point at radius r cuts at depth tip - (r / R) * cone_length (conical point); uniform
  // weight per unit lip length -> mean solid fraction over the depth window of the cone.
  return (specimen_.integratedFraction(tip_depth_m) -
          specimen_.integratedFraction(tip_depth_m - cone_length_m_)) /
         cone_length_m_;
}

ForceSample DrillingProcess::step(double dt, double tip_depth_m, double spindle_rpm) {
  // The torque follows the thrust, which it never changes.
  ForceSample out = stepThrust(dt, tip_depth_m, spindle_rpm);
  torque_Nm_ = cuttingTorque(out.thrust_N, spindle_rpm);
  out.torque_Nm = torque_Nm_;
  return out;
}

ForceSample DrillingProcess::stepThrust(double dt, double tip_depth_m, double spindle_rpm) {
  if (!(dt > 0.0)) throw std::invalid_argument("DrillingProcess::step: dt must be > 0");
  if (!std::isfinite(tip_depth_m) || !std::isfinite(spindle_rpm)) {
    throw std::invalid_argument(
        "DrillingProcess::step: tip depth and spindle speed must be finite");
  }
  ForceSample out;
  out.material = specimen_.materialAt(tip_depth_m);
  const double advance = tip_depth_m - max_depth_cut_m_;
  const bool rigid = std::isinf(params_.contact_stiffness_n_per_m);
  if (advance <= 0.0 || (rigid && spindle_rpm <= 0.0)) {
    // Tip at or behind the hole bottom (or, rigid, spindle stopped): no lip touches bone.
    thrust_N_ = 0.0;
    out.thrust_N = 0.0;
    return out;
  }
  const double phi = engagedFraction(tip_depth_m);
  if (!rigid) return stepElastic(dt, advance, phi, std::max(0.0, spindle_rpm), out);
  const double revolutions = dt * spindle_rpm / 60.0;
  const double feed_per_rev = advance / revolutions;
  max_depth_cut_m_ = tip_depth_m;
  const double target = steadyThrust(phi, feed_per_rev, spindle_rpm);
  // First-order lag with tau = lag_revolutions spindle periods (exact discretisation).
  const double tau = params_.lag_revolutions * 60.0 / spindle_rpm;
  const double a = tau > 0.0 ? std::exp(-dt / tau) : 0.0;
  thrust_N_ = a * thrust_N_ + (1.0 - a) * target;
  out.contact = phi > 0.0;
  if (!out.contact) thrust_N_ = 0.0;  // cutting air (tip advancing before the surface/canal)
  out.thrust_N = thrust_N_;
  out.feed_per_rev_m = feed_per_rev;
  out.engaged_fraction = phi;
  return out;
}

ForceSample DrillingProcess::stepElastic(double dt, double advance, double phi, double rpm,
                                         ForceSample out) {
  out.engaged_fraction = phi;
  if (!(phi > 0.0)) {
    // Cutting air (before the surface, in the canal): nothing resists, the cut follows the tip.
    max_depth_cut_m_ += advance;
    thrust_N_ = 0.0;
    return out;
  }
  const double k = params_.contact_stiffness_n_per_m;
  const double revolutions = dt * rpm / 60.0;
  // Cut advance u in [0, advance]: h(u) = F_law(u / revolutions) - k (advance - u) = 0 for
  // u > 0, h increasing, h(advance) > 0; h(0+) = chisel - k advance. If h(0+) >= 0 the spring
  // holds without cutting (u = 0); otherwise Newton in u, kept inside the bracket [lo, hi]
  // (bisection when Newton leaves it), until the step is below 1e-12 of the advance.
  double u = 0.0;
  if (revolutions > 0.0) {
    const double f0 = steadyThrust(phi, params_.ref_feed_per_rev_m, rpm);  // at f_ref
    const double alpha = params_.feed_exponent;
    const double share = params_.chisel_edge_share;
    const double lips0 = f0 * (1.0 - share);
    const double chisel = f0 * share;  // the force the chisel edge needs to indent at all
    const auto lips = [&](double x) {
      return x > 0.0 ? lips0 * std::pow(x / (revolutions * params_.ref_feed_per_rev_m), alpha)
                     : 0.0;
    };
    // Below the chisel edge's indentation force nothing is cut: u = 0, the spring holds.
    if (chisel < k * advance) {
      double lo = 0.0;
      double hi = advance;
      u = advance * 0.5;
      for (int it = 0; it < 100; ++it) {
        const double fl = lips(u);
        const double h = chisel + fl - k * (advance - u);
        if (h > 0.0) {
          hi = u;
        } else {
          lo = u;
        }
        const double dh = (u > 0.0 ? alpha * fl / u : 0.0) + k;
        const double step = h / dh;
        if (std::abs(step) <= 1e-15 + 1e-12 * advance) break;  // converged (Newton's step)
        double next = u - step;
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        u = next;
      }
    }
  }
  max_depth_cut_m_ += u;
  out.overlap_m = advance - u;
  thrust_N_ = k * out.overlap_m;
  out.thrust_N = thrust_N_;
  out.contact = true;
  out.feed_per_rev_m = revolutions > 0.0 ? u / revolutions : 0.0;
  return out;
}

double DrillingProcess::removedDepth(Material layer) const {
  double s = 0.0;
  double e = 0.0;
  specimen_.layerInterval(layer, &s, &e);
  if (e <= s) return 0.0;
  return std::clamp(max_depth_cut_m_, s, e) - s;
}

double DrillingProcess::residualInnerCorticalThickness() const {
  return std::max(0.0, specimen_.innerCorticalEnd() - max_depth_cut_m_);
}

}  // namespace pedicle_drilling::core
