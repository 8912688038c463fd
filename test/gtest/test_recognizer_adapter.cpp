// core::RecognizerAdapter: the force axis, non-finite samples dropped and counted, the latch and
// the stop reason (the glue the StateRecognizer nodelet and the closed-loop engine share).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/drilling/recognizer_adapter.hpp"

namespace pc = pedicle_drilling::core;

namespace {

/** @brief A block of two samples; stops on the first sample above 10 N; may throw. */
class FakeRecognizer : public pc::RecognizerInterface {
 public:
  explicit FakeRecognizer(std::vector<double>* seen) : seen_(seen) {}
  void configure(const pc::RecognizerSettings&) override {}
  void reset() override { out_ = pc::RecognizerOutput(); }
  const pc::RecognizerOutput& push(double t, double raw_force) override {
    if (raw_force < -100.0) throw std::runtime_error("bad sample");
    seen_->push_back(raw_force);
    out_.new_average = seen_->size() % 2 == 0;
    if (raw_force > 10.0 && !out_.stop) {
      out_.stop = true;
      out_.stop_t = t;
    }
    return out_;
  }
  const pc::RecognizerOutput& output() const override { return out_; }
  std::string stopReason() const override { return out_.stop ? "over 10 N" : ""; }
  std::string describe() const override { return "fake"; }
  std::vector<std::string> parameterNames() const override { return {}; }

 private:
  std::vector<double>* seen_;
  pc::RecognizerOutput out_;
};

}  // namespace

TEST(RecognizerAdapter, TakesTheSignedAxisComponent) {
  std::vector<double> seen;
  pc::ForceAxis axis;
  axis.index = 1;
  axis.sign = -1.0;
  pc::RecognizerAdapter a(std::make_unique<FakeRecognizer>(&seen), axis);
  EXPECT_DOUBLE_EQ(a.thrust(Eigen::Vector3d(1.0, 2.0, 3.0)), -2.0);
  EXPECT_TRUE(a.onSample(0.001, Eigen::Vector3d(1.0, 2.0, 3.0)).accepted);
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0], -2.0);
  pc::RecognizerAdapter z(std::make_unique<FakeRecognizer>(&seen));  // default: +z
  EXPECT_EQ(z.thrust(Eigen::Vector3d(1.0, 2.0, 3.0)), 3.0);
}

TEST(RecognizerAdapter, DropsAndCountsNonFiniteSamples) {
  std::vector<double> seen;
  pc::RecognizerAdapter a(std::make_unique<FakeRecognizer>(&seen));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(a.onSample(0.001, Eigen::Vector3d(0.0, 0.0, nan)).accepted);
  EXPECT_FALSE(a.onSample(nan, Eigen::Vector3d(0.0, 0.0, 1.0)).accepted);
  EXPECT_FALSE(a.admit(0.002, inf));
  // Another axis's NaN is not the thrust's.
  EXPECT_TRUE(a.onSample(0.003, Eigen::Vector3d(nan, 0.0, 1.0)).accepted);
  EXPECT_EQ(a.nonFiniteCount(), 3u);
  EXPECT_EQ(seen.size(), 1u);
  a.reset();
  EXPECT_EQ(a.nonFiniteCount(), 3u);  // counted since construction
}

TEST(RecognizerAdapter, ReportsTheStopOnceOnTheSampleThatLatchesIt) {
  std::vector<double> seen;
  pc::RecognizerAdapter a(std::make_unique<FakeRecognizer>(&seen));
  pc::RecognizerStep s = a.onSample(0.001, Eigen::Vector3d(0.0, 0.0, 1.0));
  EXPECT_FALSE(s.new_average);
  EXPECT_FALSE(s.new_stop);
  EXPECT_EQ(s.stop_reason, "");
  s = a.onSample(0.002, Eigen::Vector3d(0.0, 0.0, 11.0));
  EXPECT_TRUE(s.new_average);
  EXPECT_TRUE(s.new_stop);
  EXPECT_EQ(s.stop_reason, "over 10 N");
  s = a.onSample(0.003, Eigen::Vector3d(0.0, 0.0, 12.0));
  EXPECT_FALSE(s.new_stop);  // latched
  EXPECT_TRUE(a.output().stop);
  a.reset();
  EXPECT_FALSE(a.output().stop);
  EXPECT_TRUE(a.push(0.004, 13.0).new_stop);  // the latch again after a reset
}

TEST(RecognizerAdapter, AnExceptionOfTheClassIsAStop) {
  std::vector<double> seen;
  pc::RecognizerAdapter a(std::make_unique<FakeRecognizer>(&seen));
  const pc::RecognizerStep s = a.push(0.001, -200.0);
  EXPECT_TRUE(s.new_stop);
  EXPECT_NE(s.stop_reason.find("bad sample"), std::string::npos) << s.stop_reason;
}

TEST(RecognizerAdapter, RefusesNoRecognizerAndABadAxis) {
  EXPECT_THROW(pc::RecognizerAdapter(nullptr), std::invalid_argument);
  std::vector<double> seen;
  pc::ForceAxis axis;
  axis.index = 3;
  EXPECT_THROW(pc::RecognizerAdapter(std::make_unique<FakeRecognizer>(&seen), axis),
               std::invalid_argument);
  axis.index = 0;
  axis.sign = 2.0;
  EXPECT_THROW(axis.validate(), std::invalid_argument);
}
