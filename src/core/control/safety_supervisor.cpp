#include "pedicle_drilling/core/control/safety_supervisor.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace pedicle_drilling::core {

const ParamTable<SupervisorParams>& SupervisorParams::table() {
  static const ParamTable<SupervisorParams> t = [] {
    using P = SupervisorParams;
    ParamTable<P> d;
    d.include(SafetyParams::table(), &P::safety)
        .number("pair_tolerance_s", &P::pair_tolerance_s, Range::closed(0, 1), "s")
        .integer("history", &P::history, Range::closed(1, 10000), "samples");
    return d;
  }();
  return t;
}

void SupervisorParams::validate() const {
  table().validate(*this);
  safety.validate();
}

const StampedPosition* StampPairer::add(const StampedPosition& sample, bool is_predicted) {
  std::deque<StampedPosition>& own = is_predicted ? predicted_ : tracked_;
  own.push_back(sample);
  while (static_cast<int>(own.size()) > history_) own.pop_front();
  const StampedPosition* best = nullptr;
  double best_dt = tolerance_s_;
  for (const StampedPosition& s : is_predicted ? tracked_ : predicted_) {
    const double dt = std::abs(s.stamp - sample.stamp);
    if (dt <= best_dt) {
      best_dt = dt;
      best = &s;
    }
  }
  return best;
}

void StampPairer::clear() {
  tracked_.clear();
  predicted_.clear();
}

double nextUsefulCheckTick(double t, double rate_hz, double quiet) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  if (quiet == kInf) return kInf;
  const double next = std::floor(t * rate_hz + 1e-6) + 1.0;  // the grid's rounding: 1e-6 period
  return quiet == -kInf ? next : std::max(next, std::floor(quiet * rate_hz) - 1.0);
}

SafetySupervisor::SafetySupervisor(const SupervisorParams& params)
    : params_(params), monitor_(params.safety), pairer_(params.pair_tolerance_s, params.history) {
  params_.validate();
}

void SafetySupervisor::onForce(double now, const Eigen::Vector3d& force) {
  have_force_ = true;
  monitor_.onForce(now, force);
}

PairResult SafetySupervisor::onTracked(double now, const StampedPosition& tracked) {
  const bool finite = tracked.position.allFinite() && std::isfinite(tracked.stamp);
  if (finite && have_tracker_ && !(tracked.stamp > last_tracked_stamp_)) {
    ++stale_tracked_;
    return PairResult::kStale;
  }
  if (finite) last_tracked_stamp_ = tracked.stamp;
  have_tracker_ = true;
  // The watchdog and the NaN check, whether or not a prediction exists (no trial running).
  monitor_.onTracked(now, tracked.position, tracked.position);
  return compare(now, tracked, pairer_.add(tracked, false), false);
}

PairResult SafetySupervisor::onPredicted(double now, const StampedPosition& predicted) {
  if (!predicted.position.allFinite() || !std::isfinite(predicted.stamp)) {
    monitor_.comparePositions(now, predicted.position, predicted.position);  // NaN: stop
    return PairResult::kUnpaired;
  }
  return compare(now, predicted, pairer_.add(predicted, true), true);
}

PairResult SafetySupervisor::compare(double now, const StampedPosition& sample,
                                     const StampedPosition* best, bool sample_is_predicted) {
  if (best == nullptr) return PairResult::kUnpaired;
  if (best->frame != sample.frame) {
    monitor_.rejectPair(now,
                        "the predicted and the tracked marker pose are in different frames ('" +
                            (sample_is_predicted ? sample.frame : best->frame) + "' and '" +
                            (sample_is_predicted ? best->frame : sample.frame) +
                            "') while drilling: H1 cannot be checked");
    return PairResult::kFrameMismatch;
  }
  const StampedPosition& predicted = sample_is_predicted ? sample : *best;
  const StampedPosition& tracked = sample_is_predicted ? *best : sample;
  monitor_.comparePositions(now, predicted.position, tracked.position);
  return PairResult::kCompared;
}

void SafetySupervisor::check(double now) {
  // Armed once both streams were heard since reset, or as soon as a trial runs: then a sensor
  // that never published times out from the arming time.
  if (heardBoth() || trial_running_) monitor_.check(now);
}

std::optional<SafetyVerdict> SafetySupervisor::takeNewStop() {
  if (!monitor_.stopped() || stop_reported_) return std::nullopt;
  stop_reported_ = true;
  return monitor_.verdict();
}

void SafetySupervisor::reset() {
  monitor_.reset();
  pairer_.clear();
  have_force_ = false;
  have_tracker_ = false;
  last_tracked_stamp_ = 0.0;
  stale_tracked_ = 0;
  stop_reported_ = false;
}

}  // namespace pedicle_drilling::core
