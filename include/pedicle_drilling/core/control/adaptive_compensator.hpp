/**
 * @file adaptive_compensator.hpp
 * @brief The paper's model-based prediction, corrected online from the tracker: a compensator
 *        for a patient who no longer moves exactly as the model identified from them.
 *
 * The paper's compensator (Algorithm 1) predicts the vertebra's displacement p(t) from the
 * ventilator's tidal volume through the patient's identified model and never looks at the tracker
 * while drilling. A patient on the table differs from the recording the model was identified
 * from: the slope, the lag behind the volume and the baseline change (doc/simulator_physics.md,
 * "Patient population"). This compensator fits, on every tracker sample, along each predicted
 * model axis j (world direction u_j):
 *
 *     m_j(t_k) = b_j + a p_j(t_k - tau)
 *
 * a common gain a, lag tau and a baseline b_j per axis by least squares. The lag is the grid
 * candidate of least residual over the samples weighted by exp(-age / lag_forgetting_time_s)
 * (a patient's lag is a property of the patient: a long memory), re-chosen only while the two
 * memories' gains agree within `gain_agreement` (a change of gain in progress looks like a lead
 * to the long memory) and when its residual is `lag_switch_margin` below the current lag's; the
 * gain and the baseline, at
 * that lag, over the samples weighted by exp(-age / forgetting_time_s) (they change within a
 * breath or two: a short memory). The gain has a prior towards 1 (gain_prior_mm2, as a sample
 * of that many mm^2 of variance with gain 1). Its
 * prediction is b + a p(t - tau), bounded so that no tracker input moves the drill further than
 * `max_correction_mm` from where the paper's compensator would put it (the offset found at the
 * registration kept):
 *
 *  - a sample whose residual against the current prediction exceeds `gate_mm` is not used (a
 *    glitch, a reflection, a tracker jump: the safety monitor judges it, the fit never follows it);
 *  - `disagree_samples` such samples in a row mean that model and tracker disagree beyond what a
 *    slope, lag and baseline explain (a marker that moved on the bone, a patient who moved, a lost
 *    registration). The compensator then stops the trial (its observeMarker throws, which the
 *    planner turns into a stop with retreat naming it) rather than hold the feed and re-estimate:
 *    the drill is in bone, the bone's motion is not understood, and the way on is a new
 *    registration that only the surgeon can decide (the monitor's 1.2 mm H1 bound would stop the
 *    drill at the next sample anyway; this says why).
 *
 * Written by us. The idea of correcting a surrogate-driven motion model online from sparse
 * direct measurements is the radiotherapy literature's (e.g. Seppenwoolde et al. 2007, the
 * CyberKnife Synchrony model updated from the periodic X-ray images, Med. Phys. 34(7):2774).
 */
#ifndef PEDICLE_DRILLING_CORE_ADAPTIVE_COMPENSATOR_HPP_
#define PEDICLE_DRILLING_CORE_ADAPTIVE_COMPENSATOR_HPP_

#include <Eigen/Core>

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "pedicle_drilling/core/common/param_table.hpp"
#include "pedicle_drilling/core/control/compensator_interface.hpp"

namespace pedicle_drilling::core {

/** @brief Parameters of the AdaptiveModelCompensator (settings by these names). */
struct AdaptiveModelParams {
  double forgetting_time_s = 2.0;  ///< gain and baseline: weight exp(-age / this) [s], (0.1, 60]
  double lag_forgetting_time_s = 20.0;  ///< lag: weight exp(-age / this) [s], (0.1, 120]
  double gain_min = 0.5;                ///< lower bound of the fitted gain a, [0.1, 1]
  double gain_max = 2.0;                ///< upper bound of the fitted gain a, [1, 10]
  double gain_agreement = 0.05;    ///< lag re-chosen only when the gains agree this well, (0, 1]
  double lag_switch_margin = 0.2;  ///< a new lag needs this much less residual, [0, 0.9]
  double gain_prior_mm2 = 1.0;     ///< weight of the prior a = 1 [mm^2], [0, 1e4]
  double lag_max_s = 0.1;          ///< lag candidates in [-lag_max_s, lag_max_s] [s], [0, 0.5]
  double lag_step_s = 0.01;        ///< spacing of the lag candidates [s], [0.001, 0.1]
  double max_correction_mm = 2.0;  ///< bound on the departure from the model [mm], (0, 20]
  double gate_mm = 1.2;            ///< a sample further than this from the prediction is unused
  int disagree_samples = 3;        ///< unused samples in a row that stop the trial, [1, 100]

  /** @brief @throws std::invalid_argument naming the field. */
  void validate() const;
  /** @brief The declaration of every field. */
  static const ParamTable<AdaptiveModelParams>& table();
};

/**
 * @brief The paper's prediction (PaperCompensator), corrected online from the tracked marker for
 *        the patient's gain, lag and baseline (see the file's description).
 */
class AdaptiveModelCompensator : public CompensatorInterface {
 public:
  AdaptiveModelCompensator();
  ~AdaptiveModelCompensator() override;
  void configure(const CompensatorSettings& settings) override;
  void setPatient(const MotionModel& model, const CompensationParams& params) override;
  void setVentilator(const VentilatorSettings& settings) override;
  void setBreathStart(double t) override;
  /**
   * @brief A tracker sample: used for the fit unless gated.
   * @throws std::runtime_error when model and tracker disagree (disagree_samples gated in a row).
   */
  void observeMarker(double stamp, const Eigen::Vector3d& position_world) override;
  bool ready() const override { return paper_.ready(); }
  Eigen::Vector3d displacement(double t) const override;
  std::vector<double> velocitySteps(double t0, double t1) const override;
  std::string describe() const override;
  std::vector<std::string> parameterNames() const override;

  /** @brief The fitted gain (1 before two samples). */
  double gain() const { return gain_; }
  /** @brief The chosen lag [s] (0 before two samples). */
  double lag() const { return lag_; }
  /** @brief Samples used by the fit. */
  int samplesUsed() const { return used_; }
  /** @brief Samples gated out. */
  int samplesGated() const { return gated_total_; }
  /** @brief The parameters in use. */
  const AdaptiveModelParams& params() const { return p_; }

 private:
  /// Weighted sums of one lag candidate, per predicted axis (x: model, y: tracked).
  struct Sums {
    std::array<double, 3> x{}, y{}, xx{}, xy{}, yy{};
  };
  /// A world vector's components along each predicted axis (0 on the others).
  std::array<double, 3> axes(const Eigen::Vector3d& v) const;
  /// The model's displacement along each predicted axis at t [m].
  std::array<double, 3> modelAxes(double t) const;
  /// The fitted prediction along each predicted axis at t, bounded [m], given the model's
  /// there (`now`, modelAxes(t)).
  std::array<double, 3> fittedAxes(double t, const std::array<double, 3>& now) const;
  void refit();

  AdaptiveModelParams p_;
  PaperCompensator paper_;
  std::array<bool, 3> axis_used_{{false, false, false}};
  std::array<Eigen::Vector3d, 3> axis_dir_;
  std::vector<double> lags_;
  /// Weighted sums with a memory of `time_s`, one per lag candidate.
  struct Memory {
    double time_s = 1.0;
    std::vector<Sums> sums;
    double weight = 0.0;  ///< the sum of the weights
    void decay(double dt);
    /// The gain of candidate i (bounded, with the prior), its residual and baselines.
    double fit(std::size_t i, const std::array<bool, 3>& used, const AdaptiveModelParams& p,
               double* residual, std::array<double, 3>* baseline) const;
  };
  Memory short_;  ///< gain and baseline
  Memory long_;   ///< lag
  double last_stamp_ = 0.0;
  std::optional<std::array<double, 3>> offset_;  ///< tracked minus model at the first sample
  double gain_ = 1.0;
  double lag_ = 0.0;
  std::size_t lag_index_ = 0;         ///< into lags_ (0: no lag)
  std::array<double, 3> baseline_{};  ///< b_j minus the offset [m]
  int used_ = 0;
  int gated_in_row_ = 0;
  int gated_total_ = 0;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_ADAPTIVE_COMPENSATOR_HPP_
