/**
 * @file motion_pipeline.hpp
 * @brief The whole per-patient identification (paper Sec. III and V-B) in one call, shared by
 *        the `identify` CLI and the MotionIdentification nodelet so both give the same model on
 *        the same data.
 *
 * Pipeline per axis (AP, SI, LR), on displacement samples paired with the tidal volume at the
 * marker times (the 8 Hz CSV `t,tv,ap,si,lr`, virtual_volunteer.hpp):
 *  1. validatePairedSamples(): equal lengths, finite values, strictly increasing time, at
 *     least two breaths (countBreaths()); each failure throws the RecordingFormatError subclass
 *     of virtual_volunteer.hpp that names it;
 *  2. de-noise the displacement with the DWT (Eq. 1, s_de = d3 + d4 + d5 by default) choosing
 *     the basis among the candidates by RMSE-DMM (Fig. 6), denoising.hpp;
 *  3. s_de has no approximation and so (almost) zero mean: the mean of the raw displacement is
 *     added back, d_fit = s_de + mean(d), so that q0 stays in the recording's frame (the slope
 *     is unaffected: the model has an intercept);
 *  4. optionally (denoise_tv, not in the paper) pass Tv through the same wavelet and kept levels
 *     plus its mean. Eq. 1 removes the sub-0.125 Hz part of the displacement (breath-to-breath
 *     depth changes, in a6/d6) but not of Tv, which biases the fitted slope low; on the default
 *     virtual volunteers the AP/SI slope error is -1 % to -7.5 % with displacement-only
 *     de-noising and within +-3 % with both signals filtered alike;
 *  5. fit d_fit against Tv (and dTv/dt by central differences for the hysteresis model) with
 *     Ceres (default) or the paper's PSO. R^2 (Eq. 16) is against d_fit, as in the paper; the
 *     R^2 against the raw displacement is reported too.
 */
#pragma once

#include <array>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/denoising.hpp"
#include "pedicle_drilling/core/breathing/identification.hpp"
#include "pedicle_drilling/core/breathing/motion_model.hpp"
#include "pedicle_drilling/core/breathing/motion_model_io.hpp"
#include "pedicle_drilling/core/breathing/pso.hpp"
#include "pedicle_drilling/core/breathing/virtual_volunteer.hpp"
#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling::core {

/** @brief Identification method. */
enum class IdentificationMethod {
  kCeres,  ///< Levenberg-Marquardt (fitCeres())
  kPso     ///< the paper's particle swarm (fitPso())
};

/** @brief "ceres" or "pso". */
std::string methodName(IdentificationMethod method);

/** @brief Parses "ceres"/"pso"; returns false on an unknown name. */
bool parseMethod(const std::string& name, IdentificationMethod* method);

/** @brief Options of identifyPatient(); defaults follow the paper. */
struct PipelineOptions {
  ModelKind kind = ModelKind::kLinear;                         ///< model of every axis
  IdentificationMethod method = IdentificationMethod::kCeres;  ///< solver
  bool denoise = true;             ///< de-noise the displacement (step 2); false fits raw data
  bool denoise_tv = false;         ///< step 4 (needs denoise)
  DenoiseOptions denoise_options;  ///< wavelet candidates, level, kept levels, dTv
  CeresFitOptions ceres;           ///< Ceres settings
  PsoOptions pso;                  ///< PSO settings (paper: 24 particles, 2000 iterations)

  /**
   * @brief Checks the options (level 1..16, kept levels in 1..level, known candidate wavelets,
   *        dTv >= 0, denoise_tv only with denoise, PSO population / iterations >= 1).
   * @throws std::invalid_argument naming the option.
   */
  void validate() const;

  /** @brief The declaration of the options a node or tool sets (names as the ROS parameters). */
  static const ParamTable<PipelineOptions>& table();
};

/** @brief What happened on one axis. */
struct AxisReport {
  Axis axis = Axis::kAP;         ///< the axis
  std::string wavelet = "none";  ///< chosen basis ("none" without de-noising)
  FitResult fit;                 ///< coefficients, R^2 (vs the fitted data), RMSE, time
  double r2_raw = 0.0;           ///< R^2 of the model against the raw displacement
  AxisSamples samples;           ///< the data fitted (Tv, dTv/dt, d_fit)
  std::vector<double> raw;       ///< the raw displacement
};

/** @brief Result of identifyPatient(). */
struct PipelineResult {
  PatientModel model;              ///< ready to write with writeModelYaml()
  std::array<AxisReport, 3> axes;  ///< indexed by Axis
  int breaths = 0;                 ///< breaths counted in the tidal volume
  std::size_t samples = 0;         ///< paired samples used
  double duration_s = 0.0;         ///< time span of the samples
};

/**
 * @brief Validates paired samples (step 1 above).
 * @param source names the data in error messages (file name, "window", ...)
 * @throws MissingColumnError (empty / size mismatch), NonFiniteValueError,
 *         NonIncreasingTimeError, TooFewBreathsError
 */
void validatePairedSamples(const PairedSamples& samples, const std::string& source);

/**
 * @brief Runs the pipeline above on validated samples and fills the per-patient model.
 * @throws the errors of validatePairedSamples() and std::invalid_argument for bad options.
 */
PipelineResult identifyPatient(const PairedSamples& samples, const PipelineOptions& options,
                               const std::string& patient_id, const std::string& source = "input");

/**
 * @brief Which tracker-frame axis (with sign) carries AP, SI and LR.
 *
 * d_axis = sign[axis] * p[index[axis]] for a marker position p = (x, y, z) in the tracker frame.
 */
struct AxisMapping {
  std::array<int, 3> index{{2, 1, 0}};          ///< tracker component (0 x, 1 y, 2 z) per Axis
  std::array<double, 3> sign{{1.0, 1.0, 1.0}};  ///< +1 or -1 per Axis

  /** @brief (AP, SI, LR) of a tracker-frame position, same unit as p. */
  std::array<double, 3> map(double x, double y, double z) const;
};

/**
 * @brief Parses a mapping from three specs "[+|-]x|y|z" (e.g. "+z", "-y", "x"), one per axis.
 *        The three must use distinct components (a signed permutation).
 * @throws std::invalid_argument naming the axis ("ap", "si", "lr") and the bad spec
 */
AxisMapping parseAxisMapping(const std::string& ap, const std::string& si, const std::string& lr);

/** @brief One line per axis: wavelet, q1, q2, q0, R^2 (fitted and raw), RMSE, iterations, ms. */
std::string formatAxisReport(const AxisReport& report);

}  // namespace pedicle_drilling::core
