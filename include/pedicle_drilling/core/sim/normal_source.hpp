/**
 * @file normal_source.hpp
 * @brief Portable, seedable standard-normal generator shared by every random model of the core.
 */
#pragma once

#include <cmath>
#include <cstdint>
#include <random>

namespace pedicle_drilling::core {

/**
 * @brief One uniform number in [0, 1) from a seed, by splitmix64 (Steele, Lea and Flood 2014):
 *        for a single draw per trial that must not disturb any generator's sequence. Give each
 *        use its own stream by offsetting or xor-ing the seed with a constant of its own.
 */
inline double uniformFromSeed(std::uint64_t seed) {
  std::uint64_t z = seed + 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  z = z ^ (z >> 31);
  return static_cast<double>(z >> 11) * 0x1.0p-53;
}

/**
 * @brief Standard-normal deviates by an explicit Box-Muller transform on raw mt19937_64 output.
 *
 * std::normal_distribution is implementation-defined; this generator gives the same sequence
 * with every standard library, so a seed reproduces a specimen, a sensor or a trial everywhere.
 */
class NormalSource {
 public:
  /** @brief Generator seeded with `seed` (mt19937_64). */
  explicit NormalSource(std::uint64_t seed) : rng_(seed) {}

  /** @brief Uniform deviate in the open interval (0, 1) from 53 random bits. */
  double uniformOpen() {
    return (static_cast<double>(rng_() >> 11) + 0.5) * (1.0 / 9007199254740992.0);
  }

  /** @brief Standard-normal deviate (mean 0, SD 1). */
  double normal() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    constexpr double kTwoPi = 6.28318530717958647692;
    const double u1 = uniformOpen();
    const double u2 = uniformOpen();
    const double r = std::sqrt(-2.0 * std::log(u1));
    spare_ = r * std::sin(kTwoPi * u2);
    has_spare_ = true;
    return r * std::cos(kTwoPi * u2);
  }

 private:
  std::mt19937_64 rng_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

}  // namespace pedicle_drilling::core
