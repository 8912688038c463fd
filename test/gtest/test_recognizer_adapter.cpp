// core::RecognizerAdapter: the force axis, the whole sample and its context, non-finite samples
// dropped and counted, the latch and the stop reason (the glue the StateRecognizer nodelet and the
// closed-loop engine share).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/drilling/recognizer_adapter.hpp"

namespace pc = pedicle_drilling::core;

namespace {

const Eigen::Vector3d kNoTorque = Eigen::Vector3d::Zero();

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

/** @brief Reads the whole sample: keeps each; stops when the torque about z passes 0.1 N m. */
class WrenchRecognizer : public pc::RecognizerInterface {
 public:
  void configure(const pc::RecognizerSettings&) override {}
  void reset() override { out_ = pc::RecognizerOutput(); }
  const pc::RecognizerOutput& push(double, double) override {
    throw std::logic_error("push: this class reads the whole sample");
  }
  const pc::RecognizerOutput& pushSample(const pc::RecognizerSample& sample) override {
    if (!std::isfinite(sample.torque_nm[2])) throw std::invalid_argument("torque z not finite");
    seen.push_back(sample);
    out_.new_average = true;
    if (sample.torque_nm[2] > 0.1 && !out_.stop) {
      out_.stop = true;
      out_.stop_t = sample.t;
    }
    return out_;
  }
  const pc::RecognizerOutput& output() const override { return out_; }
  std::string stopReason() const override { return out_.stop ? "torque over 0.1 N m" : ""; }
  std::string describe() const override { return "wrench"; }
  std::vector<std::string> parameterNames() const override { return {}; }

  std::vector<pc::RecognizerSample> seen;

 private:
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
  EXPECT_TRUE(a.onSample(0.001, Eigen::Vector3d(1.0, 2.0, 3.0), kNoTorque).accepted);
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
  EXPECT_FALSE(a.onSample(0.001, Eigen::Vector3d(0.0, 0.0, nan), kNoTorque).accepted);
  EXPECT_FALSE(a.onSample(nan, Eigen::Vector3d(0.0, 0.0, 1.0), kNoTorque).accepted);
  EXPECT_FALSE(a.admit(0.002, inf));
  // Another axis's NaN is not the thrust's.
  EXPECT_TRUE(a.onSample(0.003, Eigen::Vector3d(nan, 0.0, 1.0), kNoTorque).accepted);
  EXPECT_EQ(a.nonFiniteCount(), 3u);
  EXPECT_EQ(seen.size(), 1u);
  a.reset();
  EXPECT_EQ(a.nonFiniteCount(), 3u);  // counted since construction
}

TEST(RecognizerAdapter, ReportsTheStopOnceOnTheSampleThatLatchesIt) {
  std::vector<double> seen;
  pc::RecognizerAdapter a(std::make_unique<FakeRecognizer>(&seen));
  pc::RecognizerStep s = a.onSample(0.001, Eigen::Vector3d(0.0, 0.0, 1.0), kNoTorque);
  EXPECT_FALSE(s.new_average);
  EXPECT_FALSE(s.new_stop);
  EXPECT_EQ(s.stop_reason, "");
  s = a.onSample(0.002, Eigen::Vector3d(0.0, 0.0, 11.0), kNoTorque);
  EXPECT_TRUE(s.new_average);
  EXPECT_TRUE(s.new_stop);
  EXPECT_EQ(s.stop_reason, "over 10 N");
  s = a.onSample(0.003, Eigen::Vector3d(0.0, 0.0, 12.0), kNoTorque);
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

TEST(RecognizerAdapter, AClassThatReadsTheWholeSampleGetsTheWrenchAndTheContext) {
  auto owned = std::make_unique<WrenchRecognizer>();
  WrenchRecognizer* recognizer = owned.get();
  pc::ForceAxis axis;
  axis.sign = -1.0;
  pc::RecognizerAdapter a(std::move(owned), axis);
  ASSERT_TRUE(
      a.onSample(0.001, Eigen::Vector3d(0.5, -0.25, -3.0), Eigen::Vector3d(0.01, 0.02, 0.03))
          .accepted);
  ASSERT_EQ(recognizer->seen.size(), 1u);
  const pc::RecognizerSample& first = recognizer->seen[0];
  EXPECT_EQ(first.t, 0.001);
  EXPECT_EQ(first.thrust_n, 3.0);  // the axis's, as push() would get it
  EXPECT_EQ(first.force_n, (std::array<double, 3>{0.5, -0.25, -3.0}));
  EXPECT_EQ(first.torque_nm, (std::array<double, 3>{0.01, 0.02, 0.03}));
  EXPECT_TRUE(std::isnan(first.feed_depth_m));  // nothing heard yet: unknown
  EXPECT_TRUE(std::isnan(first.spindle_rpm));
  a.setContext(0.004, 12000.0);
  const pc::RecognizerStep s =
      a.onSample(0.002, Eigen::Vector3d(0.0, 0.0, -3.0), Eigen::Vector3d(0.0, 0.0, 0.2));
  EXPECT_TRUE(s.new_stop);
  EXPECT_EQ(s.stop_reason, "torque over 0.1 N m");
  ASSERT_EQ(recognizer->seen.size(), 2u);
  EXPECT_EQ(recognizer->seen[1].feed_depth_m, 0.004);
  EXPECT_EQ(recognizer->seen[1].spindle_rpm, 12000.0);
}

TEST(RecognizerAdapter, AThrustOnlyClassGetsTheThrustOfTheWholeSample) {
  std::vector<double> seen;
  pc::RecognizerAdapter a(std::make_unique<FakeRecognizer>(&seen));
  a.setContext(0.001, 12000.0);
  EXPECT_TRUE(
      a.push(a.sample(0.001, Eigen::Vector3d(1.0, 2.0, 4.0), Eigen::Vector3d(9.0, 9.0, 9.0)))
          .accepted);
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0], 4.0);
}

TEST(RecognizerAdapter, AWholeSampleTheClassRefusesIsAStop) {
  pc::RecognizerAdapter a(std::make_unique<WrenchRecognizer>());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  // The thrust is finite, so the sample is admitted; the class refuses its torque.
  const pc::RecognizerStep s =
      a.onSample(0.001, Eigen::Vector3d(0.0, 0.0, 1.0), Eigen::Vector3d(0.0, 0.0, nan));
  EXPECT_TRUE(s.accepted);
  EXPECT_TRUE(s.new_stop);
  EXPECT_NE(s.stop_reason.find("torque z not finite"), std::string::npos) << s.stop_reason;
}

TEST(RecognizerAdapter, TheContextComesFromTheDrillsJointsInAJointStateSample) {
  auto owned = std::make_unique<WrenchRecognizer>();
  WrenchRecognizer* recognizer = owned.get();
  pc::RecognizerAdapter a(std::move(owned));
  const double rad_s = 12000.0 * 2.0 * M_PI / 60.0;
  a.setContextFromJoints({"rsssii_joint1", "feed_joint", "spindle_joint"}, {0.1, 0.006, 3.0},
                         {0.0, 0.0005, rad_s});
  a.onSample(0.001, Eigen::Vector3d(0.0, 0.0, 1.0), kNoTorque);
  EXPECT_EQ(recognizer->seen.back().feed_depth_m, 0.006);
  EXPECT_NEAR(recognizer->seen.back().spindle_rpm, 12000.0, 1e-9);
  // A sample without the spindle's velocity keeps the speed heard before; other names work.
  a.setContextFromJoints({"feed_joint", "spindle_joint"}, {0.007, 1.0}, {});
  pc::DrillJointNames lab;
  lab.feed = "drill_feed";
  lab.spindle = "drill_spindle";
  a.setContextFromJoints({"drill_spindle"}, {0.0}, {-rad_s / 2.0}, lab);
  a.onSample(0.002, Eigen::Vector3d(0.0, 0.0, 1.0), kNoTorque);
  EXPECT_EQ(recognizer->seen.back().feed_depth_m, 0.007);
  EXPECT_NEAR(recognizer->seen.back().spindle_rpm, -6000.0, 1e-9);
}

TEST(RecognizerAdapter, TheCommandedFeedAndTheTrackerSampleGoWithEverySampleAfter) {
  auto owned = std::make_unique<WrenchRecognizer>();
  WrenchRecognizer* recognizer = owned.get();
  pc::RecognizerAdapter a(std::move(owned));
  a.onSample(0.001, Eigen::Vector3d(0.0, 0.0, 1.0), kNoTorque);
  EXPECT_TRUE(std::isnan(recognizer->seen.back().feed_command_m));
  EXPECT_TRUE(std::isnan(recognizer->seen.back().tracker_m[0]));
  EXPECT_TRUE(std::isnan(recognizer->seen.back().tracker_stamp));
  // A controller without the feed joint says nothing of it.
  a.setFeedCommandFromController({"rsssii_joint1"}, {0.5});
  a.setFeedCommandFromController({"feed_joint"}, {0.012});
  a.setTracker(2.875, Eigen::Vector3d(0.3, -0.1, 1.2));
  a.onSample(0.002, Eigen::Vector3d(0.0, 0.0, 1.0), kNoTorque);
  EXPECT_EQ(recognizer->seen.back().feed_command_m, 0.012);
  EXPECT_EQ(recognizer->seen.back().tracker_m, (std::array<double, 3>{0.3, -0.1, 1.2}));
  EXPECT_EQ(recognizer->seen.back().tracker_stamp, 2.875);
}
