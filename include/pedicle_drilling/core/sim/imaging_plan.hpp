// The simulated bench's planning step: a drilling plan made from the specimen as a surgeon makes
// it on a preoperative CT, with the errors of clinical CT and of image-to-patient registration
// (doc/bench_sources.md), so that the plan is right only as far as a real one is. No ROS.
#ifndef PEDICLE_DRILLING_CORE_IMAGING_PLAN_HPP_
#define PEDICLE_DRILLING_CORE_IMAGING_PLAN_HPP_

#include <Eigen/Geometry>

#include <cstdint>

#include "pedicle_drilling/core/common/param_table.hpp"
#include "pedicle_drilling/core/control/depth_limit.hpp"
#include "pedicle_drilling/core/drilling/bone_specimen.hpp"

namespace pedicle_drilling::core {

/** @brief The imaging and registration errors of the simulated plan, and its safety margin. */
struct PlanImagingParams {
  /**
   * @brief SD of a layer boundary's position on clinical CT, along the trajectory [mm], [0, 2]:
   *        0.17 mm, the overall error of cortical-width measurement on clinical CT (Prevrhal et
   *        al. 2003, Med Phys 30(1):1-8). Drawn for the surface and for the inner cortex's far
   *        side.
   */
  double boundary_sd_mm = 0.17;
  /**
   * @brief 3-D RMS error of the image-to-patient registration [mm], [0, 5]: 0.96 mm, surface
   *        registration with 20 points on the lamina of a lumbar vertebra phantom in CT-based
   *        spinal navigation (https://pmc.ncbi.nlm.nih.gov/articles/PMC3476741). Moves the planned
   * entry in the marker's frame; the drill's own contact finds the surface along the axis
   * (DepthLimit), so it sets the entry's tolerance.
   */
  double registration_rms_mm = 0.96;
  /**
   * @brief The planned depth stops this far before the measured far side of the inner cortex
   *        [mm], [0, 5]. 1.3 mm: the 99.9 % quantile of the plan's far-side error plus the depth
   *        limit's estimate error (its maxima over 0.25 s windows of the drilling), on
   *        calibration seeds (scripts/dev/run_calibration.sh depth; doc/campaign_results.md,
   *        "Constants chosen on simulated outcomes"), never from outcomes.
   */
  double margin_mm = 1.3;
  /** @brief The entry's tolerance in SDs of its error along the axis (registration and CT
   *         surface), [1, 10]: 3. */
  double tolerance_sigmas = 3.0;

  /** @brief @throws std::invalid_argument naming the field when out of range. */
  void validate() const;
  /** @brief The declaration of the fields (Simulator `plan/...`). */
  static const ParamTable<PlanImagingParams>& table();
};

/** @brief A plan and what its making drew (for the report and the margin's choice). */
struct ImagingPlan {
  DrillingPlan plan;  ///< in the marker's frame
  /// The measured far side of the inner cortex from the measured surface, minus the true one
  /// [m]: the plan's depth error before the margin (the far side's and the surface's errors).
  double far_side_error_m = 0.0;
  /// The planned entry's offset from the true surface along the bone's normal [m] (the
  /// registration's and the CT surface's errors), positive into the bone.
  double entry_error_m = 0.0;
};

/**
 * @brief The plan of one specimen: the entry at the bone frame's origin (the top surface's
 *        centre), the direction into the bone (the bone frame's -z), the depth to the measured
 *        far side less the margin, all moved by the registration error into the marker's frame.
 *        Deterministic for a seed (its own stream: nothing else the seed draws changes).
 * @param marker_from_bone the bone frame in the marker's (fixed: both on the platform)
 * @throws std::invalid_argument when the plan's depth is not positive (a margin too large)
 */
ImagingPlan makeImagingPlan(const BoneSpecimen& specimen, const Eigen::Isometry3d& marker_from_bone,
                            const PlanImagingParams& params, std::uint64_t seed);

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_IMAGING_PLAN_HPP_
