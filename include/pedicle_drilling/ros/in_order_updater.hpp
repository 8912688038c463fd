// A node's /diagnostics through diagnostic_updater's tasks, published by the node itself
// (publishInOrder), stamped with the node's time.
#ifndef PEDICLE_DRILLING_ROS_IN_ORDER_UPDATER_HPP_
#define PEDICLE_DRILLING_ROS_IN_ORDER_UPDATER_HPP_

#include <diagnostic_msgs/DiagnosticArray.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <diagnostic_updater/publisher.h>
#include <ros/ros.h>

#include <deque>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace pedicle_drilling {

/**
 * @brief diagnostic_updater::Updater's tasks (added as to any Updater, the TopicDiagnostics
 *        too), collected into one DiagnosticArray that the node publishes itself: in order
 *        (publishInOrder; the Updater publishes by value) and stamped with the node's time
 *        (the lockstep's step; the Updater stamps ros::Time::now(), the last /clock).
 */
class InOrderUpdater : public diagnostic_updater::Updater {
 public:
  /** @brief @p name: the nodelet's name, the statuses' prefix and hardware id. */
  InOrderUpdater(const ros::NodeHandle& nh, const ros::NodeHandle& pnh, std::string name);

  /** @brief Every task's status, named "<nodelet name>: <task>", as force_update() names it. */
  diagnostic_msgs::DiagnosticArray collect(const ros::Time& stamp);

 private:
  std::string name_;
};

/**
 * @brief A node's /diagnostics through an InOrderUpdater, published by publish() only (the
 *        Updater's own ~diagnostic_period is not used: update() is never called).
 *
 * The Updater's own publisher is neither latched nor told of new subscribers. roscpp keeps one
 * publication of /diagnostics per process, latched or not, and with the queue, as its first
 * advertiser says: advertised here first, latched, it keeps the process's /diagnostics latched
 * (failStartup()'s report relies on it too), so a late subscriber gets the latest status at
 * once; and a subscriber connecting also gets a fresh one (the constructor's callback).
 */
class InOrderDiagnostics {
 public:
  /**
   * @brief Advertises the latched /diagnostics, then makes the Updater (@p name: the
   *        nodelet's). @p on_subscriber runs for each new subscriber, on roscpp's thread,
   *        possibly before this constructor has returned.
   */
  InOrderDiagnostics(ros::NodeHandle& nh, const ros::NodeHandle& pnh, const std::string& name,
                     std::function<void()> on_subscriber);
  /** @brief The Updater, to add tasks to. */
  InOrderUpdater& updater() { return *updater_; }
  /** @brief A rate (@p rate_hz within @p tolerance) and stamp check of the stream on the
   *         resolved @p topic; tick() it on every message. */
  diagnostic_updater::TopicDiagnostic& addStream(const std::string& topic, double rate_hz,
                                                 double tolerance);
  /** @brief Every task's status, published in order (publishInOrder), stamped @p stamp. */
  void publish(const ros::Time& stamp);
  /** @brief No more connection callbacks. */
  void shutdown() { pub_.shutdown(); }

 private:
  ros::Publisher pub_;
  std::unique_ptr<InOrderUpdater> updater_;
  std::deque<double> rates_;  // the streams' checks read them through pointers
  std::vector<std::unique_ptr<diagnostic_updater::TopicDiagnostic>> streams_;
};

}  // namespace pedicle_drilling

#endif  // PEDICLE_DRILLING_ROS_IN_ORDER_UPDATER_HPP_
