#include "pedicle_drilling/ros/trajectory_route.hpp"

#include <ros/callback_queue_interface.h>

#include <boost/make_shared.hpp>
#include <iomanip>
#include <sstream>
#include <utility>

#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling {

namespace {

/** @brief A function run once on a callback queue. */
class DeferredCall : public ros::CallbackInterface {
 public:
  explicit DeferredCall(std::function<void()> call) : call_(std::move(call)) {}
  CallResult call() override {
    call_();
    return Success;
  }

 private:
  std::function<void()> call_;
};

/** @brief control_msgs' name of a FollowJointTrajectory error code. */
std::string errorCodeName(std::int32_t code) {
  using R = FollowJointTrajectoryResult;
  switch (code) {
    case R::SUCCESSFUL:
      return "SUCCESSFUL";
    case R::INVALID_GOAL:
      return "INVALID_GOAL";
    case R::INVALID_JOINTS:
      return "INVALID_JOINTS";
    case R::OLD_HEADER_TIMESTAMP:
      return "OLD_HEADER_TIMESTAMP";
    case R::PATH_TOLERANCE_VIOLATED:
      return "PATH_TOLERANCE_VIOLATED";
    case R::GOAL_TOLERANCE_VIOLATED:
      return "GOAL_TOLERANCE_VIOLATED";
    default:
      return "unknown error code";
  }
}

}  // namespace

TrajectoryRoute::TrajectoryRoute(ros::NodeHandle& nh, const std::vector<std::string>& controllers,
                                 bool use_action, FaultHandler on_fault)
    : use_action_(use_action), nh_(nh), on_fault_(std::move(on_fault)) {
  controllers_.resize(controllers.size());
  for (std::size_t i = 0; i < controllers.size(); ++i) {
    Controller& c = controllers_[i];
    if (use_action_) {
      c.name = nh_.resolveName(controllers[i] + "/follow_joint_trajectory");
      c.client = std::make_unique<Client>(nh_, controllers[i] + "/follow_joint_trajectory");
    } else {
      c.name = nh_.resolveName(controllers[i] + "/command");
      c.publisher =
          nh_.advertise<trajectory_msgs::JointTrajectory>(controllers[i] + "/command", 10);
    }
  }
}

TrajectoryRoute::~TrajectoryRoute() {
  {
    std::lock_guard<std::mutex> lock(goals_mutex_);
    for (Controller& c : controllers_) {
      // The planner unloaded mid-trial: the controllers hold (the drill guard stops the drives
      // of a planner that dies without this).
      for (Client::GoalHandle& goal : c.goals) {
        if (goal.getCommState() != actionlib::CommState::DONE) goal.cancel();
      }
      c.goals.clear();
    }
  }
  for (Controller& c : controllers_) c.client.reset();
  // A deferred fault not run yet is dropped; one running ends first (removeByID waits for it).
  nh_.getCallbackQueue()->removeByID(reinterpret_cast<std::uint64_t>(this));
}

void TrajectoryRoute::send(std::size_t index, const trajectory_msgs::JointTrajectory& trajectory) {
  Controller& c = controllers_.at(index);
  if (!use_action_) {
    c.publisher.publish(boost::make_shared<trajectory_msgs::JointTrajectory>(trajectory));
    return;
  }
  FollowJointTrajectoryGoal goal;
  goal.trajectory = trajectory;  // tolerances empty: the controller's own
  std::lock_guard<std::mutex> lock(goals_mutex_);
  // The goals seen done are forgotten; the others are kept to the end, so that an abort of a goal
  // already replaced is heard too.
  c.goals.remove_if(
      [](Client::GoalHandle& g) { return g.getCommState() == actionlib::CommState::DONE; });
  const std::uint64_t serial = c.running->load() + 1;
  c.running->store(serial);  // before the send: the old goal's preemption is not the running one's
  c.goals.push_back(c.client->sendGoal(
      goal, [this, index, serial](Client::GoalHandle g) { onTransition(index, serial, g); }));
}

bool TrajectoryRoute::waitForServers(double timeout_s, std::string* why) const {
  if (!use_action_) return true;
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
  for (const Controller& c : controllers_) {
    while (!c.client->isServerConnected()) {
      if (ros::WallTime::now() > deadline || !ros::ok()) {
        *why = "trial refused: no action server " + c.name +
               " (FollowJointTrajectory, ~trajectory_interface action) within " +
               core::Range::format(timeout_s) +
               " s (~action_server_timeout_s; is the controller loaded?); nothing was started";
        return false;
      }
      ros::WallDuration(0.01).sleep();
    }
  }
  return true;
}

void TrajectoryRoute::onTransition(std::size_t index, std::uint64_t serial,
                                   Client::GoalHandle goal) {
  // Inside actionlib's lock: no lock of ours, no goal sent (defer).
  if (goal.getCommState() != actionlib::CommState::DONE) return;
  const Controller& c = controllers_[index];
  const actionlib::TerminalState end = goal.getTerminalState();
  const bool running = serial == c.running->load();
  std::string what;
  switch (end.state_) {
    case actionlib::TerminalState::SUCCEEDED:
      return;
    case actionlib::TerminalState::PREEMPTED:
    case actionlib::TerminalState::RECALLED:
      if (!running) return;  // replaced by the planner's next goal
      what = "canceled the running goal (another client's goal or cancel)";
      break;
    case actionlib::TerminalState::REJECTED:
      what = "rejected a goal";
      break;
    case actionlib::TerminalState::ABORTED:
      what = "aborted a goal";
      break;
    case actionlib::TerminalState::LOST:
      what = "lost a goal (the action server stopped reporting it)";
      break;
  }
  std::ostringstream why;
  why << "controller fault: " << c.name << " " << what;
  const FollowJointTrajectoryResultConstPtr result = goal.getResult();
  if (result) {
    why << " (error_code " << result->error_code << " " << errorCodeName(result->error_code);
    if (!result->error_string.empty()) why << ": " << result->error_string;
    why << ")";
  }
  defer(why.str());
}

void TrajectoryRoute::defer(const std::string& why) {
  FaultHandler handler = on_fault_;
  nh_.getCallbackQueue()->addCallback(
      boost::make_shared<DeferredCall>([handler, why]() { handler(why); }),
      reinterpret_cast<std::uint64_t>(this));
}

}  // namespace pedicle_drilling
