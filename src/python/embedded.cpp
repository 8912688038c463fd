#include "embedded.hpp"

#include <pybind11/embed.h>

#include <mutex>
#include <stdexcept>

namespace py = pybind11;

namespace pedicle_drilling::python_detail {

void ensureInterpreter() {
  static std::once_flag once;
  std::call_once(once, [] {
    if (Py_IsInitialized()) return;
    py::initialize_interpreter(false);  // no signal handlers: the host process keeps its own
    PyEval_SaveThread();
  });
}

std::pair<std::string, std::string> splitClassName(const std::string& name, const char* what,
                                                   const char* example) {
  const std::size_t dot = name.rfind('.');
  if (dot == std::string::npos || dot == 0 || dot + 1 == name.size()) {
    throw std::runtime_error(std::string("python ") + what + " '" + name +
                             "': expected python:<module>.<Class>, e.g. python:" + example);
  }
  return {name.substr(0, dot), name.substr(dot + 1)};
}

}  // namespace pedicle_drilling::python_detail
