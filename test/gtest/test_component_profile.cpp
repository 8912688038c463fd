/**
 * @file test_component_profile.cpp
 * @brief core::ComponentProfile: laps and scoped timers add to their component, off
 *        (no profile) they do nothing; a profiled simulation times its components, Bullet's
 *        world step inside the arm's, and steps exactly as an unprofiled one.
 */
#include <gtest/gtest.h>

#include <chrono>
#include <set>
#include <string>
#include <thread>

#include "pedicle_drilling/core/common/component_profile.hpp"
#include "pedicle_drilling/core/sim/drilling_simulation.hpp"
#include "support.hpp"

namespace pedicle_drilling::core {
namespace {

TEST(ComponentProfile, LapsAndScopesAddToTheirComponentAndNothingWhenOff) {
  ComponentProfile profile;
  {
    ComponentLaps laps(&profile);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
    laps.mark(Component::kPlatform);
    const ScopedComponentTimer timer(&profile, Component::kArmStep);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_GE(profile.seconds(Component::kPlatform), 0.002);
  EXPECT_GE(profile.seconds(Component::kArmStep), 0.002);
  EXPECT_EQ(profile.seconds(Component::kDrilling), 0.0);
  profile.addTrial(30.0);
  profile.addTrial(12.5);
  EXPECT_EQ(profile.trials(), 2u);
  EXPECT_DOUBLE_EQ(profile.simSeconds(), 42.5);
  // Off: no profile, nothing recorded anywhere (and no clock read).
  ComponentLaps off(nullptr);
  off.mark(Component::kPlatform);
  const ScopedComponentTimer none(nullptr, Component::kPlatform);
  std::set<std::string> names;
  for (int c = 0; c < static_cast<int>(Component::kCount); ++c) {
    names.insert(ComponentProfile::name(static_cast<Component>(c)));
  }
  EXPECT_EQ(names.size(), static_cast<std::size_t>(Component::kCount)) << "a name each";
}

TEST(ComponentProfile, AProfiledSimulationTimesItsComponentsAndStepsTheSame) {
  DrillingSimulationParams params;
  DrillingSimulation plain(test::workcellUrdf(), params, 3);
  DrillingSimulation profiled(test::workcellUrdf(), params, 3);
  plain.reset(3, true);
  profiled.reset(3, true);
  ComponentProfile profile;
  profiled.setProfile(&profile);
  for (int k = 0; k < 500; ++k) {
    const SimulationStep a = plain.stepOnce();
    const SimulationStep b = profiled.stepOnce();
    ASSERT_EQ(a.time_s, b.time_s);
    ASSERT_EQ(a.tip_depth_m, b.tip_depth_m) << "step " << k;
    ASSERT_EQ(a.force_sampled, b.force_sampled);
    ASSERT_EQ(a.measured_wrench, b.measured_wrench) << "step " << k;
  }
  for (Component c : {Component::kArmStep, Component::kBulletWorld, Component::kArmControllers,
                      Component::kPlatform, Component::kDrilling, Component::kSensor}) {
    EXPECT_GT(profile.seconds(c), 0.0) << ComponentProfile::name(c);
  }
  EXPECT_LT(profile.seconds(Component::kBulletWorld), profile.seconds(Component::kArmStep));
  const double before = profile.seconds(Component::kArmStep);
  profiled.setProfile(nullptr);
  profiled.stepOnce();
  EXPECT_EQ(profile.seconds(Component::kArmStep), before) << "off again";
}

}  // namespace
}  // namespace pedicle_drilling::core
