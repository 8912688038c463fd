// core::StreamStats: the handling delay and the missing samples of a stamped stream.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "pedicle_drilling/core/common/stream_stats.hpp"

namespace pedicle_drilling::core {
namespace {

TEST(StreamStats, ARegularStreamHandledOnTimeLosesNothing) {
  StreamStats s;
  for (int k = 0; k < 1000; ++k) s.observe(k * 3e-3, k * 3e-3 + 1e-3);
  EXPECT_EQ(s.count(), 1000u);
  EXPECT_NEAR(s.maxDelay(), 1e-3, 1e-12);
  EXPECT_NEAR(s.period(), 3e-3, 1e-12);
  EXPECT_EQ(s.missing(), 0u);
}

TEST(StreamStats, GapsCountTheSamplesThatNeverCame) {
  StreamStats s;
  for (int k = 0; k < 1000; ++k) {
    if (k == 5 || k == 6 || (k >= 500 && k < 510)) continue;  // 2 before the period, 10 after
    s.observe(k * 1e-3, k * 1e-3);
  }
  EXPECT_NEAR(s.period(), 1e-3, 1e-12);
  EXPECT_EQ(s.missing(), 12u);
}

TEST(StreamStats, TheLargestDelayIsKept) {
  StreamStats s;
  s.observe(0.0, 0.001);
  s.observe(0.01, 0.26);  // a sample handled 250 ms late
  s.observe(0.02, 0.021);
  EXPECT_NEAR(s.maxDelay(), 0.25, 1e-12);
}

TEST(StreamStats, JitterOfATenthOfAPeriodIsNotALoss) {
  StreamStats s;
  for (int k = 0; k < 500; ++k) {
    const double jitter = ((k * 7) % 3 - 1) * 0.001;  // -1, 0 or +1 ms on a 10 ms stream
    s.observe(k * 0.01 + jitter, k * 0.01 + 0.005);
  }
  EXPECT_NEAR(s.period(), 0.01, 0.0015);
  EXPECT_EQ(s.missing(), 0u);
}

TEST(StreamStats, NonFiniteStampsAreIgnoredAndResetForgets) {
  StreamStats s;
  s.observe(std::numeric_limits<double>::quiet_NaN(), 0.0);
  EXPECT_EQ(s.count(), 0u);
  for (int k = 0; k < 100; ++k) s.observe(k * 1e-3, k * 1e-3);
  s.observe(0.2, 0.2);
  EXPECT_GT(s.missing(), 0u);
  s.reset();
  EXPECT_EQ(s.count(), 0u);
  EXPECT_EQ(s.missing(), 0u);
  EXPECT_EQ(s.period(), 0.0);
}

}  // namespace
}  // namespace pedicle_drilling::core
