// Tests of the drill guard: the planner's heartbeat, the unanswered stop, the drivers' watch.
#include <gtest/gtest.h>

#include <limits>
#include <stdexcept>

#include "pedicle_drilling/core/control/drill_guard.hpp"

namespace pedicle_drilling::core {
namespace {

TEST(DrillGuardTest, AnIdlePlannerNeedsNoHeartbeat) {
  DrillGuard g;
  EXPECT_TRUE(g.enabled(0.0));
  EXPECT_TRUE(g.enabled(100.0));  // no trial: nothing feeds, nothing watched
  EXPECT_EQ(g.quietUntil(), std::numeric_limits<double>::infinity());
}

TEST(DrillGuardTest, APlannerThatFallsSilentDuringItsTrialDisablesWithinItsTimeout) {
  DrillGuardParams p;  // planner_timeout_s 0.06
  DrillGuard g(p);
  g.onPlannerPhase(1.0, true, false);
  double t = 1.0;
  for (int ms = 1000; ms < 3000; ++ms) {  // 1 ms checks; a beat every 20 ms until 1.98 s
    t = ms * 1e-3;
    if (ms < 2000 && ms % 20 == 0) g.onPlannerHeartbeat(t);
    if (!g.enabled(t)) break;
  }
  EXPECT_FALSE(g.enabled(t));
  // The last beat was at 1.98 s: disabled at the first 1 ms check at or past 1.98 + the timeout
  // (the sum's rounding decides between the two).
  EXPECT_GE(t, 1.98 + p.planner_timeout_s - 1e-9);
  EXPECT_LT(t, 1.98 + p.planner_timeout_s + 0.0015);
  EXPECT_NE(g.reason().find("planner_lost"), std::string::npos) << g.reason();
  // Latched: a beat that comes back does not re-enable the drives (the trial is lost).
  g.onPlannerHeartbeat(t);
  EXPECT_FALSE(g.enabled(t));
  g.reset();
  EXPECT_TRUE(g.enabled(t));
}

TEST(DrillGuardTest, AStopThePlannerDoesNotAnswerDisables) {
  DrillGuard g;  // stop_ack_timeout_s 0.1
  g.onPlannerPhase(0.0, true, true);
  for (double t = 0.0; t < 0.5; t += 0.01) g.onPlannerHeartbeat(t);
  g.onMonitorStop(0.5);
  g.onPlannerHeartbeat(0.55);
  EXPECT_TRUE(g.enabled(0.55));
  EXPECT_DOUBLE_EQ(g.quietUntil(), 0.6);
  g.onPlannerHeartbeat(0.59);
  EXPECT_TRUE(g.enabled(0.6));
  EXPECT_FALSE(g.enabled(0.601));
  EXPECT_NE(g.reason().find("stop_unanswered"), std::string::npos) << g.reason();
}

TEST(DrillGuardTest, AStopThePlannerAnswersKeepsTheDrivesForTheRetreat) {
  DrillGuard g;
  g.onPlannerPhase(0.0, true, true);
  g.onMonitorStop(0.5);
  g.onPlannerHeartbeat(0.501);
  g.onPlannerPhase(0.501, true, false);  // retreating
  for (double t = 0.501; t < 3.0; t += 0.02) {
    g.onPlannerHeartbeat(t);
    EXPECT_TRUE(g.enabled(t)) << t;
  }
  g.onPlannerPhase(3.0, false, false);  // done: the heartbeat is no longer watched
  EXPECT_TRUE(g.enabled(10.0));
}

TEST(DrillGuardTest, AStopBeforeTheDrillingMustEndTheDrillingToo) {
  DrillGuard g;                        // stop_ack_timeout_s 0.1
  g.onPlannerPhase(0.0, true, false);  // registering
  g.onPlannerHeartbeat(0.5);
  g.onMonitorStop(0.5);  // the planner ignores it and starts drilling at 0.52
  g.onPlannerPhase(0.52, true, true);
  g.onPlannerHeartbeat(0.6);
  EXPECT_TRUE(g.enabled(0.62));
  EXPECT_FALSE(g.enabled(0.621));
  EXPECT_NE(g.reason().find("stop_unanswered"), std::string::npos) << g.reason();
}

TEST(DrillGuardTest, AResetKeepsARunningPlannerWatched) {
  DrillGuard g;
  g.onPlannerPhase(0.0, true, true);
  g.onPlannerHeartbeat(0.5);
  g.reset();  // the monitor's reset: the planner's trial still runs, its heartbeat still counts
  EXPECT_TRUE(g.plannerRunning());
  EXPECT_TRUE(g.enabled(0.55));
  EXPECT_FALSE(g.enabled(0.5 + g.params().planner_timeout_s + 1e-3));
  EXPECT_NE(g.reason().find("planner_lost"), std::string::npos) << g.reason();
}

TEST(DrillGuardTest, ParametersAreChecked) {
  DrillGuardParams p;
  p.planner_timeout_s = 0.01;  // shorter than the heartbeat period
  EXPECT_THROW(DrillGuard{p}, std::invalid_argument);
  p = DrillGuardParams();
  p.stop_ack_timeout_s = std::numeric_limits<double>::infinity();
  try {
    DrillGuard g(p);
    FAIL() << "an infinite stop_ack timeout was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("guard_stop_ack_timeout_s", 0), 0u) << e.what();
  }
}

TEST(DriveGuardWatchTest, FailsClosedBeforeAnyMessageAndAfterTheTimeout) {
  DriveGuardWatch w(0.05);
  EXPECT_FALSE(w.allows(0.0));
  EXPECT_NE(w.why(0.0), "");
  w.onEnable(1.0, true);
  EXPECT_TRUE(w.allows(1.0));
  EXPECT_TRUE(w.allows(1.049));
  EXPECT_FALSE(w.allows(1.0501));
  EXPECT_NE(w.why(1.06).find("no drill_guard/enable"), std::string::npos);
  w.onEnable(1.07, true);
  EXPECT_TRUE(w.allows(1.07));
  w.onEnable(1.08, false);
  EXPECT_FALSE(w.allows(1.08));
  w.reset();
  EXPECT_FALSE(w.allows(1.08));
  EXPECT_THROW(DriveGuardWatch(0.0), std::invalid_argument);
  EXPECT_THROW(DriveGuardWatch(std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
}

}  // namespace
}  // namespace pedicle_drilling::core
