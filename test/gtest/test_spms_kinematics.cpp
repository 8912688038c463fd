/**
 * @file test_spms_kinematics.cpp
 * @brief IK/FK round trip over the workspace, dependent coordinates, unreachable poses,
 *        lead-screw model of the SPMS 3-PRS platform.
 */
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>

#include "pedicle_drilling/core/robot/spms_kinematics.hpp"

namespace pedicle_drilling::core {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

// Max joint-position error (m) between two full poses (covers all 6 coordinates).
double jointError(const SpmsKinematics& k, const PlatformFullPose& a, const PlatformFullPose& b) {
  double e = 0.0;
  for (int i = 0; i < 3; ++i) {
    e = std::max(e, (k.platformJoint(i, a) - k.platformJoint(i, b)).norm());
  }
  return e;
}

TEST(SpmsKinematics, HomePoseIsSymmetric) {
  SpmsKinematics k;
  const SpmsIkResult r = k.inverseHeave(0.0);
  ASSERT_TRUE(r.reachable) << r.reason;
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(r.sliders[i], k.geometry().home_slider_m, 1e-12);
  EXPECT_NEAR(r.pose.x_m, 0.0, 1e-12);
  EXPECT_NEAR(r.pose.y_m, 0.0, 1e-12);
  EXPECT_NEAR(r.pose.yaw_rad, 0.0, 1e-12);
}

TEST(SpmsKinematics, PureHeaveMovesAllSlidersEqually) {
  SpmsKinematics k;  // vertical rails: slider displacement equals heave
  for (double z : {-6e-3, -2.5e-3, 0.0, 2.5e-3, 6e-3}) {
    const SpmsIkResult r = k.inverseHeave(z);
    ASSERT_TRUE(r.reachable) << r.reason;
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(r.sliders[i] - k.geometry().home_slider_m, z, 1e-12);
  }
}

TEST(SpmsKinematics, RoundTripOverWorkspaceGridWithin1um) {
  for (double incl : {0.0, 15.0}) {
    SpmsGeometry g;
    g.rail_inclination_deg = incl;
    SpmsKinematics k(g);
    double max_err = 0.0;
    int n = 0;
    for (double z = -6e-3; z <= 6e-3 + 1e-12; z += 1.5e-3) {
      for (double roll = -3.0; roll <= 3.0 + 1e-9; roll += 1.0) {
        for (double pitch = -3.0; pitch <= 3.0 + 1e-9; pitch += 1.0) {
          PlatformPose p;
          p.z_m = z;
          p.roll_rad = roll * kDeg;
          p.pitch_rad = pitch * kDeg;
          const SpmsIkResult ik = k.inverse(p);
          ASSERT_TRUE(ik.reachable) << ik.reason;
          const SpmsFkResult fk = k.forward(ik.sliders);
          ASSERT_TRUE(fk.ok) << fk.reason;
          EXPECT_NEAR(fk.pose.z_m, z, 1e-6);
          EXPECT_NEAR(fk.pose.roll_rad, p.roll_rad, 1e-6);
          EXPECT_NEAR(fk.pose.pitch_rad, p.pitch_rad, 1e-6);
          const double e = jointError(k, fk.pose, ik.pose);
          EXPECT_LT(e, 1e-6);
          max_err = std::max(max_err, e);
          ++n;
        }
      }
    }
    EXPECT_EQ(n, 9 * 7 * 7);
    RecordProperty(incl == 0.0 ? "max_err_m_vertical" : "max_err_m_inclined",
                   std::to_string(max_err));
    EXPECT_LT(max_err, 1e-9);  // Newton converges far below the 1 um requirement
  }
}

TEST(SpmsKinematics, ParasiticMotionsAreSmallAndConsistent) {
  SpmsKinematics k;
  PlatformPose p;
  p.roll_rad = 3.0 * kDeg;
  p.pitch_rad = -3.0 * kDeg;
  const SpmsIkResult r = k.inverse(p);
  ASSERT_TRUE(r.reachable) << r.reason;
  // Each spherical joint stays in the vertical radial plane of its leg.
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d pj = k.platformJoint(i, r.pose);
    const Eigen::Vector3d b = k.sliderPoint(i, 0.0);
    const Eigen::Vector3d t = Eigen::Vector3d::UnitZ().cross(b.normalized());
    EXPECT_NEAR(t.dot(pj), 0.0, 1e-12);
  }
  // Second-order small: |x|,|y| << 1 mm, |yaw| << 0.1 deg for 3 deg tilts.
  EXPECT_LT(std::abs(r.pose.x_m), 1e-3);
  EXPECT_LT(std::abs(r.pose.y_m), 1e-3);
  EXPECT_LT(std::abs(r.pose.yaw_rad), 0.1 * kDeg);
  EXPECT_GT(std::abs(r.pose.x_m) + std::abs(r.pose.y_m), 0.0);  // but not identically zero
  // Pure heave has no parasitic motion at all.
  const SpmsIkResult h = k.inverseHeave(4e-3);
  EXPECT_NEAR(h.pose.x_m, 0.0, 1e-12);
  EXPECT_NEAR(h.pose.y_m, 0.0, 1e-12);
  EXPECT_NEAR(h.pose.yaw_rad, 0.0, 1e-12);
}

TEST(SpmsKinematics, UnreachablePosesReportReason) {
  SpmsKinematics k;
  // Beyond the slider stroke (+/-100 mm around home).
  SpmsIkResult r = k.inverseHeave(0.150);
  EXPECT_FALSE(r.reachable);
  EXPECT_NE(r.reason.find("stroke"), std::string::npos) << r.reason;
  r = k.inverseHeave(-0.150);
  EXPECT_FALSE(r.reachable);
  EXPECT_NE(r.reason.find("stroke"), std::string::npos) << r.reason;
  // Large tilt: spherical-joint limit or stroke.
  PlatformPose p;
  p.roll_rad = 40.0 * kDeg;
  r = k.inverse(p);
  EXPECT_FALSE(r.reachable);
  EXPECT_FALSE(r.reason.empty());
  std::string reason;
  EXPECT_FALSE(k.isReachable(p, &reason));
  EXPECT_EQ(reason, r.reason);
  // Rod cannot reach: a tiny rod relative to the radial offset.
  SpmsGeometry g;
  g.rod_length_m = 0.06;  // radial gap at home is 50 mm
  SpmsKinematics small(g);
  PlatformPose tilt;
  tilt.roll_rad = 25.0 * kDeg;
  const SpmsIkResult rr = small.inverse(tilt);
  EXPECT_FALSE(rr.reachable);
  EXPECT_FALSE(rr.reason.empty());
}

// The spherical joints' limit decides as acos(cosine) > limit, also a hair either side of it
// (inverse and forward skip the acos only well within the limit).
TEST(SpmsKinematics, TheTiltLimitDecidesExactlyAtItsBoundary) {
  PlatformPose p;
  p.z_m = 3e-3;
  p.roll_rad = 4.0 * kDeg;
  p.pitch_rad = -2.0 * kDeg;
  const SpmsIkResult free = SpmsKinematics().inverse(p);
  ASSERT_TRUE(free.reachable) << free.reason;
  const Eigen::Matrix3d rot = free.pose.rotation();
  double worst = 0.0;  // the largest tilt of the three rods, as the checks compute it
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d rod = SpmsKinematics().platformJoint(i, free.pose) -
                                SpmsKinematics().sliderPoint(i, free.sliders[i]);
    const double c = std::clamp(rod.normalized().dot(rot * Eigen::Vector3d::UnitZ()), -1.0, 1.0);
    worst = std::max(worst, std::acos(c) / kDeg);
  }
  for (const double margin : {1e-9, 1e-6, 1e-3}) {
    SpmsGeometry over;  // the limit just above the worst tilt: every check passes
    over.max_spherical_tilt_deg = worst + margin;
    SpmsGeometry under;  // just below: the worst rod is refused, by name
    under.max_spherical_tilt_deg = worst - margin;
    EXPECT_TRUE(SpmsKinematics(over).inverse(p).reachable) << margin;
    const SpmsIkResult refused = SpmsKinematics(under).inverse(p);
    EXPECT_FALSE(refused.reachable) << margin;
    EXPECT_NE(refused.reason.find("spherical joint tilt"), std::string::npos) << refused.reason;
    EXPECT_TRUE(SpmsKinematics(over).forward(free.sliders, PlatformPose{}).ok) << margin;
    const SpmsFkResult fk = SpmsKinematics(under).forward(free.sliders, PlatformPose{});
    EXPECT_FALSE(fk.ok) << margin;
    EXPECT_NE(fk.reason.find("spherical joint tilt"), std::string::npos) << fk.reason;
  }
}

TEST(SpmsKinematics, ATiltLimitOutsideItsRangeIsRefused) {
  for (const double limit : {0.0, -10.0, 180.5, std::nan("")}) {
    SpmsGeometry g;
    g.max_spherical_tilt_deg = limit;
    EXPECT_THROW(SpmsKinematics k(g), std::invalid_argument) << limit;
  }
  SpmsGeometry g;
  g.max_spherical_tilt_deg = 180.0;
  EXPECT_NO_THROW(SpmsKinematics k(g));
}

TEST(SpmsKinematics, ForwardRejectsSlidersOutOfStroke) {
  SpmsKinematics k;
  const SpmsFkResult fk = k.forward(Eigen::Vector3d(0.15, 0.15, 0.30));
  EXPECT_FALSE(fk.ok);
  EXPECT_NE(fk.reason.find("stroke"), std::string::npos);
}

TEST(SpmsKinematics, BreathingTrajectoryTracksWithinWorkspace) {
  // AP breathing displacement of about 5 mm (paper Sec. V-B) as heave; all reachable.
  SpmsKinematics k;
  for (int j = 0; j <= 100; ++j) {
    const double z = 2.5e-3 * std::sin(2.0 * 3.14159265358979323846 * j / 100.0);
    EXPECT_TRUE(k.inverseHeave(z).reachable);
  }
}

TEST(LeadScrew, AngleSliderRoundTrip) {
  LeadScrew ls;  // 5 mm lead, 1:1 belt
  EXPECT_NEAR(ls.sliderFromMotorAngle(2.0 * 3.14159265358979323846), 0.005, 1e-15);
  LeadScrew geared;
  geared.belt_reduction = 2.0;
  geared.zero_offset_m = 0.1;
  EXPECT_NEAR(geared.sliderFromMotorAngle(2.0 * 3.14159265358979323846), 0.1025, 1e-15);
  for (double s : {0.05, 0.1, 0.1234, 0.25}) {
    EXPECT_NEAR(geared.sliderFromMotorAngle(geared.motorAngleFromSlider(s)), s, 1e-15);
  }
}

// The platform's forward kinematics with a kept Jacobian (the simulation steps it every
// millisecond): along a breathing heave with a tilt, each step from the last pose, the same pose
// as Newton's method to 1e-12 in every coordinate; a NaN matrix is replaced by a computed one; a
// wrong one (a tenth of the true Jacobian) still converges, as Newton does.
TEST(SpmsKinematics, ForwardWithKeptJacobianEqualsNewton) {
  SpmsGeometry g;
  g.rail_inclination_deg = 15.0;
  SpmsKinematics k(g);
  SpmsFkJacobian kept;
  PlatformPose guess_newton, guess_kept;
  int chord_iterations = 0;
  int newton_iterations = 0;
  for (int step = 0; step <= 4000; ++step) {
    const double t = 1e-3 * step;
    PlatformPose p;
    p.z_m = 5e-3 * std::sin(2.0 * 3.14159265358979323846 * t / 4.0);
    p.roll_rad = 1.5 * kDeg * std::sin(t);
    p.pitch_rad = -0.8 * kDeg * std::cos(0.7 * t);
    const SpmsIkResult ik = k.inverse(p);
    ASSERT_TRUE(ik.reachable) << ik.reason;
    const SpmsFkResult newton = k.forward(ik.sliders, guess_newton);
    const SpmsFkResult chord = k.forward(ik.sliders, guess_kept, &kept);
    ASSERT_TRUE(newton.ok && chord.ok) << newton.reason << chord.reason;
    ASSERT_TRUE(kept.matrix.allFinite());
    EXPECT_TRUE(chord.rotation == chord.pose.rotation());  // the same bits
    EXPECT_NEAR(chord.pose.z_m, newton.pose.z_m, 1e-12);
    EXPECT_NEAR(chord.pose.roll_rad, newton.pose.roll_rad, 1e-12);
    EXPECT_NEAR(chord.pose.pitch_rad, newton.pose.pitch_rad, 1e-12);
    EXPECT_NEAR(chord.pose.x_m, newton.pose.x_m, 1e-12);
    EXPECT_NEAR(chord.pose.y_m, newton.pose.y_m, 1e-12);
    EXPECT_NEAR(chord.pose.yaw_rad, newton.pose.yaw_rad, 1e-12);
    guess_newton = {newton.pose.z_m, newton.pose.roll_rad, newton.pose.pitch_rad};
    guess_kept = {chord.pose.z_m, chord.pose.roll_rad, chord.pose.pitch_rad};
    chord_iterations += chord.iterations;
    newton_iterations += newton.iterations;
  }
  std::cout << "[ forward ] iterations over 4001 steps: Newton " << newton_iterations
            << " (7 residuals each), kept Jacobian " << chord_iterations << std::endl;
  const Eigen::Matrix3d right = kept.matrix;
  PlatformPose p;
  p.z_m = 2e-3;
  p.roll_rad = 2.0 * kDeg;
  const SpmsIkResult ik = k.inverse(p);
  ASSERT_TRUE(ik.reachable);
  SpmsFkJacobian wrong;
  wrong.matrix = 0.1 * right;
  const SpmsFkResult from_wrong = k.forward(ik.sliders, PlatformPose{}, &wrong);
  ASSERT_TRUE(from_wrong.ok) << from_wrong.reason;
  EXPECT_NEAR(from_wrong.pose.z_m, 2e-3, 1e-9);
  EXPECT_NEAR(from_wrong.pose.roll_rad, 2.0 * kDeg, 1e-9);
  EXPECT_LT((wrong.matrix - right).norm(), 0.05 * right.norm());  // replaced by a computed one
  // ... with its factorisation: the kept LU solves with the new matrix.
  ASSERT_TRUE(wrong.factorised);
  const Eigen::Vector3d b(1.0, -2.0, 0.5);
  EXPECT_LT((wrong.matrix * wrong.lu.solve(b) - b).norm(), 1e-9);
}

}  // namespace
}  // namespace pedicle_drilling::core
