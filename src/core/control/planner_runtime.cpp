#include "pedicle_drilling/core/control/planner_runtime.hpp"

#include <cmath>
#include <stdexcept>
#include <utility>

#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling::core {

PlannerRuntime::PlannerRuntime(std::unique_ptr<TrialSequencer> sequencer, double heartbeat_period_s,
                               ForceAxis thrust)
    : sequencer_(std::move(sequencer)), heartbeat_period_s_(heartbeat_period_s), thrust_(thrust) {
  if (!sequencer_) throw std::invalid_argument("PlannerRuntime: no trial sequencer");
  if (!(heartbeat_period_s_ > 0.0)) {
    throw std::invalid_argument("heartbeat_period_s: must be > 0 s");
  }
  thrust_.validate();
}

TrialStartAnswer PlannerRuntime::start(const TrialRequest& request, const MotionModel& model,
                                       double now, double stamp) {
  trial_start_stamp_ = stamp;
  stops_heard_ = 0;
  TrialStartAnswer answer;
  answer.message = sequencer_->start(request, model, now);
  answer.success = answer.message.empty();
  if (answer.success) {
    answer.message = "trial started: " + request.mode + ", spindle " +
                     Range::format(sequencer_->spindleRpm()) + " rpm";
  }
  return answer;
}

void PlannerRuntime::onStop(double now, double stamp, bool retreat, const std::string& reason) {
  if (stamp >= trial_start_stamp_) ++stops_heard_;
  sequencer_->onStop(now, retreat, reason);
}

void PlannerRuntime::onMonitorStatus(double now, double stamp, bool error,
                                     const std::string& message) {
  sequencer_->onMonitorAlive(now);
  if (!error || stamp < trial_start_stamp_) return;
  sequencer_->onStop(now, true, monitorErrorReason(message));
}

std::string PlannerRuntime::monitorErrorReason(const std::string& message) {
  return "safety monitor ERROR: " + message;
}

bool PlannerRuntime::onTidalVolume(double stamp, double time_in_breath_s) {
  const double start = stamp - time_in_breath_s;
  if (!std::isfinite(start)) return false;
  sequencer_->setBreathStart(start);
  return true;
}

void PlannerRuntime::setTidalVolumeSource(const std::string& tidal_topic, double timeout_periods) {
  tidal_topic_ = tidal_topic;
  breath_timeout_periods_ = timeout_periods;
  sequencer_->setBreathSource(tidal_topic_, breath_timeout_periods_);
}

void PlannerRuntime::onBreathSourceStatus(const std::string& source, const std::string& topic,
                                          bool ready, const std::string& problem) {
  sequencer_->setBreathSource(breathSourceName(tidal_topic_, source, topic),
                              breath_timeout_periods_);
  sequencer_->setBreathSourceProblem(ready ? "" : problem);
}

std::string PlannerRuntime::breathSourceName(const std::string& tidal_topic,
                                             const std::string& source, const std::string& topic) {
  if (topic.empty()) return tidal_topic;
  return source + " on " + topic + " (via " + tidal_topic + ")";
}

void PlannerRuntime::onForce(double now, double stamp, const Eigen::Vector3d& force) {
  sequencer_->onForce(now, stamp, thrust_.thrust(force));
}

void PlannerRuntime::onPhase(TrialPhase phase, double now) {
  const bool was_running = running_;
  running_ = isRunning(phase);
  if (running_ && !was_running) next_beat_ = now;  // beat from the trial's first step
}

bool PlannerRuntime::beatDue(double t) {
  if (!running_ || t + 1e-9 < next_beat_) return false;
  next_beat_ = t + heartbeat_period_s_;
  return true;
}

void PlannerRuntime::fireDueTimers(double now, const std::function<void()>& carry_out) {
  while (const std::optional<TimerRequest::Kind> kind = timers_.popDue(now)) {
    sequencer_->onTimer(*kind, now);
    carry_out();
  }
}

std::optional<double> PlannerRuntime::nextDue() const {
  std::optional<double> due = timers_.nextDue();
  if (running_ && (!due || next_beat_ < *due)) due = next_beat_;
  return due;
}

int PlannerRuntime::stopRank(const std::string& source, const std::string& own_name) {
  if (source == own_name) return 2;  // the planner's own, heard back
  return source.find("safety_monitor") != std::string::npos ? 1 : 0;
}

}  // namespace pedicle_drilling::core
