/**
 * @file lockstep.cpp
 * @brief LockstepParticipant (lockstep.hpp).
 */
#include "pedicle_drilling/ros/lockstep.hpp"

#include <boost/make_shared.hpp>

#include <algorithm>
#include <chrono>
#include <future>
#include <memory>
#include <stdexcept>
#include <thread>
#include <utility>

#include "pedicle_drilling/StepAck.h"

namespace pedicle_drilling {

bool useSimLockstep() {
  XmlRpc::XmlRpcValue value;
  if (!ros::param::get("/use_sim_lockstep", value)) return false;
  if (value.getType() != XmlRpc::XmlRpcValue::TypeBoolean) {
    throw std::invalid_argument("/use_sim_lockstep: must be true or false");
  }
  return static_cast<bool>(value);
}

LockstepParticipant::LockstepParticipant(ros::NodeHandle nh, std::string node, StepFn on_step,
                                         bool deferred_first, NextStepFn next_step)
    : nh_(nh),
      enabled_(useSimLockstep()),
      deferred_first_(deferred_first),
      node_(std::move(node)),
      on_step_(std::move(on_step)),
      next_step_(std::move(next_step)) {
  if (!enabled_) return;
  ack_pub_ = nh_.advertise<StepAck>("simulator/step_ack", 10);
}

LockstepParticipant::~LockstepParticipant() { stop(); }

void LockstepParticipant::stop() {
  // roscpp's unsubscription waits for a callback of this subscription that another thread is
  // running (SubscriptionQueue::clear takes the lock its call holds) and drops the queued ones.
  // Before ack_pub_ goes: an unloaded recognizer's step answered on the participants' thread
  // while its publisher was destroyed aborted the nodelet manager (boost assertion `px != 0`
  // in roscpp's TopicManager::publish).
  step_sub_.shutdown();
}

namespace {

/** @brief A callback that says it ran (drain()). */
class RanCallback : public ros::CallbackInterface {
 public:
  explicit RanCallback(std::shared_ptr<std::promise<void>> ran) : ran_(std::move(ran)) {}
  CallResult call() override {
    ran_->set_value();
    return Success;
  }

 private:
  std::shared_ptr<std::promise<void>> ran_;
};

}  // namespace

void LockstepParticipant::drain() {
  if (shared_) drainSharedQueue();
}

void LockstepParticipant::drainSharedQueue() {
  auto ran = std::make_shared<std::promise<void>>();
  std::future<void> done = ran->get_future();
  // One thread serves the queue, in order: when this runs, whatever was queued before it (or
  // was running) has ended.
  sharedQueue()->addCallback(boost::make_shared<RanCallback>(ran));
  while (done.wait_for(std::chrono::milliseconds(100)) != std::future_status::ready) {
    if (ros::isShuttingDown()) return;  // the thread stops serving the queue
  }
}

void LockstepParticipant::start() {
  if (started_) throw std::logic_error("LockstepParticipant::start: called twice");
  started_ = true;
  if (!enabled_) return;
  step_sub_ = nh_.subscribe("simulator/step", 10, &LockstepParticipant::onStep, this,
                            ros::TransportHints().tcpNoDelay());
}

void LockstepParticipant::shareQueue(std::initializer_list<ros::NodeHandle*> handles) {
  if (started_) throw std::logic_error("LockstepParticipant::shareQueue: after start()");
  if (!enabled_) return;
  ros::CallbackQueue* queue = sharedQueue();
  shared_ = true;
  nh_.setCallbackQueue(queue);
  for (ros::NodeHandle* nh : handles) nh->setCallbackQueue(queue);
}

ros::CallbackQueue* LockstepParticipant::sharedQueue() {
  // Never destroyed: its detached thread serves it until ROS shuts down, and the nodelets that
  // registered on it may be unloaded in any order before then.
  static ros::CallbackQueue* const queue = [] {
    auto* q = new ros::CallbackQueue();
    std::thread([q] {
      while (!ros::isShuttingDown()) q->callAvailable(ros::WallDuration(0.1));
    }).detach();
    return q;
  }();
  return queue;
}

ros::Time LockstepParticipant::now() const {
  if (!enabled_) return ros::Time::now();
  std::lock_guard<std::mutex> lock(mutex_);
  return std::max(last_step_, last_seen_);
}

void LockstepParticipant::observe(const ros::Time& stamp) {
  if (!enabled_) return;
  std::lock_guard<std::mutex> lock(mutex_);
  last_seen_ = std::max(last_seen_, stamp);
}

void LockstepParticipant::deliver(const ros::Time& stamp, int rank, std::function<void()> handle) {
  if (!enabled_) {
    handle();
    return;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  deferred_.push_back({stamp, rank, seq_++, std::move(handle)});
}

void LockstepParticipant::noteSent() {
  if (!enabled_) return;
  std::lock_guard<std::mutex> lock(mutex_);
  sent_ = true;
}

void LockstepParticipant::onStep(const rosgraph_msgs::Clock::ConstPtr& msg) {
  const ros::Time t = msg->clock;
  std::vector<Deferred> due;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    last_step_ = std::max(last_step_, t);
    // Sent in an earlier step: everything sent then is here (the simulator waited for its
    // sender's answer before this step). What was sent in this step waits for the next one.
    const auto sent_before = [&t](const Deferred& d) { return d.stamp < t; };
    std::stable_partition(deferred_.begin(), deferred_.end(),
                          [&](const Deferred& d) { return !sent_before(d); });
    const auto first_due = std::find_if(deferred_.begin(), deferred_.end(), sent_before);
    due.assign(std::make_move_iterator(first_due), std::make_move_iterator(deferred_.end()));
    deferred_.erase(first_due, deferred_.end());
  }
  std::sort(due.begin(), due.end(), [](const Deferred& a, const Deferred& b) {
    if (a.stamp != b.stamp) return a.stamp < b.stamp;
    if (a.rank != b.rank) return a.rank < b.rank;
    return a.seq < b.seq;
  });
  if (!deferred_first_ && on_step_) on_step_(t);
  for (const Deferred& d : due) d.handle();
  if (deferred_first_ && on_step_) on_step_(t);
  StepAck ack;
  ack.stamp = t;
  ack.node = node_;
  // Zero: every step (no next-step function). Else the next step after what was sent in this
  // step (1 ns later: the simulator's first step after t), or the timers' next, or never.
  if (next_step_) {
    bool sent = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      std::swap(sent, sent_);
    }
    const std::optional<ros::Time> timer = next_step_(t);
    ack.next_step = sent ? t + ros::Duration(0, 1) : timer.value_or(ros::TIME_MAX);
  }
  publishInOrder(ack_pub_, ack);
}

}  // namespace pedicle_drilling
