// Helpers shared by the gtest suites: files of the package's source tree.
#ifndef PEDICLE_DRILLING_TEST_GTEST_SUPPORT_HPP_
#define PEDICLE_DRILLING_TEST_GTEST_SUPPORT_HPP_

#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

namespace pedicle_drilling::test {

/** @brief The package's source folder (passed by CMakeLists.txt). */
inline std::string sourceDir() { return PEDICLE_DRILLING_SOURCE_DIR; }

/** @brief Whole text of a file; throws naming it when it cannot be read. */
inline std::string readFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open " + path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/** @brief urdf/workcell.urdf of the package. */
inline std::string workcellUrdf() { return readFile(sourceDir() + "/urdf/workcell.urdf"); }

}  // namespace pedicle_drilling::test

#endif  // PEDICLE_DRILLING_TEST_GTEST_SUPPORT_HPP_
