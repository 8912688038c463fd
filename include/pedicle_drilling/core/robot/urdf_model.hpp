/**
 * @file urdf_model.hpp
 * @brief urdfdom's parse of a robot description, kept for the description parsed last.
 *
 * A campaign builds a simulation per trial from one description (the simulation and its arm
 * each read it): parsing it once per process instead of twice per trial.
 *
 * No ROS headers; urdfdom only.
 */
#ifndef PEDICLE_DRILLING_CORE_URDF_MODEL_HPP
#define PEDICLE_DRILLING_CORE_URDF_MODEL_HPP

#include <urdf_model/model.h>

#include <memory>
#include <string>

namespace pedicle_drilling::core {

/**
 * @brief urdf::parseURDF(urdf_xml), the same model object for the same text as the last call
 * (thread-safe; a different text is parsed and kept instead).
 *
 * The model is shared between its callers: they read it and never change it. Returns nullptr
 * when urdfdom cannot parse the text (nothing kept then).
 */
std::shared_ptr<const urdf::ModelInterface> parseUrdfKept(const std::string& urdf_xml);

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_URDF_MODEL_HPP
