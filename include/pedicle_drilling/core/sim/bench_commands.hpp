// The Simulator nodelet's command path, without ROS: the commands received under the lockstep,
// held until the step their transport delay (core::CommandTransport, the engine's rule) makes
// them due, and the counters of a trial's command transport that the ground truth reports.
#ifndef PEDICLE_DRILLING_CORE_SIM_BENCH_COMMANDS_HPP_
#define PEDICLE_DRILLING_CORE_SIM_BENCH_COMMANDS_HPP_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "pedicle_drilling/core/drilling/force_tare.hpp"
#include "pedicle_drilling/core/robot/target_result.hpp"
#include "pedicle_drilling/core/robot/trajectory_executor.hpp"
#include "pedicle_drilling/core/sim/closed_loop_engine.hpp"

namespace pedicle_drilling::core {

/**
 * @brief What a trial's command transport did (simulator/ground_truth's counters): cleared at
 *        every reset and start_trial.
 */
struct BenchCounters {
  std::uint32_t late_commands = 0;         ///< trajectories whose start passed before they arrived
  std::uint32_t rejected_commands = 0;     ///< trajectories a controller refused
  double max_command_lateness_s = 0.0;     ///< the latest of the late ones [s]
  std::uint32_t command_waits = 0;         ///< steps that waited for a trajectory (~command_wait_s)
  double command_wait_wall_s = 0.0;        ///< the wall time those waits took [s]
  std::uint32_t command_wait_expired = 0;  ///< waits that ran out
  std::uint32_t lockstep_timeouts = 0;     ///< steps a participant did not answer in time
  std::uint64_t lockstep_steps = 0;        ///< steps that waited for the participants
  std::uint64_t lockstep_skipped = 0;      ///< steps run without waiting

  /**
   * @brief Counts @p command late when its start passed before it arrived at @p now (half a
   *        physics step of rounding allowed); a ros_control controller starts it now.
   */
  void noteLateness(const TrajectoryCommand& command, double now, double physics_rate_hz);
  /** @brief Counts a trajectory a controller refused. */
  void noteResult(const TargetResult& result);
};

/** @brief A command received under the lockstep, due at the end of the first step at or after
 *         `due`. Exactly one of: a trajectory, a tare request, a spindle speed. */
struct PendingCommand {
  double due = 0.0;                             ///< sim time it takes effect [s]
  std::optional<TrajectoryCommand> trajectory;  ///< an arm or feed trajectory
  double spindle_rpm = 0.0;                     ///< the spindle speed (neither of the others)
  std::string controller;                       ///< the trajectory's controller
  std::optional<TareRequest> tare;              ///< a tare request
};

/**
 * @brief The commands in transit under the lockstep: each is due its CommandTransport delay
 *        after the step it was sent in, and the due ones are handed out in the order received
 *        (the engine's transport, its events due at a step handled after the step's
 *        measurements).
 */
class BenchCommandQueue {
 public:
  BenchCommandQueue() = default;
  /** @brief Empty, with a fresh transport for the trial of @p seed (CommandTransport). */
  BenchCommandQueue(double delay_s, double jitter_s, std::uint64_t seed)
      : transport_(delay_s, jitter_s, seed) {}

  /** @brief A trajectory for @p controller sent at @p now (a jitter draw). */
  void pushTrajectory(double now, const std::string& controller, const TrajectoryCommand& command);
  /** @brief A spindle speed sent at @p now (CommandTransport::spindleDelay). */
  void pushSpindle(double now, double rpm);
  /** @brief A tare request sent at @p now (no jitter draw: CommandTransport::undrawnDelay). */
  void pushTare(double now, const TareRequest& request);
  /** @brief Removes and returns the commands due by @p t, in the order received. */
  std::vector<PendingCommand> takeDue(double t);
  /** @brief The commands in transit. */
  std::size_t size() const { return pending_.size(); }

 private:
  CommandTransport transport_;
  std::vector<PendingCommand> pending_;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_SIM_BENCH_COMMANDS_HPP_
