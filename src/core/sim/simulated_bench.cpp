#include "pedicle_drilling/core/sim/simulated_bench.hpp"

#include <algorithm>
#include <thread>
#include <utility>

#include "pedicle_drilling/core/sim/closed_loop_engine.hpp"

namespace pedicle_drilling::core {

SimulatedBench::SimulatedBench(std::unique_ptr<DrillingSimulation> sim,
                               const StreamSchedule& streams, bool lockstep,
                               const BenchTransport& transport, BenchReports reports)
    : sim_(std::move(sim)),
      streams_(streams),
      lockstep_(lockstep),
      reports_(std::move(reports)),
      commands_(transport.delay_s, transport.jitter_s, transport.seed) {}

SimulatedBench::Step SimulatedBench::step() {
  Step s;
  s.step = sim_->stepOnce();
  s.amplitude = amplitude_.takeDue(sim_->ventilator().breathIndex());
  if (s.amplitude) sim_->setPatientAmplitudeFactor(*s.amplitude);  // from this breath's start
  // The step's index since the reset: the streams' phases are the engine's.
  s.n = StreamSchedule::stepIndex(s.step.time_s, sim_->params().physics_rate_hz);
  s.due = streams_.at(s.n, s.step, *sim_);
  return s;
}

void SimulatedBench::applyDue(double t) {
  for (const PendingCommand& c : commands_.takeDue(t)) apply(c);
}

void SimulatedBench::apply(const PendingCommand& c) {
  if (c.tare) {
    sim_->requestTare(*c.tare);
  } else if (!c.trajectory) {
    reports_.spindle(sim_->commandSpindle(c.spindle_rpm));
  } else {
    counters_.noteLateness(*c.trajectory, sim_->time(), sim_->params().physics_rate_hz);
    const TargetResult r = sim_->commandTrajectory(c.controller, *c.trajectory);
    counters_.noteResult(r);
    reports_.trajectory(c.controller, r);
  }
}

void SimulatedBench::commandTrajectory(const std::string& controller,
                                       const TrajectoryCommand& command) {
  if (lockstep_) {
    commands_.pushTrajectory(sim_->time(), controller, command);
  } else {
    takeTrajectory(controller, command);
  }
}

TargetResult SimulatedBench::takeTrajectory(const std::string& controller,
                                            const TrajectoryCommand& command) {
  counters_.noteLateness(command, sim_->time(), sim_->params().physics_rate_hz);
  const TargetResult r = sim_->commandTrajectory(controller, command);
  trial_.onTrajectory();
  counters_.noteResult(r);
  reports_.trajectory(controller, r);
  return r;
}

void SimulatedBench::trajectoryEnd(const std::string& controller, double* end_s) const {
  const std::vector<ControllerSpec>& specs = sim_->controllers();
  for (std::size_t i = 0; i < specs.size(); ++i) {
    if (specs[i].name == controller) *end_s = sim_->controllerTrajectoryEnd(i);
  }
}

void SimulatedBench::commandSpindle(double rpm) {
  if (lockstep_) {
    // A keepalive takes the command path without a jitter draw (the engine's rule).
    commands_.pushSpindle(sim_->time(), rpm);
  } else {
    reports_.spindle(sim_->commandSpindle(rpm));
  }
}

void SimulatedBench::requestTare(const TareRequest& request) {
  if (lockstep_) {
    commands_.pushTare(sim_->time(), request);
  } else {
    sim_->requestTare(request);
  }
}

void SimulatedBench::setPatientAmplitude(double factor) {
  amplitude_.arm(sim_->ventilator().breathIndex(), factor);
}

std::optional<double> SimulatedBench::reset(std::unique_ptr<DrillingSimulation> fresh,
                                            const BenchTransport& transport, bool hold,
                                            double pre_trial_s) {
  // The drivers are the same across specimens: an enable they hold carries over.
  if (!sim_->drivesHalted()) fresh->onDriveEnable(true);
  sim_ = std::move(fresh);
  amplitude_.clear();
  // The last trial's commands do not drive this one.
  commands_ = BenchCommandQueue(transport.delay_s, transport.jitter_s, transport.seed);
  trips_.clear();
  counters_ = BenchCounters();
  std::optional<double> hold_at;
  if (hold) {
    const double breath_s = 60.0 / sim_->trialConditions().ventilator_rate_bpm;
    hold_at = trialStartTime(transport.seed, sim_->time(), pre_trial_s, breath_s, true);
  }
  trial_.reset(hold_at);
  return hold_at;
}

bool SimulatedBench::startTrial() {
  const bool remounted = sim_->startTrial();
  counters_ = BenchCounters();
  return remounted;
}

bool BenchPacer::pace(double t) const {
  if (factor_ <= 0.0) return false;
  using Clock = std::chrono::steady_clock;
  const Clock::time_point due = wall0_ + std::chrono::duration_cast<Clock::duration>(
                                             std::chrono::duration<double>((t - sim0_) / factor_));
  if (due - Clock::now() > std::chrono::milliseconds(1)) std::this_thread::sleep_until(due);
  return true;
}

SimulatedBench::CommandWait SimulatedBench::waitForCommand(std::unique_lock<std::mutex>& lock,
                                                           double wait_s,
                                                           const std::function<bool()>& running) {
  const double step = 1.0 / sim_->params().physics_rate_hz;
  const auto starved = [this, step] {
    return trial_.starved(sim_->armTrajectoryEnd(), sim_->time(), step);
  };
  if (lockstep_ || wait_s <= 0.0 || !starved()) return CommandWait::kNone;
  using Clock = std::chrono::steady_clock;
  const Clock::time_point start = Clock::now();
  const Clock::time_point deadline =
      start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(wait_s));
  // Woken by a trajectory, a phase or a shutdown; a 50 ms slice asks `running` again.
  while (running() && starved() && Clock::now() < deadline) {
    cv_.wait_until(lock, std::min(deadline, Clock::now() + std::chrono::milliseconds(50)));
  }
  const bool expired = running() && starved();
  ++counters_.command_waits;
  counters_.command_wait_wall_s += std::chrono::duration<double>(Clock::now() - start).count();
  if (!expired) return CommandWait::kArrived;
  trial_.giveUpWait();  // until the next trajectory or phase: one wait, not one per step
  ++counters_.command_wait_expired;
  return CommandWait::kExpired;
}

bool SimulatedBench::holdAtTrialStart(std::unique_lock<std::mutex>& lock,
                                      const std::function<void()>& at_hold,
                                      const std::function<bool()>& running) {
  if (!trial_.reachesHold(sim_->time())) return false;
  trial_.setHeld(true);
  at_hold();
  cv_.notify_all();  // start_trial waits for it
  const std::uint64_t generation = trial_.generation();
  while (running() && trial_.holds(generation)) {
    cv_.wait_for(lock, std::chrono::milliseconds(50));
  }
  trial_.setHeld(false);
  return true;
}

bool SimulatedBench::waitForHold(std::unique_lock<std::mutex>& lock,
                                 std::chrono::steady_clock::duration timeout,
                                 const std::function<bool()>& running) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (running() && trial_.holdAhead() && std::chrono::steady_clock::now() < deadline) {
    cv_.wait_for(lock, std::chrono::milliseconds(50));
  }
  return !trial_.holdAhead();
}

}  // namespace pedicle_drilling::core
