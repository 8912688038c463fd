// Tests of core::TrialView, PanelSettings and layoutLabels: what the rviz plugins show,
// without Qt, Ogre or ROS.
#include "pedicle_drilling/core/control/trial_view.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace pd = pedicle_drilling::core;

namespace {

std::string value(const pd::TrialView& view, const std::string& label) {
  for (const pd::Readout& r : view.readouts()) {
    if (r.label == label) return r.value;
  }
  return "(no readout " + label + ")";
}

bool alarm(const pd::TrialView& view, const std::string& label) {
  for (const pd::Readout& r : view.readouts()) {
    if (r.label == label) return r.alarm;
  }
  return false;
}

/** @brief A trial through its phases; the recognizer stops in the inner layer. */
void runTrial(pd::TrialView* view, double residual_m, bool monitor_stop = false) {
  view->onPhase("moving_to_pose", true);
  view->onPhase("registering", true);
  view->onPhase("drilling", true);
  view->onRecognizer("cancellous", 3, 1.2, 0.4, false);
  view->onGroundTruth(0.008, 0.009, 0.011, 0.003, false);
  view->onRecognizer("stopped", 4, 3.1, 2.5, !monitor_stop);
  if (monitor_stop) {
    view->onStop("/safety_monitor", "force_exceeded: force 10.2 N > 10.000 N", true);
  } else {
    view->onStop("/state_recognizer", "inner cortical layer reached", false);
  }
  view->onGroundTruth(0.011 - residual_m, 0.009, 0.011, residual_m, false);
  view->onPhase("stopped", true);
  view->onPhase("retreating", true);
  view->onPhase("done", false);
}

}  // namespace

TEST(PanelSettings, ValidatesNamingTheFieldAndRoundTripsThroughTheConfiguration) {
  pd::PanelSettings s;
  EXPECT_NO_THROW(s.validate());
  s.mode = "sideways";
  EXPECT_THROW(s.validate(), std::invalid_argument);
  try {
    s.validate();
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("mode", 0), 0u);
  }
  s = pd::PanelSettings();
  s.mode = "stationary";
  s.segment_profile = "exact";
  s.spindle_rpm = 16000.0;
  s.feed_rate_mm_s = 0.75;
  s.seed = 18446744073709551615ull;
  std::vector<std::string> problems;
  const pd::PanelSettings back = pd::PanelSettings::fromConfig(s.toConfig(), &problems);
  EXPECT_TRUE(problems.empty());
  EXPECT_EQ(back.mode, "stationary");
  EXPECT_EQ(back.segment_profile, "exact");
  EXPECT_EQ(back.spindle_rpm, 16000.0);
  EXPECT_EQ(back.feed_rate_mm_s, 0.75);
  EXPECT_EQ(back.seed, 18446744073709551615ull);
}

TEST(PanelSettings, ABrokenConfigurationKeepsTheDefaultsAndSaysWhich) {
  std::vector<std::string> problems;
  const pd::PanelSettings s = pd::PanelSettings::fromConfig(
      {{"Mode", "sideways"}, {"Rpm", "fast"}, {"Feed", "-1"}, {"Seed", "-3"}, {"Profile", "x"}},
      &problems);
  const pd::PanelSettings defaults;
  EXPECT_EQ(s.mode, defaults.mode);
  EXPECT_EQ(s.spindle_rpm, defaults.spindle_rpm);
  EXPECT_EQ(s.feed_rate_mm_s, defaults.feed_rate_mm_s);
  EXPECT_EQ(s.seed, defaults.seed);
  EXPECT_EQ(s.segment_profile, defaults.segment_profile);
  EXPECT_NO_THROW(s.validate());
  ASSERT_EQ(problems.size(), 5u);
  std::string all;
  for (const std::string& p : problems) all += p + "\n";
  for (const char* key : {"mode", "Rpm", "feed_rate_mm_s", "Seed", "segment_profile"}) {
    EXPECT_NE(all.find(key), std::string::npos) << key << " in\n" << all;
  }
}

TEST(TrialView, ARecognizerStopInsideTheInnerLayerIsASuccessWithItsResidual) {
  pd::TrialView view;
  EXPECT_EQ(view.verdict(), pd::TrialVerdict::kNone);
  runTrial(&view, 1.4e-3);
  EXPECT_TRUE(view.ended());
  EXPECT_EQ(view.verdict(), pd::TrialVerdict::kSuccess);
  EXPECT_EQ(value(view, "residual"), "1.40 mm");
  EXPECT_EQ(value(view, "verdict"), "SUCCESS");
  EXPECT_EQ(value(view, "recognizer"), "stopped, key point 4");
  EXPECT_NE(view.summary().find("residual 1.40 mm"), std::string::npos) << view.summary();
  EXPECT_NE(view.summary().find("SUCCESS"), std::string::npos);
  EXPECT_FALSE(alarm(view, "verdict"));
}

TEST(TrialView, TooMuchLeftAMonitorStopOrAFailedTrialIsAFailure) {
  pd::TrialView thick;
  runTrial(&thick, 2.5e-3);
  EXPECT_EQ(thick.verdict(), pd::TrialVerdict::kFailure);
  pd::TrialView monitor;
  runTrial(&monitor, 1.0e-3, true);
  EXPECT_EQ(monitor.verdict(), pd::TrialVerdict::kFailure);
  EXPECT_TRUE(alarm(monitor, "stop"));
  EXPECT_NE(value(monitor, "stop").find("/safety_monitor: force_exceeded"), std::string::npos);
  pd::TrialView failed;
  failed.onPhase("moving_to_pose", true);
  failed.onPhase("failed", false);
  EXPECT_EQ(failed.verdict(), pd::TrialVerdict::kFailure);
  EXPECT_TRUE(alarm(failed, "phase"));
  // Without ground truth (hardware) there is no residual to judge.
  pd::TrialView hardware;
  hardware.onPhase("moving_to_pose", true);
  hardware.onStop("/state_recognizer", "inner cortical layer reached", false);
  hardware.onPhase("done", false);
  EXPECT_EQ(value(hardware, "residual"), "(no ground truth)");
  EXPECT_EQ(hardware.verdict(), pd::TrialVerdict::kFailure);
}

TEST(TrialView, PairsPredictionAndTrackerByStampForTheH1ErrorAndWatchesH2) {
  pd::TrialView view;
  view.onPhase("moving_to_pose", true);
  EXPECT_TRUE(std::isnan(view.positionError()));
  view.onTrackedMarker(1.0, Eigen::Vector3d(0.0, 0.0, 0.0));
  view.onPredictedMarker(1.125, Eigen::Vector3d(0.0, 0.0, 0.5e-3));  // no partner yet
  EXPECT_TRUE(std::isnan(view.positionError()));
  view.onPredictedMarker(1.0, Eigen::Vector3d(0.0, 0.0, 0.3e-3));
  EXPECT_NEAR(view.positionError(), 0.3e-3, 1e-15);
  view.onTrackedMarker(1.125, Eigen::Vector3d(0.0, 0.0, 2.0e-3));  // the pending prediction
  EXPECT_NEAR(view.positionError(), 1.5e-3, 1e-15);
  EXPECT_TRUE(alarm(view, "predicted - tracked"));                      // over H1 = 1.2 mm
  view.onTrackedMarker(1.25, Eigen::Vector3d(std::nan(""), 0.0, 0.0));  // ignored
  EXPECT_NEAR(view.positionError(), 1.5e-3, 1e-15);
  view.onForce(4.0);
  EXPECT_FALSE(alarm(view, "force"));
  view.onForce(10.5);
  view.onForce(3.0);
  EXPECT_TRUE(alarm(view, "force"));  // the maximum stays
  EXPECT_NE(value(view, "force").find("max 10.50"), std::string::npos) << value(view, "force");
  view.onMonitorStatus(2, "force_exceeded");
  EXPECT_EQ(view.monitorLevel(), 2);
  EXPECT_TRUE(alarm(view, "safety monitor"));
  // A new trial starts afresh.
  view.onPhase("done", false);
  view.onPhase("moving_to_pose", true);
  EXPECT_TRUE(std::isnan(view.positionError()));
  EXPECT_FALSE(alarm(view, "force"));
  EXPECT_EQ(view.monitorLevel(), -1);
}

TEST(LayoutLabels, NeighboursThatWouldOverlapGoToAnotherRow) {
  // K1 and K2 2 px apart (the README's old screenshot), K3 far away, STOP close to K3.
  const std::vector<pd::ChartLabel> labels = {
      {100.0, 20.0}, {102.0, 20.0}, {300.0, 20.0}, {310.0, 34.0}, {125.0, 20.0}};
  const std::vector<int> rows = pd::layoutLabels(labels);
  ASSERT_EQ(rows.size(), labels.size());
  for (std::size_t i = 0; i < labels.size(); ++i) {
    for (std::size_t j = i + 1; j < labels.size(); ++j) {
      if (rows[i] != rows[j]) continue;
      const bool apart = labels[i].x + labels[i].width + 4.0 <= labels[j].x ||
                         labels[j].x + labels[j].width + 4.0 <= labels[i].x;
      EXPECT_TRUE(apart) << i << " and " << j << " overlap on row " << rows[i];
    }
  }
  EXPECT_EQ(rows[0], 0);
  EXPECT_EQ(rows[1], 1);
  EXPECT_EQ(rows[4], 0);  // 125 >= 100 + 20 + 4: back on the first row
  EXPECT_EQ(rows[2], 0);
  EXPECT_EQ(rows[3], 1);
  // More labels than rows: still a valid row each.
  const std::vector<int> crowded =
      pd::layoutLabels(std::vector<pd::ChartLabel>(6, {0.0, 10.0}), 4.0, 2);
  for (int r : crowded) EXPECT_TRUE(r == 0 || r == 1);
}

TEST(ForceTrace, KeepsTheTrialFromTheContactToTheStopAndFreezesAfterIt) {
  pd::ForceTrace trace(2.0, 3.0);
  double t = 0.0;
  for (; t < 10.0; t += 0.05) trace.add(t, "idle", 0, 0.0, 0.0, false);  // air
  ASSERT_FALSE(trace.samples().empty());
  EXPECT_GE(trace.samples().front().t, 10.0 - 2.0 - 1e-9);  // only the lead-in before contact
  trace.add(t, "outer_cortical", 1, 1.5, 0.8, false);
  EXPECT_DOUBLE_EQ(trace.contactTime(), t);
  t += 0.05;
  trace.add(t, "outer_cortical", 2, 2.5, 0.9, false);
  trace.add(t + 5.0, "inner_cortical", 4, 3.5, 1.5, false);
  trace.add(t + 5.05, "inner_cortical", 4, 3.6, 1.9, false);
  trace.add(t + 5.1, "stopped", 4, 3.4, 1.2, true);
  EXPECT_TRUE(trace.stopped());
  EXPECT_DOUBLE_EQ(trace.innerPeak(), 1.9);
  const std::size_t kept = trace.samples().size();
  trace.add(t + 7.0, "stopped", 4, 0.0, 0.0, true);   // within the tail
  trace.add(t + 60.0, "stopped", 4, 0.0, 0.0, true);  // long after: not kept
  EXPECT_EQ(trace.samples().size(), kept + 1);
  ASSERT_EQ(trace.events().size(), 4u);  // K1, K2, K4, STOP
  EXPECT_EQ(trace.events()[2].label, "K4");
  EXPECT_TRUE(trace.events()[3].stop);
  EXPECT_DOUBLE_EQ(trace.events()[3].t, t + 5.1);
  // The recognizer reset (no stop any more): a new trial.
  trace.add(t + 61.0, "idle", 0, 0.0, 0.0, false);
  EXPECT_FALSE(trace.stopped());
  EXPECT_TRUE(trace.events().empty());
  EXPECT_TRUE(std::isnan(trace.contactTime()));
}

TEST(ForceTrace, DepthIsInterpolatedFromTheGroundTruthAndTimeBackwardsStartsOver) {
  pd::ForceTrace trace;
  EXPECT_TRUE(std::isnan(trace.depthAt(1.0)));
  trace.addDepth(1.0, 0.001);
  trace.addDepth(2.0, 0.002);
  EXPECT_TRUE(std::isnan(trace.depthAt(0.5)));
  EXPECT_NEAR(trace.depthAt(1.25), 0.00125, 1e-15);
  EXPECT_DOUBLE_EQ(trace.depthAt(2.0), 0.002);
  EXPECT_DOUBLE_EQ(trace.depthAt(5.0), 0.002);
  trace.add(10.0, "outer_cortical", 1, 1.0, 0.5, false);
  trace.add(3.0, "idle", 0, 0.0, 0.0, false);  // time went backwards
  EXPECT_EQ(trace.samples().size(), 1u);
  EXPECT_TRUE(std::isnan(trace.contactTime()));
}

TEST(ForceTrace, AMonitorStopIsMarkedTooAndTheRecognizersResetStartsANewTrial) {
  pd::ForceTrace trace(2.0, 3.0);
  trace.add(1.0, "outer_cortical", 1, 2.0, 0.8, false);
  trace.add(1.5, "outer_cortical", 1, 9.0, 0.9, false);
  trace.addStop(1.6, "/safety_monitor");
  ASSERT_TRUE(trace.stopped());
  ASSERT_EQ(trace.events().size(), 2u);
  EXPECT_EQ(trace.events()[1].label, "STOP /safety_monitor");
  trace.addStop(1.7, "/state_recognizer");  // only the first stop
  EXPECT_EQ(trace.events().size(), 2u);
  trace.add(2.0, "outer_cortical", 1, 0.0, 0.0, false);  // the recognizer runs on: same trial
  EXPECT_TRUE(trace.stopped());
  EXPECT_EQ(trace.samples().size(), 3u);
  trace.add(30.0, "idle", 0, 0.0, 0.0, false);  // reset at the next trial's start
  EXPECT_FALSE(trace.stopped());
  EXPECT_TRUE(trace.events().empty());
}

TEST(ForceTrace, ThrustAloneIsAStripChartOfTheLeadInAndFollowsTheTrialsRules) {
  pd::ForceTrace trace(2.0, 3.0);
  double t = 0.0;
  for (; t < 10.0; t += 0.01) trace.addThrust(t, 0.1);  // no drilling_state: the F/T sensor only
  ASSERT_FALSE(trace.thrust().empty());
  EXPECT_TRUE(trace.samples().empty());
  EXPECT_GE(trace.thrust().front().t, t - 0.01 - 2.0 - 1e-9);  // the last lead_in_s
  trace.addThrust(t, std::nan(""));                            // dropped
  trace.addThrust(t, std::numeric_limits<double>::infinity());
  EXPECT_DOUBLE_EQ(trace.thrust().back().thrust, 0.1);
  trace.add(t, "outer_cortical", 1, 1.5, 0.8, false);  // the contact: kept from here on
  const std::size_t at_contact = trace.thrust().size();
  for (double s = t; s < t + 5.0; s += 0.01) trace.addThrust(s, 2.0);
  EXPECT_GT(trace.thrust().size(), at_contact + 400);
  trace.add(t + 5.0, "stopped", 4, 3.4, 1.2, true);
  trace.addThrust(t + 6.0, 1.0);   // within the tail
  trace.addThrust(t + 60.0, 1.0);  // long after the stop: frozen
  EXPECT_DOUBLE_EQ(trace.thrust().back().t, t + 6.0);
  trace.addThrust(1.0, 0.5);  // time went backwards: a new record
  ASSERT_EQ(trace.thrust().size(), 1u);
  EXPECT_DOUBLE_EQ(trace.thrust().front().t, 1.0);
}
