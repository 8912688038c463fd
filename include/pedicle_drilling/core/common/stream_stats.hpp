/**
 * @file stream_stats.hpp
 * @brief What a consumer can measure of a stamped sensor stream by itself: how late each sample
 *        is handled (its handling time minus its stamp, on the same clock) and how many samples
 *        never arrived (gaps in the stamps). The SafetyMonitor keeps one per input stream (F/T
 *        sensor, tracker) and reports them on /diagnostics; the campaign records them per trial.
 */
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace pedicle_drilling::core {

/**
 * @brief Delay and loss of one stamped stream. The stream's period is its own: the median of
 *        its first kPeriodSamples spacings, so any sensor rate is checked against itself; a
 *        spacing over 1.5 periods counts round(spacing / period) - 1 missing samples.
 */
class StreamStats {
 public:
  /** @brief Spacings that fix the stream's period. */
  static constexpr std::size_t kPeriodSamples = 21;

  /** @brief Forgets everything (a new trial). */
  void reset() { *this = StreamStats(); }

  /** @brief A sample stamped @p stamp_s handled at @p handled_s (seconds, one clock). */
  void observe(double stamp_s, double handled_s) {
    if (!std::isfinite(stamp_s) || !std::isfinite(handled_s)) return;
    ++count_;
    max_delay_s_ = std::max(max_delay_s_, handled_s - stamp_s);
    if (count_ > 1) {
      const double spacing = stamp_s - last_stamp_s_;
      if (spacing > 0.0) {
        if (period_s_ <= 0.0) {
          spacings_.push_back(spacing);
          if (spacings_.size() == kPeriodSamples) {
            std::vector<double> sorted = spacings_;
            std::nth_element(sorted.begin(), sorted.begin() + kPeriodSamples / 2, sorted.end());
            period_s_ = sorted[kPeriodSamples / 2];
            for (double s : spacings_) countGap(s);  // the spacings seen before the period
            spacings_.clear();
          }
        } else {
          countGap(spacing);
        }
      }
    }
    last_stamp_s_ = std::max(last_stamp_s_, stamp_s);
  }

  /** @brief Samples observed. */
  std::uint64_t count() const { return count_; }
  /** @brief The largest handling delay [s] (0 before any sample). */
  double maxDelay() const { return max_delay_s_; }
  /** @brief Samples missing from the stamps' gaps (0 until the period is known). */
  std::uint64_t missing() const { return missing_; }
  /** @brief The stream's period [s] (0 until kPeriodSamples spacings were seen). */
  double period() const { return period_s_; }

 private:
  void countGap(double spacing) {
    if (spacing > 1.5 * period_s_) {
      missing_ += static_cast<std::uint64_t>(std::llround(spacing / period_s_)) - 1;
    }
  }

  std::uint64_t count_ = 0;
  double max_delay_s_ = 0.0;
  double last_stamp_s_ = -INFINITY;
  double period_s_ = 0.0;
  std::vector<double> spacings_;
  std::uint64_t missing_ = 0;
};

}  // namespace pedicle_drilling::core
