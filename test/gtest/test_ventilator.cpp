#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>

#include "pedicle_drilling/core/breathing/ventilator.hpp"

namespace pedicle_drilling::core {
namespace {

VentilatorSettings paperSettings() {
  VentilatorSettings s;  // defaults are the paper's: 500 ml, 12 /min, 1:2, square, ratio 1.5
  return s;
}

TEST(Ventilator, PaperSettingsInspiratoryFlowIs300) {
  const VentilatorModel model(paperSettings());
  EXPECT_NEAR(model.period(), 5.0, 1e-12);
  EXPECT_NEAR(model.inspiratoryTime(), 5.0 / 3.0, 1e-12);
  EXPECT_NEAR(model.sample(0.5).flow_ml_s, 300.0, 1e-6);
  EXPECT_NEAR(model.sample(1.6).flow_ml_s, 300.0, 1e-6);
}

TEST(Ventilator, VolumeReaches500AtEndOfInspirationEveryCycle) {
  const VentilatorModel model(paperSettings());
  for (int k : {0, 1, 7, 100, 999}) {
    const double t_end = k * 5.0 + 5.0 / 3.0;
    EXPECT_NEAR(model.volumeInCycle(5.0 / 3.0), 500.0, 0.5);
    EXPECT_NEAR(model.sample(t_end - 1e-9).volume_ml, 500.0, 0.5) << "cycle " << k;
  }
}

TEST(Ventilator, PeakExpiratoryFlowIsOneAndAHalfTimesInspiratory) {
  const VentilatorModel model(paperSettings());
  const double peak = -model.sample(5.0 / 3.0 + 1e-12).flow_ml_s;
  EXPECT_NEAR(peak / 300.0, 1.5, 0.015);
  // The exponential is monotone: the peak is at the start of expiration.
  double most_negative = 0.0;
  for (double t = 0.0; t < 5.0; t += 0.001) {
    most_negative = std::min(most_negative, model.sample(t).flow_ml_s);
  }
  // A 1 ms grid misses the exact start of expiration by < 1 ms: tau = 1.18 s, so < 0.1 %.
  EXPECT_LE(-most_negative, peak + 1e-9);
  EXPECT_NEAR(-most_negative, peak, 1e-3 * peak);
}

TEST(Ventilator, NoDriftOverOneThousandCycles) {
  const VentilatorModel model(paperSettings());
  const double start_first = model.sample(0.0).volume_ml;
  const double start_thousandth = model.sample(999 * 5.0).volume_ml;
  EXPECT_NEAR(start_thousandth, start_first, 0.5);
  // The balance itself holds to solver precision, so even the end of a cycle is back at 0.
  EXPECT_NEAR(model.volumeInCycle(5.0), 0.0, 1e-6);
  // Independently of volumeInCycle(), the flow itself must balance: Simpson's rule on each
  // smooth piece (inspiration, expiration) of one cycle. 1000 cycles may drift at most 0.5 ml,
  // so one cycle's net volume must be below 0.5 ml / 1000.
  const auto integrate = [&model](double from, double to) {
    const int n = 200000;  // even
    const double h = (to - from) / n;
    const double inner = 1e-12;  // stay inside the piece: the flow jumps at its ends
    double sum = model.sample(from + inner).flow_ml_s + model.sample(to - inner).flow_ml_s;
    for (int i = 1; i < n; ++i) sum += (i % 2 ? 4.0 : 2.0) * model.sample(from + i * h).flow_ml_s;
    return sum * h / 3.0;
  };
  const double inspired = integrate(0.0, 5.0 / 3.0);
  const double expired = integrate(5.0 / 3.0, 5.0);
  EXPECT_NEAR(inspired, 500.0, 1e-6);
  EXPECT_NEAR(1000.0 * (inspired + expired), 0.0, 0.5);
  // And the volume the model reports mid-cycle is the integral of its flow.
  EXPECT_NEAR(model.sample(999 * 5.0 + 3.0).volume_ml, inspired + integrate(5.0 / 3.0, 3.0), 1e-6);
}

TEST(Ventilator, EverySixShapeDeliversTvMaxWithinHalfPercent) {
  for (const auto& name : waveformNames()) {
    VentilatorSettings s = paperSettings();
    ASSERT_TRUE(parseWaveform(name, &s.waveform));
    s.pause_fraction = 0.1;
    const VentilatorModel model(s);
    // Integrate the sampled flow over the inspiration, independently of volumeInCycle().
    double inspired = 0.0;
    const int n = 200000;
    const double dt = model.inspiratoryTime() / n;
    for (int i = 0; i < n; ++i) inspired += model.flowInCycle((i + 0.5) * dt) * dt;
    EXPECT_NEAR(inspired, 500.0, 2.5) << name;
    EXPECT_NEAR(model.volumeInCycle(model.inspiratoryTime()), 500.0, 2.5) << name;
    EXPECT_NEAR(model.volumeInCycle(model.period()), 0.0, 1e-6) << name;
    const ConstraintResiduals r = model.residuals();
    EXPECT_LT(std::abs(r.inspired_minus_tv_ml), 1e-6) << name;
    EXPECT_LT(std::abs(r.expired_plus_tv_ml), 1e-6) << name;
    EXPECT_LT(std::abs(r.peak_ratio_error), 1e-6) << name;
  }
}

TEST(Ventilator, ShapesDiffer) {
  // The shapes must actually be different curves, not one curve under six names.
  VentilatorSettings a = paperSettings();
  VentilatorSettings b = paperSettings();
  a.waveform = InspiratoryWaveform::kAscendingRamp;
  b.waveform = InspiratoryWaveform::kDescendingRamp;
  const VentilatorModel ma(a);
  const VentilatorModel mb(b);
  EXPECT_LT(ma.flowInCycle(0.1), ma.flowInCycle(1.5));
  EXPECT_GT(mb.flowInCycle(0.1), mb.flowInCycle(1.5));
  // Ramp from zero: peak is twice the mean flow of 300 ml/s.
  EXPECT_NEAR(ma.peakInspiratoryFlow(), 600.0, 1e-6);
}

TEST(Ventilator, InspiratoryPauseHoldsVolume) {
  VentilatorSettings s = paperSettings();
  s.pause_fraction = 0.2;
  const VentilatorModel model(s);
  const double pause_start = model.inspiratoryTime() * 0.8;
  EXPECT_NEAR(model.flowInCycle(pause_start + 0.01), 0.0, 1e-12);
  EXPECT_NEAR(model.volumeInCycle(pause_start + 0.01), 500.0, 1e-6);
  EXPECT_NEAR(model.volumeInCycle(model.inspiratoryTime() - 1e-9), 500.0, 1e-6);
  // Same volume in less time: higher flow.
  EXPECT_NEAR(model.inspiratoryAmplitude(), 500.0 / pause_start, 1e-6);
}

TEST(Ventilator, TimeConstantModeMatchesRcLung) {
  // jCpSim VentilationOfRcLung: tau = R C = 0.4 s.
  VentilatorSettings s = paperSettings();
  s.expiratory_spec = ExpiratorySpec::kTimeConstant;
  s.expiratory_tau_s = 0.4;
  const VentilatorModel model(s);
  EXPECT_NEAR(model.expiratoryTau(), 0.4, 1e-9);
  const double te = model.period() - model.inspiratoryTime();
  EXPECT_NEAR(model.expiratoryPeak(), 500.0 / (0.4 * (1.0 - std::exp(-te / 0.4))), 1e-6);
}

TEST(Ventilator, PaperConstantsViolateTheirOwnConstraints) {
  // Documents the inconsistency of Eq. 10-11 (calibration.md): a = 300 inspires exactly 500 ml,
  // but the published (b, c) expire about 536 ml and leave a ~34 ml/s flow jump.
  const ConstraintResiduals r = paperConstantsResiduals();
  EXPECT_NEAR(r.inspired_minus_tv_ml, 0.0, 1e-9);
  EXPECT_NEAR(r.expired_plus_tv_ml, -36.0, 1.0);
  EXPECT_NEAR(r.end_flow_jump_ml_s, 33.8, 0.5);
  EXPECT_NEAR(r.peak_ratio_error, 0.0, 1e-3);
  // Our model keeps the peak ratio and the balance exactly; only continuity is given up.
  const ConstraintResiduals ours = VentilatorModel(paperSettings()).residuals();
  EXPECT_LT(std::abs(ours.expired_plus_tv_ml), 1e-6);
  EXPECT_GT(ours.end_flow_jump_ml_s, 0.0);
}

TEST(Ventilator, ValidationNamesTheField) {
  VentilatorSettings s = paperSettings();
  s.rate_bpm = 0.0;
  try {
    s.validate();
    FAIL() << "rate 0 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("rate_bpm"), std::string::npos);
  }
  s = paperSettings();
  s.tv_max_ml = std::nan("");
  EXPECT_THROW(s.validate(), std::invalid_argument);
  s = paperSettings();
  s.peak_flow_ratio = 0.3;  // cannot return 500 ml in 3.33 s
  try {
    VentilatorModel model(s);
    FAIL() << "infeasible ratio accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("peak_flow_ratio"), std::string::npos);
  }
}

TEST(Ventilator, ParsesIeRatioAndWaveforms) {
  double i = 0;
  double e = 0;
  EXPECT_TRUE(parseIeRatio("1:2", &i, &e));
  EXPECT_DOUBLE_EQ(i, 1.0);
  EXPECT_DOUBLE_EQ(e, 2.0);
  EXPECT_TRUE(parseIeRatio("1.5:3", &i, &e));
  for (const char* bad : {"12", "1:", ":2", "a:b", "1:2:3", "0:2", "-1:2", "1:2x"}) {
    EXPECT_FALSE(parseIeRatio(bad, &i, &e)) << bad;
  }
  InspiratoryWaveform w;
  EXPECT_FALSE(parseWaveform("triangle", &w));
  EXPECT_EQ(waveformNames().size(), 6u);
}

TEST(BreathScheduler, SettingsChangeAtNextBreathOnly) {
  BreathScheduler scheduler(paperSettings());
  EXPECT_NEAR(scheduler.sample(1.0).flow_ml_s, 300.0, 1e-6);
  VentilatorSettings faster = paperSettings();
  faster.tv_max_ml = 400.0;
  faster.rate_bpm = 15.0;  // T = 4 s
  scheduler.requestSettings(faster);
  // Still the old breath: same flow, same period.
  EXPECT_NEAR(scheduler.sample(1.2).flow_ml_s, 300.0, 1e-6);
  EXPECT_NEAR(scheduler.sample(4.99).volume_ml,
              VentilatorModel(paperSettings()).volumeInCycle(4.99), 1e-9);
  EXPECT_TRUE(scheduler.hasPendingSettings());
  // Next breath starts at t = 5 with the new settings: Ti = 4/3 s, flow = 400 / (4/3) = 300.
  const VentilatorSample s = scheduler.sample(5.0 + 1.0);
  EXPECT_FALSE(scheduler.hasPendingSettings());
  EXPECT_EQ(scheduler.breathIndex(), 1);
  EXPECT_NEAR(scheduler.model().period(), 4.0, 1e-12);
  EXPECT_NEAR(s.volume_ml, 300.0, 1e-6);
  EXPECT_NEAR(scheduler.sample(5.0 + 4.0 / 3.0).volume_ml, 400.0, 1e-6);
  // The breath after lasts 4 s.
  scheduler.sample(9.0 + 0.001);
  EXPECT_EQ(scheduler.breathIndex(), 2);
}

TEST(BreathScheduler, SettingsForALaterBreathWaitForIt) {
  BreathScheduler scheduler(paperSettings());
  VentilatorSettings slower = paperSettings();
  slower.rate_bpm = 8.0;  // T = 7.5 s
  scheduler.requestSettings(slower, 2);
  scheduler.sample(5.5);  // breath 1: not yet
  EXPECT_EQ(scheduler.breathIndex(), 1);
  EXPECT_TRUE(scheduler.hasPendingSettings());
  EXPECT_NEAR(scheduler.model().period(), 5.0, 1e-12);
  scheduler.sample(10.5);  // breath 2 starts at 10 s with them
  EXPECT_EQ(scheduler.breathIndex(), 2);
  EXPECT_FALSE(scheduler.hasPendingSettings());
  EXPECT_NEAR(scheduler.model().period(), 7.5, 1e-12);
  // A breath already begun is never changed: an index not ahead is the next breath.
  scheduler.requestSettings(paperSettings(), 0);
  scheduler.sample(17.0);
  EXPECT_NEAR(scheduler.model().period(), 7.5, 1e-12);
  scheduler.sample(17.6);
  EXPECT_EQ(scheduler.breathIndex(), 3);
  EXPECT_NEAR(scheduler.model().period(), 5.0, 1e-12);
}

TEST(BreathScheduler, BadSettingsRejectedAndOldOnesKept) {
  BreathScheduler scheduler(paperSettings());
  VentilatorSettings bad = paperSettings();
  bad.rate_bpm = -3.0;
  EXPECT_THROW(scheduler.requestSettings(bad), std::invalid_argument);
  EXPECT_FALSE(scheduler.hasPendingSettings());
  EXPECT_NEAR(scheduler.sample(6.0).flow_ml_s, 300.0, 1e-6);
}

TEST(BreathScheduler, RestartAfterTimeJumpedBackStartsANewBreath) {
  BreathScheduler scheduler(paperSettings(), 100.0);
  scheduler.sample(107.0);  // second breath, 2 s in
  EXPECT_EQ(scheduler.breathIndex(), 1);
  // Without a restart, an earlier time is clamped (a ventilator does not go back).
  EXPECT_NEAR(scheduler.sample(50.0).t, 107.0, 1e-12);
  VentilatorSettings bigger = paperSettings();
  bigger.tv_max_ml = 600.0;
  scheduler.requestSettings(bigger);
  scheduler.restart(50.0);
  EXPECT_EQ(scheduler.breathIndex(), 2);
  EXPECT_FALSE(scheduler.hasPendingSettings());  // the new breath takes the pending settings
  const VentilatorSample s = scheduler.sample(50.5);
  EXPECT_NEAR(s.t, 50.5, 1e-12);
  EXPECT_NEAR(s.flow_ml_s, 360.0, 1e-6);  // 600 ml over 5/3 s
  EXPECT_NEAR(s.volume_ml, 180.0, 1e-6);
  EXPECT_NEAR(scheduler.breathStart(), 50.0, 1e-12);
  EXPECT_THROW(scheduler.restart(std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
}

}  // namespace
}  // namespace pedicle_drilling::core
