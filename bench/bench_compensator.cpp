// Benchmark: cost of a compensator's prediction per call, the paper's (C++ PaperCompensator)
// against one written in Python (python:pd_campaign.compensators.
// PhaseTemplateCompensator through PythonCompensator, the interpreter embedded), each fed one
// breath-modulated tracker sample per 0.125 s and asked for displacement() at 40 Hz (the
// planner's 5 points per 125 ms segment), 10^6 and 10^5 calls.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>

#include "pedicle_drilling/core/control/compensation_planner.hpp"
#include "pedicle_drilling/core/control/compensator_interface.hpp"
#include "pedicle_drilling/python/python_compensator.hpp"

namespace pd = pedicle_drilling;

namespace {

/** @brief ns per displacement() call over `calls` calls, a tracker sample every 5th call. */
double nsPerCall(pd::core::CompensatorInterface* c, std::size_t calls, double* checksum) {
  pd::core::MotionModel model;
  model.axis(pd::core::Axis::kAP).q1 = 0.008;
  c->setPatient(model, pd::core::CompensationParams());
  c->setVentilator(pd::core::VentilatorSettings());
  c->setBreathStart(0.0);
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < calls; ++i) {
    const double t = 0.025 * static_cast<double>(i);
    if (i % 5 == 0) {
      c->setBreathStart(5.0 * std::floor(t / 5.0));
      c->observeMarker(t, Eigen::Vector3d(0.0, 0.0, 0.003 * std::sin(2.0 * M_PI * t / 5.0)));
    }
    *checksum += c->displacement(t + 0.125).z();
  }
  return std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start)
             .count() /
         static_cast<double>(calls);
}

}  // namespace

int main() {
  double checksum = 0.0;
  pd::core::PaperCompensator paper;
  paper.configure({});
  const double cpp_ns = nsPerCall(&paper, 1000000, &checksum);
  pd::PythonCompensator python("pd_campaign.compensators.PhaseTemplateCompensator");
  python.configure({});
  const double python_ns = nsPerCall(&python, 100000, &checksum);
  std::printf("# checksum %.6g\n", checksum);
  std::printf("BENCH compensator_per_call %.1f ns\n", cpp_ns);
  std::printf("BENCH python_compensator_per_call %.1f ns\n", python_ns);
  std::printf("BENCH python_over_cpp_compensator_cost %.0f x\n", python_ns / cpp_ns);
  return 0;
}
