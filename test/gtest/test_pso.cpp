// Tests of the PSO baseline identifier (paper Sec. V-B settings).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "pedicle_drilling/core/breathing/identification.hpp"
#include "pedicle_drilling/core/breathing/pso.hpp"
#include "pedicle_drilling/core/breathing/virtual_volunteer.hpp"

namespace pedicle_drilling::core {
namespace {

AxisSamples volunteerAxis(int id, Axis axis) {
  const VolunteerData v = generateVolunteer(defaultVolunteer(id));
  return axisSamples(pairAtMarkerTimes(v.recording), axis);
}

TEST(Pso, DefaultsAreThePapersAndClercKennedy) {
  const PsoOptions o;
  EXPECT_EQ(o.population, 24);
  EXPECT_EQ(o.iterations, 2000);
  EXPECT_DOUBLE_EQ(o.inertia, 0.729);
  EXPECT_DOUBLE_EQ(o.cognitive, 1.494);
  EXPECT_DOUBLE_EQ(o.social, 1.494);
}

TEST(Pso, SameSeedGivesIdenticalResult) {
  const AxisSamples s = volunteerAxis(2, Axis::kSI);
  PsoOptions o;
  o.seed = 42;
  o.iterations = 300;  // determinism does not need convergence
  for (ModelKind kind : {ModelKind::kLinear, ModelKind::kHysteresis}) {
    const FitResult a = fitPso(kind, s, o);
    const FitResult b = fitPso(kind, s, o);
    EXPECT_EQ(a.model.coefficients(), b.model.coefficients());  // bitwise
    EXPECT_EQ(a.r2, b.r2);
    o.seed = 43;
    const FitResult c = fitPso(kind, s, o);
    EXPECT_NE(a.model.coefficients(), c.model.coefficients());
    o.seed = 42;
  }
}

TEST(Pso, ReachesOlsRSquaredWithPaperSettings) {
  for (int id : {1, 3, 5}) {
    for (Axis a : kAllAxes) {
      const AxisSamples s = volunteerAxis(id, a);
      for (ModelKind kind : {ModelKind::kLinear, ModelKind::kHysteresis}) {
        SCOPED_TRACE("volunteer " + std::to_string(id) + " " + axisName(a) + " " +
                     modelKindName(kind));
        const FitResult ols = fitOls(kind, s);
        const FitResult pso = fitPso(kind, s);
        // OLS is the exact maximum of R^2: PSO can only approach it from below.
        EXPECT_LE(pso.r2, ols.r2 + 1e-12);
        EXPECT_NEAR(pso.r2, ols.r2, 1e-6);
        EXPECT_NEAR(pso.model.q1, ols.model.q1, 1e-3 * std::abs(ols.model.q1));
        EXPECT_EQ(pso.iterations, 2000);
        EXPECT_EQ(pso.method, "pso");
      }
    }
  }
}

TEST(Pso, BoundsContainTheOptimum) {
  for (int id = 1; id <= 5; ++id) {
    for (Axis a : kAllAxes) {
      const AxisSamples s = volunteerAxis(id, a);
      for (ModelKind kind : {ModelKind::kLinear, ModelKind::kHysteresis}) {
        const PsoBounds b = psoBounds(kind, s, 2.0);
        const std::vector<double> c = fitOls(kind, s).model.coefficients();
        ASSERT_EQ(b.lower.size(), c.size());
        for (size_t k = 0; k < c.size(); ++k) {
          EXPECT_LT(b.lower[k], c[k]) << id << axisName(a) << k;
          EXPECT_GT(b.upper[k], c[k]) << id << axisName(a) << k;
        }
      }
    }
  }
}

TEST(Pso, RejectsBadOptions) {
  const AxisSamples s = volunteerAxis(1, Axis::kAP);
  PsoOptions o;
  o.population = 0;
  EXPECT_THROW(fitPso(ModelKind::kLinear, s, o), std::invalid_argument);
  o = PsoOptions();
  o.bound_scale = 0.0;
  EXPECT_THROW(fitPso(ModelKind::kLinear, s, o), std::invalid_argument);
}

}  // namespace
}  // namespace pedicle_drilling::core
