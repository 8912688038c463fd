/**
 * @file ventilator_conversions.hpp
 * @brief Ventilator settings between ROS parameters / messages and the core struct.
 */
#pragma once

#include <functional>
#include <string>

#include "pedicle_drilling/SetVentilatorSettings.h"
#include "pedicle_drilling/VentilatorSettings.h"
#include "pedicle_drilling/core/breathing/ventilator.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"

namespace pedicle_drilling {

/** @brief Core settings to message. */
VentilatorSettings toMsg(const core::VentilatorSettings& settings);

/** @brief Message to core settings; throws std::invalid_argument naming a bad field. */
core::VentilatorSettings fromMsg(const VentilatorSettings& msg);

/**
 * @brief Serves a SetVentilatorSettings request (the Ventilator nodelet's and the Simulator's):
 *        checks the settings, hands them to @p request_settings (which queues them for the next
 *        breath, under the caller's lock) and fills the response; bad settings (or a refusal
 *        by @p request_settings) leave the previous ones in force.
 */
void serveSetVentilatorSettings(
    const SetVentilatorSettings::Request& request, SetVentilatorSettings::Response& response,
    const std::function<void(const core::VentilatorSettings&)>& request_settings);

}  // namespace pedicle_drilling
