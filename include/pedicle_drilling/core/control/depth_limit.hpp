// The depth limit of a drilling plan: the last line of defence against a perforation, whatever
// recognizer or compensator runs. No ROS; SI units.
//
// A surgeon plans each drilling on the preoperative image: the entry point on the bone's surface,
// the direction and the depth the tip must never pass. The plan is in the frame of the tracked
// reference body fixed to the bone (the marker), as image-to-patient registration gives it. The
// planner measures the tip's advance into the bone along the drill axis from the tracked and
// predicted bone (the tracker's residual against the prediction corrects the prediction), takes
// the bone's surface where the drill's own thrust first shows contact (within the registration's
// tolerance of the planned entry; its shallow end when no contact shows), and holds the feed at
// the surface plus the planned depth.
#ifndef PEDICLE_DRILLING_CORE_DEPTH_LIMIT_HPP_
#define PEDICLE_DRILLING_CORE_DEPTH_LIMIT_HPP_

#include <Eigen/Geometry>

#include <deque>
#include <string>

#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling::core {

/** @brief One drilling's plan (msg/DrillingPlan.msg), in the tracked reference body's frame. */
struct DrillingPlan {
  std::string frame;  ///< the tracked marker's frame the plan is given in (a tf frame)
  Eigen::Vector3d entry = Eigen::Vector3d::Zero();  ///< entry point on the bone's surface [m]
  Eigen::Vector3d direction{0.0, 0.0, -1.0};        ///< drilling direction (normalised on use)
  /** @brief Depth from the entry along the direction that the tip never passes [m], (0, 0.2]. */
  double depth_m = 0.0;
  /**
   * @brief How far along the direction the true surface may lie from the planned entry [m],
   *        [0, 0.02]: the image-to-patient registration's error bound. A contact sensed outside
   *        it is clamped to it; without a sensed contact the shallow end counts.
   */
  double entry_tolerance_m = 0.0;

  /** @brief "" when usable, else why not (finite values, a non-zero direction, ranges). */
  std::string check() const;
};

/** @brief The planner's depth-limit settings (doc/nodes.md: the planner's `depth_limit/...`). */
struct DepthLimitParams {
  /**
   * @brief A trial needs a plan (true): without one the planner refuses to start. false: a
   *        trial without one has no depth limit (on a node only with
   *        `~unsafe_allow_disabled_watchdogs`); the core engine's bench then makes no plan: the
   *        paper's system as published, which had none (the paper-reproduction scenarios).
   */
  bool require_plan = true;
  /**
   * @brief Thrust that marks the tip on the bone [N], (0, 5]: 0.5 N, ten times the simulated
   *        sensor's noise with the spindle running (0.05 N) and a sixth of the outer cortex's
   *        averaged force (3.2 N, paper Fig. 16).
   */
  double contact_force_n = 0.5;
  /** @brief Consecutive samples at or above contact_force_n that make a contact, [1, 100]: 3,
   *         so that one spike is no contact. */
  int contact_samples = 3;
  /** @brief Largest angle between the plan's direction and the drill axis [deg], (0, 30]. */
  double max_plan_angle_deg = 5.0;
  /** @brief Tracker samples whose axial residual against the prediction are averaged into the
   *         correction, [1, 100]: 4, half a second at 8 Hz. */
  int residual_samples = 4;

  /** @brief Check every field. @throws std::invalid_argument naming the field. */
  void validate() const;
  /** @brief The declaration of the fields (names as the ROS parameters, `depth_limit/...`). */
  static const ParamTable<DepthLimitParams>& table();
};

/**
 * @brief The depth limit of one trial, in the planner's coordinates: the tip's advance along the
 *        drill axis since the registration (CompensationPlanner::predictedAdvance) [m].
 */
class DepthLimit {
 public:
  /** @brief Construct. @throws std::invalid_argument for invalid params. */
  explicit DepthLimit(const DepthLimitParams& params);

  /**
   * @brief The plan at the registration: where its entry lies along the drill axis.
   * @param plan the trial's plan (checked)
   * @param world_from_marker the tracked marker's pose at the registration, world frame
   * @param tip_world the drill tip at the registration (the drilling pose), world frame
   * @param drill_axis unit drilling direction, world frame
   * @return "" when the limit is set, else why the plan cannot be drilled (no limit is set)
   */
  std::string begin(const DrillingPlan& plan, const Eigen::Isometry3d& world_from_marker,
                    const Eigen::Vector3d& tip_world, const Eigen::Vector3d& drill_axis);

  /** @brief A thrust sample [N] with the tip's predicted advance at its stamp [m]. */
  void onThrust(double predicted_advance, double thrust_n);
  /**
   * @brief A tracker sample's residual against the prediction along the drill axis [m]: the
   *        tracked bone minus the predicted bone, positive when the bone is nearer the drill.
   */
  void onResidual(double residual_m);

  /** @brief Whether begin() set a limit. */
  bool active() const { return active_; }
  /** @brief The planned entry's advance (the registration's) [m]. */
  double registeredEntry() const { return registered_entry_; }
  /** @brief Whether the thrust showed the contact (within the tolerance). */
  bool contact() const { return contact_; }
  /** @brief The surface's advance in use [m]: the sensed contact, clamped to the tolerance, else
   *         the tolerance's shallow end. */
  double entry() const;
  /** @brief The mean residual of the last residual_samples tracker samples [m]. */
  double correction() const;
  /**
   * @brief The deepest predicted advance allowed now [m]: entry() + depth - correction() (a
   *        bone nearer the drill than predicted lowers it).
   */
  double limit() const;
  /** @brief The plan's depth [m]. */
  double depth() const { return depth_; }
  /** @brief One line on where the limit stands (for a stop's reason and the log). */
  std::string describe() const;

 private:
  DepthLimitParams params_;
  bool active_ = false;
  double registered_entry_ = 0.0;
  double tolerance_ = 0.0;
  double depth_ = 0.0;
  bool contact_ = false;
  double contact_advance_ = 0.0;
  int run_ = 0;                   // consecutive samples at or above the contact force
  double run_start_advance_ = 0;  // the advance at the run's first sample
  std::deque<double> residuals_;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_DEPTH_LIMIT_HPP_
