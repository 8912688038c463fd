// Tests of core::StageAxis: a lead-screw drive's position loop with velocity feed-forward,
// speed and acceleration limits (the SPMS sliders and the drill device's feed).
#include "param_table_checks.hpp"
#include "pedicle_drilling/core/robot/stage_axis.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace pd = pedicle_drilling::core;

namespace {
constexpr double kDt = 1e-3;
constexpr double kPi = 3.14159265358979323846;
}  // namespace

TEST(StageAxis, FollowsAReferenceWithinItsLimitsWithNoError) {
  pd::StageAxis axis(pd::StageAxisParams(), 0.1);
  // A breathing-like sine, 5 mm peak to peak at 0.2 Hz: 3 mm/s, far inside the limits.
  double max_err = 0.0;
  const double w = 2.0 * kPi * 0.2;
  const auto ref = [w](double t) { return 0.1 + 2.5e-3 * std::sin(w * t); };
  for (int k = 0; k < 10000; ++k) {
    const double t = k * kDt;  // the set-point at the start of the step
    const double x = axis.step(kDt, ref(t), 2.5e-3 * w * std::cos(w * t));
    if (k > 200) max_err = std::max(max_err, std::abs(x - ref(t + kDt)));
  }
  EXPECT_LT(max_err, 1e-6);  // the feed-forward does the work; the loop only corrects
}

TEST(StageAxis, NeverExceedsItsSpeedOrAcceleration) {
  pd::StageAxisParams p;
  p.max_speed_m_s = 0.01;
  p.max_accel_m_s2 = 0.5;
  pd::StageAxis axis(p, 0.0);
  double prev_v = 0.0;
  double max_v = 0.0;
  for (int k = 0; k < 3000; ++k) {
    axis.step(kDt, 0.02, 0.0);  // a 20 mm step: the loop asks for far more than it may
    EXPECT_LE(std::abs(axis.velocity() - prev_v), p.max_accel_m_s2 * kDt * (1 + 1e-12));
    max_v = std::max(max_v, std::abs(axis.velocity()));
    prev_v = axis.velocity();
  }
  EXPECT_NEAR(max_v, 0.01, 1e-12);           // it reached its speed limit
  EXPECT_NEAR(axis.position(), 0.02, 1e-4);  // and arrived
}

TEST(StageAxis, ItsErrorDecaysWithTheLoopBandwidth) {
  pd::StageAxisParams p;
  p.max_accel_m_s2 = 1e4;  // no acceleration limit here
  p.bandwidth_hz = 20.0;
  pd::StageAxis axis(p, 0.0);
  const double e0 = 1e-4;
  // After one time constant 1 / (2 pi f) the error is e0 / e (first order, within the
  // discretisation of the 1 ms step).
  const int n = static_cast<int>(std::lround(1.0 / (2.0 * kPi * 20.0) / kDt));
  for (int k = 0; k < n; ++k) axis.step(kDt, e0, 0.0);
  const double expected = e0 * std::pow(1.0 - 2.0 * kPi * 20.0 * kDt, n);
  EXPECT_NEAR(e0 - axis.position(), expected, 1e-9);
  EXPECT_NEAR(e0 - axis.position(), e0 / std::exp(1.0), 0.1 * e0);
}

TEST(StageAxis, AVelocityStepOfTheReferenceIsRoundedByTheAcceleration) {
  pd::StageAxis axis(pd::StageAxisParams(), 0.0);  // 2 m/s^2
  // The reference moves at +3 mm/s, then reverses to -4.5 mm/s (a square flow's end of
  // inspiration at 0.01 mm/ml): the drive needs 7.5 mm/s / 2 m/s^2 = 3.75 ms to reverse.
  double ref = 0.0;
  for (int k = 0; k < 1000; ++k) {
    axis.step(kDt, ref, 3e-3);
    ref += 3e-3 * kDt;
  }
  EXPECT_NEAR(axis.position(), ref, 1e-9);
  double max_err = 0.0;
  int reversing = 0;
  for (int k = 0; k < 1000; ++k) {
    axis.step(kDt, ref, -4.5e-3);
    ref -= 4.5e-3 * kDt;
    max_err = std::max(max_err, std::abs(axis.position() - ref));
    reversing += axis.velocity() > -4.5e-3 + 1e-9 ? 1 : 0;
  }
  EXPECT_GE(reversing, 3);                  // not an instant reversal
  EXPECT_LT(max_err, 25e-6);                // a few tens of um while it turns
  EXPECT_NEAR(axis.position(), ref, 1e-7);  // and back on the reference
}

TEST(StageAxis, BadParametersAreRefusedNamingThem) {
  for (const char* name : {"max_speed_m_s", "max_accel_m_s2", "bandwidth_hz"}) {
    pd::StageAxisParams p;
    double* field = std::string(name) == "max_speed_m_s"    ? &p.max_speed_m_s
                    : std::string(name) == "max_accel_m_s2" ? &p.max_accel_m_s2
                                                            : &p.bandwidth_hz;
    for (double bad : {0.0, -1.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
      *field = bad;
      try {
        pd::StageAxis axis(p);
        ADD_FAILURE() << name << " = " << bad << " accepted";
      } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
      }
    }
  }
}

TEST(StageAxisParams, TheTableDeclaresEveryFieldWithItsDefaultAndRange) {
  pedicle_drilling::test::expectDeclaredDefaults(
      pd::StageAxisParams::table(),
      {{"max_speed_m_s", "0.05"}, {"max_accel_m_s2", "2"}, {"bandwidth_hz", "20"}});
  pedicle_drilling::test::expectRangesRefusedNamingTheField(pd::StageAxisParams::table());
  pd::StageAxisParams p;
  p.bandwidth_hz = std::numeric_limits<double>::infinity();
  EXPECT_EQ(pedicle_drilling::test::invalidArgumentOf([&p] { p.validate(); }),
            "bandwidth_hz = inf is out of range (0, inf) Hz");
}
