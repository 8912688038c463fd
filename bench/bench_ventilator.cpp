/**
 * @file bench_ventilator.cpp
 * @brief Cost of solving a ventilator's shape constants (Ceres) and of evaluating Tv(t).
 */
#include <chrono>
#include <cstdio>

#include "pedicle_drilling/core/breathing/ventilator.hpp"

int main() {
  using Clock = std::chrono::steady_clock;
  namespace pd = pedicle_drilling::core;
  const int solves = 200;
  const auto t0 = Clock::now();
  double sink = 0.0;
  for (int i = 0; i < solves; ++i) {
    pd::VentilatorSettings settings;
    settings.tv_max_ml = 400.0 + i;
    sink += pd::VentilatorModel(settings).expiratoryTau();
  }
  const auto t1 = Clock::now();
  const pd::VentilatorModel model{pd::VentilatorSettings{}};
  const int samples = 5000000;
  for (int i = 0; i < samples; ++i) sink += model.sample(i * 1e-3).volume_ml;
  const auto t2 = Clock::now();
  const double solve_us = std::chrono::duration<double, std::micro>(t1 - t0).count() / solves;
  const double sample_ns = std::chrono::duration<double, std::nano>(t2 - t1).count() / samples;
  std::printf("BENCH ventilator_solve %.1f us\n", solve_us);
  std::printf("BENCH ventilator_sample %.1f ns\n", sample_ns);
  return sink == 0.0 ? 1 : 0;
}
