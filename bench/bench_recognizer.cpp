// Benchmark: cost of StateRecognizer::push per raw sample over 10^7 synthetic samples, and of a
// recognizer written in Python (python:pd_campaign.recognizers.ThresholdRecognizer
// through PythonRecognizer, the interpreter embedded) over 10^6 of the same samples.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "pedicle_drilling/core/drilling/state_recognizer.hpp"
#include "pedicle_drilling/python/python_recognizer.hpp"

namespace {

// Air, outer cortical hump (3 N), cancellous plateau (0.7 N), inner hump (3 N), breakthrough.
double cleanForce(double t) {
  if (t < 2.0) return 0.0;
  if (t < 4.0) return 1.5 * (t - 2.0);
  if (t < 5.0) return 3.0;
  if (t < 6.0) return 3.0 - 2.3 * (t - 5.0);
  if (t < 16.0) return 0.7;
  if (t < 18.0) return 0.7 + 1.15 * (t - 16.0);
  if (t < 19.5) return 3.0;
  return 0.1;
}

}  // namespace

int main() {
  constexpr std::size_t kSamples = 10000000;
  constexpr std::size_t kPeriod = 23000;  // one synthetic two-layer drilling per 23 s at 1 kHz
  // Pre-generate one drilling profile with noise so that the timed loop measures push() only.
  std::vector<double> profile(kPeriod);
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 0.3);
  for (std::size_t i = 0; i < kPeriod; ++i) {
    const double t = static_cast<double>(i) * 1e-3;
    const double f = cleanForce(t);
    profile[i] = f + noise(rng);
  }
  pedicle_drilling::core::StateRecognizer rec;
  double checksum = 0.0;
  std::size_t stops = 0;
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < kSamples; ++i) {
    const std::size_t j = i % kPeriod;
    if (j == 0 && i != 0) {
      stops += rec.output().stop ? 1 : 0;
      rec.reset();
    }
    checksum += rec.push(static_cast<double>(j) * 1e-3, profile[j]).feature;
  }
  const auto end = std::chrono::steady_clock::now();
  const double ns = std::chrono::duration<double, std::nano>(end - start).count();
  std::printf("# %zu samples, %zu stops, checksum %.6g\n", kSamples, stops, checksum);
  std::printf("BENCH recognizer_per_sample %.3f ns\n", ns / static_cast<double>(kSamples));
  // The same samples through a Python class (pd_campaign on the Python path: make bench runs in
  // the sourced workspace).
  constexpr std::size_t kPythonSamples = 1000000;
  pedicle_drilling::PythonRecognizer python("pd_campaign.recognizers.ThresholdRecognizer");
  python.configure({});
  std::size_t python_stops = 0;
  const auto python_start = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < kPythonSamples; ++i) {
    const std::size_t j = i % kPeriod;
    if (j == 0 && i != 0) {
      python_stops += python.output().stop ? 1 : 0;
      python.reset();
    }
    python.push(static_cast<double>(j) * 1e-3, profile[j]);
  }
  const double python_ns =
      std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - python_start)
          .count() /
      static_cast<double>(kPythonSamples);
  std::printf("# python: %zu samples, %zu stops\n", kPythonSamples, python_stops);
  std::printf("BENCH python_recognizer_per_sample %.1f ns\n", python_ns);
  std::printf("BENCH python_over_cpp_recognizer_cost %.0f x\n",
              python_ns * static_cast<double>(kSamples) / ns);
  return 0;
}
