/**
 * @file motion_model_io.hpp
 * @brief Per-patient displacement-model file (YAML, read with yaml-cpp), written atomically.
 *
 * Format as written (block mappings with two-space indentation, `key: value` scalars, flow
 * sequences of integers, `#` comments; strings double-quoted with YAML's escapes):
 *
 *   # pedicle_drilling vertebra displacement model
 *   patient_id: "volunteer_1"
 *   units: "Tv ml, dTv/dt ml/s, d mm; q1 mm/ml, q2 mm*s/ml, q0 mm"
 *   axes:
 *     ap:
 *       model: linear            # or hysteresis
 *       q1: 0.0100000000000000002
 *       q2: 0                    # always written; 0 for the linear model
 *       q0: 0.29999999999999999
 *       r2: 0.97999999999999998
 *       rmse: 0.2
 *       wavelet: "coif4"         # "none" when not de-noised
 *       level: 6
 *       kept_levels: [3, 4, 5]
 *     si: ...
 *     lr: ...
 *   meta:                        # optional free key/value strings (e.g. generator truth)
 *     breaths_per_min: "20"
 *
 * Doubles are written with 17 significant digits, so a write/read round trip is exact. The
 * reader takes any YAML of this shape (yaml-cpp: other indentations, block lists, quoting) and
 * refuses, with a ModelFileError naming the file, the line and the key: text that is not YAML
 * (a tab in the indentation, a bad indentation), more than one document, a repeated key, a
 * missing required key, an unknown model kind, a number that is quoted or not finite (nan,
 * .inf), an integer that is not decimal, a negative level, a kept detail level outside
 * [1, level] or listed twice, and a meta key other than letters, digits, '_', '-' and '.'.
 * Keys it does not know are ignored (`units`, `equivalent_stiffness`: informative).
 *
 * Atomic write (core::AtomicFile, atomic_file.hpp): the text goes to a temporary file beside
 * the destination and is renamed over it. On any failure the temporary file is removed and
 * ModelFileError is thrown, so the destination is either the old file (or absent) or the
 * complete new one.
 */
#pragma once

#include <array>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "pedicle_drilling/core/breathing/motion_model.hpp"

namespace pedicle_drilling::core {

/** @brief The model file format this build writes and reads (`format_version`; a file without
 *         the key is version 1). */
constexpr int kModelFormatVersion = 1;

/** @brief One axis of the model file: coefficients plus fit and de-noising provenance. */
struct AxisModelRecord {
  AxisModel model;               ///< kind and coefficients
  double r2 = 0.0;               ///< R^2 of the fit (Eq. 16)
  double rmse = 0.0;             ///< RMSE of the fit, mm
  std::string wavelet = "none";  ///< wavelet basis used for de-noising
  int level = 0;                 ///< DWT level (0: not de-noised)
  std::vector<int> kept_levels;  ///< detail levels kept (Eq. 1)
};

/** @brief Per-patient model file content. */
struct PatientModel {
  std::string patient_id;                                 ///< free-form id
  std::array<AxisModelRecord, 3> axes;                    ///< indexed by Axis
  std::vector<std::pair<std::string, std::string>> meta;  ///< optional extra key/values

  /** @brief The prediction model (kinds and coefficients of the three axes). */
  MotionModel motionModel() const;
};

/** @brief Error reading or writing a model file; the message names the path and problem. */
class ModelFileError : public std::runtime_error {
 public:
  /** @brief Error with message. */
  explicit ModelFileError(const std::string& what) : std::runtime_error(what) {}
};

/**
 * @brief Serialises a model to the YAML text above.
 * @throws ModelFileError naming the axis and field when a coefficient, R² or RMSE is not finite,
 *         or naming a meta key the reader would refuse (see the file doc) or a repeated one: no
 *         file that cannot be read back is ever written.
 */
std::string modelToYaml(const PatientModel& model);

/** @brief Parses the YAML text above; @p source names the origin in error messages. */
PatientModel modelFromYaml(const std::string& text, const std::string& source = "<string>");

/** @brief Writes the model file atomically (see file doc). @throws ModelFileError. */
void writeModelYaml(const PatientModel& model, const std::string& path);

/** @brief Reads a model file. @throws ModelFileError. */
PatientModel readModelYaml(const std::string& path);

}  // namespace pedicle_drilling::core
