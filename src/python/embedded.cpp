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

py::object makeObject(const std::string& class_name, const char* what, const char* example,
                      std::initializer_list<const char*> methods) {
  ensureInterpreter();
  const auto [module_name, type_name] = splitClassName(class_name, what, example);
  py::gil_scoped_acquire gil;
  try {
    py::object object = py::module_::import(module_name.c_str()).attr(type_name.c_str())();
    for (const char* method : methods) {
      if (!py::hasattr(object, method)) {
        throw std::runtime_error(std::string("has no method ") + method + "()");
      }
    }
    return object;
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("python ") + what + " '" + class_name +
                             "' cannot be made: " + e.what());
  }
}

void configureObject(const py::object& object,
                     const std::vector<std::pair<std::string, std::string>>& settings) {
  py::dict values;
  for (const auto& [name, value] : settings) values[py::str(name)] = py::str(value);
  try {
    object.attr("configure")(values);
  } catch (const py::error_already_set& e) {
    throw std::invalid_argument(py::str(e.value()).cast<std::string>());
  }
}

}  // namespace pedicle_drilling::python_detail
