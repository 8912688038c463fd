/**
 * @file force_plot_panel.cpp
 * @brief rviz panel `pedicle_drilling/ForcePlotPanel` (see force_plot_panel.hpp).
 */
#include "pedicle_drilling/rviz/force_plot_panel.hpp"

#include <QComboBox>
#include <QFontMetrics>
#include <QHBoxLayout>
#include <QLabel>
#include <QLineEdit>
#include <QPaintEvent>
#include <QPainter>
#include <QPainterPath>
#include <QTimer>
#include <QVBoxLayout>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <rviz/config.h>
#include <std_msgs/String.h>
#include <pluginlib/class_list_macros.hpp>

#include "pedicle_drilling/core/control/trial_view.hpp"

namespace pedicle_drilling {
namespace rviz_plugins {

/** @brief The chart: paints a core::ForceTrace over time or depth. */
class TraceChart : public QWidget {
 public:
  explicit TraceChart(QWidget* parent) : QWidget(parent) {
    setMinimumSize(260, 180);
    setSizePolicy(QSizePolicy::Expanding, QSizePolicy::Expanding);
  }

  core::ForceTrace trace;
  bool depth_axis = false;
  bool thrust_on = false;  // a wrench topic is set: the thrust's title
  double c1 = std::numeric_limits<double>::quiet_NaN();
  double c2 = std::numeric_limits<double>::quiet_NaN();
  double c3 = std::numeric_limits<double>::quiet_NaN();

 protected:
  void paintEvent(QPaintEvent* /*event*/) override {
    QPainter painter(this);
    painter.setRenderHint(QPainter::Antialiasing, true);
    painter.fillRect(rect(), QColor(28, 28, 32));
    const QFontMetrics fm(painter.font());
    row_h_ = fm.height();
    // Top: title row, then up to three rows of event labels.
    const double top = 4.0 + row_h_ * 4.0;
    plot_ = QRectF(48.0, top, std::max(10.0, width() - 96.0),
                   std::max(10.0, height() - top - row_h_ - 10.0));
    painter.setPen(QColor(90, 90, 96));
    painter.drawRect(plot_);
    drawTitle(&painter, fm);
    if (!scale()) {
      painter.setPen(QColor(170, 170, 170));
      painter.drawText(plot_, Qt::AlignCenter,
                       depth_axis ? "no depth: the depth axis needs simulator/ground_truth"
                                  : "no drilling_state or wrench received");
      return;
    }
    drawAxes(&painter);
    drawThresholds(&painter);
    drawEvents(&painter, fm);
    drawCurves(&painter);
  }

 private:
  const QColor force_colour_{80, 200, 255};
  const QColor feature_colour_{255, 170, 60};
  const QColor thrust_colour_{150, 220, 150};

  /** @brief x of a sample time: seconds since the contact, or the deepest cut in mm. */
  double xValue(double t) const { return depth_axis ? 1e3 * trace.depthAt(t) : t - t0_; }
  double xOf(double x) const {
    return plot_.left() + (x - x_min_) / (x_max_ - x_min_) * plot_.width();
  }
  double yForce(double f) const {
    return plot_.bottom() - std::clamp(f / force_max_, 0.0, 1.0) * plot_.height();
  }
  double yFeature(double a) const {
    return plot_.bottom() -
           std::clamp((a - feature_min_) / (feature_max_ - feature_min_), 0.0, 1.0) *
               plot_.height();
  }

  void drawTitle(QPainter* painter, const QFontMetrics& fm) const {
    painter->setPen(force_colour_);
    painter->drawText(QPointF(4.0, 2.0 + row_h_), "averaged force [N]");
    painter->setPen(feature_colour_);
    const double a_x = 4.0 + fm.horizontalAdvance("averaged force [N]  ");
    painter->drawText(QPointF(a_x, 2.0 + row_h_), "A*");
    double x_x = a_x + fm.horizontalAdvance("A*   ");
    if (thrust_on) {
      painter->setPen(thrust_colour_);
      const double th_x = a_x + fm.horizontalAdvance("A*  ");
      painter->drawText(QPointF(th_x, 2.0 + row_h_), "thrust [N]");
      x_x = th_x + fm.horizontalAdvance("thrust [N]   ");
    }
    painter->setPen(QColor(170, 170, 170));
    painter->drawText(QPointF(x_x, 2.0 + row_h_),
                      depth_axis ? "x: depth of the cut [mm]" : "x: time since contact [s]");
    painter->setPen(Qt::white);
    painter->drawText(QRectF(0.0, 2.0, width() - 4.0, row_h_ + 2.0), Qt::AlignRight,
                      QString::fromStdString(trace.stateName()));
  }

  /** @brief Before the contact: the first kept sample of either series. */
  double firstTime() const {
    double t = std::numeric_limits<double>::infinity();
    if (!trace.samples().empty()) t = trace.samples().front().t;
    if (!trace.thrust().empty()) t = std::min(t, trace.thrust().front().t);
    return std::isfinite(t) ? t : 0.0;
  }

  /** @brief The plotted points and the axes' ranges; false when there is nothing to plot. */
  bool scale() {
    t0_ = std::isnan(trace.contactTime()) ? firstTime() : trace.contactTime();
    points_.clear();
    for (const core::TraceSample& s : trace.samples()) {
      const double x = xValue(s.t);
      if (std::isfinite(x)) points_.emplace_back(x, &s);
    }
    thrust_points_.clear();
    for (const core::ThrustSample& s : trace.thrust()) {
      const double x = xValue(s.t);
      if (std::isfinite(x)) thrust_points_.emplace_back(x, s.thrust);
    }
    if (points_.empty() && thrust_points_.empty()) return false;
    x_min_ = x_max_ = points_.empty() ? thrust_points_.front().first : points_.front().first;
    force_max_ = 1.0;
    feature_max_ = 0.0;
    feature_min_ = 0.0;
    for (const auto& [x, s] : points_) {
      x_min_ = std::min(x_min_, x);
      x_max_ = std::max(x_max_, x);
      force_max_ = std::max(force_max_, s->force);
      feature_max_ = std::max(feature_max_, s->feature);
      feature_min_ = std::min(feature_min_, s->feature);
    }
    for (const auto& [x, thrust] : thrust_points_) {
      x_min_ = std::min(x_min_, x);
      x_max_ = std::max(x_max_, x);
      force_max_ = std::max(force_max_, thrust);
    }
    for (double c : {c1, c2}) {
      if (std::isfinite(c)) feature_max_ = std::max(feature_max_, c);
    }
    if (x_max_ - x_min_ < 1e-6) x_max_ = x_min_ + 1.0;
    force_max_ *= 1.1;
    feature_max_ = feature_max_ * 1.1 + 1e-12;
    return true;
  }

  /** @brief Force on the left, A* on the right, time or depth below. */
  void drawAxes(QPainter* painter) const {
    painter->setPen(force_colour_);
    for (int i = 0; i <= 4; ++i) {
      const double f = force_max_ * i / 4.0;
      painter->drawText(QRectF(0.0, yForce(f) - row_h_ / 2, 44.0, row_h_), Qt::AlignRight,
                        QString::number(f, 'f', 1));
    }
    painter->setPen(feature_colour_);
    for (int i = 0; i <= 4; ++i) {
      const double a = feature_min_ + (feature_max_ - feature_min_) * i / 4.0;
      painter->drawText(QRectF(plot_.right() + 4.0, yFeature(a) - row_h_ / 2, 44.0, row_h_),
                        Qt::AlignLeft, QString::number(a, 'f', 2));
    }
    painter->setPen(QColor(170, 170, 170));
    for (int i = 0; i <= 4; ++i) {
      const double x = x_min_ + (x_max_ - x_min_) * i / 4.0;
      painter->drawText(QRectF(xOf(x) - 40.0, plot_.bottom() + 2.0, 80.0, row_h_), Qt::AlignCenter,
                        QString::number(x, 'f', 1));
    }
  }

  /** @brief The recognizer's thresholds on A*: C1, C2 and, after key point 4, C3 x the peak. */
  void drawThresholds(QPainter* painter) const {
    std::vector<std::pair<double, QString>> lines;
    if (std::isfinite(c1)) lines.emplace_back(c1, "C1");
    if (std::isfinite(c2)) lines.emplace_back(c2, "C2");
    if (std::isfinite(c3) && std::isfinite(trace.innerPeak())) {
      lines.emplace_back(c3 * trace.innerPeak(), "C3 peak");
    }
    for (const auto& [value, label] : lines) {
      QPen pen(feature_colour_.darker(130));
      pen.setStyle(Qt::DotLine);
      painter->setPen(pen);
      painter->drawLine(QPointF(plot_.left(), yFeature(value)),
                        QPointF(plot_.right(), yFeature(value)));
      painter->drawText(QPointF(plot_.left() + 3.0, yFeature(value) - 2.0), label);
    }
  }

  /** @brief Key points and the stop: vertical lines, labels on rows that do not overlap. */
  void drawEvents(QPainter* painter, const QFontMetrics& fm) const {
    std::vector<core::ChartLabel> labels;
    std::vector<const core::TraceEvent*> shown;
    for (const core::TraceEvent& e : trace.events()) {
      const double x = xValue(e.t);
      if (!std::isfinite(x)) continue;
      labels.push_back(
          {xOf(x), static_cast<double>(fm.horizontalAdvance(QString::fromStdString(e.label)))});
      shown.push_back(&e);
    }
    const std::vector<int> rows = core::layoutLabels(labels, 4.0, 3);
    for (std::size_t i = 0; i < shown.size(); ++i) {
      const core::TraceEvent& e = *shown[i];
      const double x = labels[i].x;
      QPen pen(e.stop ? QColor(255, 60, 60) : QColor(200, 200, 200));
      pen.setStyle(e.stop ? Qt::SolidLine : Qt::DashLine);
      pen.setWidthF(e.stop ? 2.5 : 1.0);
      painter->setPen(pen);
      const double label_y = 4.0 + row_h_ * (rows[i] + 2);
      painter->drawLine(QPointF(x, label_y + 2.0), QPointF(x, plot_.bottom()));
      painter->drawText(QPointF(x - labels[i].width / 2.0, label_y),
                        QString::fromStdString(e.label));
    }
  }

  void drawCurves(QPainter* painter) const {
    QPainterPath thrust_path;
    for (std::size_t i = 0; i < thrust_points_.size(); ++i) {
      const QPointF p(xOf(thrust_points_[i].first), yForce(thrust_points_[i].second));
      if (i == 0) {
        thrust_path.moveTo(p);
      } else {
        thrust_path.lineTo(p);
      }
    }
    QPainterPath force_path;
    QPainterPath feature_path;
    bool first = true;
    for (const auto& [x, s] : points_) {
      const QPointF pf(xOf(x), yForce(s->force));
      const QPointF pa(xOf(x), yFeature(s->feature));
      if (first) {
        force_path.moveTo(pf);
        feature_path.moveTo(pa);
        first = false;
      } else {
        force_path.lineTo(pf);
        feature_path.lineTo(pa);
      }
    }
    painter->setClipRect(plot_);
    QColor thrust = thrust_colour_;
    thrust.setAlpha(170);  // under the averaged force: the raw stream is noisy
    painter->setPen(QPen(thrust, 1.0));
    painter->drawPath(thrust_path);
    painter->setPen(QPen(feature_colour_, 1.5));
    painter->drawPath(feature_path);
    painter->setPen(QPen(force_colour_, 2.0));
    painter->drawPath(force_path);
  }

  QRectF plot_;
  double row_h_ = 12.0;
  double t0_ = 0.0;
  double x_min_ = 0.0;
  double x_max_ = 1.0;
  double force_max_ = 1.0;
  double feature_min_ = 0.0;
  double feature_max_ = 1.0;
  std::vector<std::pair<double, const core::TraceSample*>> points_;
  std::vector<std::pair<double, double>> thrust_points_;  // (x, thrust [N])
};

ForcePlotPanel::ForcePlotPanel(QWidget* parent) : rviz::Panel(parent) {
  auto* layout = new QVBoxLayout(this);
  auto* controls = new QHBoxLayout();
  controls->addWidget(new QLabel("Topic:"));
  topic_edit_ = new QLineEdit("drilling_state");
  controls->addWidget(topic_edit_);
  controls->addWidget(new QLabel("X:"));
  axis_combo_ = new QComboBox();
  axis_combo_->addItems({"time", "depth"});
  controls->addWidget(axis_combo_);
  layout->addLayout(controls);
  auto* wrench = new QHBoxLayout();
  wrench->addWidget(new QLabel("Wrench (thrust):"));
  wrench_edit_ = new QLineEdit("");
  wrench_edit_->setToolTip(
      "geometry_msgs/WrenchStamped the recognizer reads (ft_sensor/wrench); its thrust is the "
      "component along the recognizer's ~axis. Empty (the default): no thrust curve.");
  wrench->addWidget(wrench_edit_);
  layout->addLayout(wrench);
  auto* thresholds = new QHBoxLayout();
  thresholds->addWidget(new QLabel("Recognizer node (C1, C2, C3):"));
  recognizer_edit_ = new QLineEdit("/state_recognizer");
  thresholds->addWidget(recognizer_edit_);
  layout->addLayout(thresholds);
  chart_ = new TraceChart(this);
  layout->addWidget(chart_, 1);
  status_label_ = new QLabel("no message yet");
  layout->addWidget(status_label_);
  timer_ = new QTimer(this);

  nh_.setCallbackQueue(&queue_);
  connect(topic_edit_, SIGNAL(editingFinished()), this, SLOT(onTopicEdited()));
  connect(wrench_edit_, SIGNAL(editingFinished()), this, SLOT(onTopicEdited()));
  connect(recognizer_edit_, SIGNAL(editingFinished()), this, SLOT(onTopicEdited()));
  connect(axis_combo_, SIGNAL(currentIndexChanged(int)), this, SLOT(onAxisChanged(int)));
  connect(timer_, SIGNAL(timeout()), this, SLOT(poll()));
}

ForcePlotPanel::~ForcePlotPanel() {
  timer_->stop();
  sub_.shutdown();
  wrench_sub_.shutdown();
  truth_sub_.shutdown();
  stop_sub_.shutdown();
}

void ForcePlotPanel::onInitialize() {
  status_pub_ = nh_.advertise<std_msgs::String>("force_plot/status", 1, true);
  subscribe(topic_edit_->text().toStdString());
  subscribeWrench();
  subscribeTruth();
  stop_sub_ = nh_.subscribe("drill/stop", 20, &ForcePlotPanel::stopCallback, this);
  publishStatus();
  timer_->start(50);
}

void ForcePlotPanel::load(const rviz::Config& config) {
  rviz::Panel::load(config);
  QString value;
  if (config.mapGetString("Topic", &value)) {
    topic_edit_->setText(value);
    subscribe(value.toStdString());
  }
  if (config.mapGetString("Wrench", &value)) {
    wrench_edit_->setText(value);
    subscribeWrench();
  }
  if (config.mapGetString("Ground truth", &value)) {
    truth_topic_ = value.toStdString();
    subscribeTruth();
  }
  if (config.mapGetString("Axis", &value)) {
    const int index = axis_combo_->findText(value);
    if (index >= 0) {
      axis_combo_->setCurrentIndex(index);
    } else {
      ROS_WARN("ForcePlotPanel: Axis '%s' is not time or depth; time kept",
               value.toStdString().c_str());
    }
  }
  if (config.mapGetString("Recognizer", &value)) recognizer_edit_->setText(value);
}

void ForcePlotPanel::save(rviz::Config config) const {
  rviz::Panel::save(config);
  config.mapSetValue("Topic", topic_edit_->text());
  config.mapSetValue("Wrench", wrench_edit_->text());
  config.mapSetValue("Ground truth", QString::fromStdString(truth_topic_));
  config.mapSetValue("Axis", axis_combo_->currentText());
  config.mapSetValue("Recognizer", recognizer_edit_->text());
}

void ForcePlotPanel::onTopicEdited() {
  subscribe(topic_edit_->text().toStdString());
  subscribeWrench();
  thresholds_read_ = ros::WallTime();
  Q_EMIT configChanged();
}

void ForcePlotPanel::onAxisChanged(int index) {
  chart_->depth_axis = index == 1;
  chart_->update();
  Q_EMIT configChanged();
}

void ForcePlotPanel::subscribe(const std::string& topic) {
  sub_.shutdown();
  received_ = false;
  chart_->trace.clear();
  if (topic.empty()) {
    status_label_->setText("no topic");
    return;
  }
  try {
    sub_ = nh_.subscribe(topic, 200, &ForcePlotPanel::stateCallback, this);
    status_label_->setText(QString::fromStdString("waiting for " + topic));
  } catch (const ros::Exception& e) {
    status_label_->setText(QString("cannot subscribe: ") + e.what());
  }
}

void ForcePlotPanel::subscribeWrench() {
  wrench_sub_.shutdown();
  thrust_received_ = false;
  last_thrust_t_ = -1.0;
  const std::string topic = wrench_edit_->text().toStdString();
  chart_->thrust_on = !topic.empty();
  if (topic.empty()) return;
  try {
    wrench_sub_ = nh_.subscribe(topic, 1000, &ForcePlotPanel::wrenchCallback, this);
  } catch (const ros::Exception& e) {
    status_label_->setText(QString("cannot subscribe to the wrench: ") + e.what());
  }
}

void ForcePlotPanel::subscribeTruth() {
  truth_sub_.shutdown();
  if (truth_topic_.empty()) return;
  try {
    truth_sub_ = nh_.subscribe(truth_topic_, 100, &ForcePlotPanel::truthCallback, this);
  } catch (const ros::Exception& e) {
    status_label_->setText(QString("cannot subscribe to the ground truth: ") + e.what());
  }
}

void ForcePlotPanel::readThresholds() {
  // The recognizer's own parameters (the paper recognizer's ~c1, ~c2, ~c3); another class has
  // none of these, and then no line is drawn.
  const std::string node = recognizer_edit_->text().toStdString();
  double value = 0.0;
  chart_->c1 = ros::param::getCached(node + "/c1", value) ? value : std::nan("");
  chart_->c2 = ros::param::getCached(node + "/c2", value) ? value : std::nan("");
  chart_->c3 = ros::param::getCached(node + "/c3", value) ? value : std::nan("");
  // The thrust is the wrench along the recognizer's ~axis; without it, the force's magnitude.
  std::string axis;
  if (!ros::param::getCached(node + "/axis", axis)) {
    axis.clear();
  } else if (axis != "x" && axis != "y" && axis != "z" && axis != "-x" && axis != "-y" &&
             axis != "-z") {
    ROS_WARN_ONCE(
        "ForcePlotPanel: parameter %s/axis is '%s', not x, y, z, -x, -y or -z: the "
        "thrust curve shows the force's magnitude",
        node.c_str(), axis.c_str());
    axis.clear();
  }
  thrust_axis_ = axis;
}

void ForcePlotPanel::wrenchCallback(const geometry_msgs::WrenchStamped::ConstPtr& msg) {
  const double t =
      msg->header.stamp.isZero() ? ros::Time::now().toSec() : msg->header.stamp.toSec();
  if (t >= last_thrust_t_ && t - last_thrust_t_ < 0.005) return;  // at most 200 samples/s
  last_thrust_t_ = t;
  const geometry_msgs::Vector3& f = msg->wrench.force;
  double thrust = std::sqrt(f.x * f.x + f.y * f.y + f.z * f.z);
  if (!thrust_axis_.empty()) {
    const char c = thrust_axis_.back();
    thrust = (thrust_axis_.front() == '-' ? -1.0 : 1.0) * (c == 'x' ? f.x : c == 'y' ? f.y : f.z);
  }
  chart_->trace.addThrust(t, thrust);
  thrust_received_ = true;
}

void ForcePlotPanel::publishStatus() {
  const std::string status =
      std::string("recognizer samples: ") + (chart_->trace.samples().empty() ? "no" : "yes") +
      "; thrust samples: " + (chart_->trace.thrust().empty() ? "no" : "yes") +
      "; ground truth: " + (truth_topic_.empty() ? std::string("off") : truth_topic_);
  if (status == last_status_ || !status_pub_) return;
  last_status_ = status;
  std_msgs::String msg;
  msg.data = status;
  status_pub_.publish(msg);
}

void ForcePlotPanel::stateCallback(const DrillingState::ConstPtr& msg) {
  const double t =
      msg->header.stamp.isZero() ? ros::Time::now().toSec() : msg->header.stamp.toSec();
  chart_->trace.add(t, msg->state_name, msg->last_key_point, msg->averaged_force, msg->feature,
                    msg->stop);
  received_ = true;
  last_message_ = ros::WallTime::now();
}

void ForcePlotPanel::truthCallback(const GroundTruth::ConstPtr& msg) {
  chart_->trace.addDepth(msg->header.stamp.toSec(), msg->max_depth_cut_m);
}

void ForcePlotPanel::stopCallback(const StopCommand::ConstPtr& msg) {
  const double t =
      msg->header.stamp.isZero() ? ros::Time::now().toSec() : msg->header.stamp.toSec();
  chart_->trace.addStop(t, msg->source);
}

void ForcePlotPanel::poll() {
  if (thresholds_read_.isZero() || (ros::WallTime::now() - thresholds_read_).toSec() > 5.0) {
    readThresholds();
    thresholds_read_ = ros::WallTime::now();
  }
  queue_.callAvailable();
  if (received_) {
    const double age = (ros::WallTime::now() - last_message_).toSec();
    status_label_->setText(age > 2.0 ? QString("last message %1 s ago").arg(age, 0, 'f', 1)
                                     : QString("receiving"));
  } else if (thrust_received_) {
    status_label_->setText(
        QString::fromStdString("thrust only: waiting for " + topic_edit_->text().toStdString()));
  }
  publishStatus();
  const bool stopped = chart_->trace.stopped();
  if (stopped && !logged_stop_) {
    for (const core::TraceEvent& e : chart_->trace.events()) {
      if (!e.stop) continue;
      ROS_INFO("ForcePlotPanel: stop marked (%s) at %.3f s after the contact (%zu key points)",
               e.label.c_str(), e.t - chart_->trace.contactTime(),
               chart_->trace.events().size() - 1);
    }
  }
  logged_stop_ = stopped;
  chart_->update();
}

}  // namespace rviz_plugins
}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::rviz_plugins::ForcePlotPanel, rviz::Panel)
