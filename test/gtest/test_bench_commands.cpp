// core::BenchCommandQueue and core::BenchCounters: the Simulator's commands in transit under
// the lockstep (due by core::CommandTransport's rule, handed out in the order received) and the
// trial's transport counters in its ground truth.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "pedicle_drilling/core/sim/bench_commands.hpp"

namespace pc = pedicle_drilling::core;

namespace {

pc::TrajectoryCommand startingAt(double start_s) {
  pc::TrajectoryCommand c;
  c.joint_names = {"feed_joint"};
  c.points.resize(1);
  c.points[0].time_s = start_s + 0.1;
  c.points[0].positions = {0.01};
  c.start_time_s = start_s;
  return c;
}

}  // namespace

TEST(BenchCommandQueue, CommandsAreDueAfterTheTransportDelayInTheOrderReceived) {
  pc::BenchCommandQueue queue(2e-3, 0.0, 7);
  queue.pushTrajectory(1.000, "feed_controller", startingAt(1.0));
  queue.pushSpindle(1.000, 12000.0);
  pc::TareRequest tare;
  queue.pushTare(1.001, tare);
  EXPECT_EQ(queue.size(), 3u);
  EXPECT_TRUE(queue.takeDue(1.001).empty());
  const std::vector<pc::PendingCommand> due = queue.takeDue(1.002);
  ASSERT_EQ(due.size(), 2u);
  ASSERT_TRUE(due[0].trajectory.has_value());
  EXPECT_EQ(due[0].controller, "feed_controller");
  EXPECT_FALSE(due[1].trajectory.has_value());
  EXPECT_FALSE(due[1].tare.has_value());
  EXPECT_DOUBLE_EQ(due[1].spindle_rpm, 12000.0);
  const std::vector<pc::PendingCommand> tare_due = queue.takeDue(1.003);
  ASSERT_EQ(tare_due.size(), 1u);
  EXPECT_TRUE(tare_due[0].tare.has_value());
  EXPECT_EQ(queue.size(), 0u);
}

TEST(BenchCommandQueue, TheJitterIsTheEnginesTransportAndKeepsTheOrder) {
  // The same seed, delay and jitter: each command due when CommandTransport says.
  pc::BenchCommandQueue queue(1e-3, 5e-3, 42);
  pc::CommandTransport transport(1e-3, 5e-3, 42);
  std::vector<double> expected;
  for (int i = 0; i < 20; ++i) {
    const double now = 0.001 * i;
    queue.pushTrajectory(now, "arm_controller", startingAt(now));
    expected.push_back(now + transport.delay(now));
  }
  double last = 0.0;
  std::size_t seen = 0;
  for (int step = 0; step < 100 && seen < expected.size(); ++step) {
    for (const pc::PendingCommand& c : queue.takeDue(0.001 * step)) {
      EXPECT_DOUBLE_EQ(c.due, expected[seen]) << seen;
      EXPECT_GE(c.due, last);  // never before the command sent before it
      last = c.due;
      ++seen;
    }
  }
  EXPECT_EQ(seen, expected.size());
}

TEST(BenchCommandQueue, ASpindleKeepaliveDrawsNoJitter) {
  pc::BenchCommandQueue queue(1e-3, 5e-3, 3);
  queue.pushSpindle(0.0, 12000.0);  // a change: drawn
  queue.pushSpindle(0.1, 12000.0);  // a keepalive: the bare delay
  std::vector<pc::PendingCommand> due = queue.takeDue(1.0);
  ASSERT_EQ(due.size(), 2u);
  EXPECT_NEAR(due[1].due, 0.101, 1e-12);
}

TEST(BenchCounters, CountsLateAndRejectedCommands) {
  pc::BenchCounters counters;
  counters.noteLateness(startingAt(1.0), 1.0004, 1000.0);  // within half a step: on time
  EXPECT_EQ(counters.late_commands, 0u);
  counters.noteLateness(startingAt(1.0), 1.0100, 1000.0);
  counters.noteLateness(startingAt(1.0), 1.0050, 1000.0);
  EXPECT_EQ(counters.late_commands, 2u);
  EXPECT_NEAR(counters.max_command_lateness_s, 0.01, 1e-12);
  counters.noteLateness(startingAt(std::numeric_limits<double>::quiet_NaN()), 5.0, 1000.0);
  EXPECT_EQ(counters.late_commands, 2u);  // no stamp: it starts now, never late
  pc::TargetResult result;
  counters.noteResult(result);
  result.status = pc::TargetStatus::kClamped;
  counters.noteResult(result);
  EXPECT_EQ(counters.rejected_commands, 0u);
  result.status = pc::TargetStatus::kRejected;
  counters.noteResult(result);
  EXPECT_EQ(counters.rejected_commands, 1u);
}
