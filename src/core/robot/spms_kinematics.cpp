/**
 * @file spms_kinematics.cpp
 * @brief 3-PRS SPMS inverse/forward kinematics (see spms_kinematics.hpp).
 */
#include "pedicle_drilling/core/robot/spms_kinematics.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;
constexpr int kMaxIterations = 50;
}  // namespace

Eigen::Matrix3d PlatformFullPose::rotation() const {
  return (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Vector3d PlatformFullPose::position(double home_height_m) const {
  return Eigen::Vector3d(x_m, y_m, home_height_m + z_m);
}

double LeadScrew::sliderFromMotorAngle(double motor_angle_rad) const {
  return zero_offset_m + lead_m_per_rev * motor_angle_rad / (2.0 * kPi * belt_reduction);
}

double LeadScrew::motorAngleFromSlider(double slider_m) const {
  return (slider_m - zero_offset_m) * 2.0 * kPi * belt_reduction / lead_m_per_rev;
}

SpmsKinematics::SpmsKinematics(SpmsGeometry geometry) : geometry_(geometry) {
  const SpmsGeometry& g = geometry_;
  // A tilt's cosine above this is well within the limit (1e-9 in cosine is far more than
  // acos's rounding), so the joint-limit checks decide as acos(cosine) > limit would, without
  // an acos per leg per query (the simulation solves the platform every step).
  tilt_certainly_within_cos_ = std::cos(g.max_spherical_tilt_deg * kDeg) + 1e-9;
  if (!(g.base_radius_m > 0.0 && g.platform_radius_m > 0.0 && g.rod_length_m > 0.0 &&
        g.slider_max_m > g.slider_min_m && g.home_slider_m >= g.slider_min_m &&
        g.home_slider_m <= g.slider_max_m)) {
    throw std::invalid_argument("SpmsKinematics: inconsistent geometry");
  }
  if (!(g.max_spherical_tilt_deg > 0.0 && g.max_spherical_tilt_deg <= 180.0)) {
    throw std::invalid_argument("SpmsKinematics: max_spherical_tilt_deg must be in (0, 180] deg");
  }
  const double gamma = g.rail_inclination_deg * kDeg;
  for (int i = 0; i < 3; ++i) {
    const double th = (g.leg_azimuth_offset_deg + 120.0 * i) * kDeg;
    const Eigen::Vector3d er(std::cos(th), std::sin(th), 0.0);
    base_point_[i] = g.base_radius_m * er;
    rail_dir_[i] = std::cos(gamma) * Eigen::Vector3d::UnitZ() - std::sin(gamma) * er;
    tangent_[i] = Eigen::Vector3d(-std::sin(th), std::cos(th), 0.0);
    platform_local_[i] = g.platform_radius_m * er;
  }
  const double s = g.home_slider_m;
  const double gap = g.base_radius_m - s * std::sin(gamma) - g.platform_radius_m;
  if (std::abs(gap) >= g.rod_length_m) {
    throw std::invalid_argument("SpmsKinematics: rod too short for the home pose");
  }
  home_height_m_ = s * std::cos(gamma) + std::sqrt(g.rod_length_m * g.rod_length_m - gap * gap);
}

Eigen::Vector3d SpmsKinematics::platformJoint(int i, const PlatformFullPose& pose) const {
  return platformJoint(i, pose, pose.rotation());
}

Eigen::Vector3d SpmsKinematics::platformJoint(int i, const PlatformFullPose& pose,
                                              const Eigen::Matrix3d& rotation) const {
  return pose.position(home_height_m_) + rotation * platform_local_[i];
}

Eigen::Vector3d SpmsKinematics::sliderPoint(int i, double s_m) const {
  return base_point_[i] + s_m * rail_dir_[i];
}

bool SpmsKinematics::dependentCoordinates(const PlatformPose& pose, PlatformFullPose* full) const {
  // Leg-plane constraints: t_i . P_i = 0 (t_i . B_i = 0 and t_i . u_i = 0), independent of z.
  PlatformFullPose p;
  p.z_m = pose.z_m;
  p.roll_rad = pose.roll_rad;
  p.pitch_rad = pose.pitch_rad;
  bool converged = false;
  for (int it = 0; it < kMaxIterations; ++it) {
    const Eigen::Matrix3d rot = p.rotation();
    Eigen::Vector3d r;
    Eigen::Matrix3d jac;
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d rp = rot * platform_local_[i];
      r[i] = tangent_[i].x() * p.x_m + tangent_[i].y() * p.y_m + tangent_[i].dot(rp);
      jac(i, 0) = tangent_[i].x();
      jac(i, 1) = tangent_[i].y();
      jac(i, 2) = tangent_[i].dot(Eigen::Vector3d::UnitZ().cross(rp));  // d(Rz R')/dyaw
    }
    if (r.cwiseAbs().maxCoeff() < 1e-15) {
      converged = true;
      break;
    }
    const Eigen::Vector3d delta = jac.fullPivLu().solve(-r);
    if (!delta.allFinite()) break;
    p.x_m += delta[0];
    p.y_m += delta[1];
    p.yaw_rad += delta[2];
    if (delta.cwiseAbs().maxCoeff() < 1e-16) {
      converged = true;
      break;
    }
  }
  if (full) *full = p;
  return converged && std::abs(p.yaw_rad) < 0.5 * kPi;
}

SpmsIkResult SpmsKinematics::inverse(const PlatformPose& pose) const {
  SpmsIkResult res;
  if (!dependentCoordinates(pose, &res.pose)) {
    res.reason = "dependent x/y/yaw solve did not converge (pose outside the mechanism's range)";
    return res;
  }
  const SpmsGeometry& g = geometry_;
  const double L = g.rod_length_m;
  const Eigen::Matrix3d rot = res.pose.rotation();  // once per pose, not per leg
  const Eigen::Vector3d normal = rot * Eigen::Vector3d::UnitZ();
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d d = platformJoint(i, res.pose, rot) - base_point_[i];
    const double ud = rail_dir_[i].dot(d);
    const double disc = ud * ud - d.squaredNorm() + L * L;
    if (disc < 0.0) {
      std::ostringstream os;
      os << "leg " << i << ": rod (" << L * 1e3 << " mm) cannot reach the platform joint";
      res.reason = os.str();
      return res;
    }
    // Branch with the slider below the platform joint along the rail.
    const double s = ud - std::sqrt(disc);
    res.sliders[i] = s;
    if (s < g.slider_min_m || s > g.slider_max_m) {
      std::ostringstream os;
      os << "leg " << i << ": slider " << s * 1e3 << " mm outside stroke [" << g.slider_min_m * 1e3
         << ", " << g.slider_max_m * 1e3 << "] mm";
      res.reason = os.str();
      return res;
    }
    const Eigen::Vector3d rod = platformJoint(i, res.pose, rot) - sliderPoint(i, s);
    const double cosine = std::clamp(rod.normalized().dot(normal), -1.0, 1.0);
    if (cosine > tilt_certainly_within_cos_) continue;  // the same decision, without the acos
    const double tilt = std::acos(cosine);
    if (tilt > g.max_spherical_tilt_deg * kDeg) {
      std::ostringstream os;
      os << "leg " << i << ": spherical joint tilt " << tilt / kDeg << " deg exceeds "
         << g.max_spherical_tilt_deg << " deg";
      res.reason = os.str();
      return res;
    }
  }
  res.reachable = true;
  return res;
}

SpmsIkResult SpmsKinematics::inverseHeave(double z_m) const {
  PlatformPose p;
  p.z_m = z_m;
  return inverse(p);
}

bool SpmsKinematics::isReachable(const PlatformPose& pose, std::string* reason) const {
  const SpmsIkResult r = inverse(pose);
  if (reason) *reason = r.reason;
  return r.reachable;
}

SpmsFkResult SpmsKinematics::forward(const Eigen::Vector3d& sliders,
                                     const PlatformPose& initial_guess,
                                     SpmsFkJacobian* jacobian) const {
  SpmsFkResult res;
  const SpmsGeometry& g = geometry_;
  for (int i = 0; i < 3; ++i) {
    if (sliders[i] < g.slider_min_m || sliders[i] > g.slider_max_m) {
      std::ostringstream os;
      os << "leg " << i << ": slider " << sliders[i] * 1e3 << " mm outside stroke";
      res.reason = os.str();
      return res;
    }
  }
  const double L = g.rod_length_m;
  // Residual: rod-length error per leg (m), for q = (z, roll, pitch); the full pose and its
  // rotation on request.
  auto residual = [&](const Eigen::Vector3d& q, PlatformFullPose* full, Eigen::Matrix3d* rotation,
                      bool* ok) {
    PlatformPose pp;
    pp.z_m = q[0];
    pp.roll_rad = q[1];
    pp.pitch_rad = q[2];
    PlatformFullPose fp;
    *ok = dependentCoordinates(pp, &fp);
    Eigen::Vector3d r;
    const Eigen::Matrix3d rot = fp.rotation();
    for (int i = 0; i < 3; ++i) {
      r[i] = (platformJoint(i, fp, rot) - sliderPoint(i, sliders[i])).norm() - L;
    }
    if (full) *full = fp;
    if (rotation) *rotation = rot;
    return r;
  };
  // Central differences of the residual at q (m, rad steps of 1e-7).
  auto differences = [&](const Eigen::Vector3d& q, bool* ok) {
    Eigen::Matrix3d jac;
    const double h[3] = {1e-7, 1e-7, 1e-7};
    for (int j = 0; j < 3; ++j) {
      Eigen::Vector3d qp = q;
      Eigen::Vector3d qm = q;
      qp[j] += h[j];
      qm[j] -= h[j];
      bool ok1 = true;
      bool ok2 = true;
      jac.col(j) = (residual(qp, nullptr, nullptr, &ok1) - residual(qm, nullptr, nullptr, &ok2)) /
                   (2.0 * h[j]);
      *ok = *ok && ok1 && ok2;
    }
    return jac;
  };
  Eigen::Vector3d q(initial_guess.z_m, initial_guess.roll_rad, initial_guess.pitch_rad);
  if (q.isZero()) q[0] = (sliders.mean() - g.home_slider_m) * rail_dir_[0].z();
  bool ok = true;
  PlatformFullPose full;
  Eigen::Matrix3d full_rotation;
  Eigen::Vector3d r = residual(q, &full, &full_rotation, &ok);
  SpmsFkJacobian own;
  SpmsFkJacobian& kept = jacobian ? *jacobian : own;
  Eigen::Matrix3d& jac = kept.matrix;
  // Chord steps on the kept Jacobian and its factorisation while each cuts the residual
  // tenfold; else (and without one) Newton's method, a new Jacobian at every iterate, which is
  // then kept.
  bool reuse = jacobian != nullptr && jac.allFinite();
  int it = 0;
  for (; it < kMaxIterations && ok; ++it) {
    const double size = r.cwiseAbs().maxCoeff();
    if (size < 1e-13) break;
    if (!reuse) {
      jac = differences(q, &ok);
      kept.factorised = false;
    }
    if (!kept.factorised) {
      kept.lu.compute(jac);
      kept.factorised = true;
    }
    const Eigen::Vector3d delta = kept.lu.solve(-r);
    if (!delta.allFinite()) {
      if (reuse) {
        reuse = false;
        continue;
      }
      ok = false;
      break;
    }
    // Damp large steps (keep rotations within a few degrees per iteration).
    const double max_rot = std::max(1e-12, delta.tail<2>().cwiseAbs().maxCoeff());
    const double scale = std::min(1.0, 0.1 / max_rot);
    const Eigen::Vector3d q_next = q + scale * delta;
    PlatformFullPose full_next;
    Eigen::Matrix3d rotation_next;
    bool ok_next = true;
    const Eigen::Vector3d r_next = residual(q_next, &full_next, &rotation_next, &ok_next);
    if (reuse && (!ok_next || !(r_next.cwiseAbs().maxCoeff() < 0.1 * size))) {
      reuse = false;  // the kept Jacobian is too far off: Newton from this iterate
      continue;
    }
    q = q_next;
    r = r_next;
    full = full_next;
    full_rotation = rotation_next;
    ok = ok_next;
  }
  res.iterations = it;
  res.pose = full;
  res.rotation = full_rotation;
  res.residual_m = r.cwiseAbs().maxCoeff();
  if (!ok || !(res.residual_m < 1e-9)) {
    res.reason = "forward kinematics did not converge (slider combination not assemblable)";
    return res;
  }
  res.reason = assemblyProblem(sliders, full, full_rotation);
  res.ok = res.reason.empty();
  return res;
}

std::string SpmsKinematics::assemblyProblem(const Eigen::Vector3d& sliders,
                                            const PlatformFullPose& pose,
                                            const Eigen::Matrix3d& rot) const {
  // Same branch and joint-limit checks as the inverse.
  const Eigen::Vector3d normal = rot * Eigen::Vector3d::UnitZ();
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d rod = platformJoint(i, pose, rot) - sliderPoint(i, sliders[i]);
    if (rod.dot(rail_dir_[i]) <= 0.0) {
      return "forward kinematics converged to the slider-above-joint branch";
    }
    const double cosine = std::clamp(rod.normalized().dot(normal), -1.0, 1.0);
    if (cosine > tilt_certainly_within_cos_) continue;  // the same decision, without the acos
    const double tilt = std::acos(cosine);
    if (tilt > geometry_.max_spherical_tilt_deg * kDeg) {
      std::ostringstream os;
      os << "leg " << i << ": spherical joint tilt " << tilt / kDeg << " deg over limit";
      return os.str();
    }
  }
  return "";
}

}  // namespace pedicle_drilling::core
