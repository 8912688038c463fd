/**
 * @file ventilator.hpp
 * @brief Volume-controlled ventilator model: flow F(t) and tidal volume Tv(t) from the settings
 *        (paper Sec. IV-A, Eq. 10-12), with shape constants solved by Ceres so that every breath
 *        inspires exactly Tv_max and expires exactly as much.
 *
 * Cycle layout (period T = 60 / rate):
 *   [0, Ti - Tp)   inspiratory flow, one of the six shapes of Fig. 10a, amplitude A
 *   [Ti - Tp, Ti)  inspiratory pause (zero flow), optional
 *   [Ti, T)        passive exponential expiration F = -P exp(-(t - Ti) / tau)
 * with Ti = T * I / (I + E). The inspiratory amplitude A and, depending on the settings, either
 * the expiratory time constant tau (given the peak expiratory to inspiratory flow ratio) or the
 * expiratory peak P (given tau) are solved by Ceres' DOGLEG trust region (the paper's method)
 * from two equality constraints that hold exactly:
 *   integral of inspiratory flow            = Tv_max
 *   integral of expiratory flow             = -Tv_max
 * plus, in ratio mode, P = ratio * peak inspiratory flow. Because each cycle balances to solver
 * precision and Tv(t) is evaluated per cycle from its closed-form integral, the volume never
 * drifts, whatever the number of cycles.
 *
 * The paper's own constants (a = 300, b = 0.4602, c = 0.0753) cannot satisfy Eq. 11: a 1.5 x peak
 * exponential that also reaches zero flow at the end of a 10/3 s expiration expels at most
 * about 447 ml. We therefore drop the end-of-expiration continuity (the flow jumps from a small
 * residual expiratory flow to inspiration, as real ventilators do when expiratory time is short)
 * and keep the volume balance and the peak ratio. See paperConstantsResiduals().
 */
#pragma once

#include <string>
#include <vector>

#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling::core {

/** @brief The six standard inspiratory flow shapes of Fig. 10a. */
enum class InspiratoryWaveform {
  kSquare,
  kAscendingRamp,
  kDescendingRamp,
  kSine,
  kExponentialRise,
  kExponentialDecay
};

/** @brief Parses "square", "ascending_ramp", ... ; returns false on an unknown name. */
bool parseWaveform(const std::string& name, InspiratoryWaveform* waveform);

/** @brief Canonical name of a waveform ("square", "ascending_ramp", ...). */
std::string waveformName(InspiratoryWaveform waveform);

/** @brief All accepted waveform names, for help texts and error messages. */
std::vector<std::string> waveformNames();

/** @brief How the expiratory exponential is specified. */
enum class ExpiratorySpec {
  kPeakRatio,    ///< peak expiratory flow = ratio x peak inspiratory flow (paper: 1.5)
  kTimeConstant  ///< tau given (e.g. R*C of an RC lung, 0.4 s in jCpSim)
};

/** @brief Ventilator settings, all in SI-like clinical units (ml, breaths/min, s). */
struct VentilatorSettings {
  double tv_max_ml = 500.0;     ///< set tidal volume, ml, (0, 3000]
  double rate_bpm = 12.0;       ///< breaths per minute, (0, 60]
  double ie_inspiratory = 1.0;  ///< I of the I:E ratio, > 0
  double ie_expiratory = 2.0;   ///< E of the I:E ratio, > 0
  InspiratoryWaveform waveform = InspiratoryWaveform::kSquare;
  double pause_fraction = 0.0;  ///< inspiratory pause as a fraction of Ti, [0, 0.5]
  ExpiratorySpec expiratory_spec = ExpiratorySpec::kPeakRatio;
  double peak_flow_ratio = 1.5;   ///< used with kPeakRatio, [0.2, 10]
  double expiratory_tau_s = 0.4;  ///< used with kTimeConstant, (0, 10]
  /// Shape parameter of the ramps: flow at the low end as a fraction of the peak, [0, 1).
  double ramp_start_fraction = 0.0;
  /// Shape parameter of the exponential rise/decay: time constant as a fraction of the flow
  /// period, (0, 10].
  double exponential_shape = 0.3;

  /** @brief Throws std::invalid_argument naming the first out-of-range field. */
  void validate() const;

  /** @brief The declaration of every setting: name, range, unit (the ROS parameters too). */
  static const ParamTable<VentilatorSettings>& table();
};

/** @brief Parses an I:E ratio "a:b" with positive numbers; returns false when malformed. */
bool parseIeRatio(const std::string& text, double* inspiratory, double* expiratory);

/** @brief Instantaneous ventilator output. */
struct VentilatorSample {
  double t = 0.0;          ///< time, s
  double flow_ml_s = 0.0;  ///< flow, ml/s (positive = inspiration)
  double volume_ml = 0.0;  ///< tidal volume above end-expiratory volume, ml
};

/** @brief Residuals of a candidate set of constants against the balance constraints. */
struct ConstraintResiduals {
  double inspired_minus_tv_ml = 0.0;  ///< inspired volume - Tv_max
  double expired_plus_tv_ml = 0.0;    ///< expired (negative) volume + Tv_max
  double end_flow_jump_ml_s = 0.0;    ///< |flow just before the next breath| (continuity)
  double peak_ratio_error = 0.0;      ///< peak expiratory / inspiratory flow - requested ratio
};

/** @brief Ventilator model of one setting; immutable, cheap to evaluate. */
class VentilatorModel {
 public:
  /** @brief Validates the settings and solves the shape constants (throws on failure). */
  explicit VentilatorModel(const VentilatorSettings& settings);

  const VentilatorSettings& settings() const { return settings_; }
  double period() const { return period_; }                     ///< T, s
  double inspiratoryTime() const { return inspiratory_time_; }  ///< Ti incl. pause, s
  double flowTime() const { return flow_time_; }                ///< Ti - pause, s
  double inspiratoryAmplitude() const { return amplitude_; }    ///< A, ml/s
  double expiratoryPeak() const { return expiratory_peak_; }    ///< P, ml/s
  double expiratoryTau() const { return expiratory_tau_; }      ///< tau, s
  double peakInspiratoryFlow() const;                           ///< max inspiratory flow, ml/s
  int solverIterations() const { return solver_iterations_; }

  /** @brief Flow at time tau within a cycle, tau in [0, T). */
  double flowInCycle(double tau) const;
  /** @brief Volume at time tau within a cycle (closed-form integral), tau in [0, T]. */
  double volumeInCycle(double tau) const;
  /** @brief Flow and volume at absolute time t >= 0 (cycle k starts at k T). */
  VentilatorSample sample(double t) const;
  /** @brief Samples [0, duration) at fs Hz. */
  std::vector<VentilatorSample> sampleStream(double fs_hz, double duration_s) const;
  /** @brief The balance residuals of this model's own constants. */
  ConstraintResiduals residuals() const;

 private:
  double shapeValue(double x) const;     // inspiratory shape on x in [0, 1], peak-normalised
  double shapeIntegral(double x) const;  // integral of shapeValue from 0 to x

  VentilatorSettings settings_;
  double period_ = 0.0;
  double inspiratory_time_ = 0.0;
  double flow_time_ = 0.0;  // Ti - pause
  double amplitude_ = 0.0;
  double expiratory_peak_ = 0.0;
  double expiratory_tau_ = 0.0;
  int solver_iterations_ = 0;
};

/**
 * @brief Residuals of the paper's published constants (a = 300, b = 0.4602, c = 0.0753) of
 *        Eq. 10 at Tv_max = 500 ml, T = 5 s, I:E = 1:2, against the same constraints.
 */
ConstraintResiduals paperConstantsResiduals();

/**
 * @brief Ventilator whose settings can change at run time; a change takes effect at the start
 *        of the next breath, never mid-breath. Time must be non-decreasing.
 */
class BreathScheduler {
 public:
  explicit BreathScheduler(const VentilatorSettings& settings, double start_time = 0.0);
  /**
   * @brief Queues new settings for the next breath (validated and solved now; throws on bad
   *        settings).
   */
  void requestSettings(const VentilatorSettings& settings);
  /**
   * @brief Queues new settings for the breath numbered @p from_breath, at the earliest the next
   *        one: a second scheduler that follows this one a little late (the patient's breathing,
   *        sampled at t - lag) takes a change with the same breath as its ventilator, even when
   *        the request falls between the two schedulers' breath starts.
   */
  void requestSettings(const VentilatorSettings& settings, long from_breath);
  /** @brief Output at time t; t earlier than the last call is clamped to it. */
  VentilatorSample sample(double t);
  /**
   * @brief Starts a new breath at `start_time`, which may be earlier than the last sample (time
   *        jumped back: a bag replayed in a loop, a simulation reset). Pending settings take
   *        effect with it; the breath index keeps counting. @throws std::invalid_argument for a
   *        non-finite time.
   */
  void restart(double start_time);
  /**
   * @brief Moves the current breath's start to `start_time` without counting a new breath (a
   *        breath the schedule began on its own, found on the patient's flow a little earlier or
   *        later: FlowPhasedSchedule). Times before it are sampled as it. @throws
   *        std::invalid_argument for a non-finite time.
   */
  void rephase(double start_time);
  /** @brief The last sampled time (or the start time). */
  double lastTime() const { return last_t_; }
  /** @brief Index of the breath containing the last sampled time (0-based). */
  long breathIndex() const { return breath_index_; }
  /** @brief Start time of the current breath. */
  double breathStart() const { return breath_start_; }
  const VentilatorModel& model() const { return model_; }
  bool hasPendingSettings() const { return pending_valid_; }

 private:
  /** @brief Counts a new breath; the pending settings take effect if they are due with it. */
  void beginBreath();

  VentilatorModel model_;
  VentilatorModel pending_;
  bool pending_valid_ = false;
  long pending_from_ = 0;  ///< the breath index the pending settings take effect with
  double breath_start_ = 0.0;
  double last_t_ = 0.0;
  long breath_index_ = 0;
};

}  // namespace pedicle_drilling::core
