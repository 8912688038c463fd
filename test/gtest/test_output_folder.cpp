// Tests of core::pathInsideFolder: a model file is written inside the declared folder only.
#include "pedicle_drilling/core/common/output_folder.hpp"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

namespace pd = pedicle_drilling::core;
namespace fs = std::filesystem;

namespace {

/** @brief A fresh temporary directory with `models/` (the folder) and `outside/` in it. */
class OutputFolder : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "pd_output_folder_XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    base_ = fs::canonical(pattern);
    fs::create_directories(base_ / "models" / "sub");
    fs::create_directories(base_ / "outside");
    folder_ = (base_ / "models").string();
  }
  void TearDown() override { fs::remove_all(base_); }

  std::string refusal(const std::string& path) const {
    try {
      pd::pathInsideFolder(folder_, path);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  }

  fs::path base_;
  std::string folder_;
};

}  // namespace

TEST_F(OutputFolder, APathInsideTheFolderResolvesThere) {
  EXPECT_EQ(pd::pathInsideFolder(folder_, "model.yaml"), (base_ / "models/model.yaml").string());
  EXPECT_EQ(pd::pathInsideFolder(folder_, "sub/model.yaml"),
            (base_ / "models/sub/model.yaml").string());
  EXPECT_EQ(pd::pathInsideFolder(folder_, folder_ + "/sub/../model.yaml"),
            (base_ / "models/model.yaml").string());
  // The folder itself given through a link: resolved first.
  fs::create_directory_symlink(base_ / "models", base_ / "link_to_models");
  EXPECT_EQ(pd::pathInsideFolder((base_ / "link_to_models").string(), "model.yaml"),
            (base_ / "models/model.yaml").string());
  // A link inside the folder to a file inside it: the file it leads to.
  fs::create_symlink(base_ / "models/sub/real.yaml", base_ / "models/alias.yaml");
  EXPECT_EQ(pd::pathInsideFolder(folder_, "alias.yaml"), (base_ / "models/sub/real.yaml").string());
}

TEST_F(OutputFolder, APathOutsideTheFolderIsRefusedNamingIt) {
  for (const std::string& path :
       {std::string("../outside/model.yaml"), std::string("/etc/passwd"),
        (base_ / "outside/model.yaml").string(), std::string("sub/../../outside/model.yaml")}) {
    const std::string why = refusal(path);
    EXPECT_NE(why.find("'" + path + "'"), std::string::npos) << path << ": " << why;
    EXPECT_NE(why.find("outside the model folder"), std::string::npos) << path << ": " << why;
  }
  // A directory link inside the folder that leads out of it.
  fs::create_directory_symlink(base_ / "outside", base_ / "models/escape");
  EXPECT_NE(refusal("escape/model.yaml").find("outside the model folder"), std::string::npos);
  // A file link inside the folder that leads out of it (dangling or not).
  fs::create_symlink(base_ / "outside/target.yaml", base_ / "models/dangling.yaml");
  EXPECT_NE(refusal("dangling.yaml").find("outside the model folder"), std::string::npos);
  std::ofstream(base_ / "outside/target.yaml") << "x\n";
  EXPECT_NE(refusal("dangling.yaml").find("outside the model folder"), std::string::npos);
}

TEST_F(OutputFolder, NoFileNoDirectoryOrNoFolderIsRefused) {
  EXPECT_NE(refusal("").find("names no file"), std::string::npos);
  EXPECT_NE(refusal(".").find("names no file"), std::string::npos);
  EXPECT_NE(refusal("sub/..").find("names no file"), std::string::npos);
  EXPECT_NE(refusal("missing/model.yaml").find("does not exist"), std::string::npos);
  EXPECT_THROW(pd::pathInsideFolder((base_ / "nowhere").string(), "model.yaml"),
               std::invalid_argument);
}

TEST(DefaultModelFolder, IsUnderRosHome) {
  const char* ros_home = std::getenv("ROS_HOME");
  const char* home = std::getenv("HOME");
  const std::string kept_ros_home = ros_home != nullptr ? ros_home : "";
  const std::string kept_home = home != nullptr ? home : "";
  setenv("ROS_HOME", "/var/ros_home", 1);
  EXPECT_EQ(pd::defaultModelFolder(), "/var/ros_home/pedicle_drilling/models");
  unsetenv("ROS_HOME");
  setenv("HOME", "/var/user_home", 1);
  EXPECT_EQ(pd::defaultModelFolder(), "/var/user_home/.ros/pedicle_drilling/models");
  if (ros_home != nullptr) setenv("ROS_HOME", kept_ros_home.c_str(), 1);
  if (home != nullptr) setenv("HOME", kept_home.c_str(), 1);
}
