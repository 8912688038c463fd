/**
 * @file pso.hpp
 * @brief Particle swarm identification of the displacement models, the paper's method
 *        (Sec. V-B: population 24, 2000 iterations, fitness R^2 of Eq. 16). Baseline only: both
 *        models are linear in their coefficients, so fitOls() / fitCeres() are exact and faster.
 *
 * Algorithm: standard global-best inertia-weight PSO,
 *   v <- w v + c1 r1 (p_best - x) + c2 r2 (g_best - x),   x <- x + v,
 * with w = 0.729 and c1 = c2 = 1.494 (r1, r2 ~ U(0,1) per dimension). These are the values
 * equivalent to Clerc & Kennedy's constriction factor chi = 0.7298 with phi = 4.1
 * (M. Clerc, J. Kennedy, "The particle swarm - explosion, stability, and convergence in a
 * multidimensional complex space", IEEE Trans. Evol. Comput. 6(1):58-73, 2002):
 * w = chi, c = chi * 2.05 = 1.496. Velocities are clamped to the width of the search box per
 * dimension and positions to the box (velocity zeroed on the clamped dimension).
 *
 * Search box, derived from the data scale (so it works for any units / patient):
 *   range_d = max(d) - min(d), range_tv = max(Tv) - min(Tv), range_r = max(dTv/dt) - min(dTv/dt)
 *   q1 in [-k range_d / range_tv, +k range_d / range_tv]
 *   q2 in [-k range_d / range_r,  +k range_d / range_r]     (hysteresis only)
 *   q0 in mean(d) +- k range_d (1 + max|Tv| / range_tv + max|dTv/dt| / range_r)
 * with k = bound_scale (default 2). Any coefficient set whose prediction spans more than k times
 * the measured range is excluded, which keeps every R^2-competitive solution inside the box
 * (the OLS slope satisfies |q1| <= range_d / range_tv times a factor of order one), and the q0
 * interval covers mean(d) - q1 mean(Tv) - q2 mean(dTv/dt) for every q1, q2 in the box.
 *
 * Determinism: one std::mt19937_64 seeded with options.seed drives initialisation and updates,
 * in a fixed order, so a given seed and data give bit-identical results.
 */
#pragma once

#include <cstdint>
#include <vector>

#include "pedicle_drilling/core/breathing/identification.hpp"

namespace pedicle_drilling::core {

/** @brief PSO settings (defaults: paper Sec. V-B and Clerc & Kennedy 2002). */
struct PsoOptions {
  int population = 24;       ///< swarm size (paper)
  int iterations = 2000;     ///< iterations (paper)
  double inertia = 0.729;    ///< w
  double cognitive = 1.494;  ///< c1
  double social = 1.494;     ///< c2
  double bound_scale = 2.0;  ///< k in the search-box derivation (see file doc)
  std::uint64_t seed = 1;    ///< std::mt19937_64 seed
};

/** @brief Search box of the coefficients (identification order, see AxisModel). */
struct PsoBounds {
  std::vector<double> lower;  ///< per-coefficient lower bound
  std::vector<double> upper;  ///< per-coefficient upper bound
};

/** @brief Search box derived from the data scale (see file doc). */
PsoBounds psoBounds(ModelKind kind, const AxisSamples& samples, double bound_scale);

/**
 * @brief PSO identification maximising R^2 (Eq. 16). FitResult::iterations is the number of
 *        swarm iterations run; converged is true when the final R^2 is finite.
 */
FitResult fitPso(ModelKind kind, const AxisSamples& samples,
                 const PsoOptions& options = PsoOptions());

}  // namespace pedicle_drilling::core
