#include "pedicle_drilling/ros/trajectory_action_server.hpp"

#include <utility>

namespace pedicle_drilling {

TrajectoryActionServer::TrajectoryActionServer(const ros::NodeHandle& nh,
                                               const std::vector<std::string>& controllers,
                                               Hooks hooks)
    : hooks_(std::move(hooks)), nh_(nh) {
  nh_.setCallbackQueue(&queue_);
  controllers_.resize(controllers.size());
  for (std::size_t i = 0; i < controllers.size(); ++i) {
    Controller& c = controllers_[i];
    c.name = controllers[i];
    c.server = std::make_unique<Server>(
        nh_, c.name + "/follow_joint_trajectory",
        [this, i](Server::GoalHandle goal) { onGoal(i, goal); },
        [this, i](Server::GoalHandle goal) { onCancel(i, goal); }, false);
  }
  check_timer_ =
      nh_.createWallTimer(ros::WallDuration(0.01), [this](const ros::WallTimerEvent&) { check(); });
  for (Controller& c : controllers_) c.server->start();
  spinner_ = std::make_unique<ros::AsyncSpinner>(1, &queue_);
  spinner_->start();
}

TrajectoryActionServer::~TrajectoryActionServer() {
  spinner_->stop();  // no callback of ours runs after this
  check_timer_.stop();
  controllers_.clear();
}

void TrajectoryActionServer::abort(const std::string& controller, const std::string& why) {
  std::lock_guard<std::mutex> lock(aborts_mutex_);
  aborts_[controller] = why;
}

void TrajectoryActionServer::onGoal(std::size_t index, Server::GoalHandle goal) {
  Controller& c = controllers_[index];
  double end_s = 0.0;
  const core::TargetResult r = hooks_.command(c.name, goal.getGoal()->trajectory, &end_s);
  if (!r.ok()) {
    FollowJointTrajectoryResult result;
    result.error_code = FollowJointTrajectoryResult::INVALID_GOAL;
    result.error_string = r.message;
    goal.setRejected(result, r.message);
    return;  // the running goal goes on (the controller kept its trajectory)
  }
  goal.setAccepted();
  if (c.running) {
    FollowJointTrajectoryResult result;
    result.error_code = FollowJointTrajectoryResult::SUCCESSFUL;
    c.running->setCanceled(result, "replaced by a new goal");
  }
  c.running = goal;
  c.end_s = end_s;
}

void TrajectoryActionServer::onCancel(std::size_t index, Server::GoalHandle goal) {
  Controller& c = controllers_[index];
  if (!c.running || *c.running != goal) return;  // not running: actionlib ends it
  hooks_.hold(c.name);
  FollowJointTrajectoryResult result;
  result.error_code = FollowJointTrajectoryResult::SUCCESSFUL;
  c.running->setCanceled(result, "canceled: the controller holds where it is");
  c.running.reset();
}

void TrajectoryActionServer::check() {
  std::map<std::string, std::string> aborts;
  {
    std::lock_guard<std::mutex> lock(aborts_mutex_);
    aborts.swap(aborts_);
  }
  const double now = hooks_.now();
  for (Controller& c : controllers_) {
    if (!c.running) continue;
    const auto aborted = aborts.find(c.name);
    FollowJointTrajectoryResult result;
    if (aborted != aborts.end()) {
      result.error_code = FollowJointTrajectoryResult::PATH_TOLERANCE_VIOLATED;
      result.error_string = aborted->second;
      c.running->setAborted(result, aborted->second);
      c.running.reset();
    } else if (now >= c.end_s) {
      result.error_code = FollowJointTrajectoryResult::SUCCESSFUL;
      c.running->setSucceeded(result, "the trajectory ended");
      c.running.reset();
    }
  }
}

}  // namespace pedicle_drilling
