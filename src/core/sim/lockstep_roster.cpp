#include "pedicle_drilling/core/sim/lockstep_roster.hpp"

#include <chrono>

#include "pedicle_drilling/core/common/wait_deadline.hpp"

namespace pedicle_drilling::core {

void LockstepRoster::answer(const std::string& node, std::uint64_t stamp_ns,
                            std::uint64_t next_step_ns) {
  Participant& p = participants_[node];
  if (stamp_ns < p.answered_ns) return;
  p.answered_ns = stamp_ns;
  p.next_step_ns = next_step_ns;
}

bool LockstepRoster::allAnswered(std::uint64_t step_ns) const {
  for (const auto& participant : participants_) {
    if (participant.second.answered_ns < step_ns) return false;
  }
  return true;
}

bool LockstepRoster::wantsStep(std::uint64_t step_ns) const {
  if (participants_.empty()) return true;
  for (const auto& participant : participants_) {
    const Participant& p = participant.second;
    if (p.next_step_ns == 0 || p.next_step_ns <= step_ns) return true;
  }
  return false;
}

std::vector<std::string> LockstepRoster::dropSilent(std::uint64_t step_ns) {
  std::vector<std::string> dropped;
  for (auto it = participants_.begin(); it != participants_.end();) {
    if (it->second.answered_ns < step_ns) {
      dropped.push_back(it->first);
      it = participants_.erase(it);
    } else {
      ++it;
    }
  }
  return dropped;
}

void LockstepGate::answer(const std::string& node, std::uint64_t stamp_ns,
                          std::uint64_t next_step_ns) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    roster_.answer(node, stamp_ns, next_step_ns);
  }
  cv_.notify_all();
}

bool LockstepGate::wantsStep(std::uint64_t step_ns) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return roster_.wantsStep(step_ns);
}

LockstepGate::WaitResult LockstepGate::wait(std::uint64_t step_ns,
                                            const std::function<bool()>& keep_waiting) {
  using Clock = std::chrono::steady_clock;
  std::unique_lock<std::mutex> lock(mutex_);
  WaitDeadline deadline(
      Clock::now(),
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(timeout_s_)),
      std::chrono::milliseconds(500));
  while (keep_waiting() && !roster_.allAnswered(step_ns) && !deadline.expired(Clock::now())) {
    const Clock::time_point due = deadline.sliceEnd(Clock::now(), std::chrono::milliseconds(50));
    cv_.wait_until(lock, due);
    deadline.woke(due, Clock::now());
  }
  WaitResult result;
  result.stalled_s = std::chrono::duration<double>(deadline.stalled()).count();
  if (!keep_waiting() || roster_.allAnswered(step_ns)) return result;
  result.dropped = roster_.dropSilent(step_ns);
  result.timed_out = true;
  return result;
}

}  // namespace pedicle_drilling::core
