/**
 * @file force_plot_panel.cpp
 * @brief rviz panel `pedicle_drilling/ForcePlotPanel` (see force_plot_panel.hpp).
 */
#include "pedicle_drilling/rviz/force_plot_panel.hpp"

#include <QDoubleSpinBox>
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
#include <deque>
#include <limits>
#include <string>

#include <rviz/config.h>
#include <pluginlib/class_list_macros.hpp>

namespace pedicle_drilling {
namespace rviz_plugins {

/** @brief The chart itself: keeps the last `window` seconds of samples and paints them. */
class StripChart : public QWidget {
 public:
  explicit StripChart(QWidget* parent) : QWidget(parent) {
    setMinimumSize(240, 140);
    setSizePolicy(QSizePolicy::Expanding, QSizePolicy::Expanding);
  }

  /** @brief Appends one recognizer output; non-finite values are skipped (not plotted). */
  void add(double t, const DrillingState& msg) {
    if (!samples_.empty() && t < samples_.back().t) {
      samples_.clear();  // time went backwards (simulation reset, bag loop): start over
      events_.clear();
      last_key_point_ = 0;
      stopped_ = false;
    }
    if (msg.last_key_point != last_key_point_ && msg.last_key_point > 0) {
      events_.push_back({t, "K" + std::to_string(msg.last_key_point), false});
    }
    last_key_point_ = msg.last_key_point;
    if (msg.stop && !stopped_) {
      events_.push_back({t, "STOP", true});
    }
    stopped_ = msg.stop;
    if (std::isfinite(msg.averaged_force) && std::isfinite(msg.feature)) {
      samples_.push_back({t, msg.averaged_force, msg.feature});
    }
    state_name_ = msg.state_name;
    trim(t);
  }

  /** @brief Length of the visible window (s). */
  void setWindow(double seconds) {
    window_s_ = seconds;
    if (!samples_.empty()) {
      trim(samples_.back().t);
    }
    update();
  }

 protected:
  void paintEvent(QPaintEvent* /*event*/) override {
    QPainter painter(this);
    painter.setRenderHint(QPainter::Antialiasing, true);
    painter.fillRect(rect(), QColor(28, 28, 32));
    const QRectF plot(46.0, 22.0, std::max(10.0, width() - 92.0), std::max(10.0, height() - 44.0));
    painter.setPen(QColor(90, 90, 96));
    painter.drawRect(plot);

    const QColor force_colour(80, 200, 255);
    const QColor feature_colour(255, 170, 60);
    painter.setPen(force_colour);
    painter.drawText(QPointF(plot.left(), 15.0), "averaged force [N]");
    painter.setPen(feature_colour);
    painter.drawText(QPointF(plot.left() + 130.0, 15.0), "A*");
    painter.setPen(Qt::white);
    painter.drawText(QRectF(plot.left(), 2.0, plot.width(), 18.0), Qt::AlignRight,
                     QString::fromStdString(state_name_));
    if (samples_.empty()) {
      painter.setPen(QColor(170, 170, 170));
      painter.drawText(plot, Qt::AlignCenter, "no drilling_state received");
      return;
    }

    const double t_end = samples_.back().t;
    const double t_start = t_end - window_s_;
    double force_max = 1.0;
    double feature_min = std::numeric_limits<double>::infinity();
    double feature_max = -std::numeric_limits<double>::infinity();
    for (const Sample& s : samples_) {
      force_max = std::max(force_max, s.force);
      feature_min = std::min(feature_min, s.feature);
      feature_max = std::max(feature_max, s.feature);
    }
    force_max *= 1.1;
    if (feature_max - feature_min < 1e-9) {
      feature_min -= 0.5;
      feature_max += 0.5;
    }
    auto x_of = [&](double t) { return plot.left() + (t - t_start) / window_s_ * plot.width(); };
    auto y_force = [&](double f) {
      return plot.bottom() - std::clamp(f / force_max, 0.0, 1.0) * plot.height();
    };
    auto y_feature = [&](double a) {
      return plot.bottom() - (a - feature_min) / (feature_max - feature_min) * plot.height();
    };

    // Axes labels: force on the left, A* on the right, time relative to the newest sample.
    painter.setPen(force_colour);
    for (int i = 0; i <= 4; ++i) {
      const double f = force_max * i / 4.0;
      painter.drawText(QRectF(0.0, y_force(f) - 8.0, 42.0, 16.0), Qt::AlignRight,
                       QString::number(f, 'f', 1));
    }
    painter.setPen(feature_colour);
    for (int i = 0; i <= 4; ++i) {
      const double a = feature_min + (feature_max - feature_min) * i / 4.0;
      painter.drawText(QRectF(plot.right() + 4.0, y_feature(a) - 8.0, 44.0, 16.0), Qt::AlignLeft,
                       QString::number(a, 'g', 3));
    }
    painter.setPen(QColor(170, 170, 170));
    for (int i = 0; i <= 4; ++i) {
      const double t = t_start + window_s_ * i / 4.0;
      painter.drawText(QRectF(x_of(t) - 30.0, plot.bottom() + 2.0, 60.0, 16.0), Qt::AlignCenter,
                       QString::number(t - t_end, 'f', 1) + " s");
    }

    // Key points and the stop as vertical lines.
    for (const Event& e : events_) {
      if (e.t < t_start) {
        continue;
      }
      QPen pen(e.stop ? QColor(255, 60, 60) : QColor(200, 200, 200));
      pen.setStyle(e.stop ? Qt::SolidLine : Qt::DashLine);
      pen.setWidthF(e.stop ? 2.0 : 1.0);
      painter.setPen(pen);
      painter.drawLine(QPointF(x_of(e.t), plot.top()), QPointF(x_of(e.t), plot.bottom()));
      painter.drawText(QPointF(x_of(e.t) + 3.0, plot.top() + 12.0),
                       QString::fromStdString(e.label));
    }

    QPainterPath force_path;
    QPainterPath feature_path;
    bool first = true;
    for (const Sample& s : samples_) {
      const QPointF pf(x_of(s.t), y_force(s.force));
      const QPointF pa(x_of(s.t), y_feature(s.feature));
      if (first) {
        force_path.moveTo(pf);
        feature_path.moveTo(pa);
        first = false;
      } else {
        force_path.lineTo(pf);
        feature_path.lineTo(pa);
      }
    }
    painter.setClipRect(plot);
    painter.setPen(QPen(feature_colour, 1.5));
    painter.drawPath(feature_path);
    painter.setPen(QPen(force_colour, 2.0));
    painter.drawPath(force_path);
  }

 private:
  struct Sample {
    double t;
    double force;
    double feature;
  };
  struct Event {
    double t;
    std::string label;
    bool stop;
  };

  void trim(double t_now) {
    while (!samples_.empty() && samples_.front().t < t_now - window_s_) {
      samples_.pop_front();
    }
    while (!events_.empty() && events_.front().t < t_now - window_s_) {
      events_.pop_front();
    }
  }

  std::deque<Sample> samples_;
  std::deque<Event> events_;
  std::string state_name_;
  double window_s_ = 20.0;
  int last_key_point_ = 0;
  bool stopped_ = false;
};

ForcePlotPanel::ForcePlotPanel(QWidget* parent) : rviz::Panel(parent) {
  auto* layout = new QVBoxLayout(this);
  auto* controls = new QHBoxLayout();
  controls->addWidget(new QLabel("Topic:"));
  topic_edit_ = new QLineEdit("drilling_state");
  controls->addWidget(topic_edit_);
  controls->addWidget(new QLabel("Window [s]:"));
  window_spin_ = new QDoubleSpinBox();
  window_spin_->setRange(1.0, 600.0);
  window_spin_->setValue(20.0);
  controls->addWidget(window_spin_);
  layout->addLayout(controls);
  chart_ = new StripChart(this);
  layout->addWidget(chart_, 1);
  status_label_ = new QLabel("no message yet");
  layout->addWidget(status_label_);
  timer_ = new QTimer(this);

  nh_.setCallbackQueue(&queue_);
  connect(topic_edit_, SIGNAL(editingFinished()), this, SLOT(onTopicEdited()));
  connect(window_spin_, SIGNAL(valueChanged(double)), this, SLOT(onWindowChanged(double)));
  connect(timer_, SIGNAL(timeout()), this, SLOT(poll()));
}

ForcePlotPanel::~ForcePlotPanel() {
  timer_->stop();
  sub_.shutdown();
}

void ForcePlotPanel::onInitialize() {
  subscribe(topic_edit_->text().toStdString());
  timer_->start(50);
}

void ForcePlotPanel::load(const rviz::Config& config) {
  rviz::Panel::load(config);
  QString topic;
  if (config.mapGetString("Topic", &topic)) {
    topic_edit_->setText(topic);
    subscribe(topic.toStdString());
  }
  float window = 0.0f;
  if (config.mapGetFloat("Window", &window) && window >= 1.0f) {
    window_spin_->setValue(window);
  }
}

void ForcePlotPanel::save(rviz::Config config) const {
  rviz::Panel::save(config);
  config.mapSetValue("Topic", topic_edit_->text());
  config.mapSetValue("Window", window_spin_->value());
}

void ForcePlotPanel::onTopicEdited() {
  subscribe(topic_edit_->text().toStdString());
  Q_EMIT configChanged();
}

void ForcePlotPanel::onWindowChanged(double seconds) {
  chart_->setWindow(seconds);
  Q_EMIT configChanged();
}

void ForcePlotPanel::subscribe(const std::string& topic) {
  sub_.shutdown();
  received_ = false;
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

void ForcePlotPanel::stateCallback(const DrillingState::ConstPtr& msg) {
  const double t =
      msg->header.stamp.isZero() ? ros::Time::now().toSec() : msg->header.stamp.toSec();
  chart_->add(t, *msg);
  received_ = true;
  last_message_ = ros::WallTime::now();
}

void ForcePlotPanel::poll() {
  queue_.callAvailable();
  if (received_) {
    const double age = (ros::WallTime::now() - last_message_).toSec();
    status_label_->setText(age > 2.0 ? QString("last message %1 s ago").arg(age, 0, 'f', 1)
                                     : QString("receiving"));
  }
  chart_->update();
}

}  // namespace rviz_plugins
}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::rviz_plugins::ForcePlotPanel, rviz::Panel)
