// The drilling-state recognizer as a plugin interface: raw thrust samples in, the
// state and the stop decision out. Our paper recognizer (StateRecognizer) and the literature
// baseline implement it; the StateRecognizer nodelet, the core engine (trial_engine, campaign)
// and the offline `recognize` tool run whichever class is named. pluginlib loads outside classes
// through this base class (`pedicle_drilling::core::RecognizerInterface`); the header has no ROS
// type, so a plugin needs nothing of ROS but pluginlib's export macro.
#ifndef PEDICLE_DRILLING_CORE_RECOGNIZER_INTERFACE_HPP_
#define PEDICLE_DRILLING_CORE_RECOGNIZER_INTERFACE_HPP_

#include <array>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "pedicle_drilling/core/common/param_table.hpp"
#include "pedicle_drilling/core/drilling/state_recognizer.hpp"

namespace pedicle_drilling::core {

/** @brief Parameters by name, as text (`name=value` on a command line, a ROS parameter map). */
using RecognizerSettings = std::vector<std::pair<std::string, std::string>>;

/**
 * @brief One sample of the F/T sensor with what the drill was doing then, for a recognizer that
 *        reads more than the thrust (RecognizerInterface::pushSample). Forces and torques are
 *        the sensor's, in its frame, as it reports them (tared with the thrust). Only `t` and
 *        `thrust_n` are checked before a class sees the sample; a class that reads another
 *        field checks it (NaN: unknown, or a faulty axis).
 */
struct RecognizerSample {
  double t = 0.0;                     ///< sample time [s]
  double thrust_n = 0.0;              ///< the thrust along the configured axis: push()'s [N]
  std::array<double, 3> force_n{};    ///< the whole force (x, y, z) [N]
  std::array<double, 3> torque_nm{};  ///< the whole torque (x, y, z) [N m]
  /// The feed joint's position, latest heard (the drill's advance along its axis) [m]
  double feed_depth_m = std::numeric_limits<double>::quiet_NaN();
  /// The spindle's speed, latest heard [rpm]
  double spindle_rpm = std::numeric_limits<double>::quiet_NaN();
  /// The feed joint's commanded position (its controller's desired), latest heard [m]
  double feed_command_m = std::numeric_limits<double>::quiet_NaN();
  /// The latest tracked marker position, in the tracker's frame [m]
  std::array<double, 3> tracker_m{std::numeric_limits<double>::quiet_NaN(),
                                  std::numeric_limits<double>::quiet_NaN(),
                                  std::numeric_limits<double>::quiet_NaN()};
  /// That tracker sample's stamp [s]
  double tracker_stamp = std::numeric_limits<double>::quiet_NaN();
};

/**
 * @brief A drilling-state recognizer fed one raw thrust sample at a time (push), or one whole
 *        wrench sample with its context (pushSample: by default the thrust to push).
 *
 * Life cycle: default construction (pluginlib), configure() once, then push() samples; reset()
 * starts a new trial with the same parameters. The output is RecognizerOutput: a plugin fills at
 * least `state`, `layer_state`, `stop` (latched until reset), `stop_t`, `stop_index` and
 * `new_average` (true when it has a new value for the DrillingState message); the rest it may
 * leave at their defaults (key points, k, D). Not thread-safe.
 */
class RecognizerInterface {
 public:
  virtual ~RecognizerInterface() = default;

  /**
   * @brief Set the parameters (unnamed ones keep their defaults) and check them.
   * @throws std::invalid_argument whose message starts with the offending name.
   */
  virtual void configure(const RecognizerSettings& settings) = 0;
  /** @brief Forget the trial (parameters kept). */
  virtual void reset() = 0;
  /**
   * @brief One raw thrust sample.
   * @throws std::invalid_argument if t or raw_force is not finite.
   */
  virtual const RecognizerOutput& push(double t, double raw_force) = 0;
  /**
   * @brief One sample with the whole wrench and the drill's context. Every caller of a
   *        recognizer (the StateRecognizer nodelet, the core engine) calls this; the default
   *        passes the thrust to push(), so that a class reading only the thrust overrides
   *        push() alone. A class that reads the wrench or the context overrides this.
   * @throws std::invalid_argument as push().
   */
  virtual const RecognizerOutput& pushSample(const RecognizerSample& sample) {
    return push(sample.t, sample.thrust_n);
  }
  /** @brief Latest output. */
  virtual const RecognizerOutput& output() const = 0;
  /** @brief The reason of the latched stop, for the StopCommand ("" if none). */
  virtual std::string stopReason() const = 0;
  /** @brief One line describing the parameters in use (for the log). */
  virtual std::string describe() const = 0;
  /** @brief Names of the parameters configure() accepts. */
  virtual std::vector<std::string> parameterNames() const = 0;
};

/** @brief The paper's recognizer (StateRecognizer, Sec. IV-C/D) behind the interface. */
class PaperRecognizer : public RecognizerInterface {
 public:
  PaperRecognizer() = default;
  /** @brief With parameters already in their struct (validated here). */
  explicit PaperRecognizer(const RecognizerParams& params);
  void configure(const RecognizerSettings& settings) override;
  void reset() override { recognizer_.reset(); }
  const RecognizerOutput& push(double t, double raw_force) override {
    return recognizer_.push(t, raw_force);
  }
  const RecognizerOutput& output() const override { return recognizer_.output(); }
  std::string stopReason() const override;
  std::string describe() const override;
  std::vector<std::string> parameterNames() const override;
  /** @brief Parameters in use. */
  const RecognizerParams& params() const { return recognizer_.params(); }

 private:
  StateRecognizer recognizer_;
};

/** @brief Parameters of the force-difference breakthrough baseline (ForceDifferenceRecognizer). */
struct ForceDifferenceParams {
  /// Raw samples per block mean: a count, not a duration (50: the paper recognizer's block of
  /// 0.15 s at the simulated 1000/3 Hz sensor; at another rate, set it from the rate).
  int pre_average = 50;
  double contact_force_n = 1.0;     ///< block mean above this: the drill is in bone [N]
  double process_noise = 0.001;     ///< Kalman q: variance of the FDSS's change per block [N^2]
  double measurement_noise = 0.01;  ///< Kalman r: variance of one FDSS [N^2]
  double drop_threshold_n = 0.05;   ///< filtered FDSS below -this: a falling force [N/block]
  int drop_confirm = 3;             ///< consecutive falling blocks that make a breakthrough
  int stop_at_breakthrough = 2;     ///< stop at this breakthrough (2: the second cortex)
  double rearm_rise_n = 0.015;      ///< filtered FDSS above +this re-arms the detector [N/block]
  int rise_confirm = 1;             ///< consecutive rising blocks that re-arm it (a cortex entry)
  /**
   * @brief Stop at this cortex entry (0: never; the contact is the first entry, each re-arm
   *        after a breakthrough the next): 2 stops at the inner cortex's entry, the task's stop
   *        layer, where the breakthrough detector alone can only stop at its exit.
   */
  int stop_at_entry = 0;
  /** @brief Checks every field against its declaration. @throws std::invalid_argument naming it. */
  void validate() const;
  /** @brief The declaration of the fields (the class's settings, by these names). */
  static const ParamTable<ForceDifferenceParams>& table();
};

/**
 * @brief Literature baseline: breakthrough detection on the force difference between successive
 *        samples (FDSS) filtered by a Kalman filter, after Ong and Bouazza-Marouf, "The detection
 *        of drill bit break-through for the enhancement of safety in mechatronic assisted
 *        orthopaedic drilling", Mechatronics 9(6):565-588, 1999. Their method detects the
 *        imminent break-through of a cortex from the filtered FDSS falling below a threshold;
 *        written by us from that description. Our adaptation to a vertebra: the FDSS is taken
 *        on block means of `pre_average` raw samples, a breakthrough is `drop_confirm`
 *        consecutive falling blocks while in bone, the detector re-arms when the force rises
 *        again (the next cortex), and the stop comes at the `stop_at_breakthrough`-th one (the
 *        outer cortex's breakthrough into cancellous bone is the first). States: idle before
 *        contact, outer cortical until the first breakthrough, cancellous until the force rises
 *        again, inner cortical after. With `stop_at_entry` 2 it stops where the force rises
 *        again after the first breakthrough (the inner cortex's entry; added for the leaderboard).
 */
class ForceDifferenceRecognizer : public RecognizerInterface {
 public:
  ForceDifferenceRecognizer() = default;
  void configure(const RecognizerSettings& settings) override;
  void reset() override;
  const RecognizerOutput& push(double t, double raw_force) override;
  const RecognizerOutput& output() const override { return out_; }
  std::string stopReason() const override;
  std::string describe() const override;
  std::vector<std::string> parameterNames() const override;

 private:
  void onBlock(double f);
  void latchStop();

  ForceDifferenceParams p_;
  RecognizerOutput out_;
  std::size_t raw_count_ = 0;
  int block_n_ = 0;
  double block_sum_ = 0.0;
  double cur_t_ = 0.0;
  bool have_previous_ = false;
  double previous_ = 0.0;
  double x_ = 0.0;  // Kalman estimate of the FDSS
  double P_ = 1.0;  // its variance
  bool in_bone_ = false;
  bool armed_ = true;
  int rising_ = 0;  // consecutive blocks above rearm_rise_n while disarmed
  int falling_ = 0;
  int breakthroughs_ = 0;
  int entries_ = 0;  // cortex entries: the contact, then each re-arm
};

/**
 * @brief Any recognizer behind a guard: an exception its push(), reset() or stopReason() throws
 *        (a plugin's bug, a Python error) never leaves the guard. It latches a stop instead
 *        (state `stopped`, new_average set, so that the stop is published) whose stopReason()
 *        names the class's error; every later push() reports that stop until a reset() that
 *        succeeds. Samples are not checked here (the wrapped class refuses non-finite ones, and
 *        that refusal is a stop too).
 */
class GuardedRecognizer : public RecognizerInterface {
 public:
  /** @throws std::invalid_argument if @p inner is null. */
  explicit GuardedRecognizer(std::unique_ptr<RecognizerInterface> inner);
  void configure(const RecognizerSettings& settings) override { inner_->configure(settings); }
  void reset() override;
  const RecognizerOutput& push(double t, double raw_force) override;
  const RecognizerOutput& pushSample(const RecognizerSample& sample) override;
  const RecognizerOutput& output() const override;
  std::string stopReason() const override;
  std::string describe() const override { return inner_->describe(); }
  std::vector<std::string> parameterNames() const override { return inner_->parameterNames(); }
  /** @brief The class's error that latched the stop ("" while it has not failed). */
  const std::string& error() const { return error_; }

 private:
  void latchError(double t, const std::string& what);
  /** @brief @p push_one (a push to the inner class) behind the guard, for a sample at @p t. */
  template <typename Push>
  const RecognizerOutput& guarded(double t, Push push_one);

  std::unique_ptr<RecognizerInterface> inner_;
  std::string error_;
  RecognizerOutput failed_;  // the output while error_ is set
  std::size_t samples_ = 0;  // raw samples pushed since the reset
};

/** @brief The built-in recognizers' names, as pluginlib declares them. */
std::vector<std::string> builtinRecognizerNames();

/**
 * @brief A built-in recognizer by its pluginlib name ("pedicle_drilling/PaperRecognizer",
 *        "pedicle_drilling/ForceDifferenceRecognizer"), configured.
 * @throws std::invalid_argument for an unknown name (listing the known ones) or bad settings.
 */
std::unique_ptr<RecognizerInterface> makeBuiltinRecognizer(const std::string& name,
                                                           const RecognizerSettings& settings);

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_RECOGNIZER_INTERFACE_HPP_
