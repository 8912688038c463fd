#include "pedicle_drilling/ros/in_order_updater.hpp"

#include <utility>

#include "pedicle_drilling/ros/publish_in_order.hpp"

namespace pedicle_drilling {

InOrderUpdater::InOrderUpdater(const ros::NodeHandle& nh, const ros::NodeHandle& pnh,
                               std::string name)
    : diagnostic_updater::Updater(nh, pnh, "/" + name), name_(std::move(name)) {
  setHardwareID(name_);
}

diagnostic_msgs::DiagnosticArray InOrderUpdater::collect(const ros::Time& stamp) {
  diagnostic_msgs::DiagnosticArray array;
  array.header.stamp = stamp;
  boost::mutex::scoped_lock lock(lock_);  // the Updater's: no task added meanwhile
  for (const DiagnosticTaskInternal& task : getTasks()) {
    diagnostic_updater::DiagnosticStatusWrapper status;
    status.level = diagnostic_msgs::DiagnosticStatus::ERROR;
    status.message = "No message was set";
    status.hardware_id = name_;
    task.run(status);
    status.name = name_ + ": " + task.getName();
    array.status.push_back(status);
  }
  return array;
}

InOrderDiagnostics::InOrderDiagnostics(ros::NodeHandle& nh, const ros::NodeHandle& pnh,
                                       const std::string& name,
                                       std::function<void()> on_subscriber) {
  pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 10,
      [on_subscriber](const ros::SingleSubscriberPublisher&) { on_subscriber(); },
      ros::SubscriberStatusCallback(), ros::VoidConstPtr(), true);
  updater_ = std::make_unique<InOrderUpdater>(nh, pnh, name);
}

diagnostic_updater::TopicDiagnostic& InOrderDiagnostics::addStream(const std::string& topic,
                                                                   double rate_hz,
                                                                   double tolerance) {
  rates_.push_back(rate_hz);
  double* rate = &rates_.back();
  streams_.push_back(std::make_unique<diagnostic_updater::TopicDiagnostic>(
      topic, *updater_, diagnostic_updater::FrequencyStatusParam(rate, rate, tolerance),
      diagnostic_updater::TimeStampStatusParam()));
  return *streams_.back();
}

void InOrderDiagnostics::publish(const ros::Time& stamp) {
  publishInOrder(pub_, updater_->collect(stamp));
}

}  // namespace pedicle_drilling
