// Tests of core::ClosedLoopEngine: whole trials on the simulation with the nodelets' objects.
#include "pedicle_drilling/core/closed_loop_engine.hpp"

#include <gtest/gtest.h>

#include <iostream>
#include <string>

#include "pedicle_drilling/core/motion_model_io.hpp"
#include "support.hpp"

namespace pd = pedicle_drilling::core;

namespace {

const std::string kSource = pedicle_drilling::test::sourceDir();

pd::EngineConfig config() {
  pd::EngineConfig c;
  c.urdf_xml = pedicle_drilling::test::workcellUrdf();
  c.drilling_pose = {0.0, 0.435859, 1.319709, 0.0, 1.386025, 0.0};  // config/drilling_pose.yaml
  c.sequencer.retreat.distance_m = 0.025;  // config/compensation_planner.yaml
  return c;
}

pd::EngineTrialSpec spec(const std::string& mode, std::uint64_t seed) {
  pd::EngineTrialSpec s;
  s.seed = seed;
  s.mode = mode;
  // config/patient_default.yaml: virtual volunteer 1 (seed 5 draws this volunteer).
  const pd::PatientModel patient = pd::readModelYaml(kSource + "/config/patient_default.yaml");
  s.model = patient.motionModel();
  if (mode != "stationary") {
    const pd::AxisModelRecord& ap = patient.axes[static_cast<int>(pd::Axis::kAP)];
    s.bone_motion = pd::BoneMotionModel{ap.model.q1, ap.model.q2};
  }
  return s;
}

void expectSameRecord(const pd::EngineTrialRecord& a, const pd::EngineTrialRecord& b) {
  ASSERT_EQ(a.states.size(), b.states.size());
  for (std::size_t i = 0; i < a.states.size(); ++i) {
    EXPECT_EQ(a.states[i].t, b.states[i].t);
    EXPECT_EQ(a.states[i].averaged_force, b.states[i].averaged_force) << i;  // bit for bit
    EXPECT_EQ(a.states[i].state_name, b.states[i].state_name);
  }
  ASSERT_EQ(a.truth.size(), b.truth.size());
  for (std::size_t i = 0; i < a.truth.size(); ++i) {
    EXPECT_EQ(a.truth[i].max_depth_cut_m, b.truth[i].max_depth_cut_m) << i;
    EXPECT_EQ(a.truth[i].relative_ap_m, b.truth[i].relative_ap_m) << i;
  }
  ASSERT_EQ(a.stops.size(), b.stops.size());
  for (std::size_t i = 0; i < a.stops.size(); ++i) {
    EXPECT_EQ(a.stops[i].t, b.stops[i].t);
    EXPECT_EQ(a.stops[i].reason, b.stops[i].reason);
  }
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.last_truth.residual_inner_cortical_m, b.last_truth.residual_inner_cortical_m);
}

std::string statuses(const pd::EngineTrialRecord& r) {
  std::string s;
  for (const auto& p : r.status) s += (s.empty() ? "" : " ") + p.second;
  return s;
}

}  // namespace

TEST(ClosedLoopEngine, StationaryTrialStopsInsideTheInnerLayer) {
  pd::ClosedLoopEngine engine(config());
  const pd::EngineTrialRecord r = engine.run(spec("stationary", 5));
  std::cout << "[ trial ] stationary seed 5: " << statuses(r) << "; residual "
            << r.last_truth.residual_inner_cortical_m * 1e3 << " mm" << std::endl;
  EXPECT_EQ(statuses(r), "moving_to_pose registering drilling stopped retreating done");
  ASSERT_FALSE(r.stops.empty());
  EXPECT_EQ(r.stops[0].source, "/state_recognizer");
  EXPECT_FALSE(r.stops[0].retreat);
  EXPECT_FALSE(r.last_truth.breakthrough);
  EXPECT_GT(r.last_truth.max_depth_cut_m, r.last_truth.inner_cortical_start_m);
  EXPECT_GT(r.last_truth.residual_inner_cortical_m, 0.0);
  EXPECT_LE(r.last_truth.residual_inner_cortical_m, 2e-3);
  // One recognizer state per 50 force samples, key points in order.
  ASSERT_GT(r.states.size(), 100u);
  EXPECT_NEAR(r.states[1].t - r.states[0].t, 0.05, 1e-9);
  ASSERT_GE(r.key_points.size(), 4u);
  for (std::size_t i = 0; i < r.key_points.size(); ++i) {
    EXPECT_EQ(r.key_points[i].first, static_cast<int>(i) + 1);
  }
}

TEST(ClosedLoopEngine, OneSeedGivesTheSameTrialBitForBitWhateverRanBefore) {
  pd::ClosedLoopEngine a(config());
  pd::ClosedLoopEngine b(config());
  const pd::EngineTrialRecord first = a.run(spec("compensated", 7));
  b.run(spec("stationary", 3));  // another trial first: must not matter
  const pd::EngineTrialRecord second = b.run(spec("compensated", 7));
  expectSameRecord(first, second);
  // The compensated bench trial is safe: a stop, and the inner layer not broken through.
  EXPECT_FALSE(first.stops.empty()) << statuses(first);
  EXPECT_FALSE(first.last_truth.breakthrough);
}

TEST(ClosedLoopEngine, BadConfigurationNamesTheField) {
  pd::EngineConfig c = config();
  c.delays.stop_to_planner_s = -1.0;
  try {
    pd::ClosedLoopEngine engine(c);
    FAIL() << "accepted a negative delay";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("stop_to_planner_s:", 0), 0u) << e.what();
  }
  c = config();
  c.drilling_pose.pop_back();
  EXPECT_THROW(pd::ClosedLoopEngine{c}, std::invalid_argument);
  c = config();
  c.tracker_rate_hz = 0.0;
  EXPECT_THROW(pd::ClosedLoopEngine{c}, std::invalid_argument);
}

TEST(ClosedLoopEngine, ARefusedTrialIsAnErrorNamingTheReason) {
  pd::ClosedLoopEngine engine(config());
  pd::EngineTrialSpec s = spec("stationary", 1);
  s.mode = "sideways";
  try {
    engine.run(s);
    FAIL() << "ran a trial of an unknown mode";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("mode"), std::string::npos) << e.what();
  }
}
