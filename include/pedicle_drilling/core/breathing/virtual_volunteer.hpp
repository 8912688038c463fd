/**
 * @file virtual_volunteer.hpp
 * @brief Virtual volunteers: synthetic recordings of spontaneous breathing (tidal volume at
 *        64 Hz) and T12 skin-marker displacement (AP / SI / LR at 8 Hz), as in paper Sec. III-A,
 *        with known ground-truth model coefficients; plus the recording CSV files.
 *
 * ---------------------------------------------------------------------------------------------
 * CSV convention (files written by writeRecordingCsv(), read by readRecordingCsv()):
 *   <name>.csv        header `t,tv,ap,si,lr`, one row per 8 Hz marker sample. `tv` is the 64 Hz
 *                     tidal volume linearly interpolated to the marker time (the identification
 *                     needs paired samples). Units: t s, tv ml, ap/si/lr mm.
 *   <name>_tv64.csv   header `t,tv`, the raw 64 Hz tidal-volume stream (s, ml).
 * Every cell is a finite number (no NaN, no missing-sample markers): each file holds one rate.
 * Columns are found by header name (any order, extra columns ignored). The reader rejects, with
 * a RecordingFormatError subclass naming the problem: a missing required column, a row with the
 * wrong number of fields or a non-numeric cell, NaN/inf, non-increasing time, and a recording
 * with fewer than two breaths (counted from tv by countBreaths()).
 * ---------------------------------------------------------------------------------------------
 *
 * Generator (generateVolunteer()), all choices physically motivated, not tuned to Table II:
 *  - Breathing: breath-by-breath total time Ttot_i = 60/f (1 + cv_f e_i) and tidal volume
 *    VT_i = VT (1 + cv_VT u_i), with e, u AR(1) unit-variance sequences of lag-1 coefficient
 *    0.3 (breath components are correlated over ~3 breaths: Am J Respir Crit Care Med
 *    1995;152:1967-76). Breath-to-breath CVs of 10-18 % are used: Tobin et al., J Appl Physiol
 *    65:309-317, 1988, report CV(f) 20.8 % and CV(VT) 33 % over 15 min of unconstrained
 *    breathing in 65 healthy subjects (young subjects: CV(f) 16 %, CV(VT) 22 %); the paper's
 *    30 s windows of instructed regular breathing are taken at the lower end. Rate about 20/min
 *    (paper Sec. III-A), VT about 500 ml (resting tidal volume), Ti/Ttot about 0.4 (Tobin et al.
 *    Chest 84:202-205, 1983: Ti/Ttot 0.42 in normal subjects). Each volunteer has its own
 *    pattern (Benchetrit, Respir Physiol 122:123-129, 2000: individuality of breathing pattern).
 *  - Flow shape: Tv rises as VT (3s^2 - 2s^3) over Ti (symmetric inspiratory flow) and falls as
 *    VT (1-s)^3 (1+3s) over Te (expiratory flow peaking at Te/3, as in passive expiration); both
 *    have zero flow at the phase ends, so Tv and dTv/dt are continuous and every breath returns
 *    to the end-expiratory level (no volume drift). Flow-sensor noise is white, default 3 ml.
 *  - Displacement truth: the hysteresis model d = q1 Tv + q2 dTv/dt + q0 with q2 = -q1 tau,
 *    i.e. the marker lags the volume by tau. Respiratory hysteresis of thoracic structures is
 *    documented (Seppenwoolde et al., Int J Radiat Oncol Biol Phys 53:822-834, 2002), but no
 *    source gives the lag between a flow sensor and a T12 skin marker in prone subjects, so
 *    tau = 0.06-0.14 s is an assumption: a visible but small loop (phase 7-17 deg at 20/min),
 *    in keeping with the paper's observation that a line in Tv fits well (Fig. 14).
 *    Peak-to-peak amplitudes per mean breath about 5 / 2 / 1 mm AP / SI / LR (paper Sec. V-B):
 *    q1 = amplitude / VT.
 *  - Tracker noise: NDI Polaris (Vicra / Spectra) volumetric accuracy 0.25 mm RMS (NDI technical
 *    specification). Taken as isotropic per marker (0.25 / sqrt(3) per axis) and doubled in
 *    variance because the displacement is Marker 1 relative to the reference Marker 2 (paper
 *    Fig. 4): sigma_axis = 0.25 sqrt(2/3) = 0.204 mm, scaled 0.8-1.0 per volunteer (marker
 *    distance / pose).
 *  - Slow drift (skin / soft-tissue creep, tracker warm-up): a ramp plus a slow sinusoid (period
 *    40-90 s), 0.1-0.3 mm over the recording.
 *  - Small patient movements: Poisson events (about 2 per minute), each a smoothed step (weight
 *    shift, persists) or bump (returns after 1-3 s), zero-mean Gaussian sizes per axis; largest
 *    in LR (0.25 mm), because the paper attributes the LR displacement mainly to small movements
 *    shifting the patient's weight centre (Sec. V-B). The LR axis therefore has the lowest
 *    signal-to-noise ratio (smallest amplitude, same tracker noise, largest movements).
 */
#pragma once

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "pedicle_drilling/core/breathing/identification.hpp"
#include "pedicle_drilling/core/breathing/motion_model.hpp"

namespace pedicle_drilling::core {

/** @brief A recording: tidal volume at 64 Hz and marker displacement at 8 Hz. */
struct Recording {
  std::vector<double> t_tv;    ///< tidal-volume sample times, s
  std::vector<double> tv;      ///< tidal volume, ml
  std::vector<double> t_disp;  ///< marker sample times, s
  std::vector<double> ap;      ///< AP displacement, mm
  std::vector<double> si;      ///< SI displacement, mm
  std::vector<double> lr;      ///< LR displacement, mm
};

/** @brief Displacement samples paired with tidal volume at the marker times (the 8 Hz CSV). */
struct PairedSamples {
  std::vector<double> t;   ///< s
  std::vector<double> tv;  ///< ml
  std::vector<double> ap;  ///< mm
  std::vector<double> si;  ///< mm
  std::vector<double> lr;  ///< mm

  /** @brief Displacement column of one axis. */
  const std::vector<double>& axis(Axis a) const;
};

/** @brief Parameters of one virtual volunteer (see file doc for the sources). */
struct VolunteerParams {
  int id = 0;                           ///< volunteer id
  std::uint64_t seed = 0;               ///< std::mt19937_64 seed of all random parts
  double duration_s = 30.0;             ///< recording length (paper: about 30 s)
  double tv_rate_hz = 64.0;             ///< flow-sensor rate (paper)
  double disp_rate_hz = 8.0;            ///< tracker rate (paper)
  double breaths_per_min = 20.0;        ///< mean spontaneous rate
  double rate_cv = 0.12;                ///< breath-to-breath CV of the breath duration
  double tidal_volume_ml = 500.0;       ///< mean tidal volume
  double tidal_volume_cv = 0.15;        ///< breath-to-breath CV of the tidal volume
  double breath_autocorrelation = 0.3;  ///< lag-1 correlation of breath components
  double ti_over_ttot = 0.42;           ///< inspiratory fraction of a breath
  double tv_noise_ml = 3.0;             ///< flow-sensor (integrated volume) white noise, ml
  MotionModel truth;                    ///< hysteresis-model truth per axis (q1, q2, q0)
  std::array<double, 3> tracker_noise_mm{{0.2, 0.2, 0.2}};  ///< white noise sigma per axis
  std::array<double, 3> drift_mm{{0.2, 0.2, 0.2}};          ///< drift amplitude per axis
  double movements_per_min = 2.0;                           ///< Poisson rate of movements
  std::array<double, 3> movement_mm{{0.1, 0.1, 0.25}};      ///< movement size sigma per axis

  /** @brief Same volunteer with no tracker / flow noise, no drift and no movements. */
  VolunteerParams noiseFree() const;
};

/** @brief Output of the generator: the noisy recording plus the clean ground truth. */
struct VolunteerData {
  VolunteerParams params;           ///< the parameters used (truth coefficients inside)
  Recording recording;              ///< what the sensors would record
  Recording clean;                  ///< noise-, drift- and movement-free signals
  std::vector<double> dtv_dt;       ///< analytic dTv/dt at t_tv, ml/s
  std::vector<double> dtv_dt_disp;  ///< analytic dTv/dt at t_disp, ml/s
  int num_breaths = 0;              ///< countBreaths() of the recorded tv at the marker times
};

/**
 * @brief A small patient movement: a raised-cosine transition of `ramp` seconds starting at
 *        `t`, either a step that persists (`hold` < 0) or a bump that returns after `hold` s.
 */
struct PatientMovement {
  double t = 0.0;                         ///< onset [s]
  double ramp = 0.5;                      ///< transition time [s]
  double hold = -1.0;                     ///< < 0: step; else time held before returning [s]
  std::array<double, 3> size{{0, 0, 0}};  ///< displacement per axis (AP, SI, LR) [mm]
};

/** @brief Sum of the movements' displacement along `axis` (0 AP, 1 SI, 2 LR) at time t [mm]. */
double movementDisplacementMm(const std::vector<PatientMovement>& movements, int axis, double t);

/** @brief Parameters of the default volunteers, ids 1..5 (fixed seeds); throws otherwise. */
VolunteerParams defaultVolunteer(int id);

/** @brief Generates a volunteer's recording deterministically from its parameters. */
VolunteerData generateVolunteer(const VolunteerParams& params);

/** @brief Pairs a recording at the marker times (tv linearly interpolated from 64 Hz). */
PairedSamples pairAtMarkerTimes(const Recording& recording);

/**
 * @brief Samples of one axis for identification: Tv, dTv/dt (central differences on the paired
 *        tv at the marker times, see timeDerivative()) and the displacement.
 */
AxisSamples axisSamples(const PairedSamples& paired, Axis axis);

/**
 * @brief Number of breaths in a tidal-volume signal: inspirations that rise from below
 *        P5 + 0.25 (P95 - P5) to above P5 + 0.5 (P95 - P5), P = percentiles of tv (hysteresis
 *        thresholds: robust to sensor noise and to breath-to-breath depth changes).
 */
int countBreaths(const std::vector<double>& tv);

/** @brief Base of all recording-file errors. */
class RecordingFormatError : public std::runtime_error {
 public:
  /** @brief Error with a message naming the file and the problem. */
  explicit RecordingFormatError(const std::string& what) : std::runtime_error(what) {}
};
/** @brief Missing file, missing header or a required column absent. */
class MissingColumnError : public RecordingFormatError {
  using RecordingFormatError::RecordingFormatError;
};
/** @brief Wrong field count or a cell that is not a number. */
class MalformedRowError : public RecordingFormatError {
  using RecordingFormatError::RecordingFormatError;
};
/** @brief NaN or infinite cell. */
class NonFiniteValueError : public RecordingFormatError {
  using RecordingFormatError::RecordingFormatError;
};
/** @brief Time column not strictly increasing. */
class NonIncreasingTimeError : public RecordingFormatError {
  using RecordingFormatError::RecordingFormatError;
};
/** @brief Fewer than two breaths in the tidal-volume column. */
class TooFewBreathsError : public RecordingFormatError {
  using RecordingFormatError::RecordingFormatError;
};

/** @brief Path of the 64 Hz companion file: "<stem>_tv64.csv" for "<stem>.csv". */
std::string tv64PathFor(const std::string& csv_path);

/**
 * @brief Writes `<csv_path>` (8 Hz, t,tv,ap,si,lr) and tv64PathFor(csv_path) (64 Hz, t,tv),
 *        17 significant digits. @throws std::runtime_error when a file cannot be written.
 */
void writeRecordingCsv(const Recording& recording, const std::string& csv_path);

/** @brief Reads and validates an 8 Hz `t,tv,ap,si,lr` CSV (see file doc). */
PairedSamples readRecordingCsv(const std::string& csv_path);

/** @brief Reads and validates a 64 Hz `t,tv` CSV; returns {t, tv}. */
std::array<std::vector<double>, 2> readTv64Csv(const std::string& csv_path);

}  // namespace pedicle_drilling::core
