#include "pedicle_drilling/core/drilling/recognizer_adapter.hpp"

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace pedicle_drilling::core {

void ForceAxis::validate() const {
  if (index < 0 || index > 2) {
    throw std::invalid_argument("force axis index " + std::to_string(index) +
                                " is not 0, 1 or 2 (x, y, z)");
  }
  if (sign != 1.0 && sign != -1.0) {
    throw std::invalid_argument("force axis sign " + std::to_string(sign) + " is not +1 or -1");
  }
}

RecognizerAdapter::RecognizerAdapter(std::unique_ptr<RecognizerInterface> recognizer,
                                     ForceAxis axis)
    : axis_(axis) {
  if (!recognizer) throw std::invalid_argument("RecognizerAdapter: no recognizer");
  axis_.validate();
  recognizer_ = std::make_unique<GuardedRecognizer>(std::move(recognizer));
}

bool RecognizerAdapter::admit(double t, double thrust) {
  if (std::isfinite(thrust) && std::isfinite(t)) return true;
  ++non_finite_count_;
  return false;
}

RecognizerStep RecognizerAdapter::push(double t, double thrust) {
  RecognizerStep step;
  step.accepted = true;
  // One latch, the recognizer's: the stop is new on the sample that latches it.
  const bool was_stopped = recognizer_->output().stop;
  const RecognizerOutput& out = recognizer_->push(t, thrust);
  step.new_average = out.new_average;
  step.new_stop = out.stop && !was_stopped;
  if (step.new_stop) step.stop_reason = recognizer_->stopReason();
  return step;
}

RecognizerStep RecognizerAdapter::onSample(double t, const Eigen::Vector3d& force) {
  const double thrust = axis_.thrust(force);
  if (!admit(t, thrust)) return RecognizerStep();
  return push(t, thrust);
}

}  // namespace pedicle_drilling::core
