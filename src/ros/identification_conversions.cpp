#include "pedicle_drilling/ros/identification_conversions.hpp"

#include <cctype>
#include <sstream>
#include <vector>

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
  params.load(MotionIdentificationParams::table(), &p);
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
