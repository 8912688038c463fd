// Tests of core::JointTrajectoryExecutor: each rule of ros_control's JointTrajectoryController
// that the simulated arm and SPMS controllers follow (trajectory_executor.hpp), stated from its
// documented behaviour.
#include "pedicle_drilling/core/robot/trajectory_executor.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace pd = pedicle_drilling::core;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/** @brief Strict rules that accept partial goals (most tests command joint "a" alone). */
pd::ControllerRules partial() {
  pd::ControllerRules r;
  r.allow_partial_joints_goal = true;
  return r;
}

/** @brief The lenient rules (strict = false). */
pd::ControllerRules lenient() {
  pd::ControllerRules r;
  r.strict = false;
  return r;
}

/** @brief Two joints "a" and "b", limits [-1, 1] and 2 /s, holding (0, 0). */
pd::JointTrajectoryExecutor twoJoints(pd::ControllerRules rules = partial()) {
  return pd::JointTrajectoryExecutor({"a", "b"}, {{-1.0, 1.0, 2.0}, {-1.0, 1.0, 2.0}},
                                     Eigen::Vector2d::Zero(), rules);
}

pd::TrajectoryCommand command(std::vector<std::string> names, double start,
                              std::vector<pd::TrajectoryPoint> points) {
  pd::TrajectoryCommand c;
  c.joint_names = std::move(names);
  c.start_time_s = start;
  c.points = std::move(points);
  return c;
}

double q(const pd::JointTrajectoryExecutor& ex, double t, int j = 0) {
  return ex.sample(t).position[j];
}
double qd(const pd::JointTrajectoryExecutor& ex, double t, int j = 0) {
  return ex.sample(t).velocity[j];
}
double qdd(const pd::JointTrajectoryExecutor& ex, double t, int j = 0) {
  return ex.sample(t).acceleration[j];
}

/** @brief Joint a: linear from 0 at t = 0 to 1 at t = 10 (0.1 /s); b untouched. */
pd::JointTrajectoryExecutor runningRamp(pd::ControllerRules rules = partial()) {
  pd::JointTrajectoryExecutor ex = twoJoints(rules);
  EXPECT_TRUE(ex.command(command({"a"}, kNaN, {{10.0, {1.0}}}), 0.0).ok());
  return ex;
}

}  // namespace

TEST(JointTrajectoryExecutor, HoldsItsPositionAtRestUntilCommanded) {
  pd::JointTrajectoryExecutor ex = twoJoints();
  ex.hold(Eigen::Vector2d(0.3, -0.2));
  for (double t : {-1.0, 0.0, 5.0}) {
    const pd::TrajectoryState s = ex.sample(t);
    EXPECT_EQ(s.position, Eigen::Vector2d(0.3, -0.2));
    EXPECT_EQ(s.velocity, Eigen::Vector2d::Zero());
    EXPECT_EQ(s.acceleration, Eigen::Vector2d::Zero());
  }
}

TEST(JointTrajectoryExecutor, PositionsOnlyGiveALinearSegment) {
  const pd::JointTrajectoryExecutor ex = runningRamp();
  EXPECT_DOUBLE_EQ(q(ex, 2.5), 0.25);
  EXPECT_DOUBLE_EQ(qd(ex, 2.5), 0.1);
  EXPECT_DOUBLE_EQ(qdd(ex, 2.5), 0.0);
  EXPECT_DOUBLE_EQ(q(ex, 2.5, 1), 0.0);  // joint b not named: keeps its reference
}

TEST(JointTrajectoryExecutor, AfterTheLastPointTheJointsHoldItAtRest) {
  const pd::JointTrajectoryExecutor ex = runningRamp();
  EXPECT_DOUBLE_EQ(q(ex, 12.0), 1.0);
  EXPECT_DOUBLE_EQ(qd(ex, 12.0), 0.0);
  EXPECT_DOUBLE_EQ(ex.endTime(), 10.0);
}

TEST(JointTrajectoryExecutor, ANewTrajectoryTakesOverAtItsStartTime) {
  pd::JointTrajectoryExecutor ex = runningRamp();
  // Received at t = 1, starting at t = 5: the ramp runs until 5, then the new one from there.
  ASSERT_TRUE(ex.command(command({"a"}, 5.0, {{6.0, {0.0}}}), 1.0).ok());
  EXPECT_DOUBLE_EQ(q(ex, 3.0), 0.3);
  EXPECT_DOUBLE_EQ(q(ex, 5.0), 0.5);
  EXPECT_NEAR(q(ex, 5.5), 0.25, 1e-12);  // linear from the ramp's 0.5 at 5 to 0 at 6
  EXPECT_DOUBLE_EQ(q(ex, 6.0), 0.0);
}

TEST(JointTrajectoryExecutor, AZeroStampOrAStartInThePastMeansNow) {
  for (double start : {kNaN, 0.5, 2.0}) {
    pd::JointTrajectoryExecutor ex = runningRamp();
    ASSERT_TRUE(ex.command(command({"a"}, start, {{4.0, {0.0}}}), 2.0).ok());
    EXPECT_DOUBLE_EQ(q(ex, 2.0), 0.2) << start;    // from the ramp's state now
    EXPECT_NEAR(q(ex, 3.0), 0.1, 1e-12) << start;  // straight to the new point
    EXPECT_DOUBLE_EQ(q(ex, 6.0), 0.0) << start;    // the ramp is gone
  }
}

TEST(JointTrajectoryExecutor, PointsAtOrBeforeTheTakeoverAreDropped) {
  pd::JointTrajectoryExecutor ex = runningRamp();
  ASSERT_TRUE(
      ex.command(command({"a"}, 5.0, {{4.0, {-1.0}}, {5.0, {-1.0}}, {7.0, {0.9}}}), 1.0).ok());
  EXPECT_DOUBLE_EQ(q(ex, 4.0), 0.4);  // the ramp, not the dropped point
  EXPECT_DOUBLE_EQ(q(ex, 5.0), 0.5);
  EXPECT_NEAR(q(ex, 6.0), 0.7, 1e-12);
}

TEST(JointTrajectoryExecutor, VelocitiesGiveACubicThroughThemExactly) {
  pd::JointTrajectoryExecutor ex = twoJoints();
  ASSERT_TRUE(
      ex.command(command({"a"}, kNaN, {{1.0, {0.5}, {1.0}}, {2.0, {0.5}, {-0.5}}}), 0.0).ok());
  EXPECT_DOUBLE_EQ(q(ex, 1.0), 0.5);
  EXPECT_DOUBLE_EQ(qd(ex, 1.0), 1.0);
  EXPECT_DOUBLE_EQ(qd(ex, 2.0), -0.5);
  // Velocity continuous through the point at t = 1, from both sides.
  EXPECT_NEAR(qd(ex, 1.0 - 1e-7), 1.0, 1e-5);
  EXPECT_NEAR(qd(ex, 1.0 + 1e-7), 1.0, 1e-5);
  // The first segment is the cubic Hermite from rest at 0 to (0.5, slope 1) at 1: at its middle
  // h01 * 0.5 + h11 * 1 = 0.5 * 0.5 - 0.125.
  EXPECT_NEAR(q(ex, 0.5), 0.125, 1e-12);
  // Velocity is the derivative of position.
  const double h = 1e-6;
  EXPECT_NEAR((q(ex, 1.5 + h) - q(ex, 1.5 - h)) / (2 * h), qd(ex, 1.5), 1e-6);
  EXPECT_NEAR((qd(ex, 1.5 + h) - qd(ex, 1.5 - h)) / (2 * h), qdd(ex, 1.5), 1e-5);
}

TEST(JointTrajectoryExecutor, AccelerationsGiveAQuinticThroughThemExactly) {
  pd::JointTrajectoryExecutor ex = twoJoints();
  ASSERT_TRUE(
      ex.command(command({"a"}, kNaN, {{1.0, {0.2}, {0.3}, {-0.4}}, {2.5, {0.6}, {0.1}, {0.7}}}),
                 0.0)
          .ok());
  EXPECT_NEAR(q(ex, 1.0), 0.2, 1e-12);
  EXPECT_NEAR(qd(ex, 1.0), 0.3, 1e-12);
  EXPECT_NEAR(qdd(ex, 1.0), -0.4, 1e-12);
  EXPECT_NEAR(q(ex, 2.5), 0.6, 1e-12);
  EXPECT_NEAR(qd(ex, 2.5), 0.1, 1e-12);
  EXPECT_NEAR(qdd(ex, 2.5), 0.7, 1e-12);
  // Acceleration continuous through the point at t = 1 (C2), which a cubic is not.
  EXPECT_NEAR(qdd(ex, 1.0 - 1e-9), -0.4, 1e-6);
  EXPECT_NEAR(qdd(ex, 1.0 + 1e-9), -0.4, 1e-6);
  const double h = 1e-6;
  EXPECT_NEAR((q(ex, 1.7 + h) - q(ex, 1.7 - h)) / (2 * h), qd(ex, 1.7), 1e-6);
  EXPECT_NEAR((qd(ex, 1.7 + h) - qd(ex, 1.7 - h)) / (2 * h), qdd(ex, 1.7), 1e-5);
}

TEST(JointTrajectoryExecutor, ATakeoverAtTheLastPointStartsFromItsVelocity) {
  // A stream of segments: each ends where the next takes over. The takeover starts from the
  // running trajectory's state there, its velocity included (it once started from rest, and the
  // arm stalled at every 125 ms boundary while the bone moved).
  pd::JointTrajectoryExecutor ex = twoJoints();
  ASSERT_TRUE(ex.command(command({"a"}, 0.0, {{0.125, {0.0125}, {0.1}}}), 0.0).ok());
  ASSERT_TRUE(ex.command(command({"a"}, 0.125, {{0.25, {0.025}, {0.1}}}), 0.01).ok());
  for (double t : {0.125, 0.15, 0.2, 0.25}) {
    EXPECT_NEAR(qd(ex, t), 0.1, 1e-12) << t;
    EXPECT_NEAR(q(ex, t), 0.1 * t, 1e-12) << t;
  }
}

TEST(JointTrajectoryExecutor, RejectedCommandsLeaveTheRunningTrajectory) {
  pd::JointTrajectoryExecutor ex = runningRamp();
  const std::vector<pd::TrajectoryCommand> bad = {
      command({"a"}, kNaN, {{2.0, {kNaN}}}),
      command({"a"}, kNaN, {{2.0, {0.1}, {std::numeric_limits<double>::infinity()}}}),
      command({"c"}, kNaN, {{2.0, {0.1}}}),
      command({"a", "a"}, kNaN, {{2.0, {0.1, 0.1}}}),
      command({"a"}, kNaN, {{3.0, {0.1}}, {2.0, {0.1}}}),
      command({"a"}, kNaN, {{2.0, {0.1, 0.2}}}),
      command({"a"}, kNaN, {{2.0, {0.1}, {0.1, 0.2}}}),
      command({"a"}, kNaN, {{2.0, {0.1}, {}, {0.3}}}),
      command({"a"}, std::numeric_limits<double>::infinity(), {{2.0, {0.1}}}),
      command({}, kNaN, {{2.0, {}}}),
  };
  for (const pd::TrajectoryCommand& c : bad) {
    const pd::TargetResult r = ex.command(c, 1.0);
    EXPECT_EQ(r.status, pd::TargetStatus::kRejected);
    EXPECT_FALSE(r.message.empty());
    EXPECT_DOUBLE_EQ(q(ex, 5.0), 0.5);
  }
}

TEST(JointTrajectoryExecutor, LenientClampsOutOfLimitPositionsAndRejectsEmptyCommands) {
  pd::JointTrajectoryExecutor ex = twoJoints(lenient());
  pd::TargetResult r = ex.command(command({"b"}, kNaN, {{10.0, {3.0}}}), 0.0);
  EXPECT_EQ(r.status, pd::TargetStatus::kClamped);
  EXPECT_NE(r.message.find("joint 'b' target 3 clamped"), std::string::npos) << r.message;
  EXPECT_DOUBLE_EQ(q(ex, 10.0, 1), 1.0);
  r = ex.command(command({"a"}, kNaN, {}), 10.0);
  EXPECT_EQ(r.status, pd::TargetStatus::kRejected);
  EXPECT_DOUBLE_EQ(q(ex, 10.0, 1), 1.0);
}

TEST(JointTrajectoryExecutor, TooFastSegmentsAreReported) {
  for (const pd::ControllerRules& rules : {partial(), lenient()}) {
    pd::JointTrajectoryExecutor ex = twoJoints(rules);
    const pd::TargetResult r = ex.command(command({"a"}, kNaN, {{10.1, {1.0}}}), 10.0);
    EXPECT_EQ(r.status, pd::TargetStatus::kClamped);
    EXPECT_NE(r.message.find("above its velocity limit 2"), std::string::npos) << r.message;
  }
}

// ros_control, joint_trajectory_controller_impl.h (updateTrajectoryCommand): without
// allow_partial_joints_goal, "Joints on incoming goal don't match the controller joints".
TEST(JointTrajectoryExecutor, StrictRefusesACommandThatDoesNotNameEveryJoint) {
  pd::JointTrajectoryExecutor ex = twoJoints(pd::ControllerRules{});
  pd::TargetResult r = ex.command(command({"a"}, kNaN, {{1.0, {0.5}}}), 0.0);
  EXPECT_EQ(r.status, pd::TargetStatus::kRejected);
  EXPECT_NE(r.message.find("don't match the controller joints [a, b]"), std::string::npos)
      << r.message;
  EXPECT_DOUBLE_EQ(q(ex, 1.0), 0.0);
  // Every joint, in any order: accepted.
  r = ex.command(command({"b", "a"}, kNaN, {{1.0, {0.25, 0.5}}}), 0.0);
  EXPECT_TRUE(r.ok()) << r.message;
  EXPECT_DOUBLE_EQ(q(ex, 1.0, 0), 0.5);
  EXPECT_DOUBLE_EQ(q(ex, 1.0, 1), 0.25);
  // With allow_partial_joints_goal the subset is taken, the other joint keeps its reference.
  pd::JointTrajectoryExecutor partial_ex = twoJoints(partial());
  EXPECT_TRUE(partial_ex.command(command({"a"}, kNaN, {{1.0, {0.5}}}), 0.0).ok());
  EXPECT_DOUBLE_EQ(q(partial_ex, 1.0, 0), 0.5);
  EXPECT_DOUBLE_EQ(q(partial_ex, 1.0, 1), 0.0);
}

// ros_control's controller does not clamp; the limits are the arm driver's, which refuses. A
// strict controller here refuses the whole command and names the joint.
TEST(JointTrajectoryExecutor, StrictRefusesOutOfLimitPositionsAndClampsNothing) {
  pd::JointTrajectoryExecutor ex = runningRamp();
  const pd::TargetResult r = ex.command(command({"b"}, kNaN, {{10.0, {3.0}}}), 1.0);
  EXPECT_EQ(r.status, pd::TargetStatus::kRejected);
  EXPECT_NE(r.message.find("joint 'b' position 3 outside its limits [-1, 1]"), std::string::npos)
      << r.message;
  EXPECT_DOUBLE_EQ(q(ex, 5.0), 0.5);  // the running trajectory goes on
  EXPECT_DOUBLE_EQ(q(ex, 10.0, 1), 0.0);
}

// ros_control, init_joint_trajectory.h: "Dropping all N trajectory point(s), as they occur
// before the current time"; updateTrajectoryCommand then keeps the current trajectory.
TEST(JointTrajectoryExecutor, StrictRejectsATrajectoryThatHasAlreadyEnded) {
  pd::JointTrajectoryExecutor ex = runningRamp();
  const pd::TargetResult r = ex.command(command({"a"}, 1.0, {{1.5, {0.0}}, {2.0, {0.8}}}), 3.0);
  EXPECT_EQ(r.status, pd::TargetStatus::kRejected);
  EXPECT_NE(r.message.find("dropping all 2 trajectory point(s)"), std::string::npos) << r.message;
  EXPECT_DOUBLE_EQ(q(ex, 3.5), 0.35);  // still the ramp
  // A point in the future is enough: the late command is taken (from now to that point).
  EXPECT_TRUE(ex.command(command({"a"}, 1.0, {{2.0, {0.8}}, {4.0, {0.5}}}), 3.0).ok());
  EXPECT_NEAR(q(ex, 4.0), 0.5, 1e-12);
}

// ros_control, updateTrajectoryCommand: "Empty trajectory command, stopping." (hold position,
// reached within stop_trajectory_duration).
TEST(JointTrajectoryExecutor, StrictStopsOnAnEmptyCommandWithinTheStopDuration) {
  pd::ControllerRules rules = partial();
  rules.stop_trajectory_duration_s = 0.4;
  pd::JointTrajectoryExecutor ex = runningRamp(rules);
  EXPECT_TRUE(ex.command(command({}, kNaN, {}), 2.0).ok());
  EXPECT_DOUBLE_EQ(q(ex, 2.0), 0.2);
  EXPECT_NEAR(qd(ex, 2.0), 0.1, 1e-12);  // no jump in velocity
  EXPECT_NEAR(q(ex, 2.4), 0.2 + 0.5 * 0.4 * 0.1, 1e-12);
  EXPECT_NEAR(qd(ex, 2.4), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(q(ex, 9.0), q(ex, 2.4));  // and holds there
  for (double t = 2.0; t < 2.4; t += 0.01) EXPECT_LE(qd(ex, t + 0.01), qd(ex, t) + 1e-12);
}

TEST(JointTrajectoryExecutor, APointARoundingErrorFromTheTakeoverIsAtIt) {
  // The same late command, its times exact (the core engine) and as they come back from
  // nanosecond stamps (the pipeline): a point 1e-10 s after the takeover is the point at it,
  // not a 1e-10 s segment.
  for (double rounding : {0.0, 1e-10, -1e-10}) {
    pd::JointTrajectoryExecutor ex = runningRamp();
    ASSERT_TRUE(ex.command(command({"a"}, 1.0 + rounding,
                                   {{2.0 + rounding, {-1.0}}, {3.0 + rounding, {0.9}}}),
                           2.0)
                    .ok());
    EXPECT_NEAR(q(ex, 2.0), 0.2, 1e-9) << rounding;  // from the ramp's state, not the point
    EXPECT_NEAR(q(ex, 2.5), 0.55, 1e-9) << rounding;
    EXPECT_NEAR(qd(ex, 2.5), 0.7, 1e-6) << rounding;
  }
  // A command whose last point is a rounding error after now has arrived at its end (the
  // lenient rule; the strict one rejects it, StrictRejectsATrajectoryThatHasAlreadyEnded).
  pd::JointTrajectoryExecutor ex = runningRamp(lenient());
  const pd::TargetResult r =
      ex.command(command({"a"}, 1.0, {{1.5, {0.0}}, {3.0 + 1e-10, {0.8}}}), 3.0);
  EXPECT_NE(r.message.find("every point lies in the past"), std::string::npos) << r.message;
  EXPECT_NEAR(q(ex, 3.75), 0.55, 1e-9);  // over its last interval (1.5 s), not at once
  EXPECT_NEAR(q(ex, 4.6), 0.8, 1e-12);
}

TEST(JointTrajectoryExecutor, LenientTakesACommandThatArrivesAfterItsEndToItsFinalPoint) {
  pd::JointTrajectoryExecutor ex = runningRamp(lenient());
  const pd::TargetResult r = ex.command(command({"a"}, 1.0, {{1.5, {0.0}}, {2.0, {0.8}}}), 3.0);
  EXPECT_EQ(r.status, pd::TargetStatus::kClamped);
  EXPECT_NE(r.message.find("every point lies in the past"), std::string::npos) << r.message;
  EXPECT_DOUBLE_EQ(q(ex, 3.0), 0.3);
  EXPECT_DOUBLE_EQ(q(ex, 3.5), 0.8);  // over its last interval (0.5 s)
}

TEST(JointTrajectoryExecutor, PruningNeverChangesWhatLaterSamplesSee) {
  pd::JointTrajectoryExecutor ex = twoJoints();
  ASSERT_TRUE(
      ex.command(command({"a"}, kNaN, {{1.0, {0.5}, {0.2}}, {2.0, {0.1}, {0.0}}, {3.0, {0.4}}}),
                 0.0)
          .ok());
  std::vector<double> before;
  for (int i = 0; i <= 40; ++i) before.push_back(q(ex, 1.5 + 0.05 * i));
  ex.prune(1.5);
  for (int i = 0; i <= 40; ++i) EXPECT_EQ(q(ex, 1.5 + 0.05 * i), before[i]) << i;
  ex.prune(4.0);
  EXPECT_DOUBLE_EQ(q(ex, 5.0), 0.4);
}

TEST(JointTrajectoryExecutor, BadConstructionIsRefused) {
  EXPECT_THROW(pd::JointTrajectoryExecutor({}, {}, Eigen::VectorXd()), std::invalid_argument);
  EXPECT_THROW(pd::JointTrajectoryExecutor({"a", "a"}, {{}, {}}, Eigen::Vector2d::Zero()),
               std::invalid_argument);
  EXPECT_THROW(pd::JointTrajectoryExecutor({"a"}, {{1.0, -1.0, 1.0}}, Eigen::VectorXd::Zero(1)),
               std::invalid_argument);
  EXPECT_THROW(pd::JointTrajectoryExecutor({"a"}, {{-1.0, 1.0, 0.0}}, Eigen::VectorXd::Zero(1)),
               std::invalid_argument);
  EXPECT_THROW(pd::JointTrajectoryExecutor({"a"}, {{}}, Eigen::Vector2d::Zero()),
               std::invalid_argument);
  pd::ControllerRules no_stop;
  no_stop.stop_trajectory_duration_s = 0.0;
  EXPECT_THROW(pd::JointTrajectoryExecutor({"a"}, {{}}, Eigen::VectorXd::Zero(1), no_stop),
               std::invalid_argument);
}
