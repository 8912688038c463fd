/**
 * @file patient_population.hpp
 * @brief A population of virtual patients, one drawn per trial seed, each in two states: the
 *        identification state (the awake patient breathing on their own while the tracker records
 *        the 30 s the model is identified from, paper Sec. III-A) and the surgery state (the
 *        anaesthetised patient on the ventilator whose vertebra we drill). The planner's model is
 *        identified from the first (the paper's DWT de-noising and Ceres fit, motion_pipeline.hpp);
 *        the bone moves as the second. Every distribution, its source or the reasoning of an
 *        assumption: doc/simulator_physics.md, "Patient population".
 *
 * A patient is a function of the whole 64-bit trial seed. The two seed spaces differ in bit 62
 * (pd_campaign.design.trial_seed), so no patient of an evaluation seed is ever drawn from a
 * calibration seed.
 *
 * No ROS headers.
 */
#ifndef PEDICLE_DRILLING_CORE_PATIENT_POPULATION_HPP_
#define PEDICLE_DRILLING_CORE_PATIENT_POPULATION_HPP_

#include <cstdint>

#include "pedicle_drilling/core/breathing/motion_pipeline.hpp"
#include "pedicle_drilling/core/breathing/virtual_volunteer.hpp"
#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling::core {

/**
 * @brief The population's distributions (Simulator parameters under `population/`). Log-normal
 *        quantities are given by their median and the SD of their logarithm; normal ones by mean
 *        and SD, truncated where stated.
 */
struct PopulationParams {
  /// false: the five virtual volunteers (the realistic bench); true: a patient per seed.
  bool enabled = false;
  /// AP peak-to-peak displacement for 500 ml (the slope x 500 ml) [mm], median, [0.1, 20].
  double ap_amplitude_median_mm = 2.5;
  double ap_amplitude_sigma_ln = 0.5;  ///< its log SD, [0, 1.5]
  double si_over_ap = 0.4;             ///< SI amplitude / AP amplitude, [0, 2]
  double lr_over_ap = 0.2;             ///< LR amplitude / AP amplitude, [0, 2]
  double lag_mean_s = 0.12;            ///< displacement behind the volume [s], [0, 0.4]
  double lag_sd_s = 0.08;              ///< its SD (truncated to [0, 0.4] s) [s], [0, 0.2]
  double drift_median_mm = 0.05;       ///< slow AP drift amplitude [mm], median, [0, 2]
  double drift_sigma_ln = 0.5;         ///< its log SD, [0, 1.5]
  double movements_per_min_max = 1.0;  ///< small movements: rate uniform in [0, this], [0, 10]
  /// Spontaneous breathing while identified [breaths/min], mean, SD (truncated [8, 25]).
  double spontaneous_rate_mean_bpm = 16.6;
  double spontaneous_rate_sd_bpm = 2.8;
  /// Breath-to-breath CV of the spontaneous breath's duration: mean, SD (truncated [0.05, 0.4]).
  double spontaneous_rate_cv_mean = 0.16;
  double spontaneous_rate_cv_sd = 0.08;
  /// Breath-to-breath CV of the spontaneous tidal volume: mean, SD (truncated [0.05, 0.5]).
  double spontaneous_volume_cv_mean = 0.22;
  double spontaneous_volume_cv_sd = 0.10;
  /// Spontaneous tidal volume while identified [ml], mean, SD (truncated [300, 800]).
  double spontaneous_tidal_volume_mean_ml = 500.0;
  double spontaneous_tidal_volume_sd_ml = 100.0;
  /// Identification -> surgery: the bone's slope changes by a log-normal factor of this log SD.
  double gain_change_sigma_ln = 0.38;
  double lag_change_sd_s = 0.05;  ///< and its lag by a normal change of this SD [s], [0, 0.2]
  /// Breath-to-breath CV of the volume the ventilator delivers around its setting, [0, 0.2].
  double delivered_volume_cv = 0.01;
  /// The ventilator's systematic error, delivered / set volume: a normal factor of this SD
  /// around 1 (truncated at 3 SD) per patient, [0, 0.1].
  double delivered_volume_bias_sd = 0.05;
  double cardiac_amplitude_max_mm = 0.1;  ///< cardiac AP amplitude uniform in [0, this] [mm]
  double heart_rate_mean_bpm = 68.0;      ///< heart rate [beats/min] (truncated [50, 100])
  double heart_rate_sd_bpm = 10.0;        ///< its SD [beats/min]
  /// The bone's AP stroke on the table (slope x the trial's delivered volume) is at most this
  /// [mm] (the slope is scaled down to it), [1, 20]: what the bench's approach clears.
  double max_stroke_mm = 7.0;

  /** @brief @throws std::invalid_argument naming the field (as `population/<name>`). */
  void validate() const;
  /** @brief The declaration of every field (ROS names under ~population/). */
  static const ParamTable<PopulationParams>& table();
};

/** @brief The bone in the surgery state: what changes from the identification state. */
struct SurgeryChange {
  double gain = 1.0;                   ///< factor on the slope q1_AP
  double lag_change_s = 0.0;           ///< added to the lag (the result at least 0)
  double delivered_volume_cv = 0.0;    ///< breath-to-breath CV of the delivered volume
  double delivered_volume_bias = 1.0;  ///< delivered / set volume, every breath
  double cardiac_mm = 0.0;             ///< cardiac AP amplitude [mm]
  double heart_rate_bpm = 68.0;        ///< heart rate [beats/min]
  double cardiac_phase_rad = 0.0;      ///< cardiac phase at t = 0 [rad]
};

/** @brief One patient of the population. */
struct PopulationPatient {
  /// The identification state: the awake patient's recording parameters (truth inside).
  VolunteerParams identification;
  SurgeryChange surgery;  ///< what differs on the table
  double drift_mm = 0.1;  ///< slow AP drift amplitude in surgery [mm]
  /** @brief AP slope while identified [mm/ml]. */
  double identificationSlope() const;
  /** @brief Lag while identified [s]. */
  double identificationLag() const;
};

/** @brief The patient of trial `seed` (its own stream of the whole seed). */
PopulationPatient drawPopulationPatient(std::uint64_t seed, const PopulationParams& params);

/**
 * @brief The planner's model of a patient: the 30 s identification recording generated from
 *        the identification state (generateVolunteer) through the paper's pipeline
 *        (identifyPatient: DWT de-noising with automatic wavelet selection, Ceres), as the
 *        campaign's Table II identification runs it (linear model, de-noised volume).
 */
PipelineResult identifyPopulationPatient(const PopulationPatient& patient);

/**
 * @brief Breath-to-breath factor on the delivered volume of breath `breath_index` of trial
 *        `seed`: 1 + cv z, z standard normal truncated at +-3, from a stream of (seed, index).
 */
double deliveredVolumeFactor(std::uint64_t seed, long breath_index, double cv);

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_PATIENT_POPULATION_HPP_
