/**
 * @file force_plot_panel.hpp
 * @brief rviz panel `pedicle_drilling/ForcePlotPanel`: the recognizer's averaged force and
 *        feature A* from `drilling_state` and the F/T sensor's thrust ("Wrench", empty by
 *        default: the wrench the recognizer reads, along its `~axis`) over the trial (from the bone
 * contact to the stop), against time since the contact or the depth of the deepest cut (simulator
 *        ground truth, optional: "Ground truth" empty on hardware), with the thresholds C1, C2
 *        and C3 x the inner peak drawn, the key points labelled without overlap and the stop
 *        marked. The record is core::ForceTrace. Each input works alone.
 *
 * What it has is published latched on `force_plot/status` (std_msgs/String) at every change,
 * for scripts and tests: "recognizer samples: yes|no; thrust samples: yes|no; ground truth:
 * TOPIC|off".
 */
#pragma once

#ifndef Q_MOC_RUN
#include <ros/callback_queue.h>
#include <ros/ros.h>

#include <geometry_msgs/WrenchStamped.h>
#include <pedicle_drilling/DrillingState.h>
#include <pedicle_drilling/GroundTruth.h>
#include <pedicle_drilling/StopCommand.h>
#include <rviz/panel.h>
#endif

class QComboBox;
class QLabel;
class QLineEdit;
class QTimer;

namespace pedicle_drilling {
namespace rviz_plugins {

class TraceChart;

/** @brief Chart of pedicle_drilling/DrillingState over one trial. */
class ForcePlotPanel : public rviz::Panel {
  Q_OBJECT

 public:
  /** @brief Builds the widgets; subscribes in onInitialize(). */
  explicit ForcePlotPanel(QWidget* parent = nullptr);
  ~ForcePlotPanel() override;

  /** @brief Subscribes the configured topic and starts polling its callback queue. */
  void onInitialize() override;
  /** @brief Restores "Topic", "Wrench", "Ground truth", "Axis" and "Recognizer" from the rviz
   *         configuration (an empty "Wrench" or "Ground truth": not subscribed). */
  void load(const rviz::Config& config) override;
  /** @brief Stores "Topic", "Wrench", "Ground truth", "Axis" and "Recognizer". */
  void save(rviz::Config config) const override;

 private Q_SLOTS:
  void onTopicEdited();
  void onAxisChanged(int index);
  void poll();

 private:
  void subscribe(const std::string& topic);
  void subscribeWrench();
  void subscribeTruth();
  void readThresholds();
  void publishStatus();
  void stateCallback(const DrillingState::ConstPtr& msg);
  void wrenchCallback(const geometry_msgs::WrenchStamped::ConstPtr& msg);
  void truthCallback(const GroundTruth::ConstPtr& msg);
  void stopCallback(const StopCommand::ConstPtr& msg);

  TraceChart* chart_;
  QLineEdit* topic_edit_;
  QLineEdit* wrench_edit_;
  QComboBox* axis_combo_;
  QLineEdit* recognizer_edit_;
  QLabel* status_label_;
  QTimer* timer_;
  ros::CallbackQueue queue_;
  ros::NodeHandle nh_;
  ros::Subscriber sub_;
  ros::Subscriber wrench_sub_;
  ros::Subscriber truth_sub_;
  ros::Publisher status_pub_;
  std::string truth_topic_ = "simulator/ground_truth";  // "" = no depth axis (hardware)
  std::string thrust_axis_;      // the recognizer's ~axis (x, -z, ...); "" = the magnitude
  std::string last_status_;      // the last published force_plot/status
  double last_thrust_t_ = -1.0;  // decimation of the wrench stream (at most 200 samples/s)
  bool thrust_received_ = false;
  ros::Subscriber stop_sub_;
  ros::WallTime last_message_;
  ros::WallTime thresholds_read_;
  bool received_ = false;
  bool logged_stop_ = false;
};

}  // namespace rviz_plugins
}  // namespace pedicle_drilling
