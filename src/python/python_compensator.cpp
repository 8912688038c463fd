#include "pedicle_drilling/python/python_compensator.hpp"

#include <pybind11/eigen.h>
#include <pybind11/embed.h>
#include <pybind11/stl.h>

#include <cmath>
#include <stdexcept>

#include "embedded.hpp"
#include "pedicle_drilling/core/breathing/motion_model.hpp"
#include "pedicle_drilling/core/control/compensation_planner.hpp"

namespace py = pybind11;

namespace pedicle_drilling {

namespace {

py::list vector3(const Eigen::Vector3d& v) {
  return py::cast(std::vector<double>{v.x(), v.y(), v.z()});
}

}  // namespace

/** @brief The Python object, touched only with the GIL held. */
struct PythonCompensator::Impl {
  py::object object;
  bool has_observe = false;
  bool has_steps = false;
};

PythonCompensator::PythonCompensator(const std::string& class_name)
    : impl_(std::make_unique<Impl>()), class_name_(class_name) {
  py::object object = python_detail::makeObject(
      class_name, "compensator", "pd_campaign.compensators.PhaseTemplateCompensator",
      {"configure", "set_patient", "set_ventilator", "set_breath_start", "ready", "displacement"});
  py::gil_scoped_acquire gil;
  impl_->object = std::move(object);
  impl_->has_observe = py::hasattr(impl_->object, "observe_marker");
  impl_->has_steps = py::hasattr(impl_->object, "velocity_steps");
}

PythonCompensator::~PythonCompensator() {
  py::gil_scoped_acquire gil;
  impl_->object = py::object();  // released with the GIL held
}

void PythonCompensator::configure(const core::CompensatorSettings& settings) {
  py::gil_scoped_acquire gil;
  python_detail::configureObject(impl_->object, settings);
}

void PythonCompensator::setPatient(const core::MotionModel& model,
                                   const core::CompensationParams& params) {
  py::gil_scoped_acquire gil;
  py::dict axes;
  for (core::Axis a : core::kAllAxes) {
    const core::AxisModel& m = model.axis(a);
    py::dict axis;
    axis["kind"] = core::modelKindName(m.kind);
    axis["q0"] = m.q0;
    axis["q1"] = m.q1;
    axis["q2"] = m.q2;
    axes[py::str(core::axisName(a))] = axis;
  }
  py::dict p;
  p["feed_rate_m_s"] = params.feed_rate_m_s;
  p["period_s"] = params.period_s;
  p["latency_s"] = params.latency_s;
  p["predict_axis"] =
      py::cast(std::vector<bool>(params.predict_axis.begin(), params.predict_axis.end()));
  p["compensate_lateral"] = params.compensate_lateral;
  p["drill_axis"] = vector3(params.drill_axis);
  py::dict directions;
  for (core::Axis a : core::kAllAxes) {
    directions[py::str(core::axisName(a))] = vector3(params.axis_direction[static_cast<int>(a)]);
  }
  p["axis_direction"] = directions;
  try {
    impl_->object.attr("set_patient")(axes, p);
  } catch (const py::error_already_set& e) {
    throw std::invalid_argument(class_name_ + ".set_patient: " + e.what());
  }
}

void PythonCompensator::setVentilator(const core::VentilatorSettings& settings) {
  settings.validate();
  py::gil_scoped_acquire gil;
  py::dict v;
  v["tv_max_ml"] = settings.tv_max_ml;
  v["rate_bpm"] = settings.rate_bpm;
  v["ie_inspiratory"] = settings.ie_inspiratory;
  v["ie_expiratory"] = settings.ie_expiratory;
  v["waveform"] = core::waveformName(settings.waveform);
  v["pause_fraction"] = settings.pause_fraction;
  try {
    impl_->object.attr("set_ventilator")(v);
  } catch (const py::error_already_set& e) {
    throw std::invalid_argument(class_name_ + ".set_ventilator: " + e.what());
  }
}

void PythonCompensator::setBreathStart(double t) {
  py::gil_scoped_acquire gil;
  try {
    impl_->object.attr("set_breath_start")(t);
  } catch (const py::error_already_set& e) {
    throw std::runtime_error(class_name_ + ".set_breath_start: " + e.what());
  }
}

void PythonCompensator::observeMarker(double stamp, const Eigen::Vector3d& position_world) {
  py::gil_scoped_acquire gil;
  if (!impl_->has_observe) return;
  try {
    impl_->object.attr("observe_marker")(stamp, position_world);  // a numpy array (pybind11/eigen)
  } catch (const py::error_already_set& e) {
    throw std::runtime_error(class_name_ + ".observe_marker: " + e.what());
  }
}

bool PythonCompensator::ready() const {
  py::gil_scoped_acquire gil;
  try {
    return impl_->object.attr("ready")().cast<bool>();
  } catch (const py::error_already_set& e) {
    throw std::runtime_error(class_name_ + ".ready: " + e.what());
  }
}

Eigen::Vector3d PythonCompensator::displacement(double t) const {
  py::gil_scoped_acquire gil;
  Eigen::Vector3d d;
  try {
    const std::vector<double> v = impl_->object.attr("displacement")(t).cast<std::vector<double>>();
    if (v.size() != 3) {
      throw std::runtime_error(class_name_ + ".displacement: " + std::to_string(v.size()) +
                               " numbers, expected 3 (metres, world frame)");
    }
    d = Eigen::Vector3d(v[0], v[1], v[2]);
  } catch (const py::error_already_set& e) {
    throw std::runtime_error(class_name_ + ".displacement: " + e.what());
  } catch (const py::cast_error&) {
    throw std::runtime_error(class_name_ + ".displacement: must return three numbers");
  }
  if (!d.allFinite()) {
    throw std::runtime_error(class_name_ + ".displacement: not finite at t=" + std::to_string(t));
  }
  return d;
}

std::vector<double> PythonCompensator::velocitySteps(double t0, double t1) const {
  py::gil_scoped_acquire gil;
  if (!impl_->has_steps) return {};
  try {
    return impl_->object.attr("velocity_steps")(t0, t1).cast<std::vector<double>>();
  } catch (const py::error_already_set& e) {
    throw std::runtime_error(class_name_ + ".velocity_steps: " + e.what());
  }
}

std::string PythonCompensator::describe() const {
  py::gil_scoped_acquire gil;
  if (py::hasattr(impl_->object, "describe")) return py::str(impl_->object.attr("describe")());
  return class_name_;
}

std::vector<std::string> PythonCompensator::parameterNames() const {
  py::gil_scoped_acquire gil;
  if (!py::hasattr(impl_->object, "parameter_names")) return {};
  return impl_->object.attr("parameter_names")().cast<std::vector<std::string>>();
}

}  // namespace pedicle_drilling
