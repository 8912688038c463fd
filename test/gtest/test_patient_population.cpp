// Tests of the population of virtual patients: one patient per seed, never shared between the
// seed spaces, drawn from the declared distributions, identified from its own recording, and
// moving on the table as its surgery state says.
#include "pedicle_drilling/core/sim/patient_population.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "pedicle_drilling/core/sim/drilling_simulation.hpp"

namespace pd = pedicle_drilling::core;

namespace {

constexpr std::uint64_t kEvaluationBit = 1ULL << 62;  // pd_campaign.design.trial_seed

/** @brief A trial seed of the calibration space (bit 62 clear), as the campaign's hash makes. */
std::uint64_t calibrationSeed(std::uint64_t i) {
  std::uint64_t z = i * 0x9E3779B97F4A7C15ULL + 0x1234567ULL;
  z = (z ^ (z >> 31)) * 0xBF58476D1CE4E5B9ULL;
  return (z ^ (z >> 29)) & ((1ULL << 62) - 1);
}

std::tuple<double, double, double, double> identity(const pd::PopulationPatient& p) {
  return {p.identificationSlope(), p.identificationLag(), p.surgery.gain,
          p.identification.breaths_per_min};
}

double mean(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}

double sd(const std::vector<double>& v) {
  const double m = mean(v);
  double s = 0.0;
  for (double x : v) s += (x - m) * (x - m);
  return std::sqrt(s / static_cast<double>(v.size() - 1));
}

}  // namespace

TEST(PatientPopulation, NoPatientOfOneSeedSpaceIsDrawnInTheOther) {
  const pd::PopulationParams params;
  std::set<std::tuple<double, double, double, double>> calibration;
  for (std::uint64_t i = 0; i < 2000; ++i) {
    calibration.insert(identity(pd::drawPopulationPatient(calibrationSeed(i), params)));
  }
  EXPECT_EQ(calibration.size(), 2000u);  // a patient per seed
  for (std::uint64_t i = 0; i < 2000; ++i) {
    // The same 62 bits in the evaluation space, and other evaluation seeds.
    for (std::uint64_t seed :
         {calibrationSeed(i) | kEvaluationBit, calibrationSeed(i + 100000) | kEvaluationBit}) {
      EXPECT_EQ(calibration.count(identity(pd::drawPopulationPatient(seed, params))), 0u) << seed;
    }
  }
}

TEST(PatientPopulation, IsAFunctionOfTheSeed) {
  const pd::PopulationParams params;
  const pd::PopulationPatient a = pd::drawPopulationPatient(77, params);
  const pd::PopulationPatient b = pd::drawPopulationPatient(77, params);
  EXPECT_EQ(identity(a), identity(b));
  EXPECT_EQ(a.identification.seed, b.identification.seed);
  EXPECT_EQ(a.surgery.cardiac_mm, b.surgery.cardiac_mm);
  EXPECT_NE(identity(a), identity(pd::drawPopulationPatient(78, params)));
}

TEST(PatientPopulation, DrawsFromTheDeclaredDistributions) {
  const pd::PopulationParams params;
  std::vector<double> log_amplitude, lag, log_gain, lag_change, rate, heart, cardiac;
  for (std::uint64_t i = 0; i < 4000; ++i) {
    const pd::PopulationPatient p = pd::drawPopulationPatient(calibrationSeed(i), params);
    const double amplitude = p.identificationSlope() * 500.0;  // the amplitude is per 500 ml
    log_amplitude.push_back(std::log(amplitude));
    lag.push_back(p.identificationLag());
    log_gain.push_back(std::log(p.surgery.gain));
    lag_change.push_back(p.surgery.lag_change_s);
    rate.push_back(p.identification.breaths_per_min);
    heart.push_back(p.surgery.heart_rate_bpm);
    cardiac.push_back(p.surgery.cardiac_mm);
  }
  EXPECT_NEAR(std::exp(mean(log_amplitude)), params.ap_amplitude_median_mm, 0.1);
  EXPECT_NEAR(sd(log_amplitude), params.ap_amplitude_sigma_ln, 0.03);
  EXPECT_NEAR(mean(log_gain), 0.0, 0.02);
  EXPECT_NEAR(sd(log_gain), params.gain_change_sigma_ln, 0.02);
  EXPECT_NEAR(sd(lag_change), params.lag_change_sd_s, 0.005);
  EXPECT_NEAR(mean(lag), params.lag_mean_s + 0.011, 0.006);  // truncated at 0: +0.011 s
  for (const std::vector<double>* v : {&lag, &rate, &heart, &cardiac}) {
    EXPECT_TRUE(std::all_of(v->begin(), v->end(), [](double x) { return std::isfinite(x); }));
  }
  EXPECT_GE(*std::min_element(lag.begin(), lag.end()), 0.0);
  EXPECT_LE(*std::max_element(lag.begin(), lag.end()), 0.4);
  EXPECT_GE(*std::min_element(rate.begin(), rate.end()), 8.0);
  EXPECT_LE(*std::max_element(rate.begin(), rate.end()), 25.0);
  EXPECT_GE(*std::min_element(heart.begin(), heart.end()), 50.0);
  EXPECT_LE(*std::max_element(heart.begin(), heart.end()), 100.0);
  EXPECT_LE(*std::max_element(cardiac.begin(), cardiac.end()), params.cardiac_amplitude_max_mm);
}

TEST(PatientPopulation, ChangingOneSpreadChangesNoOtherDraw) {
  pd::PopulationParams wider;
  wider.gain_change_sigma_ln = 0.5;
  for (std::uint64_t seed : {3ULL, 99ULL, kEvaluationBit | 5ULL}) {
    const pd::PopulationPatient a = pd::drawPopulationPatient(seed, pd::PopulationParams());
    const pd::PopulationPatient b = pd::drawPopulationPatient(seed, wider);
    EXPECT_EQ(a.identificationSlope(), b.identificationSlope());
    EXPECT_EQ(a.identificationLag(), b.identificationLag());
    EXPECT_EQ(a.surgery.lag_change_s, b.surgery.lag_change_s);
    EXPECT_NEAR(std::log(b.surgery.gain),
                0.5 / pd::PopulationParams().gain_change_sigma_ln * std::log(a.surgery.gain),
                1e-12);
  }
}

TEST(PatientPopulation, BadParametersNameTheField) {
  pd::PopulationParams p;
  p.gain_change_sigma_ln = -0.1;
  try {
    pd::drawPopulationPatient(1, p);
    FAIL() << "accepted a negative spread";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("gain_change_sigma_ln"), std::string::npos) << e.what();
  }
  p = pd::PopulationParams();
  p.heart_rate_mean_bpm = NAN;
  EXPECT_THROW(p.validate(), std::invalid_argument);
}

TEST(PatientPopulation, TheModelIsIdentifiedFromThePatientsOwnRecording) {
  const pd::PopulationParams params;
  for (std::uint64_t seed : {11ULL, kEvaluationBit | 12ULL}) {
    const pd::PopulationPatient p = pd::drawPopulationPatient(seed, params);
    const pd::PipelineResult r = pd::identifyPopulationPatient(p);
    const pd::AxisModelRecord& ap = r.model.axes[static_cast<int>(pd::Axis::kAP)];
    EXPECT_EQ(ap.model.kind, pd::ModelKind::kLinear);
    // The linear model of a lagging, noisy, drifting recording: near the true slope, not on it.
    EXPECT_NEAR(ap.model.q1 / p.identificationSlope(), 1.0, 0.25) << seed;
    EXPECT_GT(ap.r2, 0.5) << seed;
    EXPECT_NE(ap.wavelet, "none");  // de-noised with the automatically selected wavelet
  }
}

TEST(PatientPopulation, TheBoneOnTheTableIsTheSurgeryState) {
  pd::PopulationParams params;
  params.cardiac_amplitude_max_mm = 0.2;
  const pd::PopulationPatient p = pd::drawPopulationPatient(5, params);
  const pd::VirtualPatient bone = pd::populationVirtualPatient(5, p);
  EXPECT_EQ(bone.volunteer_id, 0);
  EXPECT_DOUBLE_EQ(bone.q1_ap_mm_per_ml, p.identificationSlope() * p.surgery.gain);
  EXPECT_DOUBLE_EQ(bone.lag_s, std::max(0.0, p.identificationLag() + p.surgery.lag_change_s));
  EXPECT_EQ(bone.cardiac_mm, p.surgery.cardiac_mm);
  EXPECT_EQ(bone.delivered_volume_cv, params.delivered_volume_cv);
  EXPECT_EQ(bone.delivered_volume_bias, p.surgery.delivered_volume_bias);
  // The cardiac component is in the displacement: at zero volume, over one heartbeat.
  pd::VirtualPatient still = bone;
  still.drift_mm = 0.0;
  still.movements.clear();
  double low = 1e9, high = -1e9;
  const double beat = 60.0 / bone.heart_rate_bpm;
  for (double t = 0.0; t < beat; t += beat / 100.0) {
    low = std::min(low, still.apDisplacementMm(0.0, t));
    high = std::max(high, still.apDisplacementMm(0.0, t));
  }
  EXPECT_NEAR(high - low, 2.0 * bone.cardiac_mm, 0.01 * bone.cardiac_mm + 1e-9);
}

TEST(PatientPopulation, DeliveredVolumeVariesBreathByBreath) {
  EXPECT_EQ(pd::deliveredVolumeFactor(9, 3, 0.0), 1.0);
  std::vector<double> f;
  for (long k = 0; k < 4000; ++k) f.push_back(pd::deliveredVolumeFactor(9, k, 0.02));
  EXPECT_NEAR(mean(f), 1.0, 0.002);
  EXPECT_NEAR(sd(f), 0.02, 0.002);
  EXPECT_EQ(pd::deliveredVolumeFactor(9, 17, 0.02), f[17]);  // a function of (seed, breath)
  EXPECT_NE(pd::deliveredVolumeFactor(10, 17, 0.02), f[17]);
}
