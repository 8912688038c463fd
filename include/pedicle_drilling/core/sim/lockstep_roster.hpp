// The Simulator's side of the lockstep (doc/running.md, "Lockstep"), without ROS: the
// participants as their latest answers on simulator/step_ack say, whether a step waits for them,
// whether all answered it, and which stayed silent (LockstepRoster); the stepping thread's wait
// for their answers against a wall-clock deadline (LockstepGate). Stamps are ROS times in
// nanoseconds (the exact order of ros::Time, no rounding).
#ifndef PEDICLE_DRILLING_CORE_SIM_LOCKSTEP_ROSTER_HPP_
#define PEDICLE_DRILLING_CORE_SIM_LOCKSTEP_ROSTER_HPP_

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace pedicle_drilling::core {

/**
 * @brief The lockstep's participants: each joins with its first answer, is dropped when it
 *        misses a step's deadline (dropSilent), and joins again with its next answer. Not
 *        thread-safe: the caller serialises access.
 */
class LockstepRoster {
 public:
  /**
   * @brief The answer of @p node to the step at @p stamp_ns, needing @p next_step_ns next
   *        (0: every step). An answer older than the one already heard is ignored.
   */
  void answer(const std::string& node, std::uint64_t stamp_ns, std::uint64_t next_step_ns);

  /** @brief Every participant answered the step at @p step_ns (true with none). */
  bool allAnswered(std::uint64_t step_ns) const;

  /**
   * @brief The step at @p step_ns waits for the participants for their own sake: there are
   *        none yet (one joins with its first answer), or one needs every step (next step 0),
   *        or it is one's next step.
   */
  bool wantsStep(std::uint64_t step_ns) const;

  /** @brief Drops and returns (in name order) the participants that did not answer the step
   *         at @p step_ns. */
  std::vector<std::string> dropSilent(std::uint64_t step_ns);

  /** @brief The number of participants. */
  std::size_t size() const { return participants_.size(); }

 private:
  /** @brief A participant as its latest answer says. */
  struct Participant {
    std::uint64_t answered_ns = 0;   ///< the latest step it answered
    std::uint64_t next_step_ns = 0;  ///< the next step it needs (0: every step)
  };
  std::map<std::string, Participant> participants_;
};

/**
 * @brief The lockstep's participants shared between the threads that hear their answers and
 *        the stepping thread that waits for them: thread-safe.
 */
class LockstepGate {
 public:
  /** @brief A participant silent for @p timeout_s of wall time is dropped (~lockstep_timeout_s). */
  explicit LockstepGate(double timeout_s = 5.0) : timeout_s_(timeout_s) {}

  /** @brief An answer (LockstepRoster::answer); wakes the waiting thread. */
  void answer(const std::string& node, std::uint64_t stamp_ns, std::uint64_t next_step_ns);
  /** @brief LockstepRoster::wantsStep. */
  bool wantsStep(std::uint64_t step_ns) const;

  /** @brief How a wait ended. */
  struct WaitResult {
    std::vector<std::string> dropped;  ///< the participants dropped for their silence
    double stalled_s = 0.0;  ///< wall time this thread did not run (not counted against them)
    bool timed_out = false;  ///< a participant did not answer in time (dropped)
  };
  /**
   * @brief Waits until every participant answered the step at @p step_ns. After the timeout
   *        of wall time the silent ones are dropped (until they answer again). A freeze of the
   *        machine stops this thread and the participants alike: a wake-up over 0.5 s late
   *        moves the deadline by as much. Ends early, dropping nobody, when @p keep_waiting
   *        (asked at least every 50 ms) is false.
   */
  WaitResult wait(std::uint64_t step_ns, const std::function<bool()>& keep_waiting);
  /** @brief Wakes a waiting thread (to ask keep_waiting at once). */
  void wake() { cv_.notify_all(); }

 private:
  double timeout_s_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  LockstepRoster roster_;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_SIM_LOCKSTEP_ROSTER_HPP_
