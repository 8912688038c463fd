#include "pedicle_drilling/rviz/drilling_panel.hpp"

#include <pluginlib/class_list_macros.hpp>

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFont>
#include <QGridLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QPushButton>
#include <QSpinBox>
#include <QTimer>
#include <QVBoxLayout>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <vector>

#include <pedicle_drilling/ResetSimulation.h>
#include <pedicle_drilling/StartTrial.h>

namespace pedicle_drilling {
namespace rviz_plugins {

namespace {

Eigen::Vector3d toEigen(const geometry_msgs::Point& p) { return {p.x, p.y, p.z}; }

/** @brief The settings as the controls report names them. */
std::string settingsText(const core::PanelSettings& s) {
  char text[200];
  std::snprintf(text, sizeof(text), "settings: mode %s, profile %s, %.0f rpm, %.2f mm/s, seed %llu",
                s.mode.c_str(), s.segment_profile.empty() ? "planner's" : s.segment_profile.c_str(),
                s.spindle_rpm, s.feed_rate_mm_s, static_cast<unsigned long long>(s.seed));
  return text;
}

}  // namespace

DrillingPanel::DrillingPanel(QWidget* parent) : rviz::Panel(parent) {
  auto* layout = new QVBoxLayout(this);
  // Settings two to a row, the buttons beside the seed: the readouts must fit below.
  auto* form = new QGridLayout();
  mode_combo_ = new QComboBox();
  mode_combo_->addItems({"stationary", "uncompensated", "compensated"});
  form->addWidget(new QLabel("Case"), 0, 0);
  form->addWidget(mode_combo_, 0, 1);
  profile_combo_ = new QComboBox();
  profile_combo_->addItem("planner's", QString());
  profile_combo_->addItem("rest_to_rest", QString("rest_to_rest"));
  profile_combo_->addItem("exact", QString("exact"));
  form->addWidget(new QLabel("Profile"), 0, 2);
  form->addWidget(profile_combo_, 0, 3);
  rpm_spin_ = new QDoubleSpinBox();
  rpm_spin_->setRange(1000.0, 60000.0);
  rpm_spin_->setDecimals(0);
  rpm_spin_->setSingleStep(1000.0);
  rpm_spin_->setSuffix(" rpm");
  form->addWidget(new QLabel("Spindle"), 1, 0);
  form->addWidget(rpm_spin_, 1, 1);
  feed_spin_ = new QDoubleSpinBox();
  feed_spin_->setRange(0.05, 10.0);
  feed_spin_->setDecimals(2);
  feed_spin_->setSingleStep(0.05);
  feed_spin_->setSuffix(" mm/s");
  form->addWidget(new QLabel("Feed"), 1, 2);
  form->addWidget(feed_spin_, 1, 3);
  seed_spin_ = new QSpinBox();
  seed_spin_->setRange(0, std::numeric_limits<int>::max());
  form->addWidget(new QLabel("Seed"), 2, 0);
  form->addWidget(seed_spin_, 2, 1);
  auto* buttons = new QHBoxLayout();
  start_button_ = new QPushButton("Start");
  stop_button_ = new QPushButton("Stop");
  reset_button_ = new QPushButton("Reset");
  buttons->addWidget(start_button_);
  buttons->addWidget(stop_button_);
  buttons->addWidget(reset_button_);
  form->addLayout(buttons, 2, 2, 1, 2);
  layout->addLayout(form);
  verdict_label_ = new QLabel();
  QFont big = verdict_label_->font();
  big.setPointSizeF(big.pointSizeF() * 1.4);
  big.setBold(true);
  verdict_label_->setFont(big);
  verdict_label_->setWordWrap(true);
  layout->addWidget(verdict_label_);
  service_label_ = new QLabel();
  service_label_->setWordWrap(true);
  layout->addWidget(service_label_);
  call_label_ = new QLabel();
  call_label_->setWordWrap(true);
  layout->addWidget(call_label_);

  auto* grid = new QGridLayout();
  grid->setVerticalSpacing(1);
  for (int i = 0; i < 9; ++i) {
    readout_labels_[i] = new QLabel();
    readout_values_[i] = new QLabel();
    readout_values_[i]->setWordWrap(true);
    grid->addWidget(readout_labels_[i], i, 0, Qt::AlignTop);
    grid->addWidget(readout_values_[i], i, 1);
  }
  grid->setColumnStretch(1, 1);
  layout->addLayout(grid);
  layout->addStretch(1);

  applySettings(core::PanelSettings());
  timer_ = new QTimer(this);
  nh_.setCallbackQueue(&queue_);
  connect(start_button_, SIGNAL(clicked()), this, SLOT(onStart()));
  connect(stop_button_, SIGNAL(clicked()), this, SLOT(onStop()));
  connect(reset_button_, SIGNAL(clicked()), this, SLOT(onReset()));
  connect(mode_combo_, SIGNAL(currentIndexChanged(int)), this, SLOT(onSettingsChanged()));
  connect(profile_combo_, SIGNAL(currentIndexChanged(int)), this, SLOT(onSettingsChanged()));
  connect(rpm_spin_, SIGNAL(valueChanged(double)), this, SLOT(onSettingsChanged()));
  connect(feed_spin_, SIGNAL(valueChanged(double)), this, SLOT(onSettingsChanged()));
  connect(seed_spin_, SIGNAL(valueChanged(int)), this, SLOT(onSettingsChanged()));
  connect(timer_, SIGNAL(timeout()), this, SLOT(poll()));
  refreshControls();
  refreshReadouts();
}

DrillingPanel::~DrillingPanel() {
  quit_ = true;
  timer_->stop();
  if (watcher_.joinable()) watcher_.join();
  if (call_thread_.joinable()) call_thread_.join();
  for (ros::Subscriber& s : subs_) s.shutdown();
  truth_sub_.shutdown();
  wrench_sub_.shutdown();
}

void DrillingPanel::onInitialize() {
  subs_.push_back(nh_.subscribe("compensation/status", 20, &DrillingPanel::statusCallback, this));
  subs_.push_back(nh_.subscribe("drilling_state", 100, &DrillingPanel::stateCallback, this));
  subs_.push_back(nh_.subscribe("drill/stop", 20, &DrillingPanel::stopCallback, this));
  subs_.push_back(nh_.subscribe("compensation/predicted_marker_pose", 50,
                                &DrillingPanel::predictedCallback, this));
  subs_.push_back(nh_.subscribe("tracker/marker_pose", 50, &DrillingPanel::trackedCallback, this));
  subscribeInputs();
  subs_.push_back(nh_.subscribe("/diagnostics", 20, &DrillingPanel::diagnosticsCallback, this));
  subs_.push_back(nh_.subscribe("drilling_panel/press", 10, &DrillingPanel::pressCallback, this));
  stop_pub_ = nh_.advertise<StopCommand>("drill/stop", 10);
  summary_pub_ = nh_.advertise<std_msgs::String>("drilling_panel/summary", 1, true);
  controls_pub_ = nh_.advertise<std_msgs::String>("drilling_panel/controls", 1, true);
  watcher_ = std::thread([this]() { watchServices(); });
  timer_->start(50);
}

void DrillingPanel::subscribeInputs() {
  truth_sub_.shutdown();
  wrench_sub_.shutdown();
  try {
    if (!truth_topic_.empty()) {
      truth_sub_ = nh_.subscribe(truth_topic_, 100, &DrillingPanel::truthCallback, this);
    }
    // The force at 1 kHz: only the newest few matter for the readout.
    if (!wrench_topic_.empty()) {
      wrench_sub_ = nh_.subscribe(wrench_topic_, 5, &DrillingPanel::wrenchCallback, this);
    }
  } catch (const ros::Exception& e) {
    ROS_ERROR("DrillingPanel: cannot subscribe to the inputs (Ground truth '%s', Wrench '%s'): %s",
              truth_topic_.c_str(), wrench_topic_.c_str(), e.what());
  }
}

core::PanelSettings DrillingPanel::settings() const {
  core::PanelSettings s;
  s.mode = mode_combo_->currentText().toStdString();
  s.segment_profile = profile_combo_->currentData().toString().toStdString();
  s.spindle_rpm = rpm_spin_->value();
  s.feed_rate_mm_s = feed_spin_->value();
  s.seed = static_cast<std::uint64_t>(seed_spin_->value());
  return s;
}

void DrillingPanel::applySettings(const core::PanelSettings& s) {
  mode_combo_->setCurrentText(QString::fromStdString(s.mode));
  profile_combo_->setCurrentIndex(
      std::max(0, profile_combo_->findData(QString::fromStdString(s.segment_profile))));
  rpm_spin_->setValue(s.spindle_rpm);
  feed_spin_->setValue(s.feed_rate_mm_s);
  seed_spin_->setValue(static_cast<int>(
      std::min<std::uint64_t>(s.seed, static_cast<std::uint64_t>(seed_spin_->maximum()))));
}

void DrillingPanel::load(const rviz::Config& config) {
  rviz::Panel::load(config);
  std::map<std::string, std::string> saved;
  for (const char* key : {"Mode", "Profile", "Rpm", "Feed", "Seed"}) {
    QString value;
    if (config.mapGetString(key, &value)) saved[key] = value.toStdString();
  }
  std::vector<std::string> problems;
  applySettings(core::PanelSettings::fromConfig(saved, &problems));
  for (const std::string& p : problems) ROS_WARN("DrillingPanel: configuration: %s", p.c_str());
  QString topic;
  const bool truth = config.mapGetString("Ground truth", &topic);
  if (truth) truth_topic_ = topic.toStdString();
  const bool wrench = config.mapGetString("Wrench", &topic);
  if (wrench) wrench_topic_ = topic.toStdString();
  if (truth || wrench) subscribeInputs();
}

void DrillingPanel::save(rviz::Config config) const {
  rviz::Panel::save(config);
  for (const auto& [key, value] : settings().toConfig()) {
    config.mapSetValue(QString::fromStdString(key), QString::fromStdString(value));
  }
  config.mapSetValue("Ground truth", QString::fromStdString(truth_topic_));
  config.mapSetValue("Wrench", QString::fromStdString(wrench_topic_));
}

void DrillingPanel::onSettingsChanged() { Q_EMIT configChanged(); }

void DrillingPanel::onStart() { runCall(false); }

void DrillingPanel::onReset() { runCall(true); }

void DrillingPanel::onStop() {
  StopCommand stop;
  stop.header.stamp = ros::Time::now();
  stop.source = "/rviz/drilling_panel";
  stop.reason = "operator stop (DrillingPanel)";
  stop.retreat = true;
  stop_pub_.publish(stop);
  call_label_->setText("stop sent: spindle off, retreat");
}

void DrillingPanel::runCall(bool reset_only) {
  if (call_busy_) return;
  const core::PanelSettings s = settings();
  try {
    s.validate();
  } catch (const std::invalid_argument& e) {
    call_label_->setText(QString("not started: ") + e.what());
    return;
  }
  if (call_thread_.joinable()) call_thread_.join();
  call_busy_ = true;
  call_label_->setText(reset_only ? "resetting the simulator ..." : "starting a trial ...");
  refreshControls();
  const bool can_reset = reset_available_;
  if (reset_only) view_.reset();
  call_thread_ = std::thread([this, s, reset_only, can_reset]() {
    std::string result;
    // On the simulator the specimen and patient of the seed are mounted first (the bone held
    // still for the stationary case); on hardware there is no simulator/reset to call.
    if (can_reset) {
      ResetSimulation reset;
      reset.request.seed = s.seed;
      reset.request.moving_bone = s.mode != "stationary";
      if (!ros::service::call(reset_service_, reset)) {
        result = reset_service_ + " failed (service gone?)";
      } else if (!reset.response.success) {
        result = "simulator reset refused: " + reset.response.message;
      } else {
        result = "simulator reset: seed " + std::to_string(s.seed);
      }
    }
    if (!reset_only && (result.empty() || result.rfind("simulator reset:", 0) == 0)) {
      StartTrial start;
      start.request.mode = s.mode;
      start.request.spindle_rpm = s.spindle_rpm;
      start.request.feed_rate_mm_s = s.feed_rate_mm_s;
      start.request.max_duration_s = 0.0;
      start.request.segment_profile = s.segment_profile;
      if (!ros::service::call(start_service_, start)) {
        result = start_service_ + " failed (service gone?)";
      } else {
        result = (start.response.success ? "started: " : "refused: ") + start.response.message;
      }
    }
    std::lock_guard<std::mutex> lock(call_mutex_);
    call_result_ = result;
    call_result_new_ = true;
    call_busy_ = false;
  });
}

void DrillingPanel::watchServices() {
  while (!quit_) {
    start_available_ = ros::service::exists(start_service_, false);
    reset_available_ = ros::service::exists(reset_service_, false);
    for (int i = 0; i < 10 && !quit_; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
}

void DrillingPanel::refreshControls() {
  const bool running = view_.phase() != "" && !view_.ended() && view_.phase() != "idle";
  start_button_->setEnabled(start_available_ && !call_busy_ && !running);
  reset_button_->setEnabled(reset_available_ && !call_busy_ && !running);
  stop_button_->setEnabled(running);
  QString why;
  if (!start_available_) {
    why = QString::fromStdString(
        start_service_ + " is not available: start drilling_pipeline.launch or demo.launch");
  } else if (!reset_available_) {
    why = QString::fromStdString(reset_service_ +
                                 " is not available (hardware): Reset is off, the seed unused");
  } else if (running) {
    why = "a trial is running";
  }
  service_label_->setText(why);
  const std::string controls =
      std::string("start ") + (start_button_->isEnabled() ? "enabled" : "disabled") + ", stop " +
      (stop_button_->isEnabled() ? "enabled" : "disabled") + ", reset " +
      (reset_button_->isEnabled() ? "enabled" : "disabled") +
      (why.isEmpty() ? "" : ": " + why.toStdString()) + "; " + settingsText(settings());
  if (controls != last_controls_ && controls_pub_) {
    last_controls_ = controls;
    std_msgs::String msg;
    msg.data = controls;
    controls_pub_.publish(msg);
  }
}

void DrillingPanel::refreshReadouts() {
  const std::vector<core::Readout> readouts = view_.readouts();
  for (std::size_t i = 0; i < 9; ++i) {
    if (i >= readouts.size()) {
      readout_labels_[i]->clear();
      readout_values_[i]->clear();
      continue;
    }
    const core::Readout& r = readouts[i];
    readout_labels_[i]->setText(QString::fromStdString(r.label));
    readout_values_[i]->setText(QString::fromStdString(r.value));
    QString style = r.alarm ? "color: #ff4040;" : "";
    if (r.label == "verdict" && view_.verdict() == core::TrialVerdict::kSuccess) {
      style = "color: #40d040; font-weight: bold;";
    } else if (r.label == "verdict" && r.alarm) {
      style += " font-weight: bold;";
    }
    readout_values_[i]->setStyleSheet(style);
  }
  // The banner: the verdict with the residual, or the phase while running.
  const core::TrialVerdict verdict = view_.verdict();
  std::string banner = view_.phase().empty() ? "no trial" : view_.phase();
  if (verdict == core::TrialVerdict::kSuccess || verdict == core::TrialVerdict::kFailure) {
    banner = verdict == core::TrialVerdict::kSuccess ? "SUCCESS" : "FAILURE";
    const auto residual =
        std::find_if(readouts.begin(), readouts.end(),
                     [](const core::Readout& r) { return r.label == "residual"; });
    if (residual != readouts.end()) banner += ", residual " + residual->value;
  }
  verdict_label_->setText(QString::fromStdString(banner));
  verdict_label_->setStyleSheet(verdict == core::TrialVerdict::kSuccess   ? "color: #40d040;"
                                : verdict == core::TrialVerdict::kFailure ? "color: #ff4040;"
                                                                          : "");
  const std::string summary = view_.summary();
  if (summary != last_summary_) {
    last_summary_ = summary;
    std_msgs::String msg;
    msg.data = summary;
    summary_pub_.publish(msg);
    if (view_.ended()) ROS_INFO("DrillingPanel: %s", summary.c_str());
  }
}

void DrillingPanel::poll() {
  queue_.callAvailable();
  {
    std::lock_guard<std::mutex> lock(call_mutex_);
    if (call_result_new_) {
      call_label_->setText(QString::fromStdString(call_result_));
      call_result_new_ = false;
    }
  }
  refreshControls();
  refreshReadouts();
}

void DrillingPanel::statusCallback(const TrialStatus::ConstPtr& msg) {
  view_.onPhase(msg->phase_name, msg->running);
}

void DrillingPanel::stateCallback(const DrillingState::ConstPtr& msg) {
  view_.onRecognizer(msg->state_name, msg->last_key_point, msg->averaged_force, msg->feature,
                     msg->stop);
}

void DrillingPanel::stopCallback(const StopCommand::ConstPtr& msg) {
  view_.onStop(msg->source, msg->reason, msg->retreat);
}

void DrillingPanel::truthCallback(const GroundTruth::ConstPtr& msg) {
  view_.onGroundTruth(msg->max_depth_cut_m, msg->inner_cortical_start_m, msg->inner_cortical_end_m,
                      msg->residual_inner_cortical_m, msg->breakthrough);
}

void DrillingPanel::predictedCallback(const geometry_msgs::PoseStamped::ConstPtr& msg) {
  view_.onPredictedMarker(msg->header.stamp.toSec(), toEigen(msg->pose.position));
}

void DrillingPanel::trackedCallback(const geometry_msgs::PoseStamped::ConstPtr& msg) {
  view_.onTrackedMarker(msg->header.stamp.toSec(), toEigen(msg->pose.position));
}

void DrillingPanel::wrenchCallback(const geometry_msgs::WrenchStamped::ConstPtr& msg) {
  const geometry_msgs::Vector3& f = msg->wrench.force;
  view_.onForce(std::sqrt(f.x * f.x + f.y * f.y + f.z * f.z));
}

void DrillingPanel::diagnosticsCallback(const diagnostic_msgs::DiagnosticArray::ConstPtr& msg) {
  for (const diagnostic_msgs::DiagnosticStatus& s : msg->status) {
    if (s.name == monitor_status_name_) view_.onMonitorStatus(s.level, s.message);
  }
}

void DrillingPanel::pressCallback(const std_msgs::String::ConstPtr& msg) {
  // The button itself is clicked: a greyed-out button ignores it, as it ignores the mouse.
  if (msg->data == "start") {
    start_button_->click();
  } else if (msg->data == "stop") {
    stop_button_->click();
  } else if (msg->data == "reset") {
    reset_button_->click();
  } else {
    ROS_WARN("DrillingPanel: drilling_panel/press '%s' is not start, stop or reset",
             msg->data.c_str());
  }
}

}  // namespace rviz_plugins
}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::rviz_plugins::DrillingPanel, rviz::Panel)
