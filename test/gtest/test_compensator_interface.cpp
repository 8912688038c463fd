// Tests of the compensator plugin interface: the paper compensator is the prediction
// it wraps, the tracker-feedback baseline, the factory, and a planner driven by any class.
#include "pedicle_drilling/core/control/compensator_interface.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "param_table_checks.hpp"
#include "pedicle_drilling/core/control/compensation_planner.hpp"

namespace pd = pedicle_drilling::core;

namespace {

pd::MotionModel apModel() {
  pd::MotionModel m;
  m.axis(pd::Axis::kAP).q1 = 0.01;
  m.axis(pd::Axis::kAP).q0 = 0.4;
  return m;
}

std::string errorOf(pd::CompensatorInterface* c, const pd::CompensatorSettings& s) {
  try {
    c->configure(s);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

/** @brief A compensator of the test: a 2 mm sine along world z at 0.25 Hz, velocity step at 0.93 s.
 */
class SineCompensator : public pd::CompensatorInterface {
 public:
  void configure(const pd::CompensatorSettings&) override {}
  void setPatient(const pd::MotionModel&, const pd::CompensationParams&) override {
    patient_set = true;
  }
  void setVentilator(const pd::VentilatorSettings&) override {}
  void setBreathStart(double) override {}
  void observeMarker(double stamp, const Eigen::Vector3d&) override { observed.push_back(stamp); }
  bool ready() const override { return true; }
  Eigen::Vector3d displacement(double t) const override {
    return Eigen::Vector3d(0.0, 0.0, 2e-3 * std::sin(2.0 * M_PI * 0.25 * t));
  }
  std::vector<double> velocitySteps(double t0, double t1) const override {
    return t0 < 0.93 && 0.93 <= t1 ? std::vector<double>{0.93} : std::vector<double>{};
  }
  std::string describe() const override { return "sine"; }
  std::vector<std::string> parameterNames() const override { return {}; }

  bool patient_set = false;
  std::vector<double> observed;
};

}  // namespace

TEST(PaperCompensator, IsThePredictionItWrapsWhateverTheOrderOfItsInputs) {
  pd::CompensationParams params;
  pd::DisplacementPredictor reference(apModel(), params);
  reference.setVentilator(pd::VentilatorSettings());
  reference.setBreathStart(0.3);
  // Settings and phase before the patient (the sequencer may have them first) ...
  pd::PaperCompensator early;
  early.configure({});
  EXPECT_FALSE(early.ready());
  early.setVentilator(pd::VentilatorSettings());
  early.setBreathStart(0.3);
  EXPECT_FALSE(early.ready());
  early.setPatient(apModel(), params);
  // ... or after it.
  pd::PaperCompensator late;
  late.setPatient(apModel(), params);
  EXPECT_FALSE(late.ready());
  late.setVentilator(pd::VentilatorSettings());
  late.setBreathStart(0.3);
  ASSERT_TRUE(early.ready());
  ASSERT_TRUE(late.ready());
  for (double t = -2.0; t < 12.0; t += 0.0371) {
    EXPECT_EQ(early.displacement(t), reference.displacement(t)) << t;  // bit for bit
    EXPECT_EQ(late.displacement(t), reference.displacement(t)) << t;
  }
  EXPECT_EQ(early.velocitySteps(0.0, 10.0), reference.flowSteps(0.0, 10.0));
  EXPECT_FALSE(early.velocitySteps(0.0, 10.0).empty());
  EXPECT_TRUE(early.parameterNames().empty());
  EXPECT_NE(errorOf(&early, {{"latency_s", "0.1"}}).find("latency_s"), std::string::npos);
  EXPECT_THROW(pd::PaperCompensator().displacement(0.0), std::logic_error);
}

TEST(TrackedMarkerCompensator, HoldsTheLastSampleAndIgnoresLostOrLateOnes) {
  pd::TrackedMarkerCompensator c;
  c.configure({});
  EXPECT_FALSE(c.ready());
  EXPECT_THROW(c.displacement(0.0), std::logic_error);
  c.observeMarker(1.0, Eigen::Vector3d(0.1, 0.2, 0.3));
  ASSERT_TRUE(c.ready());
  EXPECT_EQ(c.displacement(5.0), Eigen::Vector3d(0.1, 0.2, 0.3));
  c.observeMarker(1.125, Eigen::Vector3d(0.1, 0.2, 0.301));
  EXPECT_EQ(c.displacement(1.2), Eigen::Vector3d(0.1, 0.2, 0.301));  // held, not extrapolated
  c.observeMarker(1.25, Eigen::Vector3d(std::nan(""), 0.0, 0.0));    // a lost sample
  c.observeMarker(1.0, Eigen::Vector3d(9.0, 9.0, 9.0));              // late
  c.observeMarker(1.125, Eigen::Vector3d(9.0, 9.0, 9.0));            // repeated
  EXPECT_EQ(c.displacement(1.3), Eigen::Vector3d(0.1, 0.2, 0.301));
  EXPECT_TRUE(c.velocitySteps(0.0, 10.0).empty());
}

TEST(TrackedMarkerCompensator, ExtrapolatesAtTheLastVelocityUpToTheHorizon) {
  pd::TrackedMarkerCompensator c;
  c.configure({{"extrapolate", "true"}, {"max_horizon_s", "0.25"}});
  c.observeMarker(2.0, Eigen::Vector3d(0.0, 0.0, 0.010));
  EXPECT_EQ(c.displacement(2.1), Eigen::Vector3d(0.0, 0.0, 0.010));  // one sample: no velocity
  c.observeMarker(2.125, Eigen::Vector3d(0.0, 0.0, 0.011));          // 8 mm/s
  EXPECT_NEAR(c.displacement(2.125).z(), 0.011, 1e-15);
  EXPECT_NEAR(c.displacement(2.225).z(), 0.011 + 0.1 * 0.008, 1e-12);
  EXPECT_NEAR(c.displacement(9.0).z(), 0.011 + 0.25 * 0.008, 1e-12);  // capped
  EXPECT_NEAR(c.displacement(2.0).z(), 0.011, 1e-15);                 // never backwards
  EXPECT_NE(c.describe().find("constant-velocity"), std::string::npos);
}

TEST(TrackedMarkerCompensator, BadSettingsNameTheParameter) {
  pd::TrackedMarkerCompensator c;
  EXPECT_EQ(errorOf(&c, {{"max_horizon_s", "0"}}).rfind("max_horizon_s", 0), 0u);
  EXPECT_EQ(errorOf(&c, {{"max_horizon_s", "nan"}}).rfind("max_horizon_s", 0), 0u);
  EXPECT_EQ(errorOf(&c, {{"max_horizon_s", "1s"}}).rfind("max_horizon_s", 0), 0u);
  EXPECT_EQ(errorOf(&c, {{"extrapolate", "yes"}}).rfind("extrapolate", 0), 0u);
  EXPECT_EQ(errorOf(&c, {{"gain", "2"}}), "unknown parameter 'gain'");  // as every ParamTable
  EXPECT_EQ(c.parameterNames(), (std::vector<std::string>{"extrapolate", "max_horizon_s"}));
}

TEST(TrackedMarkerParams, TheTableDeclaresEveryFieldWithItsDefaultAndRange) {
  pedicle_drilling::test::expectDeclaredDefaults(
      pd::TrackedMarkerParams::table(), {{"extrapolate", "false"}, {"max_horizon_s", "0.5"}});
  pedicle_drilling::test::expectRangesRefusedNamingTheField(pd::TrackedMarkerParams::table());
  EXPECT_EQ(pd::TrackedMarkerCompensator().parameterNames(),
            pd::TrackedMarkerParams::table().declaredNames());
}

TEST(CompensatorFactory, MakesTheBuiltInsAndNamesTheKnownOnesOtherwise) {
  for (const std::string& name : pd::builtinCompensatorNames()) {
    EXPECT_NE(pd::makeBuiltinCompensator(name, {}), nullptr) << name;
  }
  try {
    pd::makeBuiltinCompensator("my_pkg/Nope", {});
    FAIL() << "an unknown class was made";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("pedicle_drilling/TrackedMarkerCompensator"),
              std::string::npos);
  }
  EXPECT_THROW(pd::makeBuiltinCompensator("pedicle_drilling/TrackedMarkerCompensator",
                                          {{"max_horizon_s", "-1"}}),
               std::invalid_argument);
}

TEST(CompensationPlannerWithACompensator, FollowsWhatTheClassPredictsAndItsVelocitySteps) {
  pd::CompensationParams params;
  params.feed_rate_m_s = 0.5e-3;
  params.segment_profile = pd::SegmentProfile::kExact;
  auto sine = std::make_unique<SineCompensator>();
  SineCompensator* raw = sine.get();
  pd::CompensationPlanner planner(params, apModel(), std::move(sine));
  EXPECT_TRUE(raw->patient_set);
  planner.start(pd::CompensationMode::kCompensated, 0.5);
  const Eigen::Vector3d axis = params.drill_axis;  // -z
  for (double t : {0.5, 0.9, 1.7, 3.2}) {
    const double feed = 0.5e-3 * (t - 0.5);
    const double y = 2e-3 * std::sin(2.0 * M_PI * 0.25 * t) - 2e-3 * std::sin(M_PI * 0.25);
    // The drill axis is -z: a bone rising along +z shortens the feed-joint offset.
    EXPECT_NEAR(planner.referenceFeed(t), feed - y, 1e-15) << t;
    EXPECT_NEAR(planner.boneDisplacementSinceStart(t).z(), y, 1e-15) << t;
  }
  EXPECT_EQ(planner.reference(1.0).dot(axis), planner.referenceFeed(1.0));
  // The class's velocity step at 0.93 s is a knot of the exact segment that contains it
  // (segment 3: 0.875 to 1 s, samples every 25 ms).
  ASSERT_EQ(planner.segmentIndexAt(0.93), 3);
  bool knot = false;
  for (const pd::PlannedPoint& p : planner.segment(3).points) knot = knot || p.t == 0.93;
  EXPECT_TRUE(knot);
  for (const pd::PlannedPoint& p : planner.segment(2).points) EXPECT_NE(p.t, 0.93);
  EXPECT_THROW(pd::CompensationPlanner(params, apModel(), nullptr), std::invalid_argument);
}

namespace {

/// The tracker-feedback baseline with a bug: displacement() throws once `fail` is set.
class FailingCompensator : public pd::TrackedMarkerCompensator {
 public:
  explicit FailingCompensator(const bool* fail) : fail_(fail) {}
  Eigen::Vector3d displacement(double t) const override {
    if (*fail_) throw std::logic_error("plugin bug");
    return pd::TrackedMarkerCompensator::displacement(t);
  }

 private:
  const bool* fail_;
};

}  // namespace

// The TrialSequencer runs every class behind this guard: the first error is kept (the sequencer
// stops on it) and from then on the guard answers by itself, the last displacement held.
TEST(GuardedCompensator, KeepsTheFirstErrorAndHoldsTheLastDisplacement) {
  bool fail = false;
  pd::GuardedCompensator guard(std::make_unique<FailingCompensator>(&fail));
  guard.configure({});
  guard.observeMarker(1.0, Eigen::Vector3d(0.0, 0.0, 0.002));
  ASSERT_TRUE(guard.ready());
  EXPECT_TRUE(guard.displacement(1.1).isApprox(Eigen::Vector3d(0.0, 0.0, 0.002)));
  fail = true;
  EXPECT_TRUE(guard.displacement(1.2).isApprox(Eigen::Vector3d(0.0, 0.0, 0.002)));
  EXPECT_EQ(guard.error(), "displacement: plugin bug");
  EXPECT_FALSE(guard.ready());
  EXPECT_TRUE(guard.velocitySteps(1.0, 2.0).empty());
  EXPECT_NE(guard.describe().find("failed: displacement: plugin bug"), std::string::npos);
  fail = false;  // not asked again: the first error stays
  guard.observeMarker(1.3, Eigen::Vector3d(0.0, 0.0, 0.004));
  EXPECT_TRUE(guard.displacement(1.4).isApprox(Eigen::Vector3d(0.0, 0.0, 0.002)));
  EXPECT_EQ(guard.error(), "displacement: plugin bug");
  EXPECT_THROW(pd::GuardedCompensator(nullptr), std::invalid_argument);
}
