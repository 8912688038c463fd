/**
 * @file drilling_force.hpp
 * @brief Mechanistic thrust-force law with material removal for drilling a layered bone specimen.
 *
 * Force law (per time step, while the tip advances past the deepest point cut so far):
 *
 *   F = K * D * phi_eff * [s + (1 - s) * (f_rev / f_ref)^alpha] * (n / n_ref)^(-beta)
 *
 * - f_rev: actual feed per revolution = (new cut depth this step) / (revolutions this step);
 *   it comes from the relative motion of drill tip and bone along the drill axis, so a bone moving
 *   toward the drill raises it and a bone moving away makes it zero (loss of contact).
 * - phi_eff: engaged solid fraction = radial average over the cutting lips of the bone solid
 *   fraction (BV/TV) at the depth each lip point is cutting; the conical 118 deg point makes the
 *   lips span 0.75 mm of depth, which gives the gradual rise/fall at layer entry/exit.
 * - K: calibrated to the paper's stationary peak thrusts (see doc/simulator_physics.md).
 * - s: the chisel edge's share of the thrust at f_ref, an indentation that does not grow with
 *   the chip load (s = 0: the whole thrust from the lips' power law).
 * Rigid contact (contact_stiffness_n_per_m = +inf): the tip's whole advance is cut in the step,
 * and a first-order lag of about one spindle revolution smooths the thrust while in contact
 * (the chip load is defined per flute passage; two flutes per revolution).
 *
 * Elastic contact (finite k_c): the cutting is in series with a spring. In each step the cut
 * advance u in [0, delta] (delta = tip advance beyond the cut surface) solves
 *
 *   k_c * (delta - u) = F_law(phi, u / revolutions, n),
 *
 * implicitly (monotone, unique root), and the thrust is the spring force. So the chip load can
 * never exceed what the contact transmits: as the spindle runs down the cut slows and the
 * thrust is bounded by k_c times the approach, and a stopped drill (n = 0) that the bone presses
 * against feels k_c * delta (no cutting at all).
 *
 * Cutting torque about the drill axis (the bone's resistance to the spindle's rotation):
 *
 *   T = kappa * (D / 2) * F      while the spindle turns (n > 0), else 0,
 *
 * with F the thrust above. The lips' tangential forces form a couple about the axis; their net
 * lateral force is zero for the symmetric two-lip bit, so the model adds no lateral force (the
 * sensor's spindle-synchronous lateral tone stands for the run-out). kappa is the measured ratio
 * of torque to thrust times bit radius (Orelaja et al. 2020, doc/simulator_physics.md §2c).
 *
 * No ROS headers; C++17 and Eigen only.
 */
#ifndef PEDICLE_DRILLING_CORE_DRILLING_FORCE_HPP
#define PEDICLE_DRILLING_CORE_DRILLING_FORCE_HPP

#include <limits>

#include "pedicle_drilling/core/drilling/bone_specimen.hpp"

namespace pedicle_drilling::core {

/** @brief Drill geometry and force-law constants. Defaults and sources: simulator_physics.md. */
struct DrillParameters {
  double bit_diameter_m = 2.5e-3;  ///< paper Sec. V-A: 2.5 mm
  double point_angle_deg = 118.0;  ///< standard twist-drill point angle
  /// Thrust per metre of bit diameter per unit solid fraction at f_ref and n_ref [N/m].
  /// Calibrated to the paper's stationary peak thrusts (Fig. 16 medians 3.16 / 2.88 N).
  double thrust_coefficient_n_per_m = 1373.0;
  double feed_exponent = 0.5;  ///< alpha: sub-linear size effect (bone-cutting data, doc §2)
  /// s: chisel-edge share of the thrust at f_ref, feed-independent (indentation), in [0, 1).
  /// 0.6: literature 50-70 %, calibrated with the DAQ rate against Fig. 16 (see doc).
  double chisel_edge_share = 0.6;
  double speed_exponent = 0.0;         ///< beta: cutting-speed softening at a fixed chip (doc §2)
  double ref_feed_per_rev_m = 2.5e-6;  ///< 0.5 mm/s at 12000 rpm
  double ref_spindle_rpm = 12000.0;    ///< paper's chosen speed
  /// Thrust lag time constant in spindle revolutions; used by the rigid contact only (with an
  /// elastic contact the series spring gives the dynamics).
  double lag_revolutions = 1.0;
  /// Stiffness of the elastic contact between the lips and the uncut bone, in series with the
  /// cutting [N/m]; +inf is the rigid contact (the tip's whole advance is cut at once). Only the
  /// compliance not simulated elsewhere belongs here (the arm's is the Bullet arm's).
  double contact_stiffness_n_per_m = 1.0e6;  ///< doc/simulator_physics.md, section 2
  /// kappa: cutting torque about the drill axis per unit thrust and bit radius, T = kappa (D/2) F
  /// (dimensionless, finite, >= 0; 0 switches the torque off). 1.6: a 2.5 mm bit in bovine femur,
  /// 41.2 N mm at 20.07 N and 24.2 N mm at 12.34 N (Orelaja et al. 2020, J Healthc Eng
  /// 2020:8817422); doc/simulator_physics.md, section 2c.
  double torque_thrust_ratio = 1.6;
};

/** @brief One output sample of the drilling process. */
struct ForceSample {
  double thrust_N = 0.0;  ///< thrust along the drill axis, >= 0 (bone pushes the drill back)
  Material material = Material::kAir;  ///< material at the drill tip point
  /// Rigid contact: true iff the lips cut in this step. Elastic contact: true iff the tip
  /// presses on the uncut bone (overlap > 0), cutting or, below the chisel edge's indentation
  /// force or with the spindle stopped, not.
  bool contact = false;
  double feed_per_rev_m = 0.0;    ///< actual feed per revolution this step
  double engaged_fraction = 0.0;  ///< phi_eff, radial mean solid fraction under the lips
  double overlap_m = 0.0;  ///< elastic overlap of the tip beyond the cut surface (elastic contact)
  /// Cutting torque about the drill axis [N m], >= 0: the bone resists the spindle's rotation
  /// (kappa (D/2) thrust while the spindle turns, 0 when it stands or nothing touches).
  double torque_Nm = 0.0;
};

/**
 * @brief Stateful drilling process: tracks the deepest cut, removes material, returns thrust.
 *
 * Depths are along the drill axis in the bone frame, 0 at the outer surface, positive into bone.
 * Only the tip advance beyond `maxDepthCut()` removes material; the hole bottom has the same
 * conical shape as the tip, so whenever the tip is at or behind the deepest cut no lip touches
 * bone and the thrust is zero (side friction of the margins is neglected).
 */
class DrillingProcess {
 public:
  /** @brief Starts an undrilled process on a copy of `specimen`. */
  explicit DrillingProcess(BoneSpecimen specimen, DrillParameters params = {});

  /**
   * @brief Advances the process by `dt` seconds to a new tip depth.
   * @param dt time step [s], > 0
   * @param tip_depth_m drill-tip depth along the axis into the bone frame [m] (may move back)
   * @param spindle_rpm spindle speed [rev/min]; with <= 0 nothing is cut (the rigid contact then
   *        gives zero thrust, the elastic one the spring force of the overlap)
   */
  ForceSample step(double dt, double tip_depth_m, double spindle_rpm);

  /**
   * @brief Cutting torque about the drill axis [N m] that goes with a thrust: kappa (D/2) F for
   *        a thrust F > 0 and a turning spindle (n > 0), else 0 (see the file brief).
   */
  double cuttingTorque(double thrust_n, double spindle_rpm) const;

  /** @brief Returns to the undrilled state (same specimen). */
  void reset();

  /**
   * @brief Quasi-static thrust [N] for a solid fraction, feed per revolution and speed
   *        (the force law without the lag); useful for calibration and tests.
   */
  double steadyThrust(double engaged_fraction, double feed_per_rev_m, double spindle_rpm) const;

  /**
   * @brief Engaged solid fraction phi_eff for the tip at `tip_depth_m` (lips cutting).
   *
   * A lip point at radius r cuts at depth tip - (r / R) * cone_length, so the radial average
   * with uniform weight per unit lip length equals the depth average of the solid fraction over
   * [tip - cone_length, tip]; it is evaluated exactly from the specimen's integrated profile.
   */
  double engagedFraction(double tip_depth_m) const;

  /** @brief Axial length of the conical tip, (D/2) / tan(point_angle/2) [m]. */
  double tipConeLength() const { return cone_length_m_; }

  /** @brief Deepest tip position cut so far [m] (0 before first contact). */
  double maxDepthCut() const { return max_depth_cut_m_; }
  /** @brief Ground truth: deepest point reached by cutting, same as maxDepthCut() [m]. */
  double depthReached() const { return max_depth_cut_m_; }
  /** @brief Ground truth: depth of the given bone layer already removed at the tip [m]. */
  double removedDepth(Material layer) const;
  /**
   * @brief Ground truth: inner-cortical far boundary minus deepest cut, clamped to >= 0 [m].
   *
   * This is the residual inner cortical thickness ahead of the tip point (paper Sec. V-E
   * success criterion: residual in (0, 2 mm]).
   */
  double residualInnerCorticalThickness() const;
  /** @brief Ground truth: the tip point has passed the inner-cortical far boundary. */
  bool breakthrough() const { return max_depth_cut_m_ >= specimen_.innerCorticalEnd(); }
  /** @brief Material at the deepest cut point (the layer being drilled). */
  Material currentLayer() const { return specimen_.materialAt(max_depth_cut_m_); }
  /** @brief Thrust of the last step [N]. */
  double lastThrust() const { return thrust_N_; }
  /** @brief Cutting torque about the drill axis of the last step [N m]. */
  double lastTorque() const { return torque_Nm_; }
  /** @brief The specimen being drilled. */
  const BoneSpecimen& specimen() const { return specimen_; }
  /** @brief The drill parameters. */
  const DrillParameters& parameters() const { return params_; }

 private:
  /// @brief The elastic contact's step (finite contact_stiffness_n_per_m), see the file brief;
  ///        completes `out` (its material already set by step()).
  ForceSample stepElastic(double dt, double advance, double phi, double rpm, ForceSample out);
  /// @brief The thrust of a step (step() without the torque).
  ForceSample stepThrust(double dt, double tip_depth_m, double spindle_rpm);

  BoneSpecimen specimen_;
  DrillParameters params_;
  double cone_length_m_;
  double max_depth_cut_m_ = 0.0;
  double thrust_N_ = 0.0;
  double torque_Nm_ = 0.0;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_DRILLING_FORCE_HPP
