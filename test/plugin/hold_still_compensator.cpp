/**
 * @file hold_still_compensator.cpp
 * @brief A compensator plugin that lives only in the test tree: an outside class,
 *        built apart from our library and known to us only by its name, plugs into the planner
 *        through pluginlib. It predicts that the bone holds still at `offset_mm` along world z
 *        (no compensation at all: nothing a surgeon should use).
 */
#include <pluginlib/class_list_macros.hpp>

#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/control/compensator_interface.hpp"

namespace test_plugins {

namespace pd = pedicle_drilling::core;

class HoldStillCompensator : public pd::CompensatorInterface {
 public:
  void configure(const pd::CompensatorSettings& settings) override {
    for (const auto& [name, value] : settings) {
      if (name != "offset_mm") {
        throw std::invalid_argument(name + ": not a parameter of test_plugins/HoldStill");
      }
      offset_m_ = 1e-3 * std::stod(value);
    }
  }
  void setPatient(const pd::MotionModel&, const pd::CompensationParams&) override {}
  void setVentilator(const pd::VentilatorSettings&) override {}
  void setBreathStart(double) override {}
  bool ready() const override { return true; }
  Eigen::Vector3d displacement(double) const override { return {0.0, 0.0, offset_m_}; }
  std::string describe() const override { return "test_plugins/HoldStill: the bone holds still"; }
  std::vector<std::string> parameterNames() const override { return {"offset_mm"}; }

 private:
  double offset_m_ = 0.0;
};

}  // namespace test_plugins

PLUGINLIB_EXPORT_CLASS(test_plugins::HoldStillCompensator,
                       pedicle_drilling::core::CompensatorInterface)
