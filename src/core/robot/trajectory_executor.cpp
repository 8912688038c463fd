#include "pedicle_drilling/core/robot/trajectory_executor.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {

namespace {

// Times within this of each other are one time: a stamp that crossed ROS (nanoseconds) or
// another machine's clock is never exactly the double it was made from, and a point a rounding
// error after the takeover would otherwise be a spline segment of 1e-10 s (unbounded speed).
constexpr double kSameTime = 1e-6;

/** @brief Position, velocity and acceleration of one joint on one segment at s in [0, h]. */
struct Scalar {
  double q, v, a;
};

Scalar linear(double p0, double p1, double h, double s) {
  const double v = (p1 - p0) / h;
  return {p0 + v * s, v, 0.0};
}

// Cubic Hermite: positions and velocities at both ends.
Scalar cubic(double p0, double v0, double p1, double v1, double h, double s) {
  const double c2 = (3.0 * (p1 - p0) / h - 2.0 * v0 - v1) / h;
  const double c3 = (2.0 * (p0 - p1) / h + v0 + v1) / (h * h);
  return {p0 + s * (v0 + s * (c2 + s * c3)), v0 + s * (2.0 * c2 + 3.0 * c3 * s),
          2.0 * c2 + 6.0 * c3 * s};
}

// Quintic: positions, velocities and accelerations at both ends.
Scalar quintic(double p0, double v0, double a0, double p1, double v1, double a1, double h,
               double s) {
  const double h2 = h * h, h3 = h2 * h, h4 = h3 * h, h5 = h4 * h;
  const double dp = p1 - p0;
  const double c2 = 0.5 * a0;
  const double c3 = (20.0 * dp - (8.0 * v1 + 12.0 * v0) * h - (3.0 * a0 - a1) * h2) / (2.0 * h3);
  const double c4 =
      (-30.0 * dp + (14.0 * v1 + 16.0 * v0) * h + (3.0 * a0 - 2.0 * a1) * h2) / (2.0 * h4);
  const double c5 = (12.0 * dp - 6.0 * (v1 + v0) * h - (a0 - a1) * h2) / (2.0 * h5);
  const double q = p0 + s * (v0 + s * (c2 + s * (c3 + s * (c4 + s * c5))));
  const double v = v0 + s * (2.0 * c2 + s * (3.0 * c3 + s * (4.0 * c4 + s * 5.0 * c5)));
  const double a = 2.0 * c2 + s * (6.0 * c3 + s * (12.0 * c4 + s * 20.0 * c5));
  return {q, v, a};
}

void append(TargetResult* result, const std::string& message) {
  result->status = TargetStatus::kClamped;
  if (!result->message.empty()) result->message += "; ";
  result->message += message;
}

}  // namespace

JointTrajectoryExecutor::JointTrajectoryExecutor(std::vector<std::string> joint_names,
                                                 std::vector<JointLimit> limits,
                                                 const Eigen::VectorXd& hold_q,
                                                 ControllerRules rules)
    : names_(std::move(joint_names)), limits_(std::move(limits)), rules_(rules) {
  if (names_.empty()) throw std::invalid_argument("JointTrajectoryExecutor: no joints");
  if (!(std::isfinite(rules_.stop_trajectory_duration_s) &&
        rules_.stop_trajectory_duration_s > 0.0)) {
    throw std::invalid_argument("JointTrajectoryExecutor: stop_trajectory_duration_s must be > 0");
  }
  if (limits_.size() != names_.size()) {
    throw std::invalid_argument("JointTrajectoryExecutor: one limit per joint needed");
  }
  std::set<std::string> seen;
  for (std::size_t j = 0; j < names_.size(); ++j) {
    if (names_[j].empty() || !seen.insert(names_[j]).second) {
      throw std::invalid_argument("JointTrajectoryExecutor: empty or repeated joint name '" +
                                  names_[j] + "'");
    }
    const JointLimit& l = limits_[j];
    if (std::isnan(l.lower) || std::isnan(l.upper) || !(l.lower <= l.upper) ||
        !(l.velocity > 0.0)) {
      throw std::invalid_argument("JointTrajectoryExecutor: joint '" + names_[j] +
                                  "': limits must satisfy lower <= upper and velocity > 0");
    }
  }
  hold(hold_q);
}

void JointTrajectoryExecutor::hold(const Eigen::VectorXd& q) {
  const auto n = static_cast<Eigen::Index>(names_.size());
  if (q.size() != n) throw std::invalid_argument("JointTrajectoryExecutor::hold: size mismatch");
  Knot k;
  k.t = -std::numeric_limits<double>::infinity();
  k.q = q;
  k.v = Eigen::VectorXd::Zero(n);
  k.a = Eigen::VectorXd::Zero(n);
  knots_ = {k};
}

double JointTrajectoryExecutor::endTime() const {
  return knots_.size() > 1 ? knots_.back().t : -std::numeric_limits<double>::infinity();
}

TrajectoryState JointTrajectoryExecutor::sample(double t) const {
  TrajectoryState out;
  sample(t, &out);
  return out;
}

void JointTrajectoryExecutor::sample(double t, TrajectoryState* state) const {
  const auto n = static_cast<Eigen::Index>(names_.size());
  TrajectoryState& out = *state;
  const Knot& last = knots_.back();
  if (t > last.t) {  // after the last point: at rest there (at the point itself: its state)
    out.position = last.q;
    out.velocity.setZero(n);
    out.acceleration.setZero(n);
    return;
  }
  const Knot& first = knots_.front();
  if (t <= first.t) {
    out.position = first.q;
    out.velocity = first.v;
    out.acceleration = first.a;
    return;
  }
  const auto it = std::lower_bound(knots_.begin() + 1, knots_.end(), t,
                                   [](const Knot& k, double time) { return k.t < time; });
  const Knot& b = *it;
  const Knot& a = *(it - 1);
  const double h = b.t - a.t;
  const double s = t - a.t;
  out.position.resize(n);
  out.velocity.resize(n);
  out.acceleration.resize(n);
  for (Eigen::Index j = 0; j < n; ++j) {
    Scalar x{};
    if (b.degree == 5) {
      x = quintic(a.q[j], a.v[j], a.a[j], b.q[j], b.v[j], b.a[j], h, s);
    } else if (b.degree == 3) {
      x = cubic(a.q[j], a.v[j], b.q[j], b.v[j], h, s);
    } else {
      x = linear(a.q[j], b.q[j], h, s);
    }
    out.position[j] = x.q;
    out.velocity[j] = x.v;
    out.acceleration[j] = x.a;
  }
}

void JointTrajectoryExecutor::prune(double t) {
  if (t > knots_.back().t) {  // finished: hold the last point at rest
    if (knots_.size() > 1) {
      const Eigen::VectorXd q = knots_.back().q;
      hold(q);
    }
    return;
  }
  // Keep the knot that starts the segment containing t.
  std::size_t keep = 0;
  while (keep + 1 < knots_.size() && knots_[keep + 1].t <= t) ++keep;
  if (keep > 0) knots_.erase(knots_.begin(), knots_.begin() + static_cast<long>(keep));
}

TargetResult JointTrajectoryExecutor::validate(const TrajectoryCommand& command,
                                               std::vector<int>* map) const {
  if (command.joint_names.empty()) return {TargetStatus::kRejected, "no joint names"};
  if (command.points.empty()) return {TargetStatus::kRejected, "no trajectory points"};
  if (rules_.strict && !rules_.allow_partial_joints_goal &&
      command.joint_names.size() != names_.size()) {
    std::string expected;
    for (const std::string& n : names_) expected += (expected.empty() ? "" : ", ") + n;
    return {TargetStatus::kRejected,
            "joints on incoming goal don't match the controller joints [" + expected + "]"};
  }
  std::set<std::string> seen;
  for (const std::string& name : command.joint_names) {
    auto it = std::find(names_.begin(), names_.end(), name);
    if (it == names_.end()) {
      return {TargetStatus::kRejected, "unknown or non-commandable joint '" + name + "'"};
    }
    if (!seen.insert(name).second) {
      return {TargetStatus::kRejected, "joint '" + name + "' appears twice"};
    }
    map->push_back(static_cast<int>(it - names_.begin()));
  }
  if (!std::isnan(command.start_time_s) && !std::isfinite(command.start_time_s)) {
    return {TargetStatus::kRejected, "start time is infinite"};
  }
  const std::size_t m = command.joint_names.size();
  double last_t = -std::numeric_limits<double>::infinity();
  for (std::size_t p = 0; p < command.points.size(); ++p) {
    const TrajectoryPoint& pt = command.points[p];
    const std::string where = "point " + std::to_string(p);
    if (!std::isfinite(pt.time_s)) return {TargetStatus::kRejected, where + ": bad time"};
    if (pt.time_s <= last_t) {
      return {TargetStatus::kRejected, where + ": times must strictly increase"};
    }
    last_t = pt.time_s;
    if (pt.positions.size() != m) {
      return {TargetStatus::kRejected, where + ": positions size differs from names"};
    }
    if (!pt.velocities.empty() && pt.velocities.size() != m) {
      return {TargetStatus::kRejected, where + ": velocities size differs from names"};
    }
    if (!pt.accelerations.empty() && pt.accelerations.size() != m) {
      return {TargetStatus::kRejected, where + ": accelerations size differs from names"};
    }
    if (!pt.accelerations.empty() && pt.velocities.empty()) {
      return {TargetStatus::kRejected, where + ": accelerations without velocities"};
    }
    for (const std::vector<double>* values : {&pt.positions, &pt.velocities, &pt.accelerations}) {
      for (double x : *values) {
        if (!std::isfinite(x)) return {TargetStatus::kRejected, where + ": NaN/inf value"};
      }
    }
    if (rules_.strict) {
      for (std::size_t j = 0; j < m; ++j) {
        const std::size_t c = static_cast<std::size_t>((*map)[j]);
        const JointLimit& lim = limits_[c];
        if (pt.positions[j] < lim.lower || pt.positions[j] > lim.upper) {
          std::ostringstream os;
          os << where << ": joint '" << names_[c] << "' position " << pt.positions[j]
             << " outside its limits [" << lim.lower << ", " << lim.upper << "]";
          return {TargetStatus::kRejected, os.str()};
        }
      }
    }
  }
  return {};
}

JointTrajectoryExecutor::Knot JointTrajectoryExecutor::stateKnot(double t) const {
  const TrajectoryState st = sample(t);
  Knot k;
  k.t = t;
  k.q = st.position;
  k.v = st.velocity;
  k.a = st.acceleration;
  return k;
}

void JointTrajectoryExecutor::stop(double now) {
  // Decelerate from the reference's state now to rest: a cubic from (q, v) to (q + v T / 2, 0)
  // over T is a constant deceleration, the profile ros_control's hold trajectory approximates.
  const Knot from = stateKnot(now);
  const double T = rules_.stop_trajectory_duration_s;
  Knot to;
  to.t = now + T;
  to.q = from.q + 0.5 * T * from.v;
  to.v = Eigen::VectorXd::Zero(from.v.size());
  to.a = Eigen::VectorXd::Zero(from.v.size());
  to.degree = 3;
  knots_ = {from, to};
}

TargetResult JointTrajectoryExecutor::command(const TrajectoryCommand& command, double now) {
  if (rules_.strict && command.points.empty()) {
    // ros_control: "Empty trajectory command, stopping." (names are not checked)
    stop(now);
    return {};
  }
  std::vector<int> map;
  const TargetResult valid = validate(command, &map);
  if (!valid.ok()) return valid;
  const double last_t = command.points.back().time_s;
  if (last_t <= now + kSameTime && rules_.strict) {
    std::ostringstream os;
    os << "dropping all " << command.points.size()
       << " trajectory point(s), as they occur before the current time (last point " << now - last_t
       << " s in the past): the running trajectory goes on";
    return {TargetStatus::kRejected, os.str()};
  }
  if (last_t <= now + kSameTime) {
    // A streamed command that arrived after its own end (a late message, e.g. when sim time
    // runs faster than the planner can follow): go to its final point over the duration of its
    // last interval, instead of dropping it and leaving the joints on an outdated reference.
    TrajectoryCommand late = command;
    const std::size_t np = command.points.size();
    const double span = np > 1 ? last_t - command.points[np - 2].time_s : 0.0;
    late.points = {command.points.back()};
    late.points.front().time_s = now + std::max(0.01, span);
    late.points.front().velocities.clear();
    late.points.front().accelerations.clear();
    late.start_time_s = std::numeric_limits<double>::quiet_NaN();
    TargetResult result = this->command(late, now);
    if (result.ok()) {
      std::ostringstream os;
      os << "every point lies in the past (last at " << last_t << " s, now " << now
         << " s): going to the final point";
      append(&result, os.str());
    }
    return result;
  }
  const double takeover =
      std::isfinite(command.start_time_s) && command.start_time_s > now + kSameTime
          ? std::min(command.start_time_s, last_t)
          : now;
  std::vector<Knot> knots{stateKnot(now)};
  if (takeover > now) {
    for (const Knot& k : knots_) {
      if (k.t > now + kSameTime && k.t < takeover - kSameTime) knots.push_back(k);
    }
    Knot at = stateKnot(takeover);
    // The old segment that contains the takeover keeps its spline up to it (after the old end:
    // the held position, constant).
    at.degree = 1;
    for (const Knot& k : knots_) {
      if (k.t >= takeover) {
        at.degree = k.degree;
        break;
      }
    }
    knots.push_back(at);
  }
  TargetResult result;
  const auto n = static_cast<Eigen::Index>(names_.size());
  for (const TrajectoryPoint& pt : command.points) {
    if (pt.time_s <= takeover + kSameTime) continue;  // already due: dropped
    Knot k;
    k.t = pt.time_s;
    k.q = knots.back().q;  // joints not named keep their reference
    k.v = Eigen::VectorXd::Zero(n);
    k.a = Eigen::VectorXd::Zero(n);
    k.degree = !pt.accelerations.empty() ? 5 : !pt.velocities.empty() ? 3 : 1;
    for (std::size_t j = 0; j < map.size(); ++j) {
      const int c = map[j];
      const JointLimit& lim = limits_[static_cast<std::size_t>(c)];
      double q = pt.positions[j];
      if (q < lim.lower || q > lim.upper) {
        std::ostringstream os;
        os << "joint '" << names_[static_cast<std::size_t>(c)] << "' target " << q
           << " clamped to [" << lim.lower << ", " << lim.upper << "]";
        append(&result, os.str());
        q = std::clamp(q, lim.lower, lim.upper);
      }
      k.q[c] = q;
      if (k.degree >= 3) k.v[c] = pt.velocities[j];
      if (k.degree == 5) k.a[c] = pt.accelerations[j];
    }
    knots.push_back(k);
  }
  // Speeds above the velocity limits: the joint servos cap the speed, so the joint falls behind
  // the command; say so (the first offence) instead of lagging silently.
  bool too_fast = false;
  for (std::size_t i = 1; i < knots.size() && !too_fast; ++i) {
    const double h = knots[i].t - knots[i - 1].t;
    for (Eigen::Index c = 0; c < n && !too_fast; ++c) {
      const double mean_speed = std::abs(knots[i].q[c] - knots[i - 1].q[c]) / h;
      const double speed =
          std::max(mean_speed, knots[i].degree >= 3 ? std::abs(knots[i].v[c]) : 0.0);
      const JointLimit& lim = limits_[static_cast<std::size_t>(c)];
      too_fast = speed > lim.velocity * (1.0 + 1e-6);
      if (too_fast) {
        std::ostringstream os;
        os << "joint '" << names_[static_cast<std::size_t>(c)] << "' commanded at " << speed
           << " between t = " << knots[i - 1].t << " and " << knots[i].t
           << " s, above its velocity limit " << lim.velocity
           << ": it follows at the limit and lags the command";
        append(&result, os.str());
      }
    }
  }
  knots_ = std::move(knots);
  return result;
}

}  // namespace pedicle_drilling::core
