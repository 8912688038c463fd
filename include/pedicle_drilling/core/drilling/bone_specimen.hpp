/**
 * @file bone_specimen.hpp
 * @brief Porcine lamellar bone specimen as layers along the drill axis (simulator physics core).
 *
 * The specimen is one-dimensional along the drill axis: depth 0 is the outer bone surface,
 * depth grows into the bone. Layers: outer cortical, cancellous, inner cortical, then the canal
 * (air / soft tissue, no cutting resistance). Each depth carries a solid volume fraction
 * (BV/TV, 0..1) that the drilling-force law uses as the fraction of solid bone crossed by the
 * cutting lips. All constants and their sources are listed in doc/simulator_physics.md.
 *
 * No ROS headers; C++17 and Eigen only.
 */
#ifndef PEDICLE_DRILLING_CORE_BONE_SPECIMEN_HPP
#define PEDICLE_DRILLING_CORE_BONE_SPECIMEN_HPP

#include <cstdint>
#include <string>
#include <vector>

#include "pedicle_drilling/core/common/param_table.hpp"

namespace pedicle_drilling::core {

/** @brief Material at a point along the drill axis. */
enum class Material : int {
  kAir = 0,            ///< in front of the outer surface (depth < 0)
  kOuterCortical = 1,  ///< first cortical layer
  kCancellous = 2,     ///< trabecular bone between the cortices
  kInnerCortical = 3,  ///< second (inner) cortical layer; the desired stop layer
  kCanal = 4,          ///< beyond the inner cortex (spinal canal); no bone
};

/** @brief Human-readable name of a material ("outer_cortical", ...). */
std::string materialName(Material m);

/**
 * @brief Means and standard deviations of the per-specimen random quantities.
 *
 * Thicknesses are in metres; volume fractions are dimensionless (BV/TV). Every thickness is drawn
 * from a normal distribution truncated below at `min_layer_thickness_m` (by resampling).
 * Defaults and sources: doc/simulator_physics.md.
 */
struct SpecimenDistribution {
  double outer_cortical_thickness_mean_m = 2.0e-3;   ///< outer cortex, 2.0 mm
  double outer_cortical_thickness_sd_m = 0.3e-3;     ///< 0.3 mm
  double cancellous_thickness_mean_m = 4.0e-3;       ///< cancellous core, 4 mm
  double cancellous_thickness_sd_m = 1.0e-3;         ///< 1 mm
  double inner_cortical_thickness_mean_m = 2.11e-3;  ///< paper Sec. V-E: 2.11 mm on average
  double inner_cortical_thickness_sd_m = 0.25e-3;    ///< 0.25 mm
  double min_layer_thickness_m = 0.8e-3;             ///< truncation of the thickness normals

  double outer_cortical_fraction_mean = 0.92;  ///< cortical BV/TV (porosity ~8 %)
  double inner_cortical_fraction_mean = 0.84;  ///< lower: inner/outer peak ratio 2.88/3.16 N
  double cortical_fraction_sd = 0.04;          ///< per-specimen SD of each cortical mean
  double cortical_field_cv = 0.03;             ///< within-layer relative SD (osteonal porosity)
  double cortical_corr_length_m = 0.3e-3;      ///< correlation length of the cortical field

  double cancellous_fraction_mean = 0.25;    ///< trabecular BV/TV mean
  double cancellous_fraction_sd = 0.04;      ///< per-specimen SD of the trabecular mean
  double cancellous_field_cv = 0.35;         ///< within-layer relative SD (pores/trabeculae)
  double cancellous_corr_length_m = 0.7e-3;  ///< ~ trabecular separation, 0.5-1 mm
  double cancellous_fraction_min = 0.03;     ///< clamp of the random field (pore)
  double cancellous_fraction_max = 0.70;     ///< clamp of the random field (dense strut)

  double grid_step_m = 10e-6;  ///< sampling step of the density field along depth (10 um)

  /**
   * @brief Checks every field against its physical range (thicknesses (0, 100 mm], SDs >= 0,
   *        fractions in (0, 1], ...). @throws std::invalid_argument naming the field.
   */
  void validate() const;

  /** @brief The declaration of every field a node sets: names and ranges in mm (ROS names). */
  static const ParamTable<SpecimenDistribution>& table();
};

/**
 * @brief One randomised bone specimen: layer boundaries and a solid-fraction profile along depth.
 *
 * Immutable after construction; cheap queries. Deterministic for a given seed and distribution.
 */
class BoneSpecimen {
 public:
  /**
   * @brief Builds a specimen from explicit layer thicknesses and a sampled fraction profile.
   * @param outer_m, cancellous_m, inner_m layer thicknesses [m], all > 0
   * @param grid_step_m spacing of `fraction_profile` samples [m]
   * @param fraction_profile BV/TV at depths k*grid_step_m, k = 0..N-1, covering the bone
   */
  BoneSpecimen(double outer_m, double cancellous_m, double inner_m, double grid_step_m,
               std::vector<double> fraction_profile);

  /**
   * @brief Builds a specimen with uniform fractions per layer (no random field); for tests.
   */
  static BoneSpecimen uniform(double outer_m, double cancellous_m, double inner_m,
                              double outer_fraction, double cancellous_fraction,
                              double inner_fraction, double grid_step_m = 10e-6);

  /**
   * @brief Integral of the solid fraction from depth 0 to `depth_m` [m] (exact for the
   *        piecewise-linear profile; 0 for depth <= 0, constant beyond the canal wall).
   */
  double integratedFraction(double depth_m) const;

  /** @brief Material at a depth [m] along the drill axis (depth 0 = outer surface). */
  Material materialAt(double depth_m) const;

  /** @brief Solid volume fraction (BV/TV) at a depth [m]; 0 in air and canal. Linear interp. */
  double solidFractionAt(double depth_m) const;

  /** @brief Depth of the outer-cortical / cancellous boundary [m]. */
  double outerCorticalEnd() const { return outer_m_; }
  /** @brief Depth of the cancellous / inner-cortical boundary [m]. */
  double innerCorticalStart() const { return outer_m_ + cancellous_m_; }
  /** @brief Depth of the inner-cortical far boundary (canal wall) [m]. */
  double innerCorticalEnd() const { return outer_m_ + cancellous_m_ + inner_m_; }
  /** @brief Thickness of the outer cortical layer [m]. */
  double outerCorticalThickness() const { return outer_m_; }
  /** @brief Thickness of the cancellous layer [m]. */
  double cancellousThickness() const { return cancellous_m_; }
  /** @brief Thickness of the inner cortical layer [m]. */
  double innerCorticalThickness() const { return inner_m_; }
  /** @brief Depth interval [start, end) of a bone layer [m]; air/canal give an empty interval. */
  void layerInterval(Material m, double* start_m, double* end_m) const;
  /** @brief Mean solid fraction of a bone layer (average of the profile over the layer). */
  double meanFraction(Material m) const;
  /** @brief Sampling step of the fraction profile [m]. */
  double gridStep() const { return grid_step_m_; }
  /** @brief The sampled fraction profile (index k at depth k * gridStep()). */
  const std::vector<double>& fractionProfile() const { return profile_; }

 private:
  double outer_m_;
  double cancellous_m_;
  double inner_m_;
  double grid_step_m_;
  std::vector<double> profile_;
  std::vector<double> prefix_;  // prefix_[k] = integral of the profile over [0, k * step]
};

/**
 * @brief Samples a specimen: thicknesses, per-layer mean fractions, and smoothed Gaussian random
 *        fields for the within-layer density, all from one std::mt19937_64 seeded with `seed`.
 *
 * Same seed and distribution give a bit-identical specimen on every platform (the normal
 * deviates are generated by an explicit Box-Muller transform, not std::normal_distribution).
 */
BoneSpecimen sample(std::uint64_t seed, const SpecimenDistribution& distribution = {});

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_BONE_SPECIMEN_HPP
