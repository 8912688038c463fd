/**
 * @file lockstep.hpp
 * @brief The simulator's lockstep (doc/running.md, "Lockstep"): with the global parameter
 *        /use_sim_lockstep true, the Simulator publishes `simulator/step` (rosgraph_msgs/Clock)
 *        after a physics step's messages and steps again only when every participant has
 *        answered it (at every step a participant can act at: see below) on `simulator/step_ack`
 * (pedicle_drilling/StepAck). A participant's step callback runs after the step's simulator
 * messages (one nodelet manager: its callback queue is FIFO, and every nodelet publishes shared
 * messages, which roscpp queues in publishing order: publishInOrder()), so sim time never runs
 * ahead of the nodes, and a loaded machine changes wall time, not the trial: the pipeline's trial
 * of a seed is the core engine's.
 *
 * What a participant receives from another participant (a stop, a recognizer state, a predicted
 * pose) is handled at the first step after the one it was sent in (deliver()), in stamp order,
 * whichever thread delivered it first: the engine's 1 ms transport, the same in every run.
 *
 * Fewer synchronised steps: each answer says the next step the participant must see
 * for itself (StepAck.next_step: its next timer, or the very next step when it published
 * something, noteSent()); the simulator steps everyone at those steps and at every step that
 * publishes one of its streams, and runs the steps in between without waiting. A step a
 * participant does not see is one at which it would have done nothing.
 */
#pragma once

#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>

#include "pedicle_drilling/ros/publish_in_order.hpp"

#include <algorithm>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace pedicle_drilling {

/**
 * @brief Reads /use_sim_lockstep (bool, default false).
 * @throws std::invalid_argument naming the parameter when it is set to something else.
 */
bool useSimLockstep();

/** @brief A node's side of the lockstep; inert (wall or /clock time) when it is off. */
class LockstepParticipant {
 public:
  /** @brief Called at each step with its sim time, before the deferred messages due then. */
  using StepFn = std::function<void(const ros::Time& t)>;
  /**
   * @brief After the step at `t`: the earliest later step the participant's own timers need
   *        (nullopt: none pending). Called on the step's thread, after the step's callbacks.
   */
  using NextStepFn = std::function<std::optional<ros::Time>(const ros::Time& t)>;

  /**
   * @brief Advertises `simulator/step_ack` when /use_sim_lockstep; start() subscribes the steps.
   * @param node the name in the answers (the nodelet's name).
   * @param deferred_first handle the messages sent in earlier steps before @p on_step (the
   *        engine's order for the safety monitor: a predicted pose, then the step's check);
   *        false: after it (the planner's: the step's timers, then the stops delivered).
   * @param next_step the next step its timers need; empty: the participant needs every step.
   */
  LockstepParticipant(ros::NodeHandle nh, std::string node, StepFn on_step,
                      bool deferred_first = false, NextStepFn next_step = nullptr);

  /** @brief stop(): a step running on another thread ends before the members go. */
  ~LockstepParticipant();
  LockstepParticipant(const LockstepParticipant&) = delete;
  LockstepParticipant& operator=(const LockstepParticipant&) = delete;

  /**
   * @brief Stops hearing the steps. Waits for a step being handled on another thread (the
   *        participants' thread, when a nodelet is unloaded from a running manager) to end,
   *        answer included (roscpp's unsubscription waits for the subscription's callback); no
   *        step callback, deferred message or answer runs after it. A nodelet whose step
   *        callback uses its own members calls it first in its destructor. Idempotent. Once ROS
   *        is shutting down, roscpp no longer waits.
   */
  void stop();

  /**
   * @brief After shareQueue(): waits until the participants' thread has run (or dropped)
   *        everything queued before this call. roscpp does not wait for a service or timer
   *        callback that is already running when the service is shut down or the timer stopped
   *        (since 1.15.10 it only marks them), and the nodelet manager does not hold a nodelet
   *        for callbacks on this queue: a destructor shuts its services, timers and connection
   *        callbacks, then calls this, then lets its members go. Returns at once without
   *        shareQueue() and when ROS is shutting down (the thread then stops).
   */
  void drain();

  /**
   * @brief Waits until the participants' thread has run (or dropped) everything queued on
   *        sharedQueue() before this call; drain() of a participant that shares it. For a nodelet
   *        that puts callbacks on sharedQueue() without being a participant (the FaultInjector's
   *        relays). Returns at once when ROS is shutting down.
   */
  static void drainSharedQueue();

  /**
   * @brief Subscribes `simulator/step` on the constructor's node handle's queue (the nodelet's:
   *        FIFO with its other subscriptions), when the lockstep is on. Called last in onInit,
   *        once everything @p on_step and @p next_step touch exists: the nodelet manager
   *        (nodelet 1.10.2) runs a nodelet's callbacks while its onInit still runs, and the
   *        simulator steps before its participants are loaded. Once; a second call throws
   *        std::logic_error.
   */
  void start();
  /**
   * @brief Under the lockstep, puts this participant's steps and every callback of @p handles
   *        (its subscriptions, services and connection callbacks; call it before anything is
   *        registered on them) on the process's participants' queue (sharedQueue()): one
   *        thread runs the callbacks of every participant that shares it, in the order they
   *        arrived, so that a synchronised step passes from one participant to the next
   *        without a thread switch. Each participant's callbacks stay in their
   *        order, and what one sends another is handled at the next step (deliver()), so the
   *        trial is the same as on the nodelet manager's threads. Nothing without the lockstep:
   *        on hardware each nodelet keeps its own queue (a slow planner never delays the
   *        monitor). A callback on it must not wait for another callback on it (a service of a
   *        participant is called from elsewhere: the planner's start_trial thread). Before
   *        start(); throws std::logic_error after it.
   */
  void shareQueue(std::initializer_list<ros::NodeHandle*> handles);
  /**
   * @brief The participants' queue of this process, and the one thread that serves it (made
   *        at the first call; it runs until ROS shuts down).
   */
  static ros::CallbackQueue* sharedQueue();

  /** @brief Whether the lockstep is on. */
  bool enabled() const { return enabled_; }

  /**
   * @brief A NextStepFn's answer for something due at @p due_s [s]: 1 us early, so that the
   *        step at the due time is asked for whatever its rounding (the steps' grid is 1 ms).
   */
  static ros::Time stepFor(double due_s) { return ros::Time(std::max(0.0, due_s - 1e-6)); }

  /**
   * @brief The node's clock: under the lockstep the latest step or simulator stamp it has
   *        handled (so the step's messages see the step's time before its step callback); else
   *        ros::Time::now().
   */
  ros::Time now() const;

  /** @brief A simulator message stamped @p stamp is being handled (its step is now). */
  void observe(const ros::Time& stamp);

  /**
   * @brief A message from another participant: without the lockstep, @p handle runs now; under
   *        it, at the first step later than @p stamp (the sender's step), with the other such
   *        messages in (stamp, rank, arrival) order.
   * @param rank orders messages of the same stamp from different publishers (lower first).
   */
  void deliver(const ros::Time& stamp, int rank, std::function<void()> handle);

  /**
   * @brief The node published something another participant handles at the next step: this
   *        step's answer asks for the very next step (call it at every such publication).
   */
  void noteSent();

 private:
  struct Deferred {
    ros::Time stamp;
    int rank;
    std::uint64_t seq;
    std::function<void()> handle;
  };
  void onStep(const rosgraph_msgs::Clock::ConstPtr& msg);

  ros::NodeHandle nh_;
  bool started_ = false;
  bool enabled_ = false;
  bool shared_ = false;  ///< shareQueue() put the callbacks on the participants' queue
  bool deferred_first_ = false;
  std::string node_;
  StepFn on_step_;
  NextStepFn next_step_;
  bool sent_ = false;  ///< published since the last answer
  mutable std::mutex mutex_;
  ros::Time last_step_;
  ros::Time last_seen_;
  std::vector<Deferred> deferred_;
  std::uint64_t seq_ = 0;
  ros::Subscriber step_sub_;
  ros::Publisher ack_pub_;
};

}  // namespace pedicle_drilling
