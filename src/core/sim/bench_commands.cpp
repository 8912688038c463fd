#include "pedicle_drilling/core/sim/bench_commands.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

namespace pedicle_drilling::core {

void BenchCounters::noteLateness(const TrajectoryCommand& command, double now,
                                 double physics_rate_hz) {
  const double half_step = 0.5 / physics_rate_hz;
  if (std::isfinite(command.start_time_s) && command.start_time_s < now - half_step) {
    ++late_commands;
    max_command_lateness_s = std::max(max_command_lateness_s, now - command.start_time_s);
  }
}

void BenchCounters::noteResult(const TargetResult& result) {
  if (result.status == TargetStatus::kRejected) ++rejected_commands;
}

void BenchCommandQueue::pushTrajectory(double now, const std::string& controller,
                                       const TrajectoryCommand& command) {
  const double due = now + transport_.delay(now);
  pending_.push_back({due, command, 0.0, controller, std::nullopt});
}

void BenchCommandQueue::pushSpindle(double now, double rpm) {
  const double due = now + transport_.spindleDelay(now, rpm);
  pending_.push_back({due, std::nullopt, rpm, "", std::nullopt});
}

void BenchCommandQueue::pushTare(double now, const TareRequest& request) {
  const double due = now + transport_.undrawnDelay(now);
  pending_.push_back({due, std::nullopt, 0.0, "", request});
}

std::vector<PendingCommand> BenchCommandQueue::takeDue(double t) {
  std::vector<PendingCommand> due;
  std::vector<PendingCommand> later;
  for (PendingCommand& c : pending_) {
    (c.due <= t + 1e-9 ? due : later).push_back(std::move(c));
  }
  pending_.swap(later);
  return due;
}

}  // namespace pedicle_drilling::core
