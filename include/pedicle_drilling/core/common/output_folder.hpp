// Files a node writes where a caller names them (a model file of the MotionIdentification
// nodelet's ~identify): only inside one declared folder, whatever the name says (`..`, an
// absolute path, a symbolic link).
#ifndef PEDICLE_DRILLING_CORE_OUTPUT_FOLDER_HPP_
#define PEDICLE_DRILLING_CORE_OUTPUT_FOLDER_HPP_

#include <string>

namespace pedicle_drilling::core {

/**
 * @brief The default folder of written models: $ROS_HOME/pedicle_drilling/models, ROS_HOME
 *        defaulting to $HOME/.ros (as roslaunch's); "" if neither variable is set.
 */
std::string defaultModelFolder();

/**
 * @brief The file @p path names, resolved inside @p folder: a relative path is taken from the
 *        folder; every symbolic link and `..` of the folder, of the file's directory and of the
 *        file itself (when it exists) is resolved (realpath) before the check.
 * @param folder an existing directory.
 * @return the resolved path of the file (its directory exists; the file may not).
 * @throws std::invalid_argument, a sentence naming the path, when the folder does not exist,
 *         the path names no file, its directory does not exist, or it lies outside the folder.
 */
std::string pathInsideFolder(const std::string& folder, const std::string& path);

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_OUTPUT_FOLDER_HPP_
