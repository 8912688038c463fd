// Breath starts on an airway flow signal (core::BreathStartDetector) and the schedule they
// re-phase (core::FlowPhasedSchedule): the Ventilator nodelet's `flow` source and the
// simulator's modelled breath sensor.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/breath_detector.hpp"
#include "pedicle_drilling/core/breathing/ventilator.hpp"

namespace pedicle_drilling::core {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kPeriod64 = 1.0 / 64.0;

/** @brief The starts a detector finds on @p model's flow sampled at 64 Hz from @p t0, plus
 *         Gaussian noise of @p noise_sd ml/s. */
std::vector<double> detect(const VentilatorModel& model, BreathDetectorParams params, double t0,
                           double duration, double noise_sd = 0.0) {
  BreathStartDetector detector(params);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, noise_sd > 0.0 ? noise_sd : 1.0);
  std::vector<double> starts;
  for (int i = 0; i * kPeriod64 < duration; ++i) {
    const double t = t0 + i * kPeriod64;
    const double flow = model.sample(t).flow_ml_s + (noise_sd > 0.0 ? noise(rng) : 0.0);
    if (detector.add(t, flow) == FlowSampleStatus::kBreathStart) starts.push_back(t);
  }
  return starts;
}

TEST(BreathDetector, SquareFlowStartsAtTheFirstSampleAboveTheTrigger) {
  const VentilatorModel model(VentilatorSettings{});  // the paper's: 5 s, square, 300 ml/s
  // Joined 0.3 s into a breath (mid-inspiration): not armed until the expiration, so the
  // first start found is the next breath's.
  const std::vector<double> starts = detect(model, BreathDetectorParams{}, 0.3, 29.0);
  ASSERT_EQ(starts.size(), 5u);
  for (std::size_t k = 0; k < starts.size(); ++k) {
    const double truth = 5.0 * static_cast<double>(k + 1);
    // Late by less than one sample period, never early.
    EXPECT_GE(starts[k], truth - 1e-12) << k;
    EXPECT_LT(starts[k], truth + kPeriod64) << k;
  }
}

TEST(BreathDetector, ArmedAtStartCountsAStreamThatStartsWithABreath) {
  const VentilatorModel model(VentilatorSettings{});
  BreathDetectorParams p;
  p.armed_at_start = true;
  const std::vector<double> starts = detect(model, p, kPeriod64, 12.0);
  ASSERT_EQ(starts.size(), 3u);
  EXPECT_DOUBLE_EQ(starts[0], kPeriod64);  // the stream's first sample, in breath 0
}

TEST(BreathDetector, RampCrossesTheTriggerLaterThanTheBreathStarts) {
  VentilatorSettings s;
  s.waveform = InspiratoryWaveform::kAscendingRamp;  // from 0 to its peak over the flow time
  const VentilatorModel model(s);
  BreathDetectorParams p;
  p.trigger_flow_ml_s = 100.0;
  const std::vector<double> starts = detect(model, p, 0.3, 11.0);
  ASSERT_EQ(starts.size(), 2u);
  // The ramp reaches 100 ml/s at 100 / peak of the flow time after the start; the start found
  // is the first sample past that time.
  const double crossing = 100.0 / model.peakInspiratoryFlow() * model.flowTime();
  for (std::size_t k = 0; k < starts.size(); ++k) {
    const double truth = 5.0 * static_cast<double>(k + 1) + crossing;
    EXPECT_GT(starts[k], truth) << k;
    EXPECT_LE(starts[k], truth + kPeriod64) << k;
  }
}

TEST(BreathDetector, NoiseGivesOneStartPerBreath) {
  const VentilatorModel model(VentilatorSettings{});
  // 10 ml/s SD: the sensor's noise around zero flow never reaches the 33 ml/s trigger, and the
  // 300 ml/s inspiration is above it at every sample.
  const std::vector<double> starts = detect(model, BreathDetectorParams{}, 0.3, 59.0, 10.0);
  ASSERT_EQ(starts.size(), 11u);
  for (std::size_t k = 0; k < starts.size(); ++k) {
    EXPECT_NEAR(starts[k], 5.0 * static_cast<double>(k + 1) + 0.5 * kPeriod64,
                0.5 * kPeriod64 + 1e-9)
        << k;
  }
}

TEST(BreathDetector, HysteresisAndIntervalKeepAFlowAtTheTriggerToOneStart) {
  // A flow that dithers about the trigger (30 .. 36 ml/s): re-armed only at or below the re-arm
  // flow (0), so one start however often it crosses.
  BreathDetectorParams p;
  BreathStartDetector d(p);
  EXPECT_EQ(d.add(0.0, -50.0), FlowSampleStatus::kAccepted);
  int starts = 0;
  for (int i = 1; i < 100; ++i) {
    starts += d.add(i * 0.01, i % 2 == 0 ? 30.0 : 36.0) == FlowSampleStatus::kBreathStart;
  }
  EXPECT_EQ(starts, 1);
  // With the re-arm at the trigger, a dither is a start at every rise but for the minimum
  // interval between starts.
  p.rearm_flow_ml_s = p.trigger_flow_ml_s;
  p.min_interval_s = 0.5;
  BreathStartDetector dither(p);
  dither.add(0.0, -50.0);
  std::vector<double> at;
  for (int i = 1; i <= 100; ++i) {
    const double t = i * 0.01;
    if (dither.add(t, i % 2 == 0 ? 30.0 : 36.0) == FlowSampleStatus::kBreathStart) {
      at.push_back(t);
    }
  }
  ASSERT_EQ(at.size(), 2u);
  EXPECT_NEAR(at[0], 0.01, 1e-12);
  EXPECT_NEAR(at[1], 0.51, 1e-12);
}

TEST(BreathDetector, BadSamplesAreDroppedWithTheirReason) {
  BreathStartDetector d(BreathDetectorParams{});
  EXPECT_EQ(d.add(1.0, -10.0), FlowSampleStatus::kAccepted);
  EXPECT_EQ(d.add(1.1, kNaN), FlowSampleStatus::kNonFiniteFlow);
  EXPECT_EQ(d.add(1.1, kInf), FlowSampleStatus::kNonFiniteFlow);
  EXPECT_EQ(d.add(kNaN, 300.0), FlowSampleStatus::kNonFiniteStamp);
  EXPECT_EQ(d.add(kInf, 300.0), FlowSampleStatus::kNonFiniteStamp);
  EXPECT_EQ(d.add(1.0, 300.0), FlowSampleStatus::kStampNotIncreasing);  // a repeat
  EXPECT_EQ(d.add(0.5, 300.0), FlowSampleStatus::kStampNotIncreasing);  // back in time
  EXPECT_EQ(d.dropped(), 6u);
  EXPECT_EQ(d.breaths(), 0);
  EXPECT_DOUBLE_EQ(d.lastSampleTime(), 1.0);
  EXPECT_NE(describe(FlowSampleStatus::kNonFiniteFlow).find("flow"), std::string::npos);
  EXPECT_NE(describe(FlowSampleStatus::kStampNotIncreasing).find("stamp"), std::string::npos);
  EXPECT_EQ(describe(FlowSampleStatus::kAccepted), "");
  // A dropped sample changed nothing: the next good one above the trigger is the start.
  EXPECT_EQ(d.add(1.2, 300.0), FlowSampleStatus::kBreathStart);
  EXPECT_DOUBLE_EQ(d.lastBreathStart(), 1.2);
  d.reset();
  EXPECT_EQ(d.breaths(), 0);
  EXPECT_EQ(d.add(0.1, 300.0), FlowSampleStatus::kAccepted);  // earlier stamps after a reset
}

TEST(BreathDetector, BadParametersAreRefusedNamingThem) {
  const auto message = [](BreathDetectorParams p) {
    try {
      BreathStartDetector d(p);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  BreathDetectorParams p;
  p.trigger_flow_ml_s = -1.0;
  EXPECT_NE(message(p).find("breath_trigger_flow_ml_s"), std::string::npos);
  p = BreathDetectorParams{};
  p.rearm_flow_ml_s = 50.0;  // above the 33 ml/s trigger
  EXPECT_NE(message(p).find("breath_rearm_flow_ml_s"), std::string::npos);
  p = BreathDetectorParams{};
  p.min_interval_s = kNaN;
  EXPECT_NE(message(p).find("breath_min_interval_s"), std::string::npos);
  FlowPhaseParams f;
  f.timeout_periods = 1.0;
  EXPECT_THROW(f.validate(), std::invalid_argument);
}

/** @brief A patient breathing at @p patient_bpm on a ventilator set to 12 /min. */
struct PatientRun {
  explicit PatientRun(double patient_bpm)
      : patient([patient_bpm] {
          VentilatorSettings s;
          s.rate_bpm = patient_bpm;
          return s;
        }()) {}
  VentilatorModel patient;
  FlowPhasedSchedule schedule{VentilatorSettings{}, FlowPhaseParams{}};
  std::vector<long> indices;  // the schedule's breath index at each detected start

  /** @brief Samples [t0, t1) at 64 Hz; checks the phase after each detected start. */
  void run(double t0, double t1) {
    for (double t = t0; t < t1; t += kPeriod64) {
      if (schedule.addFlow(t, patient.sample(t).flow_ml_s) != FlowSampleStatus::kBreathStart) {
        schedule.scheduler().sample(t);
        continue;
      }
      schedule.scheduler().sample(t);
      indices.push_back(schedule.scheduler().breathIndex());
      const double truth = std::floor(t / patient.period()) * patient.period();
      EXPECT_NEAR(schedule.scheduler().breathStart(), truth, kPeriod64) << t;
    }
  }
};

TEST(FlowPhasedSchedule, FollowsAPatientFasterOrSlowerThanTheSettings) {
  for (const double bpm : {11.0, 12.0, 13.0}) {
    PatientRun r(bpm);
    EXPECT_NE(r.schedule.problem(0.0).find("no flow sample"), std::string::npos);
    r.run(0.3, 0.5);
    EXPECT_NE(r.schedule.problem(0.5).find("no breath start detected yet"), std::string::npos);
    r.run(0.5, 60.0);
    EXPECT_EQ(r.schedule.problem(60.0), "") << bpm;
    // One breath counted per detected start, whether the schedule began it on its own first
    // (a slower patient) or not (a faster one).
    ASSERT_GE(r.indices.size(), 9u) << bpm;
    for (std::size_t k = 0; k < r.indices.size(); ++k) {
      EXPECT_EQ(r.indices[k], static_cast<long>(k)) << bpm;
    }
  }
}

TEST(FlowPhasedSchedule, ASilentSourceMakesThePhaseUnusableAfterTheTimeout) {
  PatientRun r(12.0);
  r.run(0.3, 21.0);  // starts at 5, 10, 15, 20
  EXPECT_EQ(r.schedule.problem(29.9), "");
  EXPECT_DOUBLE_EQ(r.schedule.timeout(), 10.0);  // 2 periods of 5 s
  const std::string why = r.schedule.problem(30.1);
  EXPECT_NE(why.find("no breath start for 10"), std::string::npos) << why;
  EXPECT_NE(why.find("breath_timeout_periods"), std::string::npos) << why;
  r.schedule.reset();
  EXPECT_NE(r.schedule.problem(30.2).find("no flow sample"), std::string::npos);
}

TEST(FlowPhasedSchedule, NewSettingsTakeEffectAtADetectedStart) {
  PatientRun r(12.0);
  r.run(0.3, 6.0);
  VentilatorSettings s;
  s.tv_max_ml = 400.0;
  r.schedule.requestSettings(s);
  EXPECT_DOUBLE_EQ(r.schedule.scheduler().model().settings().tv_max_ml, 500.0);
  r.run(6.0, 11.0);  // the start at 10 s
  EXPECT_DOUBLE_EQ(r.schedule.scheduler().model().settings().tv_max_ml, 400.0);
  s.rate_bpm = 0.0;
  EXPECT_THROW(r.schedule.requestSettings(s), std::invalid_argument);
}

}  // namespace
}  // namespace pedicle_drilling::core
