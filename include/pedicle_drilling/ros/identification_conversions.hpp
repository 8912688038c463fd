/**
 * @file identification_conversions.hpp
 * @brief The MotionIdentification nodelet's parameters, loaded once into one validated struct,
 *        and the identified model as pedicle_drilling/MotionModel.
 */
#pragma once

#include <string>

#include "pedicle_drilling/MotionModel.h"
#include "pedicle_drilling/core/breathing/motion_pipeline.hpp"
#include "pedicle_drilling/ros/node_params.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"

namespace pedicle_drilling {

/** @brief Loads and checks them. @throws ParameterError naming the parameter. */
MotionIdentificationParams loadMotionIdentificationParams(const ParamLoader& params);

/** @brief The identified model (frame, patient, method, YAML path) as the message. */
MotionModel toMsg(const core::PipelineResult& result, const std::string& frame,
                  const std::string& patient_id, const std::string& method,
                  const std::string& yaml_path);

}  // namespace pedicle_drilling
