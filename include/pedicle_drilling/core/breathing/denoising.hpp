/**
 * @file denoising.hpp
 * @brief Wavelet de-noising of the vertebra displacement (paper Sec. III-A, Eq. 1-3) and the
 * RMSE-DMM style selection of the wavelet basis (Fig. 6).
 *
 * De-noising (Eq. 1): s_de = d3 + d4 + d5, where d_j is the single-level reconstruction of the
 * detail coefficients cD_j of a level-6 DWT (all other arrays zeroed, pywt.waverec
 * semantics, see waverecSelected()). The kept levels, the DWT level, the extension mode and
 * whether a_L is included are parameters.
 *
 * IMPORTANT for callers: the default s_de = d3 + d4 + d5 contains no approximation and no
 * d6, so it has (nearly) zero mean: the DC offset of the displacement is removed, as are
 * very slow drifts (below about Fs/64). At Fs = 8 Hz, d4 spans [Fs/32, Fs/16] =
 * [0.25, 0.5] Hz, the breathing band (15-30 /min); d3 and d5 are the neighbouring bands.
 * A model fitted to s_de against tidal volume must therefore have an intercept (or the mean
 * of the raw displacement must be added back by the caller).
 *
 * Metrics (Eq. 2-3), as defined here:
 *  - NSR = 1/SNR with SNR = var(s_de) / var(s - s_de) (population variances, i.e. powers of
 *    the mean-removed signals, linear ratio, not dB). Using variances makes the metric
 *    insensitive to the DC offset removed by Eq. 1. If var(s_de) == 0, NSR = +infinity.
 *  - For every displacement sample i, U_i = { k : |Tv_k - Tv_i| <= dTv } (closed interval,
 *    i itself included) and L_i = max_{k in U_i} s_de[k] - min_{k in U_i} s_de[k]
 *    (Eq. 2). Only neighbourhoods with at least 2 samples are used. W_max = max L_i and
 *    W_mean = mean L_i over those neighbourhoods (Eq. 3); both are 0 if there is none.
 *
 * Basis selection (RMSE-DMM, Fig. 6): for each candidate i the metrics z_i1 = NSR,
 * z_i2 = W_max, z_i3 = W_mean are computed; each column j is min-max normalised,
 * z'_ij = (z_ij - min_i z_ij) / (max_i z_ij - min_i z_ij) (0 for every candidate when the
 * column is constant; a non-finite value, e.g. NSR = inf, is normalised to 1 and excluded
 * from min/max). The score is sum_j w_j z'_ij and the candidate with the smallest score is
 * chosen (first in candidate order on ties). The paper does not publish its weights ("the
 * key is to reasonably allocate the corresponding weights"), so the default is equal weights
 * 1/3 each; they can be set in DenoiseOptions::weights (non-negative, finite, not all zero;
 * they need not sum to 1).
 */
#ifndef PEDICLE_DRILLING_CORE_DENOISING_HPP
#define PEDICLE_DRILLING_CORE_DENOISING_HPP

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/dwt.hpp"
#include "pedicle_drilling/core/breathing/wavelet.hpp"

namespace pedicle_drilling::core {

/** @brief Parameters of de-noising and basis selection. Defaults follow the paper. */
struct DenoiseOptions {
  /// Candidate wavelet names; default: all 59 supported (db1-20, sym2-20, coif1-5, bior*).
  std::vector<std::string> candidates = allWaveletNames();
  int level = 6;                                   ///< DWT decomposition level (Fig. 5).
  std::vector<int> kept_levels{3, 4, 5};           ///< Detail levels summed into s_de (Eq. 1).
  bool include_approximation = false;              ///< Also add a_level to s_de (not in Eq. 1).
  ExtensionMode mode = ExtensionMode::kSymmetric;  ///< DWT boundary mode.
  double delta_tv = 5.0;  ///< Half-width dTv of U(Tv, dTv), same unit as Tv (ml).
  /// Weights of (NSR, W_max, W_mean) in the selection score.
  std::array<double, 3> weights{1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0};
};

/** @brief The three metrics of Eq. 3 for one de-noised signal. */
struct DenoiseMetrics {
  double nsr = 0.0;                ///< var(s - s_de) / var(s_de).
  double w_max = 0.0;              ///< max L_i.
  double w_mean = 0.0;             ///< mean L_i.
  std::size_t neighbourhoods = 0;  ///< Number of L_i used (neighbourhoods with >= 2 samples).
};

/** @brief One row of the basis-selection table (Fig. 6). */
struct CandidateScore {
  std::string wavelet;             ///< Candidate name.
  double nsr = 0.0;                ///< Raw NSR.
  double w_max = 0.0;              ///< Raw W_max.
  double w_mean = 0.0;             ///< Raw W_mean.
  double nsr_norm = 0.0;           ///< Min-max normalised NSR.
  double w_max_norm = 0.0;         ///< Min-max normalised W_max.
  double w_mean_norm = 0.0;        ///< Min-max normalised W_mean.
  double score = 0.0;              ///< Weighted sum of the normalised metrics.
  std::size_t neighbourhoods = 0;  ///< Number of L_i used.
};

/** @brief Result of selectWaveletBasis(). */
struct BasisSelection {
  std::vector<CandidateScore> candidates;  ///< One row per candidate, in candidate order.
  std::size_t chosen_index = 0;            ///< Index of the minimum score in candidates.
  std::string wavelet;                     ///< Name of the chosen candidate.
};

/** @brief Result of selectAndDenoise(). */
struct DenoiseResult {
  std::string wavelet;                     ///< Chosen wavelet.
  std::vector<double> denoised;            ///< s_de with the chosen wavelet (input length).
  double nsr = 0.0;                        ///< NSR of the chosen wavelet.
  double w_max = 0.0;                      ///< W_max of the chosen wavelet.
  double w_mean = 0.0;                     ///< W_mean of the chosen wavelet.
  std::vector<CandidateScore> candidates;  ///< Full selection table.
};

/**
 * @brief De-noise a signal by keeping the chosen DWT levels (Eq. 1).
 * @return s_de, same length as signal.
 * @throws std::invalid_argument on empty or non-finite input, level < 1, a kept level outside
 * [1, level] or duplicated, or nothing kept at all.
 */
std::vector<double> denoise(const std::vector<double>& signal, const Wavelet& wavelet,
                            int level = 6, const std::vector<int>& kept_levels = {3, 4, 5},
                            bool include_approximation = false,
                            ExtensionMode mode = ExtensionMode::kSymmetric);

/** @brief denoise() with the wavelet given by name (std::invalid_argument if unknown). */
std::vector<double> denoise(const std::vector<double>& signal, const std::string& wavelet,
                            int level = 6, const std::vector<int>& kept_levels = {3, 4, 5},
                            bool include_approximation = false,
                            ExtensionMode mode = ExtensionMode::kSymmetric);

/**
 * @brief NSR = var(s - s_de) / var(s_de) (see file comment); +inf if var(s_de) == 0.
 * @throws std::invalid_argument if the lengths differ or are zero.
 */
double noiseToSignalRatio(const std::vector<double>& signal, const std::vector<double>& denoised);

/**
 * @brief L_i spread metrics of Eq. 2-3 (W_max, W_mean and the number of neighbourhoods).
 *
 * O(N log N): samples are sorted by Tv and the windows |Tv_k - Tv_i| <= dTv are swept with
 * monotonic max/min queues. The nsr field of the result is left 0.
 * @throws std::invalid_argument if the lengths differ, dTv < 0 or non-finite, or Tv contains
 * a non-finite value.
 */
DenoiseMetrics tidalVolumeSpread(const std::vector<double>& denoised,
                                 const std::vector<double>& tidal_volume, double delta_tv);

/** @brief All three metrics of Eq. 3 (NSR, W_max, W_mean). */
DenoiseMetrics computeDenoiseMetrics(const std::vector<double>& signal,
                                     const std::vector<double>& denoised,
                                     const std::vector<double>& tidal_volume, double delta_tv);

/**
 * @brief Normalise the metric columns and score the candidates (Fig. 6); see file comment.
 * @param rows Rows with wavelet, nsr, w_max, w_mean filled in; the *_norm and score fields
 * are overwritten.
 * @return Index of the minimum score (first on ties).
 * @throws std::invalid_argument if rows is empty or the weights are invalid.
 */
std::size_t scoreCandidates(std::vector<CandidateScore>* rows,
                            const std::array<double, 3>& weights);

/**
 * @brief Evaluate every candidate of options.candidates and choose the basis (Fig. 6).
 * @param displacement Displacement samples s (e.g. 8 Hz).
 * @param tidal_volume Tidal volume at each displacement sample (same length).
 * @throws std::invalid_argument on bad input or options (unknown candidate names included).
 */
BasisSelection selectWaveletBasis(const std::vector<double>& displacement,
                                  const std::vector<double>& tidal_volume,
                                  const DenoiseOptions& options = DenoiseOptions());

/**
 * @brief Choose the basis with selectWaveletBasis() and return the de-noised displacement.
 *
 * The returned signal has the DC offset removed for the default kept levels {3, 4, 5}; see
 * the file comment.
 */
DenoiseResult selectAndDenoise(const std::vector<double>& displacement,
                               const std::vector<double>& tidal_volume,
                               const DenoiseOptions& options = DenoiseOptions());

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_DENOISING_HPP
