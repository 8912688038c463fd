// Copyright 2024 pedicle_drilling authors.
//
// Tests of the robot descriptions (urdf/*.urdf) and of the Bullet multibody built from them
// (pedicle_drilling::core::BulletArm).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <urdf_parser/urdf_parser.h>
#include <yaml-cpp/yaml.h>
#include <Eigen/Dense>

#include "pedicle_drilling/core/robot/bullet_arm.hpp"
#include "support.hpp"

#ifndef PEDICLE_DRILLING_SOURCE_DIR
#error "PEDICLE_DRILLING_SOURCE_DIR (the package's source folder) is passed by CMakeLists.txt"
#endif

namespace pedicle_drilling::core {
namespace {

const std::string kSourceDir = test::sourceDir();
using test::readFile;

std::string urdfPath(const std::string& name) { return kSourceDir + "/urdf/" + name; }

Eigen::Isometry3d toEigen(const urdf::Pose& p) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  double x, y, z, w;
  p.rotation.getQuaternion(x, y, z, w);
  t.linear() = Eigen::Quaterniond(w, x, y, z).normalized().toRotationMatrix();
  t.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  return t;
}

/// Independent forward kinematics straight from the urdfdom tree (no Bullet involved).
Eigen::Isometry3d urdfFk(const urdf::ModelInterface& model, const std::string& link,
                         const std::map<std::string, double>& q) {
  urdf::LinkConstSharedPtr l = model.getLink(link);
  if (!l) throw std::runtime_error("no link " + link);
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  while (l->parent_joint) {
    const urdf::Joint& j = *l->parent_joint;
    Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
    const Eigen::Vector3d axis(j.axis.x, j.axis.y, j.axis.z);
    const auto it = q.find(j.name);
    const double v = it == q.end() ? 0.0 : it->second;
    if (j.type == urdf::Joint::REVOLUTE || j.type == urdf::Joint::CONTINUOUS) {
      motion.linear() = Eigen::AngleAxisd(v, axis.normalized()).toRotationMatrix();
    } else if (j.type == urdf::Joint::PRISMATIC) {
      motion.translation() = v * axis.normalized();
    }
    t = toEigen(j.parent_to_joint_origin_transform) * motion * t;
    l = model.getLink(j.parent_link_name);
  }
  return t;
}

/// The `drilling_pose` mapping of config/drilling_pose.yaml: joint name -> value.
std::map<std::string, double> readDrillingPose(const std::string& path) {
  std::map<std::string, double> out;
  for (const auto& kv : YAML::LoadFile(path)["drilling_pose"]) {
    out[kv.first.as<std::string>()] = kv.second.as<double>();
  }
  return out;
}

Eigen::VectorXd poseVector(const BulletArm& arm, const std::map<std::string, double>& pose) {
  Eigen::VectorXd q(arm.numJoints());
  for (int k = 0; k < arm.numJoints(); ++k) q[k] = pose.at(arm.jointNames()[k]);
  return q;
}

const std::vector<std::string> kArmLinks = {
    "world",        "rsssii_base",  "rsssii_link1", "rsssii_link2", "rsssii_link3",
    "rsssii_link4", "rsssii_link5", "rsssii_link6", "device_base",  "feed_carriage",
    "ft_sensor",    "drill_motor",  "spindle",      "drill_bit",    "drill_tip"};
const std::vector<std::string> kArmJoints = {"rsssii_joint1", "rsssii_joint2", "rsssii_joint3",
                                             "rsssii_joint4", "rsssii_joint5", "rsssii_joint6",
                                             "feed_joint",    "spindle_joint"};
const std::vector<std::string> kSpmsLinks = {
    "spms_base", "slider1", "slider2",       "slider3", "rod1",
    "rod2",      "rod3",    "spms_platform", "bone",    "tracker_marker"};

class WorkcellArm : public ::testing::Test {
 protected:
  void SetUp() override {
    xml_ = readFile(urdfPath("workcell.urdf"));
    arm_ = std::make_unique<BulletArm>(xml_, "world", "drill_tip");
    pose_ = readDrillingPose(kSourceDir + "/config/drilling_pose.yaml");
  }
  std::string xml_;
  std::unique_ptr<BulletArm> arm_;
  std::map<std::string, double> pose_;
};

// ------------------------------------------------------------------------------------------

TEST(UrdfFiles, EveryUrdfParsesWithPhysicalInertiasAndLimits) {
  int count = 0;
  for (const auto& entry : std::filesystem::directory_iterator(kSourceDir + "/urdf")) {
    if (entry.path().extension() != ".urdf") continue;
    ++count;
    SCOPED_TRACE(entry.path().string());
    urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(readFile(entry.path().string()));
    ASSERT_TRUE(model) << "urdfdom failed to parse " << entry.path();
    ASSERT_TRUE(model->getRoot());
    EXPECT_EQ(model->getRoot()->name, "world");
    std::vector<urdf::LinkSharedPtr> links;
    model->getLinks(links);
    for (const auto& l : links) {
      if (!l->inertial) continue;
      SCOPED_TRACE(l->name);
      const urdf::Inertial& in = *l->inertial;
      EXPECT_GT(in.mass, 0.0);
      Eigen::Matrix3d i;
      i << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(i);
      const Eigen::Vector3d ev = es.eigenvalues();
      EXPECT_GT(ev.minCoeff(), 0.0);
      // Triangle inequality of principal moments (physically realisable body).
      EXPECT_LE(ev[2], ev[0] + ev[1] + 1e-12);
    }
    for (const auto& kv : model->joints_) {
      const urdf::Joint& j = *kv.second;
      SCOPED_TRACE(j.name);
      if (j.type == urdf::Joint::REVOLUTE || j.type == urdf::Joint::PRISMATIC) {
        ASSERT_TRUE(j.limits);
        EXPECT_LT(j.limits->lower, j.limits->upper);
        EXPECT_GT(j.limits->velocity, 0.0);
        EXPECT_GT(j.limits->effort, 0.0);
      }
      if (j.type == urdf::Joint::CONTINUOUS) {
        ASSERT_TRUE(j.limits);
        EXPECT_GT(j.limits->velocity, 0.0);
      }
    }
  }
  EXPECT_GE(count, 3);
}

TEST(UrdfFiles, ExpectedLinksAndJoints) {
  auto rsssii = urdf::parseURDF(readFile(urdfPath("rsssii.urdf")));
  auto spms = urdf::parseURDF(readFile(urdfPath("spms.urdf")));
  auto workcell = urdf::parseURDF(readFile(urdfPath("workcell.urdf")));
  ASSERT_TRUE(rsssii && spms && workcell);
  for (const auto& l : kArmLinks) {
    EXPECT_TRUE(rsssii->getLink(l)) << l;
    EXPECT_TRUE(workcell->getLink(l)) << l;
  }
  for (const auto& l : kSpmsLinks) {
    EXPECT_TRUE(spms->getLink(l)) << l;
    EXPECT_TRUE(workcell->getLink(l)) << l;
  }
  EXPECT_TRUE(workcell->getLink("tracker_camera"));
  const std::map<std::string, int> types = {
      {"rsssii_joint1", urdf::Joint::REVOLUTE},      {"rsssii_joint2", urdf::Joint::REVOLUTE},
      {"rsssii_joint3", urdf::Joint::REVOLUTE},      {"rsssii_joint4", urdf::Joint::REVOLUTE},
      {"rsssii_joint5", urdf::Joint::REVOLUTE},      {"rsssii_joint6", urdf::Joint::REVOLUTE},
      {"feed_joint", urdf::Joint::PRISMATIC},        {"spindle_joint", urdf::Joint::CONTINUOUS},
      {"slider1_joint", urdf::Joint::PRISMATIC},     {"slider2_joint", urdf::Joint::PRISMATIC},
      {"slider3_joint", urdf::Joint::PRISMATIC},     {"rod1_joint", urdf::Joint::REVOLUTE},
      {"rod2_joint", urdf::Joint::REVOLUTE},         {"rod3_joint", urdf::Joint::REVOLUTE},
      {"spms_platform_joint", urdf::Joint::FLOATING}};
  for (const auto& kv : types) {
    auto j = workcell->getJoint(kv.first);
    ASSERT_TRUE(j) << kv.first;
    EXPECT_EQ(static_cast<int>(j->type), kv.second) << kv.first;
  }
  // Feed travel 60 mm, drill bit 2.5 mm (paper Sec. V-A).
  auto feed = rsssii->getJoint("feed_joint");
  EXPECT_NEAR(feed->limits->upper - feed->limits->lower, 0.06, 1e-12);
  auto bit = rsssii->getLink("drill_bit");
  ASSERT_TRUE(bit->visual && bit->visual->geometry);
  ASSERT_EQ(bit->visual->geometry->type, urdf::Geometry::CYLINDER);
  EXPECT_NEAR(std::static_pointer_cast<urdf::Cylinder>(bit->visual->geometry)->radius * 2.0, 0.0025,
              1e-12);
  // The F/T sensor sits between the device (feed carriage) and the drill (Sec. V-A).
  EXPECT_EQ(rsssii->getLink("ft_sensor")->parent_joint->parent_link_name, "feed_carriage");
  EXPECT_EQ(rsssii->getLink("drill_motor")->parent_joint->parent_link_name, "ft_sensor");
  // The bone has three visual layers.
  EXPECT_EQ(spms->getLink("bone")->visual_array.size(), 3u);
}

TEST(UrdfFiles, SpmsNominalPoseIsConsistentWithRodLength) {
  // At the nominal pose (sliders 0.10 m, rods at -30 deg) every rod end must coincide with the
  // spherical-joint position on the platform (radius 0.04 m) at the floating joint's origin.
  auto spms = urdf::parseURDF(readFile(urdfPath("spms.urdf")));
  ASSERT_TRUE(spms);
  std::map<std::string, double> q;
  for (int i = 1; i <= 3; ++i) {
    q["slider" + std::to_string(i) + "_joint"] = 0.10;
    q["rod" + std::to_string(i) + "_joint"] = -M_PI / 6.0;
  }
  const Eigen::Isometry3d platform = urdfFk(*spms, "spms_platform", q);
  const double az[3] = {M_PI / 2.0, M_PI / 2.0 + 2.0 * M_PI / 3.0, M_PI / 2.0 + 4.0 * M_PI / 3.0};
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d rod_end =
        urdfFk(*spms, "rod" + std::to_string(i + 1), q) * Eigen::Vector3d(0, 0, 0.12);
    const Eigen::Vector3d sph =
        platform * Eigen::Vector3d(0.04 * std::cos(az[i]), 0.04 * std::sin(az[i]), 0.0);
    EXPECT_LT((rod_end - sph).norm(), 1e-6) << "branch " << i + 1;
  }
}

// ------------------------------------------------------------------------------------------

TEST(BulletArm, ChainStructureAndMergedLinks) {
  BulletArm arm(readFile(urdfPath("rsssii.urdf")), "world", "drill_tip");
  EXPECT_EQ(arm.jointNames(), kArmJoints);
  for (const auto& l : kArmLinks) EXPECT_TRUE(arm.hasLink(l)) << l;
  ASSERT_EQ(arm.jointInfo().size(), 8u);
  EXPECT_EQ(arm.jointInfo()[6].type, ArmJointType::kPrismatic);
  EXPECT_EQ(arm.jointInfo()[7].type, ArmJointType::kContinuous);
  EXPECT_NEAR(arm.jointStiffness()[1], 60.0 * 330.0, 1e-9);
  EXPECT_THROW(arm.linkPose("no_such_link"), std::out_of_range);
  // Zero configuration: arm straight up, tip at 0.12+0.18+0.42+0.36+0.07+0.07+0.03+0.3757.
  const Eigen::Isometry3d tip = arm.tipPose();
  EXPECT_NEAR(tip.translation().z(), 1.6257, 1e-5);
  EXPECT_NEAR(tip.translation().head<2>().norm(), 0.0, 1e-5);
  EXPECT_GT(tip.linear().col(2).z(), 1.0 - 1e-6);  // drill axis +z
}

TEST(BulletArm, StiffnessScaleScalesRevoluteAndPrismaticJointsOnly) {
  BulletArm arm(readFile(urdfPath("rsssii.urdf")), "world", "drill_tip");
  const Eigen::VectorXd nominal = arm.jointStiffness();
  arm.setStiffnessScale(0.7);
  const Eigen::VectorXd scaled = arm.jointStiffness();
  for (int k = 0; k < 7; ++k) EXPECT_NEAR(scaled[k], 0.7 * nominal[k], 1e-9 * nominal[k]) << k;
  EXPECT_EQ(scaled[7], nominal[7]);  // continuous spindle keeps its stiffness
  arm.setStiffnessScale(1.0);        // relative to the URDF value, not cumulative
  EXPECT_NEAR(arm.jointStiffness()[1], nominal[1], 1e-9);
  EXPECT_THROW(arm.setStiffnessScale(0.0), std::invalid_argument);
  EXPECT_THROW(arm.setStiffnessScale(std::nan("")), std::invalid_argument);
  EXPECT_THROW(arm.setStiffnessScale(11.0), std::invalid_argument);
  EXPECT_NEAR(arm.jointStiffness()[1], nominal[1], 1e-9);  // a refused scale changes nothing
}

TEST(BulletArm, LinkPosesMatchIndependentUrdfForwardKinematics) {
  const std::string xml = readFile(urdfPath("workcell.urdf"));
  auto model = urdf::parseURDF(xml);
  BulletArm arm(xml, "world", "drill_tip");
  std::mt19937 rng(42);
  for (int trial = 0; trial < 5; ++trial) {
    Eigen::VectorXd q(arm.numJoints());
    std::map<std::string, double> qmap;
    for (int k = 0; k < arm.numJoints(); ++k) {
      const ArmJointInfo& info = arm.jointInfo()[k];
      const double lo = std::isfinite(info.lower) ? info.lower : -M_PI;
      const double hi = std::isfinite(info.upper) ? info.upper : M_PI;
      q[k] = std::uniform_real_distribution<double>(lo, hi)(rng);
      qmap[arm.jointNames()[k]] = q[k];
    }
    ASSERT_TRUE(arm.resetJointState(q).ok());
    for (const auto& l : kArmLinks) {
      const Eigen::Isometry3d a = arm.linkPose(l);
      const Eigen::Isometry3d b = urdfFk(*model, l, qmap);
      EXPECT_LT((a.translation() - b.translation()).norm(), 2e-5) << l << " trial " << trial;
      EXPECT_LT((a.linear() - b.linear()).norm(), 2e-5) << l << " trial " << trial;
    }
    EXPECT_LT((arm.jointPositions() - q).norm(), 1e-5);
  }
}

TEST(BulletArm, BadUrdfThrowsClearMessage) {
  try {
    BulletArm arm("<robot name='broken'><link name='a'></robot", "a", "b");
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("could not parse"), std::string::npos) << e.what();
  }
  EXPECT_THROW(BulletArm("", "world", "drill_tip"), std::runtime_error);
  const std::string xml = readFile(urdfPath("rsssii.urdf"));
  try {
    BulletArm arm(xml, "world", "no_such_tip");
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_tip"), std::string::npos) << e.what();
  }
  try {
    BulletArm arm(xml, "drill_tip", "rsssii_link3");
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("does not descend"), std::string::npos) << e.what();
  }
  // The SPMS platform hangs off a floating joint: not simulable as a chain.
  try {
    BulletArm arm(readFile(urdfPath("spms.urdf")), "world", "bone");
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("floating"), std::string::npos) << e.what();
  }
}

TEST_F(WorkcellArm, NanAndBadTargetsAreRejectedOrClamped) {
  ASSERT_TRUE(arm_->resetJointState(poseVector(*arm_, pose_)).ok());
  const Eigen::VectorXd before = arm_->jointPositionTargets();
  Eigen::VectorXd q = before;
  q[2] = std::numeric_limits<double>::quiet_NaN();
  TargetResult r = arm_->setJointPositionTargets(q);
  EXPECT_EQ(r.status, TargetStatus::kRejected);
  EXPECT_NE(r.message.find("rsssii_joint3"), std::string::npos) << r.message;
  EXPECT_EQ(arm_->jointPositionTargets(), before);  // nothing applied
  r = arm_->setJointPositionTargets(
      std::map<std::string, double>{{"rsssii_joint1", std::numeric_limits<double>::infinity()}});
  EXPECT_EQ(r.status, TargetStatus::kRejected);
  r = arm_->setJointVelocityTargets(
      Eigen::VectorXd::Constant(arm_->numJoints(), std::numeric_limits<double>::quiet_NaN()));
  EXPECT_EQ(r.status, TargetStatus::kRejected);
  EXPECT_EQ(arm_->setJointPositionTargets(Eigen::VectorXd::Zero(3)).status,
            TargetStatus::kRejected);
  EXPECT_EQ(arm_->setJointPositionTargets(std::map<std::string, double>{{"bogus", 0.0}}).status,
            TargetStatus::kRejected);
  EXPECT_FALSE(arm_->applyTipForce(Eigen::Vector3d(0, std::nan(""), 0)));
  EXPECT_EQ(arm_->tipForce(), Eigen::Vector3d::Zero());
  // Out of limit: clamped (default policy).
  q = before;
  q[6] = 0.5;  // feed travel is 0..0.06 m
  r = arm_->setJointPositionTargets(q);
  EXPECT_EQ(r.status, TargetStatus::kClamped);
  EXPECT_NE(r.message.find("feed_joint"), std::string::npos) << r.message;
  EXPECT_DOUBLE_EQ(arm_->jointPositionTargets()[6], 0.06);
  // Velocity above the URDF limit: clamped.
  r = arm_->setJointVelocityTargets(std::map<std::string, double>{{"feed_joint", -1.0}});
  EXPECT_EQ(r.status, TargetStatus::kClamped);
  EXPECT_DOUBLE_EQ(arm_->jointVelocityTargets()[6], -0.01);
  // The state never becomes non-finite.
  arm_->step(0.2);
  EXPECT_TRUE(arm_->jointPositions().allFinite());
  EXPECT_TRUE(arm_->tipPose().matrix().allFinite());
  // Reject policy.
  BulletArmParams p;
  p.clamp_out_of_limit_targets = false;
  BulletArm strict(xml_, "world", "drill_tip", p);
  q = Eigen::VectorXd::Zero(strict.numJoints());
  q[1] = 3.0;  // joint 2 limit is +-2.0 rad
  r = strict.setJointPositionTargets(q);
  EXPECT_EQ(r.status, TargetStatus::kRejected);
  EXPECT_NE(r.message.find("rsssii_joint2"), std::string::npos) << r.message;
}

TEST_F(WorkcellArm, DrillingPosePutsTipAboveBoneWithAxisDown) {
  ASSERT_EQ(pose_.size(), 8u);
  ASSERT_TRUE(arm_->resetJointState(poseVector(*arm_, pose_)).ok());
  auto model = urdf::parseURDF(xml_);
  // Bone at the nominal SPMS pose (floating joint at its origin).
  const Eigen::Isometry3d bone = urdfFk(*model, "bone", {});
  const Eigen::Isometry3d tip = arm_->tipPose();
  const Eigen::Vector3d rel = bone.inverse() * tip.translation();
  std::cout << "[ drilling ] tip in bone frame: " << rel.transpose() * 1e3 << " mm, axis "
            << tip.linear().col(2).transpose() << std::endl;
  EXPECT_NEAR(rel.z(), 0.005, 2e-4);
  EXPECT_LT(rel.head<2>().norm(), 1e-3);
  EXPECT_LT(tip.linear().col(2).dot(bone.linear().col(2)), -0.9999);  // drill axis into bone
  // Base is about 0.6 m behind the bone.
  EXPECT_NEAR((bone.translation() - arm_->linkPose("rsssii_base").translation()).x(), 0.6, 1e-6);
  // The pose is reachable with margin: every joint at least 0.3 rad / 5 mm inside its limits
  // except the retracted feed (lower limit) and the continuous spindle.
  for (int k = 0; k < 6; ++k) {
    const ArmJointInfo& info = arm_->jointInfo()[k];
    const double v = pose_.at(info.name);
    EXPECT_GT(v - info.lower, 0.3) << info.name;
    EXPECT_GT(info.upper - v, 0.3) << info.name;
  }
  // Feeding the full travel would go 60 mm deeper: beyond the 5 mm gap + bone thickness.
  EXPECT_GT(arm_->jointInfo()[6].upper - pose_.at("feed_joint"), 0.005 + 0.01);
}

TEST_F(WorkcellArm, HoldsPoseUnderGravity) {
  ASSERT_TRUE(arm_->resetJointState(poseVector(*arm_, pose_)).ok());
  const Eigen::Vector3d p0 = arm_->tipPose().translation();
  double max_drift = 0.0;
  for (int i = 0; i < 2000; ++i) {
    EXPECT_EQ(arm_->step(1e-3), 1);
    max_drift = std::max(max_drift, (arm_->tipPose().translation() - p0).norm());
  }
  std::cout << "[ gravity ] max tip drift over 2 s: " << max_drift * 1e6 << " um" << std::endl;
  EXPECT_NEAR(arm_->simTime(), 2.0, 1e-9);
  EXPECT_LT(max_drift, 1e-4);
  EXPECT_LT(arm_->jointVelocities().norm(), 1e-3);
  // Gravity is really acting: without compensation the same pose sags.
  BulletArmParams p;
  p.gravity_compensation = false;
  BulletArm sag(xml_, "world", "drill_tip", p);
  ASSERT_TRUE(sag.resetJointState(poseVector(sag, pose_)).ok());
  sag.step(2.0);
  const double sag_dz = sag.tipPose().translation().z() - p0.z();
  std::cout << "[ gravity ] sag without compensation: " << sag_dz * 1e3 << " mm" << std::endl;
  EXPECT_LT(sag_dz, -1e-4);
}

TEST_F(WorkcellArm, PositionStepConverges) {
  const Eigen::VectorXd q0 = poseVector(*arm_, pose_);
  ASSERT_TRUE(arm_->resetJointState(q0).ok());
  Eigen::VectorXd target = q0;
  target[0] += 0.05;
  target[1] += 0.05;
  target[2] -= 0.05;
  target[4] -= 0.05;
  target[6] = 0.01;
  ASSERT_EQ(arm_->setJointPositionTargets(target).status, TargetStatus::kAccepted);
  arm_->step(0.05);
  const double err_early = (arm_->jointPositions() - target).head<6>().cwiseAbs().maxCoeff();
  arm_->step(0.95);
  const Eigen::VectorXd err = arm_->jointPositions() - target;
  std::cout << "[ step ] max joint error after 50 ms: " << err_early
            << ", after 1 s: " << err.cwiseAbs().maxCoeff() << std::endl;
  EXPECT_LT(err.head<6>().cwiseAbs().maxCoeff(), 1e-4);
  EXPECT_LT(std::abs(err[6]), 1e-6);
  EXPECT_LT(arm_->jointVelocities().head<7>().norm(), 1e-3);
  // The response is a real dynamic response, not a teleport.
  EXPECT_GT(err_early, 1e-4);
}

TEST_F(WorkcellArm, VelocityTargetsFeedTheDrill) {
  ASSERT_TRUE(arm_->resetJointState(poseVector(*arm_, pose_)).ok());
  const Eigen::Vector3d p0 = arm_->tipPose().translation();
  // Feed at 0.5 mm/s (paper Sec. V-A) and spin at 12000 rpm for 2 s.
  const double spindle = 12000.0 * 2.0 * M_PI / 60.0;
  ASSERT_EQ(arm_->setJointVelocityTargets(std::map<std::string, double>{{"feed_joint", 0.0005},
                                                                        {"spindle_joint", spindle}})
                .status,
            TargetStatus::kAccepted);
  arm_->step(2.0);
  const Eigen::Vector3d p1 = arm_->tipPose().translation();
  EXPECT_NEAR(arm_->jointPositions()[6], 0.001, 2e-5);
  EXPECT_NEAR(p1.z() - p0.z(), -0.001, 3e-5);  // drill goes down into the bone
  EXPECT_LT((p1 - p0).head<2>().norm(), 3e-5);
  EXPECT_NEAR(arm_->jointVelocities()[7], spindle, 0.01 * spindle);
  // Reference stops at the travel limit.
  ASSERT_TRUE(
      arm_->setJointVelocityTargets(std::map<std::string, double>{{"feed_joint", 0.01}}).ok());
  arm_->step(7.0);
  EXPECT_NEAR(arm_->jointPositionTargets()[6], 0.06, 1e-12);
  EXPECT_NEAR(arm_->jointPositions()[6], 0.06, 1e-4);
}

TEST_F(WorkcellArm, TipForceDeflectsAndReleases) {
  Eigen::VectorXd q = poseVector(*arm_, pose_);
  q[6] = 0.01;  // feed mid-travel, away from the hard stop
  ASSERT_TRUE(arm_->resetJointState(q).ok());
  arm_->step(0.2);
  const Eigen::Vector3d p0 = arm_->tipPose().translation();
  const std::vector<Eigen::Vector3d> forces = {
      Eigen::Vector3d(0, 0, 3.0), Eigen::Vector3d(3.0, 0, 0), Eigen::Vector3d(0, 3.0, 0)};
  for (const Eigen::Vector3d& f : forces) {
    SCOPED_TRACE(f.transpose());
    ASSERT_TRUE(arm_->applyTipForce(f));
    arm_->step(1.0);
    const Eigen::Vector3d d = arm_->tipPose().translation() - p0;
    const Eigen::Vector3d pred = arm_->predictedTipDeflection(f);
    const double along = d.dot(f.normalized());
    std::cout << "[ stiffness ] F = " << f.transpose() << " N -> deflection " << d.transpose() * 1e3
              << " mm (|d| = " << d.norm() * 1e3 << " mm, along F = " << along * 1e3
              << " mm; J K^-1 J^T F predicts " << pred.norm() * 1e3 << " mm)" << std::endl;
    EXPECT_GT(along, 0.02e-3);  // measurable, in the force direction
    EXPECT_LT(d.norm(), 0.5e-3);
    EXPECT_GT(along / d.norm(), 0.5);
    EXPECT_LT((d - pred).norm(), 0.05 * pred.norm() + 1e-6);
    // Release: back to the commanded pose.
    ASSERT_TRUE(arm_->applyTipForce(Eigen::Vector3d::Zero()));
    arm_->step(1.0);
    EXPECT_LT((arm_->tipPose().translation() - p0).norm(), 2e-6);
  }
  // The axial (drilling thrust) case is the documented 0.05-0.3 mm band.
  ASSERT_TRUE(arm_->applyTipForce(Eigen::Vector3d(0, 0, 3.0)));
  arm_->step(1.0);
  const double axial = (arm_->tipPose().translation() - p0).norm();
  EXPECT_GT(axial, 0.05e-3);
  EXPECT_LT(axial, 0.3e-3);
}

// The indexed setters (the simulation's per-step path) are the named ones without the names.
TEST(BulletArm, IndexedTargetsEqualNamedTargets) {
  const std::string xml = readFile(urdfPath("rsssii.urdf"));
  BulletArm named(xml, "world", "drill_tip"), indexed(xml, "world", "drill_tip");
  const std::vector<std::string>& names = named.jointNames();
  ASSERT_GE(names.size(), 3u);
  const std::vector<int> index = {2, 0};
  Eigen::VectorXd q(2), qd(2);
  q << 0.3, -0.2;
  qd << 0.05, 0.01;
  ASSERT_TRUE(named.setJointPositionTargets({{names[2], 0.3}, {names[0], -0.2}}).ok());
  ASSERT_TRUE(named.setJointVelocityTargets({{names[2], 0.05}, {names[0], 0.01}}).ok());
  ASSERT_TRUE(indexed.setJointPositionTargets(index, q).ok());
  ASSERT_TRUE(indexed.setJointVelocityTargets(index, qd).ok());
  EXPECT_TRUE(named.jointPositionTargets() == indexed.jointPositionTargets());
  named.step(0.05);
  indexed.step(0.05);
  EXPECT_TRUE(named.jointPositions() == indexed.jointPositions());
  const Eigen::VectorXd before = indexed.jointPositionTargets();
  EXPECT_EQ(indexed.setJointPositionTargets({static_cast<int>(names.size())}, q.head(1)).status,
            TargetStatus::kRejected);
  EXPECT_EQ(indexed.setJointVelocityTargets({0, 1}, qd.head(1)).status, TargetStatus::kRejected);
  EXPECT_TRUE(indexed.jointPositionTargets() == before);
}

// The kept inverse inertia: computed once per sub-step at tolerance 0; while the arm
// holds a pose with the spindle turning (a rotor: not watched) once; a tolerance's run stays within
// a micrometre of the exact one through a move, a feed under a tip load and a hold; a reset of
// the joints computes it afresh; a bad tolerance is refused.
TEST(BulletArm, KeptInverseInertiaFollowsTheExactServo) {
  const std::string xml = readFile(urdfPath("workcell.urdf"));
  const Eigen::VectorXd q0 = [&] {
    BulletArm probe(xml, "world", "drill_tip");
    return poseVector(probe, readDrillingPose(kSourceDir + "/config/drilling_pose.yaml"));
  }();
  BulletArmParams kept_params;
  kept_params.inverse_inertia_tolerance = 1e-4;
  BulletArm exact(xml, "world", "drill_tip"), kept(xml, "world", "drill_tip", kept_params);
  const double spindle = 12000.0 * 2.0 * M_PI / 60.0;
  Eigen::VectorXd target = q0;
  target[1] += 0.02;
  target[4] -= 0.02;
  double worst = 0.0;
  for (BulletArm* arm : {&exact, &kept}) {
    ASSERT_TRUE(arm->resetJointState(q0).ok());
    ASSERT_TRUE(arm->setJointVelocityTargets({7}, Eigen::VectorXd::Constant(1, spindle)).ok());
  }
  const auto run = [&](double seconds) {
    for (int i = 0; i < static_cast<int>(std::lround(seconds * 1000.0)); ++i) {
      exact.step(1e-3);
      kept.step(1e-3);
      worst =
          std::max(worst, (exact.tipPose().translation() - kept.tipPose().translation()).norm());
    }
  };
  // A hold at the pose, the spindle running up: the exact servo computes M^-1 every sub-step.
  const std::uint64_t kept_before_hold = kept.inverseInertiaUpdates();
  run(0.5);
  EXPECT_EQ(exact.inverseInertiaUpdates(), 500u);
  const std::uint64_t hold_updates = kept.inverseInertiaUpdates() - kept_before_hold;
  // A move of 0.02 rad on two joints, then a feed at 0.5 mm/s against a 3 N thrust.
  for (BulletArm* arm : {&exact, &kept}) ASSERT_TRUE(arm->setJointPositionTargets(target).ok());
  run(1.0);
  for (BulletArm* arm : {&exact, &kept}) {
    ASSERT_TRUE(arm->setJointVelocityTargets({6}, Eigen::VectorXd::Constant(1, 0.0005)).ok());
    ASSERT_TRUE(arm->applyTipForce(Eigen::Vector3d(0.0, 0.0, 3.0)));
  }
  run(2.0);
  std::cout << "[ inverse inertia ] updates over 3.5 s: exact " << exact.inverseInertiaUpdates()
            << ", kept " << kept.inverseInertiaUpdates() << " (hold: " << hold_updates
            << "); worst tip distance " << worst * 1e6 << " um" << std::endl;
  EXPECT_LT(hold_updates, 25u);  // the arm settles under gravity; the spindle's turning is no cause
  EXPECT_LT(kept.inverseInertiaUpdates(), exact.inverseInertiaUpdates() / 4);
  EXPECT_LT(worst, 1e-6);
  EXPECT_GT(worst, 0.0);  // not the same computation
  // A jump of the joints: computed afresh at the next sub-step.
  const std::uint64_t before = kept.inverseInertiaUpdates();
  ASSERT_TRUE(kept.resetJointState(q0).ok());
  kept.step(1e-3);
  EXPECT_EQ(kept.inverseInertiaUpdates(), before + 1);
  for (double bad : {-1e-4, std::nan(""), std::numeric_limits<double>::infinity()}) {
    BulletArmParams p;
    p.inverse_inertia_tolerance = bad;
    try {
      BulletArm arm(xml, "world", "drill_tip", p);
      ADD_FAILURE() << "tolerance " << bad << " accepted";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("inverse_inertia_tolerance"), std::string::npos);
    }
  }
}

// BulletArmParams::direct_world_step: the multibody advanced through Bullet's own passes without
// the world's collision, island and solver passes is the world's step, bit for bit, through a
// move, a feed under a tip load and the spindle's run-up; a joint at its limit (a constraint
// row) takes the world's step, and the two stay equal through it.
TEST(BulletArm, DirectWorldStepIsTheWorldsStepBitForBit) {
  const std::string xml = readFile(urdfPath("workcell.urdf"));
  const Eigen::VectorXd q0 = [&] {
    BulletArm probe(xml, "world", "drill_tip");
    return poseVector(probe, readDrillingPose(kSourceDir + "/config/drilling_pose.yaml"));
  }();
  BulletArmParams world_params, direct_params;
  world_params.inverse_inertia_tolerance = direct_params.inverse_inertia_tolerance = 1e-4;
  world_params.direct_world_step = false;
  BulletArm world(xml, "world", "drill_tip", world_params);
  BulletArm direct(xml, "world", "drill_tip", direct_params);
  int steps = 0;
  int unequal = 0;
  const auto run = [&](int n) {
    for (int i = 0; i < n; ++i, ++steps) {
      world.step(1e-3);
      direct.step(1e-3);
      const bool same =
          (world.jointPositions().array() == direct.jointPositions().array()).all() &&
          (world.jointVelocities().array() == direct.jointVelocities().array()).all() &&
          (world.jointEfforts().array() == direct.jointEfforts().array()).all();
      if (!same) ++unequal;
    }
  };
  for (BulletArm* arm : {&world, &direct}) {
    ASSERT_TRUE(arm->resetJointState(q0).ok());
    ASSERT_TRUE(arm->setJointVelocityTargets({7}, Eigen::VectorXd::Constant(1, 1256.6)).ok());
  }
  run(300);
  Eigen::VectorXd target = q0;
  target[1] += 0.02;
  target[4] -= 0.02;
  for (BulletArm* arm : {&world, &direct}) ASSERT_TRUE(arm->setJointPositionTargets(target).ok());
  run(500);
  for (BulletArm* arm : {&world, &direct}) {
    ASSERT_TRUE(arm->setJointVelocityTargets({6}, Eigen::VectorXd::Constant(1, 0.0005)).ok());
    ASSERT_TRUE(arm->applyTipForce(Eigen::Vector3d(0.0, 0.0, 3.0)));
  }
  const std::uint64_t before_feed = direct.directWorldSteps();
  run(500);
  // The feed starts on its lower limit (a row: the world's step) and leaves it within steps.
  EXPECT_GE(direct.directWorldSteps() - before_feed, 480u);
  // The feed joint teleported onto its upper limit and held there: Bullet makes a limit row.
  const ArmJointInfo feed = direct.jointInfo()[6];
  Eigen::VectorXd at_limit = direct.jointPositions();
  at_limit[6] = feed.upper;
  for (BulletArm* arm : {&world, &direct}) {
    ASSERT_TRUE(arm->resetJointState(at_limit).ok());
    ASSERT_TRUE(arm->setJointVelocityTargets({6}, Eigen::VectorXd::Constant(1, 0.01)).ok());
  }
  const std::uint64_t before_limit = direct.directWorldSteps();
  run(200);
  std::cout << "[ direct step ] " << direct.directWorldSteps() << " of " << steps
            << " sub-steps direct; " << unequal << " unequal" << std::endl;
  EXPECT_EQ(unequal, 0);
  EXPECT_EQ(world.directWorldSteps(), 0u);
  EXPECT_LT(direct.directWorldSteps() - before_limit, 200u);  // the limit took the world's step
  EXPECT_GT(world.jointVelocities().norm(), 0.0);             // not a frozen arm
}

}  // namespace
}  // namespace pedicle_drilling::core
