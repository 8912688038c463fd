#include "pedicle_drilling/core/robot/controller_layout.hpp"

#include <set>
#include <stdexcept>

namespace pedicle_drilling::core {

namespace {

void checkName(const std::string& parameter, const std::string& name) {
  if (name.empty() || name.front() == '/' || name.back() == '/' ||
      name.find_first_of(" \t") != std::string::npos) {
    throw std::invalid_argument(
        parameter + " = '" + name +
        "' must be a non-empty relative name (its topics are <name>/command "
        "and <name>/state)");
  }
}

}  // namespace

const ParamTable<ControllerLayoutParams>& ControllerLayoutParams::table() {
  static const ParamTable<ControllerLayoutParams> t = [] {
    using L = ControllerLayoutParams;
    ParamTable<L> d;
    d.text("arm_controller", &L::arm_controller)
        .names("arm_controller_joints", &L::arm_controller_joints)
        .text("feed_controller", &L::feed_controller)
        .names("feed_controller_joints", &L::feed_controller_joints);
    return d;
  }();
  return t;
}

std::vector<ControllerSpec> controllerLayout(const ControllerLayoutParams& params,
                                             const std::vector<std::string>& commandable) {
  checkName("arm_controller", params.arm_controller);
  checkName("feed_controller", params.feed_controller);
  std::set<std::string> owned;
  const auto take = [&](const std::string& parameter, const std::vector<std::string>& joints) {
    if (joints.empty()) throw std::invalid_argument(parameter + " must name at least one joint");
    for (const std::string& j : joints) {
      if (std::find(commandable.begin(), commandable.end(), j) == commandable.end()) {
        std::string list;
        for (const std::string& c : commandable) list += (list.empty() ? "" : ", ") + c;
        throw std::invalid_argument(parameter + ": '" + j +
                                    "' is not a commandable joint (one of " + list + ")");
      }
      if (!owned.insert(j).second) {
        throw std::invalid_argument(parameter + ": joint '" + j +
                                    "' is owned by another controller already");
      }
    }
  };
  take("arm_controller_joints", params.arm_controller_joints);
  take("feed_controller_joints", params.feed_controller_joints);
  for (const std::string& c : commandable) {
    if (owned.count(c) == 0) {
      throw std::invalid_argument(
          "arm_controller_joints / feed_controller_joints: no controller owns '" + c + "'");
    }
  }
  if (params.feed_controller == params.arm_controller) {
    ControllerSpec one{params.arm_controller, params.arm_controller_joints};
    one.joints.insert(one.joints.end(), params.feed_controller_joints.begin(),
                      params.feed_controller_joints.end());
    return {one};
  }
  return {{params.arm_controller, params.arm_controller_joints},
          {params.feed_controller, params.feed_controller_joints}};
}

int ownerOf(const std::vector<ControllerSpec>& controllers, const std::string& joint) {
  for (std::size_t c = 0; c < controllers.size(); ++c) {
    const std::vector<std::string>& own = controllers[c].joints;
    if (std::find(own.begin(), own.end(), joint) != own.end()) return static_cast<int>(c);
  }
  return -1;
}

}  // namespace pedicle_drilling::core
