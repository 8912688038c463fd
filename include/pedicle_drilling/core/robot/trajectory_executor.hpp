/**
 * @file trajectory_executor.hpp
 * @brief A joint trajectory executor with ros_control's JointTrajectoryController semantics,
 *        without ROS: what the simulated arm controller and the SPMS's slider controller run.
 *
 * The rules (ros_control joint_trajectory_controller, "Trajectory replacement" and the spline
 * types of its documentation; the strict ones from joint_trajectory_controller_impl.h,
 * updateTrajectoryCommand, and init_joint_trajectory.h), each tested in
 * test_trajectory_executor.cpp:
 *  - A new trajectory takes over at its start time, the message's header stamp; a zero stamp
 *    (NaN here) or a start time not after now means now. Until then the running trajectory is
 *    followed.
 *  - From the takeover, the new trajectory goes from the running trajectory's state there
 *    (position, velocity, acceleration) to its first point after the takeover; points at or
 *    before the takeover are dropped.
 *  - Between two points the spline is linear when the end point gives positions only, cubic
 *    when it gives positions and velocities, quintic when it also gives accelerations.
 *  - After the last point the joints hold its position at rest.
 *  - A command with NaN/inf values, unknown or duplicate joints, size mismatches or times that
 *    do not strictly increase is rejected whole; the running trajectory goes on.
 *  - A segment faster than a joint's velocity limit is reported (kClamped): the joint's servo
 *    follows at its limit.
 *
 * Strict rules (ControllerRules::strict, the default: what a lab's controller does):
 *  - A command must name every joint of the controller ("Joints on incoming goal don't match
 *    the controller joints"), unless allow_partial_joints_goal; then joints not named keep their
 *    reference.
 *  - A command whose last point is not after now is rejected ("Dropping all N trajectory
 *    point(s), as they occur before the current time"): the running trajectory goes on.
 *  - A command with no points stops: the reference decelerates to rest within
 *    stop_trajectory_duration_s ("Empty trajectory command, stopping"). ros_control starts that
 *    stop from the measured joint state; this executor has no measurement and starts it from the
 *    reference.
 *  - A position outside the joint limits rejects the command whole, naming the joint: nothing
 *    is clamped silently (ros_control's controller does not clamp; the limits of a lab's arm are
 *    enforced by its driver, which refuses or faults).
 *
 * Lenient rules (strict = false; this project's controller before it followed ros_control to
 * the letter, kept to compare with published results): partial commands always accepted,
 * positions outside the limits clamped and reported (kClamped), a command with no points
 * rejected, and a streamed command that arrives after its own end goes to its final point over
 * its last interval.
 *
 * Times within 1 us of each other are one time (a point "at" the takeover is dropped, a start
 * "at" now is now): a stamp that went through ROS's nanoseconds or another machine's clock is
 * never exactly the double it was made from, and a point 1e-10 s after the takeover would make a
 * segment of unbounded speed. The core engine (exact doubles) and the pipeline (stamps) agree.
 */
#ifndef PEDICLE_DRILLING_CORE_TRAJECTORY_EXECUTOR_HPP
#define PEDICLE_DRILLING_CORE_TRAJECTORY_EXECUTOR_HPP

#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "pedicle_drilling/core/robot/target_result.hpp"

namespace pedicle_drilling::core {

/** @brief One point of a joint trajectory (absolute sim time). */
struct TrajectoryPoint {
  TrajectoryPoint() = default;
  /** @brief A point at `time` with positions and, optionally, velocities and accelerations. */
  TrajectoryPoint(double time, std::vector<double> q, std::vector<double> qd = {},
                  std::vector<double> qdd = {})
      : time_s(time),
        positions(std::move(q)),
        velocities(std::move(qd)),
        accelerations(std::move(qdd)) {}
  double time_s = 0.0;                ///< absolute simulation time of the point [s]
  std::vector<double> positions;      ///< one per joint name
  std::vector<double> velocities;     ///< empty (linear) or one per joint (cubic)
  std::vector<double> accelerations;  ///< empty or one per joint (quintic, needs velocities)
};

/** @brief A joint trajectory command: names plus time-ordered points. */
struct TrajectoryCommand {
  std::vector<std::string> joint_names;  ///< subset of the executor's joints
  std::vector<TrajectoryPoint> points;   ///< strictly increasing times
  /**
   * @brief When the new trajectory takes over (the message's header stamp), as ros_control's
   *        JointTrajectoryController does: the running trajectory is followed until then, and
   *        the new one goes from that trajectory's state at this time to its first point not in
   *        the past. NaN (a zero stamp) or a time not after now: it takes over now.
   */
  double start_time_s = std::numeric_limits<double>::quiet_NaN();
};

/** @brief Position and velocity limits of one joint (URDF <limit>). */
struct JointLimit {
  double lower = -std::numeric_limits<double>::infinity();    ///< position lower limit
  double upper = std::numeric_limits<double>::infinity();     ///< position upper limit
  double velocity = std::numeric_limits<double>::infinity();  ///< speed limit (> 0)
};

/** @brief Which of ros_control's rules a controller applies (file comment). */
struct ControllerRules {
  bool strict = true;                       ///< ros_control's rules; false: the lenient ones
  bool allow_partial_joints_goal = false;   ///< strict only: accept commands naming a subset
  double stop_trajectory_duration_s = 0.5;  ///< an empty command stops within this [s] (> 0)
};

/** @brief The reference of every joint at one time. */
struct TrajectoryState {
  Eigen::VectorXd position;      ///< [rad or m]
  Eigen::VectorXd velocity;      ///< [rad/s or m/s]
  Eigen::VectorXd acceleration;  ///< [rad/s^2 or m/s^2]
};

/**
 * @brief Executes joint trajectories with JointTrajectoryController semantics (file comment).
 *        Not thread-safe.
 */
class JointTrajectoryExecutor {
 public:
  /**
   * @brief Executor of `joint_names` (one limit each) holding `hold` at rest.
   * @throws std::invalid_argument for an empty or duplicated name, a size mismatch, or a limit
   *         that is NaN, inverted or not positive in speed.
   */
  JointTrajectoryExecutor(std::vector<std::string> joint_names, std::vector<JointLimit> limits,
                          const Eigen::VectorXd& hold, ControllerRules rules = {});

  /** @brief Drops any trajectory and holds `q` at rest (a reset). @throws on a size mismatch. */
  void hold(const Eigen::VectorXd& q);

  /** @brief A new trajectory received at `now` (the rules of the file comment). */
  TargetResult command(const TrajectoryCommand& command, double now);

  /** @brief The reference at time t (t before the first knot: the first knot's state). */
  TrajectoryState sample(double t) const;
  /** @brief The same into @p out, reusing its storage (no allocation once it has the size). */
  void sample(double t, TrajectoryState* out) const;

  /** @brief Forgets the knots before t that no later sample() or command() at >= t needs. */
  void prune(double t);

  /** @brief The joints, in the order of every vector of this class. */
  const std::vector<std::string>& jointNames() const { return names_; }
  /** @brief Time of the last point (-inf while holding). */
  double endTime() const;
  /** @brief The rules this executor applies. */
  const ControllerRules& rules() const { return rules_; }

 private:
  /** @brief Knot: time, state, and the spline degree of the segment that ends here. */
  struct Knot {
    double t = 0.0;
    Eigen::VectorXd q;
    Eigen::VectorXd v;
    Eigen::VectorXd a;
    int degree = 1;  ///< 1 linear, 3 cubic, 5 quintic
  };
  TargetResult validate(const TrajectoryCommand& command, std::vector<int>* map) const;
  /** @brief The reference's state at t as a knot (takeovers and stops start from it). */
  Knot stateKnot(double t) const;
  /** @brief Strict: an empty command decelerates the reference to rest (file comment). */
  void stop(double now);

  std::vector<std::string> names_;
  std::vector<JointLimit> limits_;
  ControllerRules rules_;
  std::vector<Knot> knots_;  ///< at least one: the held state when no trajectory runs
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_TRAJECTORY_EXECUTOR_HPP
