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

template <typename Push>
RecognizerStep RecognizerAdapter::step(Push push_one) {
  RecognizerStep step;
  step.accepted = true;
  // One latch, the recognizer's: the stop is new on the sample that latches it.
  const bool was_stopped = recognizer_->output().stop;
  const RecognizerOutput& out = push_one();
  step.new_average = out.new_average;
  step.new_stop = out.stop && !was_stopped;
  if (step.new_stop) step.stop_reason = recognizer_->stopReason();
  return step;
}

RecognizerStep RecognizerAdapter::push(double t, double thrust) {
  return step([&]() -> const RecognizerOutput& { return recognizer_->push(t, thrust); });
}

RecognizerStep RecognizerAdapter::push(const RecognizerSample& sample) {
  return step([&]() -> const RecognizerOutput& { return recognizer_->pushSample(sample); });
}

void RecognizerAdapter::setContext(double feed_depth_m, double spindle_rpm) {
  context_.feed_depth_m = feed_depth_m;
  context_.spindle_rpm = spindle_rpm;
}

void RecognizerAdapter::setContextFromJoints(const std::vector<std::string>& names,
                                             const std::vector<double>& positions,
                                             const std::vector<double>& velocities,
                                             const DrillJointNames& joints) {
  constexpr double kRpmPerRadPerS = 60.0 / (2.0 * M_PI);
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (names[i] == joints.feed && i < positions.size()) context_.feed_depth_m = positions[i];
    if (names[i] == joints.spindle && i < velocities.size()) {
      context_.spindle_rpm = velocities[i] * kRpmPerRadPerS;
    }
  }
}

void RecognizerAdapter::setFeedCommandFromController(const std::vector<std::string>& names,
                                                     const std::vector<double>& desired_positions,
                                                     const DrillJointNames& joints) {
  for (std::size_t i = 0; i < names.size() && i < desired_positions.size(); ++i) {
    if (names[i] == joints.feed) context_.feed_command_m = desired_positions[i];
  }
}

void RecognizerAdapter::setTracker(double stamp, const Eigen::Vector3d& position) {
  context_.tracker_stamp = stamp;
  context_.tracker_m = {position.x(), position.y(), position.z()};
}

RecognizerSample RecognizerAdapter::sample(double t, const Eigen::Vector3d& force,
                                           const Eigen::Vector3d& torque) const {
  RecognizerSample s = context_;
  s.t = t;
  s.thrust_n = axis_.thrust(force);
  s.force_n = {force.x(), force.y(), force.z()};
  s.torque_nm = {torque.x(), torque.y(), torque.z()};
  return s;
}

RecognizerStep RecognizerAdapter::onSample(double t, const Eigen::Vector3d& force,
                                           const Eigen::Vector3d& torque) {
  const RecognizerSample s = sample(t, force, torque);
  if (!admit(s.t, s.thrust_n)) return RecognizerStep();
  return push(s);
}

}  // namespace pedicle_drilling::core
