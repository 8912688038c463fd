/**
 * @file force_plot_panel.hpp
 * @brief rviz panel `pedicle_drilling/ForcePlotPanel`: a strip chart of the recognizer's
 *        averaged force and feature A* from `drilling_state` over the last N seconds, with the
 *        key points and the stop marked.
 */
#pragma once

#ifndef Q_MOC_RUN
#include <ros/callback_queue.h>
#include <ros/ros.h>

#include <pedicle_drilling/DrillingState.h>
#include <rviz/panel.h>
#endif

class QDoubleSpinBox;
class QLabel;
class QLineEdit;
class QTimer;

namespace pedicle_drilling {
namespace rviz_plugins {

class StripChart;

/** @brief Strip chart of pedicle_drilling/DrillingState (averaged force, A*, key points). */
class ForcePlotPanel : public rviz::Panel {
  Q_OBJECT

 public:
  /** @brief Builds the widgets; subscribes in onInitialize(). */
  explicit ForcePlotPanel(QWidget* parent = nullptr);
  ~ForcePlotPanel() override;

  /** @brief Subscribes the configured topic and starts polling its callback queue. */
  void onInitialize() override;
  /** @brief Restores "Topic" and "Window" from the rviz configuration. */
  void load(const rviz::Config& config) override;
  /** @brief Stores "Topic" and "Window" in the rviz configuration. */
  void save(rviz::Config config) const override;

 private Q_SLOTS:
  void onTopicEdited();
  void onWindowChanged(double seconds);
  void poll();

 private:
  void subscribe(const std::string& topic);
  void stateCallback(const DrillingState::ConstPtr& msg);

  StripChart* chart_;
  QLineEdit* topic_edit_;
  QDoubleSpinBox* window_spin_;
  QLabel* status_label_;
  QTimer* timer_;
  ros::CallbackQueue queue_;
  ros::NodeHandle nh_;
  ros::Subscriber sub_;
  ros::WallTime last_message_;
  bool received_ = false;
};

}  // namespace rviz_plugins
}  // namespace pedicle_drilling
