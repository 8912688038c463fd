// Tests of the force stream's measured rate against the recognizer's declared rate.
#include <gtest/gtest.h>

#include <limits>
#include <stdexcept>
#include <string>

#include "param_table_checks.hpp"
#include "pedicle_drilling/core/drilling/sample_rate_check.hpp"

namespace pedicle_drilling::core {
namespace {

SampleRateCheckParams declared(double hz) {
  SampleRateCheckParams p;
  p.declared_hz = hz;
  return p;
}

/** @brief Feeds @p n samples at @p rate_hz from @p t0; returns how many windows completed. */
int feed(SampleRateCheck* check, double t0, double rate_hz, int n) {
  int windows = 0;
  for (int i = 0; i < n; ++i) windows += check->observe(t0 + i / rate_hz) ? 1 : 0;
  return windows;
}

TEST(SampleRateCheck, TheDeclaredRateMatches) {
  SampleRateCheck check(declared(1000.0 / 3.0));
  EXPECT_EQ(check.verdict(), RateVerdict::kUnknown);
  EXPECT_NE(check.describe().find("not measured yet"), std::string::npos);
  EXPECT_EQ(feed(&check, 100.0, 1000.0 / 3.0, 700), 2);  // 2 windows of 1 s in 2.1 s
  EXPECT_EQ(check.verdict(), RateVerdict::kMatch);
  EXPECT_NEAR(check.measuredHz(), 1000.0 / 3.0, 1e-6);
}

TEST(SampleRateCheck, ASensorThreeTimesFasterIsAMismatchNamingBothRates) {
  SampleRateCheck check(declared(1000.0 / 3.0));
  EXPECT_EQ(feed(&check, 0.0, 1000.0, 1001), 1);
  EXPECT_EQ(check.verdict(), RateVerdict::kMismatch);
  EXPECT_NEAR(check.measuredHz(), 1000.0, 1e-6);
  const std::string text = check.describe();
  EXPECT_NE(text.find("measured 1000 Hz"), std::string::npos) << text;
  EXPECT_NE(text.find("declared 333.333 Hz"), std::string::npos) << text;
  EXPECT_NE(text.find("+200.0 %"), std::string::npos) << text;
}

TEST(SampleRateCheck, ASlowerSensorIsAMismatchToo) {
  SampleRateCheck check(declared(1000.0));
  feed(&check, 0.0, 1000.0 / 3.0, 400);
  EXPECT_EQ(check.verdict(), RateVerdict::kMismatch);
  EXPECT_NE(check.describe().find("-66.7 %"), std::string::npos) << check.describe();
}

TEST(SampleRateCheck, TheToleranceBoundsTheDifference) {
  // 10 % by default: 360 Hz against 333.3 Hz (+8 %) matches, 370 Hz (+11 %) does not.
  SampleRateCheck near(declared(1000.0 / 3.0));
  feed(&near, 0.0, 360.0, 400);
  EXPECT_EQ(near.verdict(), RateVerdict::kMatch);
  SampleRateCheck far(declared(1000.0 / 3.0));
  feed(&far, 0.0, 370.0, 400);
  EXPECT_EQ(far.verdict(), RateVerdict::kMismatch);
  EXPECT_TRUE(ratesAgree(100.0, 109.9, 0.1));
  EXPECT_FALSE(ratesAgree(100.0, 110.1, 0.1));
  EXPECT_FALSE(ratesAgree(100.0, 89.9, 0.1));
}

TEST(SampleRateCheck, APauseOrAJumpBackRestartsTheWindowAndKeepsTheVerdict) {
  SampleRateCheck check(declared(1000.0));
  EXPECT_DOUBLE_EQ(check.pauseS(), 0.05);  // 1 s x 10 % / 2
  feed(&check, 0.0, 1000.0, 1001);
  ASSERT_EQ(check.verdict(), RateVerdict::kMatch);
  // A simulator reset (sim time jumps 2000 s ahead) or a pause of 60 ms: no rate from it.
  EXPECT_EQ(feed(&check, 2000.0, 1000.0, 900), 0);
  EXPECT_EQ(feed(&check, 2000.96, 1000.0, 900), 0);
  EXPECT_EQ(check.verdict(), RateVerdict::kMatch);
  // Time going back (a restarted bag) restarts it too.
  EXPECT_EQ(feed(&check, 10.0, 1000.0, 900), 0);
  EXPECT_EQ(feed(&check, 10.9, 1000.0, 200), 1);
  EXPECT_EQ(check.verdict(), RateVerdict::kMatch);
  // Pauses of up to 50 ms are part of the rate: 40 ms without a sample in a second of a
  // 1 kHz stream is 4 % slower (960 spacings in the 1 s window), still a match.
  SampleRateCheck gaps(declared(1000.0));
  feed(&gaps, 0.0, 1000.0, 500);
  feed(&gaps, 0.54, 1000.0, 501);
  EXPECT_EQ(gaps.verdict(), RateVerdict::kMatch);
  EXPECT_NEAR(gaps.measuredHz(), 960.0, 1.0);
}

TEST(SampleRateCheck, ANonFiniteStampIsIgnored) {
  SampleRateCheck check(declared(1000.0));
  EXPECT_FALSE(check.observe(std::numeric_limits<double>::quiet_NaN()));
  feed(&check, 0.0, 1000.0, 1001);
  EXPECT_EQ(check.verdict(), RateVerdict::kMatch);
}

TEST(SampleRateCheck, BadSettingsAreRefusedNamingThem) {
  const auto error = [](SampleRateCheckParams p) {
    try {
      SampleRateCheck check(p);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  SampleRateCheckParams p;
  EXPECT_EQ(error(p), "");
  p.declared_hz = 0.0;
  EXPECT_EQ(error(p).rfind("declared_hz", 0), 0u);
  p = SampleRateCheckParams();
  p.tolerance = 0.0;
  EXPECT_EQ(error(p).rfind("tolerance", 0), 0u);
  p = SampleRateCheckParams();
  p.window_s = 0.0;
  EXPECT_EQ(error(p).rfind("window_s", 0), 0u);
}

TEST(SampleRateCheckParamsTest, TheTableDeclaresEveryFieldWithItsDefaultAndRange) {
  pedicle_drilling::test::expectDeclaredDefaults(
      SampleRateCheckParams::table(),
      {{"declared_hz", "333.3333333"}, {"tolerance", "0.1"}, {"window_s", "1"}});
  pedicle_drilling::test::expectRangesRefusedNamingTheField(SampleRateCheckParams::table());
}

}  // namespace
}  // namespace pedicle_drilling::core
