/**
 * @file test_lockstep_participant.cpp
 * @brief LockstepParticipant subscribes the simulator's steps in start(), not in its
 *        constructor (rostest lockstep_participant.test, /use_sim_lockstep true).
 */
#include <gtest/gtest.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>

#include <chrono>
#include <functional>
#include <stdexcept>
#include <thread>

#include "pedicle_drilling/StepAck.h"
#include "pedicle_drilling/ros/lockstep.hpp"

namespace pedicle_drilling {
namespace {

/** @brief Serves @p queue until @p done, at most 60 s of wall time (a bound, not a pace). */
bool serveUntil(ros::CallbackQueue* queue, const std::function<bool()>& done) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!done() && std::chrono::steady_clock::now() < deadline && ros::ok()) {
    queue->callAvailable(ros::WallDuration(0.05));
  }
  return done();
}

TEST(LockstepParticipant, HearsTheStepsOnlyFromStart) {
  ros::NodeHandle nh;
  ros::CallbackQueue queue;
  nh.setCallbackQueue(&queue);
  ros::Publisher step_pub = nh.advertise<rosgraph_msgs::Clock>("simulator/step", 10);
  int acks = 0;
  ros::Subscriber ack_sub = nh.subscribe<StepAck>("simulator/step_ack", 10,
                                                  [&acks](const StepAck::ConstPtr&) { ++acks; });
  int steps = 0;
  LockstepParticipant participant(nh, "participant", [&steps](const ros::Time&) { ++steps; });
  ASSERT_TRUE(participant.enabled());
  // Constructed: nothing hears the steps yet, whatever the simulator publishes.
  EXPECT_EQ(step_pub.getNumSubscribers(), 0u);
  rosgraph_msgs::Clock step;
  step.clock = ros::Time(1.0);
  step_pub.publish(step);
  queue.callAvailable(ros::WallDuration(0.2));
  EXPECT_EQ(steps, 0);
  participant.start();
  ASSERT_TRUE(serveUntil(&queue, [&] { return step_pub.getNumSubscribers() == 1u; }));
  ASSERT_TRUE(serveUntil(&queue, [&] { return ack_sub.getNumPublishers() == 1u; }));
  step.clock = ros::Time(2.0);
  step_pub.publish(step);
  EXPECT_TRUE(serveUntil(&queue, [&] { return steps == 1 && acks == 1; }))
      << steps << " steps, " << acks << " answers";
  EXPECT_THROW(participant.start(), std::logic_error);
}

}  // namespace
}  // namespace pedicle_drilling

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_lockstep_participant");
  ros::NodeHandle keep;  // the node lives for the whole test
  return RUN_ALL_TESTS();
}
