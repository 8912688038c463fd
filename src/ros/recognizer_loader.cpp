#include "pedicle_drilling/ros/recognizer_loader.hpp"

#include <pluginlib/class_loader.hpp>

#include <algorithm>
#include <cstdlib>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace pedicle_drilling {

RecognizerLoader::RecognizerLoader() = default;
RecognizerLoader::~RecognizerLoader() = default;

std::unique_ptr<core::RecognizerInterface> RecognizerLoader::create(
    const std::string& name, const core::RecognizerSettings& settings) {
  const std::vector<std::string> builtin = core::builtinRecognizerNames();
  if (std::find(builtin.begin(), builtin.end(), name) != builtin.end()) {
    return core::makeBuiltinRecognizer(name, settings);
  }
  std::unique_ptr<core::RecognizerInterface> r;
  try {
    if (!loader_) {
      const char* package = "pedicle_drilling";
      const char* base = "pedicle_drilling::core::RecognizerInterface";
      loader_ = std::make_unique<pluginlib::ClassLoader<core::RecognizerInterface>>(package, base);
      // Plugin XML files outside any package export (a quick experiment, the test plugin):
      // PEDICLE_DRILLING_PLUGIN_XML, colon-separated, added to the exported ones.
      const char* extra = std::getenv("PEDICLE_DRILLING_PLUGIN_XML");
      if (extra != nullptr && *extra != '\0') {
        std::vector<std::string> paths = loader_->getPluginXmlPaths();
        std::stringstream list(extra);
        std::string path;
        while (std::getline(list, path, ':')) {
          if (!path.empty()) paths.push_back(path);
        }
        loader_ = std::make_unique<pluginlib::ClassLoader<core::RecognizerInterface>>(
            package, base, "plugin", paths);
      }
    }
    r.reset(loader_->createUnmanagedInstance(name));
  } catch (const pluginlib::PluginlibException& e) {
    std::string known;
    if (loader_) {
      for (const std::string& c : loader_->getDeclaredClasses()) {
        known += (known.empty() ? "" : ", ") + c;
      }
    }
    throw std::runtime_error("recognizer class '" + name + "' cannot be loaded (declared: " +
                             (known.empty() ? "none" : known) + "): " + e.what());
  }
  r->configure(settings);
  return r;
}

}  // namespace pedicle_drilling
