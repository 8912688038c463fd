/**
 * @file drilling_scene.cpp
 * @brief Layout of the drilling scene drawn by the rviz plugin (see drilling_scene.hpp).
 */
#include "pedicle_drilling/core/drilling/drilling_scene.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {
namespace {

constexpr double kTolerance = 1e-6;  // 1 um: rounding in the simulator's own arithmetic

void requireFinite(const char* name, double value) {
  if (!std::isfinite(value)) {
    throw std::invalid_argument(std::string(name) + " is not finite");
  }
}

void requireOrdered(const char* upper_name, double upper, const char* lower_name, double lower) {
  if (lower + kTolerance < upper) {
    std::ostringstream out;
    out << lower_name << " (" << lower << " m) is above " << upper_name << " (" << upper << " m)";
    throw std::invalid_argument(out.str());
  }
}

}  // namespace

DrillingScene layoutDrillingScene(const SpecimenDepths& depths, double max_depth_m) {
  requireFinite("outer_cortical_end_m", depths.outer_cortical_end_m);
  requireFinite("inner_cortical_start_m", depths.inner_cortical_start_m);
  requireFinite("inner_cortical_end_m", depths.inner_cortical_end_m);
  requireFinite("max_depth_cut_m", depths.max_depth_cut_m);
  requireFinite("residual_inner_cortical_m", depths.residual_inner_cortical_m);
  if (!(max_depth_m > 0.0) || !std::isfinite(max_depth_m)) {
    throw std::invalid_argument("max_depth_m must be positive and finite");
  }
  requireOrdered("the bone top surface", 0.0, "outer_cortical_end_m", depths.outer_cortical_end_m);
  requireOrdered("outer_cortical_end_m", depths.outer_cortical_end_m, "inner_cortical_start_m",
                 depths.inner_cortical_start_m);
  requireOrdered("inner_cortical_start_m", depths.inner_cortical_start_m, "inner_cortical_end_m",
                 depths.inner_cortical_end_m);
  if (depths.inner_cortical_end_m > max_depth_m) {
    std::ostringstream out;
    out << "inner_cortical_end_m (" << depths.inner_cortical_end_m << " m) is deeper than "
        << max_depth_m << " m";
    throw std::invalid_argument(out.str());
  }
  if (depths.max_depth_cut_m < 0.0 || depths.max_depth_cut_m > max_depth_m) {
    std::ostringstream out;
    out << "max_depth_cut_m (" << depths.max_depth_cut_m << " m) is outside [0, " << max_depth_m
        << "] m";
    throw std::invalid_argument(out.str());
  }
  const double inner_thickness = depths.inner_cortical_end_m - depths.inner_cortical_start_m;
  // GroundTruth.msg: the distance from the deepest cut to the far side of the inner layer.
  const double expected = std::max(0.0, depths.inner_cortical_end_m - depths.max_depth_cut_m);
  if (std::abs(depths.residual_inner_cortical_m - expected) > kTolerance) {
    std::ostringstream out;
    out << "residual_inner_cortical_m (" << depths.residual_inner_cortical_m
        << " m) is not max(0, inner_cortical_end_m - max_depth_cut_m) = " << expected << " m";
    throw std::invalid_argument(out.str());
  }

  DrillingScene scene;
  scene.outer_cortical = {0.0, -depths.outer_cortical_end_m};
  scene.cancellous = {-depths.outer_cortical_end_m, -depths.inner_cortical_start_m};
  scene.inner_cortical = {-depths.inner_cortical_start_m, -depths.inner_cortical_end_m};
  scene.has_hole = depths.max_depth_cut_m > 0.0;
  scene.hole = {0.0, -depths.max_depth_cut_m};
  const double residual = std::min(depths.residual_inner_cortical_m, inner_thickness);
  scene.has_residual = residual > 0.0;
  scene.residual = {-depths.inner_cortical_end_m + residual, -depths.inner_cortical_end_m};
  return scene;
}

}  // namespace pedicle_drilling::core
