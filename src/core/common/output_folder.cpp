#include "pedicle_drilling/core/common/output_folder.hpp"

#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <system_error>

namespace pedicle_drilling::core {

namespace fs = std::filesystem;

std::string defaultModelFolder() {
  const char* ros_home = std::getenv("ROS_HOME");
  if (ros_home != nullptr && *ros_home != '\0') {
    return (fs::path(ros_home) / "pedicle_drilling" / "models").string();
  }
  const char* home = std::getenv("HOME");
  if (home == nullptr || *home == '\0') return "";
  return (fs::path(home) / ".ros" / "pedicle_drilling" / "models").string();
}

namespace {

/** @brief True if @p p is @p root itself or below it (both canonical). */
bool inside(const fs::path& root, const fs::path& p) {
  const fs::path relative = p.lexically_relative(root);
  return !relative.empty() && relative != "." && *relative.begin() != "..";
}

}  // namespace

std::string pathInsideFolder(const std::string& folder, const std::string& path) {
  std::error_code ec;
  const fs::path root = fs::canonical(folder, ec);
  if (ec || !fs::is_directory(root)) {
    throw std::invalid_argument("the model folder '" + folder + "' is not an existing directory");
  }
  const std::string where = "'" + path + "' (model folder '" + root.string() + "')";
  fs::path p(path);
  if (p.is_relative()) p = root / p;
  const fs::path name = p.filename();
  if (path.empty() || name.empty() || name == "." || name == "..") {
    throw std::invalid_argument("the path " + where + " names no file");
  }
  const fs::path directory = fs::canonical(p.parent_path(), ec);  // links and .. resolved
  if (ec) throw std::invalid_argument("the directory of " + where + " does not exist");
  fs::path target = directory / name;
  // Where a link leads, link after link (a dangling one too: the file would be made there).
  for (int hops = 0; fs::is_symlink(fs::symlink_status(target)); ++hops) {
    fs::path next = fs::read_symlink(target, ec);
    if (!ec && next.is_relative()) next = target.parent_path() / next;
    if (!ec) target = fs::weakly_canonical(next, ec);
    if (ec || hops == 40) {
      throw std::invalid_argument("the symbolic link " + where + " cannot be resolved");
    }
  }
  if (!inside(root, target) || target == root) {
    throw std::invalid_argument("the path " + where + " is outside the model folder (" +
                                target.string() + "): refused");
  }
  return target.string();
}

}  // namespace pedicle_drilling::core
