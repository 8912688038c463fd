/**
 * @file drilling_scene.hpp
 * @brief Geometry of the drilling scene drawn by the rviz plugin: the three bone layers, the
 *        drilled hole and the residual inner cortical layer as slabs along the drill axis, from
 *        the simulator's ground truth. Validates the input so that a broken message gives a
 *        clear error instead of a nonsense picture.
 *
 * Frame: the `bone` frame of urdf/workcell.urdf, origin at the centre of the bone's top surface,
 * +z out of the bone; depths d >= 0 below the top surface map to z = -d. No ROS header here.
 */
#pragma once

#include <string>

namespace pedicle_drilling::core {

/** @brief Depths (m, below the bone top surface) from one GroundTruth message. */
struct SpecimenDepths {
  double outer_cortical_end_m = 0.0;    ///< bottom of the outer cortical layer
  double inner_cortical_start_m = 0.0;  ///< top of the inner cortical layer
  double inner_cortical_end_m = 0.0;    ///< bottom of the inner cortical layer (canal below)
  double max_depth_cut_m = 0.0;         ///< deepest point cut so far (0 = untouched)
  /// max(0, inner_cortical_end - max_depth_cut) (GroundTruth.msg): the inner cortical thickness
  /// left once the cut is in the inner layer, more than the layer before.
  double residual_inner_cortical_m = 0.0;
};

/** @brief A slab between two heights of the bone frame (top_z_m >= bottom_z_m). */
struct Slab {
  double top_z_m = 0.0;     ///< upper face, bone frame z (m)
  double bottom_z_m = 0.0;  ///< lower face, bone frame z (m)
  /** @brief Thickness (m), top minus bottom. */
  double thickness() const { return top_z_m - bottom_z_m; }
  /** @brief Height of the middle plane (m). */
  double centre() const { return 0.5 * (top_z_m + bottom_z_m); }
};

/** @brief Everything the display draws along the drill axis. */
struct DrillingScene {
  Slab outer_cortical;        ///< [0, outer_cortical_end]
  Slab cancellous;            ///< [outer_cortical_end, inner_cortical_start]
  Slab inner_cortical;        ///< [inner_cortical_start, inner_cortical_end]
  Slab hole;                  ///< [0, max_depth_cut]; empty when nothing was cut
  Slab residual;              ///< inner cortical left below the hole; empty when none is left
  bool has_hole = false;      ///< max_depth_cut > 0
  bool has_residual = false;  ///< residual thickness > 0
};

/**
 * @brief Lays out the scene from the ground-truth depths.
 *
 * The residual slab is the part of the inner cortical layer left below the cut: its bottom
 * min(residual, inner cortical thickness). Requirements (else std::invalid_argument naming the
 * field): every value finite; 0 <= outer_cortical_end <= inner_cortical_start <=
 * inner_cortical_end <= max_depth_m; 0 <= max_depth_cut <= max_depth_m; residual =
 * max(0, inner_cortical_end - max_depth_cut) (GroundTruth.msg's definition; +1 um tolerance for
 * rounding).
 * @param depths values of one GroundTruth message
 * @param max_depth_m largest plausible depth (m), guards against unit mistakes (mm sent as m)
 */
DrillingScene layoutDrillingScene(const SpecimenDepths& depths, double max_depth_m = 0.1);

}  // namespace pedicle_drilling::core
