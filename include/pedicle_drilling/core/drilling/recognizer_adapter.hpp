// The glue between a force sensor's stream and a drilling-state recognizer, one rule for the
// StateRecognizer nodelet and the closed-loop engine: the thrust is one axis component of the
// force (the whole wrench and the drill's context go with it, RecognizerSample), a non-finite
// sample is dropped and counted, the recognizer's latch says when its stop is new, and the stop's
// reason comes with it.
#ifndef PEDICLE_DRILLING_CORE_DRILLING_RECOGNIZER_ADAPTER_HPP_
#define PEDICLE_DRILLING_CORE_DRILLING_RECOGNIZER_ADAPTER_HPP_

#include <Eigen/Core>

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"
#include "pedicle_drilling/core/drilling/state_recognizer.hpp"

namespace pedicle_drilling::core {

/** @brief The thrust's axis of the sensor frame: component `index` (0 x, 1 y, 2 z) times `sign`. */
struct ForceAxis {
  int index = 2;      ///< 0, 1 or 2
  double sign = 1.0;  ///< +1 or -1
  /** @brief @throws std::invalid_argument when index is not 0, 1, 2 or sign not +-1. */
  void validate() const;
  /** @brief The thrust of @p force along this axis. */
  double thrust(const Eigen::Vector3d& force) const { return sign * force[index]; }
};

/** @brief The drill's joints by name in a joint-state sample (the URDF's names by default). */
struct DrillJointNames {
  std::string feed = "feed_joint";        ///< prismatic: the drill's advance along its axis [m]
  std::string spindle = "spindle_joint";  ///< continuous: the spindle [rad/s]
};

/** @brief What one force sample did to the recognizer (RecognizerAdapter::push). */
struct RecognizerStep {
  bool accepted = false;     ///< false: a non-finite sample, dropped (nothing else is set)
  bool new_average = false;  ///< a block ended: a new state to publish
  bool new_stop = false;     ///< the latch closed on this sample: the stop to send
  std::string stop_reason;   ///< the recognizer's reason when new_stop, else ""
};

/**
 * @brief "Force sample in, state and stop out": a recognizer (guarded: what its class throws is
 *        its stop, core::GuardedRecognizer) fed the thrust of one force axis. Non-finite samples
 *        (force or time) are dropped and counted, as the recognizer refuses them; its one latch
 *        marks the sample whose stop is new.
 */
class RecognizerAdapter {
 public:
  /** @throws std::invalid_argument if @p recognizer is null or @p axis invalid. */
  explicit RecognizerAdapter(std::unique_ptr<RecognizerInterface> recognizer,
                             ForceAxis axis = ForceAxis());

  /** @brief The thrust of a sensor sample along the configured axis. */
  double thrust(const Eigen::Vector3d& force) const { return axis_.thrust(force); }
  /**
   * @brief Whether a sample of @p thrust at @p t may reach the recognizer: false (counted in
   *        nonFiniteCount) when either is not finite.
   */
  bool admit(double t, double thrust);
  /** @brief An admitted thrust sample to the recognizer: its new state and new stop. */
  RecognizerStep push(double t, double thrust);
  /** @brief An admitted whole sample (sample()) to the recognizer: its new state and stop. */
  RecognizerStep push(const RecognizerSample& sample);
  /**
   * @brief The drill's context as last heard (NaN: unknown); it goes with every sample() after.
   * @param feed_depth_m  the feed joint's position [m]
   * @param spindle_rpm   the spindle's speed [rpm]
   */
  void setContext(double feed_depth_m, double spindle_rpm);
  /**
   * @brief setContext() from one joint-state sample (as sensor_msgs/JointState: names, and
   *        positions and velocities in their order): the feed joint's position and the spindle
   *        joint's velocity in rpm. A joint the sample lacks (or a value it lacks) keeps what
   *        was heard before.
   */
  void setContextFromJoints(const std::vector<std::string>& names,
                            const std::vector<double>& positions,
                            const std::vector<double>& velocities,
                            const DrillJointNames& joints = DrillJointNames());
  /**
   * @brief The feed joint's commanded position from one controller state (its joint names and
   *        desired positions, as JointTrajectoryControllerState): the desired position of
   *        @p joints' feed joint; a state without it keeps what was heard before.
   */
  void setFeedCommandFromController(const std::vector<std::string>& names,
                                    const std::vector<double>& desired_positions,
                                    const DrillJointNames& joints = DrillJointNames());
  /** @brief The latest tracker sample (the marker's position in the tracker's frame). */
  void setTracker(double stamp, const Eigen::Vector3d& position);
  /**
   * @brief A sensor sample for the recognizer: the thrust along the configured axis, the whole
   *        wrench and the context as last heard (setContext(), setFeedCommandFromController(),
   *        setTracker()).
   */
  RecognizerSample sample(double t, const Eigen::Vector3d& force,
                          const Eigen::Vector3d& torque) const;
  /**
   * @brief admit() then push() of the whole sample of @p force and @p torque; accepted false
   *        when dropped (a non-finite time or thrust).
   */
  RecognizerStep onSample(double t, const Eigen::Vector3d& force, const Eigen::Vector3d& torque);

  /** @brief The recognizer starts afresh (its latch cleared); the drop count is kept. */
  void reset() { recognizer_->reset(); }
  /** @brief The recognizer's latest output. */
  const RecognizerOutput& output() const { return recognizer_->output(); }
  /** @brief The recognizer's reason for its stop ("" while not stopped). */
  std::string stopReason() const { return recognizer_->stopReason(); }
  /** @brief The recognizer class's description. */
  std::string describe() const { return recognizer_->describe(); }
  /** @brief Non-finite samples dropped since construction. */
  std::size_t nonFiniteCount() const { return non_finite_count_; }
  /** @brief The axis in use. */
  const ForceAxis& axis() const { return axis_; }

 private:
  std::unique_ptr<RecognizerInterface> recognizer_;
  /** @brief The step of one admitted sample, pushed by @p push_one. */
  template <typename Push>
  RecognizerStep step(Push push_one);

  ForceAxis axis_;
  std::size_t non_finite_count_ = 0;
  RecognizerSample context_;  ///< the drill's context as last heard (its other fields unused)
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_DRILLING_RECOGNIZER_ADAPTER_HPP_
