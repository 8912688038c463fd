/**
 * @file trial_distribution_params.hpp
 * @brief The Simulator's `~trial_distribution` parameters: the specimen, patient, ventilator,
 *        sensor and arm distributions that every `simulator/reset` draws a new trial from.
 */
#pragma once

#include <ros/node_handle.h>

#include "pedicle_drilling/core/drilling/bone_specimen.hpp"
#include "pedicle_drilling/core/sim/drilling_simulation.hpp"

namespace pedicle_drilling {

/** @brief Distributions of a simulated trial, as loaded from `~trial_distribution`. */
struct TrialDistributionParams {
  core::SpecimenDistribution specimen;  ///< `~trial_distribution/specimen/*`
  core::TrialVariability variability;   ///< `patient/*`, `ventilator/*`, `sensor/*`, `arm/*`
};

/**
 * @brief Loads and range-checks `trial_distribution/...` under `private_nh` (lengths in mm);
 *        missing keys take the core defaults (the paper's conditions).
 * @throws ParameterError naming the parameter for a wrong type, an out-of-range value or an
 *         unknown key.
 */
TrialDistributionParams loadTrialDistribution(const ros::NodeHandle& private_nh);

}  // namespace pedicle_drilling
