#include "pedicle_drilling/core/control/compensator_interface.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "pedicle_drilling/core/control/compensation_planner.hpp"
#include "pedicle_drilling/core/drilling/state_recognizer.hpp"

namespace pedicle_drilling::core {

namespace {

const char* const kPaperCompensator = "pedicle_drilling/PaperCompensator";
const char* const kTrackedMarkerCompensator = "pedicle_drilling/TrackedMarkerCompensator";

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

void TrackedMarkerParams::validate() const {
  if (!(std::isfinite(max_horizon_s) && max_horizon_s > 0.0 && max_horizon_s <= 10.0)) {
    throw std::invalid_argument("max_horizon_s: must be in (0, 10] s");
  }
}

void TrackedMarkerCompensator::configure(const CompensatorSettings& settings) {
  TrackedMarkerParams p;
  for (const auto& [name, value] : settings) {
    if (name == "extrapolate") {
      p.extrapolate = parseSettingBool(name, value);
    } else if (name == "max_horizon_s") {
      p.max_horizon_s = parseSettingDouble(name, value);
    } else {
      throw std::invalid_argument(name + ": unknown tracked-marker compensator parameter");
    }
  }
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
  return {"extrapolate", "max_horizon_s"};
}

// ----------------------------------------------------------------------------- factory

std::vector<std::string> builtinCompensatorNames() {
  return {kPaperCompensator, kTrackedMarkerCompensator};
}

std::unique_ptr<CompensatorInterface> makeBuiltinCompensator(const std::string& name,
                                                             const CompensatorSettings& settings) {
  std::unique_ptr<CompensatorInterface> c;
  if (name == kPaperCompensator) {
    c = std::make_unique<PaperCompensator>();
  } else if (name == kTrackedMarkerCompensator) {
    c = std::make_unique<TrackedMarkerCompensator>();
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
