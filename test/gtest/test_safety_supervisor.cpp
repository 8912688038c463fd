// Tests of the safety monitor as a component with streams: pairing, arming, the one stop report.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include "param_table_checks.hpp"
#include "pedicle_drilling/core/control/safety_supervisor.hpp"

namespace pedicle_drilling::core {
namespace {

const Eigen::Vector3d kBone(0.6, 0.0, 0.27);

StampedPosition at(double stamp, const Eigen::Vector3d& p, const std::string& frame = "camera") {
  return {stamp, frame, p};
}

TEST(SafetySupervisorTest, PairsPredictionWithTheTrackedSampleOfTheSameStamp) {
  SafetySupervisor s;
  // Tracked first, prediction later with the same stamp: compared (both orders work).
  EXPECT_EQ(s.onTracked(1.0, at(1.0, kBone)), PairResult::kUnpaired);
  EXPECT_EQ(s.onPredicted(1.01, at(1.0, kBone + Eigen::Vector3d(0, 0, 1.0e-3))),
            PairResult::kCompared);
  EXPECT_FALSE(s.verdict().stop);  // 1.0 mm < H1 = 1.2 mm
  EXPECT_EQ(s.onPredicted(1.125, at(1.125, kBone + Eigen::Vector3d(0, 0, 1.5e-3))),
            PairResult::kUnpaired);
  EXPECT_EQ(s.onTracked(1.13, at(1.125, kBone)), PairResult::kCompared);
  ASSERT_TRUE(s.verdict().stop);
  EXPECT_EQ(s.verdict().reason, SafetyVerdict::kPositionError);
}

TEST(SafetySupervisorTest, ATrackerRepeatingAnOldStampIsStaleAndTimesOut) {
  SafetySupervisor s;  // tracker_timeout_s = 0.5
  EXPECT_EQ(s.onTracked(1.0, at(1.0, kBone)), PairResult::kUnpaired);
  double t = 1.0;
  for (int i = 0; i < 8; ++i) {  // 1 s of a stale tf: the same pose and stamp, 8 Hz
    t += 0.125;
    EXPECT_EQ(s.onTracked(t, at(1.0, kBone)), PairResult::kStale);
    // The planner's prediction for that stale stamp pairs, but is no sign of a live tracker.
    s.onPredicted(t, at(1.0, kBone));
    s.onForce(t, Eigen::Vector3d(0, 0, t));
    s.check(t);
  }
  EXPECT_EQ(s.staleTrackedCount(), 8);
  ASSERT_TRUE(s.verdict().stop);
  EXPECT_EQ(s.verdict().reason, SafetyVerdict::kTrackerTimeout);
}

TEST(SafetySupervisorTest, SamplesFurtherApartThanTheToleranceAreNotCompared) {
  SupervisorParams p;
  p.pair_tolerance_s = 0.02;
  SafetySupervisor s(p);
  s.onTracked(1.0, at(1.0, kBone));
  // 5 mm off but 30 ms apart: not the same sample, not compared, no stop.
  EXPECT_EQ(s.onPredicted(1.0, at(1.03, kBone + Eigen::Vector3d(0, 0, 5e-3))),
            PairResult::kUnpaired);
  EXPECT_FALSE(s.verdict().stop);
}

TEST(SafetySupervisorTest, DifferentFramesOutsideDrillingAreReportedNotCompared) {
  SafetySupervisor s;
  s.onTracked(1.0, at(1.0, kBone, "camera"));
  EXPECT_EQ(s.onPredicted(1.0, at(1.0, kBone + Eigen::Vector3d(0, 0, 5e-3), "world")),
            PairResult::kFrameMismatch);
  EXPECT_FALSE(s.verdict().stop);
}

TEST(SafetySupervisorTest, DifferentFramesWhileDrillingStopAtOnce) {
  SafetySupervisor s;
  s.setTrialRunning(true);
  s.setDrilling(0.9, true);
  s.onTracked(1.0, at(1.0, kBone, "camera"));
  // The same position: only the frames differ. H1 cannot be checked, so it fails closed.
  EXPECT_EQ(s.onPredicted(1.0, at(1.0, kBone, "world")), PairResult::kFrameMismatch);
  ASSERT_TRUE(s.verdict().stop);
  EXPECT_EQ(s.verdict().reason, SafetyVerdict::kPredictionLost);
  EXPECT_DOUBLE_EQ(s.verdict().t, 1.0);
}

/** @brief A live force sensor and an 8 Hz tracker from t0 to t1 (1 ms checks); the planner's
 *         prediction for each tracker sample while `predict(t)` (at the sample's own stamp). */
template <typename Predict>
void runStreams(SafetySupervisor* s, double t0, double t1, Predict predict) {
  for (int k = 0; t0 + 1e-3 * k <= t1; ++k) {
    const double t = t0 + 1e-3 * k;
    s->onForce(t, Eigen::Vector3d(0, 0, 1.0 + 1e-3 * k));  // live: never bit-identical
    if (k % 125 == 0) {
      s->onTracked(t, at(t, kBone));
      if (predict(t)) s->onPredicted(t + 2e-3, at(t, kBone));
    }
    s->check(t);
    if (s->verdict().stop) return;
  }
}

TEST(SafetySupervisorTest, PredictionsThatStopWhileDrillingStopWithinTheTimeout) {
  SupervisorParams p;  // prediction_timeout_s 0.5, tracker_timeout_s 0.5
  SafetySupervisor s(p);
  s.setTrialRunning(true);
  s.setDrilling(0.0, true);
  // Predictions until t = 2 s, then none: the tracker goes on, so only the H1 watch can see it.
  runStreams(&s, 0.0, 5.0, [](double t) { return t < 2.0; });
  ASSERT_TRUE(s.verdict().stop);
  EXPECT_EQ(s.verdict().reason, SafetyVerdict::kPredictionLost);
  // The last pair was compared at 1.875 s + 2 ms (the prediction's arrival): the stop comes
  // prediction_timeout_s after it, at the next 1 ms check.
  EXPECT_GT(s.verdict().t, 1.877 + p.safety.prediction_timeout_s);
  EXPECT_LE(s.verdict().t, 1.877 + p.safety.prediction_timeout_s + 1.5e-3);
}

TEST(SafetySupervisorTest, StalePredictionsThatNeverPairStopWhileDrilling) {
  SafetySupervisor s;
  s.setTrialRunning(true);
  s.setDrilling(0.0, true);
  // Predictions stamped 50 ms before the tracker sample (beyond the 20 ms pairing tolerance).
  for (int k = 0; k <= 5000 && !s.verdict().stop; ++k) {
    const double t = 1e-3 * k;
    s.onForce(t, Eigen::Vector3d(0, 0, 1.0 + t));
    if (k % 125 == 0) {
      s.onTracked(t, at(t, kBone));
      s.onPredicted(t + 2e-3, at(t - 0.05, kBone));
    }
    s.check(t);
  }
  ASSERT_TRUE(s.verdict().stop);
  EXPECT_EQ(s.verdict().reason, SafetyVerdict::kPredictionLost);
  EXPECT_NEAR(s.verdict().t, 0.5, 2e-3);  // from setDrilling(0.0): no pair ever
}

TEST(SafetySupervisorTest, MissingPredictionsOutsideDrillingAreNoStop) {
  SafetySupervisor s;
  s.setTrialRunning(true);  // moving to the pose, registering: no prediction yet
  runStreams(&s, 0.0, 3.0, [](double) { return false; });
  EXPECT_FALSE(s.verdict().stop);
  // The drilling starts at 3 s, predictions come: no stop; the retreat ends the watch.
  s.setDrilling(3.0, true);
  runStreams(&s, 3.0, 6.0, [](double) { return true; });
  EXPECT_FALSE(s.verdict().stop);
  s.setDrilling(6.0, false);
  runStreams(&s, 6.0, 9.0, [](double) { return false; });
  EXPECT_FALSE(s.verdict().stop);
}

TEST(SafetySupervisorTest, QuietUntilIncludesThePredictionDeadline) {
  SafetySupervisor s;
  s.setTrialRunning(true);
  s.onForce(0.0, Eigen::Vector3d(0, 0, 1.0));
  s.onTracked(0.0, at(0.0, kBone));
  s.setDrilling(0.0, true);
  s.onForce(0.45, Eigen::Vector3d(0, 0, 1.1));
  s.onTracked(0.45, at(0.45, kBone));     // the streams are fresh until 0.55 and 0.95
  EXPECT_DOUBLE_EQ(s.quietUntil(), 0.5);  // the prediction's: nothing compared since 0.0
  s.onPredicted(0.46, at(0.45, kBone));
  EXPECT_DOUBLE_EQ(s.quietUntil(), 0.55);  // compared at 0.46: the force's deadline is first
}

TEST(SafetySupervisorTest, NonFinitePredictionStops) {
  SafetySupervisor s;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  s.onPredicted(1.0, at(1.0, Eigen::Vector3d(nan, 0, 0)));
  ASSERT_TRUE(s.verdict().stop);
  EXPECT_EQ(s.verdict().reason, SafetyVerdict::kNaNInput);
}

TEST(SafetySupervisorTest, WatchdogArmsOnBothStreamsOrOnARunningTrial) {
  SupervisorParams p;
  p.safety.force_timeout_s = 0.1;
  p.safety.tracker_timeout_s = 0.5;
  {
    // Nothing heard, no trial: a silent workcell is not an error.
    SafetySupervisor s(p);
    s.check(0.0);
    s.check(10.0);
    EXPECT_FALSE(s.verdict().stop);
    EXPECT_FALSE(s.heardBoth());
  }
  {
    // A trial runs: a force sensor that never published times out from the arming time.
    SafetySupervisor s(p);
    s.setTrialRunning(true);
    s.check(0.0);
    s.check(0.05);
    EXPECT_FALSE(s.verdict().stop);
    s.check(0.2);
    ASSERT_TRUE(s.verdict().stop);
    EXPECT_EQ(s.verdict().reason, SafetyVerdict::kForceTimeout);
  }
  {
    // Both heard, then the tracker goes silent.
    SafetySupervisor s(p);
    s.onTracked(0.0, at(0.0, kBone));
    for (double t = 0.0; t < 0.7; t += 0.001) {
      s.onForce(t, Eigen::Vector3d(0, 0, 1.0 + t));  // live: never bit-identical
      s.check(t);
    }
    EXPECT_TRUE(s.heardBoth());
    ASSERT_TRUE(s.verdict().stop);
    EXPECT_EQ(s.verdict().reason, SafetyVerdict::kTrackerTimeout);
  }
}

TEST(SafetySupervisorTest, ReportsTheStopOnceUntilReset) {
  SafetySupervisor s;
  EXPECT_FALSE(s.takeNewStop());
  s.onForce(1.0, Eigen::Vector3d(0, 0, 12.0));  // > H2 = 10 N
  const std::optional<SafetyVerdict> first = s.takeNewStop();
  ASSERT_TRUE(first);
  EXPECT_EQ(first->reason, SafetyVerdict::kForceExceeded);
  s.onForce(1.001, Eigen::Vector3d(0, 0, 15.0));
  EXPECT_FALSE(s.takeNewStop());  // latched: one stop command, the first cause
  EXPECT_EQ(s.verdict().reason, SafetyVerdict::kForceExceeded);
  s.reset();
  EXPECT_FALSE(s.verdict().stop);
  EXPECT_FALSE(s.heardBoth());
  s.onForce(2.0, Eigen::Vector3d(0, 0, 11.0));
  EXPECT_TRUE(s.takeNewStop());
}

TEST(SafetySupervisorTest, RejectsBadParametersNamingThem) {
  SupervisorParams p;
  p.pair_tolerance_s = -1.0;
  try {
    SafetySupervisor s(p);
    FAIL() << "accepted a negative pair tolerance";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("pair_tolerance_s", 0), 0u) << e.what();
  }
  p = SupervisorParams();
  p.safety.force_threshold_N = 0.0;
  EXPECT_THROW(SafetySupervisor s(p), std::invalid_argument);
}

TEST(SupervisorParamsTest, TheTableIsTheMonitorsThenThePairing) {
  const ParamTable<SupervisorParams>& table = SupervisorParams::table();
  const std::vector<std::string> safety = SafetyParams::table().declaredNames();
  std::vector<std::string> names = safety;
  names.insert(names.end(), {"pair_tolerance_s", "history"});
  EXPECT_EQ(table.declaredNames(), names);
  const std::vector<ParamInfo> described = table.describe(SupervisorParams());
  ASSERT_EQ(described.size(), names.size());
  EXPECT_EQ(described[safety.size()].default_text, "0.02");
  EXPECT_EQ(described[safety.size() + 1].default_text, "64");
  pedicle_drilling::test::expectRangesRefusedNamingTheField(table);
  SupervisorParams p;
  p.history = 0;
  EXPECT_EQ(pedicle_drilling::test::invalidArgumentOf([&p] { p.validate(); }),
            "history = 0 is out of range [1, 10000] samples");
}

TEST(SafetySupervisorTest, QuietUntilBoundsWhatACheckCanChange) {
  SafetySupervisor s;  // force_timeout_s 0.1, tracker_timeout_s 0.5
  EXPECT_EQ(s.quietUntil(), std::numeric_limits<double>::infinity());  // not checking yet
  s.setTrialRunning(true);
  EXPECT_EQ(s.quietUntil(), -std::numeric_limits<double>::infinity());  // the next check arms
  s.check(2.0);
  EXPECT_DOUBLE_EQ(s.quietUntil(), 2.1);  // armed at 2.0, no force ever: 2.0 + 0.1
  s.onForce(2.05, Eigen::Vector3d(0, 0, 1));
  s.onTracked(2.05, at(2.05, kBone));
  EXPECT_DOUBLE_EQ(s.quietUntil(), 2.15);
  s.check(2.14);
  EXPECT_FALSE(s.verdict().stop);
  s.check(2.16);
  ASSERT_TRUE(s.verdict().stop);
  EXPECT_EQ(s.quietUntil(), std::numeric_limits<double>::infinity());  // latched
}

TEST(SafetySupervisorTest, NextUsefulCheckTickIsTheGridStepAPeriodBeforeQuiet) {
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(nextUsefulCheckTick(1.0, 200.0, -inf), 201.0);  // unarmed: the next grid step
  EXPECT_EQ(nextUsefulCheckTick(1.002, 200.0, -inf), 201.0);
  EXPECT_EQ(nextUsefulCheckTick(1.0, 200.0, 1.1), 219.0);    // 1.095 s: a period before 1.1 s
  EXPECT_EQ(nextUsefulCheckTick(1.0, 200.0, 1.003), 201.0);  // never before the next step
  EXPECT_EQ(nextUsefulCheckTick(1.0, 200.0, inf), inf);
}

// The monitor's nodelet under the lockstep skips the 200 Hz checks before quietUntil() (one
// period early): random streams with silences, a supervisor checked at every tick and one
// checked only at the grid steps it sees (a sample, the trial's start, or the step it asked
// for, recomputed after every step it sees). Their verdicts are equal at every 1 ms step,
// timeouts included.
TEST(SafetySupervisorTest, SkippingTheChecksBeforeQuietUntilChangesNoVerdict) {
  int timeouts = 0;
  for (unsigned seed = 1; seed <= 300; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    SafetySupervisor every, fewer;
    const int steps = 8000;
    // Silences: [start, end) in ms, per stream.
    const auto silence = [&](double longest_ms) {
      const int start = static_cast<int>(u(rng) * steps);
      return std::make_pair(start, start + static_cast<int>(u(rng) * longest_ms));
    };
    const auto force_gap = silence(300.0), tracker_gap = silence(1200.0);
    const int trial_start = static_cast<int>(u(rng) * 2000.0);
    const bool never_tracked = u(rng) < 0.1;
    double wanted_tick = -1.0;  // fewer's next check (grid index); -1: the next one
    for (int n = 0; n < steps; ++n) {
      const double t = n * 1e-3;
      bool seen = false;
      for (SafetySupervisor* s : {&every, &fewer}) {
        if (n == trial_start) s->setTrialRunning(true);
        if (n % 3 == 0 && (n < force_gap.first || n >= force_gap.second)) {
          s->onForce(t, Eigen::Vector3d(0, 0, 1.0 + 1e-3 * n));
          seen = true;
        }
        if (!never_tracked && n % 125 == 0 && (n < tracker_gap.first || n >= tracker_gap.second)) {
          s->onTracked(t, at(t, kBone));
          seen = true;
        }
      }
      if (n == trial_start) seen = true;  // the planner's phase: a step every participant sees
      if (n % 5 == 0) {
        every.check(t);
        if (seen || n / 5 >= wanted_tick) {  // a step it sees on the grid checks too
          fewer.check(t);
          seen = true;
        }
      }
      if (seen) {  // the nodelet's nextStep after a step it saw
        wanted_tick = nextUsefulCheckTick(t, 200.0, fewer.quietUntil());
      }
      ASSERT_EQ(every.verdict().stop, fewer.verdict().stop)
          << "seed " << seed << " t " << t << " " << every.verdict().message << " wanted "
          << wanted_tick << " quiet " << fewer.quietUntil() << " start " << trial_start << " fg "
          << force_gap.first << "-" << force_gap.second << " tg " << tracker_gap.first << "-"
          << tracker_gap.second;
      ASSERT_EQ(every.verdict().reason, fewer.verdict().reason) << "seed " << seed;
      ASSERT_EQ(every.verdict().t, fewer.verdict().t) << "seed " << seed;
    }
    const auto r = every.verdict().reason;
    timeouts += r == SafetyVerdict::kForceTimeout || r == SafetyVerdict::kTrackerTimeout;
  }
  EXPECT_GT(timeouts, 100);  // the streams' silences stopped many of the 300
}

}  // namespace
}  // namespace pedicle_drilling::core
