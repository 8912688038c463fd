// The simulated bench's planning step (see imaging_plan.hpp).
#include "pedicle_drilling/core/sim/imaging_plan.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "pedicle_drilling/core/sim/normal_source.hpp"

namespace pedicle_drilling::core {

const ParamTable<PlanImagingParams>& PlanImagingParams::table() {
  static const ParamTable<PlanImagingParams> t = [] {
    using P = PlanImagingParams;
    ParamTable<P> d;
    d.number("boundary_sd_mm", &P::boundary_sd_mm, Range::closed(0, 2), "mm")
        .number("registration_rms_mm", &P::registration_rms_mm, Range::closed(0, 5), "mm")
        .number("margin_mm", &P::margin_mm, Range::closed(0, 5), "mm")
        .number("tolerance_sigmas", &P::tolerance_sigmas, Range::closed(1, 10));
    return d;
  }();
  return t;
}

void PlanImagingParams::validate() const { table().validate(*this); }

ImagingPlan makeImagingPlan(const BoneSpecimen& specimen, const Eigen::Isometry3d& marker_from_bone,
                            const PlanImagingParams& params, std::uint64_t seed) {
  params.validate();
  // Its own stream of the seed. Every deviate is drawn whatever its SD.
  NormalSource n(seed * 0xD1B54A32D192ED03ULL + 0x8CB92BA72F3D8DD7ULL);
  const double surface_error = 1e-3 * params.boundary_sd_mm * n.normal();  // + : deeper
  const double far_error = 1e-3 * params.boundary_sd_mm * n.normal();
  const double per_axis = 1e-3 * params.registration_rms_mm / std::sqrt(3.0);
  const Eigen::Vector3d registration(per_axis * n.normal(), per_axis * n.normal(),
                                     per_axis * n.normal());
  ImagingPlan out;
  out.far_side_error_m = far_error - surface_error;
  const double depth = specimen.innerCorticalEnd() + out.far_side_error_m - 1e-3 * params.margin_mm;
  if (!(depth > 0.0)) {
    throw std::invalid_argument("plan/margin_mm: " + std::to_string(params.margin_mm) +
                                " mm leaves no depth to drill");
  }
  // The planned entry in the bone frame: the measured surface (depth surface_error, z down),
  // moved by the registration error.
  const Eigen::Vector3d entry_bone = Eigen::Vector3d(0.0, 0.0, -surface_error) + registration;
  out.entry_error_m = -entry_bone.z();
  out.plan.frame = "tracker_marker";
  out.plan.entry = marker_from_bone * entry_bone;
  out.plan.direction = marker_from_bone.linear() * Eigen::Vector3d(0.0, 0.0, -1.0);
  out.plan.depth_m = depth;
  const double entry_sd = std::hypot(per_axis, 1e-3 * params.boundary_sd_mm);
  out.plan.entry_tolerance_m = params.tolerance_sigmas * entry_sd;
  return out;
}

}  // namespace pedicle_drilling::core
