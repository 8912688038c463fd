/**
 * @file portable_random.hpp
 * @brief Random transforms written out in full, so that a seed gives the same numbers with every
 *        standard library: uniform, normal and exponential deviates from the raw
 *        output of the standard engines, whose sequences the C++ standard does fix.
 *
 * The standard *distributions* (std::uniform_real_distribution, std::normal_distribution,
 * std::exponential_distribution) are implementation-defined: libstdc++, libc++ and MSVC give
 * different numbers from the same engine. The engines (std::mt19937, std::mt19937_64) are not:
 * their output is specified bit for bit ([rand.predef]). The transforms below are the ones
 * libstdc++ uses, written here so that every trial recorded with the project's earlier builds
 * (which used libstdc++'s distributions) is reproduced bit for bit, now on any library:
 * - canonical: std::generate_canonical<double, 53> ([rand.util.canonical]: the engine's words
 *   summed in base 2^w, divided by 2^(w k)); a result that rounds up to 1 becomes the largest
 *   double below 1, as libstdc++ does;
 * - normal: Marsaglia's polar method (Marsaglia and Bray 1964), keeping the second deviate of
 *   each pair for the next call;
 * - exponential: -log(1 - u) / rate.
 * What remains platform-dependent is the C library's `log` (and `sqrt`, which IEEE 754 rounds
 * correctly everywhere): glibc's `log` is the same function on every glibc since 2.28.
 */
#pragma once

#include <cmath>
#include <cstdint>
#include <random>

namespace pedicle_drilling::core {

/** @brief A uniform deviate in [0, 1) from one 64-bit engine word (generate_canonical). */
inline double canonical(std::mt19937_64& rng) {
  const double u = static_cast<double>(rng()) * 0x1.0p-64;
  return u < 1.0 ? u : std::nextafter(1.0, 0.0);
}

/** @brief A uniform deviate in [0, 1) from two 32-bit engine words (generate_canonical). */
inline double canonical(std::mt19937& rng) {
  double sum = static_cast<double>(rng());
  sum += static_cast<double>(rng()) * 0x1.0p32;
  const double u = sum * 0x1.0p-64;
  return u < 1.0 ? u : std::nextafter(1.0, 0.0);
}

/** @brief A uniform deviate in [lo, hi). */
template <class Engine>
double uniform(Engine& rng, double lo, double hi) {
  return canonical(rng) * (hi - lo) + lo;
}

/** @brief An exponential deviate of the given rate (mean 1 / rate). */
template <class Engine>
double exponential(Engine& rng, double rate) {
  return -std::log(1.0 - canonical(rng)) / rate;
}

/**
 * @brief Normal deviates by Marsaglia's polar method. Each generated pair serves two calls, so
 *        an object that lives across calls and one made per call draw differently: keep the
 *        object's lifetime as the model needs it.
 */
class PolarNormal {
 public:
  /** @brief Normal deviates of mean `mean` and standard deviation `sd`. */
  explicit PolarNormal(double mean = 0.0, double sd = 1.0) : mean_(mean), sd_(sd) {}

  /** @brief The next deviate, from the engine `rng`. */
  template <class Engine>
  double operator()(Engine& rng) {
    double z;
    if (has_saved_) {
      has_saved_ = false;
      z = saved_;
    } else {
      double x, y, r2;
      do {
        x = 2.0 * canonical(rng) - 1.0;
        y = 2.0 * canonical(rng) - 1.0;
        r2 = x * x + y * y;
      } while (r2 > 1.0 || r2 == 0.0);
      const double mult = std::sqrt(-2.0 * std::log(r2) / r2);
      saved_ = x * mult;
      has_saved_ = true;
      z = y * mult;
    }
    return z * sd_ + mean_;
  }

 private:
  double mean_;
  double sd_;
  bool has_saved_ = false;
  double saved_ = 0.0;
};

}  // namespace pedicle_drilling::core
