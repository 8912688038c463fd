/**
 * @file controller_layout.hpp
 * @brief Which controller owns which joints, as a lab wires its robot: a ros_control arm
 *        controller for the 6 arm joints and another for the drill's feed axis, or one combined
 *        controller; and the split of a planner's command into one command per controller.
 */
#ifndef PEDICLE_DRILLING_CORE_CONTROLLER_LAYOUT_HPP
#define PEDICLE_DRILLING_CORE_CONTROLLER_LAYOUT_HPP

#include <algorithm>
#include <cstddef>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling::core {

namespace detail {
/** @brief True when the point type P has an `accelerations` member. */
template <class P>
constexpr auto hasAccelerations(int) -> decltype(std::declval<P&>().accelerations, bool()) {
  return true;
}
/** @brief Fallback: P has no `accelerations` member. */
template <class P>
constexpr bool hasAccelerations(long) {
  return false;
}
}  // namespace detail

/** @brief One controller: its name (its topics are `<name>/command`, `<name>/state`) and joints. */
struct ControllerSpec {
  std::string name;                 ///< e.g. "arm_controller"
  std::vector<std::string> joints;  ///< the joints it owns, in its order
};

/**
 * @brief A controller's state at one time, the fields of control_msgs/
 *        JointTrajectoryControllerState (ros_control publishes it on `<controller>/state`).
 */
struct ControllerStateSample {
  double stamp = 0.0;                      ///< when it was taken [s]
  std::vector<std::string> joint_names;    ///< the controller's joints
  std::vector<double> desired_positions;   ///< the trajectory's reference
  std::vector<double> desired_velocities;  ///< its velocity
  std::vector<double> actual_positions;    ///< measured joint positions
  std::vector<double> actual_velocities;   ///< measured joint velocities
  std::vector<double> error_positions;     ///< desired - actual (ros_control's sign)
  std::vector<double> error_velocities;    ///< desired - actual
};

/** @brief The declared controllers (the parameters arm_controller, feed_controller and joints). */
struct ControllerLayoutParams {
  std::string arm_controller = "arm_controller";  ///< the arm's controller
  std::vector<std::string> arm_controller_joints = {"rsssii_joint1", "rsssii_joint2",
                                                    "rsssii_joint3", "rsssii_joint4",
                                                    "rsssii_joint5", "rsssii_joint6"};
  std::string feed_controller = "feed_controller";  ///< the feed axis's; = arm_controller: one
  std::vector<std::string> feed_controller_joints = {"feed_joint"};
  /** @brief The declaration of every field (arm_controller, arm_controller_joints, ...). */
  static const ParamTable<ControllerLayoutParams>& table();
};

/**
 * @brief The controllers of @p params: two, or one combined controller owning both joint sets
 *        when feed_controller equals arm_controller.
 * @param commandable every joint that must be owned by exactly one controller.
 * @throws std::invalid_argument naming the parameter: an empty or malformed name, a joint that
 *         is not commandable, a joint owned twice, a commandable joint no controller owns.
 */
std::vector<ControllerSpec> controllerLayout(const ControllerLayoutParams& params,
                                             const std::vector<std::string>& commandable);

/**
 * @brief Splits a command (a struct with joint_names and points, each point with positions and
 *        optionally velocities, and accelerations when the point type has them) into one
 *        command per controller that owns any of its joints, in the controllers' order.
 *        Joints no controller owns go nowhere (the caller checks them with ownerOf); a value
 *        vector whose size is not the names' goes whole to each part (its controller rejects it).
 * @return pairs (index into @p controllers, the command with that controller's joints).
 */
template <class Command>
std::vector<std::pair<std::size_t, Command>> splitByController(
    const Command& command, const std::vector<ControllerSpec>& controllers) {
  std::vector<std::pair<std::size_t, Command>> out;
  for (std::size_t c = 0; c < controllers.size(); ++c) {
    std::vector<std::size_t> columns;
    for (std::size_t j = 0; j < command.joint_names.size(); ++j) {
      const std::vector<std::string>& own = controllers[c].joints;
      if (std::find(own.begin(), own.end(), command.joint_names[j]) != own.end()) {
        columns.push_back(j);
      }
    }
    if (columns.empty()) continue;
    Command part = command;
    part.joint_names.clear();
    for (std::size_t j : columns) part.joint_names.push_back(command.joint_names[j]);
    // A vector whose size is not the names' is passed on whole: the controller rejects it.
    const std::size_t names = command.joint_names.size();
    const auto pick = [&columns, names](const std::vector<double>& v) {
      if (v.size() != names) return v;
      std::vector<double> picked;
      for (std::size_t j : columns) picked.push_back(v[j]);
      return picked;
    };
    for (std::size_t p = 0; p < command.points.size(); ++p) {
      part.points[p].positions = pick(command.points[p].positions);
      part.points[p].velocities = pick(command.points[p].velocities);
      using Point = std::decay_t<decltype(part.points[p])>;
      if constexpr (detail::hasAccelerations<Point>(0)) {
        part.points[p].accelerations = pick(command.points[p].accelerations);
      }
    }
    out.emplace_back(c, std::move(part));
  }
  return out;
}

/** @brief The index of the controller owning @p joint, or -1. */
int ownerOf(const std::vector<ControllerSpec>& controllers, const std::string& joint);

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_CONTROLLER_LAYOUT_HPP
