#include "pedicle_drilling/ros/plugin_loader.hpp"

#include "pedicle_drilling/python/python_compensator.hpp"
#include "pedicle_drilling/python/python_recognizer.hpp"

#include <pluginlib/class_loader.hpp>

#include <algorithm>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling {

namespace {

/** @brief What differs between the plugin kinds. */
template <class Base>
struct PluginKind;

template <>
struct PluginKind<core::RecognizerInterface> {
  /** @brief A class written in Python (`python:<module>.<Class>`), else nullptr. */
  static std::unique_ptr<core::RecognizerInterface> makeForeign(const std::string& name) {
    if (!isPythonClassName(name)) return nullptr;
    return std::make_unique<PythonRecognizer>(name.substr(std::string(kPythonClassPrefix).size()));
  }
  static constexpr const char* kWhat = "recognizer";
  static constexpr const char* kBase = "pedicle_drilling::core::RecognizerInterface";
  static std::vector<std::string> builtin() { return core::builtinRecognizerNames(); }
  static std::unique_ptr<core::RecognizerInterface> make(const std::string& name,
                                                         const core::RecognizerSettings& s) {
    return core::makeBuiltinRecognizer(name, s);
  }
};

template <>
struct PluginKind<core::CompensatorInterface> {
  /** @brief A class written in Python (`python:<module>.<Class>`), else nullptr. */
  static std::unique_ptr<core::CompensatorInterface> makeForeign(const std::string& name) {
    if (!isPythonClassName(name)) return nullptr;
    return std::make_unique<PythonCompensator>(name.substr(std::string(kPythonClassPrefix).size()));
  }
  static constexpr const char* kWhat = "compensator";
  static constexpr const char* kBase = "pedicle_drilling::core::CompensatorInterface";
  static std::vector<std::string> builtin() { return core::builtinCompensatorNames(); }
  static std::unique_ptr<core::CompensatorInterface> make(const std::string& name,
                                                          const core::CompensatorSettings& s) {
    return core::makeBuiltinCompensator(name, s);
  }
};

}  // namespace

template <class Base>
PluginLoader<Base>::PluginLoader() = default;
template <class Base>
PluginLoader<Base>::~PluginLoader() = default;

template <class Base>
void PluginLoader<Base>::ensureLoader() {
  if (loader_) return;
  const char* package = "pedicle_drilling";
  const char* base = PluginKind<Base>::kBase;
  loader_ = std::make_unique<pluginlib::ClassLoader<Base>>(package, base);
  const char* extra = std::getenv("PEDICLE_DRILLING_PLUGIN_XML");
  if (extra != nullptr && *extra != '\0') {
    std::vector<std::string> paths = loader_->getPluginXmlPaths();
    std::stringstream list(extra);
    std::string path;
    while (std::getline(list, path, ':')) {
      if (!path.empty()) paths.push_back(path);
    }
    loader_ = std::make_unique<pluginlib::ClassLoader<Base>>(package, base, "plugin", paths);
  }
}

template <class Base>
std::unique_ptr<Base> PluginLoader<Base>::create(const std::string& name,
                                                 const Settings& settings) {
  const std::vector<std::string> builtin = PluginKind<Base>::builtin();
  if (std::find(builtin.begin(), builtin.end(), name) != builtin.end()) {
    return PluginKind<Base>::make(name, settings);
  }
  if (std::unique_ptr<Base> foreign = PluginKind<Base>::makeForeign(name)) {
    foreign->configure(settings);
    return foreign;
  }
  std::unique_ptr<Base> object;
  try {
    ensureLoader();
    object.reset(loader_->createUnmanagedInstance(name));
  } catch (const pluginlib::PluginlibException& e) {
    std::string known;
    if (loader_) {
      for (const std::string& c : loader_->getDeclaredClasses()) {
        known += (known.empty() ? "" : ", ") + c;
      }
    }
    throw std::runtime_error(std::string(PluginKind<Base>::kWhat) + " class '" + name +
                             "' cannot be loaded (declared: " + (known.empty() ? "none" : known) +
                             "): " + e.what());
  }
  object->configure(settings);
  return object;
}

template class PluginLoader<core::RecognizerInterface>;
template class PluginLoader<core::CompensatorInterface>;

}  // namespace pedicle_drilling
