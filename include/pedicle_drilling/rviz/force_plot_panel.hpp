/**
 * @file force_plot_panel.hpp
 * @brief rviz panel `pedicle_drilling/ForcePlotPanel`: the recognizer's averaged force and
 *        feature A* from `drilling_state` over the trial (from the bone contact to the stop),
 *        against time since the contact or the depth of the deepest cut (simulator ground
 *        truth), with the thresholds C1, C2 and C3 x the inner peak drawn, the key points
 *        labelled without overlap and the stop marked. The record is core::ForceTrace.
 */
#pragma once

#ifndef Q_MOC_RUN
#include <ros/callback_queue.h>
#include <ros/ros.h>

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
  /** @brief Restores "Topic", "Axis" and "Recognizer" from the rviz configuration. */
  void load(const rviz::Config& config) override;
  /** @brief Stores "Topic", "Axis" and "Recognizer" in the rviz configuration. */
  void save(rviz::Config config) const override;

 private Q_SLOTS:
  void onTopicEdited();
  void onAxisChanged(int index);
  void poll();

 private:
  void subscribe(const std::string& topic);
  void readThresholds();
  void stateCallback(const DrillingState::ConstPtr& msg);
  void truthCallback(const GroundTruth::ConstPtr& msg);
  void stopCallback(const StopCommand::ConstPtr& msg);

  TraceChart* chart_;
  QLineEdit* topic_edit_;
  QComboBox* axis_combo_;
  QLineEdit* recognizer_edit_;
  QLabel* status_label_;
  QTimer* timer_;
  ros::CallbackQueue queue_;
  ros::NodeHandle nh_;
  ros::Subscriber sub_;
  ros::Subscriber truth_sub_;
  ros::Subscriber stop_sub_;
  ros::WallTime last_message_;
  ros::WallTime thresholds_read_;
  bool received_ = false;
  bool logged_stop_ = false;
};

}  // namespace rviz_plugins
}  // namespace pedicle_drilling
