// core::MonitorRuntime: the SafetyMonitor nodelet's logic around its supervisor and drill guard
// (the enable heartbeat, the planner's phase, the re-tare check, the status, the reset).
#include <gtest/gtest.h>

#include <string>

#include "pedicle_drilling/core/control/monitor_runtime.hpp"

namespace pc = pedicle_drilling::core;

namespace {

std::string value(const pc::MonitorStatus& s, const std::string& key) {
  for (const auto& [k, v] : s.values) {
    if (k == key) return v;
  }
  return "<none>";
}

}  // namespace

TEST(MonitorRuntime, BeatsTheEnableEveryPeriodAndAtOnceWhenItTurnsOff) {
  pc::DrillGuardParams guard;
  guard.heartbeat_period_s = 0.01;
  guard.planner_timeout_s = 0.06;
  pc::MonitorRuntime m(pc::SupervisorParams(), guard);
  std::optional<pc::EnableBeat> b = m.beat(0.0);
  ASSERT_TRUE(b);
  EXPECT_TRUE(b->enable);
  EXPECT_FALSE(b->turned_off);
  EXPECT_FALSE(m.beat(0.005));  // within the period
  EXPECT_DOUBLE_EQ(m.nextBeat(), 0.01);
  EXPECT_TRUE(m.beat(0.01));
  // A running trial whose planner never beats: the guard disables the drives, at once.
  m.onPlannerPhase(0.011, pc::TrialPhase::kDrilling, true);
  b = m.beat(0.1);
  ASSERT_TRUE(b);
  EXPECT_FALSE(b->enable);
  EXPECT_TRUE(b->turned_off);
  EXPECT_FALSE(m.lastEnable());
  EXPECT_FALSE(m.guard().reason().empty());
  b = m.beat(0.2);
  ASSERT_TRUE(b);
  EXPECT_FALSE(b->turned_off);  // only the first false turns it off
}

TEST(MonitorRuntime, TellsTheEndOfATrialAndOfARetreat) {
  pc::MonitorRuntime m{pc::SupervisorParams(), pc::DrillGuardParams()};
  EXPECT_FALSE(m.onPlannerPhase(0.0, pc::TrialPhase::kDrilling, true).trial_ended);
  EXPECT_TRUE(m.supervisor().trialRunning());
  EXPECT_TRUE(m.guard().plannerDrilling());
  EXPECT_FALSE(m.onPlannerPhase(0.1, pc::TrialPhase::kRetreating, true).trial_ended);
  const pc::PhaseChange done = m.onPlannerPhase(0.2, pc::TrialPhase::kDone, false);
  EXPECT_TRUE(done.trial_ended);
  EXPECT_TRUE(done.retreat_ended);
  EXPECT_FALSE(m.onPlannerPhase(0.3, pc::TrialPhase::kDone, false).trial_ended);  // once
  m.onPlannerPhase(0.4, pc::TrialPhase::kMovingToPose, true);
  const pc::PhaseChange failed_then_done = m.onPlannerPhase(0.5, pc::TrialPhase::kDone, false);
  EXPECT_TRUE(failed_then_done.trial_ended);
  EXPECT_FALSE(failed_then_done.retreat_ended);
}

TEST(MonitorRuntime, ReportsItsStatusAndTheStopUntilAReset) {
  pc::SupervisorParams p;
  p.safety.force_threshold_N = 10.0;
  pc::MonitorRuntime m(p, pc::DrillGuardParams());
  pc::MonitorStatus s = m.status();
  EXPECT_EQ(s.level, pc::MonitorStatus::Level::kOk);
  EXPECT_EQ(s.message, "waiting for force/tracker");
  EXPECT_EQ(value(s, "drives_enabled"), "true");
  EXPECT_EQ(value(s, "force_samples"), "0");
  m.onPlannerPhase(0.0, pc::TrialPhase::kDrilling, true);
  m.onForce(0.001, 0.001, 0.001, Eigen::Vector3d(0.0, 0.0, 50.0));  // over H2
  const std::optional<pc::SafetyVerdict> v = m.takeNewStop(0.001);
  ASSERT_TRUE(v);
  EXPECT_FALSE(m.takeNewStop(0.002));  // one report
  s = m.status();
  EXPECT_EQ(s.level, pc::MonitorStatus::Level::kError);
  EXPECT_EQ(s.message.rfind("stop and retreat: ", 0), 0u) << s.message;
  EXPECT_EQ(value(s, "force_samples"), "1");
  EXPECT_EQ(value(s, "trial_running"), "true");
  m.reset(0.01);
  s = m.status();
  EXPECT_NE(s.level, pc::MonitorStatus::Level::kError);
  EXPECT_EQ(value(s, "force_samples"), "0");
  EXPECT_TRUE(m.guard().plannerDrilling());  // the planner's phase stays
}

TEST(MonitorRuntime, KeepsTheRetareCheckUntilAReset) {
  pc::MonitorRuntime m{pc::SupervisorParams(), pc::DrillGuardParams()};
  const pc::RetareCheck none = m.checkRetare(1.0);
  EXPECT_FALSE(none.done);
  EXPECT_EQ(value(m.status(), "retare_offset_n"), "<none>");
}

TEST(MonitorRuntime, FindsTheChecksGrid) {
  EXPECT_TRUE(pc::MonitorRuntime::onCheckGrid(2000.005, 200.0));
  EXPECT_TRUE(pc::MonitorRuntime::onCheckGrid(0.01, 200.0));
  EXPECT_FALSE(pc::MonitorRuntime::onCheckGrid(0.012, 200.0));
}
