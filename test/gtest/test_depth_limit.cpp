// Tests of core::DepthLimit, core::DrillingPlan and the simulated planning step
// (core::makeImagingPlan).
#include "pedicle_drilling/core/control/depth_limit.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "pedicle_drilling/core/sim/imaging_plan.hpp"

namespace pd = pedicle_drilling::core;

namespace {

/** @brief A plan 8 mm deep with a 1.5 mm entry tolerance, straight down in its frame. */
pd::DrillingPlan plan(const Eigen::Vector3d& entry = Eigen::Vector3d::Zero()) {
  pd::DrillingPlan p;
  p.frame = "tracker_marker";
  p.entry = entry;
  p.direction = Eigen::Vector3d(0.0, 0.0, -1.0);
  p.depth_m = 8e-3;
  p.entry_tolerance_m = 1.5e-3;
  return p;
}

const Eigen::Vector3d kDown(0.0, 0.0, -1.0);

/** @brief A limit whose planned entry is 5 mm ahead of the tip (marker at the world origin). */
pd::DepthLimit begun(pd::DepthLimitParams params = {}) {
  pd::DepthLimit limit(params);
  EXPECT_EQ(limit.begin(plan(), Eigen::Isometry3d::Identity(), Eigen::Vector3d(0, 0, 5e-3), kDown),
            "");
  return limit;
}

}  // namespace

TEST(DrillingPlan, CheckRefusesWhatCannotBeDrilled) {
  EXPECT_EQ(plan().check(), "");
  pd::DrillingPlan p = plan();
  p.depth_m = 0.0;
  EXPECT_NE(p.check().find("depth"), std::string::npos);
  p = plan();
  p.direction.setZero();
  EXPECT_NE(p.check().find("direction"), std::string::npos);
  p = plan();
  p.entry.x() = std::nan("");
  EXPECT_NE(p.check().find("entry"), std::string::npos);
  p = plan();
  p.entry_tolerance_m = 0.05;
  EXPECT_NE(p.check().find("tolerance"), std::string::npos);
}

TEST(DepthLimitParams, ValidateNamesTheField) {
  pd::DepthLimitParams p;
  p.contact_force_n = 0.0;
  try {
    p.validate();
    FAIL() << "accepted contact_force_n 0";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("contact_force_n"), std::string::npos) << e.what();
  }
}

TEST(DepthLimit, TheRegisteredEntryIsTheEntryAlongTheDrillAxisFromTheTip) {
  pd::DepthLimit limit(pd::DepthLimitParams{});
  // The marker 2 mm to the side and 3 mm below the world origin, turned 90 deg about z; the
  // entry 4 mm below the marker in its frame; the tip at the world origin, drilling down.
  Eigen::Isometry3d marker = Eigen::Isometry3d::Identity();
  marker.translate(Eigen::Vector3d(2e-3, 0.0, -3e-3));
  marker.rotate(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  ASSERT_EQ(limit.begin(plan(Eigen::Vector3d(0, 0, -4e-3)), marker, Eigen::Vector3d::Zero(), kDown),
            "");
  EXPECT_NEAR(limit.registeredEntry(), 7e-3, 1e-12);
  EXPECT_FALSE(limit.contact());
  // No contact: the tolerance's shallow end.
  EXPECT_NEAR(limit.entry(), 5.5e-3, 1e-12);
  EXPECT_NEAR(limit.limit(), 13.5e-3, 1e-12);
}

TEST(DepthLimit, APlanAtAnAngleToTheDrillIsRefusedAndAShallowerOneShortens) {
  pd::DepthLimit limit(pd::DepthLimitParams{});
  pd::DrillingPlan tilted = plan();
  tilted.direction = Eigen::Vector3d(std::sin(0.2), 0.0, -std::cos(0.2));  // 11.5 deg
  const std::string why =
      limit.begin(tilted, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), kDown);
  EXPECT_NE(why.find("max_plan_angle_deg"), std::string::npos) << why;
  EXPECT_FALSE(limit.active());
  tilted.direction = Eigen::Vector3d(std::sin(0.05), 0.0, -std::cos(0.05));  // 2.9 deg
  ASSERT_EQ(limit.begin(tilted, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), kDown), "");
  EXPECT_NEAR(limit.depth(), 8e-3 * std::cos(0.05), 1e-12);
}

TEST(DepthLimit, TheContactIsTheFirstOfItsSamplesAndASpikeIsNone) {
  pd::DepthLimitParams params;
  params.contact_samples = 3;
  pd::DepthLimit limit = begun(params);
  limit.onThrust(4.0e-3, 5.0);  // before the tolerance's shallow end (3.5 mm): no contact
  limit.onThrust(5.0e-3, 9.0);  // one spike
  limit.onThrust(5.1e-3, 0.1);
  EXPECT_FALSE(limit.contact());
  limit.onThrust(5.2e-3, 0.6);
  limit.onThrust(5.3e-3, 0.7);
  EXPECT_FALSE(limit.contact());
  limit.onThrust(5.4e-3, std::nan(""));  // a non-finite sample breaks the run
  limit.onThrust(5.5e-3, 0.6);
  limit.onThrust(5.6e-3, 0.7);
  limit.onThrust(5.7e-3, 0.8);
  EXPECT_TRUE(limit.contact());
  EXPECT_NEAR(limit.entry(), 5.5e-3, 1e-12);
  EXPECT_NEAR(limit.limit(), 13.5e-3, 1e-12);
  limit.onThrust(9e-3, 0.6);  // later samples change nothing
  EXPECT_NEAR(limit.entry(), 5.5e-3, 1e-12);
}

TEST(DepthLimit, AContactBeyondTheToleranceIsClampedToItsDeepEnd) {
  pd::DepthLimit limit = begun();
  for (int i = 0; i < 3; ++i) limit.onThrust(8e-3 + i * 1e-5, 2.0);  // 3 mm past the entry
  EXPECT_TRUE(limit.contact());
  EXPECT_NEAR(limit.entry(), 6.5e-3, 1e-12);  // 5 mm + 1.5 mm
}

TEST(DepthLimit, ABoneNearerThanPredictedLowersTheLimitByTheMeanResidual) {
  pd::DepthLimitParams params;
  params.residual_samples = 2;
  pd::DepthLimit limit = begun(params);
  const double before = limit.limit();
  limit.onResidual(1e-3);
  limit.onResidual(std::nan(""));  // ignored
  limit.onResidual(3e-4);
  limit.onResidual(5e-4);  // the oldest leaves the mean
  EXPECT_NEAR(limit.correction(), 4e-4, 1e-12);
  EXPECT_NEAR(limit.limit(), before - 4e-4, 1e-12);
  // The contact is measured with the correction: the tip's true advance.
  for (int i = 0; i < 3; ++i) limit.onThrust(5e-3, 1.0);
  EXPECT_NEAR(limit.entry(), 5.4e-3, 1e-12);
}

TEST(DepthLimit, AConstantPredictionOffsetCancelsBetweenTheContactAndNow) {
  // The tracker shows the bone 0.7 mm nearer than predicted all along: the contact is sensed
  // 0.7 mm of predicted advance early, and the limit is lowered by the same 0.7 mm, so that the
  // tip's depth below the sensed surface, (advance - e) - (contact - e), is the plan's.
  pd::DepthLimitParams params;
  params.residual_samples = 4;
  pd::DepthLimit offset = begun(params);
  pd::DepthLimit exact = begun(params);
  for (int i = 0; i < 4; ++i) offset.onResidual(7e-4);
  for (int i = 0; i < 3; ++i) {
    offset.onThrust(5.3e-3 + i * 1e-5, 1.0);  // the true surface at 6.0 mm, seen 0.7 mm early
    exact.onThrust(6.0e-3 + i * 1e-5, 1.0);
  }
  ASSERT_TRUE(offset.contact() && exact.contact());
  EXPECT_NEAR(offset.entry(), 6.0e-3, 1e-12);  // the surface in true advance
  // The deepest predicted advance allowed: 0.7 mm short of the exact one's, i.e. the same true
  // depth below the surface (8 mm).
  EXPECT_NEAR(offset.limit(), exact.limit() - 7e-4, 1e-12);
  EXPECT_NEAR(offset.limit() + offset.correction() - offset.entry(), 8e-3, 1e-12);
}

TEST(ImagingPlan, ThePlanIsTheMeasuredFarSideLessTheMarginInTheMarkersFrame) {
  const pd::BoneSpecimen specimen = pd::BoneSpecimen::uniform(2e-3, 4e-3, 2e-3, 0.9, 0.3, 0.85);
  Eigen::Isometry3d marker_from_bone = Eigen::Isometry3d::Identity();
  marker_from_bone.translate(Eigen::Vector3d(0.03, 0.0, -0.01));
  pd::PlanImagingParams exact;
  exact.boundary_sd_mm = 0.0;
  exact.registration_rms_mm = 0.0;
  exact.margin_mm = 0.5;
  const pd::ImagingPlan p = pd::makeImagingPlan(specimen, marker_from_bone, exact, 7);
  EXPECT_NEAR(p.plan.depth_m, 7.5e-3, 1e-12);
  EXPECT_TRUE(p.plan.entry.isApprox(Eigen::Vector3d(0.03, 0.0, -0.01)));
  EXPECT_TRUE(p.plan.direction.isApprox(Eigen::Vector3d(0, 0, -1)));
  EXPECT_EQ(p.far_side_error_m, 0.0);
  EXPECT_EQ(p.plan.entry_tolerance_m, 0.0);
  exact.margin_mm = 9.0;  // nothing left to drill
  EXPECT_THROW(pd::makeImagingPlan(specimen, marker_from_bone, exact, 7), std::invalid_argument);
}

TEST(ImagingPlan, ErrorsHaveTheSourcedSpreadAndTheirOwnStream) {
  const pd::BoneSpecimen specimen = pd::BoneSpecimen::uniform(2e-3, 4e-3, 2e-3, 0.9, 0.3, 0.85);
  const pd::PlanImagingParams params;  // 0.17 mm per boundary, 0.96 mm RMS registration
  double far_sq = 0.0;
  double entry_sq = 0.0;
  const int n = 4000;
  for (int seed = 1; seed <= n; ++seed) {
    const pd::ImagingPlan p =
        pd::makeImagingPlan(specimen, Eigen::Isometry3d::Identity(), params, seed);
    far_sq += p.far_side_error_m * p.far_side_error_m;
    entry_sq += p.entry_error_m * p.entry_error_m;
    EXPECT_NEAR(p.plan.depth_m, 8e-3 + p.far_side_error_m - 1.3e-3, 1e-12);
  }
  // SD of the far side from the surface: sqrt(2) x 0.17 mm; of the entry along the normal:
  // hypot(0.96 / sqrt(3), 0.17) mm (3 % sampling error at n = 4000 allowed).
  EXPECT_NEAR(std::sqrt(far_sq / n), std::sqrt(2.0) * 0.17e-3, 0.03 * 0.24e-3);
  const double entry_sd = std::hypot(0.96e-3 / std::sqrt(3.0), 0.17e-3);
  EXPECT_NEAR(std::sqrt(entry_sq / n), entry_sd, 0.03 * entry_sd);
  EXPECT_NEAR(pd::makeImagingPlan(specimen, Eigen::Isometry3d::Identity(), params, 1)
                  .plan.entry_tolerance_m,
              3.0 * entry_sd, 1e-12);
  // Deterministic for a seed.
  EXPECT_EQ(pd::makeImagingPlan(specimen, Eigen::Isometry3d::Identity(), params, 42).plan.depth_m,
            pd::makeImagingPlan(specimen, Eigen::Isometry3d::Identity(), params, 42).plan.depth_m);
}
