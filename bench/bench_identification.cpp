// bench_identification: identification speed, Ceres vs the paper's PSO, on the same data.
//
// Data: default virtual volunteers 1..5, 30 s, all three axes, raw (not de-noised) 8 Hz
// samples, linear model (the paper's model) and hysteresis model.
// Ceres fits all samples as one residual block from a Gauss-Newton first step (see
// CeresFitOptions); PSO runs at the paper's settings, 24 particles x 2000 iterations. Every fit
// is repeated so that each timing is a median over repetitions (Ceres 21, PSO 3; steady_clock).
// Prints
//   BENCH identify_speedup_ceres_over_pso <ratio> x
//   BENCH identify_ceres_time <ms> ms      (median per axis fit, linear model)
//   BENCH identify_pso_time <ms> ms        (median per axis fit, linear model)
// plus the mean R^2 of both methods and the hysteresis-model timings.

#include <algorithm>
#include <cstdio>
#include <vector>

#include "pedicle_drilling/core/breathing/identification.hpp"
#include "pedicle_drilling/core/breathing/pso.hpp"
#include "pedicle_drilling/core/breathing/virtual_volunteer.hpp"

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace

int main() {
  namespace pd = pedicle_drilling::core;
  std::vector<pd::AxisSamples> data;
  for (int id = 1; id <= 5; ++id) {
    const pd::PairedSamples p =
        pd::pairAtMarkerTimes(pd::generateVolunteer(pd::defaultVolunteer(id)).recording);
    for (pd::Axis a : pd::kAllAxes) data.push_back(pd::axisSamples(p, a));
  }
  for (pd::ModelKind kind : {pd::ModelKind::kLinear, pd::ModelKind::kHysteresis}) {
    std::vector<double> t_ceres, t_pso;
    double r2_ceres = 0.0, r2_pso = 0.0, r2_ols = 0.0, max_gap = 0.0;
    for (const pd::AxisSamples& s : data) {
      std::vector<double> reps;
      pd::FitResult c;
      for (int r = 0; r < 21; ++r) {
        c = pd::fitCeres(kind, s);
        reps.push_back(c.time_s);
      }
      t_ceres.push_back(median(reps));
      reps.clear();
      pd::FitResult p;
      for (int r = 0; r < 3; ++r) {
        p = pd::fitPso(kind, s);  // paper settings: 24 particles, 2000 iterations
        reps.push_back(p.time_s);
      }
      t_pso.push_back(median(reps));
      const double ols = pd::fitOls(kind, s).r2;
      r2_ceres += c.r2 / static_cast<double>(data.size());
      r2_pso += p.r2 / static_cast<double>(data.size());
      r2_ols += ols / static_cast<double>(data.size());
      max_gap = std::max(max_gap, ols - p.r2);
    }
    const double ms_c = 1e3 * median(t_ceres);
    const double ms_p = 1e3 * median(t_pso);
    if (kind == pd::ModelKind::kLinear) {
      std::printf("BENCH identify_speedup_ceres_over_pso %.1f x\n", ms_p / ms_c);
      std::printf("BENCH identify_ceres_time %.4f ms\n", ms_c);
      std::printf("BENCH identify_pso_time %.3f ms\n", ms_p);
      std::printf("BENCH identify_ceres_r2_mean %.10f R2\n", r2_ceres);
      std::printf("BENCH identify_pso_r2_mean %.10f R2\n", r2_pso);
      std::printf("BENCH identify_ols_r2_mean %.10f R2\n", r2_ols);
      std::printf("BENCH identify_pso_max_r2_gap_to_ols %.3g R2\n", max_gap);
    } else {
      std::printf("BENCH identify_hysteresis_speedup_ceres_over_pso %.1f x\n", ms_p / ms_c);
      std::printf("BENCH identify_hysteresis_ceres_time %.4f ms\n", ms_c);
      std::printf("BENCH identify_hysteresis_pso_time %.3f ms\n", ms_p);
      std::printf("BENCH identify_hysteresis_ceres_r2_mean %.10f R2\n", r2_ceres);
      std::printf("BENCH identify_hysteresis_pso_r2_mean %.10f R2\n", r2_pso);
      std::printf("BENCH identify_hysteresis_pso_max_r2_gap_to_ols %.3g R2\n", max_gap);
    }
  }
  return 0;
}
