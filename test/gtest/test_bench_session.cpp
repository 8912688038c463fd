// core::BenchTrial, core::AtNextBreath, core::BreathWatch, core::DriverTrips and the reset's
// checks: the Simulator nodelet's trial bookkeeping, and the breath rules it shares with the
// closed-loop engine.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "pedicle_drilling/core/sim/bench_session.hpp"
#include "support.hpp"

namespace pc = pedicle_drilling::core;

TEST(BenchTrial, HoldsAtTheDrawnStartUntilResumed) {
  pc::BenchTrial trial;
  EXPECT_FALSE(trial.reachesHold(100.0));  // no reset: no hold
  EXPECT_EQ(trial.resume(), "no hold: sim time was running");
  trial.reset(2.5);
  EXPECT_TRUE(trial.takeRestartPacing());
  EXPECT_FALSE(trial.takeRestartPacing());  // once
  EXPECT_TRUE(trial.holdAhead());
  EXPECT_FALSE(trial.reachesHold(2.4));
  EXPECT_TRUE(trial.reachesHold(2.5 - 1e-10));
  trial.setHeld(true);
  EXPECT_FALSE(trial.holdAhead());
  const std::uint64_t generation = trial.generation();
  EXPECT_TRUE(trial.holds(generation));
  EXPECT_EQ(trial.resume(), "resumed at the trial's start");
  EXPECT_FALSE(trial.holds(generation));
  EXPECT_FALSE(trial.reachesHold(3.0));
}

TEST(BenchTrial, AResetEndsTheOldHoldAndAResumeBeforeItCancelsIt) {
  pc::BenchTrial trial;
  trial.reset(1.0);
  trial.setHeld(true);
  const std::uint64_t old = trial.generation();
  trial.reset(4.0);  // the new simulation's hold is ahead
  EXPECT_FALSE(trial.holds(old));
  EXPECT_TRUE(trial.holds(trial.generation()));
  EXPECT_FALSE(trial.held());
  EXPECT_EQ(trial.resume(), "the hold at the trial's start is cancelled");
  EXPECT_FALSE(trial.holdAhead());
}

TEST(BenchTrial, StarvedWhileStreamingPastTheLastTrajectoryUntilAWaitRunsOut) {
  pc::BenchTrial trial;
  const double step = 1e-3;
  EXPECT_FALSE(trial.starved(1.0, 2.0, step));  // not streaming: sim time runs
  trial.onPhase(true);
  EXPECT_FALSE(trial.starved(2.001, 2.0, step));  // the next step is covered
  EXPECT_TRUE(trial.starved(2.0005, 2.0, step));
  trial.giveUpWait();
  EXPECT_FALSE(trial.starved(1.0, 2.0, step));  // one wait, not one per step
  trial.onTrajectory();
  EXPECT_TRUE(trial.starved(1.0, 2.0, step));
  trial.giveUpWait();
  trial.onPhase(true);  // a phase ends the given-up wait too
  EXPECT_TRUE(trial.starved(1.0, 2.0, step));
  trial.reset(std::nullopt);  // an aborted trial's phase does not hold the next one
  EXPECT_FALSE(trial.starved(1.0, 2.0, step));
}

TEST(AtNextBreath, TakesEffectOnceInTheNextBreath) {
  pc::AtNextBreath next;
  EXPECT_FALSE(next.takeDue(0).has_value());
  next.arm(3, 1.3);
  EXPECT_TRUE(next.armed());
  EXPECT_FALSE(next.takeDue(3).has_value());
  EXPECT_EQ(next.takeDue(4), 1.3);
  EXPECT_FALSE(next.armed());
  EXPECT_FALSE(next.takeDue(5).has_value());
  next.arm(5, 2.0);
  next.clear();
  EXPECT_FALSE(next.takeDue(6).has_value());
}

TEST(BreathWatch, TellsEachBreathOnce) {
  pc::VentilatorSettings settings;
  settings.rate_bpm = 30.0;  // 2 s breaths
  pc::BreathScheduler ventilator(settings);
  pc::BreathWatch watch;
  int breaths = 0;
  for (int i = 0; i <= 5000; ++i) {  // 5 s at 1 ms: breaths 0, 1 and 2
    ventilator.sample(i * 1e-3);
    if (watch.newBreath(ventilator)) ++breaths;
  }
  EXPECT_EQ(breaths, 3);
  EXPECT_FALSE(watch.newBreath(ventilator));
  watch.clear();
  EXPECT_TRUE(watch.newBreath(ventilator));
}

TEST(DriverTrips, ReportsEachTripOfTheDrillGuardOnce) {
  pc::DrillingSimulationParams p;
  p.drive_guard_timeout_s = 0.05;
  pc::DrillingSimulation sim(pedicle_drilling::test::workcellUrdf(), p, 1);
  sim.reset(1, false);
  pc::DriverTrips trips;
  sim.onDriveEnable(true);
  sim.step(0.02);
  EXPECT_FALSE(trips.update(sim).drive_guard);
  sim.onDriveEnable(false);  // a halt at once
  sim.step(0.001);
  ASSERT_TRUE(sim.drivesHalted());
  EXPECT_TRUE(trips.update(sim).drive_guard);
  EXPECT_FALSE(trips.update(sim).drive_guard);  // reported already
  trips.clear();
  EXPECT_TRUE(trips.update(sim).drive_guard);  // a new simulation counts from 0
  EXPECT_FALSE(trips.update(sim).spindle_watchdog);
}

TEST(ResetTiming, RefusesATimeZeroOffTheGridAndAPreTrialOutOfRange) {
  EXPECT_EQ(pc::checkResetTiming(0, false, -1.0), "");  // no hold: pre_trial_s unused
  EXPECT_EQ(pc::checkResetTiming(1200000000ULL, true, 60.0), "");
  EXPECT_NE(pc::checkResetTiming(1250000000ULL, false, 0.0).find("time_zero"), std::string::npos);
  EXPECT_NE(pc::checkResetTiming(0, true, 60.5).find("pre_trial_s"), std::string::npos);
  EXPECT_NE(pc::checkResetTiming(0, true, std::nan("")).find("pre_trial_s"), std::string::npos);
}

TEST(ResetTiming, TimeZeroIsTheRequestWhenAheadElseTheNextGridPoint) {
  EXPECT_EQ(pc::trialTimeZeroNs(1234567890ULL, 0), 1300000000ULL);
  EXPECT_EQ(pc::trialTimeZeroNs(1200000000ULL, 0), 1300000000ULL);  // strictly after
  EXPECT_EQ(pc::trialTimeZeroNs(1234567890ULL, 5000000000ULL), 5000000000ULL);
  EXPECT_EQ(pc::trialTimeZeroNs(1234567890ULL, 1000000000ULL), 1300000000ULL);  // in the past
}

TEST(AmplitudeFactor, InZeroToTen) {
  EXPECT_EQ(pc::checkAmplitudeFactor(0.0), "");
  EXPECT_EQ(pc::checkAmplitudeFactor(10.0), "");
  EXPECT_NE(pc::checkAmplitudeFactor(10.5), "");
  EXPECT_NE(pc::checkAmplitudeFactor(-0.1), "");
  EXPECT_NE(pc::checkAmplitudeFactor(std::numeric_limits<double>::infinity()), "");
}

TEST(OwnFrames, LeavesTheTrackersFramesAndTheJointFramesToTheirOwners) {
  const auto frame = [](const std::string& child) {
    return pc::FrameTransform{"world", child, Eigen::Isometry3d::Identity()};
  };
  const std::vector<pc::FrameTransform> all = {frame("base_link"), frame("tracker_camera"),
                                               frame("tracker_marker"), frame("bone")};
  const auto children = [](const std::vector<pc::FrameTransform>& frames) {
    std::vector<std::string> names;
    for (const pc::FrameTransform& f : frames) names.push_back(f.child);
    return names;
  };
  EXPECT_EQ(children(pc::ownFrames(all, "", {})).size(), 4u);
  EXPECT_EQ(children(pc::ownFrames(all, "tracker_marker", {})),
            (std::vector<std::string>{"base_link", "bone"}));
  EXPECT_EQ(children(pc::ownFrames(all, "", {"bone", "tracker_marker"})),
            (std::vector<std::string>{"tracker_marker", "bone"}));
  EXPECT_EQ(children(pc::ownFrames(all, "tracker_marker", {"bone", "tracker_marker"})),
            (std::vector<std::string>{"bone"}));
}
