/**
 * @file drilling_panel.hpp
 * @brief rviz panel `pedicle_drilling/DrillingPanel`: choose the case, the
 *        compensation profile, the spindle speed, the feed rate and the specimen seed; start,
 *        stop and reset a trial through the planner's and the simulator's services; watch the
 *        trial's phase, the recognizer, the force and A*, predicted vs tracked bone (H1), the
 *        force (H2), the safety monitor and the stop; at the end the residual and the verdict.
 *
 * The logic is core::PanelSettings and core::TrialView (no Qt); this class only wires widgets
 * and ROS. Service calls run on a worker thread: a missing or slow service greys the controls out
 * with the reason and never blocks rviz. Scripting hook: a std_msgs/String "start", "stop" or
 * "reset" on `drilling_panel/press` clicks that button (nothing happens when it is greyed out).
 * The panel publishes its one-line summary, latched, on `drilling_panel/summary`, and which
 * buttons are enabled with the reason of the others, latched, on `drilling_panel/controls`.
 *
 * Its inputs are configurable: "Ground truth" (the simulator's, for the residual and the
 * verdict; empty on hardware: not subscribed, the residual reads "(no ground truth)") and
 * "Wrench" (the force readout; the F/T stream the pipeline reads).
 */
#pragma once

#ifndef Q_MOC_RUN
#include <atomic>
#include <mutex>
#include <string>
#include <thread>

#include <ros/callback_queue.h>
#include <ros/ros.h>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/WrenchStamped.h>
#include <pedicle_drilling/DrillingState.h>
#include <pedicle_drilling/GroundTruth.h>
#include <pedicle_drilling/StopCommand.h>
#include <pedicle_drilling/TrialStatus.h>
#include <rviz/panel.h>
#include <std_msgs/String.h>

#include "pedicle_drilling/core/control/trial_view.hpp"
#endif

class QComboBox;
class QDoubleSpinBox;
class QLabel;
class QPushButton;
class QSpinBox;
class QTimer;

namespace pedicle_drilling {
namespace rviz_plugins {

/** @brief Drives and watches one drilling trial. */
class DrillingPanel : public rviz::Panel {
  Q_OBJECT

 public:
  /** @brief Builds the widgets; subscribes in onInitialize(). */
  explicit DrillingPanel(QWidget* parent = nullptr);
  /** @brief Joins the worker threads. */
  ~DrillingPanel() override;

  /** @brief Subscribes, starts the service watcher and the refresh timer. */
  void onInitialize() override;
  /** @brief Restores the settings (Mode, Profile, Rpm, Feed, Seed) and the inputs (Ground
   *         truth, Wrench: topics, empty = not subscribed). */
  void load(const rviz::Config& config) override;
  /** @brief Stores the settings and the inputs. */
  void save(rviz::Config config) const override;

 private Q_SLOTS:
  void onStart();
  void onStop();
  void onReset();
  void onSettingsChanged();
  void poll();

 private:
  core::PanelSettings settings() const;
  void applySettings(const core::PanelSettings& s);
  void runCall(bool reset_only);
  void watchServices();
  void refreshControls();
  void refreshReadouts();

  void statusCallback(const TrialStatus::ConstPtr& msg);
  void stateCallback(const DrillingState::ConstPtr& msg);
  void stopCallback(const StopCommand::ConstPtr& msg);
  void truthCallback(const GroundTruth::ConstPtr& msg);
  void predictedCallback(const geometry_msgs::PoseStamped::ConstPtr& msg);
  void trackedCallback(const geometry_msgs::PoseStamped::ConstPtr& msg);
  void wrenchCallback(const geometry_msgs::WrenchStamped::ConstPtr& msg);
  void diagnosticsCallback(const diagnostic_msgs::DiagnosticArray::ConstPtr& msg);
  void pressCallback(const std_msgs::String::ConstPtr& msg);

  QComboBox* mode_combo_;
  QComboBox* profile_combo_;
  QDoubleSpinBox* rpm_spin_;
  QDoubleSpinBox* feed_spin_;
  QSpinBox* seed_spin_;
  QPushButton* start_button_;
  QPushButton* stop_button_;
  QPushButton* reset_button_;
  QLabel* verdict_label_;
  QLabel* service_label_;
  QLabel* call_label_;
  QLabel* readout_labels_[9];
  QLabel* readout_values_[9];
  QTimer* timer_;

  ros::CallbackQueue queue_;
  ros::NodeHandle nh_;
  std::vector<ros::Subscriber> subs_;
  void subscribeInputs();
  ros::Subscriber truth_sub_;
  ros::Subscriber wrench_sub_;
  std::string truth_topic_ = "simulator/ground_truth";  // "" = none (hardware)
  std::string wrench_topic_ = "ft_sensor/wrench";       // "" = none
  ros::Publisher stop_pub_;
  ros::Publisher summary_pub_;
  ros::Publisher controls_pub_;
  std::string last_controls_;
  std::string start_service_ = "compensation_planner/start_trial";
  std::string reset_service_ = "simulator/reset";
  std::string monitor_status_name_ = "/safety_monitor: monitor";

  core::TrialView view_;
  std::string last_summary_;

  // Service watcher and calls (worker threads); the GUI reads these in poll().
  std::thread watcher_;
  std::atomic<bool> quit_{false};
  std::atomic<bool> start_available_{false};
  std::atomic<bool> reset_available_{false};
  std::thread call_thread_;
  std::atomic<bool> call_busy_{false};
  std::mutex call_mutex_;
  std::string call_result_;  // under call_mutex_; shown once
  bool call_result_new_ = false;
};

}  // namespace rviz_plugins
}  // namespace pedicle_drilling
