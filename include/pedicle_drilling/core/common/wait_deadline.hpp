/**
 * @file wait_deadline.hpp
 * @brief A wall-time deadline for waiting on other processes that does not count the time the
 *        waiting thread itself was not running: when the whole machine stalls (a loaded or
 *        paused virtual machine, a suspended process group), the waiter and the awaited stop
 *        alike, and the stall is nobody's lateness. The simulator's lockstep waits with it.
 */
#pragma once

#include <algorithm>
#include <chrono>

namespace pedicle_drilling::core {

/**
 * @brief A deadline waited on in slices. A slice that ends later than it was due by more than
 *        the stall threshold means this thread did not run meanwhile: the deadline moves by
 *        that stall. Pure, with the clock's readings passed in (testable without waiting).
 */
class WaitDeadline {
 public:
  using Clock = std::chrono::steady_clock;

  /**
   * @param now the wait's start
   * @param timeout how long the awaited may take while this thread runs
   * @param stall_threshold a wake-up this much later than due counts as a stall
   */
  WaitDeadline(Clock::time_point now, Clock::duration timeout, Clock::duration stall_threshold)
      : deadline_(now + timeout), stall_threshold_(stall_threshold) {}

  /** @brief When the next wait slice of at most @p slice should end. */
  Clock::time_point sliceEnd(Clock::time_point now, Clock::duration slice) const {
    return std::min(deadline_, now + slice);
  }

  /** @brief A slice due to end at @p due ended at @p now; a stall extends the deadline. */
  void woke(Clock::time_point due, Clock::time_point now) {
    const Clock::duration late = now - due;
    if (late > stall_threshold_) {
      deadline_ += late;
      stalled_ += late;
    }
  }

  /** @brief True once the deadline (with the stalls added) has passed. */
  bool expired(Clock::time_point now) const { return now >= deadline_; }

  /** @brief The total stall added so far. */
  Clock::duration stalled() const { return stalled_; }

 private:
  Clock::time_point deadline_;
  Clock::duration stall_threshold_;
  Clock::duration stalled_{0};
};

}  // namespace pedicle_drilling::core
