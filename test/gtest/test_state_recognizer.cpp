// Tests of the force-based drilling-state recognizer (doc/state_machine.md).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "pedicle_drilling/core/drilling/state_recognizer.hpp"

namespace pedicle_drilling::core {
namespace {

constexpr double kRate = 1000.0;  // raw force samples per second in the synthetic profiles

double lerp(double a, double b, double u) { return a + (b - a) * u; }

// Piecewise profile: air, outer cortical hump, cancellous plateau with fluctuation, inner
// cortical hump (optional), breakthrough. Times in s, forces in N.
struct Profile {
  double f_out = 3.0;
  double f_in = 3.0;
  double f_canc = 0.7;
  bool inner = true;
  double noise = 0.3;  // raw Gaussian noise sigma [N]
  double canc_ripple = 0.15;
  unsigned seed = 1;

  // Inner layer time window (contact .. end of breakthrough drop).
  static constexpr double kInnerStart = 16.0;
  static constexpr double kInnerPeakEnd = 19.5;
  static constexpr double kInnerEnd = 20.5;
  static constexpr double kEnd = 23.0;

  double clean(double t) const {
    if (t < 2.0) return 0.0;
    if (t < 4.0) return lerp(0.0, f_out, (t - 2.0) / 2.0);
    if (t < 5.0) return f_out;
    if (t < 6.0) return lerp(f_out, f_canc, t - 5.0);
    const double canc = f_canc + canc_ripple * std::sin(2.0 * M_PI * 0.7 * t);
    if (!inner || t < kInnerStart) return canc;
    if (t < 18.0) return lerp(canc, f_in, (t - kInnerStart) / 2.0);
    if (t < kInnerPeakEnd) return f_in;
    if (t < kInnerEnd) return lerp(f_in, 0.1, t - kInnerPeakEnd);
    return 0.1;
  }

  std::vector<double> samples() const {
    std::mt19937 rng(seed);
    std::normal_distribution<double> n(0.0, noise);
    std::vector<double> out;
    const int count = static_cast<int>(kEnd * kRate);
    out.reserve(static_cast<std::size_t>(count));
    for (int i = 0; i < count; ++i) out.push_back(clean(i / kRate) + n(rng));
    return out;
  }
};

struct RunResult {
  RecognizerOutput out;
  std::vector<DrillingState> states;  // distinct consecutive layer states visited
};

// The synthetic profiles' recognizer: declared at their 1 kHz, blocks of 50 samples (0.05 s).
RecognizerParams profileParams() {
  RecognizerParams p;
  p.sensor_rate_hz = kRate;
  p.pre_average_s = 0.05;
  return p;
}

RunResult runProfile(const std::vector<double>& f, const RecognizerParams& p = profileParams()) {
  StateRecognizer rec(p);
  RunResult r;
  r.states.push_back(DrillingState::kIdle);
  for (std::size_t i = 0; i < f.size(); ++i) {
    const RecognizerOutput& o = rec.push(static_cast<double>(i) / kRate, f[i]);
    if (o.layer_state != r.states.back()) r.states.push_back(o.layer_state);
  }
  r.out = rec.output();
  return r;
}

// Direct-drive helper: blocks of 2 raw samples (the least a block may hold: 2 s at a declared
// 1 Hz) and window 1, and Direct pushes each value twice, so that each value is fbar itself.
// One averaged sample per value (the tests push one per second, t = 0, 1, 2, ...); the value
// pushed i-th ends at raw index rawIndex(i).
RecognizerParams directParams() {
  RecognizerParams p;
  p.sensor_rate_hz = 1.0;
  p.pre_average_s = 2.0;
  p.window = 1;
  return p;
}

std::size_t rawIndex(int i) { return static_cast<std::size_t>(2 * i + 1); }

// A recognizer fed one averaged value per push (both samples of a block at time t).
class Direct {
 public:
  explicit Direct(const RecognizerParams& p) : rec_(p) {}
  const RecognizerOutput& push(double t, double f) {
    rec_.push(t, f);
    return rec_.push(t, f);
  }
  const RecognizerOutput& output() const { return rec_.output(); }
  void reset() { rec_.reset(); }

 private:
  StateRecognizer rec_;
};

TEST(StateRecognizerFeature, Eq14And15) {
  RecognizerParams p;
  // Literal Eq. 14: A = D f*^3, f* = (fbar - f_min) / D; Eq. 15 gain above H_g.
  EXPECT_DOUBLE_EQ(StateRecognizer::feature(p, -1.0, 0.0, 3.0), 0.0);
  EXPECT_DOUBLE_EQ(StateRecognizer::feature(p, 0.9, 0.0, 3.0), 3.0 * 0.027);  // 0.081 < H_g
  EXPECT_DOUBLE_EQ(StateRecognizer::feature(p, 2.4, 0.0, 3.0), 1.2 * 3.0 * 0.512);
  EXPECT_DOUBLE_EQ(StateRecognizer::feature(p, 5.0, 0.0, 3.0), 1.2 * 3.0);    // saturated at D
  EXPECT_DOUBLE_EQ(StateRecognizer::feature(p, 1.5, 0.5, 2.0), 2.0 * 0.125);  // offset f_min
  p.normalize_feature = true;
  EXPECT_DOUBLE_EQ(StateRecognizer::feature(p, 2.4, 0.0, 3.0), 0.512 * 1.2);
  EXPECT_DOUBLE_EQ(StateRecognizer::feature(p, 1.5, 0.0, 3.0), 0.125);
}

TEST(StateRecognizerFilter, PreAverageAndMovingAverageIndices) {
  RecognizerParams p;  // 0.15 s at 1000/3 Hz = 50 samples, x 10
  StateRecognizer rec(p);
  // 10 blocks of 50 raw samples are needed: raw index 499 gives the first fbar.
  for (int i = 0; i < 499; ++i) {
    EXPECT_FALSE(rec.push(i * 1e-3, 1.0).filter_ready) << i;
  }
  const RecognizerOutput& o2 = rec.push(0.499, 1.0);
  EXPECT_TRUE(o2.filter_ready);
  EXPECT_TRUE(o2.new_average);
  EXPECT_DOUBLE_EQ(o2.averaged_force, 1.0);
  EXPECT_FALSE(rec.push(0.500, 1.0).new_average);
}

TEST(StateRecognizerFilter, MovingAverageValue) {
  RecognizerParams p;
  p.sensor_rate_hz = 1.0;
  p.pre_average_s = 2.0;  // blocks of 2 samples
  p.window = 3;
  StateRecognizer rec(p);
  const double raw[] = {1, 3, 5, 7, 0, 2, 10, 20};  // blocks: 2, 6, 1, 15
  std::vector<double> fbar;
  for (int i = 0; i < 8; ++i) {
    const RecognizerOutput& o = rec.push(i, raw[i]);
    if (o.new_average && o.filter_ready) fbar.push_back(o.averaged_force);
  }
  ASSERT_EQ(fbar.size(), 2u);
  EXPECT_DOUBLE_EQ(fbar[0], 3.0);
  EXPECT_DOUBLE_EQ(fbar[1], 22.0 / 3.0);
}

TEST(StateRecognizerTransitions, IdleToOuterCorticalNeedsFth) {
  Direct rec(directParams());
  EXPECT_EQ(rec.push(0, 0.5).state, DrillingState::kIdle);
  EXPECT_EQ(rec.push(1, 1.0).state, DrillingState::kIdle);  // F_max must exceed F_th strictly
  EXPECT_EQ(rec.push(2, 1.01).state, DrillingState::kOuterCortical);
  EXPECT_FALSE(rec.output().params_ready);
  EXPECT_EQ(rec.output().last_key_point, 0);
}

TEST(StateRecognizerTransitions, Algorithm2FixesKAndD) {
  Direct rec(directParams());
  const double f[] = {0.2, 0.1, 2.0, 3.0, 1.6, 1.4};
  for (int i = 0; i < 5; ++i) {
    rec.push(i, f[i]);
    EXPECT_FALSE(rec.output().params_ready) << i;  // 1.6 >= K * 3.0
  }
  const RecognizerOutput& o = rec.push(5, f[5]);  // 1.4 < 1.5: end of layer 1
  EXPECT_TRUE(o.params_ready);
  EXPECT_EQ(o.k, 5u);
  EXPECT_DOUBLE_EQ(o.d, 3.0 - 0.1);
  EXPECT_DOUBLE_EQ(o.f_min, 0.1);
  EXPECT_EQ(o.state, DrillingState::kOuterPunctured);
  ASSERT_EQ(o.num_key_points, 2);
  EXPECT_EQ(o.key_points[0].id, 1);
  // KP1: first sample whose A* >= C1: fbar = 2.0 -> f* = 1.9/2.9, A = 2.9 f*^3 = 0.815 -> A* 0.98.
  EXPECT_EQ(o.key_points[0].index, rawIndex(2));
  EXPECT_EQ(o.key_points[0].recognized_index, rawIndex(5));
  EXPECT_EQ(o.key_points[1].id, 2);
  EXPECT_EQ(o.key_points[1].index, rawIndex(5));
}

TEST(StateRecognizerTransitions, NoKeyPoint2WhileFmaxBelowFth) {
  Direct rec(directParams());
  // Drops by more than K but F_max never exceeds F_th: soft tissue, not bone.
  for (double f : {0.2, 0.9, 0.3, 0.0, 0.95, 0.1}) rec.push(0, f);
  EXPECT_EQ(rec.output().state, DrillingState::kIdle);
  EXPECT_EQ(rec.output().num_key_points, 0);
}

TEST(StateRecognizerTransitions, CancellousNeedsConfirmedDwellBelowC1) {
  RecognizerParams p = directParams();
  p.cancellous_confirm = 3;
  Direct rec(p);
  int i = 0;
  for (double f : {0.0, 3.0, 1.0}) rec.push(i++, f);  // KP2 at i = 2 (A* = 0.111 < C1)
  ASSERT_EQ(rec.output().last_key_point, 2);
  rec.push(i++, 1.0);  // run 1 (the KP2 sample itself does not count)
  rec.push(i++, 1.0);  // run 2
  rec.push(i++, 2.5);  // A* = 2.08 > C1: rebound resets the dwell
  EXPECT_EQ(rec.output().state, DrillingState::kOuterPunctured);
  rec.push(i++, 0.7);  // i = 6, run 1
  rec.push(i++, 0.7);
  EXPECT_EQ(rec.output().state, DrillingState::kOuterPunctured);
  const RecognizerOutput& o = rec.push(i++, 0.7);  // i = 8, run 3: confirmed
  EXPECT_EQ(o.state, DrillingState::kCancellous);
  EXPECT_EQ(o.last_key_point, 3);
  EXPECT_EQ(o.key_points[2].index, rawIndex(8));
  EXPECT_EQ(o.key_points[2].recognized_index, rawIndex(8));
  EXPECT_FALSE(o.stop);
}

TEST(StateRecognizerTransitions, NoCancellousWithinTheDeadlineIsAnImplausibleForceStop) {
  RecognizerParams p = directParams();
  p.cancellous_confirm = 3;
  p.cancellous_deadline = 6;  // averaged samples after key point 2
  Direct rec(p);
  int i = 0;
  for (double f : {0.0, 3.0, 1.0}) rec.push(i++, f);  // KP2 on the third sample
  ASSERT_EQ(rec.output().last_key_point, 2);
  // A drifting sensor: A* stays above C1 after the outer layer.
  for (int k = 0; k < 6; ++k) rec.push(i++, 2.5);
  EXPECT_FALSE(rec.output().stop) << "6 samples after key point 2: not yet";
  const RecognizerOutput& o = rec.push(i++, 2.5);
  ASSERT_TRUE(o.stop);
  EXPECT_TRUE(o.stop_implausible);
  EXPECT_EQ(o.stop_key_point, 2);
  EXPECT_EQ(o.state, DrillingState::kStopped);
  EXPECT_NE(stopReason(o).find("implausible force"), std::string::npos) << stopReason(o);
}

TEST(StateRecognizerTransitions, CancellousConfirmedOnTheDeadlineSampleIsNotAStop) {
  RecognizerParams p = directParams();
  p.cancellous_confirm = 3;
  p.cancellous_deadline = 6;
  Direct rec(p);
  int i = 0;
  for (double f : {0.0, 3.0, 1.0}) rec.push(i++, f);                 // KP2
  for (double f : {2.5, 2.5, 2.5, 0.5, 0.5, 0.5}) rec.push(i++, f);  // confirmed on the 6th
  EXPECT_FALSE(rec.output().stop);
  EXPECT_EQ(rec.output().last_key_point, 3);
  EXPECT_EQ(rec.output().state, DrillingState::kCancellous);
}

TEST(StateRecognizerTransitions, CancellousDeadlineIsCountedInSamplesWhateverTheirTimes) {
  // A count of averaged samples, so the same at any sample rate: with window 1 and
  // cancellous_confirm 5 the default 25 stops on the 26th averaged sample after key point 2, at
  // 20 and at 6.67 averaged samples per second.
  for (double period : {0.05, 0.15}) {
    SCOPED_TRACE(period);
    RecognizerParams p = directParams();  // cancellous_deadline 25 (the default)
    Direct rec(p);
    int i = 0;
    for (double f : {0.0, 3.0, 1.0}) rec.push(period * i++, f);
    ASSERT_EQ(rec.output().last_key_point, 2);
    int n = 0;
    while (!rec.output().stop && n < 100) {
      rec.push(period * i++, 2.5);
      ++n;
    }
    EXPECT_EQ(n, 26);
  }
}

TEST(StateRecognizerTransitions, CancellousDeadlineZeroDisablesIt) {
  RecognizerParams p = directParams();
  p.cancellous_deadline = 0;
  Direct rec(p);
  int i = 0;
  for (double f : {0.0, 3.0, 1.0}) rec.push(i++, f);
  for (int k = 0; k < 1000; ++k) rec.push(i++, 2.5);
  EXPECT_FALSE(rec.output().stop);
  EXPECT_EQ(rec.output().state, DrillingState::kOuterPunctured);
}

TEST(StateRecognizerTransitions, TheOuterLayerHasNoTimeInTheRecognizer) {
  // The outer layer's bound is geometric and lives in the planner (outer_cortical_max_mm, mm
  // of feed relative to the bone): the recognizer alone waits for Algorithm 2.
  RecognizerParams p = directParams();
  Direct rec(p);
  double f = 1.5;
  for (int k = 0; k < 1000; ++k, f += 0.01) rec.push(k, f);
  EXPECT_FALSE(rec.output().stop);
  EXPECT_EQ(rec.output().state, DrillingState::kOuterCortical);
}

// Drive to the cancellous state with direct parameters; returns next time index.
int toCancellous(Direct& rec) {
  int i = 0;
  for (double f : {0.0, 3.0, 1.0, 0.7, 0.7, 0.7, 0.7, 0.7, 0.7}) rec.push(i++, f);
  EXPECT_EQ(rec.output().state, DrillingState::kCancellous);
  return i;
}

TEST(StateRecognizerTransitions, InnerCorticalNeedsConfirmationAboveC2) {
  Direct rec(directParams());  // inner_confirm = 2, stop_delay = 0
  int i = toCancellous(rec);
  // A* for fbar = 1.7 (D = 3): 3 (0.567)^3 = 0.546 -> 0.655 < C2; for 1.8: 0.583*1.2 = 0.700 ~
  rec.push(i++, 1.7);
  EXPECT_EQ(rec.output().state, DrillingState::kCancellous);
  rec.push(i++, 2.4);  // single spike above C2
  rec.push(i++, 0.7);
  EXPECT_EQ(rec.output().state, DrillingState::kCancellous);
  EXPECT_FALSE(rec.output().stop);
  const int first = i;
  rec.push(i++, 2.0);
  EXPECT_FALSE(rec.output().stop);
  const RecognizerOutput& o = rec.push(i++, 2.2);
  EXPECT_EQ(o.layer_state, DrillingState::kInnerCortical);
  EXPECT_EQ(o.state, DrillingState::kStopped);  // stopped at once (stop_delay = 0)
  EXPECT_EQ(o.last_key_point, 4);
  EXPECT_EQ(o.key_points[3].index, rawIndex(first));
  EXPECT_TRUE(o.stop);
  EXPECT_EQ(o.stop_index, rawIndex(first + 1));
  EXPECT_DOUBLE_EQ(o.stop_t, first + 1.0);
}

TEST(StateRecognizerTransitions, StopDelayCountsAveragedSamples) {
  RecognizerParams p = directParams();
  p.stop_delay = 3;
  Direct rec(p);
  int i = toCancellous(rec);
  rec.push(i++, 2.5);
  rec.push(i++, 2.6);  // KP4 confirmed at i-1
  const int kp4 = i - 1;
  EXPECT_EQ(rec.output().last_key_point, 4);
  EXPECT_FALSE(rec.output().stop);
  rec.push(i++, 2.7);
  rec.push(i++, 2.8);
  EXPECT_FALSE(rec.output().stop);
  rec.push(i++, 2.9);
  EXPECT_TRUE(rec.output().stop);
  EXPECT_EQ(rec.output().stop_index, rawIndex(kp4 + 3));
}

TEST(StateRecognizerTransitions, PeakDropAndBreakthrough) {
  RecognizerParams p = directParams();
  p.stop_delay = 100;  // so that the KP5 fail-safe is what stops
  Direct rec(p);
  int i = toCancellous(rec);
  rec.push(i++, 2.5);
  rec.push(i++, 2.8);
  const int peak = i;
  rec.push(i++, 3.0);  // A* = 3.6 (saturated, gained)
  rec.push(i++, 2.9);  // A* = 3.25 >= 0.7 * 3.6 = 2.52
  EXPECT_EQ(rec.output().last_key_point, 4);
  EXPECT_FALSE(rec.output().stop);
  rec.push(i++, 2.6);  // A* = 2.35 < 2.52: puncturing starts
  EXPECT_EQ(rec.output().last_key_point, 5);
  EXPECT_EQ(rec.output().key_points[4].index, rawIndex(peak));
  EXPECT_TRUE(rec.output().stop);  // fail-safe stop at KP5
  EXPECT_EQ(rec.output().stop_index, rawIndex(i - 1));
  EXPECT_EQ(rec.output().stop_key_point, 5);
  EXPECT_EQ(rec.output().state, DrillingState::kStopped);
  EXPECT_EQ(rec.output().layer_state, DrillingState::kInnerCortical);
  rec.push(i++, 1.6);  // A* = 0.50*... = 0.455 >= C1 still
  EXPECT_EQ(rec.output().layer_state, DrillingState::kInnerCortical);
  rec.push(i++, 0.5);
  // The force shows the breakthrough (key point 6 is recorded for analysis), but the
  // recognizer's state stays "stopped" at the stop's key point.
  EXPECT_EQ(rec.output().layer_state, DrillingState::kBreakthrough);
  EXPECT_EQ(rec.output().state, DrillingState::kStopped);
  EXPECT_EQ(rec.output().last_key_point, 5);
  ASSERT_EQ(rec.output().num_key_points, 6);
  EXPECT_EQ(rec.output().key_points[5].index, rawIndex(i - 1));
  // Nothing more happens afterwards.
  for (int j = 0; j < 20; ++j) rec.push(i++, j % 2 ? 3.0 : 0.0);
  EXPECT_EQ(rec.output().num_key_points, 6);
  EXPECT_EQ(rec.output().layer_state, DrillingState::kBreakthrough);
  EXPECT_EQ(rec.output().state, DrillingState::kStopped);
}

TEST(StateRecognizerTransitions, StateSaysStoppedFromTheStopUntilReset) {
  RecognizerParams p = directParams();
  Direct rec(p);
  int i = toCancellous(rec);
  EXPECT_EQ(rec.output().state, DrillingState::kCancellous);
  while (!rec.output().stop && i < 10000) rec.push(i++, 3.0);
  ASSERT_TRUE(rec.output().stop);
  EXPECT_EQ(rec.output().stop_key_point, 4);
  EXPECT_EQ(rec.output().last_key_point, 4);
  EXPECT_EQ(rec.output().state, DrillingState::kStopped);
  EXPECT_STREQ(toString(rec.output().state), "stopped");
  EXPECT_NE(stopReason(rec.output()).find("stop after key point 4 (inner_cortical)"),
            std::string::npos)
      << stopReason(rec.output());
  // A retracting drill: the force falls to zero; the state must not follow it.
  for (int j = 0; j < 50; ++j) rec.push(i++, 0.0);
  EXPECT_EQ(rec.output().state, DrillingState::kStopped);
  EXPECT_EQ(rec.output().last_key_point, 4);
  rec.reset();
  EXPECT_EQ(rec.output().state, DrillingState::kIdle);
  EXPECT_EQ(rec.output().layer_state, DrillingState::kIdle);
  EXPECT_FALSE(rec.output().stop);
  EXPECT_EQ(rec.output().stop_key_point, 0);
  EXPECT_EQ(stopReason(rec.output()), "");
}

TEST(StateRecognizerProfile, TwoLayersAllKeyPointsAndStopInInnerLayer) {
  Profile prof;
  const RunResult r = runProfile(prof.samples());
  const RecognizerOutput& o = r.out;
  ASSERT_EQ(o.num_key_points, 6);
  for (int j = 0; j < 6; ++j) {
    EXPECT_EQ(o.key_points[j].id, j + 1);
    if (j > 0) {
      EXPECT_GT(o.key_points[j].index, o.key_points[j - 1].index);
    }
  }
  const auto t = [&](int id) { return o.key_points[id - 1].t; };
  EXPECT_GT(t(1), 2.0);
  EXPECT_LT(t(1), 4.5);
  EXPECT_GT(t(2), 5.0);
  EXPECT_LT(t(2), 6.5);
  EXPECT_LT(t(3), 8.0);
  EXPECT_GT(t(4), Profile::kInnerStart);
  EXPECT_LT(t(4), 18.5);
  EXPECT_GT(t(5), 17.5);
  EXPECT_LT(t(5), Profile::kInnerEnd);
  EXPECT_GT(t(6), Profile::kInnerPeakEnd);
  EXPECT_LT(t(6), 21.5);
  EXPECT_NEAR(o.d, 3.0, 0.15);
  ASSERT_TRUE(o.stop);
  // Stop inside the inner layer, before its force starts to fall, and between KP4 and KP6.
  EXPECT_GT(o.stop_t, Profile::kInnerStart);
  EXPECT_LT(o.stop_t, Profile::kInnerPeakEnd);
  EXPECT_GE(o.stop_index, o.key_points[3].index);
  EXPECT_LT(o.stop_index, o.key_points[5].index);
  const std::vector<DrillingState> expected = {
      DrillingState::kIdle,       DrillingState::kOuterCortical, DrillingState::kOuterPunctured,
      DrillingState::kCancellous, DrillingState::kInnerCortical, DrillingState::kBreakthrough};
  EXPECT_EQ(r.states, expected);
}

TEST(StateRecognizerProfile, OneLayerOnlyNeverStops) {
  Profile prof;
  prof.inner = false;
  const RunResult r = runProfile(prof.samples());
  EXPECT_FALSE(r.out.stop);
  EXPECT_EQ(r.out.last_key_point, 3);
  EXPECT_EQ(r.out.state, DrillingState::kCancellous);
}

TEST(StateRecognizerProfile, NoContactStaysIdle) {
  Profile prof;
  prof.f_out = 0.0;
  prof.f_canc = 0.0;
  prof.canc_ripple = 0.0;
  prof.inner = false;
  const RunResult r = runProfile(prof.samples());
  EXPECT_EQ(r.out.state, DrillingState::kIdle);
  EXPECT_EQ(r.out.num_key_points, 0);
  EXPECT_FALSE(r.out.stop);
}

TEST(StateRecognizerProfile, NoiseRobustnessOverSeeds) {
  for (unsigned seed = 1; seed <= 20; ++seed) {
    Profile prof;
    prof.seed = seed;
    prof.noise = 1.0;  // raw sigma 1 N, i.e. a third of the cortical peak
    prof.canc_ripple = 0.3;
    const RunResult r = runProfile(prof.samples());
    ASSERT_EQ(r.out.num_key_points, 6) << "seed " << seed;
    ASSERT_TRUE(r.out.stop) << "seed " << seed;
    EXPECT_GT(r.out.stop_t, Profile::kInnerStart) << "seed " << seed;
    EXPECT_LT(r.out.stop_t, Profile::kInnerPeakEnd) << "seed " << seed;
    Profile one = prof;
    one.inner = false;
    EXPECT_FALSE(runProfile(one.samples()).out.stop) << "seed " << seed;
  }
}

TEST(StateRecognizerProfile, WeakerInnerLayerStillStops) {
  // Fig. 17 stationary case: F_out = 3.6 N, F_in = 3.0 N.
  Profile prof;
  prof.f_out = 3.6;
  prof.f_in = 3.0;
  const RunResult r = runProfile(prof.samples());
  ASSERT_TRUE(r.out.stop);
  EXPECT_GT(r.out.stop_t, Profile::kInnerStart);
  EXPECT_LT(r.out.stop_t, Profile::kInnerPeakEnd);
}

TEST(StateRecognizerProfile, NormalisedFeatureMissesWeakerInnerLayer) {
  // Documents why A is NOT normalised by D by default: with A in [0, 1] the same C2 = 0.7
  // requires the inner peak to reach 0.84 of the outer one, and 3.0 / 3.6 = 0.83 does not.
  Profile prof;
  prof.f_out = 3.6;
  prof.f_in = 3.0;
  prof.noise = 0.0;
  prof.canc_ripple = 0.0;
  RecognizerParams p = profileParams();
  p.normalize_feature = true;
  const RunResult r = runProfile(prof.samples(), p);
  EXPECT_FALSE(r.out.stop);
  EXPECT_EQ(r.out.last_key_point, 3);
}

TEST(StateRecognizerProfile, ResetForgetsEverything) {
  Profile prof;
  const std::vector<double> f = prof.samples();
  StateRecognizer rec(profileParams());
  for (std::size_t i = 0; i < f.size(); ++i) rec.push(i / kRate, f[i]);
  ASSERT_TRUE(rec.output().stop);
  rec.reset();
  EXPECT_FALSE(rec.output().stop);
  EXPECT_EQ(rec.output().num_key_points, 0);
  EXPECT_EQ(rec.output().state, DrillingState::kIdle);
  for (std::size_t i = 0; i < f.size(); ++i) rec.push(i / kRate, f[i]);
  EXPECT_EQ(rec.output().num_key_points, 6);
}

TEST(StateRecognizerInput, NonFiniteThrows) {
  StateRecognizer rec;
  EXPECT_THROW(rec.push(0.0, std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
  EXPECT_THROW(rec.push(std::numeric_limits<double>::infinity(), 1.0), std::invalid_argument);
}

void expectInvalid(const RecognizerParams& p, const std::string& name) {
  try {
    p.validate();
    ADD_FAILURE() << "validate() accepted bad " << name;
  } catch (const std::invalid_argument& e) {
    // "<name> = <value> is out of range ..." or "<name>: <rule>".
    const std::string what = e.what();
    EXPECT_TRUE(what.rfind(name + " ", 0) == 0 || what.rfind(name + ":", 0) == 0) << what;
  }
  EXPECT_THROW(StateRecognizer rec(p), std::invalid_argument);
}

TEST(RecognizerParamsTest, DefaultsAreValidAndFromPaper) {
  RecognizerParams p;
  EXPECT_NO_THROW(p.validate());
  EXPECT_DOUBLE_EQ(p.pre_average_s, 0.15);
  EXPECT_DOUBLE_EQ(p.sensor_rate_hz, 1000.0 / 3.0);
  EXPECT_EQ(p.blockSamples(), 50);  // the paper's fifty (Sec. V-E) at the simulated DAQ
  EXPECT_EQ(p.window, 10);
  EXPECT_DOUBLE_EQ(p.gain, 1.2);
  EXPECT_DOUBLE_EQ(p.h_g, 0.5);
  EXPECT_DOUBLE_EQ(p.c1, 0.4);
  EXPECT_DOUBLE_EQ(p.c2, 0.7);
  EXPECT_DOUBLE_EQ(p.c3, 0.7);
}

TEST(RecognizerParamsTest, EachBadParameterIsNamed) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const auto bad = [](const std::string& name, auto mutate) {
    RecognizerParams p;
    mutate(p);
    expectInvalid(p, name);
  };
  bad("pre_average_s", [](RecognizerParams& p) { p.pre_average_s = 0.0; });
  bad("pre_average_s", [nan](RecognizerParams& p) { p.pre_average_s = nan; });
  bad("pre_average_s", [](RecognizerParams& p) { p.pre_average_s = 11.0; });
  bad("sensor_rate_hz", [](RecognizerParams& p) { p.sensor_rate_hz = 0.0; });
  bad("sensor_rate_hz", [](RecognizerParams& p) { p.sensor_rate_hz = -1000.0; });
  bad("sensor_rate_hz", [](RecognizerParams& p) { p.sensor_rate_hz = 2e5; });
  bad("window", [](RecognizerParams& p) { p.window = 0; });
  bad("k_ratio", [](RecognizerParams& p) { p.k_ratio = 1.0; });
  bad("k_ratio", [](RecognizerParams& p) { p.k_ratio = 0.0; });
  bad("k_ratio", [nan](RecognizerParams& p) { p.k_ratio = nan; });
  bad("f_th", [](RecognizerParams& p) { p.f_th = 0.0; });
  bad("f_th", [nan](RecognizerParams& p) { p.f_th = nan; });
  bad("gain", [](RecognizerParams& p) { p.gain = 0.9; });
  bad("h_g", [](RecognizerParams& p) { p.h_g = -0.1; });
  bad("c1", [](RecognizerParams& p) { p.c1 = 0.0; });
  bad("c2", [](RecognizerParams& p) { p.c2 = 0.3; });
  bad("c3", [](RecognizerParams& p) { p.c3 = 1.0; });
  bad("c3", [](RecognizerParams& p) { p.c3 = std::numeric_limits<double>::infinity(); });
  bad("cancellous_confirm", [](RecognizerParams& p) { p.cancellous_confirm = 0; });
  bad("cancellous_deadline", [](RecognizerParams& p) { p.cancellous_deadline = -1; });
  bad("cancellous_deadline", [](RecognizerParams& p) { p.cancellous_deadline = 14; });
  bad("inner_confirm", [](RecognizerParams& p) { p.inner_confirm = 0; });
  bad("stop_delay", [](RecognizerParams& p) { p.stop_delay = -1; });
}

TEST(RecognizerBlock, TheBlockIsItsDurationAtTheDeclaredRateRoundedToTheNearestSample) {
  RecognizerParams p;
  const auto samples = [&p](double seconds, double rate_hz) {
    p.pre_average_s = seconds;
    p.sensor_rate_hz = rate_hz;
    return p.blockSamples();
  };
  // The paper's fifty: 0.15 s at the simulated 1000/3 Hz, and at the rates a launch line or a
  // parameter file writes for it.
  EXPECT_EQ(samples(0.15, 1000.0 / 3.0), 50);
  EXPECT_EQ(samples(0.15, 333.3333333), 50);
  EXPECT_EQ(samples(0.15, 333.333), 50);
  // A lab's sensors: the same 0.15 s.
  EXPECT_EQ(samples(0.15, 1000.0), 150);
  EXPECT_EQ(samples(0.15, 7000.0), 1050);
  EXPECT_EQ(samples(0.15, 100.0), 15);
  // To the nearest sample, halves away from zero (0.125 s x 100 Hz = 12.5 exactly).
  EXPECT_EQ(samples(0.125, 100.0), 13);
  EXPECT_EQ(samples(0.124, 100.0), 12);
  EXPECT_EQ(samples(0.126, 100.0), 13);
}

TEST(RecognizerBlock, ABlockTooShortOrTooRoundedAtTheDeclaredRateIsRefusedNamingIt) {
  const auto error = [](double seconds, double rate_hz) {
    RecognizerParams p;
    p.pre_average_s = seconds;
    p.sensor_rate_hz = rate_hz;
    try {
      p.validate();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  // Fewer than 2 samples: 0.003 s at 1000/3 Hz is 1 sample.
  const std::string one = error(0.003, 1000.0 / 3.0);
  EXPECT_EQ(one.rfind("pre_average_s: ", 0), 0u) << one;
  EXPECT_NE(one.find("sensor_rate_hz 333.333 Hz"), std::string::npos) << one;
  EXPECT_NE(one.find("at least 2 samples"), std::string::npos) << one;
  EXPECT_NE(error(0.0045, 1000.0 / 3.0), "");  // 1.5 rounds to 2, but 33 % longer
  EXPECT_EQ(error(0.006, 1000.0 / 3.0), "");   // 2 samples exactly
  // The rounded block more than 10 % from the duration: 2.4 samples -> 2 (0.2 s for 0.24 s).
  const std::string rounded = error(0.24, 10.0);
  EXPECT_EQ(rounded.rfind("pre_average_s: ", 0), 0u) << rounded;
  EXPECT_NE(rounded.find("more than 10 %"), std::string::npos) << rounded;
  EXPECT_NE(error(0.45, 10.0), "");  // 4.5 -> 5: 11 % longer
  EXPECT_EQ(error(0.55, 10.0), "");  // 5.5 -> 6: 9 % longer
  // At most 100000 samples.
  EXPECT_NE(error(10.0, 100000.0).find("at most 100000"), std::string::npos);
  EXPECT_EQ(error(1.0, 100000.0), "");
  // A bad rate is named as the rate.
  EXPECT_EQ(error(0.15, 0.0).rfind("sensor_rate_hz", 0), 0u);
}

TEST(RecognizerBlock, TheOldSampleCountIsRefusedNamingTheNewParameters) {
  RecognizerParams p;
  try {
    p.set("pre_average", "50");
    ADD_FAILURE() << "pre_average accepted";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("pre_average is retired: ", 0), 0u) << what;
    EXPECT_NE(what.find("pre_average_s"), std::string::npos) << what;
    EXPECT_NE(what.find("sensor_rate_hz"), std::string::npos) << what;
  }
  // Not a declared parameter (the documents list the new ones only).
  EXPECT_EQ(RecognizerParams::table().find("pre_average"), nullptr);
  ASSERT_NE(RecognizerParams::table().retiredWhy("pre_average"), nullptr);
  p.set("pre_average_s", "0.3");
  p.set("sensor_rate_hz", "1000");
  EXPECT_EQ(p.blockSamples(), 300);
}

TEST(RecognizerBlock, TheSameFilterInTimeAtEveryDeclaredRate) {
  // One noise-free profile sampled at 1000/3 Hz and at 1 kHz, each recognizer declared at its
  // rate with the default 0.15 s: the blocks end at the same times (every 0.15 s), and the key
  // points and the stop come within one block of each other (the block means differ a little:
  // other samples of the same force).
  Profile prof;
  prof.noise = 0.0;
  const auto run = [&prof](double rate_hz) {
    RecognizerParams p;
    p.sensor_rate_hz = rate_hz;
    StateRecognizer rec(p);
    const int n = static_cast<int>(Profile::kEnd * rate_hz);
    std::vector<double> block_ends;
    for (int i = 0; i < n; ++i) {
      const double t = (i + 1) / rate_hz;
      if (rec.push(t, prof.clean(t)).new_average) block_ends.push_back(t);
    }
    return std::make_pair(rec.output(), block_ends);
  };
  const auto [slow, slow_ends] = run(1000.0 / 3.0);
  const auto [fast, fast_ends] = run(1000.0);
  ASSERT_GE(slow_ends.size(), 100u);
  ASSERT_EQ(slow_ends.size(), fast_ends.size());
  for (std::size_t i = 0; i < slow_ends.size(); ++i) {
    EXPECT_NEAR(slow_ends[i], 0.15 * static_cast<double>(i + 1), 1e-9) << i;
    EXPECT_NEAR(fast_ends[i], slow_ends[i], 1e-9) << i;
  }
  ASSERT_TRUE(slow.stop);
  ASSERT_TRUE(fast.stop);
  EXPECT_NEAR(fast.stop_t, slow.stop_t, 0.15 + 1e-9);
  ASSERT_EQ(fast.num_key_points, slow.num_key_points);
  for (int j = 0; j < slow.num_key_points; ++j) {
    EXPECT_NEAR(fast.key_points[j].t, slow.key_points[j].t, 0.15 + 1e-9) << "key point " << j + 1;
  }
}

TEST(RecognizerParamsTest, SetByName) {
  RecognizerParams p;
  p.set("k_ratio", "0.6");
  p.set("window", "12");
  p.set("normalize_feature", "true");
  EXPECT_DOUBLE_EQ(p.k_ratio, 0.6);
  EXPECT_EQ(p.window, 12);
  EXPECT_TRUE(p.normalize_feature);
  EXPECT_THROW(p.set("bogus", "1"), std::invalid_argument);
  EXPECT_THROW(p.set("window", "1.5"), std::invalid_argument);
  EXPECT_THROW(p.set("c1", "abc"), std::invalid_argument);
  try {
    p.set("c2", "");
    ADD_FAILURE();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("c2"), std::string::npos);
  }
}

}  // namespace
}  // namespace pedicle_drilling::core
