#include "pedicle_drilling/core/robot/urdf_model.hpp"

#include <urdf_parser/urdf_parser.h>

#include <mutex>

namespace pedicle_drilling::core {

std::shared_ptr<const urdf::ModelInterface> parseUrdfKept(const std::string& urdf_xml) {
  static std::mutex mutex;
  static std::string kept_xml;
  static std::shared_ptr<const urdf::ModelInterface> kept_model;
  const std::lock_guard<std::mutex> lock(mutex);
  if (kept_model && kept_xml == urdf_xml) return kept_model;
  std::shared_ptr<const urdf::ModelInterface> model = urdf::parseURDF(urdf_xml);
  if (!model) return nullptr;
  kept_xml = urdf_xml;
  kept_model = model;
  return model;
}

}  // namespace pedicle_drilling::core
