/**
 * @file test_bone_specimen.cpp
 * @brief Layer geometry, randomisation statistics and determinism of the bone specimen.
 */
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "pedicle_drilling/core/drilling/bone_specimen.hpp"

namespace pedicle_drilling::core {
namespace {

TEST(BoneSpecimen, UniformLayersAndMaterials) {
  const BoneSpecimen b = BoneSpecimen::uniform(2e-3, 4e-3, 2e-3, 0.9, 0.25, 0.8);
  EXPECT_EQ(b.materialAt(-1e-6), Material::kAir);
  EXPECT_EQ(b.materialAt(0.0), Material::kOuterCortical);
  EXPECT_EQ(b.materialAt(1.99e-3), Material::kOuterCortical);
  EXPECT_EQ(b.materialAt(2.01e-3), Material::kCancellous);
  EXPECT_EQ(b.materialAt(6.01e-3), Material::kInnerCortical);
  EXPECT_EQ(b.materialAt(8.01e-3), Material::kCanal);
  EXPECT_DOUBLE_EQ(b.innerCorticalEnd(), 8e-3);
  EXPECT_NEAR(b.solidFractionAt(1e-3), 0.9, 1e-12);
  EXPECT_NEAR(b.solidFractionAt(4e-3), 0.25, 1e-12);
  EXPECT_NEAR(b.solidFractionAt(7e-3), 0.8, 1e-12);
  EXPECT_EQ(b.solidFractionAt(-1e-3), 0.0);
  EXPECT_EQ(b.solidFractionAt(8.5e-3), 0.0);
  double s = 0.0;
  double e = 0.0;
  b.layerInterval(Material::kCancellous, &s, &e);
  EXPECT_DOUBLE_EQ(s, 2e-3);
  EXPECT_DOUBLE_EQ(e, 6e-3);
  EXPECT_EQ(materialName(Material::kInnerCortical), "inner_cortical");
}

TEST(BoneSpecimen, IntegratedFractionIsExactForUniformLayers) {
  const BoneSpecimen b = BoneSpecimen::uniform(2e-3, 4e-3, 2e-3, 0.9, 0.25, 0.8);
  EXPECT_EQ(b.integratedFraction(-1e-3), 0.0);
  EXPECT_NEAR(b.integratedFraction(1e-3), 0.9e-3, 1e-12);
  // Interpolation across the 10 um cell at each boundary blurs by at most half a cell.
  EXPECT_NEAR(b.integratedFraction(4e-3), 1.8e-3 + 0.5e-3, 0.7 * 10e-6);
  EXPECT_NEAR(b.integratedFraction(8e-3), 1.8e-3 + 1.0e-3 + 1.6e-3, 2 * 0.7 * 10e-6);
  EXPECT_EQ(b.integratedFraction(9e-3), b.integratedFraction(8e-3));  // canal adds nothing
}

TEST(BoneSpecimen, DeterministicPerSeed) {
  const BoneSpecimen a = sample(42);
  const BoneSpecimen b = sample(42);
  const BoneSpecimen c = sample(43);
  EXPECT_EQ(a.outerCorticalThickness(), b.outerCorticalThickness());
  EXPECT_EQ(a.innerCorticalThickness(), b.innerCorticalThickness());
  EXPECT_EQ(a.fractionProfile(), b.fractionProfile());
  EXPECT_NE(a.innerCorticalThickness(), c.innerCorticalThickness());
}

TEST(BoneSpecimen, DistributionValidationNamesTheField) {
  EXPECT_NO_THROW(SpecimenDistribution{}.validate());
  auto message = [](const SpecimenDistribution& d) {
    try {
      sample(1, d);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  SpecimenDistribution d;
  d.cancellous_thickness_sd_m = -1e-3;
  EXPECT_NE(message(d).find("cancellous_thickness_sd_m"), std::string::npos) << message(d);
  d = SpecimenDistribution{};
  d.outer_cortical_fraction_mean = 1.2;
  EXPECT_NE(message(d).find("outer_cortical_fraction_mean"), std::string::npos) << message(d);
  d = SpecimenDistribution{};
  d.cancellous_fraction_max = 0.01;  // below cancellous_fraction_min
  EXPECT_NE(message(d).find("cancellous_fraction_max"), std::string::npos) << message(d);
  d = SpecimenDistribution{};
  d.grid_step_m = std::nan("");
  EXPECT_NE(message(d).find("grid_step_m"), std::string::npos) << message(d);
}

TEST(BoneSpecimen, ThicknessStatisticsMatchDistribution) {
  const SpecimenDistribution d;
  std::vector<double> outer;
  std::vector<double> canc;
  std::vector<double> inner;
  for (std::uint64_t seed = 0; seed < 400; ++seed) {
    const BoneSpecimen b = sample(seed, d);
    outer.push_back(b.outerCorticalThickness());
    canc.push_back(b.cancellousThickness());
    inner.push_back(b.innerCorticalThickness());
    EXPECT_GE(b.outerCorticalThickness(), d.min_layer_thickness_m);
    EXPECT_GE(b.cancellousThickness(), d.min_layer_thickness_m);
    EXPECT_GE(b.innerCorticalThickness(), d.min_layer_thickness_m);
  }
  auto mean = [](const std::vector<double>& v) {
    double s = 0.0;
    for (double x : v) s += x;
    return s / v.size();
  };
  // Standard error of the mean: sd / 20 -> test at ~4 SE.
  EXPECT_NEAR(mean(inner), 2.11e-3, 0.06e-3);  // paper Sec. V-E
  EXPECT_NEAR(mean(outer), d.outer_cortical_thickness_mean_m, 0.07e-3);
  EXPECT_NEAR(mean(canc), d.cancellous_thickness_mean_m, 0.25e-3);
}

TEST(BoneSpecimen, CancellousIsInhomogeneousAndLessDenseThanCortex) {
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const BoneSpecimen b = sample(seed);
    const double f_out = b.meanFraction(Material::kOuterCortical);
    const double f_can = b.meanFraction(Material::kCancellous);
    const double f_in = b.meanFraction(Material::kInnerCortical);
    EXPECT_GT(f_out, 2.0 * f_can);
    EXPECT_GT(f_in, 2.0 * f_can);
    // Within-layer variation of the cancellous field.
    double s0 = 0.0;
    double e0 = 0.0;
    b.layerInterval(Material::kCancellous, &s0, &e0);
    double lo = 1.0;
    double hi = 0.0;
    for (double z = s0; z < e0; z += 20e-6) {
      lo = std::min(lo, b.solidFractionAt(z));
      hi = std::max(hi, b.solidFractionAt(z));
    }
    EXPECT_GT(hi - lo, 0.05) << "seed " << seed;
  }
}

TEST(BoneSpecimen, CancellousFieldCorrelationLength) {
  // Empirical autocorrelation of the cancellous field at lag = correlation length should be
  // near exp(-1) (Gaussian kernel construction), and near 1 at a short lag.
  SpecimenDistribution d;
  d.cancellous_thickness_mean_m = 40e-3;  // long layer for statistics
  d.cancellous_thickness_sd_m = 0.0;
  // No clamping, pure field: mean 0.25 with a 10 % field CV stays within [0.03, 0.70] (>8 SD).
  d.cancellous_fraction_sd = 0.0;
  d.cancellous_field_cv = 0.10;
  double acf_short = 0.0;
  double acf_l = 0.0;
  const int seeds = 20;
  for (int seed = 0; seed < seeds; ++seed) {
    const BoneSpecimen b = sample(seed, d);
    double s0 = 0.0;
    double e0 = 0.0;
    b.layerInterval(Material::kCancellous, &s0, &e0);
    std::vector<double> v;
    for (double z = s0; z < e0; z += d.grid_step_m) v.push_back(b.solidFractionAt(z));
    double m = 0.0;
    for (double x : v) m += x;
    m /= v.size();
    auto acf = [&](int lag) {
      double num = 0.0;
      double den = 0.0;
      for (std::size_t i = 0; i + lag < v.size(); ++i) num += (v[i] - m) * (v[i + lag] - m);
      for (double x : v) den += (x - m) * (x - m);
      return num / den * v.size() / (v.size() - lag);
    };
    acf_short += acf(5) / seeds;
    acf_l += acf(static_cast<int>(d.cancellous_corr_length_m / d.grid_step_m)) / seeds;
  }
  EXPECT_GT(acf_short, 0.9);
  EXPECT_NEAR(acf_l, std::exp(-1.0), 0.12);
}

}  // namespace
}  // namespace pedicle_drilling::core
