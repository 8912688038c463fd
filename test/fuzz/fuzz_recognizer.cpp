/**
 * @file fuzz_recognizer.cpp
 * @brief libFuzzer target: the drilling-state recognizer fed an arbitrary sample stream (pairs
 *        of doubles: time step and raw force, NaN, inf and negative steps included). A refused
 *        sample is std::invalid_argument; anything else is a bug. Once it has stopped, it must
 *        stay stopped, and its key points never go back.
 */
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

#include "pedicle_drilling/core/drilling/state_recognizer.hpp"

namespace core = pedicle_drilling::core;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  core::StateRecognizer recognizer{core::RecognizerParams{}};
  double t = 0.0;
  bool stopped = false;
  int last_key_point = 0;
  for (std::size_t at = 0; at + 2 * sizeof(double) <= size; at += 2 * sizeof(double)) {
    double step = 0.0;
    double force = 0.0;
    std::memcpy(&step, data + at, sizeof(double));
    std::memcpy(&force, data + at + sizeof(double), sizeof(double));
    // Mostly plausible streams (1 kHz, forces of a few N) with the raw values as they come.
    if (std::isfinite(step) && std::fabs(step) < 1.0) step = 0.001 + std::fabs(step) * 1e-3;
    try {
      recognizer.push(t + step, force);
      t += step;
    } catch (const std::invalid_argument&) {
      continue;
    }
    const core::RecognizerOutput& out = recognizer.output();
    if (stopped && !out.stop) std::abort();
    if (out.last_key_point < last_key_point) std::abort();
    stopped = out.stop;
    last_key_point = out.last_key_point;
  }
  return 0;
}
