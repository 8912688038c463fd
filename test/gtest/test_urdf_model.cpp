// urdfdom's parse kept for the description parsed last (a campaign builds a simulation
// per trial from one description).
#include <gtest/gtest.h>

#include <atomic>
#include <string>
#include <thread>
#include <vector>

#include "pedicle_drilling/core/robot/urdf_model.hpp"
#include "support.hpp"

namespace pedicle_drilling::core {
namespace {

std::string tinyRobot(const std::string& name) {
  return "<robot name=\"" + name +
         "\"><link name=\"a\"/><link name=\"b\"/>"
         "<joint name=\"j\" type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/>"
         "<axis xyz=\"0 0 1\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/>"
         "</joint></robot>";
}

TEST(UrdfModel, TheSameTextGivesTheSameModelAnotherTextItsOwn) {
  const auto first = parseUrdfKept(tinyRobot("one"));
  ASSERT_TRUE(first);
  EXPECT_EQ(first->getName(), "one");
  EXPECT_TRUE(first->getJoint("j"));
  EXPECT_EQ(parseUrdfKept(tinyRobot("one")).get(), first.get());  // kept: not parsed again
  const auto second = parseUrdfKept(tinyRobot("two"));
  ASSERT_TRUE(second);
  EXPECT_NE(second.get(), first.get());
  EXPECT_EQ(second->getName(), "two");
  EXPECT_EQ(first->getName(), "one");  // a caller's model is not changed by a later parse
}

TEST(UrdfModel, AMalformedTextIsNullAndKeepsTheLastModel) {
  const auto good = parseUrdfKept(tinyRobot("good"));
  ASSERT_TRUE(good);
  EXPECT_FALSE(parseUrdfKept("<robot name=\"broken\"><link name=\"a\"></robot"));
  EXPECT_FALSE(parseUrdfKept(""));
  EXPECT_EQ(parseUrdfKept(tinyRobot("good")).get(), good.get());
}

// Nodelets in one manager reset their simulations from several threads: each caller gets the
// model of its own text.
TEST(UrdfModel, CallersOnSeveralThreadsEachGetTheirOwnTextsModel) {
  std::vector<std::thread> threads;
  std::atomic<int> wrong{0};
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([t, &wrong] {
      const std::string name = "robot" + std::to_string(t % 2);
      for (int i = 0; i < 50; ++i) {
        const auto model = parseUrdfKept(tinyRobot(name));
        if (!model || model->getName() != name) ++wrong;
      }
    });
  }
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(wrong.load(), 0);
}

TEST(UrdfModel, TheWorkcellParses) {
  const auto model = parseUrdfKept(test::workcellUrdf());
  ASSERT_TRUE(model);
  EXPECT_TRUE(model->getJoint("spindle_joint"));
  EXPECT_TRUE(model->getJoint("spms_platform_joint"));
}

}  // namespace
}  // namespace pedicle_drilling::core
