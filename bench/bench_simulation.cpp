// Copyright 2024 pedicle_drilling authors.
//
// Headless benchmark of pedicle_drilling::core::DrillingSimulation (the Simulator nodelet's
// core, no ROS): a 60 s stationary drilling trial of urdf/workcell.urdf. The arm moves from its
// home pose to the drilling pose of config/drilling_pose.yaml in 2 s, the spindle runs at
// 12000 rpm and the feed joint advances at 0.5 mm/s (paper Sec. V-A) for the rest of the minute.
// 1 kHz drilling physics and force sensor, the Bullet arm at 1 kHz (250 Hz in air, clear of the
// bone). Prints
//   BENCH sim_real_time_factor <ratio> x   simulated time / wall time (target >= 50 x)
//   BENCH sim_step_cost <us> us            mean wall time of one 1 ms physics step
#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>

#include "pedicle_drilling/core/sim/drilling_simulation.hpp"

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
  namespace core = pedicle_drilling::core;
  try {
    const std::string dir = PEDICLE_DRILLING_SOURCE_DIR;
    core::DrillingSimulationParams params;
    params.spindle_watchdog_s = 0.0;  // one spindle command, no keepalive
    core::DrillingSimulation sim(readFile(dir + "/urdf/workcell.urdf"), params, 1);
    sim.reset(1, false);
    // Drilling pose of config/drilling_pose.yaml, reached 2 s after the start.
    core::TrajectoryCommand approach;
    approach.joint_names = {"rsssii_joint1", "rsssii_joint2", "rsssii_joint3", "rsssii_joint4",
                            "rsssii_joint5", "rsssii_joint6", "feed_joint"};
    approach.points.push_back(
        {sim.time() + 2.0, {0.0, 0.435859, 1.319709, 0.0, 1.386025, 0.0, 0.0}, {}});
    if (!sim.commandTrajectory(approach).ok()) throw std::runtime_error("approach rejected");
    sim.commandSpindle(12000.0);
    const auto t0 = std::chrono::steady_clock::now();
    int steps = sim.step(2.0);
    core::TrajectoryCommand feed;
    feed.joint_names = {"feed_joint"};
    feed.points.push_back({sim.time() + 58.0, {0.029}, {}});  // 0.5 mm/s
    if (!sim.commandTrajectory(feed).ok()) throw std::runtime_error("feed rejected");
    steps += sim.step(58.0);
    const auto t1 = std::chrono::steady_clock::now();
    const double wall = std::chrono::duration<double>(t1 - t0).count();
    const core::SimulationGroundTruth gt = sim.groundTruth();
    std::printf("sim %.3f s in %.3f s wall; depth cut %.3f mm, breakthrough %d\n", sim.time(), wall,
                gt.max_depth_cut_m * 1e3, gt.breakthrough ? 1 : 0);
    std::printf("BENCH sim_real_time_factor %.1f x\n", sim.time() / wall);
    std::printf("BENCH sim_step_cost %.2f us\n", wall / steps * 1e6);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_simulation: %s\n", e.what());
    return 1;
  }
  return 0;
}
