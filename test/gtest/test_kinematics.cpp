// Tests of the urdfdom -> KDL chain (kdl_parser), FK and IK, on a 6-DoF arm with a prismatic feed
// axis.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include "pedicle_drilling/core/robot/kinematics.hpp"

namespace pedicle_drilling::core {
namespace {

const char kArm[] = R"(<?xml version="1.0"?>
<robot name="test_arm">
  <link name="world"/>
  <link name="base_link"/>
  <link name="link1"/><link name="link2"/><link name="link3"/>
  <link name="link4"/><link name="link5"/><link name="link6"/>
  <link name="flange"/><link name="feed_carriage"/><link name="drill_tip"/>
  <link name="camera"/>
  <joint name="world_to_base" type="fixed">
    <parent link="world"/><child link="base_link"/>
    <origin xyz="0.5 0 0.1" rpy="0 0 1.5707963267948966"/>
  </joint>
  <joint name="camera_mount" type="fixed">
    <parent link="base_link"/><child link="camera"/><origin xyz="0 1 1"/>
  </joint>
  <joint name="j1" type="revolute">
    <parent link="base_link"/><child link="link1"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/>
    <limit lower="-3.0" upper="3.0" effort="10" velocity="1"/>
  </joint>
  <joint name="j2" type="revolute">
    <parent link="link1"/><child link="link2"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>
    <limit lower="-2.0" upper="2.0" effort="10" velocity="1"/>
  </joint>
  <joint name="j3" type="revolute">
    <parent link="link2"/><child link="link3"/>
    <origin xyz="0 0 0.4"/><axis xyz="0 1 0"/>
    <limit lower="-2.5" upper="2.5" effort="10" velocity="1"/>
  </joint>
  <joint name="j4" type="revolute">
    <parent link="link3"/><child link="link4"/>
    <origin xyz="0.35 0 0" rpy="0 1.5707963267948966 0"/><axis xyz="0 0 1"/>
    <limit lower="-3.0" upper="3.0" effort="10" velocity="1"/>
  </joint>
  <joint name="j5" type="revolute">
    <parent link="link4"/><child link="link5"/>
    <origin xyz="0 0 0.05"/><axis xyz="0 1 0"/>
    <limit lower="-2.0" upper="2.0" effort="10" velocity="1"/>
  </joint>
  <joint name="j6" type="continuous">
    <parent link="link5"/><child link="link6"/>
    <origin xyz="0 0 0.08"/><axis xyz="0 0 1"/>
  </joint>
  <joint name="flange_fixed" type="fixed">
    <parent link="link6"/><child link="flange"/><origin xyz="0 0 0.02"/>
  </joint>
  <joint name="feed" type="prismatic">
    <parent link="flange"/><child link="feed_carriage"/>
    <origin xyz="0 0 0.05"/><axis xyz="0 0 1"/>
    <limit lower="0.0" upper="0.1" effort="10" velocity="0.01"/>
  </joint>
  <joint name="tip_fixed" type="fixed">
    <parent link="feed_carriage"/><child link="drill_tip"/><origin xyz="0 0 0.12"/>
  </joint>
</robot>
)";

KinematicChain arm() { return KinematicChain::fromUrdfString(kArm, "base_link", "drill_tip"); }

TEST(KinematicsTest, ChainStructureAndLimits) {
  const KinematicChain k = arm();
  ASSERT_EQ(k.numJoints(), 7u);
  const std::vector<std::string> names = {"j1", "j2", "j3", "j4", "j5", "j6", "feed"};
  EXPECT_EQ(k.jointNames(), names);
  EXPECT_EQ(k.chain().getNrOfSegments(), 9u);  // 7 movable + flange_fixed + tip_fixed
  EXPECT_DOUBLE_EQ(k.lowerLimits()(1), -2.0);
  EXPECT_DOUBLE_EQ(k.upperLimits()(6), 0.1);
  EXPECT_TRUE(std::isinf(k.lowerLimits()(5)));  // continuous
  EXPECT_TRUE(std::isinf(k.upperLimits()(5)));
}

TEST(KinematicsTest, ForwardAtZeroMatchesHandComputation) {
  const KinematicChain k = arm();
  const Eigen::Isometry3d T = k.forward(Eigen::VectorXd::Zero(7));
  // Up 0.3 + 0.1 + 0.4 = 0.8, along x 0.35 to the wrist, then the tool z (rotated by +90 deg
  // about y) points along base +x: 0.05 + 0.08 + 0.02 + 0.05 + 0.12 = 0.32.
  EXPECT_NEAR((T.translation() - Eigen::Vector3d(0.35 + 0.32, 0, 0.8)).norm(), 0, 1e-12);
  EXPECT_NEAR((T.linear().col(2) - Eigen::Vector3d::UnitX()).norm(), 0, 1e-12);
}

TEST(KinematicsTest, ForwardJointAxesAndFeed) {
  const KinematicChain k = arm();
  Eigen::VectorXd q = Eigen::VectorXd::Zero(7);
  q(0) = M_PI / 2;  // base rotation: x -> y
  const Eigen::Isometry3d T = k.forward(q);
  EXPECT_NEAR((T.translation() - Eigen::Vector3d(0, 0.67, 0.8)).norm(), 0, 1e-12);
  // The prismatic feed moves the tip along the tool axis by exactly the joint value.
  Eigen::VectorXd q1 = Eigen::VectorXd::Zero(7);
  q1 << 0.3, -0.4, 0.7, 0.2, 0.5, 1.1, 0.0;
  Eigen::VectorXd q2 = q1;
  q2(6) = 0.037;
  const Eigen::Isometry3d A = k.forward(q1), B = k.forward(q2);
  EXPECT_NEAR((B.translation() - A.translation() - 0.037 * A.linear().col(2)).norm(), 0, 1e-12);
  EXPECT_NEAR((A.linear() - B.linear()).norm(), 0, 1e-12);
  // A chain starting at world includes the fixed, rotated base mount.
  const KinematicChain kw = KinematicChain::fromUrdfString(kArm, "world", "drill_tip");
  const Eigen::Isometry3d W = kw.forward(Eigen::VectorXd::Zero(7));
  EXPECT_NEAR((W.translation() - Eigen::Vector3d(0.5, 0.67, 0.9)).norm(), 0, 1e-12);
}

TEST(KinematicsTest, InverseRoundTrip) {
  const KinematicChain k = arm();
  std::mt19937 rng(7);
  int ok = 0;
  for (int trial = 0; trial < 40; ++trial) {
    Eigen::VectorXd q(7);
    for (int i = 0; i < 7; ++i) {
      const double lo = std::isfinite(k.lowerLimits()(i)) ? k.lowerLimits()(i) : -M_PI;
      const double hi = std::isfinite(k.upperLimits()(i)) ? k.upperLimits()(i) : M_PI;
      q(i) =
          std::uniform_real_distribution<double>(lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo))(rng);
    }
    const Eigen::Isometry3d target = k.forward(q);
    Eigen::VectorXd seed = q;
    for (int i = 0; i < 6; ++i) seed(i) += std::uniform_real_distribution<double>(-0.3, 0.3)(rng);
    seed(6) = 0.05;
    const IkResult r = k.inverse(target, seed);
    ASSERT_TRUE(r.success) << trial << " " << r.message;
    ++ok;
    EXPECT_LT(r.position_error_m, 1e-6);
    EXPECT_LT(r.orientation_error_rad, 1e-6);
    EXPECT_TRUE(k.withinLimits(r.q));
    // Independent check of the returned errors.
    const Eigen::Isometry3d reached = k.forward(r.q);
    EXPECT_LT((reached.translation() - target.translation()).norm(), 1e-6);
    EXPECT_LT((reached.linear() - target.linear()).norm(), 2e-6);
  }
  EXPECT_EQ(ok, 40);
}

TEST(KinematicsTest, InverseUnreachableFails) {
  const KinematicChain k = arm();
  Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
  target.translation() = Eigen::Vector3d(3.0, 0, 0.5);  // arm reach is about 1.3 m
  IkOptions opt;
  opt.max_attempts = 3;
  const IkResult r = k.inverse(target, Eigen::VectorXd::Zero(7), opt);
  EXPECT_FALSE(r.success);
  EXPECT_GT(r.position_error_m, 1.0);
  EXPECT_FALSE(r.message.empty());
  EXPECT_EQ(r.attempts, 3);
}

TEST(KinematicsTest, Errors) {
  EXPECT_THROW(KinematicChain::fromUrdfString("<robot", "a", "b"), std::invalid_argument);
  EXPECT_THROW(KinematicChain::fromUrdfString(kArm, "nope", "drill_tip"), std::invalid_argument);
  EXPECT_THROW(KinematicChain::fromUrdfString(kArm, "base_link", "nope"), std::invalid_argument);
  // camera is on a side branch: base of drill_tip is not an ancestor.
  EXPECT_THROW(KinematicChain::fromUrdfString(kArm, "camera", "drill_tip"), std::invalid_argument);
  std::string floating = kArm;
  floating.replace(floating.find("name=\"j3\" type=\"revolute\""), 25,
                   "name=\"j3\" type=\"floating\"");
  EXPECT_THROW(KinematicChain::fromUrdfString(floating, "base_link", "drill_tip"),
               std::invalid_argument);
  const KinematicChain k = arm();
  EXPECT_THROW(k.forward(Eigen::VectorXd::Zero(6)), std::invalid_argument);
  Eigen::VectorXd bad = Eigen::VectorXd::Zero(7);
  bad(2) = std::nan("");
  EXPECT_THROW(k.forward(bad), std::invalid_argument);
  EXPECT_THROW(k.inverse(Eigen::Isometry3d::Identity(), bad), std::invalid_argument);
}

TEST(KinematicsTest, JointOnAnotherBranchIsNotConverted) {
  // kdl_parser converts the base -> tip path only: a floating joint on the camera's branch
  // neither changes the arm's chain nor is converted (kdl_parser would make it fixed, warning).
  std::string model = kArm;
  const std::string mount = "name=\"camera_mount\" type=\"fixed\"";
  model.replace(model.find(mount), mount.size(), "name=\"camera_mount\" type=\"floating\"");
  const KinematicChain k = KinematicChain::fromUrdfString(model, "base_link", "drill_tip");
  EXPECT_EQ(k.jointNames(), arm().jointNames());
  const Eigen::VectorXd q = Eigen::VectorXd::LinSpaced(7, -0.6, 0.9);
  EXPECT_EQ(k.forward(q).matrix(), arm().forward(q).matrix());  // bit for bit
  try {
    KinematicChain::fromUrdfString(model, "base_link", "camera");
    ADD_FAILURE() << "a floating joint on the chain must be refused";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("camera_mount"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace pedicle_drilling::core
