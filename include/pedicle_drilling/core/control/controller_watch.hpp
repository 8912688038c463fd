/**
 * @file controller_watch.hpp
 * @brief The planner's closed loop on the arm's controllers: from each controller's
 *        state (control_msgs/JointTrajectoryControllerState's fields) it tells a command that was
 *        refused or came late, a joint that does not follow, and a controller that fell silent.
 *
 * The watch keeps, per controller, the trajectory a controller following ros_control's rules
 * would run from the commands the planner sent (a JointTrajectoryExecutor fed with them at their
 * send time, seeded with the desired position of the controller's first state taken at or after
 * the trial's start: a state from before may predate a reset of the robot).
 * A state then answers two questions per joint:
 *  - desired: does the controller's reference match the expected one? A refused command (foreign
 *    joints, a trajectory already ended, a position out of limits) or one that arrived late
 *    leaves the controller on its old trajectory; past desired_tolerance it is a fault.
 *  - following: |error| = |desired - actual| past following_tolerance is a fault (a joint that
 *    stalls, collides or is pushed away).
 * And a controller whose state has not arrived for state_timeout_s while watched is a fault.
 * Tolerances are per joint: the arm controller's joints [rad], the feed axis [m].
 */
#ifndef PEDICLE_DRILLING_CORE_CONTROLLER_WATCH_HPP
#define PEDICLE_DRILLING_CORE_CONTROLLER_WATCH_HPP

#include <memory>
#include <string>
#include <vector>

#include "pedicle_drilling/core/common/param_table.hpp"
#include "pedicle_drilling/core/robot/controller_layout.hpp"
#include "pedicle_drilling/core/robot/trajectory_executor.hpp"

namespace pedicle_drilling::core {

/** @brief The watch's thresholds (chosen on calibration seeds, doc/campaign_results.md). */
struct ControllerWatchParams {
  bool enabled = true;                        ///< false: no closed loop (a driver without state)
  double arm_desired_tolerance_rad = 0.01;    ///< |desired - expected| of an arm joint
  double feed_desired_tolerance_m = 0.001;    ///< |desired - expected| of the feed axis
  double arm_following_tolerance_rad = 0.02;  ///< |desired - actual| of an arm joint
  double feed_following_tolerance_m = 0.002;  ///< |desired - actual| of the feed axis
  double state_timeout_s = 0.5;               ///< no state for this long while watched: a fault
  /** @brief Checks the declared ranges. @throws std::invalid_argument naming the field. */
  void validate() const;
  /** @brief The declaration of every field (prefix controller_watch/ where included). */
  static const ParamTable<ControllerWatchParams>& table();
};

/** @brief Watches the arm's controllers (file comment). Not thread-safe. */
class ControllerWatch {
 public:
  /**
   * @param params validated here.
   * @param controllers the layout the planner sends to.
   * @param feed_joints the joints measured in metres (the feed tolerances apply to them).
   */
  ControllerWatch(const ControllerWatchParams& params, std::vector<ControllerSpec> controllers,
                  std::vector<std::string> feed_joints);

  /** @brief A state of controller @p name, received at @p now (its stamp is the state's time).
   *  @return "" or the fault, a sentence naming the controller, the joint and the numbers. */
  std::string onState(double now, const std::string& name, const ControllerStateSample& state);
  /**
   * @brief Watching starts (a trial): each expected trajectory holds the controller's last
   *        reported desired position. @return "" or why it cannot start: a controller never
   *        reported its state, or its last state lacks a joint the planner commands on it (the
   *        planner's controller layout is not the robot's).
   */
  std::string start(double now);
  /** @brief Watching ends (the trial is over or stopped: its commands are not checked). */
  void stop() { watching_ = false; }
  /** @brief A command the planner sent at @p now (any joints: split by controller). */
  void onCommand(double now, const TrajectoryCommand& command);
  /** @brief "" or the fault of a controller silent for more than state_timeout_s at @p now. */
  std::string checkSilence(double now) const;
  /** @brief Whether a trial is watched. */
  bool watching() const { return watching_; }
  /** @brief The largest |desired - expected| and |error| seen per controller since start()
   *         (normalised by each joint's tolerance: 1 is the threshold). */
  double worstDesiredRatio() const { return worst_desired_; }
  /** @brief See worstDesiredRatio(). */
  double worstFollowingRatio() const { return worst_following_; }

 private:
  struct Watched {
    ControllerSpec spec;
    std::vector<double> desired_tolerance;
    std::vector<double> following_tolerance;
    std::unique_ptr<JointTrajectoryExecutor> expected;
    std::vector<double> last_desired;  ///< empty: no state yet
    std::string mismatch;              ///< why the last state was unusable ("" : it was)
    bool seeded = false;               ///< the expectation has its start (a state after start())
    double last_state_t = -1.0;
    TrajectoryState expected_sample;  ///< kept storage for the expectation's sample
  };
  /** @brief Every controller's expectation has its start (no command needs keeping). */
  bool allSeeded() const;
  ControllerWatchParams params_;
  std::vector<Watched> watched_;
  std::vector<ControllerSpec> specs_;  ///< the watched controllers, in watched_'s order
  /// The commands sent since start() (send time, command): replayed into a controller's
  /// expectation when its first state after the start seeds it.
  std::vector<std::pair<double, TrajectoryCommand>> sent_;
  bool watching_ = false;
  double start_t_ = 0.0;
  double worst_desired_ = 0.0;
  double worst_following_ = 0.0;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_CONTROLLER_WATCH_HPP
