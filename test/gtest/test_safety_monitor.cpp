// Tests of the Algorithm 1 monitor and the retreat planner.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "pedicle_drilling/core/control/safety_monitor.hpp"

namespace pedicle_drilling::core {
namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();
const Eigen::Vector3d kZero = Eigen::Vector3d::Zero();

// Feeds healthy data at 1 kHz force / 8 Hz tracker from t0 to t1, checking each ms. The force
// changes by one count of a Nano17 (1/320 N) every sample, as a live sensor's noise does.
void healthy(SafetyMonitor& m, double t0, double t1) {
  int n = 0;
  for (double t = t0; t < t1; t += 1e-3) {
    m.onForce(t, Eigen::Vector3d(0.1, -0.2, 3.0 + (n++ % 2) / 320.0));
    if (std::fmod(t - t0, 0.125) < 1e-3) {
      m.onTracked(t, Eigen::Vector3d(0.01, 0.02, 0.03), Eigen::Vector3d(0.0105, 0.02, 0.03));
    }
    m.check(t);
  }
}

TEST(SafetyMonitorTest, DefaultsAreThePapers) {
  SafetyParams p;
  EXPECT_DOUBLE_EQ(p.position_threshold_m, 1.2e-3);
  EXPECT_DOUBLE_EQ(p.force_threshold_N, 10.0);
  EXPECT_NO_THROW(p.validate());
}

// Feeds `offset` N on z plus alternating +-noise at 1 kHz from t0 to t1 (a drill out of the bone).
void atRest(SafetyMonitor& m, double t0, double t1, double offset, double noise = 0.03) {
  int n = 0;
  for (double t = t0; t < t1; t += 1e-3) {
    m.onForce(t, Eigen::Vector3d(0.0, 0.0, offset + ((n++ % 2) ? noise : -noise)));
  }
}

TEST(SafetyMonitorTest, RetareCheckMeasuresTheOffsetOverItsWindowOnly) {
  SafetyMonitor m;            // 0.3 N, 0.25 s
  atRest(m, 0.0, 1.0, 5.0);   // in the bone: 5 N, before the window
  atRest(m, 1.0, 1.5, 0.05);  // out of the bone: 0.05 N from the tare
  const RetareCheck ok = m.retareCheck(1.5);
  EXPECT_TRUE(ok.done);
  EXPECT_NEAR(ok.offset_n, 0.05, 0.01);
  EXPECT_GE(ok.samples, 240);
  EXPECT_LE(ok.samples, 251);
  EXPECT_FALSE(ok.drift);
  EXPECT_TRUE(ok.message.empty());
  EXPECT_FALSE(m.stopped());  // a check, not a stop
}

TEST(SafetyMonitorTest, RetareCheckFlagsADriftAboveItsLimitOnly) {
  SafetyMonitor m;
  atRest(m, 0.0, 0.5, 0.45);  // a sensor that drifted 0.45 N (0.2 N/s for 2.25 s)
  const RetareCheck drift = m.retareCheck(0.5);
  EXPECT_TRUE(drift.drift);
  EXPECT_NEAR(drift.offset_n, 0.45, 0.01);
  EXPECT_EQ(drift.message.rfind("force_offset: 0.45", 0), 0u) << drift.message;
  SafetyParams off;
  off.retare_max_offset_n = 0.0;  // the check off
  SafetyMonitor quiet(off);
  atRest(quiet, 0.0, 0.5, 0.45);
  EXPECT_FALSE(quiet.retareCheck(0.5).drift);
  SafetyMonitor none;
  EXPECT_FALSE(none.retareCheck(1.0).done);  // no sample: nothing to say
  atRest(none, 0.0, 0.5, 0.45);
  none.reset();
  EXPECT_FALSE(none.retareCheck(0.5).done);  // reset forgets the window
  SafetyParams bad;
  bad.retare_max_offset_n = -1.0;
  EXPECT_THROW(SafetyMonitor{bad}, std::invalid_argument);
}

TEST(SafetyMonitorTest, HealthyDataNeverStops) {
  SafetyMonitor m;
  healthy(m, 0.0, 5.0);
  EXPECT_FALSE(m.check(5.0).stop);
  EXPECT_EQ(m.verdict().reason, SafetyVerdict::kNone);
  EXPECT_TRUE(m.verdict().message.empty());
}

TEST(SafetyMonitorTest, PositionErrorTriggersAboveH1Only) {
  SafetyMonitor m;
  const Eigen::Vector3d pred(0.0, 0.0, 0.0);
  m.onTracked(0.0, pred, Eigen::Vector3d(1.19e-3, 0, 0));
  m.onForce(0.0, kZero);
  EXPECT_FALSE(m.check(0.0).stop);
  m.onTracked(0.1, pred, Eigen::Vector3d(0.7e-3, 0.7e-3, 0.7e-3));  // norm 1.21 mm
  const SafetyVerdict& v = m.check(0.1);
  EXPECT_TRUE(v.stop);
  EXPECT_EQ(v.reason, SafetyVerdict::kPositionError);
  EXPECT_DOUBLE_EQ(v.t, 0.1);
  EXPECT_NE(v.message.find("position"), std::string::npos);
}

TEST(SafetyMonitorTest, ForceTriggersOnNormAboveH2) {
  SafetyMonitor m;
  m.onForce(0.0, Eigen::Vector3d(0, 0, 10.0));  // equal: no stop
  EXPECT_FALSE(m.check(0.0).stop);
  m.onForce(0.001, Eigen::Vector3d(6.0, 0, 8.1));  // norm 10.08 N, no single axis above 10
  EXPECT_TRUE(m.check(0.001).stop);
  EXPECT_EQ(m.verdict().reason, SafetyVerdict::kForceExceeded);
}

TEST(SafetyMonitorTest, ABitIdenticalForceLongerThanForceStuckSIsAFrozenSensor) {
  SafetyMonitor m;  // force_stuck_s = 0.05
  const Eigen::Vector3d f(0.1, 0.2, 3.0);
  for (int i = 0; i <= 50; ++i) m.onForce(i * 1e-3, f);  // 0 .. 50 ms: not longer than 50 ms
  EXPECT_FALSE(m.stopped());
  m.onForce(0.0505, f + Eigen::Vector3d(0, 0, 1.0 / 320));  // one count changes: a new run
  for (int i = 1; i <= 50; ++i) m.onForce(0.0505 + i * 1e-3, f + Eigen::Vector3d(0, 0, 1.0 / 320));
  EXPECT_FALSE(m.stopped());
  m.onForce(0.0505 + 0.051, f + Eigen::Vector3d(0, 0, 1.0 / 320));
  ASSERT_TRUE(m.stopped());
  EXPECT_EQ(m.verdict().reason, SafetyVerdict::kForceStuck);
  EXPECT_STREQ(toString(SafetyVerdict::kForceStuck), "force_stuck");
}

TEST(SafetyMonitorTest, ForceStuckInfinityDisablesTheCheck) {
  SafetyParams p;
  p.force_stuck_s = std::numeric_limits<double>::infinity();
  SafetyMonitor m(p);
  for (int i = 0; i < 5000; ++i) m.onForce(i * 1e-3, Eigen::Vector3d::Zero());
  EXPECT_FALSE(m.stopped());
  p.force_stuck_s = 0.0;
  EXPECT_THROW(p.validate(), std::invalid_argument);
}

TEST(SafetyMonitorTest, ComparingPositionsDoesNotFeedTheTrackerWatchdog) {
  SafetyMonitor m;  // tracker_timeout_s = 0.5
  m.onTracked(0.0, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  for (int i = 1; i <= 10; ++i) {
    m.comparePositions(i * 0.1, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
    m.onForce(i * 0.1, Eigen::Vector3d(0, 0, i * 0.01));
  }
  m.check(0.6);
  ASSERT_TRUE(m.stopped());
  EXPECT_EQ(m.verdict().reason, SafetyVerdict::kTrackerTimeout);
}

TEST(SafetyMonitorTest, ForceTimeout) {
  SafetyMonitor m;  // force timeout 0.1 s, tracker 0.5 s
  m.onTracked(0.0, kZero, kZero);
  m.onForce(0.0, kZero);
  EXPECT_FALSE(m.check(0.1).stop);
  m.onTracked(0.125, kZero, kZero);
  const SafetyVerdict& v = m.check(0.1005);
  EXPECT_TRUE(v.stop);
  EXPECT_EQ(v.reason, SafetyVerdict::kForceTimeout);
}

TEST(SafetyMonitorTest, TrackerTimeout) {
  SafetyMonitor m;
  m.onTracked(0.0, kZero, kZero);
  for (double t = 0; t <= 0.5; t += 1e-3) {
    m.onForce(t, Eigen::Vector3d(0, 0, t));  // a live force (never bit-identical)
    EXPECT_FALSE(m.check(t).stop) << t;
  }
  m.onForce(0.51, Eigen::Vector3d(0, 0, 0.51));
  EXPECT_TRUE(m.check(0.51).stop);
  EXPECT_EQ(m.verdict().reason, SafetyVerdict::kTrackerTimeout);
}

TEST(SafetyMonitorTest, TimeoutWithoutAnySampleCountsFromArming) {
  SafetyMonitor m;
  EXPECT_FALSE(m.check(10.0).stop);  // arms at 10 s
  EXPECT_FALSE(m.check(10.05).stop);
  EXPECT_TRUE(m.check(10.2).stop);
  EXPECT_EQ(m.verdict().reason, SafetyVerdict::kForceTimeout);
}

TEST(SafetyMonitorTest, InfiniteTimeoutDisables) {
  SafetyParams p;
  p.force_timeout_s = std::numeric_limits<double>::infinity();
  p.tracker_timeout_s = std::numeric_limits<double>::infinity();
  SafetyMonitor m(p);
  m.check(0);
  EXPECT_FALSE(m.check(1e6).stop);
}

TEST(SafetyMonitorTest, NaNInputsTrigger) {
  {
    SafetyMonitor m;
    m.onForce(0.0, Eigen::Vector3d(0, kNaN, 0));
    EXPECT_TRUE(m.check(0.0).stop);
    EXPECT_EQ(m.verdict().reason, SafetyVerdict::kNaNInput);
  }
  {
    SafetyMonitor m;
    m.onTracked(0.0, kZero, Eigen::Vector3d(kNaN, 0, 0));
    EXPECT_EQ(m.check(0.0).reason, SafetyVerdict::kNaNInput);
  }
  {
    SafetyMonitor m;
    m.onTracked(0.0, Eigen::Vector3d(0, 0, std::numeric_limits<double>::infinity()), kZero);
    EXPECT_EQ(m.check(0.0).reason, SafetyVerdict::kNaNInput);
  }
  {
    SafetyMonitor m;
    m.onForce(kNaN, kZero);
    EXPECT_EQ(m.check(0.0).reason, SafetyVerdict::kNaNInput);
  }
  {
    SafetyMonitor m;
    EXPECT_EQ(m.check(kNaN).reason, SafetyVerdict::kNaNInput);
  }
}

TEST(SafetyMonitorTest, LatchedUntilResetKeepsFirstReason) {
  SafetyMonitor m;
  healthy(m, 0.0, 1.0);
  m.onForce(1.0, Eigen::Vector3d(0, 0, 12.0));
  EXPECT_EQ(m.check(1.0).reason, SafetyVerdict::kForceExceeded);
  // Healthy data afterwards does not clear it; a later different cause does not replace it.
  healthy(m, 1.0, 2.0);
  m.onTracked(2.0, kZero, Eigen::Vector3d(5e-3, 0, 0));
  EXPECT_TRUE(m.check(2.0).stop);
  EXPECT_EQ(m.verdict().reason, SafetyVerdict::kForceExceeded);
  EXPECT_DOUBLE_EQ(m.verdict().t, 1.0);
  EXPECT_TRUE(m.stopped());
  m.reset();
  EXPECT_FALSE(m.stopped());
  EXPECT_EQ(m.verdict().reason, SafetyVerdict::kNone);
  // After reset the old sample times are forgotten: no immediate timeout at a much later time.
  EXPECT_FALSE(m.check(100.0).stop);
  healthy(m, 100.0, 101.0);
  EXPECT_FALSE(m.check(101.0).stop);
}

TEST(SafetyMonitorTest, ReasonNames) {
  EXPECT_STREQ(toString(SafetyVerdict::kPositionError), "position_error");
  EXPECT_STREQ(toString(SafetyVerdict::kNaNInput), "nan_input");
}

TEST(SafetyMonitorTest, ParameterValidationNamesField) {
  const auto expectNamed = [](SafetyParams p, const std::string& name) {
    try {
      SafetyMonitor m(p);
      ADD_FAILURE() << name;
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()).rfind(name, 0), 0u) << e.what();
    }
  };
  SafetyParams p;
  p.position_threshold_m = 0.0;
  expectNamed(p, "position_threshold_m");
  p = SafetyParams();
  p.force_threshold_N = kNaN;
  expectNamed(p, "force_threshold_n");  // the declared (ROS) name
  p = SafetyParams();
  p.force_timeout_s = -1.0;
  expectNamed(p, "force_timeout_s");
  p = SafetyParams();
  p.tracker_timeout_s = kNaN;
  expectNamed(p, "tracker_timeout_s");
}

TEST(RetreatPlannerTest, RetreatsAlongMinusAxisTrapezoidal) {
  EXPECT_DOUBLE_EQ(RetreatParams().accel_m_s2, 1.0);  // the default: backs out at once
  RetreatParams slow;
  slow.accel_m_s2 = 50e-3;  // 10 mm, 5 mm/s, 50 mm/s^2: a visible trapezoid
  RetreatPlanner planner(slow);
  const Eigen::Vector3d tip(0.1, 0.2, 0.3);
  const Eigen::Vector3d axis(0, 0, -2.0);  // drilling downwards; not normalised
  const RetreatMotion r = planner.plan(3.0, tip, axis);
  EXPECT_EQ(r.position(3.0), tip);
  EXPECT_NEAR((r.target() - Eigen::Vector3d(0.1, 0.2, 0.31)).norm(), 0.0, 1e-15);
  EXPECT_NEAR(r.endTime(), 3.0 + 2.1, 1e-12);
  EXPECT_FALSE(r.finished(5.0));
  EXPECT_TRUE(r.finished(5.1));
  EXPECT_EQ(r.position(6.0), r.target());
  double vmax = 0;
  for (double t = 3.0; t <= 5.1; t += 1e-3) {
    const Eigen::Vector3d v = r.velocity(t);
    vmax = std::max(vmax, v.norm());
    EXPECT_GE(v.z(), 0.0);  // always backwards (against the drilling direction)
    EXPECT_NEAR(v.x(), 0.0, 1e-15);
    const double h = 1e-6;
    if (t > 3.0 + h && t < 5.1 - h) {
      EXPECT_LE((r.velocity(t + h) - r.velocity(t - h)).norm() / (2 * h), 50e-3 * (1 + 1e-6));
    }
  }
  EXPECT_NEAR(vmax, 5e-3, 1e-9);
}

TEST(RetreatPlannerTest, Validation) {
  RetreatParams p;
  p.speed_m_s = 0.0;
  EXPECT_THROW(RetreatPlanner{p}, std::invalid_argument);
  RetreatPlanner planner;
  EXPECT_THROW(planner.plan(0.0, kZero, kZero), std::invalid_argument);
  EXPECT_THROW(planner.plan(0.0, Eigen::Vector3d(kNaN, 0, 0), Eigen::Vector3d::UnitZ()),
               std::invalid_argument);
}

}  // namespace
}  // namespace pedicle_drilling::core
