// The motion compensator as a plugin interface: ventilator settings, breath phase,
// the patient's motion model and the tracked marker in; the predicted bone displacement out,
// from which the CompensationPlanner makes the feed-axis and the lateral reference (feed +
// displacement, cut into the 125 ms segments). Our paper compensator (Algorithm 1's prediction,
// DisplacementPredictor) and a tracker-feedback baseline implement it; the CompensationPlanner
// nodelet and the core engine (trial_engine, campaign) run whichever class is named. pluginlib
// loads outside classes through this base class (`pedicle_drilling::core::CompensatorInterface`);
// the header has no ROS type.
#ifndef PEDICLE_DRILLING_CORE_COMPENSATOR_INTERFACE_HPP_
#define PEDICLE_DRILLING_CORE_COMPENSATOR_INTERFACE_HPP_

#include <Eigen/Core>

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "pedicle_drilling/core/breathing/motion_model.hpp"
#include "pedicle_drilling/core/breathing/ventilator.hpp"
#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling::core {

struct CompensationParams;
class DisplacementPredictor;

/** @brief Parameters by name, as text (`name=value` on a command line, a ROS parameter map). */
using CompensatorSettings = std::vector<std::pair<std::string, std::string>>;

/**
 * @brief A predictor of the vertebra's displacement that the drill follows.
 *
 * Life cycle: default construction (pluginlib), configure() once, setPatient() for a trial; then,
 * in any order as they come, setVentilator(), setBreathStart() and observeMarker(); the planner
 * asks displacement() once ready(). One object serves one trial. Not thread-safe.
 *
 * Time is the driver's clock in seconds (ROS time on the nodelet, simulated time in the engine).
 * Positions are metres in the planner's world frame; displacement() may have any constant
 * origin: the planner only uses its change since the marker registration. The planner asks for
 * times up to one segment period plus its latency ahead of the last input: a compensator
 * predicts, it is never told the future.
 */
class CompensatorInterface {
 public:
  virtual ~CompensatorInterface() = default;

  /**
   * @brief Set the parameters (unnamed ones keep their defaults) and check them.
   * @throws std::invalid_argument whose message starts with the offending name.
   */
  virtual void configure(const CompensatorSettings& settings) = 0;
  /**
   * @brief The patient's identified model and the planner's conventions (which model axes are
   *        predicted, their world directions, the drill axis; CompensationParams).
   */
  virtual void setPatient(const MotionModel& model, const CompensationParams& params) = 0;
  /** @brief New ventilator settings. @throws std::invalid_argument on invalid settings. */
  virtual void setVentilator(const VentilatorSettings& settings) = 0;
  /** @brief Start time [s] of a breath (TidalVolume stamp - time in breath). */
  virtual void setBreathStart(double t) = 0;
  /**
   * @brief A tracked marker position [m] measured at `stamp`, rotated into the world frame
   *        (origin arbitrary). Called for every tracker sample from the registration on, after
   *        the sample's predicted pose for the safety monitor was taken. Default: ignored.
   */
  virtual void observeMarker(double stamp, const Eigen::Vector3d& position_world);
  /** @brief True once displacement() can be asked. */
  virtual bool ready() const = 0;
  /** @brief Predicted displacement [m, world] at time t. @throws std::logic_error if !ready(). */
  virtual Eigen::Vector3d displacement(double t) const = 0;
  /**
   * @brief Times in (t0, t1] where the predicted velocity steps (knots of the exact segment
   *        profile). Default: none.
   */
  virtual std::vector<double> velocitySteps(double t0, double t1) const;
  /** @brief One line describing the parameters in use (for the log). */
  virtual std::string describe() const = 0;
  /** @brief Names of the parameters configure() accepts. */
  virtual std::vector<std::string> parameterNames() const = 0;
};

/**
 * @brief The paper's compensator (Algorithm 1 lines 1-4): the ventilator's tidal volume and flow
 *        through the patient's identified model (DisplacementPredictor). No parameters of its own:
 *        the axes and the latency are the planner's.
 */
class PaperCompensator : public CompensatorInterface {
 public:
  PaperCompensator();
  ~PaperCompensator() override;
  void configure(const CompensatorSettings& settings) override;
  void setPatient(const MotionModel& model, const CompensationParams& params) override;
  void setVentilator(const VentilatorSettings& settings) override;
  void setBreathStart(double t) override;
  bool ready() const override;
  Eigen::Vector3d displacement(double t) const override;
  std::vector<double> velocitySteps(double t0, double t1) const override;
  std::string describe() const override;
  std::vector<std::string> parameterNames() const override { return {}; }
  /** @brief The prediction (nullptr before setPatient()). */
  const DisplacementPredictor* predictor() const { return predictor_.get(); }

 private:
  std::unique_ptr<DisplacementPredictor> predictor_;
  std::optional<VentilatorSettings> settings_;  // arrived before setPatient()
  std::optional<double> breath_start_;
};

/** @brief Parameters of the tracker-feedback baseline (TrackedMarkerCompensator). */
struct TrackedMarkerParams {
  /** @brief false: hold the last measurement; true: extrapolate it at the velocity of the last
   *         two measurements (a constant-velocity predictor). */
  bool extrapolate = false;
  /** @brief Extrapolate at most this far past the last measurement [s], (0, 10]. */
  double max_horizon_s = 0.5;
  /** @throws std::invalid_argument naming the field. */
  void validate() const;
  /** @brief The declaration of the fields (the class's settings, by these names). */
  static const ParamTable<TrackedMarkerParams>& table();
};

/**
 * @brief Baseline: reactive compensation by tracker feedback. The drill follows the bone's last
 *        tracked position (optionally extrapolated at constant velocity), as a system without a
 *        motion model does; it inherits the tracker's rate (8 Hz on the paper's bench) and delay,
 *        the limitation that model-based prediction is meant to overcome (Bowthorpe and Tavakoli,
 *        "Physiological organ motion prediction and compensation based on multirate, delayed,
 *        and unregistered measurements in robot-assisted surgery and therapy", IEEE/ASME Trans.
 *        Mechatronics 21(2):900-911, 2016). Written by us. It ignores the ventilator and the
 *        patient model; the marker moves with the vertebra (rigid body, no rotation assumed).
 */
class TrackedMarkerCompensator : public CompensatorInterface {
 public:
  TrackedMarkerCompensator() = default;
  void configure(const CompensatorSettings& settings) override;
  void setPatient(const MotionModel&, const CompensationParams&) override {}
  void setVentilator(const VentilatorSettings&) override {}
  void setBreathStart(double) override {}
  void observeMarker(double stamp, const Eigen::Vector3d& position_world) override;
  bool ready() const override { return count_ > 0; }
  Eigen::Vector3d displacement(double t) const override;
  std::string describe() const override;
  std::vector<std::string> parameterNames() const override;

 private:
  TrackedMarkerParams p_;
  int count_ = 0;
  double last_t_ = 0.0;
  Eigen::Vector3d last_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity_ = Eigen::Vector3d::Zero();
};

/**
 * @brief Any compensator behind a guard: an exception one of its trial-time calls throws
 *        (setVentilator, setBreathStart, observeMarker, ready, displacement, velocitySteps: a
 *        plugin's bug, a Python error) never leaves the guard. The guard keeps the error, which
 *        its owner (TrialSequencer) turns into a stop with retreat naming it, and from then on
 *        answers by itself: not ready, the last displacement it gave (the drill holds its lateral
 *        course while it backs out), no velocity steps. configure() and setPatient() pass their
 *        exceptions on (a refusal before the trial).
 */
class GuardedCompensator : public CompensatorInterface {
 public:
  /** @throws std::invalid_argument if @p inner is null. */
  explicit GuardedCompensator(std::unique_ptr<CompensatorInterface> inner);
  void configure(const CompensatorSettings& settings) override { inner_->configure(settings); }
  void setPatient(const MotionModel& model, const CompensationParams& params) override {
    inner_->setPatient(model, params);
  }
  void setVentilator(const VentilatorSettings& settings) override;
  void setBreathStart(double t) override;
  void observeMarker(double stamp, const Eigen::Vector3d& position_world) override;
  bool ready() const override;
  Eigen::Vector3d displacement(double t) const override;
  std::vector<double> velocitySteps(double t0, double t1) const override;
  std::string describe() const override;
  std::vector<std::string> parameterNames() const override { return inner_->parameterNames(); }
  /** @brief The first error a call threw ("" while none did). */
  const std::string& error() const { return error_; }

 private:
  void latch(const char* call, const std::exception* e) const;
  /// Runs @p body unless an error came before; true if it returned, false if it threw.
  bool guard(const char* call, const std::function<void()>& body) const;

  std::unique_ptr<CompensatorInterface> inner_;
  mutable std::string error_;
  mutable Eigen::Vector3d last_ = Eigen::Vector3d::Zero();  // the last displacement given
};

/** @brief The built-in compensators' names, as pluginlib declares them. */
std::vector<std::string> builtinCompensatorNames();

/**
 * @brief A built-in compensator by its pluginlib name ("pedicle_drilling/PaperCompensator",
 *        "pedicle_drilling/TrackedMarkerCompensator"), configured.
 * @throws std::invalid_argument for an unknown name (listing the known ones) or bad settings.
 */
std::unique_ptr<CompensatorInterface> makeBuiltinCompensator(const std::string& name,
                                                             const CompensatorSettings& settings);

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_COMPENSATOR_INTERFACE_HPP_
