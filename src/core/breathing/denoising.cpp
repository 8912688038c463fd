#include "pedicle_drilling/core/breathing/denoising.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <numeric>
#include <stdexcept>

namespace pedicle_drilling::core {
namespace {

void requireFinite(const std::vector<double>& v, const char* what) {
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i])) {
      throw std::invalid_argument(std::string(what) + ": non-finite value at index " +
                                  std::to_string(i));
    }
  }
}

double variance(const std::vector<double>& v) {
  const double n = static_cast<double>(v.size());
  const double mean = std::accumulate(v.begin(), v.end(), 0.0) / n;
  double acc = 0.0;
  for (double x : v) {
    acc += (x - mean) * (x - mean);
  }
  return acc / n;
}

void validateKept(int level, const std::vector<int>& kept_levels, bool include_approximation) {
  if (level < 1) {
    throw std::invalid_argument("denoise: level must be >= 1, got " + std::to_string(level));
  }
  std::vector<bool> seen(static_cast<std::size_t>(level) + 1, false);
  for (int j : kept_levels) {
    if (j < 1 || j > level) {
      throw std::invalid_argument("denoise: kept detail level " + std::to_string(j) +
                                  " outside [1, " + std::to_string(level) + "]");
    }
    if (seen[static_cast<std::size_t>(j)]) {
      throw std::invalid_argument("denoise: kept detail level " + std::to_string(j) +
                                  " listed twice");
    }
    seen[static_cast<std::size_t>(j)] = true;
  }
  if (kept_levels.empty() && !include_approximation) {
    throw std::invalid_argument("denoise: nothing kept (no detail level, no approximation)");
  }
}

void validateOptions(const std::vector<double>& displacement,
                     const std::vector<double>& tidal_volume, const DenoiseOptions& options) {
  if (displacement.empty()) {
    throw std::invalid_argument("selectWaveletBasis: empty displacement");
  }
  if (displacement.size() != tidal_volume.size()) {
    throw std::invalid_argument(
        "selectWaveletBasis: displacement has " + std::to_string(displacement.size()) +
        " samples but tidal_volume has " + std::to_string(tidal_volume.size()));
  }
  requireFinite(displacement, "selectWaveletBasis: displacement");
  requireFinite(tidal_volume, "selectWaveletBasis: tidal_volume");
  if (options.candidates.empty()) {
    throw std::invalid_argument("selectWaveletBasis: empty candidate list");
  }
  for (const std::string& name : options.candidates) {
    getWavelet(name);  // throws std::invalid_argument naming an unknown wavelet
  }
  validateKept(options.level, options.kept_levels, options.include_approximation);
  if (!std::isfinite(options.delta_tv) || options.delta_tv < 0.0) {
    throw std::invalid_argument("selectWaveletBasis: delta_tv must be finite and >= 0");
  }
}

}  // namespace

std::vector<double> denoise(const std::vector<double>& signal, const Wavelet& wavelet, int level,
                            const std::vector<int>& kept_levels, bool include_approximation,
                            ExtensionMode mode) {
  if (signal.empty()) {
    throw std::invalid_argument("denoise: empty input signal");
  }
  requireFinite(signal, "denoise: input signal");
  validateKept(level, kept_levels, include_approximation);
  const WaveletDecomposition dec = wavedec(signal, wavelet, level, mode);
  return waverecSelected(dec, kept_levels, include_approximation);
}

std::vector<double> denoise(const std::vector<double>& signal, const std::string& wavelet,
                            int level, const std::vector<int>& kept_levels,
                            bool include_approximation, ExtensionMode mode) {
  return denoise(signal, getWavelet(wavelet), level, kept_levels, include_approximation, mode);
}

double noiseToSignalRatio(const std::vector<double>& signal, const std::vector<double>& denoised) {
  if (signal.empty() || signal.size() != denoised.size()) {
    throw std::invalid_argument("noiseToSignalRatio: signals must be non-empty and equal length");
  }
  std::vector<double> residual(signal.size());
  for (std::size_t i = 0; i < signal.size(); ++i) {
    residual[i] = signal[i] - denoised[i];
  }
  const double var_de = variance(denoised);
  if (!(var_de > 0.0)) {
    return std::numeric_limits<double>::infinity();
  }
  return variance(residual) / var_de;
}

DenoiseMetrics tidalVolumeSpread(const std::vector<double>& denoised,
                                 const std::vector<double>& tidal_volume, double delta_tv) {
  if (denoised.size() != tidal_volume.size()) {
    throw std::invalid_argument("tidalVolumeSpread: denoised and tidal_volume differ in length");
  }
  if (!std::isfinite(delta_tv) || delta_tv < 0.0) {
    throw std::invalid_argument("tidalVolumeSpread: delta_tv must be finite and >= 0");
  }
  requireFinite(tidal_volume, "tidalVolumeSpread: tidal_volume");
  const std::size_t n = denoised.size();
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return tidal_volume[a] < tidal_volume[b]; });
  // Window [lo, hi) of sorted positions with |Tv - Tv_p| <= dTv; monotonic queues hold
  // sorted positions with decreasing (max queue) / increasing (min queue) s_de.
  std::deque<std::size_t> max_q;
  std::deque<std::size_t> min_q;
  std::size_t lo = 0;
  std::size_t hi = 0;
  DenoiseMetrics m;
  double sum = 0.0;
  for (std::size_t p = 0; p < n; ++p) {
    const double tv = tidal_volume[order[p]];
    while (hi < n && tidal_volume[order[hi]] - tv <= delta_tv) {
      const double v = denoised[order[hi]];
      while (!max_q.empty() && denoised[order[max_q.back()]] <= v) {
        max_q.pop_back();
      }
      max_q.push_back(hi);
      while (!min_q.empty() && denoised[order[min_q.back()]] >= v) {
        min_q.pop_back();
      }
      min_q.push_back(hi);
      ++hi;
    }
    while (tv - tidal_volume[order[lo]] > delta_tv) {
      ++lo;
    }
    while (max_q.front() < lo) {
      max_q.pop_front();
    }
    while (min_q.front() < lo) {
      min_q.pop_front();
    }
    if (hi - lo >= 2) {
      const double li = denoised[order[max_q.front()]] - denoised[order[min_q.front()]];
      m.w_max = m.neighbourhoods == 0 ? li : std::max(m.w_max, li);
      sum += li;
      ++m.neighbourhoods;
    }
  }
  m.w_mean = m.neighbourhoods == 0 ? 0.0 : sum / static_cast<double>(m.neighbourhoods);
  return m;
}

DenoiseMetrics computeDenoiseMetrics(const std::vector<double>& signal,
                                     const std::vector<double>& denoised,
                                     const std::vector<double>& tidal_volume, double delta_tv) {
  DenoiseMetrics m = tidalVolumeSpread(denoised, tidal_volume, delta_tv);
  m.nsr = noiseToSignalRatio(signal, denoised);
  return m;
}

std::size_t scoreCandidates(std::vector<CandidateScore>* rows,
                            const std::array<double, 3>& weights) {
  if (rows->empty()) {
    throw std::invalid_argument("scoreCandidates: no candidates");
  }
  double weight_sum = 0.0;
  for (double w : weights) {
    if (!std::isfinite(w) || w < 0.0) {
      throw std::invalid_argument("scoreCandidates: weights must be finite and >= 0");
    }
    weight_sum += w;
  }
  if (!(weight_sum > 0.0)) {
    throw std::invalid_argument("scoreCandidates: weights must not all be zero");
  }
  double CandidateScore::*raw[3] = {&CandidateScore::nsr, &CandidateScore::w_max,
                                    &CandidateScore::w_mean};
  double CandidateScore::*norm[3] = {&CandidateScore::nsr_norm, &CandidateScore::w_max_norm,
                                     &CandidateScore::w_mean_norm};
  for (int j = 0; j < 3; ++j) {
    double lo = std::numeric_limits<double>::infinity();
    double hi = -std::numeric_limits<double>::infinity();
    for (const CandidateScore& r : *rows) {
      const double z = r.*raw[j];
      if (std::isfinite(z)) {
        lo = std::min(lo, z);
        hi = std::max(hi, z);
      }
    }
    for (CandidateScore& r : *rows) {
      const double z = r.*raw[j];
      if (!std::isfinite(z)) {
        r.*norm[j] = 1.0;
      } else if (hi > lo) {
        r.*norm[j] = (z - lo) / (hi - lo);
      } else {
        r.*norm[j] = 0.0;
      }
    }
  }
  std::size_t best = 0;
  for (std::size_t i = 0; i < rows->size(); ++i) {
    CandidateScore& r = (*rows)[i];
    r.score = weights[0] * r.nsr_norm + weights[1] * r.w_max_norm + weights[2] * r.w_mean_norm;
    if (r.score < (*rows)[best].score) {
      best = i;
    }
  }
  return best;
}

BasisSelection selectWaveletBasis(const std::vector<double>& displacement,
                                  const std::vector<double>& tidal_volume,
                                  const DenoiseOptions& options) {
  validateOptions(displacement, tidal_volume, options);
  BasisSelection sel;
  sel.candidates.reserve(options.candidates.size());
  for (const std::string& name : options.candidates) {
    const std::vector<double> s_de =
        denoise(displacement, getWavelet(name), options.level, options.kept_levels,
                options.include_approximation, options.mode);
    const DenoiseMetrics m =
        computeDenoiseMetrics(displacement, s_de, tidal_volume, options.delta_tv);
    CandidateScore row;
    row.wavelet = name;
    row.nsr = m.nsr;
    row.w_max = m.w_max;
    row.w_mean = m.w_mean;
    row.neighbourhoods = m.neighbourhoods;
    sel.candidates.push_back(row);
  }
  sel.chosen_index = scoreCandidates(&sel.candidates, options.weights);
  sel.wavelet = sel.candidates[sel.chosen_index].wavelet;
  return sel;
}

DenoiseResult selectAndDenoise(const std::vector<double>& displacement,
                               const std::vector<double>& tidal_volume,
                               const DenoiseOptions& options) {
  BasisSelection sel = selectWaveletBasis(displacement, tidal_volume, options);
  DenoiseResult result;
  result.wavelet = sel.wavelet;
  result.denoised = denoise(displacement, getWavelet(sel.wavelet), options.level,
                            options.kept_levels, options.include_approximation, options.mode);
  const CandidateScore& chosen = sel.candidates[sel.chosen_index];
  result.nsr = chosen.nsr;
  result.w_max = chosen.w_max;
  result.w_mean = chosen.w_mean;
  result.candidates = std::move(sel.candidates);
  return result;
}

}  // namespace pedicle_drilling::core
