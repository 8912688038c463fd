/**
 * @file test_atomic_file.cpp
 * @brief core::AtomicFile: all or nothing, for one output and for several prepared together.
 */
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <dirent.h>
#include <unistd.h>

#include "pedicle_drilling/core/common/atomic_file.hpp"

namespace {

using pedicle_drilling::core::AtomicFile;
using pedicle_drilling::core::FileWriteError;
using pedicle_drilling::core::writeFileAtomically;

std::string makeTempDir() {
  char tmpl[] = "/tmp/pd_atomic_XXXXXX";
  const char* dir = mkdtemp(tmpl);
  if (dir == nullptr) throw std::runtime_error("mkdtemp failed");
  return dir;
}

std::vector<std::string> listDir(const std::string& dir) {
  std::vector<std::string> names;
  DIR* d = opendir(dir.c_str());
  while (dirent* e = readdir(d)) {
    const std::string n = e->d_name;
    if (n != "." && n != "..") names.push_back(n);
  }
  closedir(d);
  return names;
}

std::string readAll(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void removeDir(const std::string& dir) {
  for (const std::string& n : listDir(dir)) std::remove((dir + "/" + n).c_str());
  rmdir(dir.c_str());
}

}  // namespace

TEST(AtomicFile, ReplacesTheOldContentOnlyOnCommit) {
  const std::string dir = makeTempDir();
  const std::string path = dir + "/out.csv";
  writeFileAtomically(path, "old\n");
  {
    AtomicFile file(path);
    file.write("new\n");
    EXPECT_EQ(readAll(path), "old\n");   // written but not committed: the old file stands
    EXPECT_EQ(listDir(dir).size(), 2u);  // the old file and the temporary
  }
  EXPECT_EQ(readAll(path), "old\n");  // never committed: the temporary is gone, old kept
  EXPECT_EQ(listDir(dir), std::vector<std::string>{"out.csv"});
  AtomicFile file(path);
  file.write("new\n");
  file.commit();
  EXPECT_EQ(readAll(path), "new\n");
  EXPECT_EQ(listDir(dir), std::vector<std::string>{"out.csv"});
  removeDir(dir);
}

TEST(AtomicFile, SeveralOutputsAreAllOrNothingWhenOneDestinationIsMissing) {
  const std::string dir = makeTempDir();
  try {
    AtomicFile model(dir + "/model.yaml");
    AtomicFile fit(dir + "/missing/fit.csv");  // the second destination cannot be written
    ADD_FAILURE() << "a file in a missing folder was accepted";
  } catch (const FileWriteError& e) {
    EXPECT_NE(std::string(e.what()).find("missing/fit.csv"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(listDir(dir).empty());  // the first output's temporary was removed too
  removeDir(dir);
}

TEST(AtomicFile, RefusesPathsThatAreNotFilesAndMisuse) {
  const std::string dir = makeTempDir();
  EXPECT_THROW(AtomicFile(dir + "/"), FileWriteError);
  AtomicFile file(dir + "/x");
  EXPECT_THROW(file.commit(), FileWriteError);  // nothing written yet
  file.write("x");
  EXPECT_THROW(file.write("y"), FileWriteError);
  file.commit();
  EXPECT_THROW(file.commit(), FileWriteError);
  EXPECT_EQ(readAll(dir + "/x"), "x");
  removeDir(dir);
}
