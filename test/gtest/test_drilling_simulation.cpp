/**
 * @file test_drilling_simulation.cpp
 * @brief The simulated workcell without ROS: stationary drilling through the arm's feed joint
 *        (two cortical peaks, ground-truth depth, arm deflection), the SPMS platform following
 *        its rate-limited sliders, the virtual patient, and the command interface.
 */
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <limits>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/virtual_volunteer.hpp"
#include "pedicle_drilling/core/control/safety_monitor.hpp"
#include "pedicle_drilling/core/sim/drilling_simulation.hpp"
#include "support.hpp"

namespace pedicle_drilling::core {
namespace {

std::string workcell() { return pedicle_drilling::test::workcellUrdf(); }

/** @brief The defaults without the spindle driver's watchdog: these tests command the spindle
 *         once, as no client of the driver would (TheSpindleDriversWatchdog... tests it). */
DrillingSimulationParams unwatched() {
  DrillingSimulationParams p;
  p.spindle_watchdog_s = 0.0;
  return p;
}

const std::vector<std::string> kJoints = {"rsssii_joint1", "rsssii_joint2", "rsssii_joint3",
                                          "rsssii_joint4", "rsssii_joint5", "rsssii_joint6",
                                          "feed_joint"};
// config/drilling_pose.yaml
const std::vector<double> kDrillingPose = {0.0, 0.435859, 1.319709, 0.0, 1.386025, 0.0, 0.0};

void moveToDrillingPose(DrillingSimulation* sim, double duration) {
  TrajectoryCommand c;
  c.joint_names = kJoints;
  c.points.push_back({sim->time() + duration, kDrillingPose, {}});
  ASSERT_EQ(sim->commandTrajectory(c).status, TargetStatus::kAccepted);
  sim->step(duration + 0.5);
}

struct TrialRecord {
  std::vector<double> block_mean;     // 50-sample means of the measured force z
  std::vector<Material> block_layer;  // layer at the deepest cut at the block end
  double outer_peak = 0.0, inner_peak = 0.0, cancellous_mean = 0.0;
  double max_deflection = 0.0;  // commanded minus actual depth while cutting [m]
  double gap = 0.0;             // tip above the bone when the feed starts [m]
};

// Drills a stationary specimen at 0.5 mm/s, 12000 rpm, by commanding the feed joint.
TrialRecord drillStationary(DrillingSimulation* sim, double feed_m) {
  TrialRecord r;
  sim->commandSpindle(12000.0);
  moveToDrillingPose(sim, 1.0);
  r.gap = -sim->groundTruth().tip_depth_m;
  const double t0 = sim->time();
  TrajectoryCommand feed;
  feed.joint_names = {"feed_joint"};
  feed.points.push_back({t0 + feed_m / 0.5e-3, {feed_m}, {}});
  EXPECT_TRUE(sim->commandTrajectory(feed).ok());
  double sum = 0.0;
  int n = 0;
  double canc_sum = 0.0;
  int canc_n = 0;
  const int steps = static_cast<int>((feed_m / 0.5e-3 + 1.0) / sim->physicsDt());
  for (int i = 0; i < steps; ++i) {
    const SimulationStep s = sim->stepOnce();
    if (s.force.contact) {
      const double commanded = std::min(feed_m, 0.5e-3 * (s.time_s - t0)) - r.gap;
      r.max_deflection = std::max(r.max_deflection, commanded - s.tip_depth_m);
    }
    if (!s.force_sampled) continue;  // the DAQ samples every physics_rate / rate steps
    sum += s.measured_wrench[2];
    if (++n == 50) {
      const Material layer = sim->process().currentLayer();
      r.block_mean.push_back(sum / n);
      r.block_layer.push_back(layer);
      if (layer == Material::kOuterCortical) r.outer_peak = std::max(r.outer_peak, sum / n);
      if (layer == Material::kInnerCortical) r.inner_peak = std::max(r.inner_peak, sum / n);
      const double d = sim->groundTruth().max_depth_cut_m;
      const auto& sp = sim->process().specimen();
      // Cancellous level well away from both boundaries (tip cone 0.75 mm).
      if (d > sp.outerCorticalEnd() + 1.0e-3 && d < sp.innerCorticalStart() - 0.2e-3) {
        canc_sum += sum / n;
        ++canc_n;
      }
      sum = 0.0;
      n = 0;
    }
  }
  r.cancellous_mean = canc_n > 0 ? canc_sum / canc_n : std::nan("");
  return r;
}

TEST(DrillingSimulation, StartsAtHomeAndReachesTheDrillingPoseThroughTrajectories) {
  DrillingSimulation sim(workcell(), unwatched(), 1);
  sim.reset(1, false);
  // Home: tool above and behind the bone, well clear of it.
  EXPECT_LT(sim.groundTruth().tip_depth_m, -0.1);
  EXPECT_EQ(sim.groundTruth().layer, Material::kAir);
  moveToDrillingPose(&sim, 1.0);
  const Eigen::Isometry3d tip = sim.tipPose();
  // config/drilling_pose.yaml: 5 mm above the bone top centre, axis down.
  EXPECT_NEAR(sim.groundTruth().tip_depth_m, -5e-3, 0.1e-3);
  EXPECT_NEAR(tip.translation().x(), 0.6, 0.2e-3);
  EXPECT_NEAR(tip.translation().y(), 0.0, 0.2e-3);
  EXPECT_LT(tip.linear().col(2).z(), -0.9999);
}

TEST(DrillingSimulation, StationaryDrillingShowsTwoCorticalPeaksAndGroundTruthDepth) {
  for (std::uint64_t seed : {1u, 7u, 12u}) {
    SCOPED_TRACE(seed);
    DrillingSimulation sim(workcell(), unwatched(), seed);
    sim.reset(seed, false);
    const double feed = 16e-3;
    const TrialRecord r = drillStationary(&sim, feed);
    std::cout << "[ trial ] seed " << seed << ": outer peak " << r.outer_peak << " N, inner peak "
              << r.inner_peak << " N, cancellous " << r.cancellous_mean << " N, max deflection "
              << r.max_deflection * 1e3 << " mm" << std::endl;
    // Paper Fig. 16 stationary medians 3.16 / 2.88 N (calibration.md ranges).
    EXPECT_GE(r.outer_peak, 2.5);
    EXPECT_LE(r.outer_peak, 4.0);
    EXPECT_GE(r.inner_peak, 2.2);
    EXPECT_LE(r.inner_peak, 3.8);
    EXPECT_LT(r.cancellous_mean, 0.6 * std::min(r.outer_peak, r.inner_peak));
    // In the air gap before contact: only sensor noise.
    EXPECT_LT(std::abs(r.block_mean.front()), 0.1);
    // Ground truth: the tip went through (16 mm feed, 5 mm gap, ~8 mm of bone).
    const SimulationGroundTruth gt = sim.groundTruth();
    EXPECT_TRUE(gt.breakthrough);
    EXPECT_EQ(gt.layer, Material::kCanal);
    EXPECT_NEAR(gt.max_depth_cut_m, feed - r.gap, 0.05e-3);
    EXPECT_NEAR(gt.tip_depth_m, feed - r.gap, 0.05e-3);
    EXPECT_DOUBLE_EQ(gt.residual_inner_cortical_m, 0.0);
    // Finite arm stiffness: thrust pushes the tip back (0.12 mm at 3 N, bullet_arm.hpp).
    EXPECT_GT(r.max_deflection, 0.04e-3);
    EXPECT_LT(r.max_deflection, 0.3e-3);
  }
}

TEST(DrillingSimulation, GroundTruthStopsInsideTheInnerCortex) {
  DrillingSimulation sim(workcell(), unwatched(), 5);
  sim.reset(5, false);
  sim.commandSpindle(12000.0);
  moveToDrillingPose(&sim, 1.0);
  const double gap = -sim.groundTruth().tip_depth_m;
  const auto& sp = sim.process().specimen();
  const double target = sp.innerCorticalStart() + 0.5 * sp.innerCorticalThickness();
  TrajectoryCommand feed;
  feed.joint_names = {"feed_joint"};
  feed.points.push_back({sim.time() + (target + gap) / 0.5e-3, {target + gap}, {}});
  ASSERT_TRUE(sim.commandTrajectory(feed).ok());
  sim.step((target + gap) / 0.5e-3 + 0.5);
  const SimulationGroundTruth gt = sim.groundTruth();
  EXPECT_EQ(gt.layer, Material::kInnerCortical);
  EXPECT_FALSE(gt.breakthrough);
  // Deflection under the cutting thrust keeps the cut slightly short of the commanded depth.
  EXPECT_LT(gt.max_depth_cut_m, target);
  EXPECT_GT(gt.max_depth_cut_m, target - 0.3e-3);
  EXPECT_NEAR(gt.residual_inner_cortical_m, sp.innerCorticalEnd() - gt.max_depth_cut_m, 1e-12);
  // A new trial on a drilled specimen: the bench mounts a fresh one (the next seed), arm home.
  const int trials = sim.trialCount();
  EXPECT_TRUE(sim.startTrial());
  EXPECT_EQ(sim.trialCount(), trials + 1);
  EXPECT_EQ(sim.seed(), 6u);
  EXPECT_DOUBLE_EQ(sim.groundTruth().max_depth_cut_m, 0.0);
  EXPECT_LT(sim.groundTruth().tip_depth_m, -0.1);
  EXPECT_FALSE(sim.groundTruth().breakthrough);
  EXPECT_FALSE(sim.startTrial());  // not drilled yet: the same specimen
  EXPECT_EQ(sim.seed(), 6u);
  // The reset between trials returns the arm home and clears the drilling state.
  sim.reset(6, false);
  EXPECT_DOUBLE_EQ(sim.groundTruth().max_depth_cut_m, 0.0);
  EXPECT_LT(sim.groundTruth().tip_depth_m, -0.1);
  EXPECT_EQ(sim.seed(), 6u);
}

// The tracker samples once per period, at a phase drawn from the trial's seed: different
// seeds put the 8 Hz samples at different points of the breath (both grids start at 0).
TEST(DrillingSimulation, TrackerSamplesOncePerPeriodAtAPhaseDrawnFromTheSeed) {
  std::set<int> phases;
  for (std::uint64_t seed : {1u, 2u, 3u, 4u, 5u, 6u}) {
    DrillingSimulation sim(workcell(), unwatched(), seed);
    sim.reset(seed, false);
    std::vector<int> due;
    for (int k = 1; k <= 250; ++k) {
      sim.stepOnce();
      if (sim.trackerDue(125)) due.push_back(k);
    }
    ASSERT_EQ(due.size(), 2u) << "seed " << seed;
    EXPECT_EQ(due[1] - due[0], 125);
    phases.insert(due[0]);
    // The same seed, the same phase.
    DrillingSimulation again(workcell(), unwatched(), seed);
    again.reset(seed, false);
    int first = 0;
    for (int k = 1; first == 0 && k <= 125; ++k) {
      again.stepOnce();
      if (again.trackerDue(125)) first = k;
    }
    EXPECT_EQ(first, due[0]);
  }
  EXPECT_GE(phases.size(), 5u);  // six seeds, 125 possible phases
}

// Registration error: the declared magnitudes, a direction per seed, none by default.
TEST(DrillingSimulation, TheRegistrationErrorHasItsMagnitudeAndADirectionPerSeed) {
  const Eigen::Isometry3d none = registrationError(7, 0.0, 0.0);
  EXPECT_TRUE(none.matrix() == Eigen::Matrix4d::Identity());
  std::set<long> directions;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const Eigen::Isometry3d e = registrationError(seed, 1.5, 0.1);
    EXPECT_NEAR(e.translation().norm(), 1.5e-3, 1e-12);
    EXPECT_NEAR(Eigen::AngleAxisd(e.linear()).angle(), 0.1 * M_PI / 180.0, 1e-12);
    directions.insert(std::lround(1e4 * e.translation().x()));
  }
  EXPECT_GE(directions.size(), 15u);
}

TEST(DrillingSimulation, TheTrackerMeasuresInTheTrueCameraFrame) {
  DrillingSimulationParams exact;
  exact.tracker_noise_rms_mm = 0.0;
  DrillingSimulationParams off = exact;
  off.registration_error_mm = 2.0;
  DrillingSimulation a(workcell(), exact, 3), b(workcell(), off, 3);
  a.reset(3, false);
  b.reset(3, false);
  const Eigen::Isometry3d ma = a.measureMarkerPose(), mb = b.measureMarkerPose();
  // A pure translation of the camera by 2 mm moves every measurement by 2 mm.
  EXPECT_NEAR((ma.translation() - mb.translation()).norm(), 2e-3, 1e-9);
  EXPECT_TRUE(ma.linear().isApprox(mb.linear(), 1e-12));
  // The same trial's error whatever the step: the camera does not move.
  for (int k = 0; k < 500; ++k) b.stepOnce();
  for (int k = 0; k < 500; ++k) a.stepOnce();
  EXPECT_NEAR((a.measureMarkerPose().translation() - b.measureMarkerPose().translation()).norm(),
              2e-3, 1e-9);
}

// The breath phase as a bench senses it: exact by default; with a 64 Hz flow sensor
// each breath start is seen at the sensor's first sample of the breath (16 ms grid, the square
// waveform's flow jumps at the start), until then the previous breath's start holds; a clock
// offset shifts every sensed start.
TEST(DrillingSimulation, TheSensedBreathPhaseIsExactByDefault) {
  DrillingSimulation sim(workcell(), unwatched(), 1);
  for (int k = 0; k < 12000; ++k) {
    sim.stepOnce();
    ASSERT_EQ(sim.sensedTimeInBreath(),
              std::max(0.0, sim.ventilatorSample().t - sim.ventilator().breathStart()));
  }
}

namespace {
// Steps 24.5 s (five breaths at 12/min) and returns sensed - exact time in breath per step.
std::vector<double> sensedMinusExact(double rate_hz, double offset_s, std::vector<double>* exact,
                                     double latency_s = 0.0) {
  DrillingSimulationParams p = unwatched();
  p.breath_sensor_rate_hz = rate_hz;
  p.breath_clock_offset_s = offset_s;
  p.breath_sensor_latency_s = latency_s;
  DrillingSimulation sim(workcell(), p, 1);
  std::vector<double> diff;
  for (int k = 0; k < 24500; ++k) {
    sim.stepOnce();
    const double e = sim.ventilatorSample().t - sim.ventilator().breathStart();
    exact->push_back(e);
    diff.push_back(sim.sensedTimeInBreath() - e);
  }
  return diff;
}
}  // namespace

TEST(DrillingSimulation, AFlowSensorSeesEachBreathStartAtItsNextSample) {
  std::vector<double> exact;
  const std::vector<double> diff = sensedMinusExact(64.0, 0.0, &exact);
  int detections = 0, late_steps = 0;
  for (size_t k = 1000; k < diff.size(); ++k) {
    if (exact[k] < exact[k - 1]) {  // a new breath starts at this step
      // Until the sensor's next sample the previous breath's start holds.
      size_t j = k;
      while (j < diff.size() && diff[j] > 1.0) {
        ++late_steps;
        ++j;
      }
      ASSERT_LT(j, diff.size());
      EXPECT_LT(j - k, 16u) << "detected within one 16 ms sensor period";
      EXPECT_EQ((j + 1) % 16, 0u) << "on the sensor's grid (step index " << j + 1 << ")";
      // Detected: behind the exact phase by the detection delay, never ahead of it.
      EXPECT_NEAR(diff[j], -1e-3 * static_cast<double>(j - k), 1e-9);
      ++detections;
    }
  }
  EXPECT_EQ(detections, 4);  // breaths 2-5 start after the first second
  EXPECT_GT(late_steps, 0);  // the grid's phase differs from breath to breath
}

TEST(DrillingSimulation, TheBreathSensorsClockOffsetAndLatencyShiftTheSensedStart) {
  std::vector<double> exact, exact2, exact3;
  const std::vector<double> base = sensedMinusExact(64.0, 0.0, &exact);
  const std::vector<double> shifted = sensedMinusExact(64.0, -0.002, &exact2);
  const std::vector<double> late = sensedMinusExact(64.0, 0.0, &exact3, 0.03);
  int compared = 0;
  for (size_t k = 1000; k < base.size(); ++k) {
    // Before a detection has arrived the previous breath's start holds (the difference is a
    // breath period, 5 s): compared only where each run has the current breath's start.
    if (std::abs(base[k]) > 0.1 || std::abs(late[k]) > 0.1 || exact[k] < 0.05) continue;
    EXPECT_NEAR(shifted[k] - base[k], 0.002, 1e-9) << k;
    EXPECT_NEAR(late[k] - base[k], -0.03, 1e-9) << k;
    ++compared;
  }
  EXPECT_GT(compared, 20000);  // of 23500 steps
}

TEST(DrillingSimulation, BreathSensorParametersAreValidated) {
  DrillingSimulationParams p = unwatched();
  p.breath_sensor_rate_hz = -1.0;
  EXPECT_THROW(p.validate(), std::invalid_argument);
  p = unwatched();
  p.breath_clock_offset_s = 0.5;
  try {
    p.validate();
    FAIL() << "an offset of 0.5 s was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("breath_clock_offset_s"), std::string::npos) << e.what();
  }
}

// arm_rate_in_air_hz: the arm runs 4 ms blocks only out of contact and more than the clearance
// above the bone; every step in contact or nearer runs at the arm rate. The drilling through both
// cortices sees the same forces as at one rate throughout, to the sensor's floor.
TEST(DrillingSimulation, TheArmRunsAtItsAirRateOnlyClearOfTheBone) {
  DrillingSimulationParams air = unwatched();
  air.arm_rate_hz = 1000.0;
  air.arm_rate_in_air_hz = 250.0;  // the shipped clearance (unwatched() keeps the defaults)
  DrillingSimulationParams one = air;
  one.arm_rate_in_air_hz = 1000.0;
  DrillingSimulation sim_air(workcell(), air, 7), sim_one(workcell(), one, 7);
  sim_air.reset(7, false);
  sim_one.reset(7, false);
  std::uint64_t near_steps = 0;
  std::uint64_t long_blocks_near = 0;
  std::vector<double> rpm_air, rpm_one;  // the spindle driver's speed at every step
  const auto watch = [&](DrillingSimulation* sim) {
    TrialRecord r;
    std::vector<double>& rpm = sim == &sim_air ? rpm_air : rpm_one;
    moveToDrillingPose(sim, 1.0);
    sim->commandSpindle(12000.0);  // its run-up in air, 5 mm above the bone
    r.gap = -sim->groundTruth().tip_depth_m;
    const double t0 = sim->time();
    TrajectoryCommand feed;
    feed.joint_names = {"feed_joint"};
    feed.points.push_back({t0 + 12e-3 / 0.5e-3, {12e-3}, {}});
    EXPECT_TRUE(sim->commandTrajectory(feed).ok());
    double sum = 0.0;
    int n = 0;
    for (int i = 0; i < 25000; ++i) {
      const SimulationStep s = sim->stepOnce();
      rpm.push_back(sim->spindleRpm());
      if (sim == &sim_air && (s.force.contact || s.tip_depth_m > -air.arm_air_clearance_m)) {
        ++near_steps;
        if (sim->armBlockSteps() != 1) ++long_blocks_near;
      }
      if (!s.force_sampled) continue;
      sum += s.measured_wrench[2];
      if (++n == 50) {
        r.block_mean.push_back(sum / n);
        sum = 0.0;
        n = 0;
      }
    }
    return r;
  };
  const TrialRecord a = watch(&sim_air);
  const TrialRecord b = watch(&sim_one);
  EXPECT_GT(near_steps, 10000u);  // the contact phase was watched
  // The spindle's run-up at the physics rate whatever the arm's block (the sensor's
  // spindle-synchronous vibration integrates its phase from it, step by step).
  EXPECT_EQ(rpm_air, rpm_one);
  EXPECT_EQ(long_blocks_near, 0u);
  // Home to the drilling pose and the 5 mm of air: most of those blocks ran at the air rate.
  EXPECT_GT(sim_air.armBlocksInAir(), 2000u);
  EXPECT_EQ(sim_one.armBlocksInAir(), 0u);
  ASSERT_EQ(a.block_mean.size(), b.block_mean.size());
  double worst = 0.0;
  for (std::size_t k = 0; k < a.block_mean.size(); ++k) {
    worst = std::max(worst, std::abs(a.block_mean[k] - b.block_mean[k]));
  }
  std::cout << "[ air rate ] " << sim_air.armBlocksInAir()
            << " blocks in air; worst averaged force " << worst * 1e3 << " mN from one rate"
            << std::endl;
  EXPECT_LT(worst, 0.02);  // the sensor's floor: a few mN (doc/benchmarks.md)
  // Validated: a rate that does not divide the physics rate, or above 1 kHz, names itself.
  for (double bad : {300.0, 2000.0}) {
    DrillingSimulationParams p = unwatched();
    p.arm_rate_in_air_hz = bad;
    try {
      p.validate();
      ADD_FAILURE() << bad << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("arm_rate_in_air_hz"), std::string::npos) << e.what();
    }
  }
  // An arm slower than the air rate runs at its own rate in air as well.
  DrillingSimulationParams slow = unwatched();
  slow.arm_rate_hz = 100.0;
  slow.arm_rate_in_air_hz = 250.0;
  DrillingSimulation sim_slow(workcell(), slow, 7);
  sim_slow.reset(7, false);
  for (int i = 0; i < 100; ++i) sim_slow.stepOnce();
  EXPECT_EQ(sim_slow.armBlockSteps(), 10);
  EXPECT_EQ(sim_slow.armBlocksInAir(), 0u);
}

// A separation is a gap of at least 10 ms without cutting after a cut: drill 1 mm into a
// stationary specimen, then pull the drill back 0.5 mm. (Re-engaging a drilled hole, the
// compliant arm makes the lips chatter, which counts as well: the count is of interruptions of
// cutting, whatever their cause.)
TEST(DrillingSimulation, CountsEachSeparationOfDrillAndBoneOnce) {
  DrillingSimulation sim(workcell(), unwatched(), 5);
  sim.reset(5, false);
  sim.commandSpindle(12000.0);
  moveToDrillingPose(&sim, 1.0);
  const double gap = -sim.groundTruth().tip_depth_m;
  const double in = gap + 1e-3;
  TrajectoryCommand feed;
  feed.joint_names = {"feed_joint"};
  const double t0 = sim.time();
  feed.points.push_back({t0 + in / 0.5e-3, {in}, {}});
  ASSERT_TRUE(sim.commandTrajectory(feed).ok());
  sim.step(in / 0.5e-3 + 0.2);
  EXPECT_TRUE(sim.groundTruth().contact);
  EXPECT_EQ(sim.groundTruth().contact_loss_count, 0u);  // steady cutting: no separation
  // Back 0.5 mm in 0.1 s, hold 0.1 s, forward again at the feed rate.
  TrajectoryCommand back;
  back.joint_names = {"feed_joint"};
  const double t1 = sim.time();
  back.points.push_back({t1 + 0.1, {in - 0.5e-3}, {}});
  back.points.push_back({t1 + 0.2, {in - 0.5e-3}, {}});
  back.points.push_back({t1 + 0.2 + 1.5e-3 / 0.5e-3, {in + 1e-3}, {}});
  ASSERT_TRUE(sim.commandTrajectory(back).ok());
  sim.step(0.15);
  EXPECT_FALSE(sim.groundTruth().contact);
  EXPECT_EQ(sim.groundTruth().contact_loss_count, 1u);
  sim.step(0.05);  // still off the bone: the same gap, counted once
  EXPECT_FALSE(sim.groundTruth().contact);
  EXPECT_EQ(sim.groundTruth().contact_loss_count, 1u);
  // A new trial starts the count afresh.
  sim.startTrial();
  EXPECT_EQ(sim.groundTruth().contact_loss_count, 0u);
}

// The contact after the stop: a drill that does not turn, lowered so that the
// breathing bone's next approach presses into it. The elastic contact passes the bone's push
// through the drill and the arm to the force sensor, and the safety monitor's H2 (10 N) trips;
// nothing is cut. The rigid contact let the bone pass through the stopped drill without force.
struct PressResult {
  bool tripped = false;
  SafetyVerdict::Reason reason = SafetyVerdict::kNone;
  double max_thrust = 0.0;
  double max_depth_cut = -1.0;
  double overlap_at_trip = 0.0;
  double thrust_at_trip = 0.0;
};

PressResult pressStoppedDrill(double contact_stiffness) {
  DrillingSimulationParams params = unwatched();
  params.drill.contact_stiffness_n_per_m = contact_stiffness;
  DrillingSimulation sim(workcell(), params, 4);
  sim.reset(4, true);  // breathing bone, no compensation
  moveToDrillingPose(&sim, 1.0);
  double closest = -1.0;  // deepest tip depth over one breath: the bone's closest approach
  for (int i = 0; i < 5000; ++i) closest = std::max(closest, sim.stepOnce().tip_depth_m);
  EXPECT_LT(closest, 0.0);  // parked clear of the bone
  TrajectoryCommand lower;
  lower.joint_names = {"feed_joint"};
  lower.points.push_back({sim.time() + 0.5, {-closest + 1e-3}, {}});
  EXPECT_TRUE(sim.commandTrajectory(lower).ok());
  SafetyParams sp;
  sp.tracker_timeout_s = std::numeric_limits<double>::infinity();
  SafetyMonitor monitor(sp);
  PressResult r;
  for (int i = 0; i < 6000 && !r.tripped; ++i) {  // beyond the next breath
    const SimulationStep s = sim.stepOnce();
    EXPECT_EQ(sim.spindleRpm(), 0.0);
    r.max_thrust = std::max(r.max_thrust, s.force.thrust_N);
    if (s.force_sampled) monitor.onForce(s.time_s, s.measured_wrench.head<3>());
    r.tripped = monitor.check(s.time_s).stop;
    r.overlap_at_trip = s.force.overlap_m;
    r.thrust_at_trip = s.force.thrust_N;
  }
  r.reason = monitor.verdict().reason;
  r.max_depth_cut = sim.groundTruth().max_depth_cut_m;
  return r;
}

TEST(DrillingSimulation, BoneDrivenIntoAStoppedDrillTripsH2) {
  const double k = unwatched().drill.contact_stiffness_n_per_m;
  ASSERT_TRUE(std::isfinite(k));  // the simulator's default contact is elastic
  const PressResult elastic = pressStoppedDrill(k);
  std::cout << "[ press ] elastic: max thrust " << elastic.max_thrust << " N, overlap at trip "
            << elastic.overlap_at_trip * 1e6 << " um" << std::endl;
  EXPECT_TRUE(elastic.tripped);
  EXPECT_EQ(elastic.reason, SafetyVerdict::kForceExceeded);
  EXPECT_EQ(elastic.max_depth_cut, 0.0);  // a stopped drill cuts nothing
  // The force builds through the arm's compliance (about 2.5e4 N/m along the axis) in steps
  // the 1 kHz physics resolves: the monitor stops it just above H2, and the thrust then is the
  // contact spring's (about 10 um of overlap). The contact chatters as it builds, so the peak
  // may come a sample before the trip.
  EXPECT_GT(elastic.max_thrust, 10.0);
  EXPECT_LT(elastic.max_thrust, 11.0);
  EXPECT_GT(elastic.thrust_at_trip, 9.5);
  EXPECT_NEAR(elastic.overlap_at_trip * k, elastic.thrust_at_trip, 1e-9 * k);
  const PressResult rigid = pressStoppedDrill(std::numeric_limits<double>::infinity());
  EXPECT_FALSE(rigid.tripped);
  EXPECT_EQ(rigid.max_thrust, 0.0);
}

TEST(DrillingSimulation, HigherSpindleSpeedLowersTheForce) {
  double peak[2] = {0, 0};
  const double rpm[2] = {12000.0, 20000.0};
  for (int k = 0; k < 2; ++k) {
    DrillingSimulation sim(workcell(), unwatched(), 3);
    sim.reset(3, false);
    sim.commandSpindle(rpm[k]);
    moveToDrillingPose(&sim, 1.0);
    TrajectoryCommand feed;
    feed.joint_names = {"feed_joint"};
    feed.points.push_back({sim.time() + 16.0, {8e-3}, {}});
    ASSERT_TRUE(sim.commandTrajectory(feed).ok());
    for (int i = 0; i < 16000; ++i) peak[k] = std::max(peak[k], sim.stepOnce().force.thrust_N);
  }
  // At the same feed rate the law's ratio: f_rev falls as 1/n, and (n/n_ref)^-beta (0.87 with
  // the chisel-edge share, 0.74 without).
  DrillingProcess law(BoneSpecimen::uniform(2e-3, 4e-3, 2e-3, 0.9, 0.25, 0.8));
  const double f_ref = law.parameters().ref_feed_per_rev_m;
  const double ratio = law.steadyThrust(0.9, f_ref * 12000.0 / 20000.0, 20000.0) /
                       law.steadyThrust(0.9, f_ref, 12000.0);
  EXPECT_NEAR(peak[1] / peak[0], ratio, 0.03);
}

// The paper's bench: the SPMS controller streams the model's displacement to the sliders'
// trajectory, and the sliders' lead-screw drives follow it within their limits (2 m/s^2): on
// the model away from the ventilator's flow steps, rounded at them, never beyond the limits.
TEST(DrillingSimulation, OnThePapersBenchTheSpmsPlaysTheModelThroughItsDrives) {
  DrillingSimulationParams params = unwatched();
  DrillingSimulation sim(workcell(), params, 3);
  sim.setBoneMotionModel(BoneMotionModel{0.01, 0.0});
  sim.reset(3, true);
  sim.step(1.0);
  Eigen::Vector3d s_prev = sim.sliderPositions();
  sim.stepOnce();
  Eigen::Vector3d s_now = sim.sliderPositions();
  double max_accel = 0.0, max_err = 0.0, zmin = 1e9, zmax = -1e9;
  std::vector<double> errors;
  for (int i = 0; i < 10000; ++i) {
    sim.stepOnce();
    const Eigen::Vector3d s_next = sim.sliderPositions();
    max_accel = std::max(max_accel, ((s_next - 2.0 * s_now + s_prev) / 1e-6).cwiseAbs().maxCoeff());
    s_prev = s_now;
    s_now = s_next;
    const double err = std::abs(sim.platformPose().z_m - sim.desiredHeave());
    errors.push_back(err);
    max_err = std::max(max_err, err);
    zmin = std::min(zmin, sim.platformPose().z_m);
    zmax = std::max(zmax, sim.platformPose().z_m);
  }
  std::sort(errors.begin(), errors.end());
  std::cout << "[ bench ] max slider acceleration " << max_accel << " m/s^2, platform error "
            << "median " << errors[errors.size() / 2] * 1e6 << " um, 99 % "
            << errors[errors.size() * 99 / 100] * 1e6 << " um, max " << max_err * 1e6 << " um"
            << std::endl;
  EXPECT_LE(max_accel, params.slider_max_accel_m_s2 * (1.0 + 1e-6));
  EXPECT_GT(max_accel, 0.5 * params.slider_max_accel_m_s2);  // the flow steps ask for more
  EXPECT_LT(errors[errors.size() / 2], 1e-6);                // on the model between the steps
  EXPECT_LT(max_err, 40e-6);                                 // rounded at the steps
  EXPECT_NEAR(zmax - zmin, 0.01 * 500.0 * 1e-3, 0.1e-3);     // 5 mm peak to peak at 500 ml
}

// The drill device's feed is a lead-screw drive too: a reversal the trajectory asks for in
// 1 ms takes the drive's acceleration limit (2 m/s^2: 5 mm/s -> -5 mm/s in 5 ms).
TEST(DrillingSimulation, TheFeedDriveReversesWithinItsAccelerationLimit) {
  DrillingSimulationParams params = unwatched();
  params.arm_rate_in_air_hz = params.arm_rate_hz;  // the drive at every step (this is in air)
  DrillingSimulation sim(workcell(), params, 1);
  sim.step(0.2);
  const double f0 = sim.armJointPositions()[6];
  const double t0 = sim.time();
  TrajectoryCommand c;
  c.joint_names = {"feed_joint"};
  c.points.push_back({t0 + 0.01, {f0 + 0.05e-3}, {5e-3}});
  c.points.push_back({t0 + 0.2, {f0 + 1.0e-3}, {5e-3}});
  c.points.push_back({t0 + 0.201, {f0 + 1.0e-3}, {-5e-3}});
  c.points.push_back({t0 + 0.4, {f0 + 0.005e-3}, {-5e-3}});
  ASSERT_TRUE(sim.commandTrajectory(c).ok());
  std::vector<double> f;
  while (sim.time() < t0 + 0.35) {
    sim.stepOnce();
    f.push_back(sim.armJointPositions()[6]);
  }
  double max_accel = 0.0;
  for (std::size_t i = 150; i + 1 < f.size(); ++i) {  // from the cruise on
    max_accel = std::max(max_accel, std::abs(f[i + 1] - 2.0 * f[i] + f[i - 1]) / 1e-6);
  }
  // The joint's velocity goes from +5 to -5 mm/s: count the steps it takes.
  int turning = 0;
  for (std::size_t i = 150; i + 1 < f.size(); ++i) {
    const double v = (f[i + 1] - f[i]) / 1e-3;
    turning += (v < 4.5e-3 && v > -4.5e-3) ? 1 : 0;
  }
  std::cout << "[ feed ] max acceleration " << max_accel << " m/s^2, " << turning
            << " ms to reverse" << std::endl;
  EXPECT_GE(turning, 4);
  EXPECT_LE(max_accel, 1.5 * params.feed_max_accel_m_s2);  // the arm's servo adds a little
}

TEST(DrillingSimulation, MovingPlatformFollowsTheRateLimitedSliders) {
  DrillingSimulationParams params = unwatched();
  DrillingSimulation sim(workcell(), params, 2);
  sim.reset(2, true);
  const SpmsKinematics spms(params.spms);
  const double home_top = sim.boneTopZ() - sim.platformPose().z_m;
  double zmin = 1e9, zmax = -1e9;
  Eigen::Vector3d prev = sim.sliderPositions();
  for (int i = 0; i < 15000; ++i) {
    sim.stepOnce();
    const Eigen::Vector3d s = sim.sliderPositions();
    // Sliders never jump (lead-screw speed limit), the platform is the FK of the sliders.
    EXPECT_LE((s - prev).cwiseAbs().maxCoeff(), params.slider_max_speed_m_s * 1e-3 + 1e-12);
    prev = s;
    const SpmsFkResult fk = spms.forward(s);
    ASSERT_TRUE(fk.ok);
    EXPECT_NEAR(sim.platformPose().z_m, fk.pose.z_m, 1e-9);
    EXPECT_NEAR(sim.boneTopZ(), home_top + fk.pose.z_m, 1e-9);
    // Breathing is slow: the platform tracks the patient's displacement.
    // (after the first 20 ms: the drift offset at t = 0 is a step for the sliders).
    if (i > 20) {
      EXPECT_NEAR(sim.platformPose().z_m, sim.desiredHeave(), 0.05e-3);
    }
    zmin = std::min(zmin, sim.platformPose().z_m);
    zmax = std::max(zmax, sim.platformPose().z_m);
  }
  // AP peak to peak = q1 * 500 ml (4.2-5.4 mm for the virtual volunteers) +- drift.
  const double expected = sim.patient().q1_ap_mm_per_ml * 500.0 * 1e-3;
  EXPECT_NEAR(zmax - zmin, expected, 2.0 * sim.patient().drift_mm * 1e-3 + 0.1e-3);
  EXPECT_GT(zmax - zmin, 3.5e-3);
  // Ground truth reports the same AP displacement.
  EXPECT_NEAR(sim.groundTruth().bone_displacement_m.z(), sim.platformPose().z_m, 1e-9);

  // A slow lead screw cannot follow: the platform lags, it is never teleported.
  params.slider_max_speed_m_s = 1e-3;
  DrillingSimulation slow(workcell(), params, 2);
  double max_lag = 0.0;
  for (int i = 0; i < 5000; ++i) {
    const double z0 = slow.platformPose().z_m;
    slow.stepOnce();
    EXPECT_LE(std::abs(slow.platformPose().z_m - z0), 1e-6 + 1e-12);
    max_lag = std::max(max_lag, std::abs(slow.desiredHeave() - slow.platformPose().z_m));
  }
  EXPECT_GT(max_lag, 0.5e-3);

  // moving_bone = false: the platform returns to home and stays.
  sim.reset(2, false);
  sim.step(1.0);
  for (int i = 0; i < 2000; ++i) {
    sim.stepOnce();
    EXPECT_NEAR(sim.platformPose().z_m, 0.0, 1e-12);
  }
}

// The sensor frame's z is the drill axis towards the bone, and the sensor reports the bone's
// resistance positive: the thrust on Fz and the cutting torque on Tz, both positive, with the
// ratio of the law; no torque about x or y beyond the sensor's noise.
TEST(DrillingSimulation, TheSensorSeesTheCuttingTorqueOnItsZAxisWithTheThrustsSign) {
  constexpr double kRpm = 12000.0;  // the paper's speed
  constexpr double kFeed = 0.5e-3;  // 0.5 mm/s
  DrillingSimulationParams params;
  params.spindle_watchdog_s = 0.0;  // the spindle is commanded once
  DrillingSimulation sim(workcell(), params, 2);
  sim.reset(2, false);
  sim.commandSpindle(kRpm);
  TrajectoryCommand pose;
  pose.joint_names = {"rsssii_joint1", "rsssii_joint2", "rsssii_joint3", "rsssii_joint4",
                      "rsssii_joint5", "rsssii_joint6", "feed_joint"};
  pose.points.push_back({sim.time() + 1.0, {0.0, 0.435859, 1.319709, 0.0, 1.386025, 0.0, 0.0}, {}});
  ASSERT_TRUE(sim.commandTrajectory(pose).ok());
  sim.step(1.5);
  // 5 mm of air, then 2.5 mm into the outer cortex.
  TrajectoryCommand feed;
  feed.joint_names = {"feed_joint"};
  feed.points.push_back({sim.time() + 7.5e-3 / kFeed, {7.5e-3}, {}});
  ASSERT_TRUE(sim.commandTrajectory(feed).ok());
  const double kappa_r = params.drill.torque_thrust_ratio * 0.5 * params.drill.bit_diameter_m;
  double fz = 0.0, tx = 0.0, ty = 0.0, tz = 0.0, air_tz = 0.0;
  int n = 0, air_n = 0;
  const int steps = static_cast<int>(7.5e-3 / kFeed / sim.physicsDt());
  for (int i = 0; i < steps; ++i) {
    const SimulationStep s = sim.stepOnce();
    EXPECT_DOUBLE_EQ(s.force.torque_Nm, sim.process().cuttingTorque(s.force.thrust_N, kRpm));
    if (!s.force_sampled) continue;
    if (s.force.thrust_N > 2.0) {  // in the cortex
      fz += s.measured_wrench[2];
      tx += s.measured_wrench[3];
      ty += s.measured_wrench[4];
      tz += s.measured_wrench[5];
      ++n;
    } else if (!s.force.contact) {
      air_tz += s.measured_wrench[5];
      ++air_n;
    }
  }
  ASSERT_GT(n, 100);
  ASSERT_GT(air_n, 100);
  fz /= n;
  tz /= n;
  RecordProperty("cortex_mean_fz_N", std::to_string(fz));
  RecordProperty("cortex_mean_tz_Nmm", std::to_string(tz * 1e3));
  RecordProperty("cortex_mean_tx_ty_Nmm",
                 std::to_string(tx / n * 1e3) + " " + std::to_string(ty / n * 1e3));
  RecordProperty("cortex_samples", std::to_string(n));
  EXPECT_GT(fz, 2.0);
  EXPECT_GT(tz, 0.0);  // the same sign as the thrust
  // Tz = kappa (D/2) Fz up to the sensor's bias drift since the tare (2e-5 N m / sqrt(s) over
  // about 17 s: 0.08 N mm SD; the noise's mean over the samples is a fifth of that): 0.4 N mm,
  // 5 SD, against a level of about 5.8 N mm (seed 2: 5.77 N mm at 2.92 N; Tx, Ty -0.03, -0.17).
  EXPECT_NEAR(tz, kappa_r * fz, 0.4e-3);
  EXPECT_LT(std::abs(tx / n), 0.4e-3);
  EXPECT_LT(std::abs(ty / n), 0.4e-3);
  EXPECT_LT(std::abs(air_tz / air_n), 0.4e-3);  // in the air: no torque
}

TEST(DrillingSimulation, APatientLateOnItsVentilatorTakesNewSettingsWithTheSameBreath) {
  // Volunteer 3 (seed 7) lags its ventilator: a request in the first lag_s of a breath found the
  // ventilator in the new breath and the patient still in the old one, and the patient took the
  // new rate a whole breath before the ventilator and its settings stream did.
  DrillingSimulation sim(workcell(), unwatched(), 7);
  ASSERT_GT(sim.patient().lag_s, 0.002);
  while (sim.ventilator().breathIndex() < 1) sim.stepOnce();
  ASSERT_EQ(sim.patientBreathing().breathIndex(), 0) << "the request must fall in the lag";
  const double old_period = sim.ventilator().model().period();
  VentilatorSettings slower = sim.ventilator().model().settings();
  slower.rate_bpm -= 4.0;
  sim.requestVentilatorSettings(slower);
  const double new_period = 60.0 / slower.rate_bpm;
  while (sim.patientBreathing().breathIndex() < 1) sim.stepOnce();
  EXPECT_NEAR(sim.patientBreathing().model().period(), old_period, 1e-12);
  while (sim.ventilator().breathIndex() < 2) sim.stepOnce();
  EXPECT_NEAR(sim.ventilator().model().period(), new_period, 1e-12);
  while (sim.patientBreathing().breathIndex() < 2) sim.stepOnce();
  EXPECT_NEAR(sim.patientBreathing().model().period(), new_period, 1e-12);
  // The same breath, each on its own clock: the patient lag_s behind, never a breath apart.
  EXPECT_NEAR(sim.patientBreathing().breathStart(), sim.ventilator().breathStart(), 1e-9);
}

TEST(DrillingSimulation, BonePlaysADisplacementModelOnThePaperBench) {
  // Volunteer 1 + 7 % 5 = 3 has a lag, drift and movements; a played model has none of them.
  DrillingSimulation sim(workcell(), unwatched(), 7);
  BoneMotionModel model;
  model.q1_ap_mm_per_ml = 0.009;
  model.q2_ap_mm_s_per_ml = -0.0006;
  sim.setBoneMotionModel(model);
  sim.reset(7, true);
  EXPECT_EQ(sim.patient().volunteer_id, 3);  // the other draws are unchanged
  EXPECT_EQ(sim.patient().lag_s, 0.0);
  EXPECT_EQ(sim.patient().drift_mm, 0.0);
  EXPECT_TRUE(sim.patient().movements.empty());
  sim.step(0.5);
  double worst = 0.0;
  for (int i = 0; i < 10000; ++i) {
    sim.stepOnce();
    BreathScheduler ventilator = sim.ventilator();  // a copy: sampling advances a scheduler
    const VentilatorSample v = ventilator.sample(sim.time());
    const double expected = 1e-3 * (0.009 * v.volume_ml - 0.0006 * v.flow_ml_s);
    worst = std::max(worst, std::abs(sim.desiredHeave() - expected));
  }
  EXPECT_LT(worst, 1e-9);
  // Back to the virtual patient at the next reset.
  sim.setBoneMotionModel(std::nullopt);
  sim.reset(7, true);
  EXPECT_GT(sim.patient().lag_s, 0.0);
  EXPECT_FALSE(sim.patient().movements.empty());
  model.q1_ap_mm_per_ml = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(sim.setBoneMotionModel(model), std::invalid_argument);
}

TEST(DrillingSimulation, TfTreeCoversEveryLinkAndMatchesLinkPoses) {
  DrillingSimulation sim(workcell(), unwatched(), 4);
  sim.reset(4, true);
  sim.step(1.3);
  std::map<std::string, std::pair<std::string, Eigen::Isometry3d>> parent;
  for (bool fixed : {true, false}) {
    for (const FrameTransform& f : sim.frameTransforms(fixed)) {
      ASSERT_TRUE(f.transform.matrix().allFinite()) << f.child;
      parent[f.child] = {f.parent, f.transform};
    }
  }
  for (const std::string l : {"rsssii_link3", "ft_sensor", "drill_tip", "spms_platform", "bone",
                              "tracker_marker", "tracker_camera", "slider2", "rod3"}) {
    ASSERT_TRUE(parent.count(l)) << l;
    // Compose up to world and compare with the simulation's own link pose.
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    std::string c = l;
    while (c != "world") {
      ASSERT_TRUE(parent.count(c)) << c;
      t = parent[c].second * t;
      c = parent[c].first;
    }
    // Bullet stores link poses in single precision.
    EXPECT_LT((t.matrix() - sim.linkPose(l).matrix()).norm(), 1e-6) << l;
  }
  EXPECT_NEAR(sim.linkPose("bone").translation().z(), sim.boneTopZ(), 1e-6);
  // Each rod end meets its spherical joint on the platform (closed chains consistent).
  for (int i = 1; i <= 3; ++i) {
    const Eigen::Vector3d rod_end =
        sim.linkPose("rod" + std::to_string(i)) * Eigen::Vector3d(0, 0, 0.12);
    const double th = (90.0 + 120.0 * (i - 1)) * M_PI / 180.0;
    const Eigen::Vector3d sph = sim.linkPose("spms_platform") *
                                Eigen::Vector3d(0.04 * std::cos(th), 0.04 * std::sin(th), 0);
    EXPECT_LT((rod_end - sph).norm(), 1e-6) << i;
  }
  // Tracker measurement: marker in the camera frame with ~0.25 mm RMS noise.
  const Eigen::Isometry3d truth =
      sim.linkPose("tracker_camera").inverse() * sim.linkPose("tracker_marker");
  double sq = 0.0;
  for (int k = 0; k < 2000; ++k) {
    sq += (sim.measureMarkerPose().translation() - truth.translation()).squaredNorm();
  }
  EXPECT_NEAR(std::sqrt(sq / 2000) * 1e3, 0.25, 0.02);
}

TEST(DrillingSimulation, CommandsAboveTheVelocityLimitAreFollowedAtTheLimit) {
  DrillingSimulation sim(workcell(), unwatched(), 1);
  sim.step(0.2);
  // 20 mm of feed in 0.1 s is 0.2 m/s, above the feed joint's 0.01 m/s URDF limit: reported as
  // clamped, naming the joint and the limit, and executed at the limit (the joint lags).
  const double feed_before = sim.armJointPositions()[6];
  TrajectoryCommand fast;
  fast.joint_names = {"feed_joint"};
  fast.points.push_back({sim.time() + 0.1, {feed_before + 0.02}, {}});
  const TargetResult too_fast = sim.commandTrajectory(fast);
  EXPECT_EQ(too_fast.status, TargetStatus::kClamped);
  EXPECT_NE(too_fast.message.find("feed_joint"), std::string::npos) << too_fast.message;
  EXPECT_NE(too_fast.message.find("velocity limit 0.01"), std::string::npos) << too_fast.message;
  sim.step(0.1);
  const double moved = sim.armJointPositions()[6] - feed_before;
  EXPECT_GT(moved, 0.0005);               // it moves ...
  EXPECT_LT(moved, 0.01 * 0.1 + 0.0002);  // ... at most at the limit, not 20 mm
  sim.step(2.5);                          // 20 mm at 10 mm/s: it arrives 2 s late
  EXPECT_NEAR(sim.armJointPositions()[6] - feed_before, 0.02, 0.2e-3);
  // Within the limit (5 mm/s): accepted as it is.
  fast.points.front() = {sim.time() + 4.0, {std::max(0.0, feed_before)}, {}};  // 0: the stop
  const TargetResult within = sim.commandTrajectory(fast);
  EXPECT_EQ(within.status, TargetStatus::kAccepted) << within.message;
}

TEST(DrillingSimulation, BadCommandsAreRejectedOrClampedNeverIntegrated) {
  DrillingSimulation sim(workcell(), unwatched(), 1);
  sim.step(0.2);
  Eigen::VectorXd q0 = sim.armJointPositions();
  TrajectoryCommand nan;
  nan.joint_names = kJoints;
  std::vector<double> p = kDrillingPose;
  p[1] = std::numeric_limits<double>::quiet_NaN();
  nan.points.push_back({sim.time() + 1.0, p, {}});
  EXPECT_EQ(sim.commandTrajectory(nan).status, TargetStatus::kRejected);
  TrajectoryCommand unknown;
  unknown.joint_names = {"rsssii_joint1", "elbow"};
  unknown.points.push_back({sim.time() + 1.0, {0.1, 0.2}, {}});
  const TargetResult r = sim.commandTrajectory(unknown);
  EXPECT_EQ(r.status, TargetStatus::kRejected);
  EXPECT_NE(r.message.find("elbow"), std::string::npos);
  TrajectoryCommand size;
  size.joint_names = {"feed_joint"};
  size.points.push_back({sim.time() + 1.0, {0.01, 0.02}, {}});
  EXPECT_EQ(sim.commandTrajectory(size).status, TargetStatus::kRejected);
  EXPECT_EQ(sim.commandSpindle(std::nan("")).status, TargetStatus::kRejected);
  EXPECT_EQ(sim.commandSpindle(-5.0).status, TargetStatus::kRejected);
  sim.step(1.5);
  EXPECT_LT((sim.armJointPositions() - q0).cwiseAbs().maxCoeff(), 1e-5);
  EXPECT_DOUBLE_EQ(sim.spindleRpm(), 0.0);

  // ros_control's rules (controller_rules strict, the default): a command whose points all lie
  // in the past is dropped, the arm keeps its trajectory (test_trajectory_executor has the rules).
  TrajectoryCommand past;
  past.joint_names = {"feed_joint"};
  past.points.push_back({sim.time() - 0.1, {0.01}, {}});
  TrajectoryCommand late_nan = past;
  late_nan.points[0].positions[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(sim.commandTrajectory(late_nan).status, TargetStatus::kRejected);
  const TargetResult late = sim.commandTrajectory(past);
  EXPECT_EQ(late.status, TargetStatus::kRejected);
  EXPECT_NE(late.message.find("feed_controller: dropping all 1 trajectory point(s)"),
            std::string::npos)
      << late.message;
  // Out of limit (feed travel 0..60 mm): refused, naming the joint; nothing is clamped.
  TrajectoryCommand far;
  far.joint_names = {"feed_joint"};
  far.points.push_back({sim.time() + 1.0, {0.5}, {}});
  const TargetResult c = sim.commandTrajectory(far);
  EXPECT_EQ(c.status, TargetStatus::kRejected);
  EXPECT_NE(c.message.find("joint 'feed_joint' position 0.5 outside its limits"), std::string::npos)
      << c.message;
  // A command for the arm controller must name its 6 joints (no partial goals by default).
  TrajectoryCommand partial;
  partial.joint_names = {"rsssii_joint1"};
  partial.points.push_back({sim.time() + 1.0, {0.1}, {}});
  EXPECT_EQ(sim.commandTrajectory(partial).status, TargetStatus::kRejected);
  EXPECT_EQ(sim.commandTrajectory("no_such_controller", far).status, TargetStatus::kRejected);
  EXPECT_EQ(sim.commandSpindle(1e6).status, TargetStatus::kClamped);  // the spindle's drive
  sim.step(1.2);
  EXPECT_LT((sim.armJointPositions() - q0).head(7).cwiseAbs().maxCoeff(), 1e-5);
  EXPECT_NEAR(sim.spindleRpm(), 21000.0, 1e-6);
  // The controllers' state: desired, actual and their difference, as ros_control publishes it.
  ASSERT_EQ(sim.controllers().size(), 2u);
  const ControllerStateSample state = sim.controllerState(1);
  ASSERT_EQ(state.joint_names, std::vector<std::string>{"feed_joint"});
  EXPECT_NEAR(state.actual_positions[0], q0[6], 1e-9);
  EXPECT_NEAR(state.error_positions[0], state.desired_positions[0] - state.actual_positions[0],
              1e-15);
  EXPECT_THROW(sim.controllerState(2), std::out_of_range);

  // The lenient rules (controller_rules lenient): a late command goes to its final point and an
  // out-of-limit position is clamped, both flagged.
  DrillingSimulationParams lenient_params;
  lenient_params.controller_rules.strict = false;
  DrillingSimulation lenient(workcell(), lenient_params, 1);
  lenient.step(0.5);
  const Eigen::VectorXd l0 = lenient.armJointPositions();
  past.points[0].time_s = lenient.time() - 0.1;
  const TargetResult went = lenient.commandTrajectory(past);
  EXPECT_EQ(went.status, TargetStatus::kClamped);
  EXPECT_NE(went.message.find("past"), std::string::npos);
  lenient.step(1.2);  // the feed joint goes to the late command's final point (10 mm, <= 10 mm/s)
  EXPECT_NEAR(lenient.armJointPositions()[6] - l0[6], 0.01, 1e-4);
  far.points[0].time_s = lenient.time() + 1.0;
  const TargetResult clamped = lenient.commandTrajectory(far);
  EXPECT_EQ(clamped.status, TargetStatus::kClamped);
  EXPECT_NE(clamped.message.find("feed_joint"), std::string::npos);
  lenient.step(5.5);  // 50 mm at the 10 mm/s limit
  EXPECT_NEAR(lenient.armJointPositions()[6], 0.06, 1e-4);
}

TEST(DrillingSimulation, AStalledDriveHoldsAndItsControllersErrorGrows) {
  DrillingSimulation sim(workcell(), unwatched(), 1);
  sim.step(0.2);
  EXPECT_THROW(sim.setJointStalled("spindle_joint", true), std::invalid_argument);
  sim.setJointStalled("feed_joint", true);
  const double feed0 = sim.armJointPositions()[6];
  TrajectoryCommand feed;
  feed.joint_names = {"feed_joint"};
  feed.points.push_back({sim.time() + 1.0, {feed0 + 0.005}, {}});
  ASSERT_TRUE(sim.commandTrajectory(feed).ok());
  sim.step(1.2);
  EXPECT_NEAR(sim.armJointPositions()[6], feed0, 1e-6);  // it holds
  const ControllerStateSample stalled = sim.controllerState(1);
  EXPECT_NEAR(stalled.error_positions[0], 0.005, 1e-6);  // desired - actual
  sim.setJointStalled("feed_joint", false);              // released: it follows again
  sim.step(1.5);
  EXPECT_NEAR(sim.armJointPositions()[6], feed0 + 0.005, 1e-4);
  // An arm joint: its setpoint freezes where it is.
  sim.setJointStalled("rsssii_joint1", true);
  const double q1 = sim.armJointPositions()[0];
  TrajectoryCommand arm;
  arm.joint_names = kJoints;
  const Eigen::VectorXd now_q = sim.armJointPositions();
  std::vector<double> target(now_q.data(), now_q.data() + 7);
  target[0] += 0.05;
  arm.points.push_back({sim.time() + 1.0, target, {}});
  ASSERT_TRUE(sim.commandTrajectory(arm).ok());
  sim.step(1.5);
  EXPECT_NEAR(sim.armJointPositions()[0], q1, 1e-4);
  EXPECT_NEAR(sim.controllerState(0).error_positions[0], 0.05, 1e-3);
}

TEST(DrillingSimulation, TheControllersReadStampsOnTheirOwnClock) {
  // The controllers' clock 0.3 s ahead of the pipeline's: a segment stamped to end 0.25 s from
  // now has ended on their clock, and the strict controller drops it.
  DrillingSimulationParams ahead;
  ahead.arm_clock_offset_s = 0.3;
  DrillingSimulation sim(workcell(), ahead, 1);
  sim.step(0.2);
  TrajectoryCommand feed;
  feed.joint_names = {"feed_joint"};
  feed.start_time_s = sim.time();
  feed.points.push_back({sim.time() + 0.25, {0.001}, {}});
  const TargetResult r = sim.commandTrajectory(feed);
  EXPECT_EQ(r.status, TargetStatus::kRejected);
  EXPECT_NE(r.message.find("dropping all 1 trajectory point(s)"), std::string::npos) << r.message;
  // 0.1 s behind: the same command takes over 0.1 s after its stamp and ends 0.1 s later.
  DrillingSimulationParams behind;
  behind.arm_clock_offset_s = -0.1;
  DrillingSimulation late(workcell(), behind, 1);
  late.step(0.2);
  const double t0 = late.time();
  feed.start_time_s = t0 + 0.1;
  feed.points = {{t0 + 0.6, {0.002}, {}}};
  ASSERT_TRUE(late.commandTrajectory(feed).ok());
  late.step(0.15);  // t0 + 0.15: still before the takeover on the pipeline's clock + 0.1 s
  EXPECT_NEAR(late.controllerState(1).desired_positions[0], 0.0, 1e-12);
  late.step(0.55);  // t0 + 0.7: the command's end on the controllers' clock
  EXPECT_NEAR(late.controllerState(1).desired_positions[0], 0.002, 1e-9);
  DrillingSimulationParams bad;
  bad.arm_clock_drift_ppm = 5000.0;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

TEST(DrillingSimulation, NewTrajectoryReplacesTheRemainingOneAndCubicPointsAreFollowed) {
  DrillingSimulation sim(workcell(), unwatched(), 1);
  TrajectoryCommand a;
  a.joint_names = {"feed_joint"};
  a.points.push_back({sim.time() + 8.0, {0.04}, {}});  // 5 mm/s
  ASSERT_TRUE(sim.commandTrajectory(a).ok());
  sim.step(4.0);  // halfway: 20 mm
  EXPECT_NEAR(sim.armJointPositions()[6], 0.02, 0.2e-3);
  TrajectoryCommand b;
  b.joint_names = {"feed_joint"};
  b.points.push_back({sim.time() + 3.0, {0.01}, {0.0}});
  ASSERT_TRUE(sim.commandTrajectory(b).ok());
  sim.step(4.0);  // the first goal (40 mm) is abandoned
  EXPECT_NEAR(sim.armJointPositions()[6], 0.01, 0.05e-3);
}

TEST(DrillingSimulation, ANewTrajectoryTakesOverAtItsStartTimeAsJointTrajectoryController) {
  // ros_control's JointTrajectoryController: the running trajectory is followed until the new
  // one's start time (header stamp), and the new one starts from that trajectory's state then.
  DrillingSimulation sim(workcell(), unwatched(), 1);
  const double t0 = sim.time();
  TrajectoryCommand a;
  a.joint_names = {"feed_joint"};
  a.points.push_back({t0 + 4.0, {0.02}, {}});  // 5 mm/s
  ASSERT_TRUE(sim.commandTrajectory(a).ok());
  sim.step(1.0);
  // Sent at t0 + 1 s, starting at t0 + 2 s: until then the first one runs on.
  TrajectoryCommand b;
  b.joint_names = {"feed_joint"};
  b.start_time_s = t0 + 2.0;
  b.points.push_back({t0 + 2.0, {0.0}, {}});  // at the start time itself: not due, dropped
  b.points.push_back({t0 + 3.0, {0.005}, {}});
  ASSERT_TRUE(sim.commandTrajectory(b).ok());
  sim.step(0.9);  // t0 + 1.9 s: still on the first trajectory, 9.5 mm
  EXPECT_NEAR(sim.armJointPositions()[6], 0.0095, 0.2e-3);
  sim.step(0.6);  // t0 + 2.5 s: from 10 mm at t0 + 2 towards 5 mm at t0 + 3
  EXPECT_NEAR(sim.armJointPositions()[6], 0.0075, 0.2e-3);
  sim.step(1.0);
  EXPECT_NEAR(sim.armJointPositions()[6], 0.005, 0.05e-3);
  // A start time in the past (or none) takes over now.
  TrajectoryCommand c;
  c.joint_names = {"feed_joint"};
  c.start_time_s = t0;
  c.points.push_back({sim.time() + 1.0, {0.0}, {}});
  ASSERT_TRUE(sim.commandTrajectory(c).ok());
  sim.step(1.2);
  EXPECT_NEAR(sim.armJointPositions()[6], 0.0, 0.05e-3);
}

// The workcell with the first occurrence of `from` replaced by `to` must be refused with an error
// containing `expected`.
void expectEditedWorkcellRejected(const std::string& from, const std::string& to,
                                  const std::string& expected) {
  std::string urdf = workcell();
  const std::size_t at = urdf.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  urdf.replace(at, from.size(), to);
  try {
    DrillingSimulation sim(urdf, unwatched());
    FAIL() << "no exception for " << to;
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
  }
}

TEST(DrillingSimulation, SpmsLegsOfTheUrdfMustMatchTheKinematicModel) {
  EXPECT_NO_THROW(DrillingSimulation(workcell(), unwatched()));
  // Leg 1's lead screw moved outwards by 1 cm: the closed chain would not close.
  expectEditedWorkcellRejected(R"(<origin xyz="0.000000 0.120000 0.05" rpy="0 0 1.570796"/>)",
                               R"(<origin xyz="0.000000 0.130000 0.05" rpy="0 0 1.570796"/>)",
                               "leg 1");
  // A slider stroke that differs from the model's.
  expectEditedWorkcellRejected(R"(<limit lower="0.0" upper="0.20" velocity="0.05" effort="400"/>)",
                               R"(<limit lower="0.0" upper="0.15" velocity="0.05" effort="400"/>)",
                               "stroke");
}

TEST(DrillingSimulation, BrokenUrdfThrowsClearMessage) {
  try {
    DrillingSimulation sim("<robot name='x'><link name='a'></robot", unwatched());
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("could not parse"), std::string::npos) << e.what();
  }
  // The arm alone (no SPMS) is not a workcell.
  const std::string arm_only = test::readFile(test::sourceDir() + "/urdf/rsssii.urdf");
  try {
    DrillingSimulation sim(arm_only, unwatched());
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("spms"), std::string::npos) << e.what();
  }
}

TEST(VirtualPatient, DrawnFromTheVirtualVolunteerTruth) {
  for (std::uint64_t seed = 0; seed < 10; ++seed) {
    const VirtualPatient p = drawVirtualPatient(seed);
    EXPECT_EQ(p.volunteer_id, 1 + static_cast<int>(seed % 5));
    EXPECT_GT(p.q1_ap_mm_per_ml * 500.0, 4.0);  // about 5 mm peak to peak at 500 ml
    EXPECT_LT(p.q1_ap_mm_per_ml * 500.0, 6.0);
    EXPECT_GE(p.lag_s, 0.05);
    EXPECT_LE(p.lag_s, 0.15);
  }
  EXPECT_NE(drawVirtualPatient(1).drift_phase_rad, drawVirtualPatient(6).drift_phase_rad);
}

TEST(VirtualPatient, SmallMovementsFollowTheVolunteerRateAndSize) {
  EXPECT_TRUE(drawVirtualPatient(3, 0.0, 0.0).movements.empty());
  // Over the hour after the start: Poisson onsets at the volunteer's rate (1-3 per min).
  double total = 0.0;
  double expected = 0.0;
  double sum_sq = 0.0;
  int n = 0;
  for (std::uint64_t seed = 0; seed < 10; ++seed) {
    const VirtualPatient p = drawVirtualPatient(seed, 100.0, 1.0);
    const VolunteerParams v = defaultVolunteer(p.volunteer_id);
    total += p.movements.size();
    expected += v.movements_per_min * 60.0;
    for (const PatientMovement& m : p.movements) {
      EXPECT_GE(m.t, 100.0);
      EXPECT_LT(m.t, 3700.0);
      EXPECT_GE(m.ramp, 0.5);
      EXPECT_LE(m.ramp, 1.0);
      sum_sq += m.size[0] * m.size[0];
      ++n;
    }
    // Before the first onset the movements add nothing.
    EXPECT_EQ(movementDisplacementMm(p.movements, 0, 100.0), 0.0);
  }
  EXPECT_NEAR(total / expected, 1.0, 0.05);
  EXPECT_NEAR(std::sqrt(sum_sq / n), 0.10, 0.01);  // AP movement SD of the volunteers
  // The scale multiplies the sizes of the same onsets.
  const VirtualPatient a = drawVirtualPatient(4, 0.0, 1.0);
  const VirtualPatient b = drawVirtualPatient(4, 0.0, 2.0);
  ASSERT_EQ(a.movements.size(), b.movements.size());
  EXPECT_DOUBLE_EQ(b.movements[3].size[0], 2.0 * a.movements[3].size[0]);
  EXPECT_DOUBLE_EQ(b.movements[3].t, a.movements[3].t);
  // apDisplacementMm includes them.
  const double t = a.movements[3].t + 5.0;
  EXPECT_NEAR(a.apDisplacementMm(0.0, t) - drawVirtualPatient(4, 0.0, 0.0).apDisplacementMm(0.0, t),
              movementDisplacementMm(a.movements, 0, t), 1e-12);
}

}  // namespace
}  // namespace pedicle_drilling::core

namespace pedicle_drilling::core {
namespace {

TEST(DrillingSimulationTrial, StartTrialZeroesRelativeApMotion) {
  DrillingSimulationParams params = unwatched();
  DrillingSimulation sim(workcell(), params, 3);
  sim.step(2.0);  // the bone breathes, the arm holds: relative AP motion builds up
  const double before = sim.groundTruth().relative_ap_m;
  EXPECT_GT(std::abs(before), 1e-4);
  EXPECT_FALSE(sim.startTrial());  // nothing drilled: the same specimen
  EXPECT_EQ(sim.trialCount(), 1);
  EXPECT_EQ(sim.seed(), 3u);
  EXPECT_NEAR(sim.groundTruth().relative_ap_m, 0.0, 1e-12);
}

}  // namespace
}  // namespace pedicle_drilling::core

namespace pedicle_drilling::core {
namespace {

TEST(TrialConditions, ZeroSpreadGivesTheConfiguredValuesForEverySeed) {
  VentilatorSettings vent;
  vent.rate_bpm = 14.0;
  vent.tv_max_ml = 450.0;
  for (std::uint64_t seed = 0; seed < 20; ++seed) {
    const TrialConditions c = drawTrialConditions(seed, TrialVariability{}, vent, 0.03);
    EXPECT_EQ(c.volunteer_id, 1 + static_cast<int>(seed % 5));
    EXPECT_EQ(c.patient_amplitude_scale, 1.0);
    EXPECT_EQ(c.ventilator_rate_bpm, 14.0);
    EXPECT_EQ(c.ventilator_tidal_volume_ml, 450.0);
    EXPECT_EQ(c.force_noise_sd_n, 0.03);
    EXPECT_EQ(c.arm_stiffness_scale, 1.0);
  }
}

TEST(TrialConditions, SpreadsHaveTheirSdAreTruncatedAndReproducible) {
  TrialVariability v;
  v.patient_amplitude_scale_sd = 0.1;
  v.ventilator_rate_sd_bpm = 2.0;
  v.ventilator_tidal_volume_sd_ml = 50.0;
  v.sensor_noise_scale_sd = 0.2;
  v.arm_stiffness_scale_sd = 0.15;
  const VentilatorSettings vent;  // 12 bpm, 500 ml
  const int n = 4000;
  std::vector<double> amp, rate, tv, noise, stiff;
  for (int seed = 0; seed < n; ++seed) {
    const TrialConditions c = drawTrialConditions(seed, v, vent, 0.03);
    amp.push_back(c.patient_amplitude_scale);
    rate.push_back(c.ventilator_rate_bpm);
    tv.push_back(c.ventilator_tidal_volume_ml);
    noise.push_back(c.force_noise_sd_n / 0.03);
    stiff.push_back(c.arm_stiffness_scale);
  }
  auto check = [n](const std::vector<double>& x, double mean, double sd, const char* what) {
    double m = 0.0;
    for (double e : x) m += e / n;
    double var = 0.0;
    for (double e : x) var += (e - m) * (e - m) / (n - 1);
    // Truncation at 3 SD shrinks the SD by 1.3 %; 4000 draws: SE of the mean sd/63.
    EXPECT_NEAR(m, mean, 4.0 * sd / std::sqrt(n)) << what;
    EXPECT_NEAR(std::sqrt(var), sd * 0.987, 0.05 * sd) << what;
    EXPECT_LE(*std::max_element(x.begin(), x.end()), mean + 3.0 * sd + 1e-12) << what;
    EXPECT_GE(*std::min_element(x.begin(), x.end()), mean - 3.0 * sd - 1e-12) << what;
  };
  check(amp, 1.0, 0.1, "amplitude");
  check(rate, 12.0, 2.0, "rate");
  check(tv, 500.0, 50.0, "tidal volume");
  check(noise, 1.0, 0.2, "sensor noise");
  check(stiff, 1.0, 0.15, "arm stiffness");
  const TrialConditions a = drawTrialConditions(7, v, vent, 0.03);
  const TrialConditions b = drawTrialConditions(7, v, vent, 0.03);
  EXPECT_EQ(a.patient_amplitude_scale, b.patient_amplitude_scale);
  EXPECT_EQ(a.arm_stiffness_scale, b.arm_stiffness_scale);
  // Each factor has its own deviate: switching one spread off leaves the others' draws alone.
  TrialVariability only_rate = v;
  only_rate.patient_amplitude_scale_sd = 0.0;
  const TrialConditions c = drawTrialConditions(7, only_rate, vent, 0.03);
  EXPECT_EQ(c.patient_amplitude_scale, 1.0);
  EXPECT_EQ(c.ventilator_rate_bpm, a.ventilator_rate_bpm);
  EXPECT_EQ(c.arm_stiffness_scale, a.arm_stiffness_scale);
}

TEST(TrialConditions, OutOfRangeSpreadsNameTheField) {
  const VentilatorSettings vent;
  auto message = [&vent](const TrialVariability& v) {
    try {
      drawTrialConditions(1, v, vent, 0.03);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  TrialVariability v;
  v.patient_amplitude_scale_sd = 0.5;
  EXPECT_NE(message(v).find("patient/amplitude_scale_sd"), std::string::npos) << message(v);
  v = TrialVariability{};
  v.ventilator_rate_sd_bpm = std::nan("");
  EXPECT_NE(message(v).find("ventilator/rate_sd_bpm"), std::string::npos) << message(v);
  v = TrialVariability{};
  v.arm_stiffness_scale_sd = -0.1;
  EXPECT_NE(message(v).find("arm/stiffness_scale_sd"), std::string::npos) << message(v);
  v = TrialVariability{};
  v.arm_stiffness_scale = 0.05;
  EXPECT_NE(message(v).find("arm/stiffness_scale ="), std::string::npos) << message(v);
}

TEST(TrialConditions, ArmStiffnessScaleMultipliesEveryTrialsDraw) {
  const VentilatorSettings vent;
  TrialVariability spread;
  spread.arm_stiffness_scale_sd = 0.2;
  TrialVariability soft = spread;
  soft.arm_stiffness_scale = 0.2;  // 5 N/mm at the tool: the soft end of collaborative arms
  for (std::uint64_t seed = 0; seed < 50; ++seed) {
    const TrialConditions a = drawTrialConditions(seed, spread, vent, 0.03);
    const TrialConditions b = drawTrialConditions(seed, soft, vent, 0.03);
    EXPECT_DOUBLE_EQ(b.arm_stiffness_scale, 0.2 * a.arm_stiffness_scale) << seed;
    // The mean scale moves no other draw.
    EXPECT_EQ(b.patient_amplitude_scale, a.patient_amplitude_scale);
    EXPECT_EQ(b.force_noise_sd_n, a.force_noise_sd_n);
  }
  TrialVariability fixed;
  fixed.arm_stiffness_scale = 2.0;
  EXPECT_EQ(drawTrialConditions(3, fixed, vent, 0.03).arm_stiffness_scale, 2.0);
}

TEST(DrillingSimulationTrial, ResetAppliesTheDrawnPatientSensorArmAndBreathing) {
  DrillingSimulationParams params = unwatched();
  DrillingSimulation sim(workcell(), params, 3);
  const double q1_volunteer = drawVirtualPatient(8).q1_ap_mm_per_ml;
  TrialVariability v;
  v.patient_amplitude_scale_sd = 0.2;
  v.ventilator_rate_sd_bpm = 3.0;
  v.ventilator_tidal_volume_sd_ml = 80.0;
  v.sensor_noise_scale_sd = 0.3;
  v.arm_stiffness_scale_sd = 0.2;
  sim.setTrialDistribution(SpecimenDistribution{}, v);
  sim.reset(8, true);
  const TrialConditions& c = sim.trialConditions();
  const TrialConditions expected = drawTrialConditions(8, v, params.ventilator, 0.03);
  EXPECT_EQ(c.patient_amplitude_scale, expected.patient_amplitude_scale);
  EXPECT_NE(c.patient_amplitude_scale, 1.0);
  EXPECT_DOUBLE_EQ(sim.patient().q1_ap_mm_per_ml, q1_volunteer * c.patient_amplitude_scale);
  EXPECT_EQ(sim.patient().volunteer_id, 4);
  // The new breathing takes effect at the next breath (12 bpm: within 5 s).
  sim.step(5.5);
  EXPECT_DOUBLE_EQ(sim.ventilator().model().settings().rate_bpm, c.ventilator_rate_bpm);
  EXPECT_DOUBLE_EQ(sim.ventilator().model().settings().tv_max_ml, c.ventilator_tidal_volume_ml);
  // Back to no spread: the configured breathing returns and scales are 1 again.
  sim.setTrialDistribution(SpecimenDistribution{}, TrialVariability{});
  sim.reset(8, true);
  EXPECT_EQ(sim.trialConditions().arm_stiffness_scale, 1.0);
  EXPECT_DOUBLE_EQ(sim.patient().q1_ap_mm_per_ml, q1_volunteer);
  sim.step(60.0 / c.ventilator_rate_bpm + 0.5);
  EXPECT_DOUBLE_EQ(sim.ventilator().model().settings().rate_bpm, params.ventilator.rate_bpm);
}

TEST(DrillingSimulationTrial, StiffnessScaleIsAppliedToTheArmAtReset) {
  DrillingSimulationParams params = unwatched();
  DrillingSimulation sim(workcell(), params, 2);
  const Eigen::VectorXd nominal = sim.armJointStiffness();
  TrialVariability v;
  v.arm_stiffness_scale_sd = 0.3;
  sim.setTrialDistribution(SpecimenDistribution{}, v);
  sim.reset(17, false);
  const double scale = sim.trialConditions().arm_stiffness_scale;
  EXPECT_NE(scale, 1.0);
  const Eigen::VectorXd scaled = sim.armJointStiffness();
  const std::vector<std::string>& names = sim.armJointNames();
  for (int k = 0; k < scaled.size(); ++k) {
    const double factor = names[k] == "spindle_joint" ? 1.0 : scale;
    EXPECT_NEAR(scaled[k], factor * nominal[k], 1e-9 * nominal[k]) << names[k];
  }
}

TEST(DrillingSimulationTrial, BadDistributionThrowsAndLeavesTheTrialAlone) {
  DrillingSimulationParams params = unwatched();
  DrillingSimulation sim(workcell(), params, 3);
  const double inner = sim.process().specimen().innerCorticalThickness();
  SpecimenDistribution bad;
  bad.inner_cortical_thickness_mean_m = -1e-3;
  EXPECT_THROW(sim.setTrialDistribution(bad, TrialVariability{}), std::invalid_argument);
  TrialVariability bad_v;
  bad_v.sensor_noise_scale_sd = 2.0;
  EXPECT_THROW(sim.setTrialDistribution(SpecimenDistribution{}, bad_v), std::invalid_argument);
  sim.reset(3, true);  // the old, valid distributions are still in force
  EXPECT_DOUBLE_EQ(sim.process().specimen().innerCorticalThickness(), inner);
  // A specimen mean set without spread is what every trial gets.
  SpecimenDistribution fixed;
  fixed.inner_cortical_thickness_mean_m = 3.0e-3;
  fixed.inner_cortical_thickness_sd_m = 0.0;
  sim.setTrialDistribution(fixed, TrialVariability{});
  sim.reset(11, true);
  EXPECT_DOUBLE_EQ(sim.process().specimen().innerCorticalThickness(), 3.0e-3);
}

}  // namespace
}  // namespace pedicle_drilling::core

TEST(StreamPeriodSteps, RoundsTheRatioAndRefusesRatesOutsideThePhysicsRate) {
  using pedicle_drilling::core::streamPeriodSteps;
  EXPECT_EQ(streamPeriodSteps(1000.0, 8.0, "tracker_rate_hz"), 125u);
  EXPECT_EQ(streamPeriodSteps(1000.0, 64.0, "tidal_volume_rate_hz"), 16u);  // 15.625 rounds
  EXPECT_EQ(streamPeriodSteps(1000.0, 1000.0, "x"), 1u);
  EXPECT_EQ(streamPeriodSteps(1000.0, 700.0, "x"), 1u);
  for (double bad : {0.0, -1.0, 1000.5, std::nan(""), HUGE_VAL}) {
    try {
      streamPeriodSteps(1000.0, bad, "tracker_rate_hz");
      ADD_FAILURE() << "accepted " << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("tracker_rate_hz"), std::string::npos) << e.what();
    }
  }
}

namespace pedicle_drilling::core {
namespace {

TEST(DrillingSimulation, TheSpindleDriversWatchdogStopsASpindleThatHearsNoCommand) {
  DrillingSimulationParams p;  // the defaults: the driver's watchdog on
  ASSERT_DOUBLE_EQ(p.spindle_watchdog_s, 0.5);
  DrillingSimulation sim(workcell(), p, 1);
  sim.reset(1, false);
  sim.commandSpindle(12000.0);
  // Kept alive every 0.1 s (the planner's spindle_keepalive_s): it runs on.
  for (int i = 0; i < 20; ++i) {
    sim.step(0.1);
    ASSERT_EQ(sim.commandSpindle(12000.0).status, TargetStatus::kAccepted);
  }
  EXPECT_NEAR(sim.spindleRpm(), 12000.0, 1e-9);
  EXPECT_EQ(sim.spindleWatchdogTrips(), 0);
  // Silent for longer than the watchdog: the driver stops it (run-down at its rate).
  sim.step(0.49);
  EXPECT_NEAR(sim.spindleRpm(), 12000.0, 1e-9);
  sim.step(0.02);
  EXPECT_EQ(sim.spindleWatchdogTrips(), 1);
  sim.step(0.5);
  EXPECT_EQ(sim.spindleRpm(), 0.0);
  EXPECT_EQ(sim.spindleWatchdogTrips(), 1);  // once per stop; a stopped spindle is not watched
  sim.reset(2, false);
  EXPECT_EQ(sim.spindleWatchdogTrips(), 0);
}

TEST(DrillingSimulation, WithoutTheDrillGuardsEnableTheDrivesHoldAndTheSpindleStops) {
  DrillingSimulationParams p = unwatched();
  p.drive_guard_timeout_s = 0.05;
  DrillingSimulation sim(workcell(), p, 1);
  sim.reset(1, false);
  sim.step(0.01);
  // Fails closed: before any enable, nothing moves.
  EXPECT_TRUE(sim.drivesHalted());
  EXPECT_EQ(sim.commandSpindle(12000.0).status, TargetStatus::kRejected);
  EXPECT_EQ(sim.commandSpindle(0.0).status, TargetStatus::kAccepted);  // a stop is always taken
  double last_enable = 0.0;
  const auto beat = [&sim, &last_enable](double seconds) {  // the guard's 50 Hz heartbeat
    for (int i = 0; i < static_cast<int>(std::lround(seconds / 0.02)); ++i) {
      sim.onDriveEnable(true);
      last_enable = sim.time();
      sim.step(0.02);
    }
  };
  beat(0.02);
  EXPECT_FALSE(sim.drivesHalted());
  ASSERT_EQ(sim.commandSpindle(12000.0).status, TargetStatus::kAccepted);
  // The feed advances at 1 mm/s for 4 s while the guard beats.
  TrajectoryCommand c;
  c.joint_names = {"feed_joint"};
  c.points.push_back({sim.time() + 4.0, {4e-3}, {}});
  ASSERT_EQ(sim.commandTrajectory(c).status, TargetStatus::kAccepted);
  beat(1.0);
  EXPECT_NEAR(sim.spindleRpm(), 12000.0, 1e-9);
  const double feed_at_silence = sim.groundTruth().feed_joint_m;
  EXPECT_GT(feed_at_silence, 0.5e-3);
  // The guard falls silent (its process died): halted at the first step past 0.05 s.
  const double silent_from = sim.time();
  while (!sim.drivesHalted() && sim.time() < silent_from + 1.0) sim.step(0.001);
  EXPECT_GT(sim.time() - last_enable, 0.05);  // the latest enable is older than the timeout
  EXPECT_LE(sim.time() - last_enable, 0.0515);
  EXPECT_EQ(sim.driveGuardTrips(), 1);  // the hold before the first enable is not a trip
  const double feed_at_halt = sim.groundTruth().feed_joint_m;
  sim.step(0.5);
  // The feed held (within the drive's lag), the spindle ran down at its rate (0.3 s from 12000).
  EXPECT_NEAR(sim.groundTruth().feed_joint_m, feed_at_halt, 0.02e-3);
  EXPECT_LT(sim.groundTruth().feed_joint_m, feed_at_silence + 0.08e-3);
  EXPECT_EQ(sim.spindleRpm(), 0.0);
  EXPECT_TRUE(sim.groundTruth().drives_halted);
  EXPECT_EQ(sim.commandTrajectory(c).status, TargetStatus::kRejected);
  // A false is a halt at once; the enable back takes commands again (no trajectory resumes).
  beat(0.1);
  EXPECT_FALSE(sim.drivesHalted());
  EXPECT_NEAR(sim.groundTruth().feed_joint_m, feed_at_halt, 0.02e-3);
  sim.onDriveEnable(false);
  sim.step(0.001);
  EXPECT_TRUE(sim.drivesHalted());
  EXPECT_EQ(sim.driveGuardTrips(), 2);
}

TEST(DrillingSimulation, AnAbortedControllerHoldsUntilItsNextCommand) {
  DrillingSimulation sim(workcell(), unwatched(), 1);
  sim.reset(1, false);
  std::string feed_controller;
  for (const ControllerSpec& c : sim.controllers()) {
    if (std::count(c.joints.begin(), c.joints.end(), "feed_joint") > 0) feed_controller = c.name;
  }
  ASSERT_FALSE(feed_controller.empty());
  TrajectoryCommand c;
  c.joint_names = {"feed_joint"};
  c.points.push_back({sim.time() + 4.0, {4e-3}, {}});
  ASSERT_EQ(sim.commandTrajectory(c).status, TargetStatus::kAccepted);
  sim.step(1.0);
  const double before = sim.groundTruth().feed_joint_m;
  EXPECT_GT(before, 0.5e-3);
  sim.abortController(feed_controller);
  EXPECT_EQ(sim.controllerAborts(), 1);
  EXPECT_EQ(sim.groundTruth().controller_aborts, 1u);
  sim.step(0.5);
  const double held = sim.groundTruth().feed_joint_m;
  EXPECT_NEAR(held, before, 0.02e-3);  // it held (the drive's lag only), not 0.5 mm further
  // The next command is taken as usual.
  c.points = {{sim.time() + 1.0, {held + 1e-3}, {}}};
  ASSERT_EQ(sim.commandTrajectory(c).status, TargetStatus::kAccepted);
  sim.step(1.5);
  EXPECT_NEAR(sim.groundTruth().feed_joint_m, held + 1e-3, 0.02e-3);
  EXPECT_THROW(sim.abortController("no_such_controller"), std::invalid_argument);
}

TEST(DrillingSimulation, AnUntaredSensorReadsTheToolsWeightUntilTheDriversTare) {
  DrillingSimulationParams p = unwatched();
  p.sensor_tared_at_reset = false;
  p.sensor_bias_offset_n = 4.9;
  DrillingSimulation sim(workcell(), p, 3);
  sim.reset(3, false);
  sim.commandSpindle(12000.0);
  moveToDrillingPose(&sim, 1.0);  // tool free, spindle running
  const auto meanFz = [&sim](int samples) {
    double sum = 0.0;
    int n = 0;
    while (n < samples) {
      const SimulationStep s = sim.stepOnce();
      if (!s.force_sampled) continue;
      sum += s.measured_wrench[2];
      ++n;
    }
    return sum / n;
  };
  EXPECT_NEAR(meanFz(100), 4.9, 1.0);  // the weight, plus a bias of SD 0.2 N
  sim.requestTare({100, 0.5});
  EXPECT_FALSE(sim.takeTareResult());
  meanFz(100);
  const std::optional<TareResult> r = sim.takeTareResult();
  ASSERT_TRUE(r);
  EXPECT_TRUE(r->success) << r->message;
  EXPECT_NEAR(r->bias[2], 4.9, 1.0);
  EXPECT_LT(r->spread_n, 0.5);
  EXPECT_NEAR(meanFz(300), 0.0, 0.05);  // tared: what is left is noise and drift
  EXPECT_THROW(sim.requestTare({0, 0.5}), std::invalid_argument);
  // The benches' sensor, tared at reset, reads about zero without a request.
  DrillingSimulation bench(workcell(), unwatched(), 3);
  bench.reset(3, false);
  bench.commandSpindle(12000.0);
  moveToDrillingPose(&bench, 1.0);
  double sum = 0.0;
  int n = 0;
  while (n < 300) {
    const SimulationStep s = bench.stepOnce();
    if (!s.force_sampled) continue;
    sum += s.measured_wrench[2];
    ++n;
  }
  EXPECT_NEAR(sum / n, 0.0, 0.05);
}

}  // namespace
}  // namespace pedicle_drilling::core
