/**
 * @file test_lockstep_participant.cpp
 * @brief LockstepParticipant subscribes the simulator's steps in start(), not in its
 *        constructor, and shareQueue() runs them and the inputs it is given on the participants'
 *        thread (rostest lockstep_participant.test, /use_sim_lockstep true).
 */
#include <gtest/gtest.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>

#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

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

// shareQueue(): the participant's steps and the callbacks of the handles it is given run on
// the process's participants' thread, without anyone serving their own queue, one after the
// other in arrival order; refused after start().
TEST(LockstepParticipant, SharedQueueRunsTheStepsAndTheInputsOnItsThread) {
  ros::NodeHandle nh("shared");
  ros::NodeHandle inputs_nh("shared");
  ros::CallbackQueue unserved;  // nobody serves it: what runs, runs on the shared thread
  nh.setCallbackQueue(&unserved);
  inputs_nh.setCallbackQueue(&unserved);
  std::mutex mutex;
  std::vector<std::string> order;
  std::set<std::thread::id> threads;
  const auto note = [&](const std::string& what) {
    std::lock_guard<std::mutex> lock(mutex);
    order.push_back(what);
    threads.insert(std::this_thread::get_id());
  };
  LockstepParticipant participant(nh, "shared_participant",
                                  [&](const ros::Time&) { note("step"); });
  participant.shareQueue({&inputs_nh});
  ros::Subscriber input_sub = inputs_nh.subscribe<rosgraph_msgs::Clock>(
      "input", 10, [&](const rosgraph_msgs::Clock::ConstPtr&) { note("input"); });
  participant.start();
  EXPECT_THROW(participant.shareQueue({&inputs_nh}), std::logic_error);
  ros::NodeHandle pub_nh("shared");
  ros::CallbackQueue pub_queue;
  pub_nh.setCallbackQueue(&pub_queue);
  ros::Publisher step_pub = pub_nh.advertise<rosgraph_msgs::Clock>("simulator/step", 10);
  ros::Publisher input_pub = pub_nh.advertise<rosgraph_msgs::Clock>("input", 10);
  ASSERT_TRUE(serveUntil(&pub_queue, [&] {
    return step_pub.getNumSubscribers() == 1u && input_pub.getNumSubscribers() == 1u;
  }));
  // Shared messages, as the nodelets publish them (in order, inside publish()).
  auto msg = boost::make_shared<rosgraph_msgs::Clock>();
  msg->clock = ros::Time(3.0);
  input_pub.publish(msg);
  step_pub.publish(msg);
  const auto done = [&] {
    std::lock_guard<std::mutex> lock(mutex);
    return order.size() == 2;
  };
  ASSERT_TRUE(serveUntil(&pub_queue, done));
  std::lock_guard<std::mutex> lock(mutex);
  EXPECT_EQ(order, (std::vector<std::string>{"input", "step"}));
  ASSERT_EQ(threads.size(), 1u);
  EXPECT_NE(*threads.begin(), std::this_thread::get_id());
  EXPECT_TRUE(unserved.isEmpty());
}

// stop() (and so the destructor: a nodelet unloaded from a running manager) waits for a step
// that the participants' thread is handling and lets it answer: before, the answer's publisher
// went while the step still ran, and the manager aborted (the unloaded-recognizer fault).
TEST(LockstepParticipant, DestroyedDuringAStepTheStepEndsAndAnswers) {
  ros::NodeHandle nh("stopping");
  ros::CallbackQueue unserved;
  nh.setCallbackQueue(&unserved);
  std::mutex mutex;
  std::condition_variable cv;
  bool entered = false, destroying = false, destroyed = false, destroyed_during_step = true;
  auto participant = std::make_unique<LockstepParticipant>(nh, "stopping", [&](const ros::Time&) {
    std::unique_lock<std::mutex> lock(mutex);
    entered = true;
    cv.notify_all();
    cv.wait(lock, [&] { return destroying; });
    // The destructor has begun; it must not end before this step (and its answer) has. A bound
    // on the wait, not a pace: the outcome below does not depend on it when stop() is right.
    cv.wait_for(lock, std::chrono::milliseconds(500), [&] { return destroyed; });
    destroyed_during_step = destroyed;
  });
  participant->shareQueue({});
  participant->start();
  ros::NodeHandle pub_nh("stopping");
  ros::CallbackQueue pub_queue;
  pub_nh.setCallbackQueue(&pub_queue);
  ros::Publisher step_pub = pub_nh.advertise<rosgraph_msgs::Clock>("simulator/step", 10);
  int acks = 0;
  ros::Subscriber ack_sub = pub_nh.subscribe<StepAck>(
      "simulator/step_ack", 10, [&acks](const StepAck::ConstPtr&) { ++acks; });
  ASSERT_TRUE(serveUntil(&pub_queue, [&] {
    return step_pub.getNumSubscribers() == 1u && ack_sub.getNumPublishers() == 1u;
  }));
  auto msg = boost::make_shared<rosgraph_msgs::Clock>();
  msg->clock = ros::Time(4.0);
  step_pub.publish(msg);
  {
    std::unique_lock<std::mutex> lock(mutex);
    const bool in_step = cv.wait_for(lock, std::chrono::seconds(60), [&] { return entered; });
    if (!in_step) destroying = destroyed = true;  // a step arriving later passes through
    ASSERT_TRUE(in_step);
  }
  std::thread destroyer([&] {
    {
      std::lock_guard<std::mutex> lock(mutex);
      destroying = true;
    }
    cv.notify_all();
    participant.reset();
    std::lock_guard<std::mutex> lock(mutex);
    destroyed = true;
    cv.notify_all();
  });
  destroyer.join();
  EXPECT_FALSE(destroyed_during_step);
  EXPECT_TRUE(serveUntil(&pub_queue, [&] { return acks == 1; })) << acks << " answers";
  // Stopped: later steps are not heard.
  EXPECT_TRUE(serveUntil(&pub_queue, [&] { return step_pub.getNumSubscribers() == 0u; }));
}

// drain(): roscpp does not wait for a service or timer callback already running when it is shut
// down, so a destructor waits for the participants' thread to get past it before the members
// go. A callback blocked on the shared thread keeps drain() from returning until it ends.
TEST(LockstepParticipant, DrainWaitsForWhatTheSharedThreadIsRunning) {
  ros::NodeHandle nh("draining");
  ros::NodeHandle inputs_nh("draining");
  ros::CallbackQueue unserved;
  nh.setCallbackQueue(&unserved);
  inputs_nh.setCallbackQueue(&unserved);
  std::mutex mutex;
  std::condition_variable cv;
  bool entered = false, released = false, finished = false, drained = false;
  LockstepParticipant participant(nh, "draining", nullptr);
  participant.shareQueue({&inputs_nh});
  ros::Subscriber input_sub = inputs_nh.subscribe<rosgraph_msgs::Clock>(
      "input", 10, [&](const rosgraph_msgs::Clock::ConstPtr&) {
        std::unique_lock<std::mutex> lock(mutex);
        entered = true;
        cv.notify_all();
        cv.wait(lock, [&] { return released; });
        finished = true;
      });
  participant.start();
  ros::NodeHandle pub_nh("draining");
  ros::CallbackQueue pub_queue;
  pub_nh.setCallbackQueue(&pub_queue);
  ros::Publisher input_pub = pub_nh.advertise<rosgraph_msgs::Clock>("input", 10);
  ASSERT_TRUE(serveUntil(&pub_queue, [&] { return input_pub.getNumSubscribers() == 1u; }));
  input_pub.publish(boost::make_shared<rosgraph_msgs::Clock>());
  {
    std::unique_lock<std::mutex> lock(mutex);
    const bool in_callback = cv.wait_for(lock, std::chrono::seconds(60), [&] { return entered; });
    if (!in_callback) released = true;  // never leave the shared thread blocked
    ASSERT_TRUE(in_callback);
  }
  std::thread drainer([&] {
    participant.drain();
    std::lock_guard<std::mutex> lock(mutex);
    drained = true;
    cv.notify_all();
  });
  {
    std::unique_lock<std::mutex> lock(mutex);
    // A bound, not a pace: with a drain that waits, nothing below depends on it.
    cv.wait_for(lock, std::chrono::milliseconds(300), [&] { return drained; });
    EXPECT_FALSE(drained) << "drain() returned while the shared thread ran a callback";
    released = true;
    cv.notify_all();
  }
  drainer.join();
  std::lock_guard<std::mutex> lock(mutex);
  EXPECT_TRUE(drained);
  EXPECT_TRUE(finished);
}

}  // namespace
}  // namespace pedicle_drilling

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_lockstep_participant");
  ros::NodeHandle keep;  // the node lives for the whole test
  return RUN_ALL_TESTS();
}
