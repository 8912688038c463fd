#include "pedicle_drilling/core/control/controller_watch.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {

const ParamTable<ControllerWatchParams>& ControllerWatchParams::table() {
  static const ParamTable<ControllerWatchParams> t = [] {
    using P = ControllerWatchParams;
    ParamTable<P> d;
    d.flag("enabled", &P::enabled)
        .number("arm_desired_tolerance_rad", &P::arm_desired_tolerance_rad, Range::aboveUpTo(0, 1),
                "rad")
        .number("feed_desired_tolerance_m", &P::feed_desired_tolerance_m, Range::aboveUpTo(0, 0.1),
                "m")
        .number("arm_following_tolerance_rad", &P::arm_following_tolerance_rad,
                Range::aboveUpTo(0, 1), "rad")
        .number("feed_following_tolerance_m", &P::feed_following_tolerance_m,
                Range::aboveUpTo(0, 0.1), "m")
        .number("state_timeout_s", &P::state_timeout_s, Range::aboveUpTo(0, 60), "s");
    return d;
  }();
  return t;
}

void ControllerWatchParams::validate() const { table().validate(*this); }

ControllerWatch::ControllerWatch(const ControllerWatchParams& params,
                                 std::vector<ControllerSpec> controllers,
                                 std::vector<std::string> feed_joints)
    : params_(params) {
  params_.validate();
  ControllerRules expected_rules;  // what a controller that took every command on time runs
  expected_rules.allow_partial_joints_goal = true;
  for (ControllerSpec& spec : controllers) {
    Watched w;
    const std::size_t n = spec.joints.size();
    for (const std::string& joint : spec.joints) {
      const bool feed =
          std::find(feed_joints.begin(), feed_joints.end(), joint) != feed_joints.end();
      w.desired_tolerance.push_back(feed ? params_.feed_desired_tolerance_m
                                         : params_.arm_desired_tolerance_rad);
      w.following_tolerance.push_back(feed ? params_.feed_following_tolerance_m
                                           : params_.arm_following_tolerance_rad);
    }
    w.expected = std::make_unique<JointTrajectoryExecutor>(
        spec.joints, std::vector<JointLimit>(n),
        Eigen::VectorXd::Zero(static_cast<Eigen::Index>(n)), expected_rules);
    specs_.push_back(spec);
    w.spec = std::move(spec);
    watched_.push_back(std::move(w));
  }
}

std::string ControllerWatch::start(double now) {
  watching_ = false;
  if (!params_.enabled) return "";
  for (Watched& w : watched_) {
    if (!w.mismatch.empty()) return w.mismatch;
    if (w.last_desired.empty()) {
      return w.spec.name + " has not reported its state (" + w.spec.name +
             "/state): the planner cannot watch it (controller_watch/enabled false to drill "
             "without)";
    }
    // Seeded by the first state taken at or after the start (onState): the last one before it
    // may be from before a reset of the robot (a stale reference).
    w.seeded = false;
  }
  sent_.clear();
  watching_ = true;
  start_t_ = now;
  worst_desired_ = 0.0;
  worst_following_ = 0.0;
  return "";
}

void ControllerWatch::onCommand(double now, const TrajectoryCommand& command) {
  if (!watching_) return;
  // Kept only until every expectation is seeded (onState replays them then), not all trial.
  if (!allSeeded()) sent_.push_back({now, command});
  for (auto& [index, part] : splitByController(command, specs_)) {
    if (watched_[index].seeded) watched_[index].expected->command(part, now);
  }
}

std::string ControllerWatch::onState(double now, const std::string& name,
                                     const ControllerStateSample& state) {
  auto it = std::find_if(watched_.begin(), watched_.end(),
                         [&name](const Watched& w) { return w.spec.name == name; });
  if (it == watched_.end()) return "";  // a controller the planner does not command
  Watched& w = *it;
  const std::size_t n = w.spec.joints.size();
  std::vector<int> column(n, -1);
  for (std::size_t k = 0; k < state.joint_names.size(); ++k) {
    const auto at = std::find(w.spec.joints.begin(), w.spec.joints.end(), state.joint_names[k]);
    if (at != w.spec.joints.end())
      column[static_cast<std::size_t>(at - w.spec.joints.begin())] = static_cast<int>(k);
  }
  const auto value = [](const std::vector<double>& v, int k) {
    return k >= 0 && static_cast<std::size_t>(k) < v.size()
               ? v[static_cast<std::size_t>(k)]
               : std::numeric_limits<double>::quiet_NaN();
  };
  std::vector<double> desired(n), error(n);
  for (std::size_t j = 0; j < n; ++j) {
    desired[j] = value(state.desired_positions, column[j]);
    const double e = value(state.error_positions, column[j]);
    error[j] = std::isfinite(e) ? e : desired[j] - value(state.actual_positions, column[j]);
  }
  const bool complete =
      std::all_of(desired.begin(), desired.end(), [](double x) { return std::isfinite(x); }) &&
      std::all_of(error.begin(), error.end(), [](double x) { return std::isfinite(x); });
  if (!complete) {
    std::ostringstream os;
    os << w.spec.name << "/state does not give every joint the planner commands on " << w.spec.name
       << " (";
    for (std::size_t j = 0; j < n; ++j) os << (j ? ", " : "") << w.spec.joints[j];
    os << "; it names";
    for (const std::string& joint : state.joint_names) os << " " << joint;
    os << "), or has NaN/inf: the planner's controllers (arm_controller, feed_controller and their "
          "joints) must be the robot's";
    w.last_desired.clear();
    w.mismatch = os.str();
    if (!watching_) return "";
    watching_ = false;
    return w.mismatch;
  }
  w.mismatch.clear();
  w.last_desired = desired;
  w.last_state_t = now;
  if (!watching_) return "";
  if (!w.seeded) {
    if (state.stamp < start_t_) return "";  // taken before the trial: maybe before a reset
    // The expectation starts from this state's desired position and takes the commands sent
    // since the start at their send times (the motion before this state is at most one state
    // period and the transport: part of the tolerances).
    w.expected->hold(Eigen::Map<const Eigen::VectorXd>(desired.data(),
                                                       static_cast<Eigen::Index>(desired.size())));
    w.seeded = true;
    const std::size_t index = static_cast<std::size_t>(it - watched_.begin());
    for (const auto& [t, command] : sent_) {
      for (auto& [c, part] : splitByController(command, specs_)) {
        if (c == index) w.expected->command(part, t);
      }
    }
    if (allSeeded()) sent_.clear();  // every expectation has its commands from here on
    return "";
  }
  w.expected->sample(state.stamp, &w.expected_sample);
  for (std::size_t j = 0; j < n; ++j) {
    const double d =
        std::abs(desired[j] - w.expected_sample.position[static_cast<Eigen::Index>(j)]);
    const double f = std::abs(error[j]);
    worst_desired_ = std::max(worst_desired_, d / w.desired_tolerance[j]);
    worst_following_ = std::max(worst_following_, f / w.following_tolerance[j]);
    if (!(d > w.desired_tolerance[j]) && !(f > w.following_tolerance[j])) continue;
    // The message is built only on a violation (a stream per state was a visible share of a
    // trial's time).
    std::ostringstream os;
    if (d > w.desired_tolerance[j]) {
      os << w.spec.name << ": the desired position of " << w.spec.joints[j] << " differs from the "
         << "commanded by " << d << " (controller_watch tolerance " << w.desired_tolerance[j]
         << "): a command was refused or arrived late";
    } else {
      os << w.spec.name << ": " << w.spec.joints[j] << " does not follow its trajectory: error "
         << error[j] << " (controller_watch tolerance " << w.following_tolerance[j] << ")";
    }
    watching_ = false;
    return os.str();
  }
  w.expected->prune(state.stamp - 1.0);
  return "";
}

bool ControllerWatch::allSeeded() const {
  return std::all_of(watched_.begin(), watched_.end(), [](const Watched& w) { return w.seeded; });
}

std::string ControllerWatch::checkSilence(double now) const {
  if (!watching_) return "";
  for (const Watched& w : watched_) {
    const double since = std::max(w.last_state_t, start_t_);
    if (now - since > params_.state_timeout_s) {
      std::ostringstream os;
      os << w.spec.name << " silent: no " << w.spec.name << "/state for more than "
         << params_.state_timeout_s << " s";
      return os.str();
    }
  }
  return "";
}

}  // namespace pedicle_drilling::core
