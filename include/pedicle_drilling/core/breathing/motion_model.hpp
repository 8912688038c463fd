/**
 * @file motion_model.hpp
 * @brief Vertebra displacement models of paper Sec. III-B and V-B: displacement of the T12
 *        marker in AP / SI / LR as a function of the tidal volume Tv.
 *
 * Units used throughout the core library for these models:
 *   Tv      tidal volume above the end-expiratory level, ml
 *   dTv/dt  rate of change of Tv (airflow), ml/s
 *   d       marker displacement, mm
 *   q1      mm/ml,   q2  mm*s/ml,   q0  mm
 *
 * Models
 *   "linear":      d = q1 Tv + q0.
 *                  AP: beam deflection of the two discs at x = m (Eq. 6-8),
 *                      q1_AP = (5 m^4 / (24 EI) + l m^3 / (6 EI)) p0 b_w / V0.
 *                  SI: axial elongation of the discs (Eq. 9), q1_SI = 2 p0 S L / (E A V0).
 *                  LR: linear polynomial (Sec. V-B).
 *                  Only the lumped (q1, q0) are identifiable from (Tv, d) pairs; E, I, A, V0,
 *                  p0, b_w and S cannot be separated. The paper's q0_AP = q1_AP V0 is not used:
 *                  the intercept depends on where the tracker reference puts zero, so q0 is free.
 *   "hysteresis":  d = q1 Tv + q2 dTv/dt + q0.
 *                  Choice: a rate (phase-lag) term rather than separate inhale/exhale branches.
 *                  A displacement lagging the volume by a small delay tau obeys, to first order,
 *                  d(t) = q1 Tv(t - tau) + q0 ~= q1 Tv(t) - q1 tau dTv/dt + q0, i.e. q2 = -q1 tau,
 *                  which traces a loop (different d on inhale and exhale at equal Tv) in the
 *                  (Tv, d) plane. The model stays linear in its coefficients, so ordinary least
 *                  squares gives the exact optimum in closed form (an oracle for Ceres / PSO), and
 *                  unlike a sign(dTv/dt) branch term it has no discontinuity at the turning points.
 *                  The implied lag is tau = -q2 / q1 (s), see lagSeconds().
 */
#pragma once

#include <array>
#include <string>
#include <vector>

namespace pedicle_drilling::core {

/** @brief Displacement axes: anterior-posterior, superior-inferior, left-right. */
enum class Axis { kAP = 0, kSI = 1, kLR = 2 };

/** @brief The three axes in storage order (AP, SI, LR). */
constexpr std::array<Axis, 3> kAllAxes = {Axis::kAP, Axis::kSI, Axis::kLR};

/** @brief Lower-case axis name: "ap", "si", "lr". */
std::string axisName(Axis axis);

/** @brief Parses "ap"/"si"/"lr" (case-insensitive); returns false on an unknown name. */
bool parseAxis(const std::string& name, Axis* axis);

/** @brief Kind of displacement model. */
enum class ModelKind {
  kLinear,     ///< d = q1 Tv + q0
  kHysteresis  ///< d = q1 Tv + q2 dTv/dt + q0
};

/** @brief Canonical model name: "linear" or "hysteresis". */
std::string modelKindName(ModelKind kind);

/** @brief Parses "linear"/"hysteresis"; returns false on an unknown name. */
bool parseModelKind(const std::string& name, ModelKind* kind);

/** @brief Number of coefficients of a model kind (2 for linear, 3 for hysteresis). */
int numCoefficients(ModelKind kind);

/**
 * @brief Coefficients of one axis. q2 is zero (and ignored) for the linear model.
 *
 * Coefficient vector order used by the identification code: linear {q1, q0},
 * hysteresis {q1, q2, q0}.
 */
struct AxisModel {
  ModelKind kind = ModelKind::kLinear;  ///< model kind
  double q1 = 0.0;                      ///< slope vs Tv, mm/ml
  double q2 = 0.0;                      ///< rate coefficient vs dTv/dt, mm*s/ml (hysteresis only)
  double q0 = 0.0;                      ///< intercept, mm

  /** @brief Predicted displacement (mm) from Tv (ml) and dTv/dt (ml/s). */
  double predict(double tv, double dtv_dt) const;

  /** @brief Coefficients in identification order (see struct doc). */
  std::vector<double> coefficients() const;

  /** @brief Sets the coefficients from identification order; throws on a wrong size. */
  void setCoefficients(const std::vector<double>& coefficients);

  /** @brief Lag of displacement behind volume implied by the model, tau = -q2 / q1 (s). */
  double lagSeconds() const;
};

/** @brief Per-axis displacement model of one patient. */
struct MotionModel {
  std::array<AxisModel, 3> axes;  ///< indexed by static_cast<int>(Axis)

  /** @brief Model of one axis. */
  const AxisModel& axis(Axis a) const { return axes[static_cast<int>(a)]; }
  /** @brief Mutable model of one axis. */
  AxisModel& axis(Axis a) { return axes[static_cast<int>(a)]; }

  /** @brief Predicted displacement (mm) of one axis from Tv (ml) and dTv/dt (ml/s). */
  double predict(Axis a, double tv, double dtv_dt) const { return axis(a).predict(tv, dtv_dt); }
};

/**
 * @brief CT lengths of the T12 segment (Table I), in mm.
 *
 * The paper sets m1 = m2 = m (Sec. III-B); the default m is the mean of the upper (5.31 mm) and
 * lower (5.67 mm) disc lengths, 5.49 mm. L, the total disc length in Eq. 9, is 2 m.
 */
struct SpineGeometry {
  double centrum_length_mm = 23.10;             ///< l, T12 centrum (Table I)
  double disc_length_mm = 0.5 * (5.31 + 5.67);  ///< m = (m1 + m2) / 2 (Table I)

  /** @brief Beam factor 5 m^4 / 24 + l m^3 / 6 of Eq. 8, mm^4. */
  double apBeamFactorMm4() const;
  /** @brief Total disc length L = 2 m of Eq. 9, mm. */
  double totalDiscLengthMm() const { return 2.0 * disc_length_mm; }
};

/** @brief Millilitres to cubic millimetres. */
constexpr double kMm3PerMl = 1000.0;

/**
 * @brief Equivalent disc bending stiffness EI V0 / (p0 b_w) implied by an AP slope (Eq. 8).
 *
 * From q1 = (5 m^4 / 24 + l m^3 / 6) p0 b_w / (EI V0):
 *   EI V0 / (p0 b_w) = (5 m^4 / 24 + l m^3 / 6) / q1.
 * Units: with EI in N mm^2, V0 in mm^3, p0 in N/mm^2 and b_w in mm the group is in mm^6;
 * q1 is converted from mm/ml to mm/mm^3 (divide by 1000) first.
 * @param q1_mm_per_ml identified AP slope, mm/ml (must be non-zero)
 * @return EI V0 / (p0 b_w) in mm^6 (negative if q1 < 0)
 */
double apEquivalentBendingStiffness(double q1_mm_per_ml, const SpineGeometry& geometry = {});

/**
 * @brief Equivalent disc axial stiffness E A V0 / (2 p0 S L) implied by an SI slope (Eq. 9).
 *
 * From q1 = 2 p0 S L / (E A V0): E A V0 / (2 p0 S L) = 1 / q1. With E in N/mm^2, A and S in
 * mm^2, V0 in mm^3, p0 in N/mm^2 and L in mm the group is in mm^2; q1 is converted from mm/ml to
 * mm/mm^3 first. The geometry does not enter (L is inside the group).
 * @return E A V0 / (2 p0 S L) in mm^2
 */
double siEquivalentAxialStiffness(double q1_mm_per_ml);

/**
 * @brief Same as siEquivalentAxialStiffness() but with the CT disc length taken out:
 *        E A V0 / (p0 S) = 2 L / q1 with L = 2 m (Table I), in mm^3.
 */
double siAxialRigidityGroup(double q1_mm_per_ml, const SpineGeometry& geometry = {});

/**
 * @brief The equivalent disc stiffness an identified slope implies on its axis: AP
 *        apEquivalentBendingStiffness() [mm^6], SI siEquivalentAxialStiffness() [mm^2]; 0 for
 *        LR (no physical model, Sec. V-B) and for a zero slope.
 */
double equivalentStiffness(Axis axis, double q1_mm_per_ml);

/** @brief Unit and meaning of equivalentStiffness() on an axis ("" for LR). */
std::string equivalentStiffnessLabel(Axis axis);

}  // namespace pedicle_drilling::core
