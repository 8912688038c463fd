#include "pedicle_drilling/core/robot/urdf_model.hpp"

#include <urdf_parser/urdf_parser.h>

#include <mutex>

namespace pedicle_drilling::core {

namespace {

/** @brief What parseUrdfKept keeps. Never destroyed: a thread may still parse at exit. */
struct Kept {
  std::mutex mutex;
  std::string xml;
  std::shared_ptr<const urdf::ModelInterface> model;
};

Kept& kept() {
  static Kept* const state = new Kept;
  return *state;
}

}  // namespace

std::shared_ptr<const urdf::ModelInterface> parseUrdfKept(const std::string& urdf_xml) {
  Kept& k = kept();
  const std::lock_guard<std::mutex> lock(k.mutex);
  if (k.model && k.xml == urdf_xml) return k.model;
  std::shared_ptr<const urdf::ModelInterface> model = urdf::parseURDF(urdf_xml);
  if (!model) return nullptr;
  k.xml = urdf_xml;
  k.model = model;
  return model;
}

}  // namespace pedicle_drilling::core
