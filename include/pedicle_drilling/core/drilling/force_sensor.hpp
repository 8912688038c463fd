/**
 * @file force_sensor.hpp
 * @brief 6-axis force/torque sensor model (1 kHz): white noise, bias, drift, quantisation and a
 *        spindle-synchronous vibration component. Seeded and deterministic.
 *
 * Defaults follow an ATI Nano17 (SI-12-0.12 calibration): resolution 1/320 N (Fx, Fy, Fz) and
 * 1/64 N mm (torques); noise levels and the vibration amplitude are documented assumptions,
 * see doc/simulator_physics.md. No ROS headers; C++17 and Eigen only.
 */
#ifndef PEDICLE_DRILLING_CORE_FORCE_SENSOR_HPP
#define PEDICLE_DRILLING_CORE_FORCE_SENSOR_HPP

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "pedicle_drilling/core/sim/normal_source.hpp"

namespace pedicle_drilling::core {

/** @brief Wrench [Fx, Fy, Fz (N), Tx, Ty, Tz (N m)] in the sensor frame. */
using Wrench = Eigen::Matrix<double, 6, 1>;

/** @brief Sensor model parameters. Defaults and sources: doc/simulator_physics.md. */
struct ForceSensorParams {
  double rate_hz = 1000.0;  ///< output rate (one measure() call per sample)
  /**
   * @brief Rate [Hz] at which the DAQ samples the (filtered) signal: sample() is called at
   *        rate_hz (the physics) and outputs one sample every rate_hz / output_rate_hz calls
   *        (an integer). The paper does not state its sensor's rate (calibration.md).
   */
  double output_rate_hz = 1000.0;
  /** @brief Anti-alias low-pass cut-off [Hz] before the sampling (Butterworth); 0: none. */
  double antialias_cutoff_hz = 0.0;
  /** @brief Order of the anti-alias Butterworth filter (1-8). */
  int antialias_order = 2;
  double force_noise_sd_n = 0.03;               ///< white noise SD per force axis [N]
  double torque_noise_sd_nm = 0.5e-3;           ///< white noise SD per torque axis [N m]
  double force_bias_sd_n = 0.2;                 ///< SD of the initial (untared) force bias [N]
  double torque_bias_sd_nm = 5e-3;              ///< SD of the initial (untared) torque bias [N m]
  double force_drift_n_per_sqrt_s = 1e-3;       ///< bias random-walk intensity, forces
  double torque_drift_nm_per_sqrt_s = 2e-5;     ///< bias random-walk intensity, torques
  double force_resolution_n = 1.0 / 320.0;      ///< quantisation step, forces (Nano17 SI-12-0.12)
  double torque_resolution_nm = 1.0 / 64000.0;  ///< quantisation step, torques (1/64 N mm)
  bool quantize = true;                         ///< round outputs to the resolution
  /// Spindle-synchronous vibration amplitude on the axial force (sensor z) [N]; 0 disables.
  double spindle_vibration_axial_n = 0.05;
  /// How the spindle-synchronous amplitudes grow with speed: times (rpm / 12000)^exponent. 0
  /// (the default): the same at every speed; 2: an imbalance force (m e omega^2, ISO 1940).
  double spindle_vibration_speed_exponent = 0.0;
  /// Spindle-synchronous vibration amplitude on each lateral force (x, y, 90 deg apart) [N].
  double spindle_vibration_lateral_n = 0.03;
  /// Amplitude of the flute-passing harmonic (2 x spindle frequency, 2-flute bit) [N].
  double flute_harmonic_axial_n = 0.0;
  /// Vibration is only present while the spindle is loaded (drill in contact) if true.
  bool vibration_only_in_contact = false;
};

/**
 * @brief Stateful 6-axis F/T sensor: each measure() call produces one sample at rate_hz.
 */
class ForceSensor {
 public:
  /** @brief Creates a sensor; initial bias drawn from the seeded generator. */
  explicit ForceSensor(std::uint64_t seed, ForceSensorParams params = {});

  /**
   * @brief Produces one measured sample.
   * @param true_wrench the physical wrench on the sensor (sensor frame)
   * @param spindle_rpm current spindle speed [rev/min] (vibration frequency = rpm / 60)
   * @param in_contact whether the drill is cutting (used if vibration_only_in_contact)
   */
  Wrench measure(const Wrench& true_wrench, double spindle_rpm, bool in_contact = true);

  /**
   * @brief The measurement chain, called at rate_hz: the analog signal (true wrench and the
   *        spindle vibration) through the anti-alias filter, sampled every rate_hz /
   *        output_rate_hz calls, where noise, bias drift and quantisation are added.
   * @param out the sample, written only when one is taken
   * @return true when a sample was taken (this call is a DAQ sample instant)
   * With output_rate_hz = rate_hz and no filter this is measure() exactly, bit for bit.
   */
  bool sample(const Wrench& true_wrench, double spindle_rpm, bool in_contact, Wrench* out);

  /** @brief Convenience: measured Fz for a pure axial thrust (true wrench = [0,0,F,0,0,0]). */
  double measureAxial(double true_thrust_n, double spindle_rpm, bool in_contact = true);

  /** @brief Software tare: subtracts the current bias from subsequent outputs (drift remains). */
  void tare();

  /** @brief Current effective bias (true bias minus tare offset). */
  Wrench bias() const { return bias_ - tare_offset_; }

  /** @brief Time since construction [s] (samples / rate). */
  double time() const { return static_cast<double>(samples_) / params_.rate_hz; }

  /** @brief Parameters in use. */
  const ForceSensorParams& params() const { return params_; }

 private:
  double normal();

  ForceSensorParams params_;
  NormalSource normal_;  ///< noise, bias and phase deviates
  Wrench bias_ = Wrench::Zero();
  Wrench tare_offset_ = Wrench::Zero();
  /** @brief One biquad section (direct form II transposed) per force/torque axis. */
  struct Section {
    double b0 = 1.0, b1 = 0.0, b2 = 0.0, a1 = 0.0, a2 = 0.0;
    Wrench z1 = Wrench::Zero(), z2 = Wrench::Zero();
  };
  Wrench filter(const Wrench& x);
  Wrench vibration(double spindle_rpm, bool in_contact, double dt);
  /** @brief The DAQ sample of @p signal: bias drift over @p dt, bias, noise, then @p late
   *         (the direct chain's vibration), quantised. */
  Wrench finish(const Wrench& signal, double dt, const Wrench& late);

  std::vector<Section> sections_;  ///< the anti-alias filter (empty: none)
  int decimation_ = 1;             ///< rate_hz / output_rate_hz
  std::uint64_t calls_ = 0;        ///< sample() calls
  double spindle_phase_ = 0.0;
  double vibration_phase0_ = 0.0;
  /// The vibration's growth with speed, kept for the speed it was computed at (NaN: none).
  double grow_rpm_ = std::numeric_limits<double>::quiet_NaN();
  double grow_ = 1.0;
  std::uint64_t samples_ = 0;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_FORCE_SENSOR_HPP
