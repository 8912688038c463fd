/**
 * @file target_result.hpp
 * @brief Outcome of a command to a simulated actuator (joint targets, trajectories, spindle).
 */
#ifndef PEDICLE_DRILLING_CORE_TARGET_RESULT_HPP
#define PEDICLE_DRILLING_CORE_TARGET_RESULT_HPP

#include <string>

namespace pedicle_drilling::core {

/// @brief Outcome of a joint target command.
enum class TargetStatus { kAccepted, kClamped, kRejected };

/// @brief Status plus a human-readable message of a joint target command.
struct TargetResult {
  TargetStatus status = TargetStatus::kAccepted;
  std::string message;
  /// @brief True unless the command was rejected.
  bool ok() const { return status != TargetStatus::kRejected; }
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_TARGET_RESULT_HPP
