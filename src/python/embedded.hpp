// The embedded interpreter shared by the Python plugins (PythonRecognizer, PythonCompensator):
// internal to the pedicle_drilling_python library, no installed header.
#ifndef PEDICLE_DRILLING_PYTHON_EMBEDDED_HPP_
#define PEDICLE_DRILLING_PYTHON_EMBEDDED_HPP_

#include <string>
#include <utility>

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

}  // namespace pedicle_drilling::python_detail

#endif  // PEDICLE_DRILLING_PYTHON_EMBEDDED_HPP_
