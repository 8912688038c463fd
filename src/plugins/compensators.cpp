/**
 * @file compensators.cpp
 * @brief Exports the built-in motion compensators as pluginlib classes of the base class
 *        pedicle_drilling::core::CompensatorInterface (compensator_plugins.xml): the paper's, the
 *        tracker-feedback baseline and the paper's corrected from the tracker (adaptive). An
 *        outside package exports its own the same way.
 */
#include <pluginlib/class_list_macros.hpp>

#include "pedicle_drilling/core/control/adaptive_compensator.hpp"
#include "pedicle_drilling/core/control/compensator_interface.hpp"

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::core::PaperCompensator,
                       pedicle_drilling::core::CompensatorInterface)
PLUGINLIB_EXPORT_CLASS(pedicle_drilling::core::TrackedMarkerCompensator,
                       pedicle_drilling::core::CompensatorInterface)
PLUGINLIB_EXPORT_CLASS(pedicle_drilling::core::AdaptiveModelCompensator,
                       pedicle_drilling::core::CompensatorInterface)
