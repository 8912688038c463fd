// Tests of the shared identification pipeline (motion_pipeline.hpp): axis mapping, validation of
// in-memory recordings, equivalence with the step-by-step pipeline, parameter recovery.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/motion_pipeline.hpp"

namespace pedicle_drilling::core {
namespace {

PairedSamples volunteerSamples(int id) {
  return pairAtMarkerTimes(generateVolunteer(defaultVolunteer(id)).recording);
}

TEST(AxisMapping, DefaultIsApZSiYLrX) {
  const AxisMapping m = parseAxisMapping("+z", "+y", "+x");
  const std::array<double, 3> d = m.map(1.0, 2.0, 3.0);
  EXPECT_EQ(d[0], 3.0);
  EXPECT_EQ(d[1], 2.0);
  EXPECT_EQ(d[2], 1.0);
}

TEST(AxisMapping, SignsAndPermutation) {
  const AxisMapping m = parseAxisMapping("-x", "z", "-y");
  const std::array<double, 3> d = m.map(1.0, 2.0, 3.0);
  EXPECT_EQ(d[0], -1.0);
  EXPECT_EQ(d[1], 3.0);
  EXPECT_EQ(d[2], -2.0);
}

TEST(AxisMapping, RejectsBadSpecsNamingTheAxis) {
  try {
    parseAxisMapping("+z", "+w", "+x");
    FAIL() << "accepted +w";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).substr(0, 2), "si");
  }
  try {
    parseAxisMapping("+z", "+y", "-z");
    FAIL() << "accepted z twice";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).substr(0, 2), "lr");
  }
  EXPECT_THROW(parseAxisMapping("", "+y", "+x"), std::invalid_argument);
  EXPECT_THROW(parseAxisMapping("+-z", "+y", "+x"), std::invalid_argument);
  EXPECT_THROW(parseAxisMapping("zz", "+y", "+x"), std::invalid_argument);
}

TEST(ValidatePairedSamples, AcceptsAVolunteer) {
  EXPECT_NO_THROW(validatePairedSamples(volunteerSamples(1), "v1"));
}

TEST(ValidatePairedSamples, RejectsNaNNonIncreasingTimeTooFewBreathsAndSizes) {
  PairedSamples p = volunteerSamples(1);
  PairedSamples nan = p;
  nan.si[17] = std::numeric_limits<double>::quiet_NaN();
  try {
    validatePairedSamples(nan, "window");
    FAIL();
  } catch (const NonFiniteValueError& e) {
    EXPECT_NE(std::string(e.what()).find("'si'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("window"), std::string::npos) << e.what();
  }
  PairedSamples back = p;
  back.t[40] = back.t[39];
  EXPECT_THROW(validatePairedSamples(back, "w"), NonIncreasingTimeError);
  PairedSamples short_rec = p;
  for (std::vector<double>* c :
       {&short_rec.t, &short_rec.tv, &short_rec.ap, &short_rec.si, &short_rec.lr}) {
    c->resize(20);  // 2.5 s: at most one breath
  }
  EXPECT_THROW(validatePairedSamples(short_rec, "w"), TooFewBreathsError);
  PairedSamples sizes = p;
  sizes.lr.pop_back();
  EXPECT_THROW(validatePairedSamples(sizes, "w"), MissingColumnError);
  EXPECT_THROW(identifyPatient(nan, PipelineOptions(), "x"), NonFiniteValueError);
}

TEST(PipelineOptions, ValidateNamesTheProblem) {
  PipelineOptions o;
  o.denoise_options.candidates = {"coif4", "nope7"};
  EXPECT_THROW(o.validate(), std::invalid_argument);
  o = PipelineOptions();
  o.denoise_options.kept_levels = {3, 7};
  EXPECT_THROW(o.validate(), std::invalid_argument);
  o = PipelineOptions();
  o.denoise = false;
  o.denoise_tv = true;
  EXPECT_THROW(o.validate(), std::invalid_argument);
}

// identifyPatient() is exactly the documented steps done by hand.
TEST(IdentifyPatient, EqualsTheStepByStepPipeline) {
  const PairedSamples p = volunteerSamples(3);
  PipelineOptions o;
  o.denoise_options.candidates = {"coif4", "db8", "sym6"};
  const PipelineResult r = identifyPatient(p, o, "v3");
  EXPECT_EQ(r.model.patient_id, "v3");
  EXPECT_EQ(r.samples, p.t.size());
  EXPECT_EQ(r.breaths, countBreaths(p.tv));
  for (Axis a : kAllAxes) {
    const DenoiseResult dr = selectAndDenoise(p.axis(a), p.tv, o.denoise_options);
    double mean = 0.0;
    for (double v : p.axis(a)) mean += v / static_cast<double>(p.t.size());
    AxisSamples s = axisSamples(p, a);
    s.d = dr.denoised;
    for (double& v : s.d) v += mean;
    const FitResult fit = fitCeres(ModelKind::kLinear, s);
    const AxisModelRecord& rec = r.model.axes[static_cast<int>(a)];
    EXPECT_EQ(rec.wavelet, dr.wavelet);
    EXPECT_EQ(rec.level, 6);
    EXPECT_NEAR(rec.model.q1, fit.model.q1, 1e-12);
    EXPECT_NEAR(rec.model.q0, fit.model.q0, 1e-9);
    EXPECT_NEAR(rec.r2, fit.r2, 1e-12);
    EXPECT_NEAR(r.axes[static_cast<int>(a)].r2_raw, rSquared(p.axis(a), predictAll(fit.model, s)),
                1e-12);
  }
}

// Ceres and PSO through the pipeline reach the same optimum (R^2) on the same data.
TEST(IdentifyPatient, PsoAndCeresAgree) {
  const PairedSamples p = volunteerSamples(4);
  PipelineOptions o;
  o.denoise_options.candidates = {"coif4"};
  const PipelineResult c = identifyPatient(p, o, "v4");
  o.method = IdentificationMethod::kPso;
  const PipelineResult s = identifyPatient(p, o, "v4");
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(c.axes[k].fit.r2, s.axes[k].fit.r2, 1e-9);
    EXPECT_EQ(s.axes[k].fit.method, "pso");
  }
}

// With Tv filtered like the displacement, AP and SI slopes are within 5 % of the truth for all
// five default volunteers, with both model kinds.
TEST(IdentifyPatient, RecoversApAndSiSlopesWithDenoisedTv) {
  for (int id = 1; id <= 5; ++id) {
    const VolunteerParams params = defaultVolunteer(id);
    const PairedSamples p = pairAtMarkerTimes(generateVolunteer(params).recording);
    for (ModelKind kind : {ModelKind::kLinear, ModelKind::kHysteresis}) {
      PipelineOptions o;
      o.kind = kind;
      o.denoise_tv = true;
      const PipelineResult r = identifyPatient(p, o, "v");
      for (Axis a : {Axis::kAP, Axis::kSI}) {
        const double truth = params.truth.axis(a).q1;
        const double got = r.model.axes[static_cast<int>(a)].model.q1;
        EXPECT_LT(std::abs(got / truth - 1.0), 0.05)
            << "volunteer " << id << " " << axisName(a) << " " << modelKindName(kind) << ": " << got
            << " vs " << truth;
      }
    }
  }
}

}  // namespace
}  // namespace pedicle_drilling::core
