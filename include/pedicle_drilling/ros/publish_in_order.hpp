/**
 * @file publish_in_order.hpp
 * @brief publishInOrder(): how every nodelet of this package publishes.
 */
#pragma once

#include <ros/ros.h>

#include <boost/make_shared.hpp>
#include <utility>

namespace pedicle_drilling {

/**
 * @brief Publishes @p msg as a shared message. roscpp hands a shared message to the subscribers
 *        in this process (one nodelet manager's) inside publish(), in publishing order, without a
 *        copy. A message published by value is serialized and sent by roscpp's publish thread
 *        instead, and can reach a subscriber in this process after a message published later on
 *        another topic (a step, or a participant's answer to it): the lockstep's order (a step's
 *        messages before the step; what a participant sent before its answer) needs this one.
 *        Subscribers in other processes receive it as before.
 */
template <class M>
void publishInOrder(const ros::Publisher& pub, M msg) {
  pub.publish(boost::make_shared<M>(std::move(msg)));
}

}  // namespace pedicle_drilling
