#include "pedicle_drilling/core/control/compensator_interface.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "pedicle_drilling/core/control/adaptive_compensator.hpp"
#include "pedicle_drilling/core/control/compensation_planner.hpp"
#include "pedicle_drilling/core/drilling/state_recognizer.hpp"

namespace pedicle_drilling::core {

namespace {

const char* const kPaperCompensator = "pedicle_drilling/PaperCompensator";
const char* const kTrackedMarkerCompensator = "pedicle_drilling/TrackedMarkerCompensator";
const char* const kAdaptiveModelCompensator = "pedicle_drilling/AdaptiveModelCompensator";

}  // namespace

void CompensatorInterface::observeMarker(double, const Eigen::Vector3d&) {}

std::vector<double> CompensatorInterface::velocitySteps(double, double) const { return {}; }

// ----------------------------------------------------------------------- PaperCompensator

PaperCompensator::PaperCompensator() = default;
PaperCompensator::~PaperCompensator() = default;

void PaperCompensator::configure(const CompensatorSettings& settings) {
  if (!settings.empty()) {
    throw std::invalid_argument(settings.front().first +
                                ": unknown parameter (the paper compensator has none of its "
                                "own; its axes and latency are the planner's)");
  }
}

void PaperCompensator::setPatient(const MotionModel& model, const CompensationParams& params) {
  predictor_ = std::make_unique<DisplacementPredictor>(model, params);
  if (settings_) predictor_->setVentilator(*settings_);
  if (breath_start_) predictor_->setBreathStart(*breath_start_);
}

void PaperCompensator::setVentilator(const VentilatorSettings& settings) {
  if (predictor_) predictor_->setVentilator(settings);
  settings_ = settings;
}

void PaperCompensator::setBreathStart(double t) {
  if (predictor_) predictor_->setBreathStart(t);
  breath_start_ = t;
}

bool PaperCompensator::ready() const { return predictor_ != nullptr && predictor_->ready(); }

Eigen::Vector3d PaperCompensator::displacement(double t) const {
  if (!predictor_) throw std::logic_error("paper compensator: no patient model (setPatient)");
  return predictor_->displacement(t);
}

std::vector<double> PaperCompensator::velocitySteps(double t0, double t1) const {
  return predictor_ ? predictor_->flowSteps(t0, t1) : std::vector<double>();
}

std::string PaperCompensator::describe() const {
  return "paper compensator (Algorithm 1: ventilator tidal volume and flow through the patient "
         "model)";
}

// ------------------------------------------------------------- TrackedMarkerCompensator

const ParamTable<TrackedMarkerParams>& TrackedMarkerParams::table() {
  static const ParamTable<TrackedMarkerParams> t = [] {
    using P = TrackedMarkerParams;
    ParamTable<P> d;
    d.flag("extrapolate", &P::extrapolate)
        .number("max_horizon_s", &P::max_horizon_s, Range::aboveUpTo(0, 10), "s");
    return d;
  }();
  return t;
}

void TrackedMarkerParams::validate() const { table().validate(*this); }

void TrackedMarkerCompensator::configure(const CompensatorSettings& settings) {
  const TrackedMarkerParams p = TrackedMarkerParams::table().withSettings(settings);
  p.validate();
  p_ = p;
}

void TrackedMarkerCompensator::observeMarker(double stamp, const Eigen::Vector3d& position) {
  if (!std::isfinite(stamp) || !position.allFinite()) return;  // a lost sample: keep the last
  if (count_ > 0 && !(stamp > last_t_)) return;                // late or repeated
  if (count_ > 0) velocity_ = (position - last_) / (stamp - last_t_);
  last_t_ = stamp;
  last_ = position;
  ++count_;
}

Eigen::Vector3d TrackedMarkerCompensator::displacement(double t) const {
  if (count_ == 0) throw std::logic_error("tracked-marker compensator: no marker sample yet");
  if (!p_.extrapolate || count_ < 2) return last_;
  const double horizon = std::min(std::max(0.0, t - last_t_), p_.max_horizon_s);
  return last_ + horizon * velocity_;
}

std::string TrackedMarkerCompensator::describe() const {
  char text[160];
  std::snprintf(text, sizeof(text),
                "tracked-marker compensator (reactive baseline): %s, max horizon %.3f s",
                p_.extrapolate ? "constant-velocity extrapolation" : "hold the last sample",
                p_.max_horizon_s);
  return text;
}

std::vector<std::string> TrackedMarkerCompensator::parameterNames() const {
  return TrackedMarkerParams::table().declaredNames();
}

// ----------------------------------------------------------------------------- guard

GuardedCompensator::GuardedCompensator(std::unique_ptr<CompensatorInterface> inner)
    : inner_(std::move(inner)) {
  if (!inner_) throw std::invalid_argument("compensator: none given");
}

void GuardedCompensator::latch(const char* call, const std::exception* e) const {
  if (!error_.empty()) return;  // the first error is the cause
  const std::string what = e != nullptr ? e->what() : "unknown exception";
  error_ = std::string(call) + ": " + (what.empty() ? "an exception without a message" : what);
}

bool GuardedCompensator::guard(const char* call, const std::function<void()>& body) const {
  if (!error_.empty()) return false;
  try {
    body();
    return true;
  } catch (const std::exception& e) {
    latch(call, &e);
  } catch (...) {  // a plugin may throw anything
    latch(call, nullptr);
  }
  return false;
}

void GuardedCompensator::setVentilator(const VentilatorSettings& settings) {
  guard("setVentilator", [&] { inner_->setVentilator(settings); });
}

void GuardedCompensator::setBreathStart(double t) {
  guard("setBreathStart", [&] { inner_->setBreathStart(t); });
}

void GuardedCompensator::observeMarker(double stamp, const Eigen::Vector3d& position_world) {
  guard("observeMarker", [&] { inner_->observeMarker(stamp, position_world); });
}

bool GuardedCompensator::ready() const {
  bool ready = false;
  return guard("ready", [&] { ready = inner_->ready(); }) && ready;
}

Eigen::Vector3d GuardedCompensator::displacement(double t) const {
  Eigen::Vector3d d = last_;
  const bool ok = guard("displacement", [&] {
    d = inner_->displacement(t);
    if (!d.allFinite()) throw std::runtime_error("not finite at t = " + std::to_string(t) + " s");
  });
  if (ok) last_ = d;
  return last_;
}

std::vector<double> GuardedCompensator::velocitySteps(double t0, double t1) const {
  std::vector<double> steps;
  return guard("velocitySteps", [&] { steps = inner_->velocitySteps(t0, t1); })
             ? steps
             : std::vector<double>();
}

std::string GuardedCompensator::describe() const {
  std::string text;
  try {
    text = inner_->describe();
  } catch (...) {
    text = "a compensator whose describe() failed";
  }
  return error_.empty() ? text : text + "; failed: " + error_;
}

// ----------------------------------------------------------------------------- factory

std::vector<std::string> builtinCompensatorNames() {
  return {kPaperCompensator, kTrackedMarkerCompensator, kAdaptiveModelCompensator};
}

std::unique_ptr<CompensatorInterface> makeBuiltinCompensator(const std::string& name,
                                                             const CompensatorSettings& settings) {
  std::unique_ptr<CompensatorInterface> c;
  if (name == kPaperCompensator) {
    c = std::make_unique<PaperCompensator>();
  } else if (name == kTrackedMarkerCompensator) {
    c = std::make_unique<TrackedMarkerCompensator>();
  } else if (name == kAdaptiveModelCompensator) {
    c = std::make_unique<AdaptiveModelCompensator>();
  } else {
    std::string known;
    for (const std::string& n : builtinCompensatorNames()) known += (known.empty() ? "" : ", ") + n;
    throw std::invalid_argument("compensator '" + name + "' is not built in (known: " + known +
                                "; a plugin of another package is loaded through pluginlib)");
  }
  c->configure(settings);
  return c;
}

}  // namespace pedicle_drilling::core
