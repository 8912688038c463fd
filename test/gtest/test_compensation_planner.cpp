// Tests of the Algorithm 1 compensation planner (core, no ROS).
#include "pedicle_drilling/core/control/compensation_planner.hpp"

#include <gtest/gtest.h>

#include "support.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>

namespace pd = pedicle_drilling::core;

namespace {

pd::MotionModel apModel() {
  pd::MotionModel m;
  m.axis(pd::Axis::kAP).q1 = 0.01;  // 5 mm over 500 ml
  m.axis(pd::Axis::kAP).q0 = 0.4;
  m.axis(pd::Axis::kSI).q1 = 0.004;  // 2 mm
  m.axis(pd::Axis::kLR).q1 = 0.002;  // 1 mm
  return m;
}

pd::CompensationPlanner readyPlanner(const pd::CompensationParams& p, double breath_start = 0.3) {
  pd::CompensationPlanner planner(p, apModel());
  planner.compensator().setVentilator(pd::VentilatorSettings());
  planner.compensator().setBreathStart(breath_start);
  return planner;
}

/** @brief The paper compensator's prediction inside a planner made with the default class. */
const pd::DisplacementPredictor& paperPredictor(const pd::CompensationPlanner& planner) {
  const auto* paper = dynamic_cast<const pd::PaperCompensator*>(&planner.compensator());
  if (paper == nullptr || paper->predictor() == nullptr) throw std::logic_error("not the paper's");
  return *paper->predictor();
}

}  // namespace

TEST(CompensationPlanner, ModeNamesRoundTrip) {
  for (auto m : {pd::CompensationMode::kStationary, pd::CompensationMode::kUncompensated,
                 pd::CompensationMode::kCompensated}) {
    pd::CompensationMode parsed;
    ASSERT_TRUE(pd::parseCompensationMode(pd::toString(m), &parsed));
    EXPECT_EQ(parsed, m);
  }
  pd::CompensationMode parsed;
  EXPECT_FALSE(pd::parseCompensationMode("on", &parsed));
}

TEST(CompensationPlanner, InvalidParametersNameTheField) {
  auto expectField = [](pd::CompensationParams p, const std::string& field) {
    try {
      p.validate();
      FAIL() << "accepted bad " << field;
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()).rfind(field, 0), 0u) << e.what();
    }
  };
  pd::CompensationParams p;
  p.latency_s = -0.1;
  expectField(p, "latency_s");
  p = pd::CompensationParams();
  p.feed_rate_m_s = std::nan("");
  expectField(p, "feed_rate_m_s");
  p = pd::CompensationParams();
  p.drill_axis = Eigen::Vector3d(0, 0, 2);
  expectField(p, "drill_axis");
  p = pd::CompensationParams();
  p.points_per_segment = 0;
  expectField(p, "points_per_segment");
}

TEST(CompensationPlanner, PredictionFollowsVentilatorPhaseAndModel) {
  pd::CompensationParams p;
  const double start = 0.3;
  pd::CompensationPlanner planner = readyPlanner(p, start);
  const pd::VentilatorModel vent{pd::VentilatorSettings()};
  for (double tau : {0.0, 0.8, 1.6, 2.5, 4.9}) {
    for (int cycle : {-2, 0, 3}) {
      const double t = start + cycle * vent.period() + tau;
      const Eigen::Vector3d d = planner.compensator().displacement(t);
      const double tv = vent.volumeInCycle(tau);
      // AP only (default): world +z, mm -> m; SI/LR not predicted.
      EXPECT_NEAR(d.z(), 1e-3 * (0.01 * tv + 0.4), 1e-12) << "t " << t;
      EXPECT_NEAR(d.x(), 0.0, 1e-15);
      EXPECT_NEAR(d.y(), 0.0, 1e-15);
    }
  }
  p.predict_axis = {{true, true, true}};
  pd::CompensationPlanner all = readyPlanner(p, start);
  const double t = start + 1.0;
  const double tv = vent.volumeInCycle(1.0);
  EXPECT_NEAR(all.compensator().displacement(t).y(), 1e-3 * 0.004 * tv, 1e-12);
  EXPECT_NEAR(all.compensator().displacement(t).x(), 1e-3 * 0.002 * tv, 1e-12);
}

TEST(CompensationPlanner, ModesNeedThePredictionExceptStationary) {
  pd::CompensationPlanner planner(pd::CompensationParams(), apModel());
  EXPECT_THROW(planner.start(pd::CompensationMode::kCompensated, 1.0), std::logic_error);
  EXPECT_THROW(planner.start(pd::CompensationMode::kUncompensated, 1.0), std::logic_error);
  EXPECT_NO_THROW(planner.start(pd::CompensationMode::kStationary, 1.0));
  EXPECT_EQ(planner.boneDisplacementSinceStart(3.0), Eigen::Vector3d::Zero());
  EXPECT_NEAR(planner.referenceFeed(3.0), 0.5e-3 * 2.0, 1e-15);
}

TEST(CompensationPlanner, CompensatedFeedIncludesPredictedDisplacementUncompensatedDoesNot) {
  pd::CompensationParams p;
  const double t_reg = 2.0;
  pd::CompensationPlanner comp = readyPlanner(p);
  pd::CompensationPlanner unc = readyPlanner(p);
  comp.start(pd::CompensationMode::kCompensated, t_reg);
  unc.start(pd::CompensationMode::kUncompensated, t_reg);
  double max_comp = 0.0;
  for (double t = t_reg; t < t_reg + 10.0; t += 0.01) {
    const double feed = p.feed_rate_m_s * (t - t_reg);
    const Eigen::Vector3d bone = comp.boneDisplacementSinceStart(t);
    // Bone moves +z (towards the drill), the drill axis is -z: the feed must retract.
    EXPECT_NEAR(comp.referenceFeed(t), feed + bone.dot(Eigen::Vector3d(0, 0, -1)), 1e-12);
    EXPECT_NEAR(unc.referenceFeed(t), feed, 1e-15);
    // The monitor's prediction does not depend on the mode (the bone moves in both).
    EXPECT_NEAR((unc.boneDisplacementSinceStart(t) - bone).norm(), 0.0, 1e-15);
    max_comp = std::max(max_comp, std::abs(comp.referenceFeed(t) - feed));
  }
  EXPECT_GT(max_comp, 4e-3);  // the compensation spans the breathing amplitude (5 mm)
}

TEST(CompensationPlanner, SegmentsAreContinuousTrapezoidsOfThePeriod) {
  pd::CompensationParams p;
  pd::CompensationPlanner planner = readyPlanner(p);
  planner.start(pd::CompensationMode::kCompensated, 1.0);
  for (int k = 0; k < 80; ++k) {
    const pd::PlannedSegment s = planner.segment(k);
    const pd::PlannedSegment next = planner.segment(k + 1);
    EXPECT_NEAR(s.t1 - s.t0, 0.125, 1e-12);
    EXPECT_NEAR(s.t1, next.t0, 1e-12);
    EXPECT_NEAR(s.feed_end_m, next.feed_start_m, 1e-15);
    EXPECT_NEAR(s.feed_start_m, planner.referenceFeed(s.t0), 1e-15);
    ASSERT_EQ(s.points.size(), 5u);
    EXPECT_NEAR(s.points.back().t, s.t1, 1e-12);
    EXPECT_NEAR(s.points.back().feed_m, s.feed_end_m, 1e-15);
    EXPECT_EQ(s.points.back().feed_velocity_m_s, 0.0);
    // Points lie between the segment ends (monotonic trapezoid).
    const double lo = std::min(s.feed_start_m, s.feed_end_m) - 1e-15;
    const double hi = std::max(s.feed_start_m, s.feed_end_m) + 1e-15;
    double prev = s.feed_start_m;
    for (const auto& pt : s.points) {
      EXPECT_GE(pt.feed_m, lo);
      EXPECT_LE(pt.feed_m, hi);
      EXPECT_GE((pt.feed_m - prev) * (s.feed_end_m - s.feed_start_m), -1e-18);
      prev = pt.feed_m;
      EXPECT_NEAR(pt.lateral_m.norm(), 0.0, 1e-15);  // AP only, along the axis
    }
  }
}

TEST(CompensationPlanner, LateralPartOnlyWhenRequested) {
  pd::CompensationParams p;
  p.predict_axis = {{true, true, true}};
  pd::CompensationPlanner off = readyPlanner(p);
  p.compensate_lateral = true;
  pd::CompensationPlanner on = readyPlanner(p);
  off.start(pd::CompensationMode::kCompensated, 1.0);
  on.start(pd::CompensationMode::kCompensated, 1.0);
  const double t = 2.5;
  const Eigen::Vector3d y = on.boneDisplacementSinceStart(t);
  ASSERT_GT(std::hypot(y.x(), y.y()), 1e-4);
  const Eigen::Vector3d r_on = on.reference(t);
  const Eigen::Vector3d r_off = off.reference(t);
  EXPECT_NEAR(r_on.x(), y.x(), 1e-12);
  EXPECT_NEAR(r_on.y(), y.y(), 1e-12);
  EXPECT_NEAR(r_off.x(), 0.0, 1e-15);
  EXPECT_NEAR(r_off.y(), 0.0, 1e-15);
  EXPECT_NEAR(r_on.z(), r_off.z(), 1e-15);
}

// Latency study: a controller that executes the segmented command with a pure delay L. The
// tracking error is the tip's compensation (execution minus the delayed feed) minus the bone
// displacement along the drill axis, with a perfect patient model. Prints the table of
// doc/campaign_results.md ("Compensation latency") and checks that commanding the prediction for
// now + L removes most of the lag error.
TEST(CompensationPlanner, LatencyParameterCancelsControllerDelay) {
  auto trackingError = [](double controller_delay, double latency, double* max_err) {
    pd::CompensationParams p;
    p.latency_s = latency;
    pd::CompensationPlanner planner = readyPlanner(p);
    const double t_reg = 1.0;
    planner.start(pd::CompensationMode::kCompensated, t_reg);
    double sum = 0.0;
    int n = 0;
    *max_err = 0.0;
    for (double t = t_reg + 1.0; t < t_reg + 31.0; t += 0.002) {
      const double executed = planner.segmentedReference(t - controller_delay).dot(planner.axis());
      const double feed = p.feed_rate_m_s * (t - controller_delay - t_reg);
      const double bone = planner.boneDisplacementSinceStart(t).dot(planner.axis());
      const double e = (executed - feed) - bone;
      sum += e * e;
      ++n;
      *max_err = std::max(*max_err, std::abs(e));
    }
    return std::sqrt(sum / n);
  };
  std::printf("controller delay [ms] | latency_s [ms] | RMS [mm] | max [mm]\n");
  for (double delay : {0.0, 0.05, 0.1, 0.2}) {
    double max0 = 0.0;
    double max_l = 0.0;
    const double rms0 = trackingError(delay, 0.0, &max0);
    const double rms_l = trackingError(delay, delay, &max_l);
    std::printf("%5.0f | %5.0f | %.4f | %.4f\n", delay * 1e3, 0.0, rms0 * 1e3, max0 * 1e3);
    if (delay > 0.0) {
      std::printf("%5.0f | %5.0f | %.4f | %.4f\n", delay * 1e3, delay * 1e3, rms_l * 1e3,
                  max_l * 1e3);
      EXPECT_LT(rms_l, 0.5 * rms0) << "delay " << delay;
    }
  }
  double max_a = 0.0;
  double max_b = 0.0;
  // Without delay, the only error is the segmentation (chord + trapezoid lag), well inside H1.
  EXPECT_LT(trackingError(0.0, 0.0, &max_a), trackingError(0.1, 0.0, &max_b));
  EXPECT_LT(max_a, 1.2e-3);
}

TEST(ArmCompensation, BacksOffAlongTheDrillAxisAndMovesLaterally) {
  const std::string urdf = pedicle_drilling::test::workcellUrdf();
  const pd::KinematicChain arm = pd::KinematicChain::fromUrdfString(urdf, "world", "device_base");
  ASSERT_EQ(arm.numJoints(), 6u);
  Eigen::VectorXd q(6);
  q << 0.0, 0.435859, 1.319709, 0.0, 1.386025, 0.0;  // config/drilling_pose.yaml
  const pd::ArmCompensation comp(arm, q, 0.01);
  EXPECT_NEAR((comp.drillAxis() - Eigen::Vector3d(0, 0, -1)).norm(), 0.0, 1e-4);
  const Eigen::Isometry3d drilling = arm.forward(q);
  const Eigen::Isometry3d home = arm.forward(comp.homeJoints());
  EXPECT_NEAR((home.translation() - (drilling.translation() - 0.01 * comp.drillAxis())).norm(), 0.0,
              1e-6);
  EXPECT_NEAR(Eigen::AngleAxisd(home.linear().transpose() * drilling.linear()).angle(), 0.0, 1e-6);
  const Eigen::Vector3d lateral(0.001, -0.002, 0.0);
  const Eigen::VectorXd ql = comp.lateral(lateral, comp.homeJoints());
  EXPECT_NEAR((arm.forward(ql).translation() - home.translation() - lateral).norm(), 0.0, 1e-6);
}

// The drilling pose aimed at a plan's entry and axis, solved by the arm's IK.
TEST(ArmCompensation, AimedAtAPlanPutsTheTipBeforeTheEntryOnItsAxis) {
  const std::string urdf = pedicle_drilling::test::workcellUrdf();
  const pd::KinematicChain arm = pd::KinematicChain::fromUrdfString(urdf, "world", "device_base");
  Eigen::VectorXd q(6);
  q << 0.0, 0.435859, 1.319709, 0.0, 1.386025, 0.0;  // config/drilling_pose.yaml
  pd::ArmCompensation comp(arm, q, 0.01);
  std::string why;
  const Eigen::Vector3d axis = comp.drillAxis();
  EXPECT_FALSE(comp.aimedAt(Eigen::Vector3d(0.6, 0, 0.2), axis, 0.004, &why));  // no tip yet
  EXPECT_NE(why.find("tip"), std::string::npos) << why;
  const Eigen::Vector3d tip =
      pd::ArmCompensation::tipAt(urdf, "world", "drill_tip", arm.jointNames(), q);
  comp.setTipAtPose(tip);
  // The configured axis, the entry 4 mm ahead: the configured pose again.
  std::optional<pd::ArmCompensation> same = comp.aimedAt(tip + 0.004 * axis, axis, 0.004, &why);
  ASSERT_TRUE(same) << why;
  EXPECT_LT((same->drillingJoints() - q).norm(), 1e-5);
  EXPECT_LT((*same->tipAtPose() - tip).norm(), 1e-6);
  // Tilted by 10 degrees and moved 5 mm sideways: the axis is the plan's, the tip 4 mm before
  // the entry on it, and the tip link of the solved joints is there too.
  const Eigen::Vector3d d = Eigen::AngleAxisd(10.0 * M_PI / 180.0, Eigen::Vector3d::UnitX()) * axis;
  const Eigen::Vector3d entry = tip + Eigen::Vector3d(0.005, 0.0, 0.0) + 0.01 * d;
  std::optional<pd::ArmCompensation> tilted = comp.aimedAt(entry, d, 0.004, &why);
  ASSERT_TRUE(tilted) << why;
  EXPECT_LT((tilted->drillAxis() - d).norm(), 1e-6);
  EXPECT_LT((*tilted->tipAtPose() - (entry - 0.004 * d)).norm(), 1e-6);
  const Eigen::Vector3d solved_tip = pd::ArmCompensation::tipAt(
      urdf, "world", "drill_tip", arm.jointNames(), tilted->drillingJoints());
  EXPECT_LT((solved_tip - (entry - 0.004 * d)).norm(), 1e-6);
  EXPECT_TRUE(arm.withinLimits(tilted->drillingJoints()));
  // Out of the arm's reach: refused, naming it.
  EXPECT_FALSE(comp.aimedAt(Eigen::Vector3d(5.0, 0.0, 0.0), axis, 0.004, &why));
  EXPECT_NE(why.find("cannot reach"), std::string::npos) << why;
  EXPECT_FALSE(comp.aimedAt(entry, Eigen::Vector3d::Zero(), 0.004, &why));
}

TEST(CompensationPlanner, HeldFeedStopsProgressButKeepsFollowingTheBone) {
  pd::CompensationParams p;
  pd::CompensationPlanner planner = readyPlanner(p);
  planner.start(pd::CompensationMode::kCompensated, 1.0);
  planner.holdFeed(4.0);
  for (double t = 4.0; t < 12.0; t += 0.05) {
    const double bone = planner.boneDisplacementSinceStart(t).dot(planner.axis());
    EXPECT_NEAR(planner.referenceFeed(t), p.feed_rate_m_s * 3.0 + bone, 1e-12) << t;
  }
  pd::CompensationPlanner stationary(p, apModel());
  stationary.start(pd::CompensationMode::kStationary, 1.0);
  stationary.holdFeed(2.0);
  EXPECT_NEAR(stationary.referenceFeed(9.0), p.feed_rate_m_s * 1.0, 1e-15);
}

// The exact profile (beyond the paper): the reference itself with its analytic velocities, and
// knots at the ventilator's flow steps, where the predicted velocity steps.
TEST(CompensationPlanner, ExactSegmentsFollowTheReferenceWithKnotsAtTheFlowSteps) {
  pd::CompensationParams p;
  p.segment_profile = pd::SegmentProfile::kExact;
  pd::CompensationPlanner planner = readyPlanner(p, 0.3);
  const pd::VentilatorModel& vent = *paperPredictor(planner).ventilator();
  // The default settings: square flow, 12 /min, I:E 1:2, no pause: steps at the breath start
  // and at Ti = 5/3 s in every 5 s breath.
  const std::vector<double> steps = paperPredictor(planner).flowSteps(0.0, 10.5);
  ASSERT_EQ(steps.size(), 5u);
  EXPECT_NEAR(steps[0], 0.3, 1e-12);
  EXPECT_NEAR(steps[1], 0.3 + vent.flowTime(), 1e-12);
  EXPECT_NEAR(steps[2], 5.3, 1e-12);
  EXPECT_NEAR(steps[3], 5.3 + vent.flowTime(), 1e-12);
  EXPECT_NEAR(steps[4], 10.3, 1e-12);
  EXPECT_NEAR(vent.flowTime(), 5.0 / 3.0, 1e-12);
  planner.start(pd::CompensationMode::kCompensated, 4.0);
  const Eigen::Vector3d axis = planner.axis();
  // The segment that contains the inspiration start at 5.3 s: t0 = 5.25 s.
  const pd::PlannedSegment seg = planner.segment(10);
  ASSERT_DOUBLE_EQ(seg.t0, 5.25);
  std::vector<double> times;
  for (const pd::PlannedPoint& pt : seg.points) {
    times.push_back(pt.t);
    EXPECT_NEAR(pt.feed_m, planner.reference(pt.t).dot(axis), 1e-12);
  }
  // Five samples (every 25 ms) plus the step at 5.3 s (already a sample) and 1 ms after it.
  ASSERT_EQ(times.size(), 6u);
  EXPECT_NEAR(times[1], 5.3, 1e-9);
  EXPECT_NEAR(times[2], 5.301, 1e-9);
  // Before the step the flow is the expiration's (bone moving away, the drill retracts along
  // -z less than it feeds), after it the inspiratory flow: AP velocity q1 * flow.
  const double q1 = 0.01e-3;  // m/ml
  const double feed = p.feed_rate_m_s;
  // (The velocities are one-sided 1 us differences: compare with the flow mid-way.)
  const pd::VentilatorSample before = paperPredictor(planner).ventilatorAt(5.3 - 0.5e-6);
  const pd::VentilatorSample after = paperPredictor(planner).ventilatorAt(5.301 + 0.5e-6);
  // Reference = feed * axis + y: feed-axis velocity = feed + q1 * flow * (AP . axis) = feed - q1 F.
  EXPECT_NEAR(seg.points[1].feed_velocity_m_s, feed - q1 * before.flow_ml_s, 1e-8);
  EXPECT_NEAR(seg.points[2].feed_velocity_m_s, feed - q1 * after.flow_ml_s, 1e-8);
  EXPECT_GT(std::abs(seg.points[2].feed_velocity_m_s - seg.points[1].feed_velocity_m_s), 1e-3);
  // A segment without a step: only the samples, each with the reference's velocity.
  const pd::PlannedSegment plain = planner.segment(4);
  ASSERT_EQ(plain.points.size(), 5u);
  for (const pd::PlannedPoint& pt : plain.points) {
    const double f = paperPredictor(planner).ventilatorAt(pt.t - 0.5e-6).flow_ml_s;
    EXPECT_NEAR(pt.feed_velocity_m_s, feed - q1 * f, 1e-8);
  }
  // The profile's name round-trips.
  pd::SegmentProfile parsed;
  ASSERT_TRUE(pd::parseSegmentProfile("exact", &parsed));
  EXPECT_EQ(parsed, pd::SegmentProfile::kExact);
  EXPECT_STREQ(pd::toString(pd::SegmentProfile::kExact), "exact");
}
