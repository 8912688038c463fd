/**
 * @file python_compensator.hpp
 * @brief A motion compensator written in Python, behind the same interface as the
 *        C++ ones: `python:<module>.<Class>` names it wherever a compensator class is named (the
 *        CompensationPlanner nodelet's ~compensator, trial_engine and the campaign's
 *        --compensator). The class is imported from the Python path into the interpreter
 *        embedded in the process (pybind11), made with no arguments and driven through its
 *        methods; pd_campaign.compensators documents the contract and ships an example.
 */
#ifndef PEDICLE_DRILLING_PYTHON_PYTHON_COMPENSATOR_HPP_
#define PEDICLE_DRILLING_PYTHON_PYTHON_COMPENSATOR_HPP_

#include <memory>
#include <string>
#include <vector>

#include "pedicle_drilling/core/control/compensator_interface.hpp"
#include "pedicle_drilling/python/python_recognizer.hpp"

namespace pedicle_drilling {

/**
 * @brief A Python class as a core::CompensatorInterface. Each call takes Python's GIL.
 *
 * The Python object must have `configure(settings: dict[str, str])`,
 * `set_patient(model: dict, params: dict)`, `set_ventilator(settings: dict)`,
 * `set_breath_start(t: float)`, `ready() -> bool` and `displacement(t: float)` returning three
 * numbers (a numpy array, a list or a tuple: metres, world frame, any constant origin);
 * `observe_marker(stamp: float, position: numpy.ndarray[3])`, `velocity_steps(t0, t1) -> list`,
 * `describe()` and `parameter_names()` are optional. The dicts: pd_campaign.compensators.
 * A non-finite displacement is an error naming the class.
 */
class PEDICLE_DRILLING_PYTHON_API PythonCompensator : public core::CompensatorInterface {
 public:
  /**
   * @brief Imports and makes `<module>.<Class>` (the name after `python:`).
   * @throws std::runtime_error naming the class and Python's error when it cannot be imported
   *         or made, or lacks a required method.
   */
  explicit PythonCompensator(const std::string& class_name);
  ~PythonCompensator() override;

  void configure(const core::CompensatorSettings& settings) override;
  void setPatient(const core::MotionModel& model, const core::CompensationParams& params) override;
  void setVentilator(const core::VentilatorSettings& settings) override;
  void setBreathStart(double t) override;
  void observeMarker(double stamp, const Eigen::Vector3d& position_world) override;
  bool ready() const override;
  Eigen::Vector3d displacement(double t) const override;
  std::vector<double> velocitySteps(double t0, double t1) const override;
  std::string describe() const override;
  std::vector<std::string> parameterNames() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string class_name_;
};

}  // namespace pedicle_drilling

#endif  // PEDICLE_DRILLING_PYTHON_PYTHON_COMPENSATOR_HPP_
