// Unit tests of wavelet de-noising, the Eq. 2-3 metrics and the basis selection
// (denoising.hpp).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/denoising.hpp"
#include "pedicle_drilling/core/breathing/dwt.hpp"
#include "pedicle_drilling/core/breathing/wavelet.hpp"

namespace pedicle_drilling::core {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kFs = 8.0;  // displacement sampling rate (paper Sec. III-A)

/// Portable deterministic generator (PCG-style LCG + Box-Muller); not std::normal_distribution,
/// whose output is implementation-defined.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : state_(seed * 2862933555777941757ULL + 3037000493ULL) {}
  double uniform() {
    state_ = state_ * 6364136223846793005ULL + 1442695040888963407ULL;
    return (static_cast<double>(state_ >> 11) + 0.5) / 9007199254740992.0;  // (0, 1)
  }
  double normal() {
    const double u1 = uniform();
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
  }

 private:
  std::uint64_t state_;
};

/// Synthetic breathing: 30 s at 8 Hz, 20 /min, tidal volume 0..500 ml, displacement
/// proportional to Tv (2 mm at 500 ml) on top of a DC offset, plus white noise.
struct Breathing {
  std::vector<double> tv;     // ml
  std::vector<double> truth;  // mm, zero-mean breathing component
  std::vector<double> raw;    // mm, offset + truth + noise
};

Breathing makeBreathing(std::size_t n, double noise_sigma, double offset, std::uint64_t seed) {
  Rng rng(seed);
  Breathing b;
  const double f_breath = 20.0 / 60.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / kFs;
    const double tv = 250.0 * (1.0 - std::cos(2.0 * kPi * f_breath * t));
    b.tv.push_back(tv);
    b.truth.push_back(2.0 * (tv - 250.0) / 500.0);
    b.raw.push_back(offset + b.truth.back() + noise_sigma * rng.normal());
  }
  return b;
}

double mean(const std::vector<double>& v) {
  return std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

/// RMS of (a - mean(a)) - (b - mean(b)) over samples [skip, n - skip).
double rmsCentredError(const std::vector<double>& a, const std::vector<double>& b,
                       std::size_t skip) {
  const double ma = mean(a);
  const double mb = mean(b);
  double acc = 0.0;
  std::size_t count = 0;
  for (std::size_t i = skip; i + skip < a.size(); ++i) {
    const double e = (a[i] - ma) - (b[i] - mb);
    acc += e * e;
    ++count;
  }
  return std::sqrt(acc / static_cast<double>(count));
}

TEST(Denoise, DefaultOptionsFollowThePaper) {
  const DenoiseOptions o;
  EXPECT_EQ(o.candidates.size(), 59U);
  EXPECT_EQ(o.candidates, allWaveletNames());
  EXPECT_EQ(o.level, 6);
  EXPECT_EQ(o.kept_levels, (std::vector<int>{3, 4, 5}));
  EXPECT_FALSE(o.include_approximation);
  EXPECT_EQ(o.mode, ExtensionMode::kSymmetric);
  EXPECT_DOUBLE_EQ(o.delta_tv, 5.0);
  for (double w : o.weights) {
    EXPECT_DOUBLE_EQ(w, 1.0 / 3.0);
  }
}

TEST(Denoise, IsTheSumOfKeptLevels) {
  const Breathing b = makeBreathing(240, 0.3, 10.0, 1);
  const Wavelet& w = getWavelet("db5");
  const WaveletDecomposition dec = wavedec(b.raw, w, 6);
  const std::vector<double> s_de = denoise(b.raw, w);  // defaults: level 6, d3 + d4 + d5
  ASSERT_EQ(s_de.size(), b.raw.size());
  const std::vector<double> d3 = waverecSelected(dec, {3}, false);
  const std::vector<double> d4 = waverecSelected(dec, {4}, false);
  const std::vector<double> d5 = waverecSelected(dec, {5}, false);
  for (std::size_t i = 0; i < s_de.size(); ++i) {
    EXPECT_NEAR(s_de[i], d3[i] + d4[i] + d5[i], 1e-12) << i;
  }
  // Name overload and approximation option.
  EXPECT_EQ(denoise(b.raw, std::string("db5")), s_de);
  const std::vector<double> with_a = denoise(b.raw, w, 6, {3, 4, 5}, true);
  const std::vector<double> a6 = waverecSelected(dec, {}, true);
  for (std::size_t i = 0; i < s_de.size(); ++i) {
    EXPECT_NEAR(with_a[i], s_de[i] + a6[i], 1e-12) << i;
  }
}

TEST(Denoise, SyntheticBreathingErrorIsReduced) {
  // 30 s at 8 Hz (240 samples), breathing 20 /min of +-1 mm, white noise sigma 0.3 mm,
  // DC offset 10 mm. d4 = [Fs/32, Fs/16] = [0.25, 0.5] Hz contains the 0.33 Hz breathing.
  const Breathing b = makeBreathing(240, 0.3, 10.0, 42);
  for (const char* name : {"db5", "coif4", "bior2.8", "coif5"}) {
    const std::vector<double> s_de = denoise(b.raw, getWavelet(name));
    const double err_raw = rmsCentredError(b.raw, b.truth, 0);
    const double err_de = rmsCentredError(s_de, b.truth, 0);
    // About 22 % of white-noise power lies in d3 + d4 + d5 (1/8 + 1/16 + 1/32), so the noise
    // RMS drops to ~0.14 mm; band-splitting distorts the breathing by 0.02-0.09 mm RMS
    // depending on the basis (db5 worst). Measured ratios are about 0.5-0.65 (db5 worst).
    EXPECT_LT(err_de, 0.7 * err_raw) << name << ": raw " << err_raw << ", denoised " << err_de;
    EXPECT_LT(rmsCentredError(s_de, b.truth, 24), 0.7 * rmsCentredError(b.raw, b.truth, 24))
        << name;
    // d3 + d4 + d5 drops the approximation: the 10 mm DC offset is removed (documented).
    EXPECT_LT(std::abs(mean(s_de)), 0.1) << name;
    EXPECT_GT(mean(b.raw), 9.5);
  }
}

TEST(Denoise, InvalidArguments) {
  const std::vector<double> x(64, 1.0);
  const Wavelet& w = getWavelet("db4");
  EXPECT_THROW(denoise({}, w), std::invalid_argument);
  EXPECT_THROW(denoise(x, w, 0), std::invalid_argument);
  EXPECT_THROW(denoise(x, w, 6, {7}), std::invalid_argument);
  EXPECT_THROW(denoise(x, w, 6, {0}), std::invalid_argument);
  EXPECT_THROW(denoise(x, w, 6, {3, 3}), std::invalid_argument);
  EXPECT_THROW(denoise(x, w, 6, {}, false), std::invalid_argument);
  EXPECT_NO_THROW(denoise(x, w, 6, {}, true));
  EXPECT_THROW(denoise(x, std::string("db0")), std::invalid_argument);
  std::vector<double> bad = x;
  bad[10] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(denoise(bad, w), std::invalid_argument);
}

TEST(Metrics, NoiseToSignalRatioByHand) {
  // s_de = [1, 1, 3, 3]: mean 2, var 1. residual s - s_de = [0, 1, 0, 1]: var 0.25.
  EXPECT_DOUBLE_EQ(noiseToSignalRatio({1, 2, 3, 4}, {1, 1, 3, 3}), 0.25);
  // Invariant to a DC offset between s and s_de (as removed by d3 + d4 + d5).
  EXPECT_DOUBLE_EQ(noiseToSignalRatio({101, 102, 103, 104}, {1, 1, 3, 3}), 0.25);
  // Perfect de-noising -> 0; constant s_de -> +inf.
  EXPECT_DOUBLE_EQ(noiseToSignalRatio({1, 1, 3, 3}, {1, 1, 3, 3}), 0.0);
  EXPECT_TRUE(std::isinf(noiseToSignalRatio({1, 2, 3}, {0, 0, 0})));
  EXPECT_THROW(noiseToSignalRatio({1, 2}, {1}), std::invalid_argument);
  EXPECT_THROW(noiseToSignalRatio({}, {}), std::invalid_argument);
}

TEST(Metrics, TidalVolumeSpreadByHand) {
  // Tv = [0, 1, 10, 11, 30], s_de = [1, 3, 5, 2, 7], dTv = 1.5:
  // U_0 = U_1 = {0, 1} -> L = 3 - 1 = 2; U_2 = U_3 = {2, 3} -> L = 5 - 2 = 3; U_4 = {4} has
  // a single sample and is ignored. W_max = 3, W_mean = (2 + 2 + 3 + 3) / 4 = 2.5.
  const std::vector<double> tv = {0, 1, 10, 11, 30};
  const std::vector<double> s = {1, 3, 5, 2, 7};
  DenoiseMetrics m = tidalVolumeSpread(s, tv, 1.5);
  EXPECT_DOUBLE_EQ(m.w_max, 3.0);
  EXPECT_DOUBLE_EQ(m.w_mean, 2.5);
  EXPECT_EQ(m.neighbourhoods, 4U);
  // The neighbourhood is closed: |Tv_k - Tv_i| <= dTv with dTv = 1 gives the same sets.
  m = tidalVolumeSpread(s, tv, 1.0);
  EXPECT_EQ(m.neighbourhoods, 4U);
  EXPECT_DOUBLE_EQ(m.w_mean, 2.5);
  // dTv = 0.5: no neighbourhood with two samples.
  m = tidalVolumeSpread(s, tv, 0.5);
  EXPECT_EQ(m.neighbourhoods, 0U);
  EXPECT_DOUBLE_EQ(m.w_max, 0.0);
  EXPECT_DOUBLE_EQ(m.w_mean, 0.0);
  // dTv = 10: U_0 = {0, 1, 2}: 5 - 1 = 4; U_1 = {0..3}: 4; U_2 = {0..3}: 4;
  // U_3 = {1, 2, 3} (|0 - 11| > 10): 5 - 2 = 3; U_4 = {4}: ignored.
  // W_max = 4, W_mean = 15 / 4.
  m = tidalVolumeSpread(s, tv, 10.0);
  EXPECT_EQ(m.neighbourhoods, 4U);
  EXPECT_DOUBLE_EQ(m.w_max, 4.0);
  EXPECT_DOUBLE_EQ(m.w_mean, 3.75);
  // Equal Tv values (exact repeats) form a neighbourhood even with dTv = 0.
  m = tidalVolumeSpread({1.0, 4.0, 2.0}, {5.0, 5.0, 7.0}, 0.0);
  EXPECT_EQ(m.neighbourhoods, 2U);
  EXPECT_DOUBLE_EQ(m.w_max, 3.0);
  EXPECT_DOUBLE_EQ(m.w_mean, 3.0);

  const DenoiseMetrics all = computeDenoiseMetrics({2, 3, 6, 2, 8}, s, tv, 1.5);
  EXPECT_DOUBLE_EQ(all.w_max, 3.0);
  EXPECT_DOUBLE_EQ(all.nsr, noiseToSignalRatio({2, 3, 6, 2, 8}, s));

  EXPECT_THROW(tidalVolumeSpread(s, {1, 2}, 1.0), std::invalid_argument);
  EXPECT_THROW(tidalVolumeSpread(s, tv, -1.0), std::invalid_argument);
  EXPECT_THROW(tidalVolumeSpread(s, {0, 1, std::nan(""), 3, 4}, 1.0), std::invalid_argument);
}

TEST(Metrics, TidalVolumeSpreadMatchesBruteForce) {
  Rng rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const std::size_t n = 50 + 37 * static_cast<std::size_t>(trial);
    std::vector<double> tv(n);
    std::vector<double> s(n);
    for (std::size_t i = 0; i < n; ++i) {
      // Quantised Tv so that exact ties occur.
      tv[i] = std::round(rng.uniform() * 100.0) * 5.0;
      s[i] = rng.normal();
    }
    const double dtv = 2.5 + 5.0 * (trial % 4);
    double w_max = 0.0;
    double sum = 0.0;
    std::size_t count = 0;
    for (std::size_t i = 0; i < n; ++i) {
      double lo = std::numeric_limits<double>::infinity();
      double hi = -lo;
      std::size_t members = 0;
      for (std::size_t k = 0; k < n; ++k) {
        if (std::abs(tv[k] - tv[i]) <= dtv) {
          lo = std::min(lo, s[k]);
          hi = std::max(hi, s[k]);
          ++members;
        }
      }
      if (members >= 2) {
        w_max = std::max(w_max, hi - lo);
        sum += hi - lo;
        ++count;
      }
    }
    const DenoiseMetrics m = tidalVolumeSpread(s, tv, dtv);
    EXPECT_EQ(m.neighbourhoods, count) << trial;
    EXPECT_DOUBLE_EQ(m.w_max, w_max) << trial;
    EXPECT_NEAR(m.w_mean, count ? sum / static_cast<double>(count) : 0.0, 1e-12) << trial;
  }
}

CandidateScore row(const std::string& name, double nsr, double w_max, double w_mean) {
  CandidateScore r;
  r.wavelet = name;
  r.nsr = nsr;
  r.w_max = w_max;
  r.w_mean = w_mean;
  return r;
}

TEST(Selection, MinMaxNormalisedWeightedSumByHand) {
  // Columns: NSR in [0.1, 0.3], W_max in [1, 3], W_mean in [1, 2].
  // A: (0, 1, 1); B: (1, 0, 0); C: (0.5, 0.5, 0.5) after min-max normalisation.
  std::vector<CandidateScore> rows = {row("A", 0.1, 3.0, 2.0), row("B", 0.3, 1.0, 1.0),
                                      row("C", 0.2, 2.0, 1.5)};
  std::size_t best = scoreCandidates(&rows, {1.0 / 3, 1.0 / 3, 1.0 / 3});
  EXPECT_EQ(best, 1U);  // B: 1/3 < C: 1/2 < A: 2/3
  EXPECT_DOUBLE_EQ(rows[0].nsr_norm, 0.0);
  EXPECT_DOUBLE_EQ(rows[0].w_max_norm, 1.0);
  EXPECT_DOUBLE_EQ(rows[0].w_mean_norm, 1.0);
  EXPECT_NEAR(rows[2].nsr_norm, 0.5, 1e-15);
  EXPECT_NEAR(rows[0].score, 2.0 / 3.0, 1e-15);
  EXPECT_NEAR(rows[1].score, 1.0 / 3.0, 1e-15);
  EXPECT_NEAR(rows[2].score, 0.5, 1e-15);
  // Weights change the choice: only NSR -> A.
  best = scoreCandidates(&rows, {1.0, 0.0, 0.0});
  EXPECT_EQ(best, 0U);
  EXPECT_DOUBLE_EQ(rows[0].score, 0.0);
  // NSR weighted 0.6, spreads 0.2 each: A 0.4, B 0.6, C 0.5 -> A.
  best = scoreCandidates(&rows, {0.6, 0.2, 0.2});
  EXPECT_EQ(best, 0U);
  // Weights need not sum to one: scaling them does not change the choice.
  EXPECT_EQ(scoreCandidates(&rows, {3.0, 1.0, 1.0}), 0U);
}

TEST(Selection, ConstantColumnsInfinityAndTies) {
  // W_max and W_mean constant -> normalised to 0; NSR = inf -> normalised to 1.
  std::vector<CandidateScore> rows = {row("inf", std::numeric_limits<double>::infinity(), 1, 1),
                                      row("x", 0.5, 1, 1), row("y", 0.5, 1, 1)};
  const std::size_t best = scoreCandidates(&rows, {1.0, 1.0, 1.0});
  EXPECT_DOUBLE_EQ(rows[0].nsr_norm, 1.0);
  EXPECT_DOUBLE_EQ(rows[1].nsr_norm, 0.0);
  EXPECT_DOUBLE_EQ(rows[1].w_max_norm, 0.0);
  EXPECT_EQ(best, 1U);  // tie between x and y -> first
  std::vector<CandidateScore> empty;
  EXPECT_THROW(scoreCandidates(&empty, {1, 1, 1}), std::invalid_argument);
  EXPECT_THROW(scoreCandidates(&rows, {-1, 1, 1}), std::invalid_argument);
  EXPECT_THROW(scoreCandidates(&rows, {0, 0, 0}), std::invalid_argument);
}

TEST(Selection, ChoosesMinimumOfWeightedSumOnBreathingData) {
  const Breathing b = makeBreathing(240, 0.2, 10.0, 5);
  DenoiseOptions options;
  options.candidates = {"db1", "db5", "sym8", "coif4", "coif5", "bior2.8", "bior3.1"};
  const BasisSelection sel = selectWaveletBasis(b.raw, b.tv, options);
  ASSERT_EQ(sel.candidates.size(), options.candidates.size());
  // The table holds the metrics of each candidate, recomputed independently here.
  double nsr_lo = 1e300, nsr_hi = -1e300, wmax_lo = 1e300, wmax_hi = -1e300;
  double wmean_lo = 1e300, wmean_hi = -1e300;
  for (std::size_t i = 0; i < sel.candidates.size(); ++i) {
    const CandidateScore& r = sel.candidates[i];
    EXPECT_EQ(r.wavelet, options.candidates[i]);
    const std::vector<double> s_de = denoise(b.raw, getWavelet(r.wavelet));
    const DenoiseMetrics m = computeDenoiseMetrics(b.raw, s_de, b.tv, 5.0);
    EXPECT_DOUBLE_EQ(r.nsr, m.nsr);
    EXPECT_DOUBLE_EQ(r.w_max, m.w_max);
    EXPECT_DOUBLE_EQ(r.w_mean, m.w_mean);
    EXPECT_GT(r.neighbourhoods, 100U);
    nsr_lo = std::min(nsr_lo, r.nsr);
    nsr_hi = std::max(nsr_hi, r.nsr);
    wmax_lo = std::min(wmax_lo, r.w_max);
    wmax_hi = std::max(wmax_hi, r.w_max);
    wmean_lo = std::min(wmean_lo, r.w_mean);
    wmean_hi = std::max(wmean_hi, r.w_mean);
  }
  std::size_t argmin = 0;
  std::vector<double> scores;
  for (const CandidateScore& r : sel.candidates) {
    const double s =
        ((r.nsr - nsr_lo) / (nsr_hi - nsr_lo) + (r.w_max - wmax_lo) / (wmax_hi - wmax_lo) +
         (r.w_mean - wmean_lo) / (wmean_hi - wmean_lo)) /
        3.0;
    EXPECT_NEAR(r.score, s, 1e-12) << r.wavelet;
    scores.push_back(s);
  }
  argmin =
      static_cast<std::size_t>(std::min_element(scores.begin(), scores.end()) - scores.begin());
  EXPECT_EQ(sel.chosen_index, argmin);
  EXPECT_EQ(sel.wavelet, sel.candidates[argmin].wavelet);

  // selectAndDenoise returns the chosen basis and its de-noised signal.
  const DenoiseResult res = selectAndDenoise(b.raw, b.tv, options);
  EXPECT_EQ(res.wavelet, sel.wavelet);
  EXPECT_EQ(res.denoised, denoise(b.raw, getWavelet(sel.wavelet)));
  EXPECT_DOUBLE_EQ(res.nsr, sel.candidates[argmin].nsr);
  EXPECT_DOUBLE_EQ(res.w_max, sel.candidates[argmin].w_max);
  EXPECT_DOUBLE_EQ(res.w_mean, sel.candidates[argmin].w_mean);
  ASSERT_EQ(res.candidates.size(), sel.candidates.size());
  // The chosen signal tracks the truth better than the raw data.
  EXPECT_LT(rmsCentredError(res.denoised, b.truth, 0), rmsCentredError(b.raw, b.truth, 0));

  // Weight only on NSR: the chosen candidate has the smallest NSR.
  options.weights = {1.0, 0.0, 0.0};
  const BasisSelection by_nsr = selectWaveletBasis(b.raw, b.tv, options);
  for (const CandidateScore& r : by_nsr.candidates) {
    EXPECT_LE(by_nsr.candidates[by_nsr.chosen_index].nsr, r.nsr);
  }
}

TEST(Selection, DefaultCandidatesAndErrors) {
  const Breathing b = makeBreathing(240, 0.2, 0.0, 9);
  const DenoiseResult res = selectAndDenoise(b.raw, b.tv, DenoiseOptions());
  EXPECT_EQ(res.candidates.size(), 59U);
  EXPECT_NE(findWavelet(res.wavelet), nullptr);
  EXPECT_EQ(res.denoised.size(), b.raw.size());

  DenoiseOptions options;
  options.candidates = {"db5", "nosuch"};
  try {
    selectAndDenoise(b.raw, b.tv, options);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("nosuch"), std::string::npos);
  }
  options = DenoiseOptions();
  EXPECT_THROW(selectAndDenoise(b.raw, {1.0, 2.0}, options), std::invalid_argument);
  EXPECT_THROW(selectAndDenoise({}, {}, options), std::invalid_argument);
  options.candidates.clear();
  EXPECT_THROW(selectAndDenoise(b.raw, b.tv, options), std::invalid_argument);
  options = DenoiseOptions();
  options.kept_levels = {3, 7};
  EXPECT_THROW(selectAndDenoise(b.raw, b.tv, options), std::invalid_argument);
  options = DenoiseOptions();
  options.delta_tv = -1.0;
  EXPECT_THROW(selectAndDenoise(b.raw, b.tv, options), std::invalid_argument);
  options = DenoiseOptions();
  options.weights = {0.0, 0.0, 0.0};
  EXPECT_THROW(selectAndDenoise(b.raw, b.tv, options), std::invalid_argument);
  std::vector<double> bad = b.raw;
  bad[3] = std::numeric_limits<double>::infinity();
  EXPECT_THROW(selectAndDenoise(bad, b.tv, DenoiseOptions()), std::invalid_argument);
}

}  // namespace
}  // namespace pedicle_drilling::core
