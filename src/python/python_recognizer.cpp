#include "pedicle_drilling/python/python_recognizer.hpp"

#include <pybind11/embed.h>
#include <pybind11/stl.h>

#include <cmath>
#include <set>
#include <stdexcept>

#include "embedded.hpp"

namespace py = pybind11;

namespace pedicle_drilling {

namespace {

core::DrillingState stateFromName(const std::string& key, const std::string& name) {
  using S = core::DrillingState;
  for (S s : {S::kIdle, S::kOuterCortical, S::kOuterPunctured, S::kCancellous, S::kInnerCortical,
              S::kBreakthrough, S::kStopped}) {
    if (name == core::toString(s)) return s;
  }
  throw std::invalid_argument(key + ": unknown state '" + name +
                              "' (idle, outer_cortical, outer_punctured, cancellous, "
                              "inner_cortical, breakthrough, stopped)");
}

const std::set<std::string>& outputKeys() {
  static const std::set<std::string> keys{
      "state", "layer_state", "new_average", "averaged_force", "feature", "stop", "last_key_point"};
  return keys;
}

}  // namespace

bool isPythonClassName(const std::string& name) { return name.rfind(kPythonClassPrefix, 0) == 0; }

/** @brief The Python object, touched only with the GIL held. */
struct PythonRecognizer::Impl {
  py::object object;
  bool reads_sample = false;  ///< the class defines push_sample: it gets the whole sample
};

PythonRecognizer::PythonRecognizer(const std::string& class_name)
    : impl_(std::make_unique<Impl>()), class_name_(class_name) {
  py::object object = python_detail::makeObject(class_name, "recognizer",
                                                "pd_campaign.recognizers.ThresholdRecognizer",
                                                {"configure", "reset", "push"});
  py::gil_scoped_acquire gil;
  impl_->object = std::move(object);
  impl_->reads_sample = py::hasattr(impl_->object, "push_sample");
}

PythonRecognizer::~PythonRecognizer() {
  py::gil_scoped_acquire gil;
  impl_->object = py::object();  // released with the GIL held
}

void PythonRecognizer::configure(const core::RecognizerSettings& settings) {
  py::gil_scoped_acquire gil;
  python_detail::configureObject(impl_->object, settings);
  output_ = core::RecognizerOutput();
  index_ = 0;
}

void PythonRecognizer::reset() {
  py::gil_scoped_acquire gil;
  impl_->object.attr("reset")();
  output_ = core::RecognizerOutput();
  index_ = 0;
}

const core::RecognizerOutput& PythonRecognizer::push(double t, double raw_force) {
  if (!std::isfinite(t) || !std::isfinite(raw_force)) {
    throw std::invalid_argument("push: t and raw_force must be finite");
  }
  py::gil_scoped_acquire gil;
  return take("push", t, [&]() { return impl_->object.attr("push")(t, raw_force); });
}

const core::RecognizerOutput& PythonRecognizer::pushSample(const core::RecognizerSample& sample) {
  if (!impl_->reads_sample) return push(sample.t, sample.thrust_n);
  if (!std::isfinite(sample.t) || !std::isfinite(sample.thrust_n)) {
    throw std::invalid_argument("push_sample: t and thrust must be finite");
  }
  py::gil_scoped_acquire gil;
  return take("push_sample", sample.t, [&]() {
    py::dict d;
    d["t"] = sample.t;
    d["thrust"] = sample.thrust_n;
    d["force"] = py::make_tuple(sample.force_n[0], sample.force_n[1], sample.force_n[2]);
    d["torque"] = py::make_tuple(sample.torque_nm[0], sample.torque_nm[1], sample.torque_nm[2]);
    d["feed_depth_m"] = sample.feed_depth_m;
    d["spindle_rpm"] = sample.spindle_rpm;
    d["feed_command_m"] = sample.feed_command_m;
    d["tracker"] = py::make_tuple(sample.tracker_m[0], sample.tracker_m[1], sample.tracker_m[2]);
    d["tracker_stamp"] = sample.tracker_stamp;
    return impl_->object.attr("push_sample")(d);
  });
}

template <typename Call>
const core::RecognizerOutput& PythonRecognizer::take(const char* method, double t, Call call) {
  const std::size_t index = index_++;
  py::dict out;
  try {
    out = call();
  } catch (const py::error_already_set& e) {
    throw std::runtime_error(class_name_ + "." + method + ": " + e.what());
  } catch (const py::cast_error&) {
    throw std::runtime_error(class_name_ + "." + method + ": must return a dict");
  }
  const bool was_stopped = output_.stop;
  output_.new_average = false;
  for (const auto& item : out) {
    const std::string key = py::str(item.first);
    if (outputKeys().count(key) == 0) {
      throw std::invalid_argument(class_name_ + "." + method + ": unknown key '" + key + "'");
    }
    const py::handle v = item.second;
    if (key == "state" || key == "layer_state") {
      const core::DrillingState s = stateFromName(key, py::str(v));
      (key == "state" ? output_.state : output_.layer_state) = s;
    } else if (key == "new_average") {
      output_.new_average = v.cast<bool>();
    } else if (key == "averaged_force") {
      output_.averaged_force = v.cast<double>();
    } else if (key == "feature") {
      output_.feature = v.cast<double>();
    } else if (key == "stop") {
      output_.stop = output_.stop || v.cast<bool>();  // latched until reset
    } else if (key == "last_key_point") {
      output_.last_key_point = v.cast<int>();
    }
  }
  if (output_.stop && !was_stopped) {
    output_.stop_t = t;
    output_.stop_index = index;
    output_.stop_key_point = output_.last_key_point;
  }
  if (output_.stop) output_.state = core::DrillingState::kStopped;
  return output_;
}

std::string PythonRecognizer::stopReason() const {
  if (!output_.stop) return "";
  py::gil_scoped_acquire gil;
  if (py::hasattr(impl_->object, "stop_reason")) {
    return py::str(impl_->object.attr("stop_reason")());
  }
  return class_name_ + " stop at t=" + std::to_string(output_.stop_t) + " s";
}

std::string PythonRecognizer::describe() const {
  py::gil_scoped_acquire gil;
  if (py::hasattr(impl_->object, "describe")) return py::str(impl_->object.attr("describe")());
  return class_name_;
}

std::vector<std::string> PythonRecognizer::parameterNames() const {
  py::gil_scoped_acquire gil;
  if (!py::hasattr(impl_->object, "parameter_names")) return {};
  return impl_->object.attr("parameter_names")().cast<std::vector<std::string>>();
}

}  // namespace pedicle_drilling
