// The embedded interpreter shared by the Python plugins (PythonRecognizer, PythonCompensator):
// internal to the pedicle_drilling_python library, no installed header.
#ifndef PEDICLE_DRILLING_PYTHON_EMBEDDED_HPP_
#define PEDICLE_DRILLING_PYTHON_EMBEDDED_HPP_

#include <pybind11/pybind11.h>

#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

namespace pedicle_drilling::python_detail {

/**
 * @brief Starts the process's interpreter once, on first use; it is never finalised (a nodelet's
 *        library may be unloaded while Python objects it made are still referenced). The
 *        starting thread gives the GIL up, so that every call takes it from whichever thread it
 *        runs on. A process that already runs Python is used as is.
 */
void ensureInterpreter();

/**
 * @brief "<module>.<Class>" split at its last dot.
 * @param what "recognizer" or "compensator", for the message.
 * @param example a class name to show in the message.
 * @throws std::runtime_error naming the form expected.
 */
std::pair<std::string, std::string> splitClassName(const std::string& name, const char* what,
                                                   const char* example);

/**
 * @brief Imports `<module>.<Class>` (a name without the `python:` prefix) and makes it with no
 *        arguments, checking that it has every method of `methods`. Starts the interpreter and
 *        takes the GIL itself; the object is released by the caller with the GIL held.
 * @throws std::runtime_error "python <what> '<name>' cannot be made: <Python's error>".
 */
pybind11::object makeObject(const std::string& class_name, const char* what, const char* example,
                            std::initializer_list<const char*> methods);

/**
 * @brief Calls `object.configure(settings)` with a dict of name -> text (the GIL held by the
 *        caller).
 * @throws std::invalid_argument with Python's message (which names the parameter first, the
 *         contract of every plugin's configure).
 */
void configureObject(const pybind11::object& object,
                     const std::vector<std::pair<std::string, std::string>>& settings);

}  // namespace pedicle_drilling::python_detail

#endif  // PEDICLE_DRILLING_PYTHON_EMBEDDED_HPP_
