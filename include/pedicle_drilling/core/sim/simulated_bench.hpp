// The Simulator nodelet's simulation with its trial state, without ROS: a physics step and the
// streams it publishes, the commands (taken at once, or under the lockstep held for their step by
// the engine's transport), the trial's counters, the patient's amplitude from the next breath, a
// reset to a new simulation with its hold, a trial's start, and the stepping thread's waits (for
// the planner's next trajectory, at the hold) with the real-time pacing (BenchPacer).
#ifndef PEDICLE_DRILLING_CORE_SIM_SIMULATED_BENCH_HPP_
#define PEDICLE_DRILLING_CORE_SIM_SIMULATED_BENCH_HPP_

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "pedicle_drilling/core/sim/bench_commands.hpp"
#include "pedicle_drilling/core/sim/bench_session.hpp"
#include "pedicle_drilling/core/sim/drilling_simulation.hpp"
#include "pedicle_drilling/core/sim/stream_schedule.hpp"

namespace pedicle_drilling::core {

/** @brief Where the outcome of each command goes (the nodelet logs them). */
struct BenchReports {
  /** @brief A trajectory's outcome for a controller (after the counters took it). */
  std::function<void(const std::string& controller, const TargetResult&)> trajectory;
  /** @brief A spindle speed command's outcome. */
  std::function<void(const TargetResult&)> spindle;
};

/** @brief The command path's transport (CommandTransport) of a trial. */
struct BenchTransport {
  double delay_s = 1e-3;   ///< sim time from a command's step to its effect (under the lockstep)
  double jitter_s = 0.0;   ///< extra delay, uniform in [0, jitter_s], drawn from the seed
  std::uint64_t seed = 1;  ///< the trial's seed (the jitter's draws)
};

/**
 * @brief Paces sim time at a real-time factor: sim time t is due (t - sim0) / factor of wall
 *        time after the restart at sim0 (a hold, a reset or a wait restart it, instead of
 *        catching up flat out).
 */
class BenchPacer {
 public:
  /** @brief At @p real_time_factor (0: as fast as possible). */
  explicit BenchPacer(double real_time_factor = 1.0) : factor_(real_time_factor) {}
  /** @brief Sim time @p sim_time is now. */
  void restart(double sim_time) {
    wall0_ = std::chrono::steady_clock::now();
    sim0_ = sim_time;
  }
  /** @brief Sleeps until sim time @p t is due, when more than 1 ms ahead (fewer system calls).
   *  @return false: no pacing (factor 0). */
  bool pace(double t) const;

 private:
  double factor_;
  std::chrono::steady_clock::time_point wall0_ = std::chrono::steady_clock::now();
  double sim0_ = 0.0;
};

/**
 * @brief The simulated bench of the Simulator nodelet. Not thread-safe: the nodelet serialises
 *        access with its mutex, and the waits take the caller's lock on it.
 */
class SimulatedBench {
 public:
  /**
   * @brief Around @p sim: the streams of @p streams; under the @p lockstep the commands travel
   *        by @p transport; each command's outcome goes to @p reports.
   */
  SimulatedBench(std::unique_ptr<DrillingSimulation> sim, const StreamSchedule& streams,
                 bool lockstep, const BenchTransport& transport, BenchReports reports);

  /** @brief The simulation (replaced by reset()). */
  DrillingSimulation& sim() { return *sim_; }
  /** @brief The simulation (replaced by reset()). */
  const DrillingSimulation& sim() const { return *sim_; }
  /** @brief The hold and the planner's phases. */
  BenchTrial& trial() { return trial_; }
  /** @brief The trial's transport counters (the ground truth's). */
  BenchCounters& counters() { return counters_; }
  /** @brief The streams' schedule. */
  const StreamSchedule& streams() const { return streams_; }

  /** @brief One physics step (BenchStep). */
  struct Step {
    SimulationStep step;              ///< what the simulation did
    std::uint64_t n = 0;              ///< the step's index since the reset
    StreamsDue due;                   ///< the streams it publishes
    std::optional<double> amplitude;  ///< set_patient_amplitude's factor, from this breath
  };
  /** @brief Steps the physics once; an amplitude factor armed in an earlier breath applies. */
  Step step();
  /** @brief The end of the step at @p t: the commands in transit due by then, in order. */
  void applyDue(double t);

  /** @brief A trajectory for @p controller: under the lockstep queued, else taken now. */
  void commandTrajectory(const std::string& controller, const TrajectoryCommand& command);
  /**
   * @brief A trajectory taken now (a command topic without the lockstep, an action's goal):
   *        counted late or rejected, and a given-up wait for commands ends.
   */
  TargetResult takeTrajectory(const std::string& controller, const TrajectoryCommand& command);
  /** @brief The time @p controller's trajectory ends (unchanged if no such controller). */
  void trajectoryEnd(const std::string& controller, double* end_s) const;
  /** @brief A spindle speed [rpm]: under the lockstep queued, else taken now. */
  void commandSpindle(double rpm);
  /** @brief A validated tare request: under the lockstep queued, else taken now. */
  void requestTare(const TareRequest& request);
  /** @brief The patient's AP displacement x @p factor from the next breath until the reset. */
  void setPatientAmplitude(double factor);

  /**
   * @brief The reset to @p fresh (already reset to its seed): the drivers' enable carries
   *        over, the commands in transit and the armed amplitude are dropped, the transport
   *        starts again with @p transport, the counters and the trips from 0. With @p hold, the
   *        trial's start is drawn as the engine draws it (trialStartTime, @p pre_trial_s, a
   *        breath phase from the seed) and sim time holds there.
   * @return the hold's sim time, if any.
   */
  std::optional<double> reset(std::unique_ptr<DrillingSimulation> fresh,
                              const BenchTransport& transport, bool hold, double pre_trial_s);
  /** @brief simulator/start_trial (DrillingSimulation::startTrial); the counters from 0.
   *  @return true: a drilled specimen was replaced. */
  bool startTrial();
  /** @brief The drivers' trips not reported yet. */
  NewTrips newTrips() { return trips_.update(*sim_); }

  /** @brief Wakes the waits below (a trajectory, a phase, a resume, a reset, a shutdown). */
  void notify() { cv_.notify_all(); }
  /** @brief How waitForCommand ended. */
  enum class CommandWait {
    kNone,     ///< no wait: not starved, under the lockstep, or no wait allowed
    kArrived,  ///< a trajectory (or a phase) came
    kExpired,  ///< none within the time: sim time steps on, the arm holds (counted)
  };
  /**
   * @brief While the planner streams trajectories (BenchTrial::starved), waits up to
   *        @p wait_s of wall time for the next one rather than step past the end of the last
   *        one received: sim time waits for the planner, as a lockstep would, so that a loaded
   *        machine slows the trial down instead of making the arm hold and then rush. Counted
   *        in the counters. @p lock holds the mutex guarding this bench; @p running (asked
   *        every 50 ms and at each notify) false ends the wait.
   */
  CommandWait waitForCommand(std::unique_lock<std::mutex>& lock, double wait_s,
                             const std::function<bool()>& running);
  /**
   * @brief At the trial's start drawn by the last reset: sim time stops until the resume, or
   *        until a reset replaced the simulation (its own hold is still ahead). @p at_hold runs
   *        when it starts holding (the ground truth shows the hold). True if it held.
   */
  bool holdAtTrialStart(std::unique_lock<std::mutex>& lock, const std::function<void()>& at_hold,
                        const std::function<bool()>& running);
  /** @brief start_trial: waits up to @p timeout of wall time for sim time to reach the hold
   *         drawn by the reset. False: it is still ahead. */
  bool waitForHold(std::unique_lock<std::mutex>& lock, std::chrono::steady_clock::duration timeout,
                   const std::function<bool()>& running);

 private:
  void apply(const PendingCommand& c);

  std::unique_ptr<DrillingSimulation> sim_;
  StreamSchedule streams_;
  bool lockstep_ = false;
  BenchReports reports_;
  BenchTrial trial_;
  BenchCommandQueue commands_;
  BenchCounters counters_;
  AtNextBreath amplitude_;
  DriverTrips trips_;
  std::condition_variable cv_;  ///< a trajectory, a planner phase, a hold or a resume
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_SIM_SIMULATED_BENCH_HPP_
