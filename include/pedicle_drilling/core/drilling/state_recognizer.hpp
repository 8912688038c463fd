// Force-based drilling-state recognizer (paper Sec. IV-C, IV-D, V-E).
//
// Pipeline per raw thrust sample:
//   raw f  --(block mean of blockSamples() raw samples: `pre_average_s` at the declared
//             `sensor_rate_hz`, Sec. V-E)-->                       f_j
//   f_j    --(moving average of `window` values, Eq. 13)-->          fbar_i
//   fbar_i --(Algorithm 2: k, D, f_min)-->  f*_i = (fbar_i - f_min) / D
//   f*_i   --(Eq. 14, Eq. 15)-->            A*_i
//   A*_i   --(key-point state machine, doc/state_machine.md)-->      state, key points, stop
//
// The state machine (the paper's Fig. 12 is not available) is documented in detail in
// doc/state_machine.md.
#ifndef PEDICLE_DRILLING_CORE_STATE_RECOGNIZER_HPP_
#define PEDICLE_DRILLING_CORE_STATE_RECOGNIZER_HPP_

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling::core {

/**
 * @brief Parameters of the drilling-state recognizer.
 *
 * Units: forces in N. When `normalize_feature` is false (default, literal Eq. 14) the feature
 * A_i = D (f*)^3 is in N and so are `h_g`, `c1`, `c2`. When it is true, A_i = (f*)^3 is
 * dimensionless in [0, 1] and `h_g`, `c1`, `c2` are dimensionless too. `c3` is always a ratio.
 * The block of the pre-average is a duration, `pre_average_s`, turned into a count of raw
 * samples at the force sensor's declared rate `sensor_rate_hz` (blockSamples()). Counts
 * (`window`, `*_confirm`, `cancellous_deadline`, `stop_delay`) are in averaged samples, one
 * averaged sample being one block: their durations follow from `pre_average_s` at any rate.
 */
struct RecognizerParams {
  /**
   * @brief Duration of one block mean [s], (0, 10]. Sec. V-E: "the mean of each fifty raw data";
   *        0.15 s is fifty samples of the simulated DAQ at 1000/3 Hz, the rate calibrated
   *        against Fig. 16 (doc/simulator_physics.md, "Measurement chain").
   */
  double pre_average_s = 0.15;
  /**
   * @brief The force sensor's declared sample rate [Hz], (0, 100000]: what the block's count of
   *        samples is computed at. The StateRecognizer nodelet checks it against the stamps of
   *        `ft_sensor/wrench`; the core engine declares the simulated sensor's rate.
   */
  double sensor_rate_hz = 1000.0 / 3.0;
  /** @brief Moving-average length n of Eq. 13. */
  int window = 10;
  /** @brief Algorithm 2 ratio K: layer 1 ends when fbar < K * F_max. Must be in (0, 1). */
  double k_ratio = 0.5;
  /** @brief Algorithm 2 threshold F_th [N]: F_max must exceed it (contact with bone). */
  double f_th = 1.0;
  /** @brief Eq. 15 gain G (>= 1) applied to the part of A above h_g. */
  double gain = 1.2;
  /** @brief Eq. 15 threshold H_g, compared with A_i (same unit as A_i). */
  double h_g = 0.5;
  /** @brief C1: A* below it means "not in cortical bone" (key points 1, 3, 6). */
  double c1 = 0.4;
  /** @brief C2: A* above it after the cancellous phase means "inner cortical" (key point 4). */
  double c2 = 0.7;
  /** @brief C3: ratio of the inner-layer A* peak; A* below C3 * peak marks key point 5. */
  double c3 = 0.7;
  /** @brief Consecutive averaged samples with A* < C1 needed to confirm key point 3. */
  int cancellous_confirm = 5;
  /**
   * @brief Averaged samples after key point 2 within which key point 3 must be confirmed, else
   *        the force is implausible and the drill is stopped (0 disables). From the filter, not
   *        from observed durations: at key point 2 fbar < K F_max, so f* < 1/2 and
   *        A* < D/8 (about C1 at the typical D of 3.2 N); the Eq. 13 window holds only post-layer
   *        blocks `window` samples later, and the confirmation takes `cancellous_confirm`.
   *        Hence it must be 0 or at least window + cancellous_confirm. The default 25 = 2 x
   *        window + cancellous_confirm also lets the confirmation restart once after one rebound
   *        of the force (a bone lagging its prediction); chosen on calibration seeds (base seed
   *        1: 15 stopped 3 of 100 fault-free virtual-patient trials, doc/state_machine.md).
   *        3.75 s (25 blocks of 0.15 s) at any sensor rate. A force sensor whose bias
   *        drifts upwards keeps A* above C1, so key point 3, and with it the inner-layer stop,
   *        would never come. The outer layer's bound is the planner's
   *        `outer_cortical_max_mm`, in mm of feed relative to the bone (the recognizer does not
   *        know the feed).
   */
  int cancellous_deadline = 25;
  /** @brief Consecutive averaged samples with A* > C2 needed to confirm key point 4. */
  int inner_confirm = 2;
  /** @brief Extra averaged samples between confirmed key point 4 and the stop command. */
  int stop_delay = 0;
  /** @brief If true, A_i = (f*)^3 (dimensionless) instead of the literal A_i = D (f*)^3. */
  bool normalize_feature = false;

  /**
   * @brief Raw samples per block mean: pre_average_s x sensor_rate_hz rounded to the nearest
   *        integer, halves away from zero (std::lround): 50 at 0.15 s and 1000/3 Hz, 150 at
   *        1 kHz, 1050 at 7 kHz.
   */
  int blockSamples() const;

  /**
   * @brief Check every field. The block must hold at least 2 samples at the declared rate, at
   *        most 100000, and its rounded count must last within 10 % of pre_average_s.
   * @throws std::invalid_argument whose message starts with the offending field name.
   */
  void validate() const;

  /** @brief The declaration of every field: name, range, unit (the ROS parameters too). */
  static const ParamTable<RecognizerParams>& table();

  /**
   * @brief Set one field from text, e.g. set("k_ratio", "0.5"). Does not call validate().
   * @throws std::invalid_argument for an unknown or retired name (`pre_average`: the message
   *         names pre_average_s and sensor_rate_hz) or an unparsable value (message names it).
   */
  void set(const std::string& name, const std::string& value);
};

/** @brief Drilling state as seen by the recognizer. */
enum class DrillingState {
  kIdle,            ///< No bone contact yet (F_max has not exceeded F_th).
  kOuterCortical,   ///< In the outer cortical layer; Algorithm 2 running.
  kOuterPunctured,  ///< Key point 2 passed; waiting for the cancellous phase to be confirmed.
  kCancellous,      ///< Key point 3 passed; watching for the inner cortical layer.
  kInnerCortical,   ///< Key point 4 passed (stop is commanded in this state).
  kBreakthrough,    ///< Key point 6 passed: the inner cortical layer has been perforated.
  kStopped,         ///< The stop was commanded; reported until reset() (never a layer state).
};

/** @brief Human-readable name of a state. */
const char* toString(DrillingState s);

/** @brief One recognised key point (1..6). */
struct KeyPoint {
  int id = 0;                        ///< Key point number 1..6.
  std::size_t index = 0;             ///< Raw-sample index (0-based) where the event occurred.
  double t = 0.0;                    ///< Time of that raw sample [s].
  std::size_t recognized_index = 0;  ///< Raw-sample index at which it was recognised online.
  double recognized_t = 0.0;         ///< Time of recognition [s].
};

/** @brief Result of one push(); fixed size, no allocation. */
struct RecognizerOutput {
  /**
   * @brief The recognizer's state: the layer state until the stop, then kStopped until reset()
   *        (what a retracting drill's force looks like is not a drilling state).
   */
  DrillingState state = DrillingState::kIdle;
  /**
   * @brief The layer the force shows (never kStopped). The key-point machine keeps running
   *        after the stop, for offline analysis of traces drilled past the stop.
   */
  DrillingState layer_state = DrillingState::kIdle;
  /** @brief Highest key point recognised so far (0-6); frozen at the stop's key point. */
  int last_key_point = 0;
  bool new_average = false;     ///< True if this sample completed a new averaged value.
  bool filter_ready = false;    ///< True once the Eq. 13 window is full.
  double averaged_force = 0.0;  ///< Latest fbar_i [N] (0 until filter_ready).
  double feature = 0.0;         ///< Latest A*_i (0 until D is known).
  bool params_ready = false;    ///< True once Algorithm 2 has fixed k and D.
  std::size_t k = 0;            ///< Algorithm 2 k: index in the fbar series (0-based).
  double d = 0.0;               ///< Algorithm 2 D = F_max - min(fbar_1..k) [N].
  double f_min = 0.0;           ///< min(fbar_1..k) [N], the offset of f*.
  bool stop = false;            ///< Latched stop command.
  std::size_t stop_index = 0;   ///< Raw index at which stop was commanded (valid if stop).
  double stop_t = 0.0;          ///< Time at which stop was commanded (valid if stop).
  int stop_key_point = 0;       ///< Key point at which the stop was commanded (valid if stop).
  /// The stop came from the plausibility bound `cancellous_deadline` (valid if stop).
  bool stop_implausible = false;
  int num_key_points = 0;  ///< Valid entries in key_points (also those after the stop).
  std::array<KeyPoint, 6> key_points{};  ///< Key points in order 1..num_key_points.
};

/** @brief Human-readable reason of a latched stop (the StopCommand's reason); "" if none. */
std::string stopReason(const RecognizerOutput& out);

/**
 * @brief Online drilling-state recognizer fed one raw thrust sample at a time.
 *
 * Cost: O(1) per raw sample plus O(window) per completed averaged sample. Memory: the running
 * maxima of fbar before key point 2 (released at key point 2); nothing else grows.
 */
class StateRecognizer {
 public:
  /** @brief Output type of push(). */
  using Output = RecognizerOutput;

  /**
   * @brief Construct with validated parameters.
   * @throws std::invalid_argument if params.validate() fails.
   */
  explicit StateRecognizer(const RecognizerParams& params = RecognizerParams());

  /**
   * @brief Feed one raw thrust sample.
   * @param t time [s] of the sample.
   * @param raw_force thrust force [N] (tared: about 0 before contact).
   * @return the state after this sample.
   * @throws std::invalid_argument if raw_force or t is not finite.
   */
  const Output& push(double t, double raw_force);

  /** @brief Forget everything (parameters kept). */
  void reset();

  /** @brief Latest output. */
  const Output& output() const { return out_; }

  /** @brief Parameters in use. */
  const RecognizerParams& params() const { return params_; }

  /** @brief Eq. 14 + Eq. 15 for a given fbar, with the given f_min and D. */
  static double feature(const RecognizerParams& p, double fbar, double f_min, double d);

 private:
  void processAverage(double f_block);
  void onFiltered(double fbar);
  void addKeyPoint(int id, std::size_t index, double t);
  void commandStop();
  void setLayerState(DrillingState s);

  RecognizerParams params_;
  Output out_;

  // Raw accumulation.
  std::size_t raw_count_ = 0;
  double t_last_ = 0.0;
  int block_samples_ = 0;  // params_.blockSamples()
  double block_sum_ = 0.0;
  int block_n_ = 0;

  // Eq. 13 ring buffer.
  std::vector<double> ring_;
  std::size_t ring_pos_ = 0;
  std::size_t ring_fill_ = 0;
  std::size_t filtered_count_ = 0;  // number of fbar values produced
  std::size_t cur_raw_index_ = 0;   // raw index at which the current fbar became available
  double cur_t_ = 0.0;

  // Algorithm 2.
  double f_max_ = 0.0;
  double f_min_ = 0.0;
  bool contact_ = false;
  struct Record {
    double fbar;
    std::size_t raw_index;
    double t;
  };
  std::vector<Record> records_;  // strictly increasing running maxima of fbar before k

  // State machine counters.
  int run_ = 0;                // length of the current confirming run
  int punctured_samples_ = 0;  // averaged samples since key point 2 (cancellous_deadline)
  std::size_t run_start_ = 0;  // raw index of the first sample of that run
  double run_start_t_ = 0.0;
  int delay_left_ = -1;  // averaged samples until stop after key point 4 (-1: inactive)
  double inner_peak_ = 0.0;
  std::size_t inner_peak_index_ = 0;
  double inner_peak_t_ = 0.0;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_STATE_RECOGNIZER_HPP_
