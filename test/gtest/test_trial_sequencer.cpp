// Tests of core::TrialSequencer: the trial sequence of Algorithm 1 driven by explicit time.
#include "pedicle_drilling/core/control/trial_sequencer.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "support.hpp"

namespace pd = pedicle_drilling::core;

namespace {

pd::ArmCompensation workcellArm() {
  const pd::KinematicChain arm = pd::KinematicChain::fromUrdfString(
      pedicle_drilling::test::workcellUrdf(), "world", "device_base");
  Eigen::VectorXd q(6);
  q << 0.0, 0.435859, 1.319709, 0.0, 1.386025, 0.0;  // config/drilling_pose.yaml
  return pd::ArmCompensation(arm, q, 0.01);
}

pd::TrialSequencerParams params() {
  pd::TrialSequencerParams p;
  p.arm_joints = {"rsssii_joint1", "rsssii_joint2", "rsssii_joint3",
                  "rsssii_joint4", "rsssii_joint5", "rsssii_joint6"};
  p.feed_joint = "feed_joint";
  p.feed_lower_m = 0.0;
  p.feed_upper_m = 0.06;
  p.retreat.distance_m = 0.025;
  // Most tests drive the sequence without a recognizer or a monitor: their watchdogs off here,
  // on in the watchdog tests.
  p.recognizer_timeout_s = 0.0;
  p.monitor_timeout_s = 0.0;
  p.controller_watch.enabled = false;  // on in the ControllerWatch tests
  p.depth_limit.require_plan = false;  // a plan in the DepthLimit tests
  return p;
}

/** @brief A controller's state with desired q and actual q - error (stamp t). */
pd::ControllerStateSample controllerState(const pd::ControllerSpec& c, double t,
                                          const std::vector<double>& desired, double error = 0.0) {
  pd::ControllerStateSample s;
  s.stamp = t;
  s.joint_names = c.joints;
  s.desired_positions = desired;
  s.desired_velocities.assign(desired.size(), 0.0);
  for (double d : desired) {
    s.actual_positions.push_back(d - error);
    s.error_positions.push_back(error);
  }
  s.actual_velocities.assign(desired.size(), 0.0);
  s.error_velocities.assign(desired.size(), 0.0);
  return s;
}

/** @brief The watched sequencer's controllers report the drilling pose (+ offset) at t. */
void reportHome(pd::TrialSequencer* seq, const pd::ArmCompensation& arm, double t,
                double offset = 0.0) {
  const Eigen::VectorXd q = arm.homeJoints().array() + offset;
  seq->onControllerState(t, "arm_controller",
                         controllerState(seq->controllers()[0], t,
                                         std::vector<double>(q.data(), q.data() + q.size())));
  seq->onControllerState(t, "feed_controller",
                         controllerState(seq->controllers()[1], t, {arm.feedHome()}));
}

pd::MotionModel apModel() {
  pd::MotionModel m;
  m.axis(pd::Axis::kAP).q1 = 0.01;
  return m;
}

pd::TrialRequest request(const std::string& mode) {
  pd::TrialRequest r;
  r.mode = mode;
  return r;
}

const pd::FrameLookup kNoLookup;

/** @brief The pose is reached at t_pose, then four marker samples 0.125 s apart register it. */
void registerAt(pd::TrialSequencer* seq, double t_pose) {
  seq->onPoseReached(t_pose);
  seq->takeOutput();
  for (int i = 1; i <= 4; ++i) {
    const double t = t_pose + 0.125 * i;
    seq->onMarker(t, t, "world", Eigen::Vector3d(0.6, 0.0, 0.27), Eigen::Quaterniond::Identity(),
                  kNoLookup);
  }
}

/** @brief Runs a stationary trial to the drilling phase; returns the time then. */
double toDrilling(pd::TrialSequencer* seq, double t0 = 10.0) {
  EXPECT_EQ(seq->start(request("stationary"), apModel(), t0), "");
  seq->takeOutput();
  const double t_pose = t0 + 2.5;
  registerAt(seq, t_pose);
  EXPECT_EQ(seq->phase(), pd::TrialPhase::kDrilling);
  return t_pose + 0.5;
}

}  // namespace

// What a node publishes from an output (the lockstep's noteSent) against what it only keeps.
TEST(SequencerOutput, PublishesAnythingCountsWhatANodePublishesEmptyCountsEverything) {
  pd::SequencerOutput out;
  EXPECT_TRUE(out.empty());
  EXPECT_FALSE(out.publishesAnything());
  out.stop_timers = true;
  out.log.push_back(pd::SequencerLog{});
  EXPECT_FALSE(out.empty());
  EXPECT_FALSE(out.publishesAnything());  // timers and log stay inside the node
  for (int k = 0; k < 6; ++k) {
    pd::SequencerOutput one;
    if (k == 0) one.spindle_rpm.push_back(12000.0);
    if (k == 1) one.phases.push_back(pd::TrialPhase{});
    if (k == 2) one.stops.push_back("why");
    if (k == 3) one.tare_requests.push_back(pd::TareRequest{});
    if (k == 4) one.trajectories.emplace_back();
    if (k == 5) one.predicted.emplace_back();
    EXPECT_TRUE(one.publishesAnything()) << k;
    EXPECT_FALSE(one.empty()) << k;
  }
}

TEST(TrialSequencer, StartMovesToThePoseWithOnePointAndAsksForThePoseTimer) {
  pd::TrialSequencer seq(params(), workcellArm());
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kIdle);
  ASSERT_EQ(seq.start(request("stationary"), apModel(), 10.0), "");
  const pd::SequencerOutput out = seq.takeOutput();
  ASSERT_EQ(out.spindle_rpm.size(), 1u);
  EXPECT_EQ(out.spindle_rpm[0], 12000.0);
  ASSERT_EQ(out.trajectories.size(), 1u);
  const pd::JointTrajectoryCommand& move = out.trajectories[0];
  EXPECT_EQ(move.start_time, 10.0);
  ASSERT_EQ(move.joint_names.size(), 7u);
  EXPECT_EQ(move.joint_names.back(), "feed_joint");
  ASSERT_EQ(move.points.size(), 1u);  // the controller starts from its own state
  EXPECT_DOUBLE_EQ(move.points[0].time_from_start, 2.0);
  EXPECT_DOUBLE_EQ(move.points[0].positions.back(), 0.01);
  ASSERT_EQ(out.phases.size(), 1u);
  EXPECT_EQ(out.phases[0], pd::TrialPhase::kMovingToPose);
  ASSERT_EQ(out.start_timers.size(), 2u);
  EXPECT_EQ(out.start_timers[0].kind, pd::TimerRequest::Kind::kPoseReached);
  EXPECT_DOUBLE_EQ(out.start_timers[0].delay_s, 2.5);
  EXPECT_FALSE(out.start_timers[0].periodic);
  // The spindle's keepalive for the driver's watchdog (spindle_keepalive_s).
  EXPECT_EQ(out.start_timers[1].kind, pd::TimerRequest::Kind::kSpindleKeepalive);
  EXPECT_DOUBLE_EQ(out.start_timers[1].delay_s, 0.1);
  EXPECT_TRUE(out.start_timers[1].periodic);
  // A second start while running is refused.
  EXPECT_NE(seq.start(request("stationary"), apModel(), 11.0).find("a trial is running"),
            std::string::npos);
}

TEST(TrialSequencer, BadRequestsAreRefusedAndNothingHappens) {
  pd::TrialSequencer seq(params(), workcellArm());
  EXPECT_NE(seq.start(request("sideways"), apModel(), 0.0).find("mode"), std::string::npos);
  pd::TrialRequest fast = request("stationary");
  fast.feed_rate_mm_s = 11.0;
  EXPECT_NE(seq.check(fast).find("feed_rate_mm_s"), std::string::npos);
  EXPECT_NE(seq.start(fast, apModel(), 0.0).find("feed_rate_mm_s"), std::string::npos);
  pd::TrialRequest nan_rpm = request("stationary");
  nan_rpm.spindle_rpm = std::nan("");
  EXPECT_NE(seq.start(nan_rpm, apModel(), 0.0).find("spindle_rpm"), std::string::npos);
  // The moving modes need the ventilator.
  EXPECT_NE(seq.start(request("compensated"), apModel(), 0.0).find("needs the ventilator"),
            std::string::npos);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kIdle);
  EXPECT_TRUE(seq.takeOutput().empty());
  seq.setVentilator(pd::VentilatorSettings());
  seq.setBreathStart(0.0);
  EXPECT_EQ(seq.check(request("compensated")), "");
}

TEST(TrialSequencer, RegistrationThenSegmentsOnTheGridOfThePeriod) {
  pd::TrialSequencer seq(params(), workcellArm());
  ASSERT_EQ(seq.start(request("stationary"), apModel(), 10.0), "");
  seq.takeOutput();
  seq.onPoseReached(12.5);
  pd::SequencerOutput out = seq.takeOutput();
  ASSERT_EQ(out.phases.size(), 1u);
  EXPECT_EQ(out.phases[0], pd::TrialPhase::kRegistering);
  ASSERT_EQ(out.start_timers.size(), 1u);
  EXPECT_EQ(out.start_timers[0].kind, pd::TimerRequest::Kind::kRegistrationTimeout);
  // A sample measured before the arm settled does not count.
  seq.onMarker(12.55, 12.4, "world", Eigen::Vector3d(0.6, 0, 0.27), Eigen::Quaterniond::Identity(),
               kNoLookup);
  for (int i = 1; i <= 3; ++i) {
    seq.onMarker(12.5 + 0.125 * i, 12.5 + 0.125 * i, "world", Eigen::Vector3d(0.6, 0, 0.27),
                 Eigen::Quaterniond::Identity(), kNoLookup);
  }
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRegistering);
  seq.onMarker(13.0, 13.0, "world", Eigen::Vector3d(0.6, 0, 0.27), Eigen::Quaterniond::Identity(),
               kNoLookup);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kDrilling);
  out = seq.takeOutput();
  ASSERT_EQ(out.start_timers.size(), 1u);
  EXPECT_EQ(out.start_timers[0].kind, pd::TimerRequest::Kind::kSegment);
  EXPECT_TRUE(out.start_timers[0].periodic);
  EXPECT_DOUBLE_EQ(out.start_timers[0].delay_s, 0.125);
  // One period ahead: the segments starting at 13.0 and 13.125.
  ASSERT_EQ(out.trajectories.size(), 2u);
  EXPECT_DOUBLE_EQ(out.trajectories[0].start_time, 13.0);
  EXPECT_DOUBLE_EQ(out.trajectories[1].start_time, 13.125);
  for (const auto& traj : out.trajectories) {
    ASSERT_EQ(traj.points.size(), 5u);
    EXPECT_NEAR(traj.points.back().time_from_start, 0.125, 1e-12);
    EXPECT_EQ(traj.points.back().velocities.back(), 0.0);  // rest to rest
  }
  // Feed 0.5 mm/s from the feed home.
  EXPECT_NEAR(out.trajectories[1].points.back().positions.back(), 0.01 + 0.25 * 0.5e-3, 1e-9);
  seq.onSegmentTimer(13.125);
  out = seq.takeOutput();
  ASSERT_EQ(out.trajectories.size(), 1u);
  EXPECT_DOUBLE_EQ(out.trajectories[0].start_time, 13.25);
  // Predicted marker poses for the safety monitor while drilling (stationary: the marker).
  seq.onMarker(13.2, 13.2, "world", Eigen::Vector3d(0.6, 0, 0.27), Eigen::Quaterniond::Identity(),
               kNoLookup);
  out = seq.takeOutput();
  ASSERT_EQ(out.predicted.size(), 1u);
  EXPECT_NEAR((out.predicted[0].position - Eigen::Vector3d(0.6, 0, 0.27)).norm(), 0.0, 1e-12);
  EXPECT_EQ(out.predicted[0].stamp, 13.2);
}

TEST(TrialSequencer, ATimerTickAHairEarlyStillSendsTheNextSegmentOnePeriodAhead) {
  // The engine's timer accumulates its due time and the grid is t_reg + k T: the two differ in
  // the last bits. A tick that came 1e-12 s early once missed its segment, which then went out at
  // its own start and reached the controller after it (the arm held for the transport delay).
  pd::TrialSequencer seq(params(), workcellArm());
  const double t_drill = toDrilling(&seq);
  seq.takeOutput();
  for (int k = 1; k <= 40; ++k) {
    const double tick = t_drill + 0.125 * k - 1e-12;
    seq.onSegmentTimer(tick);
    const pd::SequencerOutput out = seq.takeOutput();
    ASSERT_EQ(out.trajectories.size(), 1u) << "tick " << k;
    EXPECT_NEAR(out.trajectories[0].start_time, t_drill + 0.125 * (k + 1), 1e-9) << "tick " << k;
  }
}

TEST(TrialSequencer, RegistrationTimeoutFails) {
  pd::TrialSequencer seq(params(), workcellArm());
  ASSERT_EQ(seq.start(request("stationary"), apModel(), 0.0), "");
  seq.onPoseReached(2.5);
  seq.takeOutput();
  seq.onRegistrationTimeout(5.5);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kFailed);
  const pd::SequencerOutput out = seq.takeOutput();
  EXPECT_TRUE(out.stop_timers);
  ASSERT_EQ(out.spindle_rpm.size(), 1u);
  EXPECT_EQ(out.spindle_rpm[0], 0.0);
}

TEST(TrialSequencer, RecognizerStopHoldsThenRetractsThenDone) {
  pd::TrialSequencerParams p = params();
  p.stop_hold_s = 1.0;  // a hold (the default is 0: the retreat at once, next test)
  pd::TrialSequencer seq(p, workcellArm());
  const double t = toDrilling(&seq);
  seq.takeOutput();
  seq.onSegmentTimer(t + 0.125);
  seq.onSegmentTimer(t + 0.25);
  seq.takeOutput();
  // The recognizer's state reports the stop (its drill/stop may arrive later, or never).
  seq.onRecognizerState(t + 0.3, true, "stopped", 4);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kStopped);
  pd::SequencerOutput out = seq.takeOutput();
  ASSERT_FALSE(out.spindle_rpm.empty());
  EXPECT_EQ(out.spindle_rpm.back(), 0.0);
  ASSERT_FALSE(out.trajectories.empty());
  EXPECT_DOUBLE_EQ(out.trajectories[0].start_time, t + 0.3);  // re-sent from the stop
  const double held = out.trajectories[0].points.back().positions.back();
  // The drill/stop that follows changes nothing.
  seq.onStop(t + 0.31, false, "key point 4");
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kStopped);
  out = seq.takeOutput();
  EXPECT_TRUE(out.trajectories.empty());
  // Held for stop_hold_s (1 s), then the retreat.
  seq.onSegmentTimer(t + 0.375);
  out = seq.takeOutput();
  for (const auto& traj : out.trajectories) {
    EXPECT_NEAR(traj.points.back().positions.back(), held, 1e-12);
  }
  double now = t + 0.375;
  while (seq.phase() == pd::TrialPhase::kStopped && now < t + 3.0) {
    now += 0.125;
    seq.onSegmentTimer(now);
  }
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRetreating);
  while (seq.phase() == pd::TrialPhase::kRetreating && now < t + 30.0) {
    now += 0.125;
    seq.onSegmentTimer(now);
  }
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kDone);
  out = seq.takeOutput();
  EXPECT_TRUE(out.stop_timers);
  double last_feed = 1.0;
  for (const auto& traj : out.trajectories) last_feed = traj.points.back().positions.back();
  EXPECT_NEAR(last_feed, 0.0, 1e-9);  // retracted to the feed's end (clamped)
}

TEST(TrialSequencer, RecognizerStopWithoutHoldRetreatsAtOnce) {
  pd::TrialSequencerParams p = params();
  p.stop_hold_s = 0.0;
  pd::TrialSequencer seq(p, workcellArm());
  const double t = toDrilling(&seq);
  seq.takeOutput();
  seq.onSegmentTimer(t + 0.125);
  seq.onSegmentTimer(t + 0.25);
  seq.takeOutput();
  seq.onRecognizerState(t + 0.3, true, "stopped", 4);
  // Not a tick later: a bone that moves more than predicted would cut into a held drill.
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRetreating);
  const pd::SequencerOutput out = seq.takeOutput();
  ASSERT_FALSE(out.spindle_rpm.empty());
  EXPECT_EQ(out.spindle_rpm.back(), 0.0);
  ASSERT_FALSE(out.trajectories.empty());
  const auto& traj = out.trajectories[0];
  EXPECT_DOUBLE_EQ(traj.start_time, t + 0.3);  // from the stop, not from the next segment
  // The feed goes back from its first point on (the retreat starts at the stop).
  ASSERT_GE(traj.points.size(), 2u);
  EXPECT_LT(traj.points.back().positions.back(), traj.points.front().positions.back());
  // The drill/stop that follows changes nothing.
  seq.onStop(t + 0.31, false, "key point 4");
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRetreating);
}

TEST(TrialSequencer, MonitorStopRetreatsAtOnce) {
  pd::TrialSequencer seq(params(), workcellArm());
  const double t = toDrilling(&seq);
  seq.takeOutput();
  seq.onStop(t + 0.2, true, "position_error");
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRetreating);
}

TEST(TrialSequencer, StopBeforeDrillingFailsTheTrial) {
  pd::TrialSequencer seq(params(), workcellArm());
  ASSERT_EQ(seq.start(request("stationary"), apModel(), 0.0), "");
  seq.onStop(1.0, true, "force_timeout");
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kFailed);
}

TEST(TrialSequencer, LatchedRecognizerStopRefusesToFeed) {
  pd::TrialSequencer seq(params(), workcellArm());
  seq.onRecognizerState(0.0, true, "stopped", 4);  // left over from an earlier trial
  ASSERT_EQ(seq.start(request("stationary"), apModel(), 10.0), "");
  seq.onPoseReached(12.5);
  for (int i = 1; i <= 4; ++i) {
    seq.onMarker(12.5 + 0.125 * i, 12.5 + 0.125 * i, "world", Eigen::Vector3d(0.6, 0, 0.27),
                 Eigen::Quaterniond::Identity(), kNoLookup);
  }
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kFailed);
  const pd::SequencerOutput out = seq.takeOutput();
  for (const auto& traj : out.trajectories) EXPECT_EQ(traj.points.size(), 1u);  // the move only
}

TEST(TrialSequencer, MaxDurationRetracts) {
  pd::TrialSequencer seq(params(), workcellArm());
  pd::TrialRequest r = request("stationary");
  r.max_duration_s = 1.0;
  ASSERT_EQ(seq.start(r, apModel(), 0.0), "");
  seq.onPoseReached(2.5);
  for (int i = 1; i <= 4; ++i) {
    seq.onMarker(2.5 + 0.125 * i, 2.5 + 0.125 * i, "world", Eigen::Vector3d(0.6, 0, 0.27),
                 Eigen::Quaterniond::Identity(), kNoLookup);
  }
  double now = 3.0;
  while (seq.phase() == pd::TrialPhase::kDrilling && now < 10.0) {
    now += 0.125;
    seq.onSegmentTimer(now);
  }
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRetreating);
  EXPECT_NEAR(now, 4.0, 1e-9);
}

// A component unloaded or dead mid-trial: its silence stops the feed and retracts,
// with a StopCommand the driver publishes. Timed from the start of the drilling.
TEST(TrialSequencer, SilentRecognizerOrMonitorWhileDrillingRetreats) {
  pd::TrialSequencerParams p = params();
  p.recognizer_timeout_s = 0.5;
  p.monitor_timeout_s = 2.5;
  for (const bool recognizer_dies : {true, false}) {
    pd::TrialSequencer seq(p, workcellArm());
    const double t0 = toDrilling(&seq);
    seq.takeOutput();
    double now = t0;
    double last_recognizer = t0, last_monitor = t0;
    std::vector<std::string> stops;
    while (seq.phase() == pd::TrialPhase::kDrilling && now < t0 + 10.0) {
      now += 0.125;
      if (!recognizer_dies || now < t0 + 1.0) {
        seq.onRecognizerState(now, false, "outer_cortical", 0);  // 20 Hz in life; 8 Hz here
        last_recognizer = now;
      }
      if (recognizer_dies || now < t0 + 1.0) {
        if (now - last_monitor >= 1.0) {
          seq.onMonitorAlive(now);  // /diagnostics at 1 Hz
          last_monitor = now;
        }
      }
      seq.onSegmentTimer(now);
      for (const std::string& s : seq.takeOutput().stops) stops.push_back(s);
    }
    EXPECT_EQ(seq.phase(), pd::TrialPhase::kRetreating);
    ASSERT_EQ(stops.size(), 1u);
    if (recognizer_dies) {
      EXPECT_NE(stops[0].find("recognizer silent"), std::string::npos) << stops[0];
      EXPECT_GT(now - last_recognizer, 0.5);
      EXPECT_LE(now - last_recognizer, 0.5 + 0.125 + 1e-9);
    } else {
      EXPECT_NE(stops[0].find("safety monitor silent"), std::string::npos) << stops[0];
      EXPECT_GT(now - last_monitor, 2.5);
      EXPECT_LE(now - last_monitor, 2.5 + 0.125 + 1e-9);
    }
  }
}

TEST(TrialSequencer, WatchdogsCountFromTheDrillingAndZeroTurnsThemOff) {
  pd::TrialSequencerParams p = params();
  p.recognizer_timeout_s = 0.5;
  p.monitor_timeout_s = 0.0;
  pd::TrialSequencer seq(p, workcellArm());
  seq.onRecognizerState(0.0, false, "idle", 0);  // long before: does not count as silence
  const double t0 = toDrilling(&seq);
  seq.onSegmentTimer(t0 + 0.375);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kDrilling) << "0.375 s since the drilling began";
  seq.onSegmentTimer(t0 + 0.625);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRetreating);

  p.recognizer_timeout_s = 0.0;
  pd::TrialSequencer quiet(p, workcellArm());
  const double t1 = toDrilling(&quiet);
  for (double now = t1; now < t1 + 30.0; now += 0.125) quiet.onSegmentTimer(now);
  EXPECT_NE(quiet.phase(), pd::TrialPhase::kRetreating);
  for (const double bad : {-0.1, 61.0}) {
    pd::TrialSequencerParams q = params();
    q.monitor_timeout_s = bad;
    EXPECT_THROW(pd::TrialSequencer(q, workcellArm()), std::invalid_argument);
  }
}

TEST(TrialSequencer, ParametersAreValidatedNamingTheField) {
  pd::TrialSequencerParams p = params();
  p.settle_s = -1.0;
  try {
    pd::TrialSequencer seq(p, workcellArm());
    FAIL() << "accepted settle_s = -1";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("settle_s = -1 is out of range [0, 60] s", 0), 0u)
        << e.what();
  }
  p = params();
  p.registration_samples = 0;
  EXPECT_THROW(pd::TrialSequencer(p, workcellArm()), std::invalid_argument);
  p = params();
  p.arm_joints.clear();
  EXPECT_THROW(pd::TrialSequencer(p, workcellArm()), std::invalid_argument);
}

TEST(TrialSequencer, PhaseNames) {
  EXPECT_STREQ(pd::toString(pd::TrialPhase::kMovingToPose), "moving_to_pose");
  EXPECT_STREQ(pd::toString(pd::TrialPhase::kDone), "done");
  EXPECT_TRUE(pd::isRunning(pd::TrialPhase::kStopped));
  EXPECT_FALSE(pd::isRunning(pd::TrialPhase::kFailed));
}

namespace {

/** @brief Records what the sequencer hands a compensator; predicts the last marker sample. */
class RecordingCompensator : public pd::CompensatorInterface {
 public:
  struct Log {
    std::vector<double> stamps;
    std::vector<Eigen::Vector3d> positions;
  };
  explicit RecordingCompensator(Log* log) : log_(log) {}
  void configure(const pd::CompensatorSettings&) override {}
  void setPatient(const pd::MotionModel&, const pd::CompensationParams&) override {}
  void setVentilator(const pd::VentilatorSettings&) override {}
  void setBreathStart(double) override {}
  void observeMarker(double stamp, const Eigen::Vector3d& p) override {
    log_->stamps.push_back(stamp);
    log_->positions.push_back(p);
  }
  bool ready() const override { return !log_->positions.empty(); }
  Eigen::Vector3d displacement(double) const override { return log_->positions.back(); }
  std::string describe() const override { return "recording"; }
  std::vector<std::string> parameterNames() const override { return {}; }

 private:
  Log* log_;
};

}  // namespace

TEST(TrialSequencer, ACompensatorClassHearsTheTrackerAndDrivesTheReferenceAndThePrediction) {
  RecordingCompensator::Log log;
  pd::TrialSequencer seq(params(), workcellArm());
  seq.setCompensatorFactory([&log]() { return std::make_unique<RecordingCompensator>(&log); });
  seq.setVentilator(pd::VentilatorSettings());
  seq.setBreathStart(0.0);
  ASSERT_EQ(seq.start(request("compensated"), apModel(), 10.0), "");
  seq.onPoseReached(12.5);
  seq.takeOutput();
  // The marker frame is rotated 90 degrees about z from the world: the compensator is told
  // world positions.
  const Eigen::Matrix3d world_to_marker =
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const pd::FrameLookup lookup = [&](const std::string& frame, Eigen::Isometry3d* x) {
    if (frame != "camera") return false;
    *x = Eigen::Isometry3d(world_to_marker);
    return true;
  };
  const Eigen::Vector3d marker(0.6, 0.0, 0.27);
  for (int i = 1; i <= 4; ++i) {
    const double t = 12.5 + 0.125 * i;
    seq.onMarker(t, t, "camera", marker, Eigen::Quaterniond::Identity(), lookup);
  }
  ASSERT_EQ(seq.phase(), pd::TrialPhase::kDrilling);
  ASSERT_EQ(log.stamps.size(), 4u);  // every registration sample
  EXPECT_TRUE(log.positions[0].isApprox(world_to_marker.transpose() * marker, 1e-15));
  seq.takeOutput();
  // While drilling: the prediction for the monitor is made before the sample is heard.
  const Eigen::Vector3d moved = marker + Eigen::Vector3d(0.0, 0.0, 0.002);
  seq.onMarker(13.2, 13.2, "camera", moved, Eigen::Quaterniond::Identity(), lookup);
  const pd::SequencerOutput out = seq.takeOutput();
  ASSERT_EQ(out.predicted.size(), 1u);
  EXPECT_TRUE(out.predicted[0].position.isApprox(marker, 1e-12));  // the previous sample
  ASSERT_EQ(log.stamps.size(), 5u);
  EXPECT_EQ(log.stamps.back(), 13.2);
  // ... and the planner's reference follows what the class now predicts (2 mm along marker z,
  // which is world z, against the drill axis -z).
  const pd::CompensationPlanner* planner = seq.planner();
  ASSERT_NE(planner, nullptr);
  EXPECT_NEAR(planner->boneDisplacementSinceStart(13.3).z(), 0.002, 1e-12);
}

TEST(TrialSequencer, ACompensatorFactoryThatThrowsRefusesTheStart) {
  pd::TrialSequencer seq(params(), workcellArm());
  seq.setCompensatorFactory(
      []() -> std::unique_ptr<pd::CompensatorInterface> { throw std::runtime_error("no class"); });
  EXPECT_EQ(seq.start(request("stationary"), apModel(), 0.0), "no class");
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kIdle);
}

// The drill's declared limits (max_spindle_rpm 20000: the paper's highest speed;
// max_feed_rate_mm_s 3): a request above one is refused naming the field and the limit.
TEST(TrialSequencer, ARequestBeyondTheDrillsDeclaredLimitsIsRefusedNamingFieldAndLimit) {
  pd::TrialSequencer seq(params(), workcellArm());
  pd::TrialRequest fast_spindle = request("stationary");
  fast_spindle.spindle_rpm = 30000.0;
  std::string why = seq.check(fast_spindle);
  EXPECT_EQ(why.rfind("spindle_rpm: 30000 rpm exceeds the drill's declared limit max_spindle_rpm = "
                      "20000 rpm",
                      0),
            0u)
      << why;
  EXPECT_EQ(seq.start(fast_spindle, apModel(), 0.0), why);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kIdle);
  pd::TrialRequest fast_feed = request("stationary");
  fast_feed.feed_rate_mm_s = 4.0;
  why = seq.check(fast_feed);
  EXPECT_EQ(why.rfind("feed_rate_mm_s: 4 mm/s exceeds the drill's declared limit "
                      "max_feed_rate_mm_s = 3 mm/s",
                      0),
            0u)
      << why;
  pd::TrialRequest at_limits = request("stationary");
  at_limits.spindle_rpm = 20000.0;
  at_limits.feed_rate_mm_s = 3.0;
  EXPECT_EQ(seq.check(at_limits), "");
  // A drill declared faster takes it; a default above the limit is refused at construction.
  pd::TrialSequencerParams p = params();
  p.max_spindle_rpm = 30000.0;
  EXPECT_EQ(pd::TrialSequencer(p, workcellArm()).check(fast_spindle), "");
  p = params();
  p.default_spindle_rpm = 25000.0;
  try {
    pd::TrialSequencer bad(p, workcellArm());
    FAIL() << "accepted a default above max_spindle_rpm";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("spindle_rpm: must not exceed max_spindle_rpm", 0), 0u)
        << e.what();
  }
}

namespace {

/// The tracker-feedback baseline with a bug: observeMarker throws once `fail` is set.
class FailingCompensator : public pd::TrackedMarkerCompensator {
 public:
  explicit FailingCompensator(const bool* fail) : fail_(fail) {}
  void observeMarker(double stamp, const Eigen::Vector3d& position) override {
    if (*fail_) throw std::out_of_range("plugin bug");
    pd::TrackedMarkerCompensator::observeMarker(stamp, position);
  }

 private:
  const bool* fail_;
};

}  // namespace

// An exception of the compensator class never leaves the sequencer: while drilling it is a stop
// with retreat, announced, naming the error; later calls answer without the class.
TEST(TrialSequencer, ACompensatorThatThrowsWhileDrillingIsAStopWithRetreatNamingIt) {
  bool fail = false;
  pd::TrialSequencer seq(params(), workcellArm());
  seq.setCompensatorFactory([&fail]() { return std::make_unique<FailingCompensator>(&fail); });
  seq.setVentilator(pd::VentilatorSettings());
  seq.setBreathStart(0.0);
  ASSERT_EQ(seq.start(request("compensated"), apModel(), 10.0), "");
  seq.onPoseReached(12.5);
  const Eigen::Vector3d marker(0.6, 0.0, 0.27);
  for (int i = 1; i <= 4; ++i) {
    const double t = 12.5 + 0.125 * i;
    seq.onMarker(t, t, "world", marker, Eigen::Quaterniond::Identity(), kNoLookup);
  }
  ASSERT_EQ(seq.phase(), pd::TrialPhase::kDrilling);
  seq.takeOutput();
  fail = true;
  EXPECT_NO_THROW(
      seq.onMarker(13.2, 13.2, "world", marker, Eigen::Quaterniond::Identity(), kNoLookup));
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRetreating);
  const pd::SequencerOutput out = seq.takeOutput();
  ASSERT_EQ(out.stops.size(), 1u);
  EXPECT_NE(out.stops[0].find("compensator error"), std::string::npos) << out.stops[0];
  EXPECT_NE(out.stops[0].find("observeMarker: plugin bug"), std::string::npos) << out.stops[0];
  ASSERT_FALSE(out.spindle_rpm.empty());
  EXPECT_EQ(out.spindle_rpm.back(), 0.0);
  // The retreat runs on (the class is not asked again), and the stop is announced once.
  for (double t = 13.25; t < 40.0 && seq.phase() != pd::TrialPhase::kDone; t += 0.125) {
    EXPECT_NO_THROW(seq.onSegmentTimer(t));
    seq.onMarker(t, t, "world", marker, Eigen::Quaterniond::Identity(), kNoLookup);
    EXPECT_TRUE(seq.takeOutput().stops.empty());
  }
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kDone);
}

TEST(TrialSequencer, ARequestMayNameTheSegmentProfileOfItsTrial) {
  pd::TrialSequencer seq(params(), workcellArm());
  pd::TrialRequest bad = request("stationary");
  bad.segment_profile = "blended";
  EXPECT_EQ(seq.start(bad, apModel(), 0.0).rfind("segment_profile", 0), 0u);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kIdle);
  pd::TrialRequest exact = request("stationary");
  exact.segment_profile = "exact";
  ASSERT_EQ(seq.start(exact, apModel(), 0.0), "");
  ASSERT_NE(seq.planner(), nullptr);
  EXPECT_EQ(seq.planner()->params().segment_profile, pd::SegmentProfile::kExact);
  // Empty: the sequencer's own (rest_to_rest by default).
  pd::TrialSequencer other(params(), workcellArm());
  ASSERT_EQ(other.start(request("stationary"), apModel(), 0.0), "");
  EXPECT_EQ(other.planner()->params().segment_profile, pd::SegmentProfile::kRestToRest);
}

// The outer cortical layer's plausibility is geometric. Once the tip's predicted
// advance into the bone is outer_cortical_max_mm past the recognizer's contact report, the
// outer cortex must be cut through; a recognizer still reporting it recognizer_delay_s later
// (a drifting sensor) stops the drill with retreat. Stationary: the advance is the feed
// (0.5 mm/s), so 3.5 mm is 7 s after the contact, and the stop comes 1.5 s after that.
TEST(TrialSequencer, AnOuterLayerLongerThanTheSpecimensAllowIsAnImplausibleForceStop) {
  for (const std::string next_state : {"outer_cortical", "cancellous", ""}) {
    SCOPED_TRACE(next_state);
    pd::TrialSequencerParams p = params();
    if (next_state.empty()) p.outer_cortical_max_mm = 0.0;  // off
    pd::TrialSequencer seq(p, workcellArm());
    const double t0 = toDrilling(&seq);
    seq.takeOutput();
    double now = t0;
    seq.onRecognizerState(now, false, "idle", 0);  // in the air: no contact yet
    for (int i = 0; i < 16; ++i) {                 // 2 s of approach do not count
      now += 0.125;
      seq.onRecognizerState(now, false, "idle", 0);
      seq.onSegmentTimer(now);
    }
    const double t_contact = now + 0.125;
    std::vector<std::string> stops;
    while (seq.phase() == pd::TrialPhase::kDrilling && now < t_contact + 20.0) {
      now += 0.125;
      const bool ended = next_state == "cancellous" && now >= t_contact + 6.0;
      seq.onRecognizerState(now, false, ended ? "cancellous" : "outer_cortical", ended ? 3 : 0);
      seq.onSegmentTimer(now);
      for (const std::string& s : seq.takeOutput().stops) stops.push_back(s);
    }
    if (next_state != "outer_cortical") {
      EXPECT_TRUE(stops.empty());
      EXPECT_EQ(seq.phase(), pd::TrialPhase::kDrilling);
      continue;
    }
    EXPECT_EQ(seq.phase(), pd::TrialPhase::kRetreating);
    ASSERT_EQ(stops.size(), 1u);
    EXPECT_NE(stops[0].find("implausible force"), std::string::npos) << stops[0];
    EXPECT_NE(stops[0].find("outer_cortical_max_mm"), std::string::npos) << stops[0];
    EXPECT_GE(now - t_contact, 7.0 + 1.5 - 1e-9);
    EXPECT_LE(now - t_contact, 7.0 + 1.5 + 0.125 + 1e-9);
  }
}

// The cancellous layer's bound (cancellous_max_mm, 8.3 mm): a recognizer that stays in
// `cancellous` has missed the inner layer; the planner stops 8.3 mm of advance (16.6 s at
// 0.5 mm/s) plus recognizer_delay_s after its first `cancellous` report.
TEST(TrialSequencer, ACancellousLayerLongerThanTheSpecimensAllowStopsTheDrill) {
  pd::TrialSequencer seq(params(), workcellArm());
  const double t0 = toDrilling(&seq);
  seq.takeOutput();
  double now = t0;
  double t_cancellous = -1.0;
  std::vector<std::string> stops;
  while (seq.phase() == pd::TrialPhase::kDrilling && now < t0 + 40.0) {
    now += 0.125;
    const bool in_cancellous = now >= t0 + 4.0;
    if (in_cancellous && t_cancellous < 0.0) t_cancellous = now;
    seq.onRecognizerState(now, false, in_cancellous ? "cancellous" : "outer_cortical",
                          in_cancellous ? 3 : 0);
    seq.onSegmentTimer(now);
    for (const std::string& s : seq.takeOutput().stops) stops.push_back(s);
  }
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRetreating);
  ASSERT_EQ(stops.size(), 1u);
  EXPECT_NE(stops[0].find("cancellous_max_mm"), std::string::npos) << stops[0];
  EXPECT_GE(now - t_cancellous, 16.6 + 1.5 - 1e-9);
  EXPECT_LE(now - t_cancellous, 16.6 + 1.5 + 0.125 + 1e-9);
}

// Uncompensated, the tip moves against the breathing bone: the bound counts how much deeper the
// cut went (the deepest predicted advance since the drilling began), not the stroke. Checked
// against the planner's own prediction sampled densely, independently of the sequencer.
TEST(TrialSequencer, TheLayerBoundCountsTheDeepestCutNotTheBreathingStroke) {
  pd::TrialSequencer seq(params(), workcellArm());
  seq.setVentilator(pd::VentilatorSettings());
  seq.setBreathStart(0.0);
  ASSERT_EQ(seq.start(request("uncompensated"), apModel(), 10.0), "");
  seq.onPoseReached(12.5);
  for (int i = 1; i <= 4; ++i) {
    const double t = 12.5 + 0.125 * i;
    seq.onMarker(t, t, "world", Eigen::Vector3d(0.6, 0.0, 0.27), Eigen::Quaterniond::Identity(),
                 kNoLookup);
  }
  ASSERT_EQ(seq.phase(), pd::TrialPhase::kDrilling);
  seq.takeOutput();
  const pd::CompensationPlanner* planner = seq.planner();
  ASSERT_NE(planner, nullptr);
  const double t_reg = planner->registrationTime();
  const auto deepest = [&](double t) {
    double d = planner->predictedAdvance(t_reg);
    for (double u = t_reg; u <= t; u += 0.001) d = std::max(d, planner->predictedAdvance(u));
    return d;
  };
  // The stroke is real here: the prediction moves the bone along the drill axis.
  double lo = 1.0, hi = -1.0;
  for (double u = t_reg; u < t_reg + 5.0; u += 0.01) {
    lo = std::min(lo, planner->predictedAdvance(u) - 0.0005 * (u - t_reg));
    hi = std::max(hi, planner->predictedAdvance(u) - 0.0005 * (u - t_reg));
  }
  ASSERT_GT(hi - lo, 1e-3);
  // The contact is reported where the tip is furthest back from the deepest cut (a trough of
  // the stroke): counting from the tip's position there would stop the drill too early.
  double t_contact = t_reg + 0.5;
  for (double u = t_reg + 0.5; u < t_reg + 6.0; u += 0.125) {
    if (deepest(u) - planner->predictedAdvance(u) >
        deepest(t_contact) - planner->predictedAdvance(t_contact)) {
      t_contact = u;
    }
  }
  ASSERT_GT(deepest(t_contact) - planner->predictedAdvance(t_contact), 0.5e-3);
  double now = t_reg + 0.125;
  std::vector<std::string> stops;
  while (seq.phase() == pd::TrialPhase::kDrilling && now < t_contact + 60.0) {
    seq.onRecognizerState(now, false, now < t_contact - 1e-9 ? "idle" : "outer_cortical", 0);
    seq.onSegmentTimer(now);
    for (const std::string& s : seq.takeOutput().stops) stops.push_back(s);
    now += 0.125;
  }
  ASSERT_EQ(stops.size(), 1u);
  EXPECT_NE(stops[0].find("outer_cortical_max_mm"), std::string::npos) << stops[0];
  const double t_stop = now - 0.125;
  const double base = deepest(t_contact);
  // The bound was passed at least recognizer_delay_s before the stop, and not more than one
  // tick (plus the 5 ms sampling) earlier than that.
  EXPECT_GE(deepest(t_stop - 1.5) - base, 3.5e-3 - 1e-5);
  EXPECT_LT(deepest(t_stop - 1.5 - 0.125 - 0.006) - base, 3.5e-3);
}

// The timers both drivers run (the closed-loop engine, and the planner nodelet under the
// simulator's lockstep): one rule, so that a timer fires at the same step in both.
TEST(SequencerTimers, FireInDueOrderPeriodicOnesAgainAndAStopClearsThem) {
  pd::SequencerTimers timers;
  EXPECT_TRUE(timers.empty());
  pd::SequencerOutput out;
  out.start_timers.push_back({pd::TimerRequest::Kind::kSegment, 0.125, true});
  out.start_timers.push_back({pd::TimerRequest::Kind::kPoseReached, 0.05, false});
  timers.apply(out, 10.0);
  EXPECT_FALSE(timers.popDue(10.049).has_value());
  // 1 ns of rounding allowed: a tick at the due time's neighbour still fires it.
  const auto pose = timers.popDue(10.05 - 5e-10);
  ASSERT_TRUE(pose.has_value());
  EXPECT_EQ(*pose, pd::TimerRequest::Kind::kPoseReached);
  EXPECT_FALSE(timers.popDue(10.1).has_value());
  // A late tick fires a periodic timer once per period missed, earliest first.
  int segments = 0;
  while (const auto k = timers.popDue(10.3)) {
    EXPECT_EQ(*k, pd::TimerRequest::Kind::kSegment);
    ++segments;
  }
  EXPECT_EQ(segments, 2);  // due at 10.125 and 10.25
  const auto next = timers.popDue(10.375);
  ASSERT_TRUE(next.has_value());
  pd::SequencerOutput stop;
  stop.stop_timers = true;
  timers.apply(stop, 10.4);
  EXPECT_TRUE(timers.empty());
  EXPECT_FALSE(timers.popDue(100.0).has_value());
}

// The lockstep's participants tell the simulator the next step they need (StepAck.next_step):
// nextDue() is the earliest pending timer, moving on as timers fire and cleared by a stop.
TEST(SequencerTimers, NextDueIsTheEarliestPendingTimer) {
  pd::SequencerTimers timers;
  EXPECT_FALSE(timers.nextDue().has_value());
  pd::SequencerOutput out;
  out.start_timers.push_back({pd::TimerRequest::Kind::kSegment, 0.125, true});
  out.start_timers.push_back({pd::TimerRequest::Kind::kPoseReached, 0.05, false});
  timers.apply(out, 10.0);
  ASSERT_TRUE(timers.nextDue().has_value());
  EXPECT_DOUBLE_EQ(*timers.nextDue(), 10.05);
  // Nothing fires before it; at it, the one-shot fires and the periodic one is next.
  EXPECT_FALSE(timers.popDue(*timers.nextDue() - 2e-9).has_value());
  ASSERT_TRUE(timers.popDue(10.05).has_value());
  EXPECT_DOUBLE_EQ(*timers.nextDue(), 10.125);
  ASSERT_TRUE(timers.popDue(10.125).has_value());
  EXPECT_DOUBLE_EQ(*timers.nextDue(), 10.25);  // advanced by its period
  pd::SequencerOutput stop;
  stop.stop_timers = true;
  timers.apply(stop, 10.2);
  EXPECT_FALSE(timers.nextDue().has_value());
}

TEST(SequencerTimers, TheSequencerDispatchesAFiredTimerToItsHandler) {
  pd::TrialSequencer seq(params(), workcellArm());
  ASSERT_EQ(seq.start(request("stationary"), apModel(), 1.0), "");
  pd::SequencerTimers timers;
  timers.apply(seq.takeOutput(), 1.0);
  ASSERT_EQ(seq.phase(), pd::TrialPhase::kMovingToPose);
  // The move's timer fires at its due time and the sequencer goes on to the registration; the
  // spindle's keepalive fires every 0.1 s meanwhile, each a spindle command again.
  double t = 1.0;
  int keepalives = 0;
  for (;;) {
    const std::optional<pd::TimerRequest::Kind> kind = timers.popDue(t);
    if (!kind) {
      t += 0.001;
      continue;
    }
    seq.onTimer(*kind, t);
    if (*kind == pd::TimerRequest::Kind::kPoseReached) break;
    ASSERT_EQ(*kind, pd::TimerRequest::Kind::kSpindleKeepalive);
    ++keepalives;
    const pd::SequencerOutput out = seq.takeOutput();
    ASSERT_EQ(out.spindle_rpm.size(), 1u);
    EXPECT_EQ(out.spindle_rpm[0], 12000.0);
  }
  EXPECT_NEAR(t, 3.5, 1e-9);
  EXPECT_EQ(keepalives, 24);  // 0.1 s apart, at 1.1 .. 3.4 s (the 25th is due with the pose)
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRegistering);
}

// ----------------------------------------------------------------------------- the closed loop

TEST(TrialSequencer, WatchedStartNeedsEachControllersState) {
  pd::TrialSequencerParams p = params();
  p.controller_watch.enabled = true;
  pd::TrialSequencer seq(p, workcellArm());
  const std::string refused = seq.start(request("stationary"), apModel(), 10.0);
  EXPECT_NE(refused.find("arm_controller has not reported its state"), std::string::npos)
      << refused;
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kIdle);
  reportHome(&seq, workcellArm(), 9.9);
  EXPECT_EQ(seq.start(request("stationary"), apModel(), 10.0), "");
}

TEST(TrialSequencer, AControllerThatKeepsItsOldTrajectoryIsAStopWithRetreat) {
  // The controller refused the move to the drilling pose (foreign joints, a trajectory already
  // ended): its desired stays where the arm was (0.3 rad away on every joint).
  pd::TrialSequencerParams p = params();
  p.controller_watch.enabled = true;
  const pd::ArmCompensation arm = workcellArm();
  pd::TrialSequencer seq(p, arm);
  reportHome(&seq, arm, 9.98, 0.3);
  ASSERT_EQ(seq.start(request("stationary"), apModel(), 10.0), "");
  seq.takeOutput();
  std::string stop;
  for (double t = 10.02; t < 12.0 && stop.empty(); t += 0.02) {
    reportHome(&seq, arm, t, 0.3);
    const pd::SequencerOutput out = seq.takeOutput();
    if (!out.stops.empty()) stop = out.stops.front();
  }
  EXPECT_NE(stop.find("arm_controller: the desired position of"), std::string::npos) << stop;
  EXPECT_NE(stop.find("refused or arrived late"), std::string::npos) << stop;
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kFailed);  // before drilling: the trial fails
}

TEST(TrialSequencer, AJointThatDoesNotFollowIsAStopWithRetreatWhileDrilling) {
  pd::TrialSequencerParams p = params();
  p.controller_watch.enabled = true;
  p.controller_watch.state_timeout_s = 60.0;  // the arm controller is not reported here
  const pd::ArmCompensation arm = workcellArm();
  pd::TrialSequencer seq(p, arm);
  reportHome(&seq, arm, 9.98);
  const double t = toDrilling(&seq);
  // The feed controller's desired stays near the commanded feed; its error grows.
  std::string stop;
  for (int i = 0; i < 20 && stop.empty(); ++i) {
    const double ti = t + 0.02 * i;
    seq.onSegmentTimer(ti);
    seq.takeOutput();
    const double error = 0.0005 * i;  // 0.5 mm more every state
    seq.onControllerState(ti, "feed_controller",
                          controllerState(seq.controllers()[1], ti, {arm.feedHome()}, error));
    const pd::SequencerOutput out = seq.takeOutput();
    if (!out.stops.empty()) stop = out.stops.front();
  }
  EXPECT_NE(stop.find("feed_controller: feed_joint does not follow its trajectory"),
            std::string::npos)
      << stop;
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRetreating);
}

TEST(TrialSequencer, ASilentControllerIsAStopWithRetreatWhileDrilling) {
  pd::TrialSequencerParams p = params();
  p.controller_watch.enabled = true;
  p.controller_watch.state_timeout_s = 0.3;
  const pd::ArmCompensation arm = workcellArm();
  pd::TrialSequencer seq(p, arm);
  reportHome(&seq, arm, 9.98);
  const double t = toDrilling(&seq);
  std::vector<std::string> stops;
  for (int i = 1; i <= 8 && stops.empty(); ++i) {
    seq.onSegmentTimer(t + 0.125 * i);
    stops = seq.takeOutput().stops;
  }
  ASSERT_FALSE(stops.empty());
  EXPECT_NE(stops.front().find("silent: no arm_controller/state for more than 0.3 s"),
            std::string::npos)
      << stops.front();
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRetreating);
}

TEST(TrialSequencer, TheKeepaliveRepeatsTheRunningSpindleSpeedAndNothingOnceItStopped) {
  pd::TrialSequencer seq(params(), workcellArm());
  const double t_drill = toDrilling(&seq);
  seq.takeOutput();
  seq.onTimer(pd::TimerRequest::Kind::kSpindleKeepalive, t_drill + 0.05);
  pd::SequencerOutput out = seq.takeOutput();
  ASSERT_EQ(out.spindle_rpm.size(), 1u);
  EXPECT_EQ(out.spindle_rpm[0], 12000.0);
  seq.onStop(t_drill + 0.1, true, "test");  // the spindle off with the stop
  out = seq.takeOutput();
  ASSERT_FALSE(out.spindle_rpm.empty());
  EXPECT_EQ(out.spindle_rpm.back(), 0.0);
  seq.onSpindleKeepalive(t_drill + 0.2);
  EXPECT_TRUE(seq.takeOutput().spindle_rpm.empty());  // a stopped spindle is not kept alive
  // 0: one command per change, no keepalive timer.
  pd::TrialSequencerParams p = params();
  p.spindle_keepalive_s = 0.0;
  pd::TrialSequencer once(p, workcellArm());
  ASSERT_EQ(once.start(request("stationary"), apModel(), 0.0), "");
  out = once.takeOutput();
  ASSERT_EQ(out.start_timers.size(), 1u);
  EXPECT_EQ(out.start_timers[0].kind, pd::TimerRequest::Kind::kPoseReached);
}

namespace {

/** @brief Registers at t0 + 0.125 k (k = 1..4) with markers in the world frame. */
void registerMarkers(pd::TrialSequencer* seq, double t0) {
  for (int i = 1; i <= 4; ++i) {
    const double t = t0 + 0.125 * i;
    seq->onMarker(t, t, "world", Eigen::Vector3d(0.6, 0.0, 0.27), Eigen::Quaterniond::Identity(),
                  kNoLookup);
  }
}

pd::TareResult tareResult(bool success, double t) {
  pd::TareResult r;
  r.success = success;
  r.t = t;
  r.samples = 100;
  r.bias[2] = 4.9;
  r.message = success ? "tared" : "tare failed: the force spread 2 N exceeds 0.5 N";
  return r;
}

pd::TrialSequencerParams taring() {
  pd::TrialSequencerParams p = params();
  p.tare_samples = 100;
  p.tare_max_spread_n = 0.4;
  return p;
}

}  // namespace

TEST(TrialSequencer, TheTareIsAskedAtTheDrillingPoseAndTheDrillingWaitsForIt) {
  pd::TrialSequencer seq(taring(), workcellArm());
  ASSERT_EQ(seq.start(request("stationary"), apModel(), 10.0), "");
  EXPECT_TRUE(seq.takeOutput().tare_requests.empty());  // not while the arm moves
  seq.onPoseReached(12.5);
  pd::SequencerOutput out = seq.takeOutput();
  ASSERT_EQ(out.tare_requests.size(), 1u);
  EXPECT_EQ(out.tare_requests[0].samples, 100);
  EXPECT_DOUBLE_EQ(out.tare_requests[0].max_spread_n, 0.4);
  registerMarkers(&seq, 12.5);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRegistering);  // registered, the tare still to come
  seq.onMarker(13.2, 13.2, "world", Eigen::Vector3d(0.7, 0.0, 0.27), Eigen::Quaterniond::Identity(),
               kNoLookup);  // a later marker does not register again
  seq.takeOutput();
  seq.onTareResult(13.31, tareResult(true, 13.3));
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kDrilling);
  out = seq.takeOutput();
  // The segment grid starts at the later of the registration (13.0) and the tare (13.3).
  ASSERT_FALSE(out.trajectories.empty());
  EXPECT_DOUBLE_EQ(out.trajectories[0].start_time, 13.3);
  // A late duplicate result changes nothing.
  seq.onTareResult(13.4, tareResult(false, 13.4));
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kDrilling);
}

TEST(TrialSequencer, ATareBeforeTheRegistrationEndsLetsItStartTheDrilling) {
  pd::TrialSequencer seq(taring(), workcellArm());
  ASSERT_EQ(seq.start(request("stationary"), apModel(), 10.0), "");
  seq.onPoseReached(12.5);
  seq.onTareResult(12.8, tareResult(true, 12.8));
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRegistering);
  seq.takeOutput();
  registerMarkers(&seq, 12.5);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kDrilling);
  EXPECT_DOUBLE_EQ(seq.takeOutput().trajectories.at(0).start_time, 13.0);
}

TEST(TrialSequencer, AFailedTareFailsTheTrialNamingWhy) {
  pd::TrialSequencer seq(taring(), workcellArm());
  ASSERT_EQ(seq.start(request("stationary"), apModel(), 10.0), "");
  seq.onPoseReached(12.5);
  registerMarkers(&seq, 12.5);
  seq.takeOutput();
  seq.onTareResult(13.1, tareResult(false, 13.1));
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kFailed);
  const pd::SequencerOutput out = seq.takeOutput();
  EXPECT_TRUE(out.trajectories.empty());
  EXPECT_EQ(out.spindle_rpm.back(), 0.0);
  bool named = false;
  for (const pd::SequencerLog& l : out.log) named |= l.text.find("F/T tare") != std::string::npos;
  EXPECT_TRUE(named);
}

TEST(TrialSequencer, NoTareResultFailsAtTheRegistrationTimeout) {
  pd::TrialSequencer seq(taring(), workcellArm());
  ASSERT_EQ(seq.start(request("stationary"), apModel(), 10.0), "");
  seq.onPoseReached(12.5);
  registerMarkers(&seq, 12.5);
  seq.takeOutput();
  seq.onRegistrationTimeout(15.5);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kFailed);
  bool named = false;
  for (const pd::SequencerLog& l : seq.takeOutput().log) {
    named |= l.text.find("ft_sensor/tare_result") != std::string::npos;
  }
  EXPECT_TRUE(named);
}

namespace {

/** @brief The workcell arm with its tip at the drilling pose set (the depth limit needs it). */
pd::ArmCompensation armWithTip(const Eigen::Vector3d& tip) {
  pd::ArmCompensation arm = workcellArm();
  arm.setTipAtPose(tip);
  return arm;
}

/** @brief A plan whose entry lies `gap` ahead of `tip` along `axis`, marker at kMarker. */
pd::DrillingPlan planAhead(const Eigen::Vector3d& tip, const Eigen::Vector3d& axis, double gap,
                           double depth, double tolerance) {
  pd::DrillingPlan p;
  p.frame = "tracker_marker";
  p.entry = tip + gap * axis - Eigen::Vector3d(0.6, 0.0, 0.27);  // toDrilling's marker
  p.direction = axis;
  p.depth_m = depth;
  p.entry_tolerance_m = tolerance;
  return p;
}

struct FeedRun {
  double max_feed = -1.0;  // deepest feed joint command [m]
  double stop_t = -1.0;    // when the depth limit's stop came
  std::string stop;        // its reason
};

/** @brief Segment ticks from t to t_end; `force` gives the thrust at a tick (NaN: none). */
FeedRun runFeed(pd::TrialSequencer* seq, double t, double t_end,
                const std::function<double(double)>& force = nullptr) {
  FeedRun run;
  for (; t <= t_end; t += 0.125) {
    if (force && std::isfinite(force(t))) {
      for (int i = 0; i < 3; ++i) seq->onForce(t, t, force(t));
    }
    seq->onSegmentTimer(t);
    const pd::SequencerOutput out = seq->takeOutput();
    for (const pd::JointTrajectoryCommand& c : out.trajectories) {
      for (const auto& pt : c.points) run.max_feed = std::max(run.max_feed, pt.positions.back());
    }
    for (const std::string& s : out.stops) {
      if (run.stop_t < 0.0 && s.find("depth_limit") != std::string::npos) {
        run.stop_t = t;
        run.stop = s;
      }
    }
  }
  return run;
}

}  // namespace

TEST(TrialSequencerDepthLimit, ATrialWithoutAPlanIsRefusedWhenThePlanIsRequired) {
  pd::TrialSequencerParams p = params();
  p.depth_limit.require_plan = true;
  pd::TrialSequencer seq(p, armWithTip(Eigen::Vector3d(0.6, 0.0, 0.3)));
  const std::string why = seq.start(request("stationary"), apModel(), 10.0);
  EXPECT_NE(why.find("no drilling plan"), std::string::npos) << why;
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kIdle);
  // And without the tip's position a plan cannot be placed.
  pd::TrialSequencer no_tip(p, workcellArm());
  no_tip.setPlan(planAhead(Eigen::Vector3d(0.6, 0, 0.3), Eigen::Vector3d(0, 0, -1), 2e-3, 3e-3, 0));
  EXPECT_NE(no_tip.start(request("stationary"), apModel(), 10.0).find("tip"), std::string::npos);
}

TEST(TrialSequencerDepthLimit, TheFeedIsHeldAtThePlannedDepthThenStopsAndRetreats) {
  const Eigen::Vector3d tip(0.6, 0.0, 0.3);
  pd::ArmCompensation arm = armWithTip(tip);
  pd::TrialSequencer seq(params(), arm);
  // Entry 2 mm ahead, 3 mm deep, no tolerance: no feed past 5 mm.
  seq.setPlan(planAhead(tip, arm.drillAxis(), 2e-3, 3e-3, 0.0));
  const double t_reg = toDrilling(&seq);
  EXPECT_TRUE(seq.depthLimit().active());
  const FeedRun run = runFeed(&seq, t_reg + 0.125, t_reg + 14.0);
  EXPECT_LE(run.max_feed, arm.feedHome() + 5e-3 + 1e-9);
  EXPECT_GE(run.max_feed, arm.feedHome() + 5e-3 - 1e-6);  // it drilled to the limit
  // 5 mm at 0.5 mm/s: 10 s after the registration, stopped at the next tick.
  ASSERT_GE(run.stop_t, 0.0) << "no depth_limit stop";
  EXPECT_NEAR(run.stop_t, t_reg + 10.0, 0.126);
  EXPECT_NE(run.stop.find("no contact sensed"), std::string::npos) << run.stop;
  EXPECT_TRUE(seq.phase() == pd::TrialPhase::kRetreating || seq.phase() == pd::TrialPhase::kDone);
}

TEST(TrialSequencerDepthLimit, TheSensedContactSetsTheSurfaceWithinTheTolerance) {
  const Eigen::Vector3d tip(0.6, 0.0, 0.3);
  pd::ArmCompensation arm = armWithTip(tip);
  pd::TrialSequencer seq(params(), arm);
  // Entry 2 mm ahead +- 1 mm; the thrust shows the bone from 2.5 mm of feed on (at 5 s).
  seq.setPlan(planAhead(tip, arm.drillAxis(), 2e-3, 3e-3, 1e-3));
  const double t_reg = toDrilling(&seq);
  const FeedRun run = runFeed(&seq, t_reg + 0.125, t_reg + 14.0,
                              [t_reg](double t) { return t - t_reg >= 5.0 ? 1.0 : 0.0; });
  EXPECT_TRUE(seq.depthLimit().contact());
  EXPECT_NEAR(seq.depthLimit().entry(), 2.5e-3, 0.07e-3);  // within one tick's feed
  EXPECT_LE(run.max_feed, arm.feedHome() + seq.depthLimit().entry() + 3e-3 + 1e-9);
  ASSERT_GE(run.stop_t, 0.0);
  EXPECT_NEAR(run.stop_t, t_reg + 11.0, 0.26);
  EXPECT_NE(run.stop.find("sensed contact"), std::string::npos) << run.stop;
}

TEST(TrialSequencerTarget, ThePoseAimedAtThePlanByTheTrackedMarker) {
  const std::string urdf = pedicle_drilling::test::workcellUrdf();
  pd::ArmCompensation arm = workcellArm();
  const Eigen::Vector3d tip = pd::ArmCompensation::tipAt(
      urdf, "world", "drill_tip",
      pd::KinematicChain::fromUrdfString(urdf, "world", "device_base").jointNames(),
      arm.drillingJoints());
  arm.setTipAtPose(tip);
  pd::TrialSequencerParams p = params();
  p.target_from_plan = true;
  pd::TrialSequencer seq(p, arm);
  // The plan 6 mm ahead of the tip and 3 mm aside, tilted 8 degrees, in the marker's frame.
  const Eigen::Vector3d d =
      Eigen::AngleAxisd(8.0 * M_PI / 180.0, Eigen::Vector3d::UnitY()) * arm.drillAxis();
  pd::DrillingPlan plan = planAhead(tip + Eigen::Vector3d(0.0, 0.003, 0.0), d, 6e-3, 3e-3, 0.0);
  seq.setPlan(plan);
  // No tracked marker yet: refused, naming it.
  std::string why = seq.start(request("stationary"), apModel(), 10.0);
  EXPECT_NE(why.find("tracked marker"), std::string::npos) << why;
  // The marker heard 0.5 s before the start places the plan (toDrilling's marker pose).
  seq.onMarker(9.5, 9.5, "world", Eigen::Vector3d(0.6, 0.0, 0.27), Eigen::Quaterniond::Identity(),
               kNoLookup);
  ASSERT_EQ(seq.start(request("stationary"), apModel(), 10.0), "");
  const pd::SequencerOutput out = seq.takeOutput();
  std::string aimed_why;
  const std::optional<pd::ArmCompensation> aimed =
      arm.aimedAt(plan.entry + Eigen::Vector3d(0.6, 0.0, 0.27), d, p.target_standoff_m, &aimed_why);
  ASSERT_TRUE(aimed) << aimed_why;
  ASSERT_EQ(out.trajectories.size(), 1u);
  const std::vector<double>& goal = out.trajectories[0].points.back().positions;
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(goal[i], aimed->homeJoints()[i], 1e-9) << i;
  EXPECT_LT((seq.arm().drillAxis() - d).norm(), 1e-6);
  // The registration then places the depth limit on the plan's own axis (no angle refusal).
  registerAt(&seq, 12.5);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kDrilling);
  EXPECT_TRUE(seq.depthLimit().active());
  // A marker too old refuses the next trial.
  pd::TrialSequencer late(p, arm);
  late.setPlan(plan);
  late.onMarker(5.0, 5.0, "world", Eigen::Vector3d(0.6, 0.0, 0.27), Eigen::Quaterniond::Identity(),
                kNoLookup);
  EXPECT_NE(late.start(request("stationary"), apModel(), 10.0).find("tracked marker"),
            std::string::npos);
}

TEST(TrialSequencerDepthLimit, APlanWithdrawnAfterTheStartFailsTheTrialAtTheRegistration) {
  const Eigen::Vector3d tip(0.6, 0.0, 0.3);
  pd::ArmCompensation arm = armWithTip(tip);
  pd::TrialSequencerParams p = params();
  p.depth_limit.require_plan = true;
  pd::TrialSequencer seq(p, arm);
  seq.setPlan(planAhead(tip, arm.drillAxis(), 2e-3, 3e-3, 0.0));
  ASSERT_EQ(seq.start(request("stationary"), apModel(), 10.0), "");
  seq.setPlan(std::nullopt);  // a refused plan arrived: the node clears it
  registerAt(&seq, 12.5);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kFailed);
}

TEST(TrialSequencerDepthLimit, APlanAtAnAngleToTheDrillFailsTheTrialBeforeTheFeed) {
  const Eigen::Vector3d tip(0.6, 0.0, 0.3);
  pd::ArmCompensation arm = armWithTip(tip);
  pd::TrialSequencer seq(params(), arm);
  pd::DrillingPlan p = planAhead(tip, arm.drillAxis(), 2e-3, 3e-3, 0.0);
  p.direction = Eigen::Vector3d(1.0, 0.0, 0.0);
  seq.setPlan(p);
  ASSERT_EQ(seq.start(request("stationary"), apModel(), 10.0), "");
  registerAt(&seq, 12.5);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kFailed);
}

// The breath source (setBreathSource): a moving trial needs a recent breath start; a source that
// falls silent while drilling stops the trial with retreat, the reason naming the source.
TEST(TrialSequencer, ASilentBreathSourceRefusesAndStopsAMovingTrialNamingIt) {
  pd::TrialSequencer seq(params(), workcellArm());
  seq.setBreathSource("flow on /lab/flow (via /tidal_volume)", 2.0);
  // The source's own report before any breath: quoted in the refusal.
  seq.setBreathSourceProblem("breath source flow on /lab/flow: no flow sample yet");
  std::string why = seq.check(request("compensated"));
  EXPECT_NE(why.find("needs the ventilator"), std::string::npos) << why;
  EXPECT_NE(why.find("/lab/flow: no flow sample yet"), std::string::npos) << why;
  EXPECT_EQ(seq.check(request("stationary")), "");  // the bone still: no breath needed
  seq.setBreathSourceProblem("");
  seq.setVentilator(pd::VentilatorSettings());  // 5 s breaths: 10 s bound
  seq.setBreathStart(0.0);
  // Its last start 10.5 s old: refused by the planner's own bound.
  why = seq.start(request("compensated"), apModel(), 10.5);
  EXPECT_NE(why.find("breath source silent"), std::string::npos) << why;
  EXPECT_NE(why.find("/lab/flow"), std::string::npos) << why;
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kIdle);
  // Recent: the trial starts and drills; the starts then stop coming.
  seq.setBreathStart(5.0);
  ASSERT_EQ(seq.start(request("compensated"), apModel(), 10.0), "");
  seq.takeOutput();
  registerAt(&seq, 12.5);
  ASSERT_EQ(seq.phase(), pd::TrialPhase::kDrilling);
  seq.takeOutput();
  std::vector<std::string> stops;
  double now = 13.0;
  for (; now < 20.0 && seq.phase() == pd::TrialPhase::kDrilling; now += 0.125) {
    seq.onSegmentTimer(now);
    for (const std::string& s : seq.takeOutput().stops) stops.push_back(s);
  }
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRetreating);
  ASSERT_EQ(stops.size(), 1u);
  EXPECT_NE(stops[0].find("breath source silent: no breath start from flow on /lab/flow"),
            std::string::npos)
      << stops[0];
  EXPECT_GT(now - 0.125 - 5.0, 10.0);  // the tick that stopped it: the first past the bound
  EXPECT_LE(now - 0.125 - 5.0, 10.0 + 0.125 + 1e-9);
}

TEST(TrialSequencer, TheBreathSourcesReportStopsADrillingTrial) {
  pd::TrialSequencer seq(params(), workcellArm());
  seq.setVentilator(pd::VentilatorSettings());
  seq.setBreathStart(9.0);
  ASSERT_EQ(seq.start(request("uncompensated"), apModel(), 10.0), "");
  seq.takeOutput();
  registerAt(&seq, 12.5);
  ASSERT_EQ(seq.phase(), pd::TrialPhase::kDrilling);
  seq.takeOutput();
  seq.onSegmentTimer(13.125);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kDrilling);  // no bound declared (0): no stop
  seq.setBreathSourceProblem("breath source flow on /lab/flow: no breath start for 10.1 s");
  seq.onSegmentTimer(13.25);
  EXPECT_EQ(seq.phase(), pd::TrialPhase::kRetreating);
  const pd::SequencerOutput out = seq.takeOutput();
  ASSERT_EQ(out.stops.size(), 1u);
  EXPECT_NE(out.stops[0].find("/lab/flow"), std::string::npos) << out.stops[0];
}
