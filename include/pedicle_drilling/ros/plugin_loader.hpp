/**
 * @file plugin_loader.hpp
 * @brief Creates a recognizer or a compensator by class name: the built-in ones
 *        directly, any other through pluginlib (base classes
 *        pedicle_drilling::core::RecognizerInterface and ::CompensatorInterface, exported by a
 *        package's plugin XML under `<pedicle_drilling plugin="..."/>`). Plugin XML files outside
 *        any package export (a quick experiment, the test plugins) are added from the
 *        colon-separated PEDICLE_DRILLING_PLUGIN_XML. The loader must outlive what it made.
 */
#ifndef PEDICLE_DRILLING_ROS_PLUGIN_LOADER_HPP_
#define PEDICLE_DRILLING_ROS_PLUGIN_LOADER_HPP_

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "pedicle_drilling/core/control/compensator_interface.hpp"
#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"

namespace pluginlib {
template <class T>
class ClassLoader;
}  // namespace pluginlib

namespace pedicle_drilling {

/** @brief Makes objects of a plugin base class by name; keeps their libraries loaded. */
template <class Base>
class PluginLoader {
 public:
  /** @brief Settings as text, name -> value. */
  using Settings = std::vector<std::pair<std::string, std::string>>;

  PluginLoader();
  ~PluginLoader();
  PluginLoader(const PluginLoader&) = delete;
  PluginLoader& operator=(const PluginLoader&) = delete;

  /**
   * @brief A configured object of class `name`.
   * @throws std::runtime_error naming the class when it cannot be loaded (unknown, not
   *         exported, library missing), std::invalid_argument for bad settings.
   */
  std::unique_ptr<Base> create(const std::string& name, const Settings& settings);

 private:
  void ensureLoader();
  std::unique_ptr<pluginlib::ClassLoader<Base>> loader_;
};

/** @brief Drilling-state recognizers by name. */
using RecognizerLoader = PluginLoader<core::RecognizerInterface>;
/** @brief Motion compensators by name. */
using CompensatorLoader = PluginLoader<core::CompensatorInterface>;

}  // namespace pedicle_drilling

#endif  // PEDICLE_DRILLING_ROS_PLUGIN_LOADER_HPP_
