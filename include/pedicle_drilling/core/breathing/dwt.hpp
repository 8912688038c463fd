/**
 * @file dwt.hpp
 * @brief 1-D discrete wavelet transform (single level and multilevel), PyWavelets-compatible.
 *
 * Conventions are exactly those of PyWavelets (pywt.dwt / idwt / wavedec / waverec):
 *  - Analysis: c[o] = sum_j h[j] x_ext[i_o - j] with h = dec_lo or dec_hi.
 *    - mode kSymmetric ("symmetric", half-sample symmetric extension, repeated reflection when
 *      the filter is longer than the signal): i_o = 2 o + 1, output length floor((N + F - 1)/2).
 *    - mode kPeriodization ("periodization"): an odd-length signal is first extended by
 *      repeating its last sample, then treated as periodic; i_o = F/2 + 2 o, output length
 *      ceil(N/2).
 *  - Synthesis (idwt): up-sampling by two and convolution with rec_lo / rec_hi;
 *    symmetric: the "valid" part, length 2 n - F + 2; periodization: circular, length 2 n.
 *  - Multilevel: levels above the PyWavelets maximum level are allowed (pywt only warns).
 *    Multilevel reconstruction trims each intermediate approximation to the length of the
 *    next detail array (like pywt.waverec) and the final result to the input length.
 */
#ifndef PEDICLE_DRILLING_CORE_DWT_HPP
#define PEDICLE_DRILLING_CORE_DWT_HPP

#include <cstddef>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/wavelet.hpp"

namespace pedicle_drilling::core {

/** @brief Signal extension (boundary) mode; names follow PyWavelets. */
enum class ExtensionMode { kSymmetric, kPeriodization };

/**
 * @brief Parse "symmetric" or "periodization".
 * @throws std::invalid_argument naming the mode otherwise.
 */
ExtensionMode parseExtensionMode(const std::string& name);

/** @brief "symmetric" or "periodization". */
std::string toString(ExtensionMode mode);

/**
 * @brief Length of each coefficient array of one DWT level for an input of length n.
 * @return floor((n + F - 1)/2) for kSymmetric, ceil(n/2) for kPeriodization (0 for n = 0).
 */
std::size_t dwtCoeffLength(std::size_t n, std::size_t filter_length, ExtensionMode mode);

/**
 * @brief Length of a single-level inverse DWT output from coefficient arrays of length n.
 * @return 2 n - F + 2 for kSymmetric, 2 n for kPeriodization.
 */
std::size_t idwtOutputLength(std::size_t n, std::size_t filter_length, ExtensionMode mode);

/**
 * @brief PyWavelets' dwt_max_level: floor(log2(n / (F - 1))), 0 if n < F - 1.
 *
 * Only informative: wavedec() accepts larger levels, as pywt does (with a warning there).
 */
int dwtMaxLevel(std::size_t n, std::size_t filter_length);

/**
 * @brief Single-level DWT (pywt.dwt).
 * @param x Input signal (non-empty).
 * @param ca Output approximation coefficients (resized).
 * @param cd Output detail coefficients (resized).
 * @throws std::invalid_argument if x is empty.
 */
void dwt(const std::vector<double>& x, const Wavelet& wavelet, ExtensionMode mode,
         std::vector<double>* ca, std::vector<double>* cd);

/**
 * @brief Single-level inverse DWT (pywt.idwt).
 *
 * Either array may be empty, meaning "all zeros" (pywt.idwt(None, cd) / idwt(ca, None)).
 * @throws std::invalid_argument if both are empty or the non-empty lengths differ.
 */
std::vector<double> idwt(const std::vector<double>& ca, const std::vector<double>& cd,
                         const Wavelet& wavelet, ExtensionMode mode);

/**
 * @brief Result of a multilevel decomposition.
 *
 * details[j - 1] holds cD_j (j = 1 finest ... level coarsest); approximation holds cA_level.
 * Note that PyWavelets returns [cA_L, cD_L, ..., cD_1]; see toPywtOrder().
 */
struct WaveletDecomposition {
  std::string wavelet;                             ///< Wavelet name.
  ExtensionMode mode = ExtensionMode::kSymmetric;  ///< Extension mode used.
  std::size_t signal_length = 0;                   ///< Length N of the decomposed signal.
  std::vector<double> approximation;               ///< cA_level.
  std::vector<std::vector<double>> details;        ///< details[j-1] = cD_j.

  /** @brief Decomposition level L. */
  int level() const { return static_cast<int>(details.size()); }

  /** @brief The arrays in pywt.wavedec order: cA_L, cD_L, ..., cD_1. */
  std::vector<std::vector<double>> toPywtOrder() const;
};

/**
 * @brief Multilevel DWT (pywt.wavedec(x, wavelet, mode, level)).
 * @param level Decomposition level, >= 1 (may exceed dwtMaxLevel()).
 * @throws std::invalid_argument on empty x or level < 1.
 */
WaveletDecomposition wavedec(const std::vector<double>& x, const Wavelet& wavelet, int level,
                             ExtensionMode mode = ExtensionMode::kSymmetric);

/**
 * @brief Full multilevel reconstruction (pywt.waverec), trimmed to decomposition.signal_length.
 * @throws std::invalid_argument if the wavelet name is unknown or the array lengths are not
 * those produced by wavedec() for signal_length.
 */
std::vector<double> waverec(const WaveletDecomposition& decomposition);

/**
 * @brief Reconstruction of a chosen set of levels, the others treated as zero.
 *
 * Equivalent to pywt.waverec on the wavedec arrays with the non-selected arrays replaced by
 * zeros, trimmed to the input length. The result is the sum of the single-level
 * reconstructions d_j (and a_L) of Eq. 1 of the paper. Zero arrays are never materialised.
 * @param detail_levels Levels j in [1, L] whose detail d_j is kept (duplicates rejected).
 * @param include_approximation Also keep a_L.
 * @throws std::invalid_argument on a level outside [1, L] or a duplicate level. An empty
 * selection gives all zeros.
 */
std::vector<double> waverecSelected(const WaveletDecomposition& decomposition,
                                    const std::vector<int>& detail_levels,
                                    bool include_approximation);

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_DWT_HPP
