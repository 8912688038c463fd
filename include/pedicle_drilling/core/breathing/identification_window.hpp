// The sliding window of live data that the patient model is identified from (paper Sec. III):
// tidal-volume samples and marker displacements (AP, SI, LR in mm) of the last window_s
// seconds, cleared when time jumps back (a bag restarted, a simulation reset). The
// MotionIdentification nodelet feeds it from topics and tf; the identification reads it.
#ifndef PEDICLE_DRILLING_CORE_IDENTIFICATION_WINDOW_HPP_
#define PEDICLE_DRILLING_CORE_IDENTIFICATION_WINDOW_HPP_

#include <array>
#include <deque>
#include <string>

#include "pedicle_drilling/core/breathing/virtual_volunteer.hpp"

namespace pedicle_drilling::core {

/** @brief A recording taken out of the window, or why none can be identified. */
struct WindowRecording {
  bool ok = false;      ///< false: `error` says why (too few samples, a non-finite volume)
  std::string error;    ///< reason when !ok
  Recording recording;  ///< tidal volume, and the markers inside the tidal volume's time span
};

/** @brief Sliding window of tidal volume and marker displacement samples. */
class IdentificationWindow {
 public:
  /** @brief Minimum marker samples for an identification (two 8 Hz breaths). */
  static constexpr std::size_t kMinMarkers = 16;

  /** @brief A window of `window_s` seconds. @throws std::invalid_argument unless in (0, 3600]. */
  explicit IdentificationWindow(double window_s);

  /**
   * @brief A tidal-volume sample at t [s]; duplicates and out-of-order samples are dropped.
   * @return the jump back [s] that cleared the window first, or 0.
   */
  double addTidalVolume(double t, double volume_ml);

  /**
   * @brief A marker displacement (AP, SI, LR) [mm] at t [s]; duplicates and out-of-order
   *        samples are dropped. @return the jump back [s] that cleared the window first, or 0.
   */
  double addMarker(double t, const std::array<double, 3>& d_mm);

  /** @brief The window as a recording, checked: >= 2 finite volumes, >= kMinMarkers markers. */
  WindowRecording take() const;

  /** @brief Window length [s]. */
  double windowSeconds() const { return window_s_; }

 private:
  struct Marker {
    double t;
    std::array<double, 3> d_mm;
  };
  double advance(double t);

  double window_s_;
  double latest_t_ = -1e300;
  std::deque<std::pair<double, double>> tv_;  // (t, volume)
  std::deque<Marker> marker_;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_IDENTIFICATION_WINDOW_HPP_
