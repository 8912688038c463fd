// The lockstep's wall-time deadline (core::WaitDeadline): a stall of the waiting thread itself
// is not counted against the awaited.
#include <gtest/gtest.h>

#include <chrono>

#include "pedicle_drilling/core/common/wait_deadline.hpp"

namespace pedicle_drilling::core {
namespace {

using Clock = WaitDeadline::Clock;
using std::chrono::milliseconds;

TEST(WaitDeadline, ExpiresAfterItsTimeoutWhenTheWaiterRuns) {
  const Clock::time_point t0{};
  WaitDeadline deadline(t0, milliseconds(5000), milliseconds(500));
  Clock::time_point now = t0;
  int slices = 0;
  while (!deadline.expired(now)) {
    const Clock::time_point due = deadline.sliceEnd(now, milliseconds(50));
    now = due + milliseconds(2);  // woke a little late, as a loaded thread does
    deadline.woke(due, now);
    ++slices;
  }
  EXPECT_EQ(deadline.stalled(), Clock::duration(0));
  EXPECT_GE(now - t0, milliseconds(5000));
  EXPECT_LT(now - t0, milliseconds(5100));
  EXPECT_GE(slices, 90);
}

TEST(WaitDeadline, AStallOfTheWaiterMovesTheDeadline) {
  const Clock::time_point t0{};
  WaitDeadline deadline(t0, milliseconds(5000), milliseconds(500));
  const Clock::time_point due = deadline.sliceEnd(t0 + milliseconds(1000), milliseconds(50));
  EXPECT_EQ(due, t0 + milliseconds(1050));
  // The machine froze for 8 s during this slice: without the stall the deadline had passed.
  const Clock::time_point after = due + milliseconds(8000);
  deadline.woke(due, after);
  EXPECT_EQ(deadline.stalled(), milliseconds(8000));
  EXPECT_FALSE(deadline.expired(after));
  EXPECT_FALSE(deadline.expired(t0 + milliseconds(12999)));
  EXPECT_TRUE(deadline.expired(t0 + milliseconds(13000)));
}

TEST(WaitDeadline, ALateWakeUpBelowTheThresholdIsTheAwaitedsTime) {
  const Clock::time_point t0{};
  WaitDeadline deadline(t0, milliseconds(1000), milliseconds(500));
  const Clock::time_point due = deadline.sliceEnd(t0, milliseconds(50));
  deadline.woke(due, due + milliseconds(500));  // exactly the threshold: not a stall
  EXPECT_EQ(deadline.stalled(), Clock::duration(0));
  EXPECT_TRUE(deadline.expired(t0 + milliseconds(1000)));
}

TEST(WaitDeadline, TheLastSliceEndsAtTheDeadline) {
  const Clock::time_point t0{};
  WaitDeadline deadline(t0, milliseconds(120), milliseconds(500));
  EXPECT_EQ(deadline.sliceEnd(t0 + milliseconds(100), milliseconds(50)), t0 + milliseconds(120));
}

}  // namespace
}  // namespace pedicle_drilling::core
