/**
 * @file force_sensor.cpp
 * @brief 6-axis force/torque sensor model (see force_sensor.hpp).
 */
#include "pedicle_drilling/core/drilling/force_sensor.hpp"

#include <cmath>
#include <stdexcept>

namespace pedicle_drilling::core {

namespace {
constexpr double kPi = 3.14159265358979323846;
}  // namespace

ForceSensor::ForceSensor(std::uint64_t seed, ForceSensorParams params)
    : params_(params), normal_(seed) {
  if (!(params_.rate_hz > 0.0)) throw std::invalid_argument("ForceSensor: rate_hz must be > 0");
  for (int i = 0; i < 3; ++i) bias_[i] = params_.force_bias_sd_n * normal();
  for (int i = 3; i < 6; ++i) bias_[i] = params_.torque_bias_sd_nm * normal();
  vibration_phase0_ = 2.0 * kPi * normal_.uniformOpen();
}

double ForceSensor::normal() { return normal_.normal(); }

void ForceSensor::tare() { tare_offset_ = bias_; }

Wrench ForceSensor::measure(const Wrench& true_wrench, double spindle_rpm, bool in_contact) {
  const double dt = 1.0 / params_.rate_hz;
  // Bias random walk.
  const double sq = std::sqrt(dt);
  for (int i = 0; i < 3; ++i) bias_[i] += params_.force_drift_n_per_sqrt_s * sq * normal();
  for (int i = 3; i < 6; ++i) bias_[i] += params_.torque_drift_nm_per_sqrt_s * sq * normal();

  Wrench out = true_wrench + bias_ - tare_offset_;
  for (int i = 0; i < 3; ++i) out[i] += params_.force_noise_sd_n * normal();
  for (int i = 3; i < 6; ++i) out[i] += params_.torque_noise_sd_nm * normal();

  // Spindle-synchronous vibration (runout / imbalance at f = rpm/60, flute passing at 2f).
  spindle_phase_ = std::fmod(spindle_phase_ + 2.0 * kPi * (spindle_rpm / 60.0) * dt, 2.0 * kPi);
  const bool vibrate = spindle_rpm > 0.0 && (in_contact || !params_.vibration_only_in_contact);
  if (vibrate) {
    const double ph = spindle_phase_ + vibration_phase0_;
    out[0] += params_.spindle_vibration_lateral_n * std::cos(ph);
    out[1] += params_.spindle_vibration_lateral_n * std::sin(ph);
    out[2] += params_.spindle_vibration_axial_n * std::sin(ph) +
              params_.flute_harmonic_axial_n * std::sin(2.0 * ph);
  }

  if (params_.quantize) {
    for (int i = 0; i < 3; ++i) {
      if (params_.force_resolution_n > 0.0) {
        out[i] = std::round(out[i] / params_.force_resolution_n) * params_.force_resolution_n;
      }
    }
    for (int i = 3; i < 6; ++i) {
      if (params_.torque_resolution_nm > 0.0) {
        out[i] = std::round(out[i] / params_.torque_resolution_nm) * params_.torque_resolution_nm;
      }
    }
  }
  ++samples_;
  return out;
}

double ForceSensor::measureAxial(double true_thrust_n, double spindle_rpm, bool in_contact) {
  Wrench w = Wrench::Zero();
  w[2] = true_thrust_n;
  return measure(w, spindle_rpm, in_contact)[2];
}

}  // namespace pedicle_drilling::core
