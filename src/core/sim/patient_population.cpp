#include "pedicle_drilling/core/sim/patient_population.hpp"

#include <algorithm>
#include <cmath>

#include "pedicle_drilling/core/sim/normal_source.hpp"

namespace pedicle_drilling::core {

namespace {

constexpr double kTwoPi = 6.28318530717958647692;

/** @brief splitmix64's finaliser: a well-mixed stream key of (seed, salt). */
std::uint64_t mix(std::uint64_t seed, std::uint64_t salt) {
  std::uint64_t z = seed + salt * 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

/** @brief A standard normal truncated at +-limit (resampled). */
double truncatedNormal(NormalSource* src, double limit = 3.0) {
  for (int i = 0; i < 100; ++i) {
    const double z = src->normal();
    if (std::abs(z) <= limit) return z;
  }
  return 0.0;
}

/** @brief mean + sd z, truncated to [lo, hi] by resampling z. */
double boundedNormal(NormalSource* src, double mean, double sd, double lo, double hi) {
  for (int i = 0; i < 100; ++i) {
    const double x = mean + sd * src->normal();
    if (x >= lo && x <= hi) return x;
  }
  return std::clamp(mean, lo, hi);
}

}  // namespace

const ParamTable<PopulationParams>& PopulationParams::table() {
  static const ParamTable<PopulationParams> t = [] {
    using P = PopulationParams;
    ParamTable<P> d;
    d.flag("enabled", &P::enabled)
        .number("ap_amplitude_median_mm", &P::ap_amplitude_median_mm, Range::closed(0.1, 20), "mm")
        .number("ap_amplitude_sigma_ln", &P::ap_amplitude_sigma_ln, Range::closed(0, 1.5))
        .number("si_over_ap", &P::si_over_ap, Range::closed(0, 2))
        .number("lr_over_ap", &P::lr_over_ap, Range::closed(0, 2))
        .number("lag_mean_s", &P::lag_mean_s, Range::closed(0, 0.4), "s")
        .number("lag_sd_s", &P::lag_sd_s, Range::closed(0, 0.2), "s")
        .number("drift_median_mm", &P::drift_median_mm, Range::closed(0, 2), "mm")
        .number("drift_sigma_ln", &P::drift_sigma_ln, Range::closed(0, 1.5))
        .number("movements_per_min_max", &P::movements_per_min_max, Range::closed(0, 10), "/min")
        .number("spontaneous_rate_mean_bpm", &P::spontaneous_rate_mean_bpm, Range::closed(8, 25),
                "breaths/min")
        .number("spontaneous_rate_sd_bpm", &P::spontaneous_rate_sd_bpm, Range::closed(0, 8),
                "breaths/min")
        .number("spontaneous_rate_cv_mean", &P::spontaneous_rate_cv_mean, Range::closed(0.05, 0.4))
        .number("spontaneous_rate_cv_sd", &P::spontaneous_rate_cv_sd, Range::closed(0, 0.2))
        .number("spontaneous_volume_cv_mean", &P::spontaneous_volume_cv_mean,
                Range::closed(0.05, 0.5))
        .number("spontaneous_volume_cv_sd", &P::spontaneous_volume_cv_sd, Range::closed(0, 0.2))
        .number("spontaneous_tidal_volume_mean_ml", &P::spontaneous_tidal_volume_mean_ml,
                Range::closed(300, 800), "ml")
        .number("spontaneous_tidal_volume_sd_ml", &P::spontaneous_tidal_volume_sd_ml,
                Range::closed(0, 300), "ml")
        .number("gain_change_sigma_ln", &P::gain_change_sigma_ln, Range::closed(0, 1))
        .number("lag_change_sd_s", &P::lag_change_sd_s, Range::closed(0, 0.2), "s")
        .number("delivered_volume_cv", &P::delivered_volume_cv, Range::closed(0, 0.2))
        .number("delivered_volume_bias_sd", &P::delivered_volume_bias_sd, Range::closed(0, 0.1))
        .number("cardiac_amplitude_max_mm", &P::cardiac_amplitude_max_mm, Range::closed(0, 2), "mm")
        .number("heart_rate_mean_bpm", &P::heart_rate_mean_bpm, Range::closed(50, 100), "beats/min")
        .number("heart_rate_sd_bpm", &P::heart_rate_sd_bpm, Range::closed(0, 30), "beats/min")
        .number("max_stroke_mm", &P::max_stroke_mm, Range::closed(1, 20), "mm");
    return d;
  }();
  return t;
}

void PopulationParams::validate() const { table().validate(*this); }

double PopulationPatient::identificationSlope() const {
  return identification.truth.axis(Axis::kAP).q1;
}

double PopulationPatient::identificationLag() const {
  return identification.truth.axis(Axis::kAP).lagSeconds();
}

PopulationPatient drawPopulationPatient(std::uint64_t seed, const PopulationParams& p) {
  p.validate();
  // One stream of the whole seed; every deviate is drawn whatever its spread, so that changing
  // one distribution never changes another draw of the same seed.
  NormalSource src(mix(seed, 0x706f70756c617469ULL));  // "populati"
  const double z_amplitude = truncatedNormal(&src);
  const double lag = boundedNormal(&src, p.lag_mean_s, p.lag_sd_s, 0.0, 0.4);
  const double z_drift = truncatedNormal(&src);
  const double u_movements = src.uniformOpen();
  const double rate =
      boundedNormal(&src, p.spontaneous_rate_mean_bpm, p.spontaneous_rate_sd_bpm, 8.0, 25.0);
  const double vt = boundedNormal(&src, p.spontaneous_tidal_volume_mean_ml,
                                  p.spontaneous_tidal_volume_sd_ml, 300.0, 800.0);
  const double z_gain = truncatedNormal(&src);
  const double z_lag_change = truncatedNormal(&src);
  const double u_cardiac = src.uniformOpen();
  const double heart_rate =
      boundedNormal(&src, p.heart_rate_mean_bpm, p.heart_rate_sd_bpm, 50.0, 100.0);
  const double u_cardiac_phase = src.uniformOpen();
  const double u_sign = src.uniformOpen();
  const double rate_cv =
      boundedNormal(&src, p.spontaneous_rate_cv_mean, p.spontaneous_rate_cv_sd, 0.05, 0.4);
  const double volume_cv =
      boundedNormal(&src, p.spontaneous_volume_cv_mean, p.spontaneous_volume_cv_sd, 0.05, 0.5);
  const double z_bias = truncatedNormal(&src);

  PopulationPatient patient;
  VolunteerParams& v = patient.identification;
  v.id = 0;
  v.seed = mix(seed, 0x7265636f7264ULL);  // "record": the recording's own stream
  v.breaths_per_min = rate;
  v.tidal_volume_ml = vt;
  // Breath-to-breath variability of spontaneous breathing (Tobin 1988); the inspiratory fraction
  // of the virtual volunteers (virtual_volunteer.cpp).
  v.rate_cv = rate_cv;
  v.tidal_volume_cv = volume_cv;
  v.ti_over_ttot = 0.42;
  const double ap = p.ap_amplitude_median_mm * std::exp(p.ap_amplitude_sigma_ln * z_amplitude);
  const double amplitudes[3] = {ap, p.si_over_ap * ap,
                                (u_sign < 0.5 ? -1.0 : 1.0) * p.lr_over_ap * ap};
  const double q0s[3] = {0.3, -0.2, 0.1};  // arbitrary tracker zero offsets [mm]
  for (Axis a : kAllAxes) {
    AxisModel& m = v.truth.axis(a);
    const int i = static_cast<int>(a);
    m.kind = ModelKind::kHysteresis;
    m.q1 = amplitudes[i] / 500.0;  // the amplitudes are per 500 ml
    m.q2 = -m.q1 * lag;
    m.q0 = q0s[i];
  }
  // NDI Polaris 0.25 mm RMS (3-D) per marker, relative to a reference marker: 0.25 sqrt(2/3).
  const double sigma = 0.25 * std::sqrt(2.0 / 3.0);
  v.tracker_noise_mm = {{sigma, sigma, sigma}};
  patient.drift_mm = p.drift_median_mm * std::exp(p.drift_sigma_ln * z_drift);
  v.drift_mm = {{patient.drift_mm, patient.drift_mm, patient.drift_mm}};
  v.movements_per_min = p.movements_per_min_max * u_movements;
  v.movement_mm = {{0.10, 0.10, 0.25}};

  SurgeryChange& s = patient.surgery;
  s.gain = std::exp(p.gain_change_sigma_ln * z_gain);
  s.lag_change_s = p.lag_change_sd_s * z_lag_change;
  s.delivered_volume_cv = p.delivered_volume_cv;
  s.delivered_volume_bias = 1.0 + p.delivered_volume_bias_sd * z_bias;
  s.cardiac_mm = p.cardiac_amplitude_max_mm * u_cardiac;
  s.heart_rate_bpm = heart_rate;
  s.cardiac_phase_rad = kTwoPi * u_cardiac_phase;
  return patient;
}

PipelineResult identifyPopulationPatient(const PopulationPatient& patient) {
  const VolunteerData data = generateVolunteer(patient.identification);
  const PairedSamples paired = pairAtMarkerTimes(data.recording);
  PipelineOptions options;    // the paper's pipeline: linear, Ceres, de-noised displacement
  options.denoise_tv = true;  // as the campaign's Table II (table2.py: identify --denoise-tv)
  return identifyPatient(paired, options, "population_patient", "identification recording");
}

double deliveredVolumeFactor(std::uint64_t seed, long breath_index, double cv) {
  if (!(cv > 0.0)) return 1.0;
  NormalSource src(mix(seed ^ 0x627265617468ULL, static_cast<std::uint64_t>(breath_index)));
  return 1.0 + cv * truncatedNormal(&src);
}

}  // namespace pedicle_drilling::core
