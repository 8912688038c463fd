#include "pedicle_drilling/core/control/trial_sequencer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {

const char* toString(TrialPhase p) {
  switch (p) {
    case TrialPhase::kIdle:
      return "idle";
    case TrialPhase::kMovingToPose:
      return "moving_to_pose";
    case TrialPhase::kRegistering:
      return "registering";
    case TrialPhase::kDrilling:
      return "drilling";
    case TrialPhase::kStopped:
      return "stopped";
    case TrialPhase::kRetreating:
      return "retreating";
    case TrialPhase::kDone:
      return "done";
    case TrialPhase::kFailed:
      return "failed";
  }
  return "unknown";
}

bool isRunning(TrialPhase p) {
  return p != TrialPhase::kIdle && p != TrialPhase::kDone && p != TrialPhase::kFailed;
}

namespace {

void require(bool ok, const std::string& field, const std::string& rule) {
  if (!ok) throw std::invalid_argument(field + ": " + rule);
}

/**
 * @brief *frame_from_world for a marker sample's frame: the identity for the world frame (or
 *        no frame), else the lookup's; false while the lookup does not know it.
 */
bool frameFromWorld(const std::string& frame, const std::string& world_frame,
                    const FrameLookup& lookup, Eigen::Isometry3d* frame_from_world) {
  if (frame.empty() || frame == world_frame) {
    *frame_from_world = Eigen::Isometry3d::Identity();
    return true;
  }
  return lookup && lookup(frame, frame_from_world);
}

}  // namespace

const ParamTable<TrialSequencerParams>& TrialSequencerParams::table() {
  static const ParamTable<TrialSequencerParams> t = [] {
    using P = TrialSequencerParams;
    ParamTable<P> d;
    d.number("feed_rate_mm_s", &P::default_feed_rate_mm_s, Range::aboveUpTo(0, 10), "mm/s")
        .number("spindle_rpm", &P::default_spindle_rpm, Range::aboveUpTo(0, 60000), "rpm")
        .number("max_feed_rate_mm_s", &P::max_feed_rate_mm_s, Range::aboveUpTo(0, 10), "mm/s")
        .number("max_spindle_rpm", &P::max_spindle_rpm, Range::aboveUpTo(0, 60000), "rpm")
        .number("spindle_keepalive_s", &P::spindle_keepalive_s, Range::closed(0, 10), "s")
        .number("max_duration_s", &P::default_max_duration_s, Range::aboveUpTo(0, 3600), "s")
        .include(CompensationParams::table(), &P::compensation)
        .number("move_duration_s", &P::move_duration_s, Range::aboveUpTo(0, 60), "s")
        .number("settle_s", &P::settle_s, Range::closed(0, 60), "s")
        .integer("registration_samples", &P::registration_samples, Range::closed(1, 100))
        .flag("target_from_plan", &P::target_from_plan)
        .number("target_standoff_m", &P::target_standoff_m, Range::closed(0, 0.05), "m")
        .number("target_marker_age_s", &P::target_marker_age_s, Range::aboveUpTo(0, 10), "s")
        .integer("tare_samples", &P::tare_samples, Range::closed(0, 100000))
        .number("tare_max_spread_n", &P::tare_max_spread_n, Range::aboveUpTo(0, 100), "N")
        .number("registration_timeout_s", &P::registration_timeout_s, Range::aboveUpTo(0, 60), "s")
        .number("stop_hold_s", &P::stop_hold_s, Range::closed(0, 60), "s")
        .number("recognizer_timeout_s", &P::recognizer_timeout_s, Range::closed(0, 60), "s")
        .number("monitor_timeout_s", &P::monitor_timeout_s, Range::closed(0, 60), "s")
        .number("outer_cortical_max_mm", &P::outer_cortical_max_mm, Range::closed(0, 100), "mm")
        .number("cancellous_max_mm", &P::cancellous_max_mm, Range::closed(0, 100), "mm")
        .number("recognizer_delay_s", &P::recognizer_delay_s, Range::closed(0, 60), "s")
        .include(RetreatParams::table(), &P::retreat)
        .text("feed_joint", &P::feed_joint)
        .include(ControllerLayoutParams::table(), &P::controllers)
        .include(ControllerWatchParams::table(), &P::controller_watch, "controller_watch/")
        .include(DepthLimitParams::table(), &P::depth_limit, "depth_limit/");
    return d;
  }();
  return t;
}

void TrialSequencerParams::validate() const {
  table().validate(*this);
  compensation.validate();
  require(default_feed_rate_mm_s <= max_feed_rate_mm_s, "feed_rate_mm_s",
          "must not exceed max_feed_rate_mm_s (the drill's limit, " +
              std::to_string(max_feed_rate_mm_s) + " mm/s)");
  require(default_spindle_rpm <= max_spindle_rpm, "spindle_rpm",
          "must not exceed max_spindle_rpm (the drill's limit, " + std::to_string(max_spindle_rpm) +
              " rpm)");
  require(!arm_joints.empty(), "arm_joints", "must not be empty");
  require(!feed_joint.empty(), "feed_joint", "must not be empty");
  require(std::isfinite(feed_lower_m) && std::isfinite(feed_upper_m) && feed_lower_m < feed_upper_m,
          "feed_joint", "limits must be finite with lower < upper");
}

bool SequencerOutput::publishesAnything() const {
  return !(trajectories.empty() && spindle_rpm.empty() && phases.empty() && predicted.empty() &&
           stops.empty() && tare_requests.empty());
}

bool SequencerOutput::empty() const {
  return !publishesAnything() && start_timers.empty() && !stop_timers && log.empty();
}

TrialSequencer::TrialSequencer(const TrialSequencerParams& params, const ArmCompensation& arm,
                               std::string world_frame)
    : params_(params),
      configured_arm_(arm),
      arm_(arm),
      world_frame_(std::move(world_frame)),
      retreat_planner_(params.retreat) {
  params_.compensation.drill_axis = arm_.drillAxis();
  params_.validate();
  arm_q_ = arm_.homeJoints();
  std::vector<std::string> commandable = params_.arm_joints;
  commandable.push_back(params_.feed_joint);
  controllers_ = controllerLayout(params_.controllers, commandable);
  watch_ = std::make_unique<ControllerWatch>(params_.controller_watch, controllers_,
                                             std::vector<std::string>{params_.feed_joint});
}

TrajectoryCommand toExecutorCommand(const JointTrajectoryCommand& c) {
  TrajectoryCommand command;
  command.joint_names = c.joint_names;
  command.start_time_s = c.start_time;  // the header stamp: takes over then
  for (const JointTrajectoryCommand::Point& p : c.points) {
    command.points.push_back({c.start_time + p.time_from_start, p.positions, p.velocities, {}});
  }
  return command;
}

void TrialSequencer::send(JointTrajectoryCommand traj, double now) {
  watch_->onCommand(now, toExecutorCommand(traj));
  out_.trajectories.push_back(std::move(traj));
}

void TrialSequencer::onControllerState(double now, const std::string& name,
                                       const ControllerStateSample& state) {
  const std::string why = watch_->onState(now, name, state);
  if (!why.empty()) controllerFault(now, why);
}

void TrialSequencer::onControllerFault(double now, const std::string& why) {
  if (isRunning(phase_)) controllerFault(now, why);
}

void TrialSequencer::controllerFault(double now, const std::string& why) {
  log(SequencerLog::Level::kError, why + "; stopping and retracting");
  out_.stops.push_back(why);
  handleStop(now, true, why);
}

bool TrialSequencer::compensatorFailed(double now) {
  if (compensator_ == nullptr || compensator_->error().empty() || compensator_reported_) {
    return false;
  }
  compensator_reported_ = true;
  const std::string why = "compensator error (" + compensator_->describe() + ")";
  log(SequencerLog::Level::kError, why + "; stopping and retracting");
  if (isRunning(phase_)) out_.stops.push_back(why);
  handleStop(now, true, why);
  return true;
}

void TrialSequencer::setVentilator(const VentilatorSettings& settings) {
  settings.validate();  // invalid settings are the caller's error, refused here
  settings_ = settings;
  have_settings_ = true;
  if (planner_) planner_->compensator().setVentilator(settings_);
}

void TrialSequencer::setBreathStart(double t) {
  if (!std::isfinite(t)) return;
  breath_start_ = t;
  have_phase_ = true;
  if (planner_) planner_->compensator().setBreathStart(t);
}

void TrialSequencer::setBreathSource(const std::string& source, double timeout_periods) {
  breath_source_ = source;
  breath_timeout_periods_ = timeout_periods;
}

void TrialSequencer::setBreathSourceProblem(const std::string& problem) {
  breath_source_problem_ = problem;
}

std::string TrialSequencer::breathProblem(double now) const {
  if (!breath_source_problem_.empty()) return breath_source_problem_;
  if (!haveVentilator()) {
    return "no ventilator/settings or tidal_volume received (breath source: " + breath_source_ +
           ")";
  }
  const double period = 60.0 / settings_.rate_bpm;
  const double age = now - breath_start_;
  if (breath_timeout_periods_ <= 0.0 || age <= breath_timeout_periods_ * period) return "";
  std::ostringstream os;
  os.precision(4);
  os << "breath source silent: no breath start from " << breath_source_ << " for " << age
     << " s (more than breath_timeout_periods " << breath_timeout_periods_ << " x the " << period
     << " s breath period)";
  return os.str();
}

double TrialSequencer::limitAdvance(double t) const {
  return planner_ ? planner_->predictedAdvance(t) : 0.0;
}

SequencerOutput TrialSequencer::takeOutput() {
  SequencerOutput out = std::move(out_);
  out_ = SequencerOutput();
  return out;
}

void TrialSequencer::setPhase(TrialPhase p) {
  phase_ = p;
  if (p == TrialPhase::kDone || p == TrialPhase::kFailed) watch_->stop();
  out_.phases.push_back(p);
}

void TrialSequencer::log(SequencerLog::Level level, const std::string& text) {
  out_.log.push_back({level, text});
}

void TrialSequencer::spindle(double rpm) {
  spindle_commanded_rpm_ = rpm;
  out_.spindle_rpm.push_back(rpm);
}

void TrialSequencer::onSpindleKeepalive(double) {
  if (spindle_commanded_rpm_ > 0.0) out_.spindle_rpm.push_back(spindle_commanded_rpm_);
}

void TrialSequencer::fail(const std::string& why) {
  log(SequencerLog::Level::kError, "trial failed: " + why);
  spindle(0.0);
  out_.stop_timers = true;
  out_.start_timers.clear();
  setPhase(TrialPhase::kFailed);
}

std::string TrialSequencer::check(const TrialRequest& request) const {
  ResolvedRequest resolved;
  return resolve(request, &resolved);
}

std::string TrialSequencer::resolve(const TrialRequest& request, ResolvedRequest* out) const {
  if (isRunning(phase_)) {
    return std::string("a trial is running (status ") + toString(phase_) + ")";
  }
  CompensationMode mode;
  if (!parseCompensationMode(request.mode, &mode)) {
    return "mode: unknown mode '" + request.mode +
           "' (use stationary, uncompensated or compensated)";
  }
  std::string why;
  // `limit`: the parameter declaring the bound ("" for a fixed one), named in the refusal.
  const auto pick = [&why](double requested, double fallback, double max, const char* name,
                           const char* limit, const char* unit) {
    if (requested == 0.0 || !why.empty()) return fallback;
    if (!(std::isfinite(requested) && requested > 0.0 && requested <= max)) {
      std::ostringstream os;
      os << name << ": " << requested << " " << unit;
      if (*limit != '\0' && requested > max) {
        os << " exceeds the drill's declared limit " << limit << " = " << max << " " << unit;
      }
      os << " (must be 0 for the default or in (0, " << max << "])";
      why = os.str();
    }
    return requested;
  };
  const TrialSequencerParams& p = params_;
  const double feed_mm_s =
      pick(request.feed_rate_mm_s, p.default_feed_rate_mm_s, p.max_feed_rate_mm_s, "feed_rate_mm_s",
           "max_feed_rate_mm_s", "mm/s");
  const double rpm = pick(request.spindle_rpm, p.default_spindle_rpm, p.max_spindle_rpm,
                          "spindle_rpm", "max_spindle_rpm", "rpm");
  const double max_duration =
      pick(request.max_duration_s, p.default_max_duration_s, 3600.0, "max_duration_s", "", "s");
  if (!why.empty()) return why;
  SegmentProfile profile = params_.compensation.segment_profile;
  if (!request.segment_profile.empty() && !parseSegmentProfile(request.segment_profile, &profile)) {
    return "segment_profile: unknown profile '" + request.segment_profile +
           "' (use rest_to_rest or exact; empty: the planner's)";
  }
  if (mode != CompensationMode::kStationary &&
      (!haveVentilator() || !breath_source_problem_.empty())) {
    return std::string(toString(mode)) +
           " mode needs the ventilator's breath phase: " + breathProblem(0.0);
  }
  *out = {mode, feed_mm_s, rpm, max_duration, profile};
  return "";
}

std::string TrialSequencer::start(const TrialRequest& request, const MotionModel& model,
                                  double now) {
  ResolvedRequest r;
  const std::string why = resolve(request, &r);
  if (!why.empty()) return why;
  if (r.mode != CompensationMode::kStationary) {
    const std::string breath = breathProblem(now);
    if (!breath.empty()) {
      return std::string(toString(r.mode)) + " mode needs the ventilator's breath phase: " + breath;
    }
  }
  if (plan_) {
    const std::string bad = plan_->check();
    if (!bad.empty()) return bad;
    if (!arm_.tipAtPose()) return "drilling plan: the drill tip's position is unknown (tip_link)";
  } else if (params_.depth_limit.require_plan) {
    return "no drilling plan (drilling_plan): the depth limit needs the planned entry and depth";
  }
  const std::string unaimed = aimAtPlan(now);
  if (!unaimed.empty()) return unaimed;
  const std::string unwatched = watch_->start(now);
  if (!unwatched.empty()) return unwatched;
  const CompensationMode mode = r.mode;
  const double feed_mm_s = r.feed_mm_s;
  const double rpm = r.rpm;
  const double max_duration = r.max_duration_s;
  CompensationParams cp = params_.compensation;
  cp.drill_axis = arm_.drillAxis();
  cp.feed_rate_m_s = feed_mm_s * 1e-3;
  cp.segment_profile = r.profile;
  try {
    // Behind a guard: what the class throws during the trial is a stop (compensatorFailed).
    auto guarded = std::make_unique<GuardedCompensator>(
        make_compensator_ ? make_compensator_() : std::make_unique<PaperCompensator>());
    GuardedCompensator* guard = guarded.get();
    auto planner = std::make_unique<CompensationPlanner>(cp, model, std::move(guarded));
    if (have_settings_) planner->compensator().setVentilator(settings_);
    if (have_phase_) planner->compensator().setBreathStart(breath_start_);
    if (!guard->error().empty()) throw std::runtime_error("compensator " + guard->error());
    planner_ = std::move(planner);
    compensator_ = guard;
    compensator_reported_ = false;
  } catch (const std::exception& e) {
    watch_->stop();
    return e.what();
  }
  mode_ = mode;
  spindle_rpm_ = rpm;
  max_duration_s_ = max_duration;
  registered_ = false;
  tare_pending_ = false;
  reg_count_ = 0;
  retreat_.reset();
  arm_q_ = arm_.homeJoints();
  spindle(spindle_rpm_);
  sendMoveToPose(now);
  setPhase(TrialPhase::kMovingToPose);
  out_.start_timers.push_back(
      {TimerRequest::Kind::kPoseReached, params_.move_duration_s + params_.settle_s, false});
  if (params_.spindle_keepalive_s > 0.0) {
    out_.start_timers.push_back(
        {TimerRequest::Kind::kSpindleKeepalive, params_.spindle_keepalive_s, true});
  }
  std::ostringstream os;
  os << "trial started: " << toString(mode) << ", feed " << feed_mm_s << " mm/s, spindle " << rpm
     << " rpm";
  log(SequencerLog::Level::kInfo, os.str());
  return "";
}

std::string TrialSequencer::aimAtPlan(double now) {
  arm_ = configured_arm_;
  if (!params_.target_from_plan) return "";
  if (!plan_) return "drilling target from the plan (target_from_plan): no drilling plan";
  if (!idle_marker_ || now - idle_marker_->first > params_.target_marker_age_s) {
    std::ostringstream os;
    os << "drilling target from the plan (target_from_plan): no tracked marker pose in the last "
       << params_.target_marker_age_s << " s (tracker/marker_pose) to place the plan";
    return os.str();
  }
  const Eigen::Isometry3d& world_from_marker = idle_marker_->second;
  std::string why;
  std::optional<ArmCompensation> aimed = configured_arm_.aimedAt(
      world_from_marker * plan_->entry, world_from_marker.linear() * plan_->direction,
      params_.target_standoff_m, &why);
  if (!aimed) return "drilling target from the plan (target_from_plan): " + why;
  arm_ = *aimed;
  std::ostringstream os;
  os << "drilling pose aimed at the plan: joints";
  for (int i = 0; i < arm_.drillingJoints().size(); ++i) os << " " << arm_.drillingJoints()[i];
  log(SequencerLog::Level::kInfo, os.str());
  return "";
}

void TrialSequencer::sendMoveToPose(double now) {
  JointTrajectoryCommand traj;
  traj.start_time = now;
  traj.joint_names = params_.arm_joints;
  traj.joint_names.push_back(params_.feed_joint);
  JointTrajectoryCommand::Point goal;
  for (int i = 0; i < arm_q_.size(); ++i) goal.positions.push_back(arm_q_[i]);
  goal.positions.push_back(arm_.feedHome());
  goal.velocities.assign(goal.positions.size(), 0.0);
  goal.time_from_start = params_.move_duration_s;
  // One point: the controller moves from its own current state (JointTrajectoryController
  // semantics), which stays right when a component reset the robot before this trial.
  traj.points.push_back(goal);
  send(std::move(traj), now);
}

void TrialSequencer::onPoseReached(double now) {
  if (phase_ != TrialPhase::kMovingToPose) return;
  registration_open_ = now;
  registration_deadline_ = now + params_.registration_timeout_s;
  setPhase(TrialPhase::kRegistering);
  out_.start_timers.push_back(
      {TimerRequest::Kind::kRegistrationTimeout, params_.registration_timeout_s, false});
  if (params_.tare_samples > 0) {
    // The arm is at the drilling pose, the spindle running, the tool free: the sensor's bias.
    out_.tare_requests.push_back({params_.tare_samples, params_.tare_max_spread_n});
    tare_pending_ = true;
  }
}

void TrialSequencer::onTareResult(double now, const TareResult& result) {
  if (phase_ != TrialPhase::kRegistering || !tare_pending_) return;
  tare_pending_ = false;
  if (!result.success) {
    fail("F/T tare: " + result.message);
    return;
  }
  log(SequencerLog::Level::kInfo, "F/T " + result.message);
  // The segment grid starts when both are done: the later of the two instants.
  if (registered_) startDrilling(now, std::max(t_registered_, result.t));
  compensatorFailed(now);
}

void TrialSequencer::onRegistrationTimeout(double) {
  if (phase_ == TrialPhase::kRegistering && registered_ && tare_pending_) {
    std::ostringstream os;
    os << "no F/T tare result (ft_sensor/tare_result) within " << params_.registration_timeout_s
       << " s of the drilling pose";
    fail(os.str());
  } else if (phase_ == TrialPhase::kRegistering) {
    std::ostringstream os;
    os << "no tracker/marker_pose message for registration within "
       << params_.registration_timeout_s << " s";
    fail(os.str());
  }
}

Eigen::Vector3d TrialSequencer::boneDisplacementSinceMarker(double t) const {
  // mode_, not planner_->mode(): the planner only starts after the registration.
  if (mode_ == CompensationMode::kStationary) return Eigen::Vector3d::Zero();
  return planner_->compensator().displacement(t) - y_marker_reg_;
}

void TrialSequencer::onMarker(double now, double stamp, const std::string& frame,
                              const Eigen::Vector3d& p, const Eigen::Quaterniond& orientation,
                              const FrameLookup& lookup) {
  if (!isRunning(phase_)) {
    // Outside a trial, only for a pose aimed at the plan: the marker's latest world pose.
    Eigen::Isometry3d frame_from_world;
    if (params_.target_from_plan && p.allFinite() &&
        frameFromWorld(frame, world_frame_, lookup, &frame_from_world)) {
      idle_marker_.emplace(
          stamp, frame_from_world.inverse() * (Eigen::Translation3d(p) * orientation.normalized()));
    }
    return;
  }
  if (phase_ == TrialPhase::kRegistering) {
    if (!registered_) registerSample(now, stamp, frame, p, orientation, lookup);  // else: the tare
    compensatorFailed(now);
    return;
  }
  if (!registered_ || !planner_ ||
      (phase_ != TrialPhase::kDrilling && phase_ != TrialPhase::kStopped &&
       phase_ != TrialPhase::kRetreating)) {
    return;
  }
  // Predicted marker pose at the tracker's own time stamp, for the safety monitor.
  PredictedMarker m;
  m.stamp = stamp;
  m.frame = marker_frame_;
  m.position = marker_reg_ + rotation_ * boneDisplacementSinceMarker(stamp);
  m.orientation = marker_orientation_;
  out_.predicted.push_back(m);
  if (phase_ == TrialPhase::kDrilling && p.allFinite()) {
    // The tracked bone against the predicted one along the drill axis: positive when the bone
    // is nearer the drill than predicted (DepthLimit's correction).
    depth_.onResidual(-(rotation_.transpose() * (p - m.position)).dot(planner_->axis()));
  }
  // Then the compensator hears the sample (a tracker-feedback one): the prediction above was
  // made without it, so that the monitor judges a prediction, not the measurement itself.
  if (p.allFinite()) planner_->compensator().observeMarker(stamp, rotation_.transpose() * p);
  compensatorFailed(now);
}

void TrialSequencer::registerSample(double now, double stamp, const std::string& frame,
                                    const Eigen::Vector3d& pos,
                                    const Eigen::Quaterniond& orientation,
                                    const FrameLookup& lookup) {
  if (now > registration_deadline_) {
    fail("no usable tracker/marker_pose message for registration");
    return;
  }
  if (stamp < registration_open_) return;  // measured before the arm settled
  if (!pos.allFinite()) {
    fail("non-finite marker pose during registration");
    return;
  }
  if (reg_count_ == 0) {
    marker_frame_ = frame;
    if (!frameFromWorld(marker_frame_, world_frame_, lookup, &frame_from_world_)) {
      log(SequencerLog::Level::kWarn,
          "waiting for the transform " + world_frame_ + " -> " + marker_frame_);
      return;
    }
    rotation_ = frame_from_world_.linear();
    planner_->compensator().observeMarker(stamp, rotation_.transpose() * pos);
    if (mode_ != CompensationMode::kStationary && !planner_->compensator().ready()) {
      fail("the compensator is not ready at the registration (" +
           planner_->compensator().describe() + ")");
      return;
    }
    y_marker_reg_ = mode_ == CompensationMode::kStationary
                        ? Eigen::Vector3d::Zero()
                        : planner_->compensator().displacement(stamp);
    marker_orientation_ = orientation;
    marker_sum_.setZero();
  } else if (frame != marker_frame_) {
    fail("marker frame changed during registration");
    return;
  } else {
    planner_->compensator().observeMarker(stamp, rotation_.transpose() * pos);
  }
  // Average the samples, each moved back to the first sample's time by the prediction.
  marker_sum_ += pos - rotation_ * boneDisplacementSinceMarker(stamp);
  if (++reg_count_ < params_.registration_samples) return;
  marker_reg_ = marker_sum_ / reg_count_;
  registered_ = true;
  t_registered_ = stamp;
  if (tare_pending_) {
    log(SequencerLog::Level::kInfo, "marker registered; waiting for the F/T tare");
    return;
  }
  startDrilling(now, stamp);
}

void TrialSequencer::onRecognizerState(double now, bool stop, const std::string& state_name,
                                       int key_point) {
  recognizer_reports_stop_ = stop;
  last_recognizer_t_ = now;
  if (phase_ == TrialPhase::kDrilling) {
    updateDeepest(now);
    watchLayers(state_name);
    checkLayers(now);
  }
  if (stop && phase_ == TrialPhase::kDrilling) {
    handleStop(now, false,
               "drilling_state reports a recognizer stop (state " + state_name + ", key point " +
                   std::to_string(key_point) + ")");
  }
  compensatorFailed(now);
}

void TrialSequencer::startDrilling(double now, double t_reg) {
  if (recognizer_reports_stop_) {
    fail(
        "refusing to feed: the StateRecognizer reports a stop latched from an earlier trial "
        "(drilling_state.stop); reset it (~reset, or list it in ~trial_start_services)");
    return;
  }
  // The segment grid starts at the registration time, the stamp of the last registration
  // sample (the instant the marker was measured), not when its message was handled: on ROS the
  // handling time is the last /clock tick, which trails the stamp by a scheduling-dependent
  // amount and moved the 125 ms grid against the breath from run to run.
  planner_->start(mode_, t_reg);
  depth_ = DepthLimit(params_.depth_limit);
  depth_hold_t_ = -1.0;
  if (plan_) {
    const Eigen::Isometry3d world_from_marker =
        frame_from_world_.inverse() * (Eigen::Translation3d(marker_reg_) * marker_orientation_);
    const std::string bad =
        depth_.begin(*plan_, world_from_marker, *arm_.tipAtPose(), planner_->axis());
    if (!bad.empty()) {
      fail(bad);
      return;
    }
    log(SequencerLog::Level::kInfo, "depth limit: " + depth_.describe());
  } else if (params_.depth_limit.require_plan) {
    // The plan was withdrawn (or refused) after the start: no feed without one (fails closed).
    fail("no drilling plan at the registration (drilling_plan): the depth limit needs one");
    return;
  }
  t_end_ = t_reg + max_duration_s_;
  next_k_ = 0;
  retreat_.reset();
  drilling_since_ = now;
  outer_watch_ = LayerWatch{"outer_cortical"};
  cancellous_watch_ = LayerWatch{"cancellous"};
  deepest_advance_ = 0.0;
  deepest_t_ = -1.0;
  setPhase(TrialPhase::kDrilling);
  log(SequencerLog::Level::kInfo, "marker registered (" + std::to_string(reg_count_) +
                                      " samples), drilling (" + toString(mode_) + ")");
  sendDueSegments(now);
  out_.start_timers.push_back({TimerRequest::Kind::kSegment, planner_->params().period_s, true});
}

void TrialSequencer::onMonitorAlive(double now) { last_monitor_t_ = now; }

void TrialSequencer::updateDeepest(double now) {
  // The deepest predicted advance since the drilling began: the cut's depth, which a breathing
  // bone (uncompensated) moves the tip back from. Sampled every 5 ms between calls, so that a
  // stroke's peak between two segment ticks is not missed.
  constexpr double kStep = 0.005;
  if (deepest_t_ < 0.0) {
    deepest_advance_ = planner_->predictedAdvance(now);
    deepest_t_ = now;
    return;
  }
  const double from = std::max(deepest_t_, now - 10.0);  // bounded work after a long gap
  for (double t = from + kStep; t < now; t += kStep) {
    deepest_advance_ = std::max(deepest_advance_, planner_->predictedAdvance(t));
  }
  deepest_advance_ = std::max(deepest_advance_, planner_->predictedAdvance(now));
  deepest_t_ = std::max(deepest_t_, now);
}

void TrialSequencer::watchLayers(const std::string& state_name) {
  const bool contact = state_name != "idle" && state_name != "stopped";
  for (LayerWatch* w : {&outer_watch_, &cancellous_watch_}) {
    // The outer layer starts with the contact (any state after idle: a recognizer may skip it).
    const bool starts = w == &outer_watch_ ? contact : state_name == w->state;
    if (!w->started && starts) {
      w->started = true;
      w->start_advance = deepest_advance_;
    }
    if (w->started && state_name != w->state) w->done = true;
  }
}

void TrialSequencer::checkLayers(double now) {
  if (checkLayer(now, &outer_watch_, params_.outer_cortical_max_mm, "outer_cortical_max_mm")) {
    return;
  }
  checkLayer(now, &cancellous_watch_, params_.cancellous_max_mm, "cancellous_max_mm");
}

bool TrialSequencer::checkLayer(double now, LayerWatch* w, double bound_mm, const char* param) {
  const double bound_m = bound_mm * 1e-3;
  if (!w->started || w->done || !(bound_m > 0.0)) return false;
  if (w->through_t < 0.0 && deepest_advance_ - w->start_advance >= bound_m) w->through_t = now;
  if (w->through_t < 0.0 || now - w->through_t < params_.recognizer_delay_s) return false;
  std::ostringstream os;
  os << "implausible force: the recognizer still reports the " << w->state << " layer "
     << (deepest_advance_ - w->start_advance) * 1e3
     << " mm deeper into the bone (predicted) than at its first report (" << param << " "
     << bound_mm << "; sensor drift or a missed layer?)";
  const std::string why = os.str();
  log(SequencerLog::Level::kError, why + "; stopping and retracting");
  out_.stops.push_back(why);
  w->done = true;
  handleStop(now, true, why);
  return true;
}

void TrialSequencer::onForce(double now, double stamp, double thrust_n) {
  (void)now;
  if (phase_ != TrialPhase::kDrilling || !depth_.active()) return;
  depth_.onThrust(limitAdvance(stamp), thrust_n);
}

void TrialSequencer::limitDepth(int k) {
  if (!depth_.active() || planner_->feedHeld()) return;
  const CompensationParams& cp = planner_->params();
  if (!(cp.feed_rate_m_s > 0.0)) return;
  const double t0 = planner_->registrationTime() + k * cp.period_s;
  const double t1 = t0 + cp.period_s;
  // What the tip adds to the nominal feed (the compensation against the predicted bone), at
  // the segment's points and, when the drill does not follow the bone (uncompensated), over
  // the next breath as well: the bone breathes into a held drill.
  double horizon = t1;
  if (mode_ == CompensationMode::kUncompensated && have_settings_) {
    horizon += 60.0 / settings_.rate_bpm;
  }
  const int n = std::max(cp.points_per_segment, 1);
  const double step = std::min(cp.period_s / n, 0.02);
  double intrusion = -std::numeric_limits<double>::infinity();
  for (double t = t0; t <= horizon + 1e-12; t += step) {
    intrusion = std::max(intrusion, limitAdvance(t) - planner_->nominalFeed(t));
  }
  const double feed_limit = depth_.limit() - intrusion;
  if (planner_->nominalFeed(t1) <= feed_limit) return;
  // The feed reaches the limit at t_hold (already passed: the feed goes back to it).
  const double t_hold = planner_->registrationTime() + std::max(0.0, feed_limit) / cp.feed_rate_m_s;
  planner_->holdFeed(t_hold);
  depth_hold_t_ = t_hold;
  std::ostringstream os;
  os.precision(3);
  os << std::fixed << "depth limit: feed held at " << std::max(0.0, feed_limit) * 1e3
     << " mm from t = " << t_hold << " s (" << depth_.describe() << ")";
  log(SequencerLog::Level::kWarn, os.str());
}

void TrialSequencer::checkDepthLimit(double now) {
  if (depth_hold_t_ < 0.0 || now < depth_hold_t_ - 1e-9) return;
  std::ostringstream os;
  os.precision(3);
  os << std::fixed << "depth_limit: the tip reached the plan's depth (" << depth_.describe()
     << "); stopping and retracting";
  const std::string why = os.str();
  depth_hold_t_ = -1.0;
  log(SequencerLog::Level::kError, why);
  out_.stops.push_back(why);
  handleStop(now, true, why);
}

void TrialSequencer::onSegmentTimer(double now) {
  compensatorFailed(now);  // also an error of setVentilator or setBreathStart since the last tick
  if (phase_ == TrialPhase::kDrilling) {
    // A component that falls silent while the drill feeds: its nodelet was unloaded or died.
    const auto silent = [this, now](double last, double timeout) {
      return timeout > 0.0 && now - std::max(last, drilling_since_) > timeout;
    };
    std::string why;
    if (silent(last_recognizer_t_, params_.recognizer_timeout_s)) {
      why = "recognizer silent: no drilling_state for more than " +
            std::to_string(params_.recognizer_timeout_s) + " s while drilling";
    } else if (silent(last_monitor_t_, params_.monitor_timeout_s)) {
      why = "safety monitor silent: not heard for more than " +
            std::to_string(params_.monitor_timeout_s) + " s while drilling";
    } else if (mode_ != CompensationMode::kStationary && !breathProblem(now).empty()) {
      why = breathProblem(now);  // the predicted motion's phase is lost: no drilling on a guess
    } else {
      why = watch_->checkSilence(now);
    }
    if (!why.empty()) {
      log(SequencerLog::Level::kError, why + "; stopping and retracting");
      out_.stops.push_back(why);
      handleStop(now, true, why);
    }
  }
  if (phase_ == TrialPhase::kDrilling) {
    updateDeepest(now);
    checkLayers(now);
  }
  if (phase_ == TrialPhase::kDrilling) checkDepthLimit(now);
  if (phase_ == TrialPhase::kDrilling && now >= t_end_) {
    log(SequencerLog::Level::kWarn, "max duration reached, retracting");
    startRetreat(now, "max duration");
  } else if (phase_ == TrialPhase::kStopped && now >= hold_end_) {
    startRetreat(now, "stop hold elapsed");
  } else if (phase_ == TrialPhase::kRetreating && retreat_ && retreat_->finished(now)) {
    out_.stop_timers = true;
    setPhase(TrialPhase::kDone);
    return;
  }
  if (phase_ == TrialPhase::kDrilling || phase_ == TrialPhase::kStopped ||
      phase_ == TrialPhase::kRetreating) {
    sendDueSegments(now);
  }
}

double TrialSequencer::feedCommandAt(double t, double segmented_feed) const {
  double feed = arm_.feedHome() + segmented_feed;
  if (retreat_) feed -= retreat_->position(t).x();
  return std::clamp(feed, params_.feed_lower_m, params_.feed_upper_m);
}

void TrialSequencer::sendDueSegments(double now) {
  const double period = planner_->params().period_s;
  // Segment k goes out one period ahead of its start, when the timer tick of t_k - T fires. The
  // half-period margin makes that tick send it whatever the rounding of the two clocks (the
  // timer's accumulated due time and the grid t_reg + k T differ in the last bits) and a timer
  // that fires a little early: without it, about every other tick missed its segment by 1e-12 s,
  // which then went out at its own start and reached the controller after it; the arm held the
  // last point for the transport delay (a 4 um stall at the bone's 4 mm/s) at every such
  // boundary.
  while (planner_->registrationTime() + next_k_ * period <= now + 1.5 * period) {
    if (phase_ == TrialPhase::kDrilling) limitDepth(next_k_);
    const PlannedSegment seg = planner_->segment(next_k_);
    ++next_k_;
    if (seg.t1 <= now) continue;  // late timer: skip segments already over
    std::vector<double> times;
    std::vector<double> feeds;
    std::vector<double> feed_velocities;
    std::vector<Eigen::Vector3d> lateral;
    const auto add = [&](const PlannedPoint& pt) {
      times.push_back(pt.t);
      feeds.push_back(pt.feed_m);
      feed_velocities.push_back(pt.feed_velocity_m_s);
      lateral.push_back(pt.lateral_m);
    };
    // A trajectory message takes over at its start time (JointTrajectoryController): segment
    // k alone, from t_k.
    for (const PlannedPoint& pt : seg.points) add(pt);
    // While drilling every point carries its planned velocity (the trapezoid's, or the
    // reference's for the exact profile), so that the controller's cubic spline runs the plan;
    // a hold or a retreat adds to the feed, and its velocities come from the points.
    emitTrajectory(now, seg.t0, times, feeds, lateral,
                   phase_ == TrialPhase::kDrilling ? &feed_velocities : nullptr);
    if (phase_ == TrialPhase::kDrilling &&
        arm_.feedHome() + seg.feed_end_m > params_.feed_upper_m - 1e-3) {
      log(SequencerLog::Level::kWarn, "feed axis travel exhausted, retracting");
      startRetreat(now, "feed travel exhausted");
      return;
    }
  }
}

void TrialSequencer::emitTrajectory(double now, double start, const std::vector<double>& times,
                                    const std::vector<double>& feeds,
                                    const std::vector<Eigen::Vector3d>& lateral,
                                    const std::vector<double>* feed_velocities) {
  JointTrajectoryCommand traj;
  traj.start_time = start;
  traj.joint_names = params_.arm_joints;
  traj.joint_names.push_back(params_.feed_joint);
  double prev_t = start;
  double prev_feed = times.empty() ? 0.0 : feedCommandAt(prev_t, feeds.front());
  Eigen::VectorXd prev_q = arm_q_;
  for (std::size_t i = 0; i < times.size(); ++i) {
    Eigen::VectorXd q = arm_q_;
    if (planner_->params().compensate_lateral && lateral[i].norm() > 1e-9) {
      try {
        q = arm_.lateral(lateral[i], arm_q_);
        arm_q_ = q;
      } catch (const std::exception& e) {
        log(SequencerLog::Level::kError, std::string(e.what()) + "; arm held");
      }
    }
    const double feed = feedCommandAt(times[i], feeds[i]);
    const double dt = std::max(1e-6, times[i] - prev_t);
    const bool last = i + 1 == times.size();
    JointTrajectoryCommand::Point pt;
    for (int j = 0; j < q.size(); ++j) {
      pt.positions.push_back(q[j]);
      pt.velocities.push_back(last ? 0.0 : (q[j] - prev_q[j]) / dt);
    }
    pt.positions.push_back(feed);
    pt.velocities.push_back(feed_velocities != nullptr ? (*feed_velocities)[i]
                            : last                     ? 0.0
                                                       : (feed - prev_feed) / dt);
    pt.time_from_start = times[i] - start;
    traj.points.push_back(std::move(pt));
    prev_t = times[i];
    prev_feed = feed;
    prev_q = q;
  }
  send(std::move(traj), now);
}

void TrialSequencer::resendFromNow(double now) {
  const double period = planner_->params().period_s;
  const int k = planner_->segmentIndexAt(now);
  const double t_end = planner_->registrationTime() + (k + 1) * period;
  const int n = planner_->params().points_per_segment;
  std::vector<double> times;
  std::vector<double> feeds;
  std::vector<Eigen::Vector3d> lateral;
  for (int i = 1; i <= n; ++i) {
    const double t = now + (t_end - now) * i / n;
    const Eigen::Vector3d r = planner_->segmentedReference(t);
    const double f = r.dot(planner_->axis());
    times.push_back(t);
    feeds.push_back(f);
    lateral.push_back(r - f * planner_->axis());
  }
  emitTrajectory(now, now, times, feeds, lateral, nullptr);
  next_k_ = k + 1;
  sendDueSegments(now);
}

void TrialSequencer::onStop(double now, bool retreat, const std::string& reason) {
  handleStop(now, retreat, reason);
  compensatorFailed(now);
}

void TrialSequencer::handleStop(double now, bool retreat, const std::string& reason) {
  switch (phase_) {
    case TrialPhase::kMovingToPose:
    case TrialPhase::kRegistering:
      fail("stopped before drilling began: " + reason);
      return;
    case TrialPhase::kDrilling:
    case TrialPhase::kStopped:
      spindle(0.0);
      planner_->holdFeed(now);
      if (retreat || (params_.stop_hold_s == 0.0 && phase_ == TrialPhase::kDrilling)) {
        // A safety stop, or a recognizer stop without a hold: back out at once (a bone that
        // moves more than predicted keeps cutting into a drill held in it).
        startRetreat(now, reason);
      } else if (phase_ == TrialPhase::kDrilling) {
        hold_end_ = now + params_.stop_hold_s;
        setPhase(TrialPhase::kStopped);
        resendFromNow(now);
      }
      return;
    default:
      return;  // idle, already retreating, done: nothing to stop
  }
}

void TrialSequencer::startRetreat(double now, const std::string& why) {
  spindle(0.0);
  planner_->holdFeed(now);
  // The held feed the trajectory settles at (the segment in progress ends there).
  const double feed_now = feedCommandAt(now, planner_->referenceFeed(now));
  // Back along the drill axis (feed coordinate), clamped at the retracted end of the feed.
  const RetreatParams& rp = retreat_planner_.params();
  const double distance = std::max(0.0, std::min(rp.distance_m, feed_now - params_.feed_lower_m));
  retreat_ = std::make_unique<RetreatMotion>(
      now, Eigen::Vector3d::Zero(), Eigen::Vector3d(distance, 0, 0),
      TrapezoidProfile::minimumTime(distance, rp.speed_m_s, rp.accel_m_s2));
  std::ostringstream os;
  os << "retreating " << distance * 1e3 << " mm (" << why << ")";
  log(SequencerLog::Level::kWarn, os.str());
  setPhase(TrialPhase::kRetreating);
  resendFromNow(now);
}

void TrialSequencer::onTimer(TimerRequest::Kind kind, double now) {
  switch (kind) {
    case TimerRequest::Kind::kPoseReached:
      onPoseReached(now);
      break;
    case TimerRequest::Kind::kRegistrationTimeout:
      onRegistrationTimeout(now);
      break;
    case TimerRequest::Kind::kSegment:
      onSegmentTimer(now);
      break;
    case TimerRequest::Kind::kSpindleKeepalive:
      onSpindleKeepalive(now);
      break;
  }
}

void SequencerTimers::apply(const SequencerOutput& out, double now) {
  if (out.stop_timers) timers_.clear();
  for (const TimerRequest& r : out.start_timers) {
    timers_.push_back({r.kind, now + r.delay_s, r.periodic ? r.delay_s : 0.0});
  }
}

std::optional<TimerRequest::Kind> SequencerTimers::popDue(double now) {
  auto best = timers_.end();
  for (auto it = timers_.begin(); it != timers_.end(); ++it) {
    if (it->due <= now + 1e-9 && (best == timers_.end() || it->due < best->due)) best = it;
  }
  if (best == timers_.end()) return std::nullopt;
  const TimerRequest::Kind kind = best->kind;
  if (best->period > 0.0) {
    best->due += best->period;
  } else {
    timers_.erase(best);
  }
  return kind;
}

std::optional<double> SequencerTimers::nextDue() const {
  std::optional<double> next;
  for (const Timer& t : timers_) {
    if (!next || t.due < *next) next = t.due;
  }
  return next;
}

}  // namespace pedicle_drilling::core
