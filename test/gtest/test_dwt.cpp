// Unit tests of the wavelet filter banks and the DWT (wavelet.hpp, dwt.hpp).
// Agreement with PyWavelets itself is tested in test/python/test_dwt_vs_pywt.py.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/dwt.hpp"
#include "pedicle_drilling/core/breathing/wavelet.hpp"

namespace pedicle_drilling::core {
namespace {

const double kSqrt2 = std::sqrt(2.0);

// PyWavelets' tabulated coefficients of some wavelets (the higher Symlets in particular) are
// accurate to about 1e-11 only, so filter identities hold to ~1e-11 and pywt itself
// reconstructs sym20 (N = 240, level 6) with a 1.03e-10 error. Tolerances below reflect that;
// the DWT arithmetic itself is tested against hand values at 1e-14.
const double kFilterTol = 1e-10;
const double kReconstructionTol = 5e-10;

/// Deterministic pseudo-random signal in [-1, 1] plus a slow sine (portable LCG).
std::vector<double> testSignal(std::size_t n, std::uint64_t seed) {
  std::vector<double> x(n);
  std::uint64_t state = seed * 6364136223846793005ULL + 1442695040888963407ULL;
  for (std::size_t i = 0; i < n; ++i) {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    const double u = static_cast<double>(state >> 11) / 9007199254740992.0;  // [0, 1)
    x[i] = 2.0 * u - 1.0 + std::sin(0.05 * static_cast<double>(i));
  }
  return x;
}

double maxAbsDiff(const std::vector<double>& a, const std::vector<double>& b) {
  EXPECT_EQ(a.size(), b.size());
  double m = 0.0;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    m = std::max(m, std::abs(a[i] - b[i]));
  }
  return m;
}

double energy(const std::vector<double>& v) {
  return std::inner_product(v.begin(), v.end(), v.begin(), 0.0);
}

TEST(Wavelet, AllFamiliesPresent) {
  const std::vector<std::string> names = allWaveletNames();
  ASSERT_EQ(names.size(), 59U);
  EXPECT_EQ(waveletNames(WaveletFamily::kDaubechies).size(), 20U);
  EXPECT_EQ(waveletNames(WaveletFamily::kSymlets).size(), 19U);
  EXPECT_EQ(waveletNames(WaveletFamily::kCoiflets).size(), 5U);
  EXPECT_EQ(waveletNames(WaveletFamily::kBiorthogonal).size(), 15U);
  for (const char* name : {"db1", "db5", "db20", "sym2", "sym20", "coif1", "coif4", "coif5",
                           "bior1.1", "bior2.8", "bior3.1", "bior6.8"}) {
    EXPECT_NE(findWavelet(name), nullptr) << name;
  }
  for (int k = 1; k <= 20; ++k) {
    EXPECT_EQ(getWavelet("db" + std::to_string(k)).filterLength(), 2U * k);
  }
  for (int k = 2; k <= 20; ++k) {
    EXPECT_EQ(getWavelet("sym" + std::to_string(k)).filterLength(), 2U * k);
  }
  for (int k = 1; k <= 5; ++k) {
    EXPECT_EQ(getWavelet("coif" + std::to_string(k)).filterLength(), 6U * k);
  }
  EXPECT_EQ(getWavelet("bior2.8").filterLength(), 18U);
  EXPECT_EQ(getWavelet("bior3.1").filterLength(), 4U);
}

TEST(Wavelet, UnknownNameIsAClearError) {
  EXPECT_EQ(findWavelet("db21"), nullptr);
  EXPECT_EQ(findWavelet(""), nullptr);
  EXPECT_EQ(findWavelet("haar"), nullptr);  // PyWavelets alias not supported: use db1
  try {
    getWavelet("nosuchwavelet");
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("nosuchwavelet"), std::string::npos) << e.what();
  }
}

TEST(Wavelet, FilterBankIdentities) {
  for (const std::string& name : allWaveletNames()) {
    const Wavelet& w = getWavelet(name);
    const std::size_t f = w.filterLength();
    ASSERT_EQ(f % 2, 0U) << name;
    ASSERT_EQ(w.dec_hi.size(), f);
    ASSERT_EQ(w.rec_lo.size(), f);
    ASSERT_EQ(w.rec_hi.size(), f);
    // Low-pass filters have DC gain sqrt(2), high-pass filters reject DC.
    EXPECT_NEAR(std::accumulate(w.dec_lo.begin(), w.dec_lo.end(), 0.0), kSqrt2, kFilterTol) << name;
    EXPECT_NEAR(std::accumulate(w.rec_lo.begin(), w.rec_lo.end(), 0.0), kSqrt2, kFilterTol) << name;
    EXPECT_NEAR(std::accumulate(w.dec_hi.begin(), w.dec_hi.end(), 0.0), 0.0, kFilterTol) << name;
    EXPECT_NEAR(std::accumulate(w.rec_hi.begin(), w.rec_hi.end(), 0.0), 0.0, kFilterTol) << name;
    // Biorthogonality: sum_k rec_lo[k] dec_lo[F - 1 - k + 2m] = delta_m (all families).
    for (int m = -static_cast<int>(f) / 2; m <= static_cast<int>(f) / 2; ++m) {
      double s = 0.0;
      for (int k = 0; k < static_cast<int>(f); ++k) {
        const int idx = static_cast<int>(f) - 1 - k + 2 * m;
        if (idx >= 0 && idx < static_cast<int>(f)) {
          s += w.rec_lo[k] * w.dec_lo[idx];
        }
      }
      EXPECT_NEAR(s, m == 0 ? 1.0 : 0.0, kFilterTol) << name << " m=" << m;
    }
  }
}

TEST(Wavelet, OrthogonalFiltersAreOrthonormal) {
  int count = 0;
  for (const std::string& name : allWaveletNames()) {
    const Wavelet& w = getWavelet(name);
    if (!w.orthogonal) {
      continue;
    }
    ++count;
    const int f = static_cast<int>(w.filterLength());
    for (int k = 0; k < f; ++k) {
      EXPECT_DOUBLE_EQ(w.rec_lo[k], w.dec_lo[f - 1 - k]) << name;
    }
    for (int m = 0; 2 * m < f; ++m) {
      double lo = 0.0;
      double cross = 0.0;
      for (int k = 0; k + 2 * m < f; ++k) {
        lo += w.dec_lo[k] * w.dec_lo[k + 2 * m];
        cross += w.dec_lo[k] * w.dec_hi[k + 2 * m];
      }
      EXPECT_NEAR(lo, m == 0 ? 1.0 : 0.0, kFilterTol) << name << " shift " << m;
      EXPECT_NEAR(cross, 0.0, kFilterTol) << name << " shift " << m;
    }
  }
  EXPECT_EQ(count, 20 + 19 + 5);  // db, sym, coif (pywt flags bior1.1 as not orthogonal)
}

TEST(Dwt, ExtensionModeNames) {
  EXPECT_EQ(parseExtensionMode("symmetric"), ExtensionMode::kSymmetric);
  EXPECT_EQ(parseExtensionMode("periodization"), ExtensionMode::kPeriodization);
  EXPECT_EQ(toString(ExtensionMode::kPeriodization), "periodization");
  EXPECT_THROW(parseExtensionMode("periodic"), std::invalid_argument);
}

TEST(Dwt, CoefficientLengthsFollowPywt) {
  // symmetric: floor((N + F - 1) / 2); periodization: ceil(N / 2).
  EXPECT_EQ(dwtCoeffLength(16, 2, ExtensionMode::kSymmetric), 8U);
  EXPECT_EQ(dwtCoeffLength(17, 10, ExtensionMode::kSymmetric), 13U);
  EXPECT_EQ(dwtCoeffLength(16, 40, ExtensionMode::kSymmetric), 27U);
  EXPECT_EQ(dwtCoeffLength(17, 10, ExtensionMode::kPeriodization), 9U);
  EXPECT_EQ(dwtCoeffLength(1, 10, ExtensionMode::kPeriodization), 1U);
  EXPECT_EQ(idwtOutputLength(13, 10, ExtensionMode::kSymmetric), 18U);
  EXPECT_EQ(idwtOutputLength(9, 10, ExtensionMode::kPeriodization), 18U);
  // pywt.dwt_max_level values.
  EXPECT_EQ(dwtMaxLevel(16, 2), 4);
  EXPECT_EQ(dwtMaxLevel(1000, 10), 6);
  EXPECT_EQ(dwtMaxLevel(240, 10), 4);
  EXPECT_EQ(dwtMaxLevel(16, 40), 0);
  EXPECT_EQ(dwtMaxLevel(39, 40), 0);
  EXPECT_EQ(dwtMaxLevel(65536, 40), 10);

  const std::vector<double> x = testSignal(37, 1);
  for (ExtensionMode mode : {ExtensionMode::kSymmetric, ExtensionMode::kPeriodization}) {
    const WaveletDecomposition dec = wavedec(x, getWavelet("coif4"), 8, mode);
    ASSERT_EQ(dec.level(), 8);
    std::size_t n = x.size();
    for (int j = 1; j <= 8; ++j) {
      n = dwtCoeffLength(n, 24, mode);
      EXPECT_EQ(dec.details[j - 1].size(), n) << toString(mode) << " level " << j;
    }
    EXPECT_EQ(dec.approximation.size(), n);
    const auto arrays = dec.toPywtOrder();
    ASSERT_EQ(arrays.size(), 9U);
    EXPECT_EQ(arrays[0], dec.approximation);
    EXPECT_EQ(arrays[1], dec.details[7]);
    EXPECT_EQ(arrays[8], dec.details[0]);
  }
}

TEST(Dwt, HaarByHand) {
  // x = [4, 6, 10, 12, 8, 6, 5, 5]; Haar: cA = (x0 + x1)/sqrt2, cD = (x0 - x1)/sqrt2
  // (PyWavelets sign convention, dec_hi = [-1/sqrt2, 1/sqrt2]).
  const std::vector<double> x = {4, 6, 10, 12, 8, 6, 5, 5};
  const Wavelet& haar = getWavelet("db1");
  for (ExtensionMode mode : {ExtensionMode::kSymmetric, ExtensionMode::kPeriodization}) {
    std::vector<double> ca;
    std::vector<double> cd;
    dwt(x, haar, mode, &ca, &cd);
    const std::vector<double> ca_expected = {10 / kSqrt2, 22 / kSqrt2, 14 / kSqrt2, 10 / kSqrt2};
    const std::vector<double> cd_expected = {-2 / kSqrt2, -2 / kSqrt2, 2 / kSqrt2, 0.0};
    EXPECT_LT(maxAbsDiff(ca, ca_expected), 1e-14);
    EXPECT_LT(maxAbsDiff(cd, cd_expected), 1e-14);

    // Level 2: cA2 = [(10 + 22)/2, (14 + 10)/2], cD2 = [(10 - 22)/2, (14 - 10)/2].
    const WaveletDecomposition dec = wavedec(x, haar, 2, mode);
    EXPECT_LT(maxAbsDiff(dec.approximation, {16.0, 12.0}), 1e-14);
    EXPECT_LT(maxAbsDiff(dec.details[1], {-6.0, 2.0}), 1e-14);
    EXPECT_LT(maxAbsDiff(dec.details[0], cd_expected), 1e-14);
    EXPECT_LT(maxAbsDiff(waverec(dec), x), 1e-14);

    // Level-2 detail alone: d2 = cD2 spread back over 4 samples with +/- 1/2:
    // [-6/2, -6/2, +6/2, +6/2, 2/2, 2/2, -2/2, -2/2].
    const std::vector<double> d2 = waverecSelected(dec, {2}, false);
    EXPECT_LT(maxAbsDiff(d2, {-3, -3, 3, 3, 1, 1, -1, -1}), 1e-14);
    // Approximation alone: pairs-of-pairs means.
    const std::vector<double> a2 = waverecSelected(dec, {}, true);
    EXPECT_LT(maxAbsDiff(a2, {8, 8, 8, 8, 6, 6, 6, 6}), 1e-14);
  }
  // Odd length, symmetric: [1, 2, 3] is extended to [1, 2, 3, 3].
  std::vector<double> ca;
  std::vector<double> cd;
  dwt({1, 2, 3}, haar, ExtensionMode::kSymmetric, &ca, &cd);
  EXPECT_LT(maxAbsDiff(ca, {3 / kSqrt2, 6 / kSqrt2}), 1e-14);
  EXPECT_LT(maxAbsDiff(cd, {-1 / kSqrt2, 0.0}), 1e-14);
  // idwt(cA, cD) gives the padded signal; waverec trims it.
  EXPECT_LT(maxAbsDiff(idwt(ca, cd, haar, ExtensionMode::kSymmetric), {1, 2, 3, 3}), 1e-14);
  EXPECT_LT(maxAbsDiff(idwt(ca, {}, haar, ExtensionMode::kSymmetric), {1.5, 1.5, 3, 3}), 1e-14);
}

TEST(Dwt, Db2ShortSymmetricByHand) {
  // db2 on x = [1, 0, 0, 0] (impulse), symmetric: x_ext = [.., 0, 1 | 1, 0, 0, 0 | 0, 0, ..];
  // cA[o] = sum_j dec_lo[j] x[2o + 1 - j], length floor((4 + 3)/2) = 3.
  const Wavelet& w = getWavelet("db2");
  std::vector<double> ca;
  std::vector<double> cd;
  dwt({1, 0, 0, 0}, w, ExtensionMode::kSymmetric, &ca, &cd);
  ASSERT_EQ(ca.size(), 3U);
  // o = 0: x[1 - j] for j = 0..3 -> x[1], x[0], x[-1] = x[0], x[-2] = x[1].
  EXPECT_NEAR(ca[0], w.dec_lo[1] + w.dec_lo[2], 1e-15);
  // o = 1: x[3], x[2], x[1], x[0].
  EXPECT_NEAR(ca[1], w.dec_lo[3], 1e-15);
  EXPECT_NEAR(ca[2], 0.0, 1e-15);
  EXPECT_NEAR(cd[0], w.dec_hi[1] + w.dec_hi[2], 1e-15);
  EXPECT_NEAR(cd[1], w.dec_hi[3], 1e-15);
}

TEST(Dwt, PerfectReconstructionEveryWaveletAndMode) {
  const std::vector<std::size_t> lengths = {16, 17, 240, 1001};
  const std::vector<int> levels = {1, 3, 6, 8};  // 8 exceeds dwtMaxLevel for most cases
  double worst = 0.0;
  for (const std::string& name : allWaveletNames()) {
    const Wavelet& w = getWavelet(name);
    for (ExtensionMode mode : {ExtensionMode::kSymmetric, ExtensionMode::kPeriodization}) {
      for (std::size_t n : lengths) {
        const std::vector<double> x = testSignal(n, n + w.filterLength());
        for (int level : levels) {
          const WaveletDecomposition dec = wavedec(x, w, level, mode);
          const std::vector<double> y = waverec(dec);
          ASSERT_EQ(y.size(), n);
          const double err = maxAbsDiff(x, y);
          worst = std::max(worst, err);
          EXPECT_LT(err, kReconstructionTol)
              << name << " " << toString(mode) << " N=" << n << " L=" << level;
        }
      }
    }
  }
  RecordProperty("max_reconstruction_error", std::to_string(worst));
}

TEST(Dwt, SingleLevelIdwtInvertsDwt) {
  for (const char* name : {"db5", "sym7", "coif4", "bior2.8", "bior3.1"}) {
    const Wavelet& w = getWavelet(name);
    const std::vector<double> x = testSignal(64, 3);
    for (ExtensionMode mode : {ExtensionMode::kSymmetric, ExtensionMode::kPeriodization}) {
      std::vector<double> ca;
      std::vector<double> cd;
      dwt(x, w, mode, &ca, &cd);
      std::vector<double> y = idwt(ca, cd, w, mode);
      ASSERT_GE(y.size(), x.size());
      y.resize(x.size());
      EXPECT_LT(maxAbsDiff(x, y), kFilterTol) << name << " " << toString(mode);
    }
  }
}

TEST(Dwt, OrthogonalWaveletsPreserveEnergyInPeriodizationMode) {
  // Parseval: with periodization and N = 2^k, an orthogonal DWT is an orthogonal matrix.
  const std::vector<double> x = testSignal(512, 7);
  const double ex = energy(x);
  int tested = 0;
  for (const std::string& name : allWaveletNames()) {
    const Wavelet& w = getWavelet(name);
    if (!w.orthogonal) {
      continue;
    }
    for (int level : {1, 4, 9}) {
      const WaveletDecomposition dec = wavedec(x, w, level, ExtensionMode::kPeriodization);
      double e = energy(dec.approximation);
      for (const auto& d : dec.details) {
        e += energy(d);
      }
      EXPECT_NEAR(e / ex, 1.0, kFilterTol) << name << " L=" << level;
    }
    // The single-level reconstructions are mutually orthogonal projections:
    // ||x||^2 = sum_j ||d_j||^2 + ||a_L||^2 and <d_1, d_2> = 0.
    const WaveletDecomposition dec = wavedec(x, w, 3, ExtensionMode::kPeriodization);
    const std::vector<double> d1 = waverecSelected(dec, {1}, false);
    const std::vector<double> d2 = waverecSelected(dec, {2}, false);
    const std::vector<double> d3 = waverecSelected(dec, {3}, false);
    const std::vector<double> a3 = waverecSelected(dec, {}, true);
    EXPECT_NEAR(std::inner_product(d1.begin(), d1.end(), d2.begin(), 0.0), 0.0, 1e-10) << name;
    EXPECT_NEAR((energy(d1) + energy(d2) + energy(d3) + energy(a3)) / ex, 1.0, kFilterTol) << name;
    ++tested;
  }
  EXPECT_EQ(tested, 44);
}

TEST(Dwt, BiorthogonalIsNotEnergyPreserving) {
  // Guard against accidentally treating a biorthogonal filter bank as orthogonal.
  const std::vector<double> x = testSignal(512, 7);
  const WaveletDecomposition dec =
      wavedec(x, getWavelet("bior3.1"), 3, ExtensionMode::kPeriodization);
  double e = energy(dec.approximation);
  for (const auto& d : dec.details) {
    e += energy(d);
  }
  EXPECT_GT(std::abs(e / energy(x) - 1.0), 0.05);
}

TEST(Dwt, SelectedReconstructionIsLinearAndAdditive) {
  const std::vector<double> x = testSignal(300, 11);
  for (const char* name : {"db5", "coif4", "bior2.8", "sym20"}) {
    for (ExtensionMode mode : {ExtensionMode::kSymmetric, ExtensionMode::kPeriodization}) {
      const WaveletDecomposition dec = wavedec(x, getWavelet(name), 6, mode);
      std::vector<double> sum = waverecSelected(dec, {}, true);
      for (int j = 1; j <= 6; ++j) {
        const std::vector<double> dj = waverecSelected(dec, {j}, false);
        ASSERT_EQ(dj.size(), x.size());
        for (std::size_t i = 0; i < x.size(); ++i) {
          sum[i] += dj[i];
        }
      }
      EXPECT_LT(maxAbsDiff(sum, x), kReconstructionTol) << name;
      // d3 + d4 + d5 equals the three single-level reconstructions added up.
      const std::vector<double> d345 = waverecSelected(dec, {5, 3, 4}, false);
      std::vector<double> manual(x.size(), 0.0);
      for (int j : {3, 4, 5}) {
        const std::vector<double> dj = waverecSelected(dec, {j}, false);
        for (std::size_t i = 0; i < x.size(); ++i) {
          manual[i] += dj[i];
        }
      }
      EXPECT_LT(maxAbsDiff(d345, manual), 1e-12) << name;
      // An empty selection is all zeros.
      EXPECT_EQ(waverecSelected(dec, {}, false), std::vector<double>(x.size(), 0.0));
    }
  }
}

TEST(Dwt, InvalidArguments) {
  const Wavelet& w = getWavelet("db4");
  EXPECT_THROW(wavedec({}, w, 3), std::invalid_argument);
  EXPECT_THROW(wavedec({1, 2, 3}, w, 0), std::invalid_argument);
  const WaveletDecomposition dec = wavedec(testSignal(50, 2), w, 3);
  EXPECT_THROW(waverecSelected(dec, {0}, false), std::invalid_argument);
  EXPECT_THROW(waverecSelected(dec, {4}, false), std::invalid_argument);
  EXPECT_THROW(waverecSelected(dec, {2, 2}, false), std::invalid_argument);
  WaveletDecomposition broken = dec;
  broken.details[1].pop_back();
  EXPECT_THROW(waverec(broken), std::invalid_argument);
  WaveletDecomposition unknown = dec;
  unknown.wavelet = "db99";
  EXPECT_THROW(waverec(unknown), std::invalid_argument);
  EXPECT_THROW(idwt({1.0, 2.0}, {1.0}, w, ExtensionMode::kPeriodization), std::invalid_argument);
  EXPECT_THROW(idwt({}, {}, w, ExtensionMode::kPeriodization), std::invalid_argument);
}

}  // namespace
}  // namespace pedicle_drilling::core
