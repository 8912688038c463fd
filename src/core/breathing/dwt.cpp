#include "pedicle_drilling/core/breathing/dwt.hpp"

#include <algorithm>
#include <stdexcept>

namespace pedicle_drilling::core {
namespace {

/// Filters rearranged once per call so that every inner loop is a forward dot product.
struct PreparedFilters {
  std::size_t f = 0;                   // filter length F (even)
  std::vector<double> dec_lo_rev;      // dec_lo reversed
  std::vector<double> dec_hi_rev;      // dec_hi reversed
  std::vector<double> rec_lo_poly[2];  // rec_lo polyphase p, reversed: rec[p + 2 (F/2 - 1 - i)]
  std::vector<double> rec_hi_poly[2];

  explicit PreparedFilters(const Wavelet& w) : f(w.filterLength()) {
    if (f == 0 || f % 2 != 0 || w.dec_hi.size() != f || w.rec_lo.size() != f ||
        w.rec_hi.size() != f) {
      throw std::invalid_argument("wavelet '" + w.name + "' has an invalid filter bank");
    }
    dec_lo_rev.assign(w.dec_lo.rbegin(), w.dec_lo.rend());
    dec_hi_rev.assign(w.dec_hi.rbegin(), w.dec_hi.rend());
    const std::size_t half = f / 2;
    for (std::size_t p = 0; p < 2; ++p) {
      rec_lo_poly[p].resize(half);
      rec_hi_poly[p].resize(half);
      for (std::size_t i = 0; i < half; ++i) {
        rec_lo_poly[p][i] = w.rec_lo[p + 2 * (half - 1 - i)];
        rec_hi_poly[p][i] = w.rec_hi[p + 2 * (half - 1 - i)];
      }
    }
  }
};

inline double dot(const double* a, const double* b, std::size_t n) {
  double s = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    s += a[i] * b[i];
  }
  return s;
}

/// Mathematical modulo (result in [0, m)).
inline std::ptrdiff_t posMod(std::ptrdiff_t k, std::ptrdiff_t m) {
  const std::ptrdiff_t r = k % m;
  return r < 0 ? r + m : r;
}

/// Single-level analysis into ca/cd (each of length dwtCoeffLength(n)). ext is scratch.
void analyse(const double* x, std::size_t n, const PreparedFilters& pf, ExtensionMode mode,
             double* ca, double* cd, std::vector<double>* ext) {
  const std::size_t f = pf.f;
  const std::size_t n_out = dwtCoeffLength(n, f, mode);
  std::size_t start = 0;
  if (mode == ExtensionMode::kSymmetric) {
    // ext[p] = x_sym[p - (F - 1)], with half-sample symmetric extension of period 2N
    // (repeated reflections when F > N). c[o] = sum_j h[j] x_sym[2o + 1 - j].
    const std::size_t len = n + 2 * (f - 1);
    ext->resize(len);
    const std::ptrdiff_t nn = static_cast<std::ptrdiff_t>(n);
    const std::ptrdiff_t shift = static_cast<std::ptrdiff_t>(f) - 1;
    for (std::size_t p = 0; p < len; ++p) {
      std::ptrdiff_t m = posMod(static_cast<std::ptrdiff_t>(p) - shift, 2 * nn);
      if (m >= nn) {
        m = 2 * nn - 1 - m;
      }
      (*ext)[p] = x[m];
    }
    start = 1;  // x_sym[2o + 1 - j] = ext[2o + F - j] = ext[2o + 1 + k], k = F - 1 - j
  } else {
    // Odd length: extend by the last sample; then periodic with period np = 2 n_out.
    // ext[p] = xp[(p - F) mod np]; c[o] = sum_j h[j] xp[F/2 + 2o - j].
    const std::size_t np = 2 * n_out;
    const std::size_t len = np + 2 * f;
    ext->resize(len);
    const std::ptrdiff_t shift = static_cast<std::ptrdiff_t>(f);
    for (std::size_t p = 0; p < len; ++p) {
      const std::size_t m = static_cast<std::size_t>(
          posMod(static_cast<std::ptrdiff_t>(p) - shift, static_cast<std::ptrdiff_t>(np)));
      (*ext)[p] = x[std::min(m, n - 1)];
    }
    start = f / 2 + 1;  // xp[F/2 + 2o - j] = ext[F/2 + F + 2o - j] = ext[F/2 + 1 + 2o + k]
  }
  const double* e = ext->data() + start;
  const double* lo = pf.dec_lo_rev.data();
  const double* hi = pf.dec_hi_rev.data();
  for (std::size_t o = 0; o < n_out; ++o) {
    const double* base = e + 2 * o;
    double sa = 0.0;
    double sd = 0.0;
    for (std::size_t k = 0; k < f; ++k) {
      sa += lo[k] * base[k];
      sd += hi[k] * base[k];
    }
    ca[o] = sa;
    cd[o] = sd;
  }
}

/// Single-level synthesis from a and/or d (nullptr = zeros), each of length n, into out
/// (length idwtOutputLength(n)). sa/sd are scratch.
void synthesise(const double* a, const double* d, std::size_t n, const PreparedFilters& pf,
                ExtensionMode mode, double* out, std::vector<double>* sa, std::vector<double>* sd) {
  const std::size_t f = pf.f;
  const std::size_t half = f / 2;
  const std::size_t m = idwtOutputLength(n, f, mode);
  std::fill(out, out + m, 0.0);
  if (mode == ExtensionMode::kSymmetric) {
    // out[2q + p] = sum_i P_p[i] a[q + i] (valid part of the up-sampled convolution).
    const std::size_t q_count = m / 2;  // m is even
    if (a != nullptr) {
      for (std::size_t q = 0; q < q_count; ++q) {
        out[2 * q] += dot(pf.rec_lo_poly[0].data(), a + q, half);
        out[2 * q + 1] += dot(pf.rec_lo_poly[1].data(), a + q, half);
      }
    }
    if (d != nullptr) {
      for (std::size_t q = 0; q < q_count; ++q) {
        out[2 * q] += dot(pf.rec_hi_poly[0].data(), d + q, half);
        out[2 * q + 1] += dot(pf.rec_hi_poly[1].data(), d + q, half);
      }
    }
    return;
  }
  // Periodization: x[t] = sum_{j = u mod 2} rec[j] c[((u - j)/2) mod n], u = t + F/2 - 1.
  // With the periodic extension cext[k] = c[(k - F) mod n]:
  //   x[t] = sum_i P_p[i] cext[F + (u - p)/2 - (F/2 - 1) + i], p = u mod 2.
  const std::size_t len = n + 2 * f;
  auto extend = [&](const double* c, std::vector<double>* ext) {
    ext->resize(len);
    for (std::size_t k = 0; k < len; ++k) {
      (*ext)[k] = c[posMod(static_cast<std::ptrdiff_t>(k) - static_cast<std::ptrdiff_t>(f),
                           static_cast<std::ptrdiff_t>(n))];
    }
  };
  const double* ea = nullptr;
  const double* ed = nullptr;
  if (a != nullptr) {
    extend(a, sa);
    ea = sa->data();
  }
  if (d != nullptr) {
    extend(d, sd);
    ed = sd->data();
  }
  for (std::size_t t = 0; t < m; ++t) {
    const std::size_t u = t + half - 1;
    const std::size_t p = u & 1U;
    const std::size_t first = f + (u - p) / 2 - (half - 1);
    double s = 0.0;
    if (ea != nullptr) {
      s += dot(pf.rec_lo_poly[p].data(), ea + first, half);
    }
    if (ed != nullptr) {
      s += dot(pf.rec_hi_poly[p].data(), ed + first, half);
    }
    out[t] = s;
  }
}

/// clen[0] = N, clen[j] = length of cA_j / cD_j.
std::vector<std::size_t> levelLengths(std::size_t n, std::size_t f, int level, ExtensionMode mode) {
  std::vector<std::size_t> clen(static_cast<std::size_t>(level) + 1);
  clen[0] = n;
  for (int j = 1; j <= level; ++j) {
    clen[j] = dwtCoeffLength(clen[j - 1], f, mode);
  }
  return clen;
}

}  // namespace

ExtensionMode parseExtensionMode(const std::string& name) {
  if (name == "symmetric") {
    return ExtensionMode::kSymmetric;
  }
  if (name == "periodization") {
    return ExtensionMode::kPeriodization;
  }
  throw std::invalid_argument("unknown extension mode '" + name +
                              "' (supported: symmetric, periodization)");
}

std::string toString(ExtensionMode mode) {
  return mode == ExtensionMode::kSymmetric ? "symmetric" : "periodization";
}

std::size_t dwtCoeffLength(std::size_t n, std::size_t filter_length, ExtensionMode mode) {
  if (n == 0) {
    return 0;
  }
  if (mode == ExtensionMode::kPeriodization) {
    return (n + 1) / 2;
  }
  return (n + filter_length - 1) / 2;
}

std::size_t idwtOutputLength(std::size_t n, std::size_t filter_length, ExtensionMode mode) {
  if (mode == ExtensionMode::kPeriodization) {
    return 2 * n;
  }
  return 2 * n + 2 >= filter_length ? 2 * n + 2 - filter_length : 0;
}

int dwtMaxLevel(std::size_t n, std::size_t filter_length) {
  if (filter_length < 2 || n < filter_length - 1) {
    return 0;
  }
  // floor(log2(n / (F - 1))) computed exactly in integers.
  const std::size_t ratio = n / (filter_length - 1);
  int level = 0;
  while ((static_cast<std::size_t>(1) << (level + 1)) <= ratio) {
    ++level;
  }
  return level;
}

void dwt(const std::vector<double>& x, const Wavelet& wavelet, ExtensionMode mode,
         std::vector<double>* ca, std::vector<double>* cd) {
  if (x.empty()) {
    throw std::invalid_argument("dwt: empty input signal");
  }
  const PreparedFilters pf(wavelet);
  const std::size_t n_out = dwtCoeffLength(x.size(), pf.f, mode);
  ca->assign(n_out, 0.0);
  cd->assign(n_out, 0.0);
  std::vector<double> ext;
  analyse(x.data(), x.size(), pf, mode, ca->data(), cd->data(), &ext);
}

std::vector<double> idwt(const std::vector<double>& ca, const std::vector<double>& cd,
                         const Wavelet& wavelet, ExtensionMode mode) {
  if (ca.empty() && cd.empty()) {
    throw std::invalid_argument("idwt: both coefficient arrays are empty");
  }
  if (!ca.empty() && !cd.empty() && ca.size() != cd.size()) {
    throw std::invalid_argument("idwt: coefficient arrays differ in length");
  }
  const std::size_t n = ca.empty() ? cd.size() : ca.size();
  const PreparedFilters pf(wavelet);
  if (mode == ExtensionMode::kSymmetric && 2 * n + 2 < pf.f + 1) {
    throw std::invalid_argument("idwt: coefficient arrays too short for wavelet '" + wavelet.name +
                                "'");
  }
  std::vector<double> out(idwtOutputLength(n, pf.f, mode));
  std::vector<double> sa;
  std::vector<double> sd;
  synthesise(ca.empty() ? nullptr : ca.data(), cd.empty() ? nullptr : cd.data(), n, pf, mode,
             out.data(), &sa, &sd);
  return out;
}

std::vector<std::vector<double>> WaveletDecomposition::toPywtOrder() const {
  std::vector<std::vector<double>> arrays;
  arrays.reserve(details.size() + 1);
  arrays.push_back(approximation);
  for (auto it = details.rbegin(); it != details.rend(); ++it) {
    arrays.push_back(*it);
  }
  return arrays;
}

WaveletDecomposition wavedec(const std::vector<double>& x, const Wavelet& wavelet, int level,
                             ExtensionMode mode) {
  if (x.empty()) {
    throw std::invalid_argument("wavedec: empty input signal");
  }
  if (level < 1) {
    throw std::invalid_argument("wavedec: level must be >= 1, got " + std::to_string(level));
  }
  const PreparedFilters pf(wavelet);
  const std::vector<std::size_t> clen = levelLengths(x.size(), pf.f, level, mode);
  WaveletDecomposition dec;
  dec.wavelet = wavelet.name;
  dec.mode = mode;
  dec.signal_length = x.size();
  dec.details.resize(static_cast<std::size_t>(level));
  std::vector<double> ext;
  std::vector<double> current = x;
  std::vector<double> next;
  for (int j = 1; j <= level; ++j) {
    next.resize(clen[j]);
    std::vector<double>& detail = dec.details[static_cast<std::size_t>(j - 1)];
    detail.resize(clen[j]);
    analyse(current.data(), current.size(), pf, mode, next.data(), detail.data(), &ext);
    current.swap(next);
  }
  dec.approximation = std::move(current);
  return dec;
}

std::vector<double> waverecSelected(const WaveletDecomposition& decomposition,
                                    const std::vector<int>& detail_levels,
                                    bool include_approximation) {
  const int level = decomposition.level();
  const Wavelet& wavelet = getWavelet(decomposition.wavelet);
  const PreparedFilters pf(wavelet);
  if (level < 1 || decomposition.signal_length == 0) {
    throw std::invalid_argument("waverec: empty decomposition");
  }
  const std::vector<std::size_t> clen =
      levelLengths(decomposition.signal_length, pf.f, level, decomposition.mode);
  if (decomposition.approximation.size() != clen[level]) {
    throw std::invalid_argument("waverec: approximation length does not match the signal length");
  }
  for (int j = 1; j <= level; ++j) {
    if (decomposition.details[static_cast<std::size_t>(j - 1)].size() != clen[j]) {
      throw std::invalid_argument("waverec: detail cD_" + std::to_string(j) +
                                  " length does not match the signal length");
    }
  }
  std::vector<bool> keep(static_cast<std::size_t>(level) + 1, false);
  int top = include_approximation ? level : 0;
  for (int j : detail_levels) {
    if (j < 1 || j > level) {
      throw std::invalid_argument("waverec: detail level " + std::to_string(j) + " outside [1, " +
                                  std::to_string(level) + "]");
    }
    if (keep[static_cast<std::size_t>(j)]) {
      throw std::invalid_argument("waverec: detail level " + std::to_string(j) + " listed twice");
    }
    keep[static_cast<std::size_t>(j)] = true;
    top = std::max(top, j);
  }
  if (top == 0) {
    return std::vector<double>(decomposition.signal_length, 0.0);
  }
  // a == nullptr means "approximation is all zeros" (nothing kept at or above this level).
  std::vector<double> a_buf;
  std::vector<double> out_buf;
  std::vector<double> sa;
  std::vector<double> sd;
  bool have_a = false;
  if (include_approximation) {
    a_buf = decomposition.approximation;
    have_a = true;
  }
  for (int j = top; j >= 1; --j) {
    const double* d =
        keep[static_cast<std::size_t>(j)] ? decomposition.details[j - 1].data() : nullptr;
    if (!have_a && d == nullptr) {
      continue;  // cannot happen for j == top; kept for safety
    }
    const std::size_t n = clen[j];
    out_buf.resize(idwtOutputLength(n, pf.f, decomposition.mode));
    synthesise(have_a ? a_buf.data() : nullptr, d, n, pf, decomposition.mode, out_buf.data(), &sa,
               &sd);
    // Trim to the next detail length (pywt.waverec), or to the signal length at the end.
    out_buf.resize(clen[j - 1]);
    a_buf.swap(out_buf);
    have_a = true;
  }
  return a_buf;
}

std::vector<double> waverec(const WaveletDecomposition& decomposition) {
  std::vector<int> all(static_cast<std::size_t>(decomposition.level()));
  for (int j = 1; j <= decomposition.level(); ++j) {
    all[static_cast<std::size_t>(j - 1)] = j;
  }
  return waverecSelected(decomposition, all, true);
}

}  // namespace pedicle_drilling::core
