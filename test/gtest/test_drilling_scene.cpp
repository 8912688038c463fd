// Layout of the rviz drilling scene (core/drilling_scene): slabs follow the ground-truth depths
// and broken messages are refused with the offending field named.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "pedicle_drilling/core/drilling/drilling_scene.hpp"
#include "pedicle_drilling/core/sim/drilling_simulation.hpp"
#include "support.hpp"

namespace pd = pedicle_drilling::core;

namespace {

pd::SpecimenDepths typical() {
  pd::SpecimenDepths d;
  d.outer_cortical_end_m = 0.002;
  d.inner_cortical_start_m = 0.006;
  d.inner_cortical_end_m = 0.0081;
  d.max_depth_cut_m = 0.0068;
  d.residual_inner_cortical_m = 0.0013;
  return d;
}

std::string errorOf(const pd::SpecimenDepths& d) {
  try {
    pd::layoutDrillingScene(d);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(DrillingScene, LayersStackDownFromTheTopSurface) {
  const pd::SpecimenDepths d = typical();
  const pd::DrillingScene s = pd::layoutDrillingScene(d);
  EXPECT_DOUBLE_EQ(s.outer_cortical.top_z_m, 0.0);
  EXPECT_DOUBLE_EQ(s.outer_cortical.bottom_z_m, -d.outer_cortical_end_m);
  EXPECT_DOUBLE_EQ(s.cancellous.top_z_m, s.outer_cortical.bottom_z_m);
  EXPECT_DOUBLE_EQ(s.cancellous.bottom_z_m, -d.inner_cortical_start_m);
  EXPECT_DOUBLE_EQ(s.inner_cortical.top_z_m, s.cancellous.bottom_z_m);
  EXPECT_DOUBLE_EQ(s.inner_cortical.bottom_z_m, -d.inner_cortical_end_m);
  EXPECT_NEAR(s.inner_cortical.thickness(), d.inner_cortical_end_m - d.inner_cortical_start_m,
              1e-15);
}

TEST(DrillingScene, HoleReachesTheDeepestCut) {
  const pd::SpecimenDepths d = typical();
  const pd::DrillingScene s = pd::layoutDrillingScene(d);
  EXPECT_TRUE(s.has_hole);
  EXPECT_DOUBLE_EQ(s.hole.top_z_m, 0.0);
  EXPECT_DOUBLE_EQ(s.hole.bottom_z_m, -d.max_depth_cut_m);
  EXPECT_DOUBLE_EQ(s.hole.centre(), -0.5 * d.max_depth_cut_m);
}

TEST(DrillingScene, ResidualIsTheBottomOfTheInnerCortex) {
  const pd::SpecimenDepths d = typical();
  const pd::DrillingScene s = pd::layoutDrillingScene(d);
  EXPECT_TRUE(s.has_residual);
  EXPECT_DOUBLE_EQ(s.residual.bottom_z_m, -d.inner_cortical_end_m);
  EXPECT_NEAR(s.residual.thickness(), d.residual_inner_cortical_m, 1e-15);
}

TEST(DrillingScene, UntouchedAndBrokenThroughSpecimens) {
  pd::SpecimenDepths fresh = typical();
  fresh.max_depth_cut_m = 0.0;
  fresh.residual_inner_cortical_m = fresh.inner_cortical_end_m;  // down to the canal wall
  const pd::DrillingScene a = pd::layoutDrillingScene(fresh);
  EXPECT_FALSE(a.has_hole);
  EXPECT_TRUE(a.has_residual);
  EXPECT_NEAR(a.residual.top_z_m, a.inner_cortical.top_z_m, 1e-15);

  pd::SpecimenDepths through = typical();
  through.max_depth_cut_m = 0.0095;
  through.residual_inner_cortical_m = 0.0;
  const pd::DrillingScene b = pd::layoutDrillingScene(through);
  EXPECT_TRUE(b.has_hole);
  EXPECT_FALSE(b.has_residual);
  EXPECT_LT(b.hole.bottom_z_m, b.inner_cortical.bottom_z_m);
}

TEST(DrillingScene, RejectsBrokenMessagesNamingTheField) {
  pd::SpecimenDepths nan = typical();
  nan.max_depth_cut_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(errorOf(nan).find("max_depth_cut_m"), std::string::npos);

  pd::SpecimenDepths swapped = typical();
  swapped.inner_cortical_start_m = 0.001;  // above the end of the outer cortex
  EXPECT_NE(errorOf(swapped).find("inner_cortical_start_m"), std::string::npos);

  pd::SpecimenDepths millimetres = typical();  // mm sent where m are expected
  millimetres.outer_cortical_end_m = 2.0;
  millimetres.inner_cortical_start_m = 6.0;
  millimetres.inner_cortical_end_m = 8.1;
  EXPECT_NE(errorOf(millimetres).find("inner_cortical_end_m"), std::string::npos);

  pd::SpecimenDepths negative_cut = typical();
  negative_cut.max_depth_cut_m = -0.001;
  EXPECT_NE(errorOf(negative_cut).find("max_depth_cut_m"), std::string::npos);

  pd::SpecimenDepths inconsistent = typical();  // not inner_cortical_end - max_depth_cut
  inconsistent.residual_inner_cortical_m = 0.005;
  EXPECT_NE(errorOf(inconsistent).find("residual_inner_cortical_m"), std::string::npos);
  inconsistent.residual_inner_cortical_m = -0.0001;
  EXPECT_NE(errorOf(inconsistent).find("residual_inner_cortical_m"), std::string::npos);

  EXPECT_EQ(errorOf(typical()), "");
}

// What the real simulator publishes over a whole trial, from above the bone through the canal
// wall, every 10 ms: the display lays every message out (a user once saw the display turn red
// for a whole trial: it bounded the residual by the layer's thickness, the simulator sent the
// distance to the canal wall; GroundTruth.msg now states that one definition).
TEST(DrillingScene, LaysOutEveryGroundTruthOfASimulatedTrial) {
  pd::DrillingSimulationParams params;
  params.spindle_watchdog_s = 0.0;  // one spindle command, no keepalive
  pd::DrillingSimulation sim(pedicle_drilling::test::workcellUrdf(), params, 4);
  sim.reset(4, false);
  sim.commandSpindle(12000.0);
  pd::TrajectoryCommand pose;
  pose.joint_names = {"rsssii_joint1", "rsssii_joint2", "rsssii_joint3", "rsssii_joint4",
                      "rsssii_joint5", "rsssii_joint6", "feed_joint"};
  pose.points.push_back(  // config/drilling_pose.yaml
      {sim.time() + 1.0, {0.0, 0.435859, 1.319709, 0.0, 1.386025, 0.0, 0.0}, {}});
  ASSERT_TRUE(sim.commandTrajectory(pose).ok());
  sim.step(1.5);
  pd::TrajectoryCommand feed;  // 5 mm above the bone, through about 9 mm of bone, at 2 mm/s
  feed.joint_names = {"feed_joint"};
  feed.points.push_back({sim.time() + 9.0, {0.018}, {}});
  ASSERT_TRUE(sim.commandTrajectory(feed).ok());
  int laid_out = 0, with_residual_above_the_layer = 0;
  bool broke_through = false;
  for (int i = 0; i < 950; ++i) {
    sim.step(0.01);
    const pd::SimulationGroundTruth g = sim.groundTruth();
    pd::SpecimenDepths d;
    d.outer_cortical_end_m = g.outer_cortical_end_m;
    d.inner_cortical_start_m = g.inner_cortical_start_m;
    d.inner_cortical_end_m = g.inner_cortical_end_m;
    d.max_depth_cut_m = g.max_depth_cut_m;
    d.residual_inner_cortical_m = g.residual_inner_cortical_m;
    ASSERT_EQ(errorOf(d), "") << "t = " << g.max_depth_cut_m;
    const pd::DrillingScene s = pd::layoutDrillingScene(d);
    EXPECT_LE(s.residual.thickness(), s.inner_cortical.thickness() + 1e-12);
    ++laid_out;
    with_residual_above_the_layer +=
        g.residual_inner_cortical_m > g.inner_cortical_end_m - g.inner_cortical_start_m ? 1 : 0;
    broke_through = broke_through || g.breakthrough;
  }
  EXPECT_EQ(laid_out, 950);
  EXPECT_GT(with_residual_above_the_layer, 100);  // before the inner layer: more than its thickness
  EXPECT_TRUE(broke_through);                     // and the whole way through
}
