/**
 * @file trial_distribution_params.cpp
 * @brief Loading of the Simulator's `~trial_distribution` parameters.
 */
#include "pedicle_drilling/ros/trial_distribution_params.hpp"

#include <string>

#include "pedicle_drilling/ros/param_loader.hpp"

namespace pedicle_drilling {

TrialDistributionParams loadTrialDistribution(const ros::NodeHandle& private_nh) {
  const ros::NodeHandle root(private_nh, "trial_distribution");
  const ParamLoader top(root);
  const ParamLoader private_params(private_nh);
  private_params.rejectUnknownKeys("trial_distribution",
                                   {"specimen", "patient", "ventilator", "sensor", "arm"});
  TrialDistributionParams out;

  // Specimen: layer thicknesses (mm) and solid fractions (bone_specimen.hpp, sources in
  // doc/simulator_physics.md).
  core::SpecimenDistribution& d = out.specimen;
  const ParamLoader sp(ros::NodeHandle(root, "specimen"));
  top.rejectUnknownKeys(
      "specimen",
      {"outer_cortical_thickness_mean_mm", "outer_cortical_thickness_sd_mm",
       "cancellous_thickness_mean_mm", "cancellous_thickness_sd_mm",
       "inner_cortical_thickness_mean_mm", "inner_cortical_thickness_sd_mm",
       "min_layer_thickness_mm", "outer_cortical_fraction_mean", "inner_cortical_fraction_mean",
       "cortical_fraction_sd", "cortical_field_cv", "cortical_corr_length_mm",
       "cancellous_fraction_mean", "cancellous_fraction_sd", "cancellous_field_cv",
       "cancellous_corr_length_mm", "cancellous_fraction_min", "cancellous_fraction_max"});
  auto mm = [&sp](const std::string& name, double default_m, double lo_mm, double hi_mm,
                  bool open_lo) {
    return 1e-3 * sp.getDouble(name, 1e3 * default_m, lo_mm, hi_mm, open_lo);
  };
  d.outer_cortical_thickness_mean_m =
      mm("outer_cortical_thickness_mean_mm", d.outer_cortical_thickness_mean_m, 0.0, 100.0, true);
  d.outer_cortical_thickness_sd_m =
      mm("outer_cortical_thickness_sd_mm", d.outer_cortical_thickness_sd_m, 0.0, 10.0, false);
  d.cancellous_thickness_mean_m =
      mm("cancellous_thickness_mean_mm", d.cancellous_thickness_mean_m, 0.0, 100.0, true);
  d.cancellous_thickness_sd_m =
      mm("cancellous_thickness_sd_mm", d.cancellous_thickness_sd_m, 0.0, 10.0, false);
  d.inner_cortical_thickness_mean_m =
      mm("inner_cortical_thickness_mean_mm", d.inner_cortical_thickness_mean_m, 0.0, 100.0, true);
  d.inner_cortical_thickness_sd_m =
      mm("inner_cortical_thickness_sd_mm", d.inner_cortical_thickness_sd_m, 0.0, 10.0, false);
  d.min_layer_thickness_m = mm("min_layer_thickness_mm", d.min_layer_thickness_m, 0.0, 10.0, true);
  d.outer_cortical_fraction_mean =
      sp.getDouble("outer_cortical_fraction_mean", d.outer_cortical_fraction_mean, 0.0, 1.0, true);
  d.inner_cortical_fraction_mean =
      sp.getDouble("inner_cortical_fraction_mean", d.inner_cortical_fraction_mean, 0.0, 1.0, true);
  d.cortical_fraction_sd = sp.getDouble("cortical_fraction_sd", d.cortical_fraction_sd, 0.0, 0.3);
  d.cortical_field_cv = sp.getDouble("cortical_field_cv", d.cortical_field_cv, 0.0, 1.0);
  d.cortical_corr_length_m =
      mm("cortical_corr_length_mm", d.cortical_corr_length_m, 0.0, 10.0, true);
  d.cancellous_fraction_mean =
      sp.getDouble("cancellous_fraction_mean", d.cancellous_fraction_mean, 0.0, 1.0, true);
  d.cancellous_fraction_sd =
      sp.getDouble("cancellous_fraction_sd", d.cancellous_fraction_sd, 0.0, 0.3);
  d.cancellous_field_cv = sp.getDouble("cancellous_field_cv", d.cancellous_field_cv, 0.0, 2.0);
  d.cancellous_corr_length_m =
      mm("cancellous_corr_length_mm", d.cancellous_corr_length_m, 0.0, 10.0, true);
  d.cancellous_fraction_min =
      sp.getDouble("cancellous_fraction_min", d.cancellous_fraction_min, 0.0, 1.0, true);
  d.cancellous_fraction_max = sp.getDouble("cancellous_fraction_max", d.cancellous_fraction_max,
                                           d.cancellous_fraction_min, 1.0, true);

  // Patient, ventilator, sensor and arm spreads (drilling_simulation.hpp, TrialVariability).
  core::TrialVariability& v = out.variability;
  top.rejectUnknownKeys("patient", {"amplitude_scale_sd", "movement_scale"});
  top.rejectUnknownKeys("ventilator", {"rate_sd_bpm", "tidal_volume_sd_ml"});
  top.rejectUnknownKeys("sensor", {"noise_scale_sd"});
  top.rejectUnknownKeys("arm", {"stiffness_scale_sd"});
  v.patient_amplitude_scale_sd =
      top.getDouble("patient/amplitude_scale_sd", v.patient_amplitude_scale_sd, 0.0, 0.3);
  v.patient_movement_scale =
      top.getDouble("patient/movement_scale", v.patient_movement_scale, 0.0, 5.0);
  v.ventilator_rate_sd_bpm =
      top.getDouble("ventilator/rate_sd_bpm", v.ventilator_rate_sd_bpm, 0.0, 5.0);
  v.ventilator_tidal_volume_sd_ml =
      top.getDouble("ventilator/tidal_volume_sd_ml", v.ventilator_tidal_volume_sd_ml, 0.0, 200.0);
  v.sensor_noise_scale_sd =
      top.getDouble("sensor/noise_scale_sd", v.sensor_noise_scale_sd, 0.0, 0.5);
  v.arm_stiffness_scale_sd =
      top.getDouble("arm/stiffness_scale_sd", v.arm_stiffness_scale_sd, 0.0, 0.3);

  // The core's own checks (same ranges) as a second line; reported against the namespace.
  try {
    out.specimen.validate();
    out.variability.validate();
  } catch (const std::invalid_argument& e) {
    private_params.fail("trial_distribution", e.what());
  }
  return out;
}

}  // namespace pedicle_drilling
