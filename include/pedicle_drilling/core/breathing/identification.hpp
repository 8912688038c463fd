/**
 * @file identification.hpp
 * @brief Identification of the displacement models (motion_model.hpp) from paired samples of
 *        tidal volume and marker displacement: Ceres (iterative), closed-form OLS (oracle).
 *
 * Fitness (paper Eq. 16, standard coefficient of determination):
 *   R^2 = 1 - sum (g_i - g^_i)^2 / sum (g_i - mean(g))^2,
 * where g_i is the recorded displacement and g^_i the model prediction at sample i. (The paper's
 * text calls g^_i "the average of the prediction"; the formula is only the coefficient of
 * determination if g^_i is the prediction itself, which is what is implemented.)
 *
 * Both models are linear in their coefficients, so maximising R^2 over the coefficients is
 * exactly ordinary least squares (the denominator does not depend on them). fitOls() solves it
 * in closed form (column-pivoting Householder QR of the design matrix) and is the oracle that
 * fitCeres() and fitPso() (pso.hpp) are tested against.
 */
#pragma once

#include <string>
#include <vector>

#include <ceres/ceres.h>

#include "pedicle_drilling/core/breathing/motion_model.hpp"

namespace pedicle_drilling::core {

/**
 * @brief Residual of the linear model for one sample: r = d - (q1 Tv + q0).
 *        Parameter block q = {q1, q0}.
 */
struct LinearDisplacementResidual {
  /** @brief Sample Tv (ml) and displacement d (mm). */
  LinearDisplacementResidual(double tv, double d) : tv_(tv), d_(d) {}

  /** @brief r[0] = d - (q[0] Tv + q[1]). */
  template <typename T>
  bool operator()(const T* q, T* r) const {
    r[0] = T(d_) - (q[0] * T(tv_) + q[1]);
    return true;
  }

  /** @brief AutoDiff cost function (1 residual, 2 parameters); caller / Problem owns it. */
  static ceres::CostFunction* Create(double tv, double d) {
    return new ceres::AutoDiffCostFunction<LinearDisplacementResidual, 1, 2>(
        new LinearDisplacementResidual(tv, d));
  }

 private:
  double tv_;
  double d_;
};

/**
 * @brief Residual of the hysteresis (rate-term) model for one sample:
 *        r = d - (q1 Tv + q2 dTv/dt + q0). Parameter block q = {q1, q2, q0}.
 */
struct HysteresisDisplacementResidual {
  /** @brief Sample Tv (ml), dTv/dt (ml/s) and displacement d (mm). */
  HysteresisDisplacementResidual(double tv, double dtv_dt, double d)
      : tv_(tv), dtv_dt_(dtv_dt), d_(d) {}

  /** @brief r[0] = d - (q[0] Tv + q[1] dTv/dt + q[2]). */
  template <typename T>
  bool operator()(const T* q, T* r) const {
    r[0] = T(d_) - (q[0] * T(tv_) + q[1] * T(dtv_dt_) + q[2]);
    return true;
  }

  /** @brief AutoDiff cost function (1 residual, 3 parameters); caller / Problem owns it. */
  static ceres::CostFunction* Create(double tv, double dtv_dt, double d) {
    return new ceres::AutoDiffCostFunction<HysteresisDisplacementResidual, 1, 3>(
        new HysteresisDisplacementResidual(tv, dtv_dt, d));
  }

 private:
  double tv_;
  double dtv_dt_;
  double d_;
};

/** @brief Samples of one axis: Tv (ml), dTv/dt (ml/s) and displacement (mm), equal lengths. */
struct AxisSamples {
  std::vector<double> tv;      ///< tidal volume, ml
  std::vector<double> dtv_dt;  ///< dTv/dt, ml/s (may be empty for the linear model)
  std::vector<double> d;       ///< displacement, mm
};

/**
 * @brief All residuals of one axis in one functor (one residual block): r_i = d_i - prediction
 *        of the linear (P = 2, q = {q1, q0}) or hysteresis (P = 3, q = {q1, q2, q0}) model.
 *
 * fitCeres() uses this rather than one LinearDisplacementResidual block per sample: same
 * residuals and Jacobian, but Ceres' per-block bookkeeping (evaluation, Jacobian assembly) is
 * paid once instead of once per sample, about 5x less time on 240 samples.
 * The samples are referenced, not copied: they must outlive the cost function.
 */
template <int P>
struct DisplacementBatchResidual {
  static_assert(P == 2 || P == 3, "2 (linear) or 3 (hysteresis) coefficients");
  /** @brief References the samples (dtv_dt used only for P = 3). */
  explicit DisplacementBatchResidual(const AxisSamples& samples) : s_(&samples) {}

  /** @brief r[i] = d_i - (q1 Tv_i [+ q2 dTv/dt_i] + q0) for every sample i. */
  template <typename T>
  bool operator()(const T* q, T* r) const {
    const size_t n = s_->d.size();
    for (size_t i = 0; i < n; ++i) {
      T prediction = q[0] * T(s_->tv[i]) + q[P - 1];
      if constexpr (P == 3) prediction += q[1] * T(s_->dtv_dt[i]);
      r[i] = T(s_->d[i]) - prediction;
    }
    return true;
  }

  /** @brief AutoDiff cost function with one residual per sample; caller / Problem owns it. */
  static ceres::CostFunction* Create(const AxisSamples& samples) {
    return new ceres::AutoDiffCostFunction<DisplacementBatchResidual, ceres::DYNAMIC, P>(
        new DisplacementBatchResidual(samples), static_cast<int>(samples.d.size()));
  }

 private:
  const AxisSamples* s_;
};

/** @brief Outcome of identifying one axis. */
struct FitResult {
  AxisModel model;         ///< identified kind and coefficients
  double r2 = 0.0;         ///< coefficient of determination, Eq. 16
  double rmse = 0.0;       ///< root-mean-square residual, mm
  int iterations = 0;      ///< solver iterations (0 for the closed form)
  double time_s = 0.0;     ///< wall time of the fit, s
  std::string method;      ///< "ols", "ceres" or "pso"
  bool converged = false;  ///< solver reported convergence
};

/**
 * @brief Options for fitCeres(). Defaults: tolerances far below double round-off of R^2.
 *
 * Both models are linear in their coefficients, so a Gauss-Newton step from any start is the
 * exact minimiser. A very large initial trust region (1e16) makes Levenberg-Marquardt's first
 * step that Gauss-Newton step (damping 1 / radius ~ 0); the second iteration then only
 * confirms convergence. Ceres' default (1e4) spends 10-20 iterations growing the region.
 */
struct CeresFitOptions {
  int max_iterations = 100;                   ///< Levenberg-Marquardt iterations
  double initial_trust_region_radius = 1e16;  ///< see struct doc
  double function_tolerance = 1e-16;          ///< relative cost change
  double gradient_tolerance = 1e-16;          ///< max-norm of the projected gradient
  double parameter_tolerance = 1e-16;         ///< relative step size
};

/**
 * @brief Central-difference derivative dx/dt (one-sided at the ends) for non-uniform t.
 * @throws std::invalid_argument on size mismatch, fewer than 2 samples, non-increasing t.
 */
std::vector<double> timeDerivative(const std::vector<double>& t, const std::vector<double>& x);

/** @brief R^2 of Eq. 16; returns 0 when the measured signal is constant. Sizes must match. */
double rSquared(const std::vector<double>& measured, const std::vector<double>& predicted);

/** @brief Root-mean-square of measured - predicted. Sizes must match. */
double rootMeanSquareError(const std::vector<double>& measured,
                           const std::vector<double>& predicted);

/** @brief Predictions of a model for all samples. */
std::vector<double> predictAll(const AxisModel& model, const AxisSamples& samples);

/** @brief Fills r2 and rmse of @p result from its model on @p samples. */
void evaluateFit(const AxisSamples& samples, FitResult* result);

/**
 * @brief Validates samples for a model kind (equal sizes, >= coefficient count + 1 samples,
 *        finite values, dTv/dt present for the hysteresis model).
 * @throws std::invalid_argument with a message naming the problem.
 */
void checkSamples(ModelKind kind, const AxisSamples& samples);

/** @brief Closed-form ordinary least squares (the R^2-optimal oracle). */
FitResult fitOls(ModelKind kind, const AxisSamples& samples);

/**
 * @brief Ceres identification: one AutoDiff residual block holding every sample
 *        (DisplacementBatchResidual), Levenberg-Marquardt with a dense QR linear solver, started
 *        from zero coefficients.
 */
FitResult fitCeres(ModelKind kind, const AxisSamples& samples,
                   const CeresFitOptions& options = CeresFitOptions());

}  // namespace pedicle_drilling::core
