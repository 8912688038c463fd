/**
 * @file pso.cpp
 * @brief Inertia-weight particle swarm identification (baseline of paper Sec. V-B).
 */
#include "pedicle_drilling/core/breathing/pso.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include "pedicle_drilling/core/common/portable_random.hpp"

namespace pedicle_drilling::core {

namespace {

double rangeOf(const std::vector<double>& x) {
  const auto mm = std::minmax_element(x.begin(), x.end());
  return *mm.second - *mm.first;
}

double maxAbs(const std::vector<double>& x) {
  double m = 0.0;
  for (double v : x) m = std::max(m, std::abs(v));
  return m;
}

/** R^2 fitness; the denominator is constant so it is precomputed. */
class Fitness {
 public:
  Fitness(ModelKind kind, const AxisSamples& s) : kind_(kind), s_(s) {
    double mean = 0.0;
    for (double g : s.d) mean += g;
    mean /= static_cast<double>(s.d.size());
    for (double g : s.d) ss_tot_ += (g - mean) * (g - mean);
    if (ss_tot_ <= 0.0) ss_tot_ = 1.0;  // constant signal: R^2 = -ss_res (still maximised)
  }

  double operator()(const std::vector<double>& q) const {
    double ss_res = 0.0;
    const size_t n = s_.d.size();
    if (kind_ == ModelKind::kLinear) {
      for (size_t i = 0; i < n; ++i) {
        const double e = s_.d[i] - (q[0] * s_.tv[i] + q[1]);
        ss_res += e * e;
      }
    } else {
      for (size_t i = 0; i < n; ++i) {
        const double e = s_.d[i] - (q[0] * s_.tv[i] + q[1] * s_.dtv_dt[i] + q[2]);
        ss_res += e * e;
      }
    }
    return 1.0 - ss_res / ss_tot_;
  }

 private:
  ModelKind kind_;
  const AxisSamples& s_;
  double ss_tot_ = 0.0;
};

}  // namespace

PsoBounds psoBounds(ModelKind kind, const AxisSamples& s, double k) {
  checkSamples(kind, s);
  if (!(k > 0.0)) throw std::invalid_argument("psoBounds: bound_scale must be positive");
  double range_d = rangeOf(s.d);
  if (range_d <= 0.0) range_d = 1.0;  // constant displacement: any unit scale works
  double range_tv = rangeOf(s.tv);
  if (range_tv <= 0.0) range_tv = 1.0;
  double mean_d = 0.0;
  for (double g : s.d) mean_d += g;
  mean_d /= static_cast<double>(s.d.size());

  PsoBounds b;
  const double s1 = k * range_d / range_tv;
  double q0_half = k * range_d * (1.0 + maxAbs(s.tv) / range_tv);
  b.lower.push_back(-s1);
  b.upper.push_back(s1);
  if (kind == ModelKind::kHysteresis) {
    double range_r = rangeOf(s.dtv_dt);
    if (range_r <= 0.0) range_r = 1.0;
    const double s2 = k * range_d / range_r;
    q0_half += k * range_d * maxAbs(s.dtv_dt) / range_r;
    b.lower.push_back(-s2);
    b.upper.push_back(s2);
  }
  b.lower.push_back(mean_d - q0_half);
  b.upper.push_back(mean_d + q0_half);
  return b;
}

FitResult fitPso(ModelKind kind, const AxisSamples& samples, const PsoOptions& options) {
  if (options.population < 1 || options.iterations < 0) {
    throw std::invalid_argument("fitPso: population must be >= 1 and iterations >= 0");
  }
  const auto start = std::chrono::steady_clock::now();
  const PsoBounds box = psoBounds(kind, samples, options.bound_scale);
  const size_t dim = box.lower.size();
  const size_t pop = static_cast<size_t>(options.population);
  const Fitness fitness(kind, samples);

  std::mt19937_64 rng(options.seed);
  const auto unit = [](std::mt19937_64& r) { return canonical(r); };  // portable_random.hpp

  std::vector<std::vector<double>> x(pop, std::vector<double>(dim));
  std::vector<std::vector<double>> v(pop, std::vector<double>(dim));
  std::vector<std::vector<double>> p_best(pop);
  std::vector<double> p_fit(pop);
  std::vector<double> width(dim);
  for (size_t j = 0; j < dim; ++j) width[j] = box.upper[j] - box.lower[j];

  std::vector<double> g_best;
  double g_fit = -std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < pop; ++i) {
    for (size_t j = 0; j < dim; ++j) {
      x[i][j] = box.lower[j] + unit(rng) * width[j];
      v[i][j] = (unit(rng) - 0.5) * width[j];
    }
    p_best[i] = x[i];
    p_fit[i] = fitness(x[i]);
    if (p_fit[i] > g_fit) {
      g_fit = p_fit[i];
      g_best = x[i];
    }
  }

  for (int it = 0; it < options.iterations; ++it) {
    for (size_t i = 0; i < pop; ++i) {
      for (size_t j = 0; j < dim; ++j) {
        const double r1 = unit(rng);
        const double r2 = unit(rng);
        double vj = options.inertia * v[i][j] + options.cognitive * r1 * (p_best[i][j] - x[i][j]) +
                    options.social * r2 * (g_best[j] - x[i][j]);
        vj = std::clamp(vj, -width[j], width[j]);
        double xj = x[i][j] + vj;
        if (xj < box.lower[j]) {
          xj = box.lower[j];
          vj = 0.0;
        } else if (xj > box.upper[j]) {
          xj = box.upper[j];
          vj = 0.0;
        }
        x[i][j] = xj;
        v[i][j] = vj;
      }
      const double f = fitness(x[i]);
      if (f > p_fit[i]) {
        p_fit[i] = f;
        p_best[i] = x[i];
        if (f > g_fit) {
          g_fit = f;
          g_best = x[i];
        }
      }
    }
  }

  FitResult result;
  result.model.kind = kind;
  result.model.setCoefficients(g_best);
  result.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.iterations = options.iterations;
  result.method = "pso";
  evaluateFit(samples, &result);
  result.converged = std::isfinite(result.r2);
  return result;
}

}  // namespace pedicle_drilling::core
