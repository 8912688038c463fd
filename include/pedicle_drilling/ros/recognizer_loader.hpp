/**
 * @file recognizer_loader.hpp
 * @brief Creates a drilling-state recognizer by class name (issue 17): the built-in ones
 *        directly, any other through pluginlib (base class
 *        pedicle_drilling::core::RecognizerInterface, exported by a package's plugin XML under
 *        `<pedicle_drilling plugin="..."/>`). The loader must outlive the recognizers it made.
 */
#ifndef PEDICLE_DRILLING_ROS_RECOGNIZER_LOADER_HPP_
#define PEDICLE_DRILLING_ROS_RECOGNIZER_LOADER_HPP_

#include <memory>
#include <string>

#include "pedicle_drilling/core/recognizer_interface.hpp"

namespace pluginlib {
template <class T>
class ClassLoader;
}  // namespace pluginlib

namespace pedicle_drilling {

/** @brief Makes recognizers by name; keeps the plugin libraries loaded while it lives. */
class RecognizerLoader {
 public:
  RecognizerLoader();
  ~RecognizerLoader();
  RecognizerLoader(const RecognizerLoader&) = delete;
  RecognizerLoader& operator=(const RecognizerLoader&) = delete;

  /**
   * @brief A configured recognizer of class `name`.
   * @throws std::runtime_error naming the class when it cannot be loaded (unknown, not
   *         exported, library missing), std::invalid_argument for bad settings.
   */
  std::unique_ptr<core::RecognizerInterface> create(const std::string& name,
                                                    const core::RecognizerSettings& settings);

 private:
  std::unique_ptr<pluginlib::ClassLoader<core::RecognizerInterface>> loader_;
};

}  // namespace pedicle_drilling

#endif  // PEDICLE_DRILLING_ROS_RECOGNIZER_LOADER_HPP_
