// core::SimulatedBench: the Simulator nodelet's simulation with its trial state. Under the
// lockstep a command takes effect at the end of the step its transport delay makes it due;
// without it, at once; set_patient_amplitude applies from the next breath; a reset drops what
// was in transit, keeps the drivers' enable and draws the hold as the engine draws a trial's
// start.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "pedicle_drilling/core/sim/closed_loop_engine.hpp"
#include "pedicle_drilling/core/sim/simulated_bench.hpp"
#include "support.hpp"

namespace pc = pedicle_drilling::core;

namespace {

std::unique_ptr<pc::DrillingSimulation> simulation(std::uint64_t seed) {
  pc::DrillingSimulationParams p;
  p.spindle_watchdog_s = 0.0;
  auto sim =
      std::make_unique<pc::DrillingSimulation>(pedicle_drilling::test::workcellUrdf(), p, seed);
  sim->reset(seed, true);
  return sim;
}

/** @brief The outcomes the bench reports, as the nodelet logs them. */
struct Reported {
  std::vector<std::string> trajectories;  ///< "<controller>:<status>"
  std::vector<pc::TargetStatus> spindle;
  pc::BenchReports hooks() {
    pc::BenchReports r;
    r.trajectory = [this](const std::string& controller, const pc::TargetResult& result) {
      trajectories.push_back(controller + ":" + std::to_string(static_cast<int>(result.status)));
    };
    r.spindle = [this](const pc::TargetResult& result) { spindle.push_back(result.status); };
    return r;
  }
};

pc::StreamSchedule streams() { return pc::StreamSchedule(pc::StreamRates()); }

pc::TrajectoryCommand feedTo(double t, double position) {
  pc::TrajectoryCommand c;
  c.joint_names = {"feed_joint"};
  c.points.push_back({t, {position}, {}});
  return c;
}

}  // namespace

TEST(SimulatedBench, UnderTheLockstepACommandTakesEffectAtTheStepItIsDue) {
  Reported reported;
  pc::SimulatedBench bench(simulation(3), streams(), true, {3e-3, 0.0, 3}, reported.hooks());
  bench.step();
  const double sent = bench.sim().time();
  bench.commandSpindle(6000.0);
  int steps = 0;
  while (reported.spindle.empty() && steps < 20) {
    const pc::SimulatedBench::Step s = bench.step();
    bench.applyDue(s.step.time_s);
    ++steps;
  }
  ASSERT_EQ(reported.spindle.size(), 1u);
  EXPECT_EQ(reported.spindle[0], pc::TargetStatus::kAccepted);
  EXPECT_NEAR(bench.sim().time() - sent, 3e-3, 1e-9);  // the 3 ms transport
}

TEST(SimulatedBench, WithoutTheLockstepACommandIsTakenAtOnceAndCounted) {
  Reported reported;
  pc::SimulatedBench bench(simulation(4), streams(), false, {}, reported.hooks());
  bench.step();
  bench.commandSpindle(6000.0);
  ASSERT_EQ(reported.spindle.size(), 1u);
  const double now = bench.sim().time();
  bench.commandTrajectory("feed_controller", feedTo(now + 1.0, 0.001));
  pc::TrajectoryCommand bad = feedTo(now + 1.0, std::numeric_limits<double>::quiet_NaN());
  const pc::TargetResult r = bench.takeTrajectory("feed_controller", bad);
  EXPECT_EQ(r.status, pc::TargetStatus::kRejected);
  EXPECT_EQ(reported.trajectories,
            (std::vector<std::string>{"feed_controller:0", "feed_controller:2"}));
  EXPECT_EQ(bench.counters().rejected_commands, 1u);
  double end = -1.0;
  bench.trajectoryEnd("feed_controller", &end);
  EXPECT_NEAR(end, now + 1.0, 1e-9);  // the accepted one's end: the refused one changed nothing
  pc::TrajectoryCommand late = feedTo(now + 1.0, 0.002);
  late.start_time_s = now - 0.05;
  bench.takeTrajectory("feed_controller", late);
  EXPECT_EQ(bench.counters().late_commands, 1u);
  EXPECT_NEAR(bench.counters().max_command_lateness_s, 0.05, 1e-9);
  bench.startTrial();
  EXPECT_EQ(bench.counters().late_commands, 0u);  // a trial counts its own
  EXPECT_EQ(bench.counters().rejected_commands, 0u);
}

TEST(SimulatedBench, TheAmplitudeFactorAppliesFromTheNextBreath) {
  Reported reported;
  pc::SimulatedBench bench(simulation(5), streams(), false, {}, reported.hooks());
  bench.step();
  const long armed_in = bench.sim().ventilator().breathIndex();
  bench.setPatientAmplitude(1.3);
  std::optional<double> applied;
  long applied_in = -1;
  for (int i = 0; i < 20000 && !applied; ++i) {
    const pc::SimulatedBench::Step s = bench.step();
    applied = s.amplitude;
    applied_in = bench.sim().ventilator().breathIndex();
  }
  ASSERT_TRUE(applied.has_value());
  EXPECT_EQ(*applied, 1.3);
  EXPECT_EQ(applied_in, armed_in + 1);
  EXPECT_FALSE(bench.step().amplitude.has_value());  // once
}

TEST(SimulatedBench, AResetDropsTheCommandsInTransitAndDrawsTheHoldAsTheEngine) {
  Reported reported;
  pc::SimulatedBench bench(simulation(6), streams(), true, {5e-3, 0.0, 6}, reported.hooks());
  bench.step();
  bench.sim().onDriveEnable(true);
  bench.commandSpindle(6000.0);
  bench.setPatientAmplitude(2.0);
  bench.counters().command_waits = 3;
  const std::optional<double> hold = bench.reset(simulation(7), {1e-3, 0.0, 7}, true, 1.0);
  ASSERT_TRUE(hold.has_value());
  const double breath_s = 60.0 / bench.sim().trialConditions().ventilator_rate_bpm;
  EXPECT_EQ(*hold, pc::trialStartTime(7, bench.sim().time(), 1.0, breath_s, true));
  EXPECT_TRUE(bench.trial().holdAhead());
  EXPECT_TRUE(bench.trial().takeRestartPacing());
  EXPECT_EQ(bench.counters().command_waits, 0u);
  EXPECT_EQ(bench.sim().seed(), 7u);
  for (int i = 0; i < 20000; ++i) {
    const pc::SimulatedBench::Step s = bench.step();
    EXPECT_FALSE(s.amplitude.has_value());  // the old trial's factor was dropped
    bench.applyDue(s.step.time_s);
  }
  EXPECT_TRUE(reported.spindle.empty());     // the old trial's command never arrived
  EXPECT_FALSE(bench.sim().drivesHalted());  // no guard here: nothing to carry or halt
  EXPECT_FALSE(bench.reset(simulation(8), {}, false, 1.0).has_value());
  EXPECT_FALSE(bench.trial().holdAhead());
}
