// Copyright 2024 pedicle_drilling authors.
//
// Benchmark of pedicle_drilling::core::BulletArm: the RSSSII chain of urdf/workcell.urdf at the
// drilling pose, stepped at 1 kHz for 60 s of simulated time while feeding at 0.5 mm/s,
// spinning at 12000 rpm and loaded with a 3 N axial tip force (paper Sec. V-A, V-C).
// Prints
//   BENCH bullet_arm_step <us> us                   mean wall time of one 1 ms step
//   BENCH bullet_arm_real_time_factor <ratio> x     simulated time / wall time
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>

#include <Eigen/Core>

#include "pedicle_drilling/core/robot/bullet_arm.hpp"

#ifndef PEDICLE_DRILLING_SOURCE_DIR
#error "PEDICLE_DRILLING_SOURCE_DIR (the package's source folder) is passed by CMakeLists.txt"
#endif

namespace {

std::string readFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open " + path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

int main() {
  using pedicle_drilling::core::BulletArm;
  try {
    const std::string dir = PEDICLE_DRILLING_SOURCE_DIR;
    BulletArm arm(readFile(dir + "/urdf/workcell.urdf"), "world", "drill_tip");
    // Drilling pose of config/drilling_pose.yaml.
    const std::map<std::string, double> pose = {
        {"rsssii_joint1", 0.0}, {"rsssii_joint2", 0.435859}, {"rsssii_joint3", 1.319709},
        {"rsssii_joint4", 0.0}, {"rsssii_joint5", 1.386025}, {"rsssii_joint6", 0.0},
        {"feed_joint", 0.0},    {"spindle_joint", 0.0}};
    Eigen::VectorXd q(arm.numJoints());
    for (int k = 0; k < arm.numJoints(); ++k) q[k] = pose.at(arm.jointNames()[k]);
    if (!arm.resetJointState(q).ok()) throw std::runtime_error("drilling pose rejected");
    arm.setJointVelocityTargets(std::map<std::string, double>{
        {"feed_joint", 0.0005}, {"spindle_joint", 12000.0 * 2.0 * M_PI / 60.0}});
    arm.applyTipForce(Eigen::Vector3d(0.0, 0.0, 3.0));

    const double dt = 1e-3;
    const int steps = 60000;
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < steps; ++i) arm.step(dt);
    const auto t1 = std::chrono::steady_clock::now();
    const double wall = std::chrono::duration<double>(t1 - t0).count();
    if (!arm.jointPositions().allFinite()) throw std::runtime_error("state diverged");
    std::printf("sim %.3f s, feed %.4f m, tip z %.6f m\n", arm.simTime(), arm.jointPositions()[6],
                arm.tipPose().translation().z());
    std::printf("BENCH bullet_arm_step %.3f us\n", wall / steps * 1e6);
    std::printf("BENCH bullet_arm_real_time_factor %.2f x\n", steps * dt / wall);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_sim_step: %s\n", e.what());
    return 1;
  }
  return 0;
}
