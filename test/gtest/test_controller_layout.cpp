// Tests of core::controllerLayout and core::splitByController: the controllers a lab wires (a
// 6-joint arm controller plus a feed-axis controller, or one combined controller) and the split
// of the planner's 7-joint command into one command per controller.
#include "pedicle_drilling/core/robot/controller_layout.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "pedicle_drilling/core/control/trial_sequencer.hpp"
#include "pedicle_drilling/core/robot/trajectory_executor.hpp"

namespace pd = pedicle_drilling::core;

namespace {

const std::vector<std::string> kCommandable = {"rsssii_joint1", "rsssii_joint2", "rsssii_joint3",
                                               "rsssii_joint4", "rsssii_joint5", "rsssii_joint6",
                                               "feed_joint"};

std::string errorOf(const pd::ControllerLayoutParams& p) {
  try {
    pd::controllerLayout(p, kCommandable);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(ControllerLayout, DefaultIsAnArmControllerAndAFeedController) {
  const std::vector<pd::ControllerSpec> c = pd::controllerLayout({}, kCommandable);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0].name, "arm_controller");
  EXPECT_EQ(c[0].joints.size(), 6u);
  EXPECT_EQ(c[1].name, "feed_controller");
  EXPECT_EQ(c[1].joints, std::vector<std::string>{"feed_joint"});
  EXPECT_EQ(pd::ownerOf(c, "feed_joint"), 1);
  EXPECT_EQ(pd::ownerOf(c, "rsssii_joint4"), 0);
  EXPECT_EQ(pd::ownerOf(c, "spindle_joint"), -1);
}

TEST(ControllerLayout, OneNameForBothIsOneCombinedController) {
  pd::ControllerLayoutParams p;
  p.feed_controller = p.arm_controller;
  const std::vector<pd::ControllerSpec> c = pd::controllerLayout(p, kCommandable);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].joints, kCommandable);
}

TEST(ControllerLayout, BadLayoutsNameTheParameter) {
  pd::ControllerLayoutParams p;
  p.arm_controller = "";
  EXPECT_NE(errorOf(p).find("arm_controller = ''"), std::string::npos) << errorOf(p);
  p = {};
  p.feed_controller = "/abs/";
  EXPECT_NE(errorOf(p).find("feed_controller"), std::string::npos) << errorOf(p);
  p = {};
  p.feed_controller_joints = {"feed_joint", "rsssii_joint1"};
  EXPECT_NE(errorOf(p).find("feed_controller_joints: joint 'rsssii_joint1' is owned"),
            std::string::npos)
      << errorOf(p);
  p = {};
  p.feed_controller_joints = {"spindle_joint"};
  EXPECT_NE(errorOf(p).find("feed_controller_joints: 'spindle_joint' is not a commandable"),
            std::string::npos)
      << errorOf(p);
  p = {};
  p.arm_controller_joints.pop_back();
  EXPECT_NE(errorOf(p).find("no controller owns 'rsssii_joint6'"), std::string::npos) << errorOf(p);
  p = {};
  p.feed_controller_joints.clear();
  EXPECT_NE(errorOf(p).find("feed_controller_joints must name at least one joint"),
            std::string::npos)
      << errorOf(p);
}

TEST(ControllerLayout, SplitGivesEachControllerItsColumnsInTheCommandsOrder) {
  const std::vector<pd::ControllerSpec> c = pd::controllerLayout({}, kCommandable);
  pd::JointTrajectoryCommand cmd;
  cmd.start_time = 3.0;
  cmd.joint_names = {"feed_joint",    "rsssii_joint2", "rsssii_joint1", "rsssii_joint3",
                     "rsssii_joint4", "rsssii_joint5", "rsssii_joint6"};
  cmd.points.push_back({0.125, {7, 2, 1, 3, 4, 5, 6}, {70, 20, 10, 30, 40, 50, 60}});
  cmd.points.push_back({0.25, {17, 12, 11, 13, 14, 15, 16}, {}});
  const auto parts = pd::splitByController(cmd, c);
  ASSERT_EQ(parts.size(), 2u);
  EXPECT_EQ(parts[0].first, 0u);
  EXPECT_EQ(parts[0].second.start_time, 3.0);
  EXPECT_EQ(parts[0].second.joint_names[0], "rsssii_joint2");
  EXPECT_EQ(parts[0].second.points[0].positions, (std::vector<double>{2, 1, 3, 4, 5, 6}));
  EXPECT_EQ(parts[0].second.points[0].velocities, (std::vector<double>{20, 10, 30, 40, 50, 60}));
  EXPECT_TRUE(parts[0].second.points[1].velocities.empty());
  EXPECT_EQ(parts[0].second.points[1].time_from_start, 0.25);
  EXPECT_EQ(parts[1].first, 1u);
  EXPECT_EQ(parts[1].second.joint_names, std::vector<std::string>{"feed_joint"});
  EXPECT_EQ(parts[1].second.points[1].positions, std::vector<double>{17});

  // The executor's command type keeps accelerations too.
  pd::TrajectoryCommand t;
  t.joint_names = {"rsssii_joint1", "feed_joint"};
  t.points.push_back({1.0, {1, 2}, {3, 4}, {5, 6}});
  const auto tparts = pd::splitByController(t, c);
  ASSERT_EQ(tparts.size(), 2u);
  EXPECT_EQ(tparts[1].second.points[0].accelerations, std::vector<double>{6});
  // Only the controllers the command touches get a part.
  t.joint_names = {"rsssii_joint1"};
  t.points = {{1.0, {1}}};
  EXPECT_EQ(pd::splitByController(t, c).size(), 1u);
}

TEST(ControllerLayout, ASizeMismatchIsPassedOnForTheControllerToReject) {
  const std::vector<pd::ControllerSpec> c = pd::controllerLayout({}, kCommandable);
  pd::TrajectoryCommand t;
  t.joint_names = {"feed_joint"};
  t.points.push_back({1.0, {0.01, 0.02}});
  const auto parts = pd::splitByController(t, c);
  ASSERT_EQ(parts.size(), 1u);
  EXPECT_EQ(parts[0].second.points[0].positions.size(), 2u);
  pd::JointTrajectoryExecutor feed({"feed_joint"}, {{0.0, 0.06, 0.01}}, Eigen::VectorXd::Zero(1));
  EXPECT_EQ(feed.command(parts[0].second, 0.0).status, pd::TargetStatus::kRejected);
}
