#include "pedicle_drilling/ros/identification_conversions.hpp"

#include <cctype>
#include <sstream>
#include <vector>

#include "pedicle_drilling/core/common/text_parse.hpp"

namespace pedicle_drilling {

namespace {

std::string upper(const std::string& s) {
  std::string u = s;
  for (char& c : u) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return u;
}

}  // namespace

MotionIdentificationParams loadMotionIdentificationParams(const ParamLoader& params) {
  MotionIdentificationParams p;
  p.tracker_frame = params.getString("tracker_frame", p.tracker_frame);
  // Optional frame whose axes are the patient's (e.g. `world` on the simulator, a registered
  // patient frame on hardware): marker positions are expressed in it before the axis mapping,
  // so an oblique camera does not mix AP, SI and LR.
  p.patient_frame = params.getString("patient_frame", "", true);
  p.marker_frame = params.getString("marker_frame", p.marker_frame);
  p.marker_rate_hz = params.getDouble("marker_rate_hz", p.marker_rate_hz, 0.0, 1000.0, true);
  p.tf_delay_s = params.getDouble("tf_delay_s", p.tf_delay_s, 0.0, 10.0);
  p.use_pose_topic = params.getBool("use_pose_topic", p.use_pose_topic);
  p.window_s = params.getDouble("window_s", p.window_s, 0.0, 3600.0, true);
  const std::string ap = params.getString("ap_axis", "+z");
  const std::string si = params.getString("si_axis", "+y");
  const std::string lr = params.getString("lr_axis", "+x");
  p.axis_specs = ap + "," + si + "," + lr;
  try {
    p.mapping = core::parseAxisMapping(ap, si, lr);
  } catch (const std::invalid_argument& e) {
    // The message starts with the axis name ("ap", "si" or "lr"): name that parameter.
    params.fail(std::string(e.what()).substr(0, 2) + "_axis", std::string("invalid: ") + e.what());
  }
  core::PipelineOptions& o = p.defaults;
  const std::string model = params.getString("model", "linear");
  if (!core::parseModelKind(model, &o.kind)) {
    params.fail("model", "= '" + model + "' is not linear or hysteresis");
  }
  const std::string method = params.getString("method", "ceres");
  if (!core::parseMethod(method, &o.method)) {
    params.fail("method", "= '" + method + "' is not ceres or pso");
  }
  o.denoise = params.getBool("denoise", true);
  o.denoise_tv = params.getBool("denoise_tv", false);
  if (o.denoise_tv && !o.denoise) params.fail("denoise_tv", "needs ~denoise true");
  core::DenoiseOptions& d = o.denoise_options;
  d.level = params.getInt("level", 6, 1, 16);
  d.kept_levels = params.getIntList("kept_levels", {3, 4, 5}, 1, d.level);
  const std::string wavelets = params.getString("wavelets", "all");
  if (wavelets != "all") {
    std::stringstream names(wavelets);
    std::string w;
    d.candidates.clear();
    while (std::getline(names, w, ',')) {
      if (core::findWavelet(w) == nullptr) {
        params.fail("wavelets", "names an unknown wavelet '" + w + "'");
      }
      d.candidates.push_back(w);
    }
  }
  d.delta_tv = params.getDouble("delta_tv_ml", 5.0, 0.0, 1000.0);
  o.pso.seed = static_cast<std::uint64_t>(params.getInt("pso_seed", 1, 0, 2147483647));
  o.validate();
  p.output_path = params.getString("output_path", p.output_path);
  p.patient_id = params.getString("patient_id", p.patient_id);
  return p;
}

MotionModel toMsg(const core::PipelineResult& result, const std::string& frame,
                  const std::string& patient_id, const std::string& method,
                  const std::string& yaml_path) {
  MotionModel msg;
  msg.header.frame_id = frame;
  msg.patient_id = patient_id;
  msg.method = method;
  msg.yaml_path = yaml_path;
  for (const core::AxisReport& r : result.axes) {
    MotionModelAxis axis;
    axis.axis = upper(core::axisName(r.axis));
    axis.model = core::modelKindName(r.fit.model.kind);
    axis.q1_mm_per_ml = r.fit.model.q1;
    axis.q2_mm_s_per_ml = r.fit.model.q2;
    axis.q0_mm = r.fit.model.q0;
    axis.wavelet = r.wavelet == "none" ? "" : r.wavelet;
    axis.r2 = r.fit.r2;
    axis.rmse_mm = r.fit.rmse;
    axis.equivalent_stiffness = core::equivalentStiffness(r.axis, r.fit.model.q1);
    msg.axes.push_back(axis);
  }
  return msg;
}

}  // namespace pedicle_drilling
