/**
 * @file wavelet.hpp
 * @brief Wavelet filter banks (Daubechies, Symlets, Coiflets, biorthogonal) looked up by name.
 *
 * The filter coefficients are the PyWavelets ones (same names, same sign and ordering
 * conventions), generated once into src/core/breathing/wavelet_filters.cpp by
 * scripts/dev/generate_wavelet_filters.py. No ROS dependency.
 */
#ifndef PEDICLE_DRILLING_CORE_WAVELET_HPP
#define PEDICLE_DRILLING_CORE_WAVELET_HPP

#include <cstddef>
#include <string>
#include <vector>

namespace pedicle_drilling::core {

/** @brief Wavelet family of a filter bank. */
enum class WaveletFamily { kDaubechies, kSymlets, kCoiflets, kBiorthogonal };

/**
 * @brief A two-channel filter bank, with PyWavelets' conventions.
 *
 * All four filters have the same (even) length. Analysis is a convolution with dec_lo /
 * dec_hi followed by down-sampling; synthesis is up-sampling followed by convolution with
 * rec_lo / rec_hi (see dwt.hpp). Biorthogonal filters are zero-padded as in PyWavelets.
 */
struct Wavelet {
  std::string name;            ///< PyWavelets name, e.g. "db5", "coif4", "bior2.8".
  WaveletFamily family;        ///< Family.
  bool orthogonal;             ///< True for db, sym, coif and bior1.1 (Haar).
  std::vector<double> dec_lo;  ///< Decomposition low-pass filter.
  std::vector<double> dec_hi;  ///< Decomposition high-pass filter.
  std::vector<double> rec_lo;  ///< Reconstruction low-pass filter.
  std::vector<double> rec_hi;  ///< Reconstruction high-pass filter.

  /** @brief Filter length F (same for all four filters). */
  std::size_t filterLength() const { return dec_lo.size(); }
};

/**
 * @brief Look a wavelet up by its PyWavelets name.
 * @throws std::invalid_argument naming the wavelet if it is not one of allWaveletNames().
 * @return A reference to an immutable, process-lifetime object.
 */
const Wavelet& getWavelet(const std::string& name);

/** @brief Like getWavelet() but returns nullptr for an unknown name (never throws). */
const Wavelet* findWavelet(const std::string& name) noexcept;

/**
 * @brief All supported wavelet names: db1-db20, sym2-sym20, coif1-coif5, bior1.1, 1.3, 1.5,
 * 2.2, 2.4, 2.6, 2.8, 3.1, 3.3, 3.5, 3.7, 3.9, 4.4, 5.5, 6.8 (59 names, in that order).
 */
std::vector<std::string> allWaveletNames();

/** @brief Supported wavelet names of one family, in allWaveletNames() order. */
std::vector<std::string> waveletNames(WaveletFamily family);

namespace detail {

/** @brief Raw generated filter data (one row of the table in wavelet_filters.cpp). */
struct RawWaveletFilters {
  const char* name;      ///< PyWavelets name.
  WaveletFamily family;  ///< Family.
  bool orthogonal;       ///< pywt.Wavelet(name).orthogonal.
  std::size_t length;    ///< Filter length.
  const double* dec_lo;  ///< Decomposition low-pass.
  const double* dec_hi;  ///< Decomposition high-pass.
  const double* rec_lo;  ///< Reconstruction low-pass.
  const double* rec_hi;  ///< Reconstruction high-pass.
};

/**
 * @brief The generated table of filter banks (defined in src/core/breathing/wavelet_filters.cpp).
 * @param count Receives the number of rows.
 */
const RawWaveletFilters* rawWaveletTable(std::size_t* count);

}  // namespace detail

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_WAVELET_HPP
