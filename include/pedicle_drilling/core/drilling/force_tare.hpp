/**
 * @file force_tare.hpp
 * @brief The F/T sensor's tare before contact: with the spindle running and the tool
 *        free, the mean of a declared number of samples is taken as the bias and subtracted from
 *        every later sample. A window whose force spread is too large (something touches the
 *        tool) or that holds a non-finite sample fails, and the previous bias is kept. The
 *        simulator's sensor driver and the ForceTare relay (for a driver without a tare of its
 *        own) run this class. For a driver that zeroes itself (its zero service), the same
 *        window checks the zero instead (checkZero()): the mean force after the zero must lie
 *        within a tolerance of zero, and nothing is subtracted. No ROS.
 */
#pragma once

#include <Eigen/Core>
#include <optional>
#include <sstream>
#include <string>

#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling::core {

/** @brief A tare request: how many samples, and the largest force spread accepted. */
struct TareRequest {
  int samples = 100;          ///< samples averaged, [1, 100000]
  double max_spread_n = 0.5;  ///< largest SD of the force norm over the window [N], > 0
  /**
   * @brief @throws std::invalid_argument naming the field when samples is outside [1, 100000] or
   *        max_spread_n is not positive and finite.
   */
  void validate() const;
  /** @brief The declaration of both fields. */
  static const ParamTable<TareRequest>& table();
};

/** @brief The outcome of a tare window. */
struct TareResult {
  bool success = false;
  double t = 0.0;  ///< time of the window's last sample [s]
  int samples = 0;
  Eigen::Matrix<double, 6, 1> bias = Eigen::Matrix<double, 6, 1>::Zero();  ///< mean (N, N m)
  double spread_n = 0.0;  ///< SD of the force vector over the window (root of the summed variances)
  std::string message;    ///< why it failed, or a summary
};

/** @brief Averages a window of raw wrenches and subtracts the bias from then on. */
class ForceTare {
 public:
  using Wrench = Eigen::Matrix<double, 6, 1>;

  /**
   * @brief Start a window from the next sample on (a window in progress is dropped).
   * @throws std::invalid_argument for a request that TareRequest::validate() refuses.
   */
  void request(const TareRequest& request);

  /**
   * @brief Start a window that checks a zero the sensor's driver made (its zero service)
   *        instead of measuring a bias: it takes the samples stamped at or after @p from_t (the
   *        zero was done by then) and succeeds when they are finite, their spread is within the
   *        request's and the norm of their mean force is at most @p tolerance_n. The bias is not
   *        changed; the result's bias is the mean that remained after the zero.
   * @throws std::invalid_argument for a request that TareRequest::validate() refuses or a
   *         tolerance that is not positive and finite.
   */
  void checkZero(const TareRequest& request, double tolerance_n, double from_t);

  /**
   * @brief One raw sample at @p t: returns it minus the bias in force (the window's own samples
   *        too, with the bias from before). Completes a window at its last sample.
   */
  Wrench apply(double t, const Wrench& raw);

  /** @brief The result of the window that completed since the last call, if any. */
  std::optional<TareResult> takeResult();

  /** @brief A window is collecting samples. */
  bool collecting() const { return remaining_ > 0; }
  /** @brief The bias subtracted now. */
  const Wrench& bias() const { return bias_; }
  /** @brief Forget the bias and any window (a new sensor session). */
  void reset();

 private:
  void finish(double t);
  /** @brief A complete window's verdict (finite, with its mean and spread in @p r). */
  void judge(TareResult* r, const Wrench& mean, std::ostringstream* os);

  TareRequest request_;
  int remaining_ = 0;
  int count_ = 0;
  bool finite_ = true;
  Wrench sum_ = Wrench::Zero();
  Eigen::Vector3d sum_sq_ = Eigen::Vector3d::Zero();
  Wrench bias_ = Wrench::Zero();
  bool checking_zero_ = false;     ///< the window checks the driver's zero (checkZero)
  double zero_tolerance_n_ = 0.0;  ///< with checkZero: the largest mean force accepted [N]
  double from_t_ = 0.0;            ///< with checkZero: the window's first stamp [s]
  std::optional<TareResult> result_;
};

}  // namespace pedicle_drilling::core
