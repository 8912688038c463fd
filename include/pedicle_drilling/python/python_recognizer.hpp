/**
 * @file python_recognizer.hpp
 * @brief A drilling-state recognizer written in Python, behind the same interface as
 *        the C++ ones: `python:<module>.<Class>` names it wherever a recognizer class is named
 *        (the StateRecognizer nodelet's ~recognizer, trial_engine and the campaign's
 *        --recognizer). The class is imported from the Python path (PYTHONPATH, the sourced
 *        workspaces) into an interpreter embedded in the process (pybind11), made with no
 *        arguments and driven through its methods; pd_campaign.recognizers documents the
 *        contract and ships examples.
 */
#ifndef PEDICLE_DRILLING_PYTHON_PYTHON_RECOGNIZER_HPP_
#define PEDICLE_DRILLING_PYTHON_PYTHON_RECOGNIZER_HPP_

#include <memory>
#include <string>
#include <vector>

#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"

/// The library is built with hidden visibility (pybind11's own types are hidden); its API is
/// exported by name.
#define PEDICLE_DRILLING_PYTHON_API __attribute__((visibility("default")))

namespace pedicle_drilling {

/** @brief The prefix that names a Python recognizer class: `python:<module>.<Class>`. */
constexpr const char* kPythonClassPrefix = "python:";

/** @brief Whether @p name names a Python class (starts with kPythonClassPrefix). */
PEDICLE_DRILLING_PYTHON_API bool isPythonClassName(const std::string& name);

/**
 * @brief A Python class as a core::RecognizerInterface. Each call takes Python's GIL, so the
 *        object may be used from any one thread at a time (as every recognizer).
 *
 * The Python object must have `configure(settings: dict[str, str])`, `reset()` and
 * `push(t: float, raw_force: float) -> dict` (or `push_sample(sample: dict) -> dict`, which
 * receives the whole wrench and the drill's context instead when the class defines it); the
 * dict may set `state` (a state name:
 * idle, outer_cortical, outer_punctured, cancellous, inner_cortical, stopped), `layer_state`,
 * `new_average`, `averaged_force`, `feature`, `stop`, `last_key_point` (other keys are an
 * error, naming them). `stop_reason()`, `describe()` and `parameter_names()` are optional. The
 * stop is latched here whatever the object says after it (the interface's contract), with the
 * time and raw index of the sample that brought it.
 */
class PEDICLE_DRILLING_PYTHON_API PythonRecognizer : public core::RecognizerInterface {
 public:
  /**
   * @brief Imports and makes `<module>.<Class>` (the name after `python:`).
   * @throws std::runtime_error naming the class and Python's error when it cannot be imported
   *         or made, or lacks configure, reset or push.
   */
  explicit PythonRecognizer(const std::string& class_name);
  ~PythonRecognizer() override;

  void configure(const core::RecognizerSettings& settings) override;
  void reset() override;
  const core::RecognizerOutput& push(double t, double raw_force) override;
  /**
   * @brief The object's `push_sample(sample: dict)` when its class defines one (the dict: `t`,
   *        `thrust`, `force` and `torque` as (x, y, z) tuples, `feed_depth_m`, `spindle_rpm`,
   *        `feed_command_m`, `tracker` (x, y, z) and `tracker_stamp`; NaN for what is unknown),
   * else push() of the thrust.
   */
  const core::RecognizerOutput& pushSample(const core::RecognizerSample& sample) override;
  const core::RecognizerOutput& output() const override { return output_; }
  std::string stopReason() const override;
  std::string describe() const override;
  std::vector<std::string> parameterNames() const override;

 private:
  /** @brief The dict that @p call (a Python call of @p method, GIL held) returns, as output. */
  template <typename Call>
  const core::RecognizerOutput& take(const char* method, double t, Call call);

  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string class_name_;
  core::RecognizerOutput output_;
  std::size_t index_ = 0;  ///< raw samples pushed since the reset
};

}  // namespace pedicle_drilling

#endif  // PEDICLE_DRILLING_PYTHON_PYTHON_RECOGNIZER_HPP_
