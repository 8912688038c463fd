// Tests of core::ForceTare: the F/T sensor's tare before contact.
#include "param_table_checks.hpp"
#include "pedicle_drilling/core/drilling/force_tare.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>

namespace pd = pedicle_drilling::core;

namespace {

pd::ForceTare::Wrench wrench(double fz, double fx = 0.0) {
  pd::ForceTare::Wrench w = pd::ForceTare::Wrench::Zero();
  w[0] = fx;
  w[2] = fz;
  w[5] = 0.01;
  return w;
}

}  // namespace

TEST(ForceTare, TheWindowsMeanIsSubtractedFromTheNextSampleOn) {
  pd::ForceTare tare;
  EXPECT_EQ(tare.apply(0.0, wrench(4.9))[2], 4.9);  // no tare yet: the sample unchanged
  tare.request({4, 0.5});
  EXPECT_TRUE(tare.collecting());
  const double fz[4] = {4.8, 5.0, 4.9, 5.1};
  for (int i = 0; i < 4; ++i) {
    // The window's own samples still carry the bias (the tare applies from the next one).
    EXPECT_EQ(tare.apply(0.1 * (i + 1), wrench(fz[i], 0.2))[2], fz[i]);
    if (i < 3) {
      EXPECT_FALSE(tare.takeResult());
    }
  }
  EXPECT_FALSE(tare.collecting());
  const std::optional<pd::TareResult> r = tare.takeResult();
  ASSERT_TRUE(r);
  EXPECT_TRUE(r->success) << r->message;
  EXPECT_EQ(r->samples, 4);
  EXPECT_DOUBLE_EQ(r->t, 0.4);
  EXPECT_NEAR(r->bias[2], 4.95, 1e-12);
  EXPECT_NEAR(r->bias[0], 0.2, 1e-12);
  EXPECT_NEAR(r->bias[5], 0.01, 1e-12);
  EXPECT_NEAR(r->spread_n, std::sqrt(0.0125), 1e-9);  // SD of {4.8, 5.0, 4.9, 5.1}
  EXPECT_FALSE(tare.takeResult());                    // taken once
  const pd::ForceTare::Wrench after = tare.apply(0.5, wrench(7.95, 0.2));
  EXPECT_NEAR(after[2], 3.0, 1e-12);
  EXPECT_NEAR(after[0], 0.0, 1e-12);
  EXPECT_NEAR(after[5], 0.0, 1e-12);
}

TEST(ForceTare, ASpreadAboveTheLimitFailsAndKeepsTheBiasBefore) {
  pd::ForceTare tare;
  tare.request({2, 1.0});
  tare.apply(0.0, wrench(1.0));
  tare.apply(0.1, wrench(1.0));
  ASSERT_TRUE(tare.takeResult()->success);
  tare.request({2, 0.5});
  tare.apply(0.2, wrench(2.0));  // the tool touches something: 2 N apart
  tare.apply(0.3, wrench(4.0));
  const std::optional<pd::TareResult> r = tare.takeResult();
  ASSERT_TRUE(r);
  EXPECT_FALSE(r->success);
  EXPECT_NE(r->message.find("spread"), std::string::npos) << r->message;
  EXPECT_NE(r->message.find("bias kept"), std::string::npos) << r->message;
  EXPECT_NEAR(tare.apply(0.4, wrench(1.5))[2], 0.5, 1e-12);  // the first tare's bias
}

TEST(ForceTare, ANonFiniteSampleFailsTheWindow) {
  pd::ForceTare tare;
  tare.request({3, 0.5});
  tare.apply(0.0, wrench(1.0));
  tare.apply(0.1, wrench(std::numeric_limits<double>::quiet_NaN()));
  tare.apply(0.2, wrench(1.0));
  const std::optional<pd::TareResult> r = tare.takeResult();
  ASSERT_TRUE(r);
  EXPECT_FALSE(r->success);
  EXPECT_NE(r->message.find("non-finite"), std::string::npos) << r->message;
  EXPECT_TRUE(tare.bias().isZero());
}

TEST(ForceTare, BadRequestsAreRefusedNamingTheField) {
  pd::ForceTare tare;
  for (int samples : {0, -1, 100001}) {
    try {
      tare.request({samples, 0.5});
      FAIL() << samples;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("samples"), std::string::npos) << e.what();
    }
  }
  for (double spread : {0.0, -1.0, std::numeric_limits<double>::infinity(), std::nan("")}) {
    EXPECT_THROW(tare.request({10, spread}), std::invalid_argument) << spread;
  }
  EXPECT_FALSE(tare.collecting());
}

TEST(ForceTare, ResetForgetsTheBiasAndTheWindow) {
  pd::ForceTare tare;
  tare.request({1, 0.5});
  tare.apply(0.0, wrench(3.0));
  tare.request({5, 0.5});
  tare.reset();
  EXPECT_FALSE(tare.collecting());
  EXPECT_FALSE(tare.takeResult());
  EXPECT_EQ(tare.apply(0.1, wrench(3.0))[2], 3.0);
}

TEST(ForceTare, AZeroCheckCountsTheSamplesAfterTheZeroAndSubtractsNothing) {
  pd::ForceTare tare;
  // The driver zeroed at t = 1: the samples stamped before still carry the 4.9 N.
  tare.checkZero({3, 0.5}, 0.3, 1.0);
  EXPECT_EQ(tare.apply(0.9, wrench(4.9))[2], 4.9);
  EXPECT_TRUE(tare.collecting());
  const double fz[3] = {0.05, -0.05, 0.0};
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(tare.apply(1.0 + 0.1 * i, wrench(fz[i], 0.1))[2], fz[i]);  // nothing subtracted
  }
  const std::optional<pd::TareResult> r = tare.takeResult();
  ASSERT_TRUE(r);
  EXPECT_TRUE(r->success) << r->message;
  EXPECT_EQ(r->samples, 3);
  EXPECT_DOUBLE_EQ(r->t, 1.2);
  EXPECT_NEAR(r->bias[0], 0.1, 1e-12);  // what remained after the zero
  EXPECT_NEAR(r->bias[2], 0.0, 1e-12);
  EXPECT_NE(r->message.find("zero checked over 3 samples"), std::string::npos) << r->message;
  EXPECT_TRUE(tare.bias().isZero());
  EXPECT_EQ(tare.apply(1.3, wrench(2.0))[2], 2.0);
}

TEST(ForceTare, AZeroCheckFailsWhenTheForceStaysAwayFromZero) {
  pd::ForceTare tare;
  tare.checkZero({2, 0.5}, 0.3, 0.0);
  tare.apply(0.0, wrench(4.9));
  tare.apply(0.1, wrench(4.9));
  const std::optional<pd::TareResult> r = tare.takeResult();
  ASSERT_TRUE(r);
  EXPECT_FALSE(r->success);
  EXPECT_NE(r->message.find("did not zero"), std::string::npos) << r->message;
  EXPECT_NE(r->message.find("4.9 N from zero"), std::string::npos) << r->message;
  EXPECT_NEAR(r->bias[2], 4.9, 1e-12);
  EXPECT_TRUE(tare.bias().isZero());
  // A spread above the request's fails too, and a non-finite sample.
  tare.checkZero({2, 0.5}, 0.3, 0.0);
  tare.apply(0.2, wrench(-1.0));
  tare.apply(0.3, wrench(1.0));
  EXPECT_NE(tare.takeResult()->message.find("spread"), std::string::npos);
  tare.checkZero({1, 0.5}, 0.3, 0.0);
  tare.apply(0.4, wrench(std::numeric_limits<double>::quiet_NaN()));
  EXPECT_NE(tare.takeResult()->message.find("non-finite"), std::string::npos);
}

TEST(ForceTare, AZeroCheckRefusesABadTolerance) {
  pd::ForceTare tare;
  EXPECT_THROW(tare.checkZero({2, 0.5}, 0.0, 0.0), std::invalid_argument);
  EXPECT_THROW(tare.checkZero({2, 0.5}, std::nan(""), 0.0), std::invalid_argument);
  EXPECT_THROW(tare.checkZero({0, 0.5}, 0.3, 0.0), std::invalid_argument);
  EXPECT_FALSE(tare.collecting());
}

TEST(TareRequest, TheTableDeclaresBothFieldsWithTheirDefaultsAndRanges) {
  pedicle_drilling::test::expectDeclaredDefaults(pd::TareRequest::table(),
                                                 {{"samples", "100"}, {"max_spread_n", "0.5"}});
  pedicle_drilling::test::expectRangesRefusedNamingTheField(pd::TareRequest::table());
  EXPECT_EQ(pedicle_drilling::test::invalidArgumentOf([] {
              pd::TareRequest{0, 0.5}.validate();
            }),
            "samples = 0 is out of range [1, 100000] samples");
}
