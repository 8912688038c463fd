/**
 * @file breath_detector.cpp
 * @brief Breath starts on a flow signal and the schedule they re-phase (breath_detector.hpp).
 */
#include "pedicle_drilling/core/breathing/breath_detector.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {

const ParamTable<BreathDetectorParams>& BreathDetectorParams::table() {
  static const ParamTable<BreathDetectorParams> t = [] {
    using P = BreathDetectorParams;
    ParamTable<P> d;
    d.number("breath_trigger_flow_ml_s", &P::trigger_flow_ml_s, Range::closed(0, 2000), "ml/s")
        .number("breath_rearm_flow_ml_s", &P::rearm_flow_ml_s, Range::closed(-2000, 2000), "ml/s")
        .number("breath_min_interval_s", &P::min_interval_s, Range::closed(0, 10), "s");
    return d;
  }();
  return t;
}

void BreathDetectorParams::validate() const {
  table().validate(*this);
  if (rearm_flow_ml_s > trigger_flow_ml_s) {
    std::ostringstream os;
    os << "breath_rearm_flow_ml_s = " << rearm_flow_ml_s
       << " ml/s must not exceed breath_trigger_flow_ml_s = " << trigger_flow_ml_s << " ml/s";
    throw std::invalid_argument(os.str());
  }
}

std::string describe(FlowSampleStatus s) {
  switch (s) {
    case FlowSampleStatus::kNonFiniteFlow:
      return "the flow is not finite";
    case FlowSampleStatus::kNonFiniteStamp:
      return "the stamp is not finite";
    case FlowSampleStatus::kStampNotIncreasing:
      return "the stamp is not after the previous sample's";
    default:
      return "";
  }
}

BreathStartDetector::BreathStartDetector(const BreathDetectorParams& params) : params_(params) {
  params_.validate();
  reset();
}

void BreathStartDetector::reset() {
  armed_ = params_.armed_at_start;
  breaths_ = 0;
  last_start_ = std::numeric_limits<double>::quiet_NaN();
  last_t_ = std::numeric_limits<double>::quiet_NaN();
  dropped_ = 0;
}

FlowSampleStatus BreathStartDetector::add(double t, double flow_ml_s) {
  FlowSampleStatus bad = FlowSampleStatus::kAccepted;
  if (!std::isfinite(t)) {
    bad = FlowSampleStatus::kNonFiniteStamp;
  } else if (!std::isfinite(flow_ml_s)) {
    bad = FlowSampleStatus::kNonFiniteFlow;
  } else if (!std::isnan(last_t_) && !(t > last_t_)) {
    bad = FlowSampleStatus::kStampNotIncreasing;
  }
  if (bad != FlowSampleStatus::kAccepted) {
    ++dropped_;
    return bad;
  }
  last_t_ = t;
  const bool waited = std::isnan(last_start_) || t - last_start_ >= params_.min_interval_s;
  if (armed_ && waited && flow_ml_s > params_.trigger_flow_ml_s) {
    armed_ = false;
    ++breaths_;
    last_start_ = t;
    return FlowSampleStatus::kBreathStart;
  }
  if (flow_ml_s <= params_.rearm_flow_ml_s) armed_ = true;
  return FlowSampleStatus::kAccepted;
}

// ---------------------------------------------------------------------------------------------

const ParamTable<FlowPhaseParams>& FlowPhaseParams::table() {
  static const ParamTable<FlowPhaseParams> t = [] {
    using P = FlowPhaseParams;
    ParamTable<P> d;
    d.include(BreathDetectorParams::table(), &P::detector)
        .number("breath_timeout_periods", &P::timeout_periods, Range::aboveUpTo(1, 10),
                "breath periods");
    return d;
  }();
  return t;
}

void FlowPhaseParams::validate() const {
  table().validate(*this);
  detector.validate();
}

FlowPhasedSchedule::FlowPhasedSchedule(const VentilatorSettings& settings,
                                       const FlowPhaseParams& params)
    : params_(params), detector_(params.detector), settings_(settings), scheduler_(settings) {
  params_.validate();
}

void FlowPhasedSchedule::requestSettings(const VentilatorSettings& settings) {
  scheduler_.requestSettings(settings);  // validates
  settings_ = settings;
}

void FlowPhasedSchedule::reset() {
  detector_.reset();
  have_breath_ = false;
  detected_index_ = -1;
}

FlowSampleStatus FlowPhasedSchedule::addFlow(double t, double flow_ml_s) {
  const FlowSampleStatus status = detector_.add(t, flow_ml_s);
  if (status != FlowSampleStatus::kBreathStart) return status;
  if (!have_breath_) {
    // The first breath: the schedule starts with it, with the latest settings.
    scheduler_ = BreathScheduler(settings_, t);
    have_breath_ = true;
  } else if (scheduler_.breathIndex() > detected_index_) {
    scheduler_.rephase(t);  // the schedule began this breath on its own: move it here
  } else {
    scheduler_.restart(t);
  }
  detected_index_ = scheduler_.breathIndex();
  return status;
}

double FlowPhasedSchedule::timeout() const {
  return params_.timeout_periods * scheduler_.model().period();
}

std::string FlowPhasedSchedule::problem(double now) const {
  if (!have_breath_) {
    return std::isnan(detector_.lastSampleTime())
               ? "no flow sample yet"
               : "no breath start detected yet (the flow has not risen above the trigger after "
                 "a pause or an expiration)";
  }
  const double age = now - detector_.lastBreathStart();
  if (age <= timeout()) return "";
  std::ostringstream os;
  os.precision(3);
  os << "no breath start for " << age << " s (more than breath_timeout_periods "
     << params_.timeout_periods << " x the " << scheduler_.model().period()
     << " s breath period = " << timeout() << " s)";
  return os.str();
}

}  // namespace pedicle_drilling::core
