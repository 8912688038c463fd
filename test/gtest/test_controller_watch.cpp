// Tests of core::ControllerWatch: the planner's closed loop on its controllers' states.
#include "pedicle_drilling/core/control/controller_watch.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

namespace pd = pedicle_drilling::core;

namespace {

const std::vector<pd::ControllerSpec> kControllers = {{"arm", {"a", "b"}}, {"feed", {"f"}}};

pd::ControllerStateSample state(const std::vector<std::string>& names, double t,
                                const std::vector<double>& desired, double error = 0.0) {
  pd::ControllerStateSample s;
  s.stamp = t;
  s.joint_names = names;
  s.desired_positions = desired;
  for (double d : desired) {
    s.actual_positions.push_back(d - error);
    s.error_positions.push_back(error);
  }
  return s;
}

/** @brief Both controllers of kControllers report every joint at 0 (t = 0, before a start). */
void reportAtZero(pd::ControllerWatch* watch) {
  watch->onState(0.0, "arm", state({"a", "b"}, 0.0, {0.0, 0.0}));
  watch->onState(0.0, "feed", state({"f"}, 0.0, {0.0}));
}

pd::TrajectoryCommand feedTo(double t_end, double feed) {
  pd::TrajectoryCommand c;
  c.joint_names = {"f"};
  c.points.push_back({t_end, {feed}});
  return c;
}

}  // namespace

TEST(ControllerWatch, StartsFromEachControllersLastDesiredPosition) {
  pd::ControllerWatch watch({}, kControllers, {"f"});
  EXPECT_NE(watch.start(0.0).find("arm has not reported its state"), std::string::npos);
  EXPECT_EQ(watch.onState(0.0, "arm", state({"a", "b"}, 0.0, {0.1, 0.2})), "");
  EXPECT_NE(watch.start(0.0).find("feed has not reported"), std::string::npos);
  EXPECT_EQ(watch.onState(0.0, "feed", state({"f"}, 0.0, {0.01})), "");
  EXPECT_EQ(watch.onState(0.0, "other", state({"x"}, 0.0, {5.0})), "");  // not ours: ignored
  ASSERT_EQ(watch.start(0.0), "");
  EXPECT_TRUE(watch.watching());
  // The first state at or after the start seeds the expectation; holding there is no fault.
  EXPECT_EQ(watch.onState(0.05, "arm", state({"a", "b"}, 0.05, {0.1, 0.2})), "");
  EXPECT_EQ(watch.onState(0.1, "arm", state({"b", "a"}, 0.1, {0.2, 0.1})), "");
  EXPECT_NEAR(watch.worstDesiredRatio(), 0.0, 1e-12);
}

TEST(ControllerWatch, AStateWithoutAWatchedJointRefusesTheStartNamingIt) {
  pd::ControllerWatch watch({}, {{"arm", {"a", "b", "f"}}}, {"f"});
  EXPECT_EQ(watch.onState(0.0, "arm", state({"a", "b"}, 0.0, {0.1, 0.2})), "");
  const std::string why = watch.start(0.0);
  EXPECT_NE(why.find("arm/state does not give every joint the planner commands on arm (a, b, f; "
                     "it names a b)"),
            std::string::npos)
      << why;
  EXPECT_FALSE(watch.watching());
}

TEST(ControllerWatch, ADesiredThatDepartsFromTheCommandedIsAFault) {
  pd::ControllerWatchParams p;
  p.feed_desired_tolerance_m = 0.001;
  pd::ControllerWatch watch(p, kControllers, {"f"});
  reportAtZero(&watch);
  ASSERT_EQ(watch.start(0.0), "");
  watch.onCommand(0.0, feedTo(1.0, 0.01));  // 10 mm in 1 s, linear
  // A state from before the start (the robot may have been reset since) does not seed it ...
  EXPECT_EQ(watch.onState(0.0, "feed", state({"f"}, -0.02, {0.05})), "");
  // ... the first one taken after it does; the commands sent since are replayed on it.
  EXPECT_EQ(watch.onState(0.0, "feed", state({"f"}, 0.0, {0.0})), "");
  // The controller follows it: no fault.
  EXPECT_EQ(watch.onState(0.5, "feed", state({"f"}, 0.5, {0.005})), "");
  EXPECT_NEAR(watch.worstDesiredRatio(), 0.0, 1e-9);
  // The controller kept its old trajectory (it refused the command): 6 mm behind at 0.6 s.
  const std::string why = watch.onState(0.6, "feed", state({"f"}, 0.6, {0.0}));
  EXPECT_NE(why.find("feed: the desired position of f differs from the commanded by 0.006"),
            std::string::npos)
      << why;
  EXPECT_FALSE(watch.watching());  // one fault, then quiet
  EXPECT_EQ(watch.onState(0.7, "feed", state({"f"}, 0.7, {0.0})), "");
}

TEST(ControllerWatch, AnErrorPastTheFollowingToleranceIsAFault) {
  pd::ControllerWatchParams p;
  p.arm_following_tolerance_rad = 0.02;
  pd::ControllerWatch watch(p, kControllers, {"f"});
  reportAtZero(&watch);
  ASSERT_EQ(watch.start(0.0), "");
  EXPECT_EQ(watch.onState(0.0, "arm", state({"a", "b"}, 0.0, {0.0, 0.0})), "");  // seeds
  EXPECT_EQ(watch.onState(0.1, "arm", state({"a", "b"}, 0.1, {0.0, 0.0}, 0.019)), "");
  EXPECT_NEAR(watch.worstFollowingRatio(), 0.95, 1e-9);
  const std::string why = watch.onState(0.2, "arm", state({"a", "b"}, 0.2, {0.0, 0.0}, -0.03));
  EXPECT_NE(why.find("arm: a does not follow its trajectory: error -0.03"), std::string::npos)
      << why;
}

TEST(ControllerWatch, ANaNStateOrASilentControllerIsAFault) {
  pd::ControllerWatchParams p;
  p.state_timeout_s = 0.2;
  pd::ControllerWatch watch(p, kControllers, {"f"});
  reportAtZero(&watch);
  ASSERT_EQ(watch.start(0.0), "");
  EXPECT_EQ(watch.checkSilence(0.15), "");
  watch.onState(0.15, "arm", state({"a", "b"}, 0.15, {0.0, 0.0}));
  const std::string silent = watch.checkSilence(0.25);
  EXPECT_NE(silent.find("feed silent: no feed/state for more than 0.2 s"), std::string::npos)
      << silent;
  pd::ControllerWatch nan_watch(p, kControllers, {"f"});
  reportAtZero(&nan_watch);
  ASSERT_EQ(nan_watch.start(0.0), "");
  const std::string why =
      nan_watch.onState(0.1, "arm", state({"a", "b"}, 0.1, {0.0, std::nan("")}));
  EXPECT_NE(why.find("or has NaN/inf"), std::string::npos) << why;
}

TEST(ControllerWatch, DisabledNeverStartsAndBadParametersAreRefused) {
  pd::ControllerWatchParams p;
  p.enabled = false;
  pd::ControllerWatch watch(p, kControllers, {"f"});
  EXPECT_EQ(watch.start(0.0), "");
  EXPECT_FALSE(watch.watching());
  pd::ControllerWatchParams bad;
  bad.feed_following_tolerance_m = 0.0;
  EXPECT_THROW(pd::ControllerWatch(bad, kControllers, {"f"}), std::invalid_argument);
}
