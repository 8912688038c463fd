/**
 * @file sample_rate_check.hpp
 * @brief The force sensor's measured sample rate against the rate declared to the recognizer.
 *        The paper recognizer's block is a duration (`pre_average_s`) turned into a count of
 *        samples at the declared `sensor_rate_hz`; a sensor that publishes at another rate
 *        changes the filter's length in time by the ratio of the two rates. The check measures
 *        the rate from the samples' stamps over consecutive windows of `window_s` and says
 *        whether it lies within `tolerance` of the declared one. A spacing longer than
 *        `window_s` x `tolerance` / 2, or a stamp that goes back, is a pause of the stream (a
 *        silent sensor is the SafetyMonitor's: force_timeout_s), not its rate: the window
 *        restarts after it, so that no single pause can make a rate look off. No ROS.
 */
#pragma once

#include <cmath>
#include <cstdint>
#include <string>

#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling::core {

/** @brief The default tolerance of a rate against its declaration: 10 %. */
inline constexpr double kDefaultRateTolerance = 0.1;

/** @brief True when @p measured_hz lies within @p tolerance (a fraction) of @p declared_hz. */
inline bool ratesAgree(double declared_hz, double measured_hz, double tolerance) {
  return std::fabs(measured_hz / declared_hz - 1.0) <= tolerance;
}

/** @brief Settings of SampleRateCheck. */
struct SampleRateCheckParams {
  double declared_hz = 1000.0 / 3.0;         ///< the rate the samples are declared at [Hz], > 0
  double tolerance = kDefaultRateTolerance;  ///< allowed |measured / declared - 1|, in (0, 1)
  double window_s = 1.0;                     ///< length of one measurement window [s], in (0, 60]
  /** @brief @throws std::invalid_argument naming the first field out of its range. */
  void validate() const;
  /** @brief The declaration of every field. */
  static const ParamTable<SampleRateCheckParams>& table();
};

/** @brief What the latest complete window says. */
enum class RateVerdict {
  kUnknown,   ///< no window completed yet
  kMatch,     ///< the measured rate lies within the tolerance of the declared one
  kMismatch,  ///< it does not
};

/** @brief Measures a stream's sample rate from its stamps (O(1) per sample, no allocation). */
class SampleRateCheck {
 public:
  /** @brief @throws std::invalid_argument if params.validate() does. */
  explicit SampleRateCheck(const SampleRateCheckParams& params = SampleRateCheckParams());

  /**
   * @brief One sample stamped @p stamp_s [s] (a non-finite stamp is ignored).
   * @return true when this sample completed a window: measuredHz() and verdict() are new.
   */
  bool observe(double stamp_s);

  /** @brief The verdict of the latest complete window (kept across pauses). */
  RateVerdict verdict() const { return verdict_; }
  /** @brief The rate [Hz] measured over the latest complete window (0 before the first). */
  double measuredHz() const { return measured_hz_; }
  /** @brief The spacing [s] above which the stream paused: window_s x tolerance / 2. */
  double pauseS() const { return params_.window_s * params_.tolerance / 2.0; }
  /** @brief The settings. */
  const SampleRateCheckParams& params() const { return params_; }

  /**
   * @brief One phrase naming both rates, e.g. "measured 1000 Hz over 1 s, declared 333.333 Hz
   *        (off by +200.0 %, tolerance 10 %)"; "not measured yet, declared 333.333 Hz" before
   *        the first window.
   */
  std::string describe() const;

 private:
  void restart(double stamp_s);

  SampleRateCheckParams params_;
  bool started_ = false;
  double window_start_s_ = 0.0;
  double last_s_ = 0.0;
  std::uint64_t spacings_ = 0;  // samples after window_start_s_
  double measured_hz_ = 0.0;
  double measured_over_s_ = 0.0;
  RateVerdict verdict_ = RateVerdict::kUnknown;
};

}  // namespace pedicle_drilling::core
