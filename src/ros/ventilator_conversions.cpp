#include "pedicle_drilling/ros/ventilator_conversions.hpp"

#include <stdexcept>

namespace pedicle_drilling {
namespace {

core::ExpiratorySpec parseSpec(const std::string& text, const std::string& field) {
  if (text == "peak_ratio") return core::ExpiratorySpec::kPeakRatio;
  if (text == "time_constant") return core::ExpiratorySpec::kTimeConstant;
  throw std::invalid_argument("'" + field + "' = '" + text +
                              "' is not one of: peak_ratio, time_constant");
}

core::InspiratoryWaveform parseWaveformOrThrow(const std::string& text, const std::string& field) {
  core::InspiratoryWaveform waveform;
  if (core::parseWaveform(text, &waveform)) return waveform;
  std::string names;
  for (const auto& name : core::waveformNames()) names += (names.empty() ? "" : ", ") + name;
  throw std::invalid_argument("'" + field + "' = '" + text + "' is not one of: " + names);
}

}  // namespace

VentilatorSettings toMsg(const core::VentilatorSettings& s) {
  VentilatorSettings msg;
  msg.tv_max_ml = s.tv_max_ml;
  msg.rate_bpm = s.rate_bpm;
  msg.ie_inspiratory = s.ie_inspiratory;
  msg.ie_expiratory = s.ie_expiratory;
  msg.waveform = core::waveformName(s.waveform);
  msg.pause_fraction = s.pause_fraction;
  msg.expiratory_spec =
      s.expiratory_spec == core::ExpiratorySpec::kPeakRatio ? "peak_ratio" : "time_constant";
  msg.peak_flow_ratio = s.peak_flow_ratio;
  msg.expiratory_tau_s = s.expiratory_tau_s;
  msg.ramp_start_fraction = s.ramp_start_fraction;
  msg.exponential_shape = s.exponential_shape;
  return msg;
}

core::VentilatorSettings fromMsg(const VentilatorSettings& msg) {
  core::VentilatorSettings s;
  s.tv_max_ml = msg.tv_max_ml;
  s.rate_bpm = msg.rate_bpm;
  s.ie_inspiratory = msg.ie_inspiratory;
  s.ie_expiratory = msg.ie_expiratory;
  s.waveform = parseWaveformOrThrow(msg.waveform, "waveform");
  s.pause_fraction = msg.pause_fraction;
  s.expiratory_spec = parseSpec(msg.expiratory_spec.empty() ? "peak_ratio" : msg.expiratory_spec,
                                "expiratory_spec");
  s.peak_flow_ratio = msg.peak_flow_ratio;
  s.expiratory_tau_s = msg.expiratory_tau_s;
  s.ramp_start_fraction = msg.ramp_start_fraction;
  // 0 is what a request that does not name the field carries: the documented default.
  if (msg.exponential_shape != 0.0) s.exponential_shape = msg.exponential_shape;
  s.validate();
  return s;
}

void serveSetVentilatorSettings(
    const SetVentilatorSettings::Request& request, SetVentilatorSettings::Response& response,
    const std::function<void(const core::VentilatorSettings&)>& request_settings) {
  try {
    request_settings(fromMsg(request.settings));
    response.success = true;
    response.message = "settings accepted; they take effect at the next breath";
  } catch (const std::exception& e) {
    response.success = false;
    response.message = std::string("settings rejected, previous settings kept: ") + e.what();
  }
}

}  // namespace pedicle_drilling
