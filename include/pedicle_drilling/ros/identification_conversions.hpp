/**
 * @file identification_conversions.hpp
 * @brief The MotionIdentification nodelet's parameters, loaded once into one validated struct,
 *        and the identified model as pedicle_drilling/MotionModel.
 */
#pragma once

#include <string>

#include "pedicle_drilling/MotionModel.h"
#include "pedicle_drilling/core/breathing/motion_pipeline.hpp"
#include "pedicle_drilling/ros/param_loader.hpp"

namespace pedicle_drilling {

/** @brief Every parameter of MotionIdentification (README), checked. */
struct MotionIdentificationParams {
  std::string tracker_frame = "tracker_camera";    ///< ~tracker_frame
  std::string patient_frame;                       ///< ~patient_frame ("" = the tracker's axes)
  std::string marker_frame = "tracker_marker";     ///< ~marker_frame
  double marker_rate_hz = 8.0;                     ///< ~marker_rate_hz (tf sampling)
  double tf_delay_s = 0.25;                        ///< ~tf_delay_s
  bool use_pose_topic = false;                     ///< ~use_pose_topic
  double window_s = 30.0;                          ///< ~window_s
  core::AxisMapping mapping;                       ///< ~ap_axis, ~si_axis, ~lr_axis
  std::string axis_specs = "+z,+y,+x";             ///< the three axis parameters, for the YAML
  core::PipelineOptions defaults;                  ///< ~model, ~method, ~denoise, ... (per request)
  std::string output_path = "patient_model.yaml";  ///< ~output_path
  std::string patient_id = "patient";              ///< ~patient_id
};

/** @brief Loads and checks them. @throws ParameterError naming the parameter. */
MotionIdentificationParams loadMotionIdentificationParams(const ParamLoader& params);

/** @brief The identified model (frame, patient, method, YAML path) as the message. */
MotionModel toMsg(const core::PipelineResult& result, const std::string& frame,
                  const std::string& patient_id, const std::string& method,
                  const std::string& yaml_path);

}  // namespace pedicle_drilling
