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
// The speed at which the spindle-synchronous amplitudes are given (the paper's chosen speed).
constexpr double kVibrationRefRpm = 12000.0;
}  // namespace

namespace {

/** @brief Butterworth low-pass of order n at fc for sample rate fs: bilinear transform (cut-off
 *  pre-warped), as biquads with the Butterworth pole Qs, and one first-order section if n is odd.
 */
template <class Section>
std::vector<Section> butterworth(int n, double fc, double fs) {
  std::vector<Section> out;
  const double w0 = 2.0 * kPi * fc / fs;
  const double cw = std::cos(w0);
  for (int k = 0; k < n / 2; ++k) {
    // Pole pairs at pi (2k + 1) / (2n) from the real axis (n even) or pi (k + 1) / n (n odd,
    // beside the real pole of the first-order section).
    const double angle = n % 2 == 0 ? kPi * (2.0 * k + 1.0) / (2.0 * n) : kPi * (k + 1.0) / n;
    const double q = 1.0 / (2.0 * std::cos(angle));
    const double alpha = std::sin(w0) / (2.0 * q);
    const double a0 = 1.0 + alpha;
    Section s;
    s.b0 = (1.0 - cw) / 2.0 / a0;
    s.b1 = (1.0 - cw) / a0;
    s.b2 = s.b0;
    s.a1 = -2.0 * cw / a0;
    s.a2 = (1.0 - alpha) / a0;
    out.push_back(s);
  }
  if (n % 2 == 1) {
    const double k = std::tan(w0 / 2.0);
    Section s;
    s.b0 = k / (1.0 + k);
    s.b1 = s.b0;
    s.a1 = (k - 1.0) / (k + 1.0);
    out.push_back(s);
  }
  return out;
}

}  // namespace

ForceSensor::ForceSensor(std::uint64_t seed, ForceSensorParams params)
    : params_(params), normal_(seed) {
  if (!(params_.rate_hz > 0.0)) throw std::invalid_argument("ForceSensor: rate_hz must be > 0");
  const double ratio = params_.rate_hz / params_.output_rate_hz;
  if (!(params_.output_rate_hz > 0.0) || !(ratio >= 1.0) ||
      std::abs(ratio - std::round(ratio)) > 1e-9) {
    throw std::invalid_argument(
        "ForceSensor: output_rate_hz must divide rate_hz (the physics rate)");
  }
  decimation_ = static_cast<int>(std::lround(ratio));
  if (params_.antialias_cutoff_hz > 0.0) {
    if (!(params_.antialias_cutoff_hz < 0.5 * params_.rate_hz) || params_.antialias_order < 1 ||
        params_.antialias_order > 8) {
      throw std::invalid_argument(
          "ForceSensor: antialias_cutoff_hz must be below rate_hz / 2, antialias_order in 1..8");
    }
    sections_ =
        butterworth<Section>(params_.antialias_order, params_.antialias_cutoff_hz, params_.rate_hz);
  }
  for (int i = 0; i < 3; ++i) bias_[i] = params_.force_bias_sd_n * normal();
  for (int i = 3; i < 6; ++i) bias_[i] = params_.torque_bias_sd_nm * normal();
  vibration_phase0_ = 2.0 * kPi * normal_.uniformOpen();
}

double ForceSensor::normal() { return normal_.normal(); }

void ForceSensor::tare() { tare_offset_ = bias_; }

Wrench ForceSensor::measure(const Wrench& true_wrench, double spindle_rpm, bool in_contact) {
  const double dt = 1.0 / params_.rate_hz;
  // Spindle-synchronous vibration (runout / imbalance at f = rpm/60, flute passing at 2f),
  // added after the noise as the direct chain always did.
  const Wrench v = vibration(spindle_rpm, in_contact, dt);
  return finish(true_wrench, dt, v);
}

Wrench ForceSensor::vibration(double spindle_rpm, bool in_contact, double dt) {
  Wrench v = Wrench::Zero();
  spindle_phase_ = std::fmod(spindle_phase_ + 2.0 * kPi * (spindle_rpm / 60.0) * dt, 2.0 * kPi);
  if (spindle_rpm > 0.0 && (in_contact || !params_.vibration_only_in_contact)) {
    const double ph = spindle_phase_ + vibration_phase0_;
    if (!(spindle_rpm == grow_rpm_)) {  // the spindle runs at a constant speed most of a trial
      grow_rpm_ = spindle_rpm;
      grow_ =
          params_.spindle_vibration_speed_exponent == 0.0
              ? 1.0
              : std::pow(spindle_rpm / kVibrationRefRpm, params_.spindle_vibration_speed_exponent);
    }
    const double grow = grow_;
    v[0] = grow * params_.spindle_vibration_lateral_n * std::cos(ph);
    v[1] = grow * params_.spindle_vibration_lateral_n * std::sin(ph);
    v[2] = grow * (params_.spindle_vibration_axial_n * std::sin(ph) +
                   params_.flute_harmonic_axial_n * std::sin(2.0 * ph));
  }
  return v;
}

Wrench ForceSensor::filter(const Wrench& x) {
  Wrench y = x;
  for (Section& s : sections_) {
    const Wrench in = y;
    y = s.b0 * in + s.z1;
    s.z1 = s.b1 * in - s.a1 * y + s.z2;
    s.z2 = s.b2 * in - s.a2 * y;
  }
  return y;
}

Wrench ForceSensor::finish(const Wrench& signal, double dt, const Wrench& late) {
  // Bias random walk over the sample interval.
  const double sq = std::sqrt(dt);
  for (int i = 0; i < 3; ++i) bias_[i] += params_.force_drift_n_per_sqrt_s * sq * normal();
  for (int i = 3; i < 6; ++i) bias_[i] += params_.torque_drift_nm_per_sqrt_s * sq * normal();
  Wrench out = signal + bias_ - tare_offset_;
  for (int i = 0; i < 3; ++i) out[i] += params_.force_noise_sd_n * normal();
  for (int i = 3; i < 6; ++i) out[i] += params_.torque_noise_sd_nm * normal();
  out += late;
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

bool ForceSensor::sample(const Wrench& true_wrench, double spindle_rpm, bool in_contact,
                         Wrench* out) {
  if (decimation_ == 1 && sections_.empty()) {  // the direct chain: measure(), bit for bit
    *out = measure(true_wrench, spindle_rpm, in_contact);
    return true;
  }
  const Wrench analog = true_wrench + vibration(spindle_rpm, in_contact, 1.0 / params_.rate_hz);
  const Wrench filtered = sections_.empty() ? analog : filter(analog);
  if (++calls_ % static_cast<std::uint64_t>(decimation_) != 0) return false;
  *out = finish(filtered, static_cast<double>(decimation_) / params_.rate_hz, Wrench::Zero());
  return true;
}

double ForceSensor::measureAxial(double true_thrust_n, double spindle_rpm, bool in_contact) {
  Wrench w = Wrench::Zero();
  w[2] = true_thrust_n;
  return measure(w, spindle_rpm, in_contact)[2];
}

}  // namespace pedicle_drilling::core
