// core::FaultInjector: what each fault does to the streams, and when. The core engine
// and the FaultInjector nodelet run this class.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "pedicle_drilling/core/sim/fault_injector.hpp"

namespace pd = pedicle_drilling::core;

namespace {

Eigen::Vector3d sample(double t) { return {0.01 * t, -0.02, 2.0 + 0.1 * t}; }

struct ForceRun {
  int delivered = 0;
  Eigen::Vector3d last = Eigen::Vector3d::Zero();
};

// Samples at 1 kHz from t = 0 to 1 s; the fault injected at t = 0.5 s.
ForceRun runForce(pd::FaultKind kind, pd::FaultInjector* injector,
                  Eigen::Vector3d* at_fault = nullptr) {
  injector->arm(kind);
  ForceRun run;
  for (int i = 0; i <= 1000; ++i) {
    const double t = i * 1e-3;
    if (i == 500) injector->inject(t);
    Eigen::Vector3d f = sample(t);
    if (!injector->force(t, &f)) continue;
    if (i == 500 && at_fault != nullptr) *at_fault = f;
    ++run.delivered;
    run.last = f;
  }
  return run;
}

}  // namespace

TEST(FaultInjector, NamesRoundTripAndUnknownNamesAreRefusedListingTheKnownOnes) {
  for (const std::string& name : pd::faultNames()) {
    EXPECT_EQ(pd::toString(pd::parseFaultKind(name)), name);
  }
  try {
    pd::parseFaultKind("force_melted");
    FAIL() << "accepted an unknown fault";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("force_melted"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("tracker_stale"), std::string::npos);
  }
  EXPECT_TRUE(pd::isForceFault(pd::FaultKind::kForceDrift));
  EXPECT_TRUE(pd::isTrackerFault(pd::FaultKind::kTrackerStale));
  EXPECT_TRUE(pd::isBreathingFault(pd::FaultKind::kBreathingRateUp));
  EXPECT_TRUE(pd::isCommandFault(pd::FaultKind::kCommandLost));
  EXPECT_FALSE(pd::isForceFault(pd::FaultKind::kNone));
}

TEST(FaultInjector, BadSizesAreRefusedNamingTheField) {
  pd::FaultParams p;
  p.command_delay_s = -1.0;
  try {
    pd::FaultInjector injector(p);
    FAIL() << "accepted a negative delay";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("command_delay_s", 0), 0u) << e.what();
  }
}

TEST(FaultInjector, NoFaultAndFaultsNotYetInjectedPassEverythingUnchanged) {
  pd::FaultInjector injector;
  const ForceRun none = runForce(pd::FaultKind::kNone, &injector);
  EXPECT_EQ(none.delivered, 1001);
  EXPECT_EQ(none.last, sample(1.0));
  injector.arm(pd::FaultKind::kForceSilent);  // armed, never injected
  Eigen::Vector3d f = sample(0.3);
  EXPECT_TRUE(injector.force(0.3, &f));
  EXPECT_EQ(f, sample(0.3));
  EXPECT_FALSE(injector.injected());
  EXPECT_EQ(injector.command(0.3), 0.0);
}

TEST(FaultInjector, ForceFaults) {
  pd::FaultInjector injector;
  EXPECT_EQ(runForce(pd::FaultKind::kForceSilent, &injector).delivered, 500);  // up to 0.499 s
  EXPECT_TRUE(injector.injected());
  EXPECT_DOUBLE_EQ(injector.injectionTime(), 0.5);

  const ForceRun nan = runForce(pd::FaultKind::kForceNaN, &injector);
  EXPECT_EQ(nan.delivered, 1001);
  EXPECT_TRUE(std::isnan(nan.last.x()) && std::isnan(nan.last.y()) && std::isnan(nan.last.z()));

  const ForceRun inf = runForce(pd::FaultKind::kForceInf, &injector);
  EXPECT_TRUE(std::isinf(inf.last.z()) && inf.last.z() > 0.0);
  EXPECT_EQ(inf.last.x(), sample(1.0).x());

  // One spiked sample, the first after the injection; then the sensor is well again.
  Eigen::Vector3d at_fault;
  const ForceRun spike = runForce(pd::FaultKind::kForceSpike, &injector, &at_fault);
  EXPECT_EQ(at_fault.z(), 15.0);
  EXPECT_EQ(spike.last, sample(1.0));

  // Frozen: every sample from the injection on is the first faulty one, bit for bit.
  const ForceRun stuck = runForce(pd::FaultKind::kForceStuck, &injector, &at_fault);
  EXPECT_EQ(at_fault, sample(0.5));
  EXPECT_EQ(stuck.last, sample(0.5));

  // Drift: + drift_n_per_s (t - t_fault) on the thrust only.
  const ForceRun drift = runForce(pd::FaultKind::kForceDrift, &injector);
  EXPECT_NEAR(drift.last.z(), sample(1.0).z() + 0.2 * 0.5, 1e-12);
  EXPECT_EQ(drift.last.x(), sample(1.0).x());
}

TEST(FaultInjector, TrackerFaults) {
  pd::FaultInjector injector;
  const auto pose = [&injector](double t, Eigen::Vector3d* p, double* stamp) {
    *p = Eigen::Vector3d(0.6 + 0.001 * t, 0.02, 0.3);
    Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
    *stamp = t;
    return injector.trackedPose(p, &q, stamp);
  };
  Eigen::Vector3d p;
  double stamp = 0.0;
  injector.arm(pd::FaultKind::kTrackerSilent);
  EXPECT_TRUE(pose(1.0, &p, &stamp));
  injector.inject(1.1);
  EXPECT_FALSE(pose(1.125, &p, &stamp));

  injector.arm(pd::FaultKind::kTrackerJump);
  injector.inject(2.0);
  ASSERT_TRUE(pose(2.125, &p, &stamp));
  EXPECT_NEAR(p.x(), 0.6 + 0.002125 + 0.005, 1e-12);  // 5 mm along x, and it stays
  ASSERT_TRUE(pose(2.25, &p, &stamp));
  EXPECT_NEAR(p.x(), 0.6 + 0.00225 + 0.005, 1e-12);

  injector.arm(pd::FaultKind::kTrackerStale);
  ASSERT_TRUE(pose(3.0, &p, &stamp));
  injector.inject(3.1);
  for (double t : {3.125, 3.25, 3.375}) {
    ASSERT_TRUE(pose(t, &p, &stamp));
    EXPECT_EQ(stamp, 3.0) << "the last good pose again, with its old stamp";
    EXPECT_EQ(p.x(), 0.6 + 0.003);
  }
}

TEST(FaultInjector, CommandFaultsHitTheNextCommandOnly) {
  pd::FaultInjector injector;
  injector.arm(pd::FaultKind::kCommandDelayed);
  EXPECT_EQ(injector.command(1.0), 0.0);
  injector.inject(1.05);
  EXPECT_TRUE(injector.pending());
  EXPECT_FALSE(injector.injected());
  EXPECT_DOUBLE_EQ(injector.command(1.125), 0.2);
  EXPECT_TRUE(injector.injected());
  EXPECT_DOUBLE_EQ(injector.injectionTime(), 1.125);  // when the command met the fault
  EXPECT_EQ(injector.command(1.25), 0.0);

  injector.arm(pd::FaultKind::kCommandLost);
  injector.inject(2.0);
  EXPECT_LT(injector.command(2.125), 0.0);
  EXPECT_EQ(injector.command(2.25), 0.0);

  // A force fault leaves the commands alone, a command fault the force.
  injector.arm(pd::FaultKind::kForceSilent);
  injector.inject(3.0);
  EXPECT_EQ(injector.command(3.1), 0.0);
  injector.arm(pd::FaultKind::kCommandLost);
  injector.inject(4.0);
  Eigen::Vector3d f = sample(4.1);
  EXPECT_TRUE(injector.force(4.1, &f));
  EXPECT_EQ(f, sample(4.1));
}

TEST(FaultInjector, ACommandFaultHitsCommandFaultCountCommandsInARow) {
  pd::FaultParams p;
  p.command_delay_s = 0.6;
  p.command_fault_count = 3;
  pd::FaultInjector injector(p);
  injector.arm(pd::FaultKind::kCommandDelayed);
  injector.inject(1.0);
  EXPECT_DOUBLE_EQ(injector.command(1.125), 0.6);
  EXPECT_DOUBLE_EQ(injector.injectionTime(), 1.125);  // the first command's
  EXPECT_TRUE(injector.pending());
  EXPECT_DOUBLE_EQ(injector.command(1.25), 0.6);
  EXPECT_DOUBLE_EQ(injector.command(1.375), 0.6);
  EXPECT_FALSE(injector.pending());
  EXPECT_EQ(injector.command(1.5), 0.0);  // the path is fast again
  EXPECT_DOUBLE_EQ(injector.injectionTime(), 1.125);
  p.command_fault_count = 0;
  EXPECT_THROW(pd::FaultInjector{p}, std::invalid_argument);
}

TEST(FaultInjector, NewForceFaultsNegInfOneAxisNaNAndSaturation) {
  pd::FaultInjector injector;
  const ForceRun neg = runForce(pd::FaultKind::kForceNegInf, &injector);
  EXPECT_TRUE(std::isinf(neg.last.z()) && neg.last.z() < 0.0);
  EXPECT_EQ(neg.last.x(), sample(1.0).x());
  EXPECT_EQ(injector.counts().force_altered, 501);

  // One axis NaN (default x: the lateral axis the recognizer does not read), the others kept.
  const ForceRun nan = runForce(pd::FaultKind::kForceAxisNaN, &injector);
  EXPECT_TRUE(std::isnan(nan.last.x()));
  EXPECT_EQ(nan.last.y(), sample(1.0).y());
  EXPECT_EQ(nan.last.z(), sample(1.0).z());
  pd::FaultParams p;
  p.nan_axis = 2;
  pd::FaultInjector thrust_nan(p);
  EXPECT_TRUE(std::isnan(runForce(pd::FaultKind::kForceAxisNaN, &thrust_nan).last.z()));
  p.nan_axis = 3;
  EXPECT_THROW(pd::FaultInjector{p}, std::invalid_argument);
}

TEST(FaultInjector, SaturationClipsTheThrustAtTheRangeWithTheSensorsNoise) {
  pd::FaultParams p;
  p.saturation_n = 2.03;  // the thrust of sample() passes it at t = 0.3 s
  pd::FaultInjector injector(p, 7);
  injector.arm(pd::FaultKind::kForceSaturated);
  injector.inject(0.0);
  double sum = 0.0, sum2 = 0.0;
  int clipped = 0;
  for (int i = 0; i <= 1000; ++i) {
    const double t = i * 1e-3;
    Eigen::Vector3d f = sample(t);
    ASSERT_TRUE(injector.force(t, &f));
    EXPECT_EQ(f.x(), sample(t).x());  // the other axes as they are
    if (sample(t).z() <= 2.03) {
      EXPECT_EQ(f.z(), sample(t).z()) << "within the range: unchanged";
      continue;
    }
    ++clipped;
    sum += f.z() - 2.03;
    sum2 += (f.z() - 2.03) * (f.z() - 2.03);
  }
  EXPECT_EQ(injector.counts().force_altered, clipped);
  ASSERT_GT(clipped, 600);
  const double mean = sum / clipped;
  const double sd = std::sqrt(sum2 / clipped - mean * mean);
  EXPECT_NEAR(mean, 0.0, 0.005);  // 0.03 / sqrt(700) = 0.0011: 4.5 SE
  EXPECT_NEAR(sd, 0.03, 0.004);   // the declared noise, 0.03 N
  // Negative thrust clips at -range; a zero range is refused.
  Eigen::Vector3d f(0.0, 0.0, -5.0);
  ASSERT_TRUE(injector.force(1.1, &f));
  EXPECT_NEAR(f.z(), -2.03, 0.2);
  p.saturation_n = 0.0;
  EXPECT_THROW(pd::FaultInjector{p}, std::invalid_argument);
}

TEST(FaultInjector, OcclusionBurstsDropOcclusionSamplesOfEveryPeriodAndRecover) {
  pd::FaultInjector injector;  // 2 of every 8 samples
  injector.arm(pd::FaultKind::kTrackerOcclusion);
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  std::string delivered;
  for (int i = 0; i < 24; ++i) {
    if (i == 4) injector.inject(0.5);
    Eigen::Vector3d p(0.6, 0.02, 0.3);
    double stamp = i * 0.125;
    const bool ok = injector.trackedPose(&p, &q, &stamp);
    delivered += ok ? '+' : '.';
    if (ok) {
      EXPECT_EQ(stamp, i * 0.125);  // delivered samples as they are
    }
  }
  EXPECT_EQ(delivered, "++++..++++++..++++++..++");
  EXPECT_EQ(injector.counts().tracker_dropped, 6);
  EXPECT_EQ(injector.counts().tracker_altered, 0);
  pd::FaultParams p;
  p.occlusion_samples = 8;  // a burst as long as its period never recovers
  EXPECT_THROW(pd::FaultInjector{p}, std::invalid_argument);
}

TEST(FaultInjector, StopLostDropsEveryStopFromTheInjectionOnAndCountsThem) {
  pd::FaultInjector injector;
  injector.arm(pd::FaultKind::kStopLost);
  EXPECT_TRUE(injector.stop());  // armed, not injected
  injector.inject(1.0);
  EXPECT_TRUE(pd::isStopFault(injector.kind()));
  EXPECT_FALSE(injector.stop());
  EXPECT_FALSE(injector.stop());
  EXPECT_EQ(injector.counts().stops_lost, 2);
  // Other faults leave the stops alone; arm() clears the counts.
  injector.arm(pd::FaultKind::kCommandLost);
  EXPECT_EQ(injector.counts().stops_lost, 0);
  injector.inject(2.0);
  EXPECT_TRUE(injector.stop());
  EXPECT_LT(injector.command(2.1), 0.0);
  EXPECT_EQ(injector.counts().commands_lost, 1);
}
