#include "pedicle_drilling/core/control/trial_view.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

#include "pedicle_drilling/core/control/compensation_planner.hpp"
#include "pedicle_drilling/core/control/trapezoid_segmenter.hpp"

namespace pedicle_drilling::core {

namespace {

std::string format(const char* fmt, double v) {
  char text[64];
  std::snprintf(text, sizeof(text), fmt, v);
  return text;
}

}  // namespace

// ----------------------------------------------------------------------------- PanelSettings

void PanelSettings::validate() const {
  CompensationMode m;
  if (!parseCompensationMode(mode, &m)) {
    throw std::invalid_argument("mode: '" + mode +
                                "' is not stationary, uncompensated or compensated");
  }
  SegmentProfile p;
  if (!segment_profile.empty() && !parseSegmentProfile(segment_profile, &p)) {
    throw std::invalid_argument("segment_profile: '" + segment_profile +
                                "' is not rest_to_rest or exact (empty: the planner's)");
  }
  if (!(std::isfinite(spindle_rpm) && spindle_rpm > 0.0 && spindle_rpm <= 60000.0)) {
    throw std::invalid_argument("spindle_rpm: must be in (0, 60000]");
  }
  if (!(std::isfinite(feed_rate_mm_s) && feed_rate_mm_s > 0.0 && feed_rate_mm_s <= 10.0)) {
    throw std::invalid_argument("feed_rate_mm_s: must be in (0, 10]");
  }
}

std::map<std::string, std::string> PanelSettings::toConfig() const {
  return {{"Mode", mode},
          {"Profile", segment_profile},
          {"Rpm", format("%.17g", spindle_rpm)},
          {"Feed", format("%.17g", feed_rate_mm_s)},
          {"Seed", std::to_string(seed)}};
}

PanelSettings PanelSettings::fromConfig(const std::map<std::string, std::string>& config,
                                        std::vector<std::string>* problems) {
  PanelSettings out;
  const auto note = [problems](const std::string& line) {
    if (problems != nullptr) problems->push_back(line);
  };
  const auto number = [&](const char* key, double* value) {
    const auto it = config.find(key);
    if (it == config.end()) return;
    char* end = nullptr;
    const double v = std::strtod(it->second.c_str(), &end);
    if (it->second.empty() || *end != '\0') {
      note(std::string(key) + ": '" + it->second + "' is not a number; default kept");
      return;
    }
    *value = v;
  };
  const auto text = [&](const char* key, std::string* value) {
    const auto it = config.find(key);
    if (it != config.end()) *value = it->second;
  };
  text("Mode", &out.mode);
  text("Profile", &out.segment_profile);
  number("Rpm", &out.spindle_rpm);
  number("Feed", &out.feed_rate_mm_s);
  const auto seed = config.find("Seed");
  if (seed != config.end()) {
    char* end = nullptr;
    errno = 0;
    const unsigned long long v = std::strtoull(seed->second.c_str(), &end, 10);
    if (seed->second.empty() || *end != '\0' || errno == ERANGE || seed->second[0] == '-') {
      note("Seed: '" + seed->second + "' is not an integer in [0, 2^64); default kept");
    } else {
      out.seed = v;
    }
  }
  // A field that does not validate goes back to its default, named.
  const PanelSettings defaults;
  for (int pass = 0; pass < 4; ++pass) {
    try {
      out.validate();
      break;
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      note(what + "; default kept");
      const std::string field = what.substr(0, what.find(':'));
      if (field == "mode") out.mode = defaults.mode;
      if (field == "segment_profile") out.segment_profile = defaults.segment_profile;
      if (field == "spindle_rpm") out.spindle_rpm = defaults.spindle_rpm;
      if (field == "feed_rate_mm_s") out.feed_rate_mm_s = defaults.feed_rate_mm_s;
    }
  }
  return out;
}

// ----------------------------------------------------------------------------- verdict

bool paperSuccess(bool recognizer_stop, bool breakthrough, double max_depth_cut_m,
                  double inner_cortical_start_m, double residual_m) {
  return recognizer_stop && !breakthrough && max_depth_cut_m > inner_cortical_start_m &&
         residual_m > 0.0 && residual_m <= 2.0e-3;
}

// ----------------------------------------------------------------------------- TrialView

void TrialView::reset() { *this = TrialView(h1_m_, h2_n_); }

void TrialView::onPhase(const std::string& phase_name, bool running) {
  if (phase_name == "moving_to_pose" && phase_ != "moving_to_pose") reset();
  phase_ = phase_name;
  running_ = running;
}

void TrialView::onRecognizer(const std::string& state_name, int last_key_point,
                             double averaged_force, double feature, bool stop) {
  state_name_ = state_name;
  key_point_ = last_key_point;
  averaged_force_ = averaged_force;
  feature_ = feature;
  recognizer_stop_ = recognizer_stop_ || stop;
}

void TrialView::onStop(const std::string& source, const std::string& reason, bool retreat) {
  if (!stop_source_.empty()) return;  // the first stop is the trial's
  stop_source_ = source.empty() ? "(unnamed)" : source;
  stop_reason_ = reason;
  stop_retreat_ = retreat;
}

void TrialView::onGroundTruth(double max_depth_cut_m, double inner_cortical_start_m,
                              double inner_cortical_end_m, double residual_m, bool breakthrough) {
  have_truth_ = true;
  max_cut_m_ = max_depth_cut_m;
  inner_start_m_ = inner_cortical_start_m;
  inner_end_m_ = inner_cortical_end_m;
  residual_m_ = residual_m;
  breakthrough_ = breakthrough_ || breakthrough;
}

void TrialView::onPredictedMarker(double stamp, const Eigen::Vector3d& position) {
  onMarker(stamp, position, true);
}

void TrialView::onTrackedMarker(double stamp, const Eigen::Vector3d& position) {
  onMarker(stamp, position, false);
}

void TrialView::onMarker(double stamp, const Eigen::Vector3d& position, bool predicted) {
  if (!position.allFinite()) return;
  const StampedPosition* partner = markers_.add({stamp, "", position}, predicted);
  if (partner == nullptr) return;
  h1_error_m_ = (position - partner->position).norm();
  h1_max_m_ = std::max(h1_max_m_, h1_error_m_);
}

void TrialView::onForce(double force_n) {
  if (!std::isfinite(force_n)) return;
  force_n_ = force_n;
  if (running_) force_max_n_ = std::max(force_max_n_, force_n);
}

void TrialView::onMonitorStatus(int level, const std::string& message) {
  monitor_level_ = level;
  monitor_message_ = message;
}

TrialVerdict TrialView::verdict() const {
  if (phase_.empty() || phase_ == "idle") return TrialVerdict::kNone;
  if (!ended()) return TrialVerdict::kRunning;
  if (phase_ == "failed" || !have_truth_) return TrialVerdict::kFailure;
  const bool recognizer_stop = !stop_source_.empty() && !stop_retreat_;
  return paperSuccess(recognizer_stop, breakthrough_, max_cut_m_, inner_start_m_, residual_m_)
             ? TrialVerdict::kSuccess
             : TrialVerdict::kFailure;
}

std::vector<Readout> TrialView::readouts() const {
  std::vector<Readout> out;
  out.push_back(
      {"phase", phase_.empty() ? "(no compensation/status)" : phase_, phase_ == "failed"});
  std::string state = state_name_.empty() ? "(no drilling_state)" : state_name_;
  if (key_point_ > 0) state += ", key point " + std::to_string(key_point_);
  out.push_back({"recognizer", state, false});
  out.push_back({"force / A*",
                 std::isfinite(averaged_force_)
                     ? format("%.2f N", averaged_force_) + " / " + format("%.3g", feature_)
                     : "-",
                 false});
  std::string h1 = "-";
  if (std::isfinite(h1_error_m_)) {
    h1 = format("%.2f mm", h1_error_m_ * 1e3) + " (max " + format("%.2f", h1_max_m_ * 1e3) +
         ", H1 " + format("%.1f", h1_m_ * 1e3) + ")";
  }
  out.push_back({"predicted - tracked", h1, h1_max_m_ > h1_m_});
  std::string f = "-";
  if (std::isfinite(force_n_)) {
    f = format("%.2f N", force_n_) + " (max " + format("%.2f", force_max_n_) + ", H2 " +
        format("%.0f", h2_n_) + ")";
  }
  out.push_back({"force", f, force_max_n_ > h2_n_});
  static const char* const kLevels[] = {"OK", "WARN", "ERROR", "STALE"};
  std::string monitor = "(no /diagnostics)";
  if (monitor_level_ >= 0 && monitor_level_ <= 3) {
    monitor = std::string(kLevels[monitor_level_]) + ": " + monitor_message_;
  }
  out.push_back({"safety monitor", monitor, monitor_level_ == 2});
  out.push_back(
      {"stop", stop_source_.empty() ? "-" : stop_source_ + ": " + stop_reason_, stop_retreat_});
  std::string residual = have_truth_ ? "-" : "(no ground truth)";
  if (have_truth_ && ended()) {
    residual = breakthrough_ ? "broken through" : format("%.2f mm", residual_m_ * 1e3);
    if (!breakthrough_ && max_cut_m_ <= inner_start_m_) residual += " (inner layer not reached)";
  }
  out.push_back({"residual", residual, breakthrough_});
  const TrialVerdict v = verdict();
  const char* verdict = v == TrialVerdict::kSuccess   ? "SUCCESS"
                        : v == TrialVerdict::kFailure ? "FAILURE"
                        : v == TrialVerdict::kRunning ? "running"
                                                      : "-";
  out.push_back({"verdict", verdict, v == TrialVerdict::kFailure});
  return out;
}

std::string TrialView::summary() const {
  std::string s = "trial " + (phase_.empty() ? std::string("idle") : phase_);
  for (const Readout& r : readouts()) {
    if (r.label == "stop" || r.label == "residual" || r.label == "verdict") {
      s += "; " + r.label + " " + r.value;
    }
  }
  return s;
}

// ----------------------------------------------------------------------------- ForceTrace

void ForceTrace::clear() { *this = ForceTrace(lead_in_s_, tail_s_); }

void ForceTrace::add(double t, const std::string& state_name, int last_key_point,
                     double averaged_force, double feature, bool stop) {
  if (!std::isfinite(t)) return;
  const bool reset = (recognizer_stop_ && !stop) || (last_key_point_ > 0 && last_key_point == 0);
  if (t < last_t_ || reset) clear();  // a new simulation, or a reset recognizer: a new trial
  last_t_ = t;
  recognizer_stop_ = stop;
  if (stopped() && t > stop_t_ + tail_s_) return;  // frozen: the stop stays in view
  state_name_ = state_name;
  if (std::isnan(contact_t_) && state_name != "idle" && !state_name.empty()) {
    contact_t_ = t;
  }
  if (last_key_point != last_key_point_ && last_key_point > 0) {
    events_.push_back({t, "K" + std::to_string(last_key_point), false});
  }
  last_key_point_ = last_key_point;
  if (stop && !stopped()) {
    stop_t_ = t;
    events_.push_back({t, "STOP", true});
  }
  if (std::isfinite(averaged_force) && std::isfinite(feature)) {
    samples_.push_back({t, averaged_force, feature});
    if (last_key_point >= 4 && !stopped()) {
      inner_peak_ = std::isnan(inner_peak_) ? feature : std::max(inner_peak_, feature);
    }
  }
  // Before the contact only the lead-in is kept.
  if (std::isnan(contact_t_)) {
    const double from = t - lead_in_s_;
    samples_.erase(samples_.begin(),
                   std::find_if(samples_.begin(), samples_.end(),
                                [from](const TraceSample& s) { return s.t >= from; }));
  }
  if (samples_.size() > 100000) samples_.erase(samples_.begin());  // hours of data: keep bounded
}

void ForceTrace::addStop(double t, const std::string& source) {
  if (!std::isfinite(t) || stopped()) return;
  stop_t_ = t;
  events_.push_back(
      {t, source.find("state_recognizer") != std::string::npos ? "STOP" : "STOP " + source, true});
}

void ForceTrace::addDepth(double t, double depth_m) {
  if (!std::isfinite(t) || !std::isfinite(depth_m)) return;
  if (!depth_.empty() && t < depth_.back().first) depth_.clear();
  depth_.emplace_back(t, depth_m);
  if (depth_.size() > 200000) depth_.erase(depth_.begin());
}

void ForceTrace::addThrust(double t, double thrust_n) {
  if (!std::isfinite(t) || !std::isfinite(thrust_n)) return;
  if (!thrust_.empty() && t < thrust_.back().t) thrust_.clear();  // a new simulation
  if (stopped() && t > stop_t_ + tail_s_) return;                 // frozen with the stop
  thrust_.push_back({t, thrust_n});
  if (std::isnan(contact_t_)) {
    const double from = t - lead_in_s_;
    thrust_.erase(thrust_.begin(),
                  std::find_if(thrust_.begin(), thrust_.end(),
                               [from](const ThrustSample& s) { return s.t >= from; }));
  }
  if (thrust_.size() > 200000) thrust_.erase(thrust_.begin());  // keep bounded
}

double ForceTrace::depthAt(double t) const {
  if (depth_.empty() || t < depth_.front().first) return std::numeric_limits<double>::quiet_NaN();
  const auto it = std::lower_bound(depth_.begin(), depth_.end(), t,
                                   [](const auto& e, double v) { return e.first < v; });
  if (it == depth_.end()) return depth_.back().second;
  if (it->first == t || it == depth_.begin()) return it->second;
  const auto& a = *(it - 1);
  const auto& b = *it;
  return a.second + (b.second - a.second) * (t - a.first) / (b.first - a.first);
}

// ----------------------------------------------------------------------------- labels

std::vector<int> layoutLabels(const std::vector<ChartLabel>& labels, double gap, int max_rows) {
  std::vector<std::size_t> order(labels.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&labels](std::size_t a, std::size_t b) { return labels[a].x < labels[b].x; });
  std::vector<double> row_end;  // right edge of the last label of each row
  std::vector<int> rows(labels.size(), 0);
  for (std::size_t i : order) {
    const ChartLabel& l = labels[i];
    int row = -1;
    for (std::size_t r = 0; r < row_end.size(); ++r) {
      if (row_end[r] + gap <= l.x) {
        row = static_cast<int>(r);
        break;
      }
    }
    if (row < 0 && static_cast<int>(row_end.size()) < std::max(1, max_rows)) {
      row = static_cast<int>(row_end.size());
      row_end.push_back(-1e300);
    }
    if (row < 0) {  // every row taken: the one that ends first
      row = static_cast<int>(std::min_element(row_end.begin(), row_end.end()) - row_end.begin());
    }
    row_end[row] = l.x + l.width;
    rows[i] = row;
  }
  return rows;
}

}  // namespace pedicle_drilling::core
