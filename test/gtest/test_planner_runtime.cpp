// core::PlannerRuntime: the CompensationPlanner's state around its TrialSequencer (the trial's
// start stamp and stops heard, the monitor's status, the heartbeat, the timers on explicit time,
// the breath source and phase), as the nodelet and the closed-loop engine run it.
#include "pedicle_drilling/core/control/planner_runtime.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>

#include "support.hpp"

namespace pd = pedicle_drilling::core;

namespace {

pd::TrialSequencerParams params() {
  pd::TrialSequencerParams p;
  p.arm_joints = {"rsssii_joint1", "rsssii_joint2", "rsssii_joint3",
                  "rsssii_joint4", "rsssii_joint5", "rsssii_joint6"};
  p.retreat.distance_m = 0.025;
  p.recognizer_timeout_s = 0.0;
  p.monitor_timeout_s = 0.0;
  p.controller_watch.enabled = false;
  p.depth_limit.require_plan = false;
  return p;
}

std::unique_ptr<pd::TrialSequencer> sequencer(const pd::TrialSequencerParams& p = params()) {
  const pd::KinematicChain arm = pd::KinematicChain::fromUrdfString(
      pedicle_drilling::test::workcellUrdf(), "world", "device_base");
  Eigen::VectorXd q(6);
  q << 0.0, 0.435859, 1.319709, 0.0, 1.386025, 0.0;  // config/drilling_pose.yaml
  return std::make_unique<pd::TrialSequencer>(p, pd::ArmCompensation(arm, q, 0.01));
}

pd::TrialRequest request(const std::string& mode) {
  pd::TrialRequest r;
  r.mode = mode;
  return r;
}

pd::MotionModel apModel() {
  pd::MotionModel m;
  m.axis(pd::Axis::kAP).q1 = 0.01;
  return m;
}

/** @brief Carries out a runtime's output as a driver on explicit time does: its timers. */
void carryOut(pd::PlannerRuntime* r, double now) {
  const pd::SequencerOutput out = r->sequencer().takeOutput();
  for (pd::TrialPhase p : out.phases) r->onPhase(p, now);
  r->applyTimers(out, now);
}

}  // namespace

TEST(PlannerRuntime, ConstructionRefusesNoSequencerABadPeriodOrABadAxis) {
  EXPECT_THROW(pd::PlannerRuntime(nullptr, 0.01), std::invalid_argument);
  EXPECT_THROW(pd::PlannerRuntime(sequencer(), 0.0), std::invalid_argument);
  pd::ForceAxis bad;
  bad.index = 3;
  EXPECT_THROW(pd::PlannerRuntime(sequencer(), 0.01, bad), std::invalid_argument);
  pd::ForceAxis minus_x;
  minus_x.index = 0;
  minus_x.sign = -1.0;
  const pd::PlannerRuntime r(sequencer(), 0.01, minus_x);
  EXPECT_EQ(r.thrustAxis().index, 0);
  EXPECT_DOUBLE_EQ(r.thrustAxis().thrust(Eigen::Vector3d(2.0, 0.0, 5.0)), -2.0);
}

TEST(PlannerRuntime, StartAnswersAsAPersonReadsAndAStopCountsFromTheTrialsStamp) {
  pd::PlannerRuntime r(sequencer(), 0.01);
  r.onStop(1.0, 1.0, true, "an earlier trial's stop");
  EXPECT_EQ(r.stopsHeard(), 1u);  // no trial yet: stamps from 0 count
  const pd::TrialStartAnswer bad = r.start(request("sideways"), apModel(), 5.0, 105.0);
  EXPECT_FALSE(bad.success);
  EXPECT_FALSE(bad.message.empty());
  EXPECT_EQ(r.sequencer().phase(), pd::TrialPhase::kIdle);
  const pd::TrialStartAnswer ok = r.start(request("stationary"), apModel(), 10.0, 110.0);
  ASSERT_TRUE(ok.success) << ok.message;
  EXPECT_EQ(ok.message, "trial started: stationary, spindle 12000 rpm");
  EXPECT_DOUBLE_EQ(r.trialStartStamp(), 110.0);
  EXPECT_EQ(r.stopsHeard(), 0u);
  // A latched stop stamped before the start is not this trial's: not counted, still handed on.
  r.onStop(10.5, 109.9, true, "latched");
  EXPECT_EQ(r.stopsHeard(), 0u);
  EXPECT_EQ(r.sequencer().phase(), pd::TrialPhase::kFailed);  // a stop before the drilling
  r.onStop(10.6, 110.0, false, "at the start");
  r.onStop(10.7, 110.5, false, "after it");
  EXPECT_EQ(r.stopsHeard(), 2u);
}

TEST(PlannerRuntime, AMonitorErrorDuringTheTrialIsAStopAndItsStatusKeepsItAlive) {
  pd::TrialSequencerParams p = params();
  p.monitor_timeout_s = 0.5;
  pd::PlannerRuntime r(sequencer(p), 0.01);
  ASSERT_TRUE(r.start(request("stationary"), apModel(), 10.0, 10.0).success);
  r.sequencer().takeOutput();
  // An ERROR stamped before the trial (the monitor's stop of an earlier one): alive, no stop.
  r.onMonitorStatus(10.2, 9.9, true, "stop and retreat: force_timeout");
  EXPECT_EQ(r.sequencer().phase(), pd::TrialPhase::kMovingToPose);
  r.onMonitorStatus(10.3, 10.3, false, "monitoring");
  EXPECT_EQ(r.sequencer().phase(), pd::TrialPhase::kMovingToPose);
  r.onMonitorStatus(10.4, 10.4, true, "stop and retreat: position_error");
  EXPECT_EQ(r.sequencer().phase(), pd::TrialPhase::kFailed);
  bool named = false;
  for (const pd::SequencerLog& line : r.sequencer().takeOutput().log) {
    named |= line.text.find("safety monitor ERROR: stop and retreat: position_error") !=
             std::string::npos;
  }
  EXPECT_TRUE(named);
  EXPECT_EQ(pd::PlannerRuntime::monitorErrorReason("x"), "safety monitor ERROR: x");
}

TEST(PlannerRuntime, TheHeartbeatIsDueFromATrialsFirstPhaseThenEveryPeriodUntilItEnds) {
  pd::PlannerRuntime r(sequencer(), 0.01);
  EXPECT_FALSE(r.running());
  EXPECT_FALSE(r.beatDue(0.0));  // idle: no heartbeat
  r.onPhase(pd::TrialPhase::kIdle, 0.5);
  EXPECT_FALSE(r.nextDue());
  r.onPhase(pd::TrialPhase::kMovingToPose, 1.0);
  EXPECT_TRUE(r.running());
  ASSERT_TRUE(r.nextDue());
  EXPECT_DOUBLE_EQ(*r.nextDue(), 1.0);
  EXPECT_TRUE(r.beatDue(1.0));
  EXPECT_FALSE(r.beatDue(1.005));
  EXPECT_DOUBLE_EQ(r.nextBeat(), 1.01);
  EXPECT_TRUE(r.beatDue(1.01 - 5e-10));         // 1e-9 s of rounding
  r.onPhase(pd::TrialPhase::kDrilling, 1.012);  // still running: the schedule stays
  EXPECT_FALSE(r.beatDue(1.015));
  EXPECT_TRUE(r.beatDue(1.02));
  r.onPhase(pd::TrialPhase::kDone, 1.025);
  EXPECT_FALSE(r.running());
  EXPECT_FALSE(r.beatDue(1.1));
  r.onPhase(pd::TrialPhase::kMovingToPose, 2.0);  // the next trial beats from its start
  EXPECT_TRUE(r.beatDue(2.0));
}

TEST(PlannerRuntime, DueTimersFireInOrderEachCarriedOutAndTheNextDueIsTheEarliest) {
  const pd::TrialSequencerParams p = params();
  pd::PlannerRuntime r(sequencer(p), 0.01);
  ASSERT_TRUE(r.start(request("stationary"), apModel(), 10.0, 10.0).success);
  carryOut(&r, 10.0);
  const double pose_due = 10.0 + p.move_duration_s + p.settle_s;
  // The heartbeat is due first (the trial runs from 10.0), then the spindle's keepalive.
  ASSERT_TRUE(r.nextDue());
  EXPECT_DOUBLE_EQ(*r.nextDue(), 10.0);
  ASSERT_TRUE(r.beatDue(10.0));
  ASSERT_TRUE(r.nextDue());
  EXPECT_DOUBLE_EQ(*r.nextDue(), 10.0 + std::min(0.01, p.spindle_keepalive_s));
  int carried = 0;
  const double now = pose_due - 0.01;
  r.fireDueTimers(now, [&] {
    ++carried;
    carryOut(&r, now);
  });
  EXPECT_GT(carried, 0);  // the keepalive, every period
  EXPECT_EQ(r.sequencer().phase(), pd::TrialPhase::kMovingToPose);
  carried = 0;
  r.fireDueTimers(pose_due, [&] {
    ++carried;
    carryOut(&r, pose_due);
  });
  EXPECT_EQ(r.sequencer().phase(), pd::TrialPhase::kRegistering);
  EXPECT_GE(carried, 1);
  // Nothing is due twice: the same time fires nothing more.
  carried = 0;
  r.fireDueTimers(pose_due, [&] { ++carried; });
  EXPECT_EQ(carried, 0);
}

TEST(PlannerRuntime, TheBreathPhaseComesFromTheTidalVolumeAndItsSourceIsNamed) {
  pd::PlannerRuntime r(sequencer(), 0.01);
  r.setTidalVolumeSource("/ns/tidal_volume", 2.0);
  EXPECT_FALSE(r.onTidalVolume(std::numeric_limits<double>::quiet_NaN(), 0.5));
  EXPECT_FALSE(r.onTidalVolume(10.0, std::numeric_limits<double>::infinity()));
  EXPECT_NE(r.sequencer().breathProblem(10.0).find("/ns/tidal_volume"), std::string::npos);
  pd::VentilatorSettings v;
  r.sequencer().setVentilator(v);
  EXPECT_TRUE(r.onTidalVolume(10.0, 0.5));  // the breath started at 9.5
  EXPECT_TRUE(r.sequencer().haveVentilator());
  EXPECT_EQ(r.sequencer().breathProblem(10.0), "");
  // Silent for more than two breath periods: the problem names the source.
  const double period = 60.0 / v.rate_bpm;
  EXPECT_NE(r.sequencer().breathProblem(9.5 + 2.5 * period).find("/ns/tidal_volume"),
            std::string::npos);
  r.onBreathSourceStatus("flow", "/ventilator/flow", false, "no breath detected yet");
  EXPECT_EQ(r.sequencer().breathProblem(10.0), "no breath detected yet");
  r.onBreathSourceStatus("flow", "/ventilator/flow", true, "");
  EXPECT_NE(r.sequencer()
                .breathProblem(9.5 + 2.5 * period)
                .find("flow on /ventilator/flow (via /ns/tidal_volume)"),
            std::string::npos);
  EXPECT_EQ(pd::PlannerRuntime::breathSourceName("/tv", "model", ""), "/tv");
  EXPECT_EQ(pd::PlannerRuntime::breathSourceName("/tv", "flow", "/f"), "flow on /f (via /tv)");
}

TEST(PlannerRuntime, StopsRankThePlannersOwnLastAndTheMonitorsBeforeOthers) {
  EXPECT_EQ(pd::PlannerRuntime::stopRank("/compensation_planner", "/compensation_planner"), 2);
  EXPECT_EQ(pd::PlannerRuntime::stopRank("/safety_monitor", "/compensation_planner"), 1);
  EXPECT_EQ(pd::PlannerRuntime::stopRank("/state_recognizer", "/compensation_planner"), 0);
}
