// Active compensation planner of Algorithm 1 (see the header).
#include "pedicle_drilling/core/control/compensation_planner.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {

namespace {

/** @brief Time of point i = 1..n of a segment of period T: t0 + T i / n, the last exactly t1. */
double pointTime(const PlannedSegment& seg, double period, int i, int n) {
  return i == n ? seg.t1 : seg.t0 + period * i / n;
}

void require(bool ok, const std::string& name, const std::string& why) {
  if (!ok) throw std::invalid_argument(name + ": " + why);
}

bool isUnit(const Eigen::Vector3d& v) { return v.allFinite() && std::abs(v.norm() - 1.0) < 1e-6; }

}  // namespace

const char* toString(CompensationMode mode) {
  switch (mode) {
    case CompensationMode::kStationary:
      return "stationary";
    case CompensationMode::kUncompensated:
      return "uncompensated";
    case CompensationMode::kCompensated:
      return "compensated";
  }
  return "unknown";
}

bool parseCompensationMode(const std::string& name, CompensationMode* mode) {
  for (CompensationMode m : {CompensationMode::kStationary, CompensationMode::kUncompensated,
                             CompensationMode::kCompensated}) {
    if (name == toString(m)) {
      *mode = m;
      return true;
    }
  }
  return false;
}

const ParamTable<CompensationParams>& CompensationParams::table() {
  static const ParamTable<CompensationParams> t = [] {
    using P = CompensationParams;
    ParamTable<P> d;
    d.number("latency_s", &P::latency_s, Range::closed(0, 1), "s")
        .number("period_s", &P::period_s, Range::aboveUpTo(0, 1), "s")
        .number("accel_ratio", &P::accel_ratio, Range::aboveUpTo(0, 1000))
        .integer("points_per_segment", &P::points_per_segment, Range::closed(1, 100))
        .parsed(
            "segment_profile", {"rest_to_rest", "exact"}, "",
            [](const P& v) { return std::string(toString(v.segment_profile)); },
            [](P& v, const std::string& x) { parseSegmentProfile(x, &v.segment_profile); })
        .parsed(
            "predicted_axes", {}, "comma-separated of ap, si, lr",
            [](const P& v) {
              std::string s;
              for (Axis a : kAllAxes) {
                if (v.predict_axis[static_cast<int>(a)]) s += (s.empty() ? "" : ",") + axisName(a);
              }
              return s;
            },
            [](P& v, const std::string& x) {
              std::array<bool, 3> axes{{false, false, false}};
              std::stringstream items(x);
              std::string name;
              while (std::getline(items, name, ',')) {
                Axis a;
                if (!parseAxis(name, &a)) {
                  throw std::invalid_argument("has unknown axis '" + name + "' (use ap, si, lr)");
                }
                axes[static_cast<int>(a)] = true;
              }
              v.predict_axis = axes;
            })
        .flag("compensate_si_lr", &P::compensate_lateral);
    return d;
  }();
  return t;
}

void CompensationParams::validate() const {
  table().validate(*this);
  require(std::isfinite(feed_rate_m_s) && feed_rate_m_s >= 0.0 && feed_rate_m_s <= 0.01,
          "feed_rate_m_s", "must be in [0, 0.01] m/s");
  require(isUnit(drill_axis), "drill_axis", "must be a finite unit vector");
  for (int i = 0; i < 3; ++i) {
    require(isUnit(axis_direction[i]), "axis_direction",
            axisName(kAllAxes[i]) + " direction must be a finite unit vector");
  }
}

// ---------------------------------------------------------------------------------------------

DisplacementPredictor::DisplacementPredictor(const MotionModel& model,
                                             const CompensationParams& params)
    : model_(model), params_(params) {}

void DisplacementPredictor::setVentilator(const VentilatorSettings& settings) {
  ventilator_ = std::make_shared<VentilatorModel>(settings);
}

void DisplacementPredictor::setBreathStart(double t) {
  if (!std::isfinite(t)) throw std::invalid_argument("breath start time must be finite");
  breath_start_ = t;
  have_phase_ = true;
}

VentilatorSample DisplacementPredictor::ventilatorAt(double t) const {
  if (!ready()) throw std::logic_error("ventilator settings or breath phase not known yet");
  // VentilatorModel::sample() is periodic for t >= 0; shift by whole periods for t < start.
  const double period = ventilator_->period();
  double rel = t - breath_start_;
  rel -= std::floor(rel / period) * period;
  VentilatorSample s = ventilator_->sample(rel);
  s.t = t;
  return s;
}

std::vector<double> DisplacementPredictor::flowSteps(double t0, double t1) const {
  std::vector<double> out;
  if (!ready() || !(t1 > t0)) return out;
  const double period = ventilator_->period();
  const double in_cycle[] = {0.0, ventilator_->flowTime(), ventilator_->inspiratoryTime()};
  const double first = std::floor((t0 - breath_start_) / period);
  for (double n = first; breath_start_ + n * period <= t1; n += 1.0) {
    for (double tau : in_cycle) {
      const double t = breath_start_ + n * period + tau;
      if (t > t0 && t <= t1 && (out.empty() || t > out.back() + 1e-9)) out.push_back(t);
    }
  }
  return out;
}

Eigen::Vector3d DisplacementPredictor::displacement(double t) const {
  const VentilatorSample s = ventilatorAt(t);
  Eigen::Vector3d d = Eigen::Vector3d::Zero();
  for (int i = 0; i < 3; ++i) {
    if (!params_.predict_axis[i]) continue;
    const double mm = model_.predict(kAllAxes[i], s.volume_ml, s.flow_ml_s);
    d += 1e-3 * mm * params_.axis_direction[i];
  }
  return d;
}

// ---------------------------------------------------------------------------------------------

CompensationPlanner::CompensationPlanner(const CompensationParams& params, const MotionModel& model)
    : CompensationPlanner(params, model, std::make_unique<PaperCompensator>()) {}

CompensationPlanner::CompensationPlanner(const CompensationParams& params, const MotionModel& model,
                                         std::unique_ptr<CompensatorInterface> compensator)
    : params_(params),
      axis_(params.drill_axis),
      compensator_(std::move(compensator)),
      segmenter_((params.validate(), params.period_s), params.accel_ratio) {
  axis_.normalize();
  if (!compensator_) throw std::invalid_argument("compensator: none given");
  compensator_->setPatient(model, params_);
}

void CompensationPlanner::start(CompensationMode mode, double t_reg) {
  if (!std::isfinite(t_reg)) throw std::invalid_argument("registration time must be finite");
  if (mode != CompensationMode::kStationary && !compensator_->ready()) {
    throw std::logic_error(std::string(toString(mode)) + " mode: the compensator is not ready (" +
                           compensator_->describe() +
                           "; the paper's needs the ventilator settings and breath phase)");
  }
  mode_ = mode;
  t_reg_ = t_reg;
  feed_held_ = false;
  y_reg_ = mode == CompensationMode::kStationary ? Eigen::Vector3d::Zero()
                                                 : compensator_->displacement(t_reg);
}

void CompensationPlanner::holdFeed(double t) {
  if (!std::isfinite(t)) throw std::invalid_argument("hold time must be finite");
  if (feed_held_) return;
  feed_held_ = true;
  t_hold_ = t;
}

Eigen::Vector3d CompensationPlanner::boneDisplacementSinceStart(double t) const {
  if (mode_ == CompensationMode::kStationary) return Eigen::Vector3d::Zero();
  return compensator_->displacement(t) - y_reg_;
}

double CompensationPlanner::nominalFeed(double t) const {
  const double t_feed = feed_held_ ? std::min(t, t_hold_) : t;
  return params_.feed_rate_m_s * std::max(0.0, t_feed - t_reg_);
}

Eigen::Vector3d CompensationPlanner::reference(double t) const {
  Eigen::Vector3d r = nominalFeed(t) * axis_;
  if (mode_ != CompensationMode::kCompensated) return r;
  const Eigen::Vector3d y = compensator_->displacement(t + params_.latency_s) - y_reg_;
  const double along = y.dot(axis_);
  r += along * axis_;
  if (params_.compensate_lateral) r += y - along * axis_;
  return r;
}

int CompensationPlanner::segmentIndexAt(double t) const {
  if (!(t > t_reg_)) return 0;
  return static_cast<int>(std::floor((t - t_reg_) / params_.period_s));
}

Eigen::Vector3d CompensationPlanner::referenceVelocity(double t, bool left) const {
  // One-sided difference over 1 us: exact for the linear pieces of a square flow, and 1e-6
  // relative for the exponential expiration; never across a flow step.
  constexpr double h = 1e-6;
  return left ? (reference(t) - reference(t - h)) / h : (reference(t + h) - reference(t)) / h;
}

PlannedSegment CompensationPlanner::exactSegment(int k) const {
  PlannedSegment out;
  out.index = k;
  out.t0 = t_reg_ + k * params_.period_s;
  out.t1 = out.t0 + params_.period_s;
  // Samples at t0 + i T / n, and knots where the commanded reference's velocity steps: at each
  // flow step (shifted by the latency, since the reference is y(t + latency)) a point with the
  // velocity before the step and, 1 ms later, one with the velocity after it.
  struct Knot {
    double t;
    bool left;
  };
  std::vector<Knot> knots;
  const int n = params_.points_per_segment;
  for (int i = 1; i <= n; ++i) knots.push_back({pointTime(out, params_.period_s, i, n), true});
  if (mode_ == CompensationMode::kCompensated && compensator_->ready()) {
    constexpr double kStepWidth = 1e-3;
    const double lat = params_.latency_s;
    for (double step : compensator_->velocitySteps(out.t0 + lat, out.t1 + lat)) {
      const double s = step - lat;
      knots.push_back({s, true});
      if (s + kStepWidth < out.t1) knots.push_back({s + kStepWidth, false});
    }
  }
  std::sort(knots.begin(), knots.end(), [](const Knot& a, const Knot& b) { return a.t < b.t; });
  out.feed_start_m = reference(out.t0).dot(axis_);
  for (std::size_t i = 0; i < knots.size(); ++i) {
    if (i > 0 && knots[i].t <= knots[i - 1].t + 1e-9) continue;  // a knot on a sample time
    PlannedPoint pt;
    pt.t = knots[i].t;
    const Eigen::Vector3d p = reference(pt.t);
    pt.feed_m = p.dot(axis_);
    pt.feed_velocity_m_s = referenceVelocity(pt.t, knots[i].left).dot(axis_);
    pt.lateral_m = p - pt.feed_m * axis_;
    out.points.push_back(pt);
  }
  out.feed_end_m = out.points.back().feed_m;
  return out;
}

PlannedSegment CompensationPlanner::segment(int k) const {
  if (params_.segment_profile == SegmentProfile::kExact) return exactSegment(k);
  PlannedSegment out;
  out.index = k;
  out.t0 = t_reg_ + k * params_.period_s;
  out.t1 = out.t0 + params_.period_s;
  const int n = params_.points_per_segment;
  out.points.reserve(n);
  const Eigen::Vector3d p0 = reference(out.t0);
  const Eigen::Vector3d p1 = reference(out.t1);
  const Segment seg = segmenter_.plan(out.t0, p0, p1);
  out.feed_start_m = p0.dot(axis_);
  out.feed_end_m = p1.dot(axis_);
  for (int i = 1; i <= n; ++i) {
    PlannedPoint pt;
    pt.t = pointTime(out, params_.period_s, i, n);
    const Eigen::Vector3d p = i == n ? p1 : seg.position(pt.t);
    pt.feed_m = p.dot(axis_);
    pt.feed_velocity_m_s = i == n ? 0.0 : seg.velocity(pt.t).dot(axis_);
    pt.lateral_m = p - pt.feed_m * axis_;
    out.points.push_back(pt);
  }
  return out;
}

Eigen::Vector3d CompensationPlanner::segmentedReference(double t) const {
  return segmentedSample(t).position;
}

SegmentSample CompensationPlanner::segmentedSample(double t) const {
  if (params_.segment_profile == SegmentProfile::kExact) {
    return {reference(t), referenceVelocity(t, false)};
  }
  const int k = segmentIndexAt(t);
  const double t0 = t_reg_ + k * params_.period_s;
  const Segment seg = segmenter_.plan(t0, reference(t0), reference(t0 + params_.period_s));
  SegmentSample out;
  out.position = seg.position(t);
  out.velocity = seg.velocity(t);
  return out;
}

// ---------------------------------------------------------------------------------------------

ArmCompensation::ArmCompensation(const KinematicChain& arm, const Eigen::VectorXd& drilling_q,
                                 double feed_home_m)
    : arm_(arm), feed_home_(feed_home_m) {
  require(std::isfinite(feed_home_m) && feed_home_m >= 0.0, "feed_home_m",
          "must be finite and >= 0");
  require(drilling_q.size() == static_cast<int>(arm_.numJoints()) && drilling_q.allFinite(),
          "drilling_pose", "needs one finite value per arm joint");
  const Eigen::Isometry3d pose = arm_.forward(drilling_q);
  drilling_q_ = drilling_q;
  drilling_pose_ = pose;
  axis_ = pose.linear().col(2).normalized();
  home_pose_ = pose;
  home_pose_.translation() -= feed_home_m * axis_;
  if (feed_home_m == 0.0) {
    home_q_ = drilling_q;
    return;
  }
  const IkResult ik = arm_.inverse(home_pose_, drilling_q);
  if (!ik.success) {
    throw std::invalid_argument("feed_home_m: the arm cannot back off the drilling pose by " +
                                std::to_string(feed_home_m) + " m: " + ik.message);
  }
  home_q_ = ik.q;
}

void ArmCompensation::setTipAtPose(const Eigen::Vector3d& tip) {
  require(tip.allFinite(), "tip_link", "the drill tip at the drilling pose must be finite");
  tip_at_pose_ = tip;
}

Eigen::Vector3d ArmCompensation::tipAt(const std::string& urdf_xml, const std::string& base_link,
                                       const std::string& tip_link,
                                       const std::vector<std::string>& arm_joints,
                                       const Eigen::VectorXd& arm_q) {
  const KinematicChain chain = KinematicChain::fromUrdfString(urdf_xml, base_link, tip_link);
  const std::vector<std::string>& names = chain.jointNames();
  require(names.size() >= arm_joints.size() &&
              std::equal(arm_joints.begin(), arm_joints.end(), names.begin()) &&
              arm_q.size() == static_cast<int>(arm_joints.size()),
          "tip_link",
          "the chain " + base_link + " -> " + tip_link + " must start with the arm's joints");
  Eigen::VectorXd q = Eigen::VectorXd::Zero(static_cast<int>(names.size()));
  q.head(arm_q.size()) = arm_q;
  return chain.forward(q).translation();
}

Eigen::VectorXd ArmCompensation::lateral(const Eigen::Vector3d& lateral,
                                         const Eigen::VectorXd& seed) const {
  if (!lateral.allFinite()) throw std::runtime_error("lateral offset is not finite");
  Eigen::Isometry3d target = home_pose_;
  target.translation() += lateral;
  IkOptions options;
  options.max_attempts = 3;
  const IkResult ik = arm_.inverse(target, seed, options);
  if (!ik.success) throw std::runtime_error("lateral compensation IK failed: " + ik.message);
  return ik.q;
}

std::optional<ArmCompensation> ArmCompensation::aimedAt(const Eigen::Vector3d& entry,
                                                        const Eigen::Vector3d& direction,
                                                        double standoff_m, std::string* why) const {
  if (!entry.allFinite() || !direction.allFinite() || direction.norm() < 1e-9 ||
      !std::isfinite(standoff_m) || standoff_m < 0.0) {
    *why = "the target's entry, direction and standoff must be finite (a non-zero direction)";
    return std::nullopt;
  }
  if (!tip_at_pose_) {
    *why = "the drill tip's position is unknown (tip_link)";
    return std::nullopt;
  }
  const Eigen::Vector3d d = direction.normalized();
  // The tip rides with the device: its offset in the device frame at the configured pose.
  const Eigen::Vector3d tip_in_device = drilling_pose_.inverse() * *tip_at_pose_;
  Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
  target.linear() =
      Eigen::Quaterniond::FromTwoVectors(axis_, d).toRotationMatrix() * drilling_pose_.linear();
  const Eigen::Vector3d tip = entry - standoff_m * d;
  target.translation() = tip - target.linear() * tip_in_device;
  const IkResult ik = arm_.inverse(target, drilling_q_);
  if (!ik.success) {
    std::ostringstream os;
    os << "the arm cannot reach the drilling pose aimed at the plan (tip at " << tip.transpose()
       << " m, axis " << d.transpose() << "): " << ik.message;
    *why = os.str();
    return std::nullopt;
  }
  try {
    ArmCompensation aimed(arm_, ik.q, feed_home_);
    aimed.setTipAtPose(arm_.forward(ik.q) * tip_in_device);
    return aimed;
  } catch (const std::exception& e) {
    *why = e.what();
    return std::nullopt;
  }
}

}  // namespace pedicle_drilling::core
