/**
 * @file ventilator_conversions.hpp
 * @brief Ventilator settings between ROS parameters / messages and the core struct.
 */
#pragma once

#include <string>

#include "pedicle_drilling/VentilatorSettings.h"
#include "pedicle_drilling/core/ventilator.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"

namespace pedicle_drilling {

/** @brief Reads ~tv_max_ml, ~rate_bpm, ~ie_ratio, ~waveform, ... with range checks. */
core::VentilatorSettings loadVentilatorSettings(const ParamLoader& params);

/** @brief Core settings to message. */
VentilatorSettings toMsg(const core::VentilatorSettings& settings);

/** @brief Message to core settings; throws std::invalid_argument naming a bad field. */
core::VentilatorSettings fromMsg(const VentilatorSettings& msg);

}  // namespace pedicle_drilling
