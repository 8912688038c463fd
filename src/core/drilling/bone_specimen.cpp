/**
 * @file bone_specimen.cpp
 * @brief Porcine lamellar bone specimen: layered geometry and random solid-fraction field.
 */
#include "pedicle_drilling/core/drilling/bone_specimen.hpp"
#include "pedicle_drilling/core/sim/normal_source.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>

namespace pedicle_drilling::core {

namespace {

constexpr double kPi = 3.14159265358979323846;

double truncatedNormal(NormalSource* src, double mean, double sd, double lower) {
  if (sd <= 0.0) return std::max(mean, lower);
  for (int i = 0; i < 1000; ++i) {
    const double v = mean + sd * src->normal();
    if (v >= lower) return v;
  }
  return std::max(mean, lower);
}

/**
 * Unit-variance Gaussian-correlated random field with `n` samples at spacing `step`:
 * white noise convolved with a Gaussian kernel of SD corr_length/2, so that the autocorrelation
 * is exp(-d^2 / corr_length^2) (e-folding distance = corr_length).
 */
std::vector<double> gaussianField(NormalSource* src, std::size_t n, double step,
                                  double corr_length) {
  std::vector<double> out(n, 0.0);
  if (n == 0) return out;
  const double sigma_k = std::max(0.5 * corr_length, step) / step;  // in samples
  const int half = static_cast<int>(std::ceil(4.0 * sigma_k));
  std::vector<double> kernel(2 * half + 1);
  double norm2 = 0.0;
  for (int j = -half; j <= half; ++j) {
    const double w = std::exp(-0.5 * (j / sigma_k) * (j / sigma_k));
    kernel[j + half] = w;
    norm2 += w * w;
  }
  const double scale = 1.0 / std::sqrt(norm2);
  std::vector<double> white(n + 2 * half);
  for (double& w : white) w = src->normal();
  for (std::size_t i = 0; i < n; ++i) {
    double acc = 0.0;
    for (int j = 0; j <= 2 * half; ++j) acc += kernel[j] * white[i + j];
    out[i] = acc * scale;
  }
  return out;
}

}  // namespace

std::string materialName(Material m) {
  switch (m) {
    case Material::kAir:
      return "air";
    case Material::kOuterCortical:
      return "outer_cortical";
    case Material::kCancellous:
      return "cancellous";
    case Material::kInnerCortical:
      return "inner_cortical";
    case Material::kCanal:
      return "canal";
  }
  return "unknown";
}

BoneSpecimen::BoneSpecimen(double outer_m, double cancellous_m, double inner_m, double grid_step_m,
                           std::vector<double> fraction_profile)
    : outer_m_(outer_m),
      cancellous_m_(cancellous_m),
      inner_m_(inner_m),
      grid_step_m_(grid_step_m),
      profile_(std::move(fraction_profile)) {
  if (!(outer_m > 0.0 && cancellous_m > 0.0 && inner_m > 0.0 && grid_step_m > 0.0)) {
    throw std::invalid_argument("BoneSpecimen: thicknesses and grid step must be > 0");
  }
  if (profile_.empty()) throw std::invalid_argument("BoneSpecimen: empty fraction profile");
  prefix_.assign(profile_.size(), 0.0);
  for (std::size_t k = 1; k < profile_.size(); ++k) {
    prefix_[k] = prefix_[k - 1] + 0.5 * grid_step_m_ * (profile_[k - 1] + profile_[k]);
  }
}

double BoneSpecimen::integratedFraction(double depth_m) const {
  const double z = std::min(depth_m, innerCorticalEnd());
  if (z <= 0.0) return 0.0;
  const double x = z / grid_step_m_;
  const std::size_t k = static_cast<std::size_t>(x);
  if (k + 1 >= profile_.size()) return prefix_.back();
  const double t = x - static_cast<double>(k);
  return prefix_[k] +
         grid_step_m_ * (t * profile_[k] + 0.5 * t * t * (profile_[k + 1] - profile_[k]));
}

BoneSpecimen BoneSpecimen::uniform(double outer_m, double cancellous_m, double inner_m,
                                   double outer_fraction, double cancellous_fraction,
                                   double inner_fraction, double grid_step_m) {
  const double total = outer_m + cancellous_m + inner_m;
  const std::size_t n = static_cast<std::size_t>(std::ceil(total / grid_step_m)) + 2;
  std::vector<double> profile(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double z = k * grid_step_m;
    if (z < outer_m) {
      profile[k] = outer_fraction;
    } else if (z < outer_m + cancellous_m) {
      profile[k] = cancellous_fraction;
    } else {
      profile[k] = inner_fraction;
    }
  }
  return BoneSpecimen(outer_m, cancellous_m, inner_m, grid_step_m, std::move(profile));
}

Material BoneSpecimen::materialAt(double depth_m) const {
  if (depth_m < 0.0) return Material::kAir;
  if (depth_m < outerCorticalEnd()) return Material::kOuterCortical;
  if (depth_m < innerCorticalStart()) return Material::kCancellous;
  if (depth_m < innerCorticalEnd()) return Material::kInnerCortical;
  return Material::kCanal;
}

double BoneSpecimen::solidFractionAt(double depth_m) const {
  if (depth_m < 0.0 || depth_m >= innerCorticalEnd()) return 0.0;
  const double x = depth_m / grid_step_m_;
  const std::size_t k = static_cast<std::size_t>(x);
  if (k + 1 >= profile_.size()) return profile_.back();
  const double t = x - static_cast<double>(k);
  return (1.0 - t) * profile_[k] + t * profile_[k + 1];
}

void BoneSpecimen::layerInterval(Material m, double* start_m, double* end_m) const {
  double s = 0.0;
  double e = 0.0;
  switch (m) {
    case Material::kOuterCortical:
      s = 0.0;
      e = outerCorticalEnd();
      break;
    case Material::kCancellous:
      s = outerCorticalEnd();
      e = innerCorticalStart();
      break;
    case Material::kInnerCortical:
      s = innerCorticalStart();
      e = innerCorticalEnd();
      break;
    default:
      break;
  }
  if (start_m) *start_m = s;
  if (end_m) *end_m = e;
}

double BoneSpecimen::meanFraction(Material m) const {
  double s = 0.0;
  double e = 0.0;
  layerInterval(m, &s, &e);
  if (e <= s) return 0.0;
  double acc = 0.0;
  int count = 0;
  for (double z = s + 0.5 * grid_step_m_; z < e; z += grid_step_m_) {
    acc += solidFractionAt(z);
    ++count;
  }
  return count > 0 ? acc / count : 0.0;
}

const ParamTable<SpecimenDistribution>& SpecimenDistribution::table() {
  static const ParamTable<SpecimenDistribution> t = [] {
    using D = SpecimenDistribution;
    ParamTable<D> d;
    // Lengths are stored in m and declared (set, documented) in mm.
    const auto mm = [&d](const char* name, double D::*field, Range range) {
      d.number(
          name, [field](const D& v) { return 1e3 * (v.*field); },
          [field](D& v, double x) { v.*field = 1e-3 * x; }, range, "mm");
    };
    mm("outer_cortical_thickness_mean_mm", &D::outer_cortical_thickness_mean_m,
       Range::aboveUpTo(0, 100));
    mm("outer_cortical_thickness_sd_mm", &D::outer_cortical_thickness_sd_m, Range::closed(0, 10));
    mm("cancellous_thickness_mean_mm", &D::cancellous_thickness_mean_m, Range::aboveUpTo(0, 100));
    mm("cancellous_thickness_sd_mm", &D::cancellous_thickness_sd_m, Range::closed(0, 10));
    mm("inner_cortical_thickness_mean_mm", &D::inner_cortical_thickness_mean_m,
       Range::aboveUpTo(0, 100));
    mm("inner_cortical_thickness_sd_mm", &D::inner_cortical_thickness_sd_m, Range::closed(0, 10));
    mm("min_layer_thickness_mm", &D::min_layer_thickness_m, Range::aboveUpTo(0, 10));
    d.number("outer_cortical_fraction_mean", &D::outer_cortical_fraction_mean,
             Range::aboveUpTo(0, 1))
        .number("inner_cortical_fraction_mean", &D::inner_cortical_fraction_mean,
                Range::aboveUpTo(0, 1))
        .number("cortical_fraction_sd", &D::cortical_fraction_sd, Range::closed(0, 0.3))
        .number("cortical_field_cv", &D::cortical_field_cv, Range::closed(0, 1));
    mm("cortical_corr_length_mm", &D::cortical_corr_length_m, Range::aboveUpTo(0, 10));
    d.number("cancellous_fraction_mean", &D::cancellous_fraction_mean, Range::aboveUpTo(0, 1))
        .number("cancellous_fraction_sd", &D::cancellous_fraction_sd, Range::closed(0, 0.3))
        .number("cancellous_field_cv", &D::cancellous_field_cv, Range::closed(0, 2));
    mm("cancellous_corr_length_mm", &D::cancellous_corr_length_m, Range::aboveUpTo(0, 10));
    d.number("cancellous_fraction_min", &D::cancellous_fraction_min, Range::aboveUpTo(0, 1))
        .number("cancellous_fraction_max", &D::cancellous_fraction_max, Range::aboveUpTo(0, 1));
    return d;
  }();
  return t;
}

void SpecimenDistribution::validate() const {
  table().validate(*this);
  if (!(cancellous_fraction_max > cancellous_fraction_min)) {
    throw std::invalid_argument(
        "cancellous_fraction_max = " + Range::format(cancellous_fraction_max) +
        " must be > cancellous_fraction_min = " + Range::format(cancellous_fraction_min));
  }
  if (!(std::isfinite(grid_step_m) && grid_step_m > 0.0 && grid_step_m <= 1e-3)) {
    throw std::invalid_argument("grid_step_m = " + Range::format(grid_step_m) +
                                " is out of range (0, 0.001]");
  }
}

BoneSpecimen sample(std::uint64_t seed, const SpecimenDistribution& d) {
  d.validate();
  NormalSource src(seed);
  const double t_out = truncatedNormal(&src, d.outer_cortical_thickness_mean_m,
                                       d.outer_cortical_thickness_sd_m, d.min_layer_thickness_m);
  const double t_can = truncatedNormal(&src, d.cancellous_thickness_mean_m,
                                       d.cancellous_thickness_sd_m, d.min_layer_thickness_m);
  const double t_in = truncatedNormal(&src, d.inner_cortical_thickness_mean_m,
                                      d.inner_cortical_thickness_sd_m, d.min_layer_thickness_m);
  auto clampf = [](double v, double lo, double hi) { return std::min(std::max(v, lo), hi); };
  const double f_out =
      clampf(d.outer_cortical_fraction_mean + d.cortical_fraction_sd * src.normal(), 0.5, 1.0);
  const double f_can = clampf(d.cancellous_fraction_mean + d.cancellous_fraction_sd * src.normal(),
                              d.cancellous_fraction_min, d.cancellous_fraction_max);
  const double f_in =
      clampf(d.inner_cortical_fraction_mean + d.cortical_fraction_sd * src.normal(), 0.5, 1.0);

  const double step = d.grid_step_m;
  const double total = t_out + t_can + t_in;
  const std::size_t n = static_cast<std::size_t>(std::ceil(total / step)) + 2;
  const std::vector<double> field_out = gaussianField(&src, n, step, d.cortical_corr_length_m);
  const std::vector<double> field_can = gaussianField(&src, n, step, d.cancellous_corr_length_m);
  const std::vector<double> field_in = gaussianField(&src, n, step, d.cortical_corr_length_m);

  std::vector<double> profile(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double z = k * step;
    if (z < t_out) {
      profile[k] = clampf(f_out * (1.0 + d.cortical_field_cv * field_out[k]), 0.3, 1.0);
    } else if (z < t_out + t_can) {
      profile[k] = clampf(f_can * (1.0 + d.cancellous_field_cv * field_can[k]),
                          d.cancellous_fraction_min, d.cancellous_fraction_max);
    } else {
      profile[k] = clampf(f_in * (1.0 + d.cortical_field_cv * field_in[k]), 0.3, 1.0);
    }
  }
  return BoneSpecimen(t_out, t_can, t_in, step, std::move(profile));
}

}  // namespace pedicle_drilling::core
