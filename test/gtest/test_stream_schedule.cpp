// core::StreamSchedule and core::DelayLine: which streams a physics step publishes, and the
// tracker samples held back by a latency (the schedule the closed-loop engine and the
// Simulator nodelet share).
#include <gtest/gtest.h>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/sim/stream_schedule.hpp"
#include "support.hpp"

namespace pc = pedicle_drilling::core;

TEST(StreamSchedule, PublishesEachStreamAtItsPeriodFromTheReset) {
  pc::StreamRates r;
  r.tracker_hz = 8.0;
  r.controller_state_hz = 50.0;
  r.ground_truth_hz = 20.0;
  r.tidal_volume_hz = 64.0;  // 15.6 steps: rounded to 16
  r.joint_state_hz = 100.0;
  r.tf_hz = 100.0;
  r.safety_check_hz = 200.0;
  const pc::StreamSchedule schedule(r);
  pc::DrillingSimulation sim(pedicle_drilling::test::workcellUrdf(), pc::DrillingSimulationParams(),
                             3);
  sim.reset(3, false);
  int tracker = 0;
  int force = 0;
  for (std::uint64_t n = 1; n <= 1000; ++n) {
    pc::SimulationStep step = sim.stepOnce();
    const pc::StreamsDue due = schedule.at(n, step, sim);
    EXPECT_EQ(due.controller_states, n % 20 == 0) << n;
    EXPECT_EQ(due.ground_truth, n % 50 == 0 || step.layer_changed) << n;
    EXPECT_EQ(due.tidal_volume, n % 16 == 0) << n;
    EXPECT_EQ(due.joint_states, n % 10 == 0) << n;
    EXPECT_EQ(due.tf, n % 10 == 0) << n;
    EXPECT_EQ(due.safety_check, n % 5 == 0) << n;
    EXPECT_EQ(due.force, step.force_sampled) << n;
    EXPECT_EQ(due.tracker, sim.trackerDue(125)) << n;
    tracker += due.tracker;
    force += due.force;
    if (due.force || due.controller_states) {
      EXPECT_TRUE(due.any());
    }
  }
  EXPECT_EQ(tracker, 8);  // 8 Hz, at the simulation's own phase
  EXPECT_GT(force, 0);    // every sensor sample, whatever its rate
  // A step's ground truth is also published where the layer changes.
  pc::SimulationStep step;
  step.force_sampled = false;
  step.layer_changed = true;
  EXPECT_TRUE(schedule.at(7, step, sim).ground_truth);
}

TEST(StreamSchedule, AStreamMayBeOffOnlyWhereItIsOptional) {
  pc::StreamRates r;  // the engine's defaults: no joint states, tf or checks
  const pc::StreamSchedule schedule(r);
  EXPECT_TRUE(schedule.tidalVolumeOn());
  EXPECT_FALSE(schedule.safetyCheckOn());
  pc::DrillingSimulation sim(pedicle_drilling::test::workcellUrdf(), pc::DrillingSimulationParams(),
                             1);
  pc::SimulationStep step;
  step.force_sampled = false;
  const pc::StreamsDue due = schedule.at(1000, step, sim);
  EXPECT_FALSE(due.joint_states);
  EXPECT_FALSE(due.tf);
  EXPECT_FALSE(due.safety_check);
  r.tidal_volume_hz = 0.0;
  EXPECT_FALSE(pc::StreamSchedule(r).tidalVolumeOn());
  r.tracker_hz = 0.0;  // required
  try {
    pc::StreamSchedule bad(r);
    FAIL() << "a tracker at 0 Hz was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("tracker_rate_hz"), std::string::npos) << e.what();
  }
  r.tracker_hz = 8.0;
  r.tf_hz = 2000.0;  // above the physics rate
  EXPECT_THROW(pc::StreamSchedule{r}, std::invalid_argument);
}

TEST(StreamSchedule, TheStepIndexIsTheStepsSinceTheReset) {
  EXPECT_EQ(pc::StreamSchedule::stepIndex(0.001, 1000.0), 1u);
  EXPECT_EQ(pc::StreamSchedule::stepIndex(2.0000000001, 1000.0), 2000u);
  EXPECT_EQ(pc::StreamSchedule::stepIndex(1.9999999999, 1000.0), 2000u);
}

TEST(DelayLine, HoldsEachMessageForItsLatencyInOrder) {
  pc::DelayLine<int> line;
  EXPECT_FALSE(line.delays());
  line.setDelay(0.014);
  EXPECT_TRUE(line.delays());
  line.push(1.000, 1);
  line.push(1.001, 2);
  EXPECT_FALSE(line.due(1.013));
  EXPECT_TRUE(line.due(1.014));
  std::vector<int> sent;
  line.deliverDue(1.014, [&sent](int v) { sent.push_back(v); });
  EXPECT_EQ(sent, std::vector<int>({1}));
  line.deliverDue(1.0150000000005, [&sent](int v) { sent.push_back(v); });  // within 1 ns
  EXPECT_EQ(sent, std::vector<int>({1, 2}));
  EXPECT_FALSE(line.due(10.0));
  line.push(2.0, 3);
  line.clear();
  EXPECT_FALSE(line.due(10.0));
}
