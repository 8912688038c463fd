/**
 * @file drilling_simulation.cpp
 * @brief Simulated workcell orchestration (see drilling_simulation.hpp).
 */
#include "pedicle_drilling/core/sim/drilling_simulation.hpp"

#include <urdf_model/model.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>

#include "pedicle_drilling/core/breathing/breath_detector.hpp"
#include "pedicle_drilling/core/breathing/virtual_volunteer.hpp"
#include "pedicle_drilling/core/common/portable_random.hpp"
#include "pedicle_drilling/core/control/drill_guard.hpp"
#include "pedicle_drilling/core/robot/stage_axis.hpp"
#include "pedicle_drilling/core/robot/trajectory_executor.hpp"
#include "pedicle_drilling/core/robot/urdf_model.hpp"
#include "pedicle_drilling/core/sim/normal_source.hpp"

namespace pedicle_drilling::core {

namespace {

constexpr double kPi = 3.14159265358979323846;
// A separation of drill and bone: no contact for this many 1 ms steps (10 ms).
constexpr int kSeparationSteps = 10;
// Points of the bench's SPMS stream per period (every 5 ms at 125 ms): the cubic between them
// is within 1e-9 m of the model's displacement on the expiration's exponential.
constexpr int kBenchPointsPerPeriod = 25;

// The tracker's sample phase of a trial, uniform in [0, 1): its own stream of the seed, so that
// it changes nothing else the seed draws.
double trackerPhaseFraction(std::uint64_t seed) {
  return uniformFromSeed(seed ^ 0x7472616b70686173ULL);
}

// A unit vector uniform on the sphere from two uniform numbers (Archimedes: z uniform).
Eigen::Vector3d unitVector(double u1, double u2) {
  const double z = 2.0 * u1 - 1.0;
  const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
  return {r * std::cos(2.0 * kPi * u2), r * std::sin(2.0 * kPi * u2), z};
}

}  // namespace

Eigen::Isometry3d registrationError(std::uint64_t seed, double translation_mm,
                                    double rotation_deg) {
  // Its own streams of the seed: it changes nothing else the seed draws.
  const Eigen::Vector3d t = unitVector(uniformFromSeed(seed ^ 0x7265677472616e31ULL),
                                       uniformFromSeed(seed ^ 0x7265677472616e32ULL));
  const Eigen::Vector3d axis = unitVector(uniformFromSeed(seed ^ 0x726567726f743031ULL),
                                          uniformFromSeed(seed ^ 0x726567726f743032ULL));
  Eigen::Isometry3d e = Eigen::Isometry3d::Identity();
  e.linear() = Eigen::AngleAxisd(rotation_deg * kPi / 180.0, axis).toRotationMatrix();
  e.translation() = 1e-3 * translation_mm * t;
  return e;
}

namespace {

Eigen::Isometry3d toIsometry(const urdf::Pose& p) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  t.linear() = Eigen::Quaterniond(p.rotation.w, p.rotation.x, p.rotation.y, p.rotation.z)
                   .normalized()
                   .toRotationMatrix();
  return t;
}

Eigen::Isometry3d jointMotion(const urdf::Joint& joint, double q) {
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d axis(joint.axis.x, joint.axis.y, joint.axis.z);
  if (joint.type == urdf::Joint::PRISMATIC) {
    m.translation() = q * axis;
  } else if (joint.type == urdf::Joint::REVOLUTE || joint.type == urdf::Joint::CONTINUOUS) {
    m.linear() = Eigen::AngleAxisd(q, axis.normalized()).toRotationMatrix();
  }
  return m;
}

}  // namespace

double VirtualPatient::apDisplacementMm(double lagged_tv_ml, double t,
                                        double lagged_flow_ml_s) const {
  const double d = q1_ap_mm_per_ml * lagged_tv_ml + q2_ap_mm_s_per_ml * lagged_flow_ml_s +
                   drift_mm * std::sin(2.0 * kPi * t / drift_period_s + drift_phase_rad) +
                   movementDisplacementMm(movements, 0, t);
  if (cardiac_mm == 0.0) return d;
  return d + cardiac_mm * std::sin(2.0 * kPi * heart_rate_bpm / 60.0 * t + cardiac_phase_rad);
}

namespace {

/**
 * @brief A patient of slope q1, lag and drift amplitude, its drift period and phase from the
 *        seed, and small movements at `movements_per_min` (AP size SD `movement_ap_mm` times
 *        `movement_scale`) over the hour after `start_time_s`.
 */
VirtualPatient makeVirtualPatient(std::uint64_t seed, double start_time_s, double movement_scale,
                                  double q1, double lag_s, double drift_mm,
                                  double movements_per_min, double movement_ap_mm) {
  VirtualPatient p;
  p.q1_ap_mm_per_ml = q1;
  p.lag_s = lag_s;
  p.drift_mm = drift_mm;
  std::mt19937_64 rng(seed ^ 0x9e3779b97f4a7c15ULL);
  const double u1 = static_cast<double>(rng() >> 11) * 0x1.0p-53;
  const double u2 = static_cast<double>(rng() >> 11) * 0x1.0p-53;
  p.drift_period_s = 40.0 + 50.0 * u1;  // 40-90 s, as the volunteers' slow drift
  p.drift_phase_rad = 2.0 * kPi * u2;
  // Small movements over the next hour, as generateVolunteer() shapes them: raised-cosine
  // ramps of 0.5-1 s, half persisting steps, half bumps held 1-3 s.
  if (movement_scale > 0.0 && movements_per_min > 0.0) {
    NormalSource mv(seed * 0x9E3779B97F4A7C15ULL + 0x5851F42D4C957F2DULL);
    const double rate_hz = movements_per_min / 60.0;
    double t = start_time_s - std::log(mv.uniformOpen()) / rate_hz;
    while (t < start_time_s + 3600.0) {
      PatientMovement m;
      m.t = t;
      m.ramp = 0.5 + 0.5 * mv.uniformOpen();
      m.hold = mv.uniformOpen() < 0.5 ? -1.0 : 1.0 + 2.0 * mv.uniformOpen();
      m.size[0] = movement_scale * movement_ap_mm * mv.normal();
      p.movements.push_back(m);
      t -= std::log(mv.uniformOpen()) / rate_hz;
    }
  }
  return p;
}

}  // namespace

VirtualPatient drawVirtualPatient(std::uint64_t seed, double start_time_s, double movement_scale) {
  const int id = 1 + static_cast<int>(seed % 5);
  const VolunteerParams v = defaultVolunteer(id);
  const AxisModel& ap = v.truth.axis(Axis::kAP);
  VirtualPatient p = makeVirtualPatient(seed, start_time_s, movement_scale, ap.q1, ap.lagSeconds(),
                                        v.drift_mm[0], v.movements_per_min, v.movement_mm[0]);
  p.volunteer_id = id;
  return p;
}

VirtualPatient populationVirtualPatient(std::uint64_t seed, const PopulationPatient& patient,
                                        double start_time_s, double movement_scale) {
  const VolunteerParams& v = patient.identification;
  VirtualPatient p = makeVirtualPatient(
      seed, start_time_s, movement_scale, patient.identificationSlope() * patient.surgery.gain,
      std::max(0.0, patient.identificationLag() + patient.surgery.lag_change_s), patient.drift_mm,
      v.movements_per_min, v.movement_mm[0]);
  p.volunteer_id = 0;
  p.cardiac_mm = patient.surgery.cardiac_mm;
  p.heart_rate_bpm = patient.surgery.heart_rate_bpm;
  p.cardiac_phase_rad = patient.surgery.cardiac_phase_rad;
  p.delivered_volume_cv = patient.surgery.delivered_volume_cv;
  p.delivered_volume_bias = patient.surgery.delivered_volume_bias;
  return p;
}

std::uint64_t streamPeriodSteps(double physics_rate_hz, double rate_hz, const std::string& name) {
  if (!(std::isfinite(rate_hz) && rate_hz > 0.0 && rate_hz <= physics_rate_hz)) {
    std::ostringstream os;
    os << name << ": must be in (0, " << physics_rate_hz << "] Hz, got " << rate_hz;
    throw std::invalid_argument(os.str());
  }
  return static_cast<std::uint64_t>(std::max(1.0, std::round(physics_rate_hz / rate_hz)));
}

const ParamTable<TrialVariability>& TrialVariability::table() {
  static const ParamTable<TrialVariability> t = [] {
    using V = TrialVariability;
    ParamTable<V> d;
    d.number("patient/amplitude_scale_sd", &V::patient_amplitude_scale_sd, Range::closed(0, 0.3))
        .number("patient/movement_scale", &V::patient_movement_scale, Range::closed(0, 5))
        .number("ventilator/rate_sd_bpm", &V::ventilator_rate_sd_bpm, Range::closed(0, 5),
                "breaths/min")
        .number("ventilator/tidal_volume_sd_ml", &V::ventilator_tidal_volume_sd_ml,
                Range::closed(0, 200), "ml")
        .number("sensor/noise_scale_sd", &V::sensor_noise_scale_sd, Range::closed(0, 0.5))
        .number("arm/stiffness_scale_sd", &V::arm_stiffness_scale_sd, Range::closed(0, 0.3))
        .number("arm/stiffness_scale", &V::arm_stiffness_scale, Range::closed(0.1, 4))
        .number("patient/gain_error", &V::patient_gain_error, Range::closed(0.3, 3))
        .number("patient/lag_error_s", &V::patient_lag_error_s, Range::closed(-0.2, 0.2), "s");
    return d;
  }();
  return t;
}

void TrialVariability::validate() const { table().validate(*this); }

ForceSensorParams DrillingSimulationParams::calibratedSensor() {
  ForceSensorParams p;
  p.output_rate_hz = 1000.0 / 3.0;
  return p;
}

namespace {

/** @brief The controllers' rules (ros_control's by default). */
const ParamTable<ControllerRules>& controllerRulesTable() {
  static const ParamTable<ControllerRules> t = [] {
    using R = ControllerRules;
    ParamTable<R> d;
    d.parsed(
         "controller_rules", {"strict", "lenient"}, "",
         [](const R& r) { return std::string(r.strict ? "strict" : "lenient"); },
         [](R& r, const std::string& x) { r.strict = x == "strict"; })
        .flag("allow_partial_joints_goal", &R::allow_partial_joints_goal)
        .number("stop_trajectory_duration_s", &R::stop_trajectory_duration_s,
                Range::aboveUpTo(0, 10), "s");
    return d;
  }();
  return t;
}

}  // namespace

const ParamTable<DrillingSimulationParams>& DrillingSimulationParams::table() {
  static const ParamTable<DrillingSimulationParams> t = [] {
    using P = DrillingSimulationParams;
    ParamTable<P> d;
    d.number("arm_rate_hz", &P::arm_rate_hz, Range::closed(1, 1000), "Hz")
        .number("arm_rate_in_air_hz", &P::arm_rate_in_air_hz, Range::closed(1, 1000), "Hz")
        .number("arm_air_clearance_m", &P::arm_air_clearance_m, Range::closed(1e-4, 0.1), "m")
        .number("arm_inverse_inertia_tolerance", &P::arm_inverse_inertia_tolerance,
                Range::closed(0, 0.01), "rad or m")
        .number("slider_max_speed_m_s", &P::slider_max_speed_m_s, Range::aboveUpTo(0, 1), "m/s")
        .number("slider_max_accel_m_s2", &P::slider_max_accel_m_s2, Range::aboveUpTo(0, 100),
                "m/s^2")
        .number("slider_bandwidth_hz", &P::slider_bandwidth_hz, Range::aboveUpTo(0, 500), "Hz")
        .number("feed_max_accel_m_s2", &P::feed_max_accel_m_s2, Range::aboveUpTo(0, 100), "m/s^2")
        .number("feed_bandwidth_hz", &P::feed_bandwidth_hz, Range::aboveUpTo(0, 500), "Hz")
        .number("bench_period_s", &P::bench_period_s, Range::closed(0.01, 1), "s")
        .number("spindle_accel_rpm_s", &P::spindle_accel_rpm_s, Range::aboveUpTo(0, 1e6), "rpm/s")
        .number("spindle_watchdog_s", &P::spindle_watchdog_s, Range::closed(0, 10), "s")
        .number("drive_guard_timeout_s", &P::drive_guard_timeout_s, Range::closed(0, 1), "s")
        .number("tracker_noise_rms_mm", &P::tracker_noise_rms_mm, Range::closed(0, 10), "mm")
        .number("registration_error_mm", &P::registration_error_mm, Range::closed(0, 10), "mm")
        .number("registration_error_deg", &P::registration_error_deg, Range::closed(0, 5), "deg")
        .number("breath_sensor_rate_hz", &P::breath_sensor_rate_hz, Range::closed(0, 1000), "Hz")
        .number("breath_trigger_flow_ml_s", &P::breath_trigger_flow_ml_s, Range::closed(0, 2000),
                "ml/s")
        .number("breath_sensor_latency_s", &P::breath_sensor_latency_s, Range::closed(0, 0.5), "s")
        .number("breath_clock_offset_s", &P::breath_clock_offset_s, Range::closed(-0.1, 0.1), "s")
        .number("arm_clock_offset_s", &P::arm_clock_offset_s, Range::closed(-10, 10), "s")
        .number("arm_clock_drift_ppm", &P::arm_clock_drift_ppm, Range::closed(-1000, 1000), "ppm")
        .number(
            "force_noise_sd_n", [](const P& v) { return v.sensor.force_noise_sd_n; },
            [](P& v, double x) { v.sensor.force_noise_sd_n = x; }, Range::closed(0, 10), "N")
        .number(
            "force_sensor_rate_hz", [](const P& v) { return v.sensor.output_rate_hz; },
            [](P& v, double x) { v.sensor.output_rate_hz = x; }, Range::aboveUpTo(0, 1000), "Hz")
        .number(
            "force_antialias_cutoff_hz", [](const P& v) { return v.sensor.antialias_cutoff_hz; },
            [](P& v, double x) { v.sensor.antialias_cutoff_hz = x; }, Range::fromBelow(0, 500),
            "Hz")
        .integer(
            "force_antialias_order",
            [](const P& v) { return static_cast<double>(v.sensor.antialias_order); },
            [](P& v, double x) { v.sensor.antialias_order = static_cast<int>(x); },
            Range::closed(1, 8))
        .number(
            "force_resolution_n", [](const P& v) { return v.sensor.force_resolution_n; },
            [](P& v, double x) { v.sensor.force_resolution_n = x; }, Range::closed(0, 1), "N")
        .number(
            "contact_stiffness_n_per_m",
            [](const P& v) { return v.drill.contact_stiffness_n_per_m; },
            [](P& v, double x) { v.drill.contact_stiffness_n_per_m = x; },
            Range::aboveUpTo(0, std::numeric_limits<double>::infinity()), "N/m")
        .number(
            "chisel_edge_share", [](const P& v) { return v.drill.chisel_edge_share; },
            [](P& v, double x) { v.drill.chisel_edge_share = x; }, Range::closed(0, 0.9))
        .number(
            "thrust_coefficient_n_per_m",
            [](const P& v) { return v.drill.thrust_coefficient_n_per_m; },
            [](P& v, double x) { v.drill.thrust_coefficient_n_per_m = x; },
            Range::aboveUpTo(0, 1e5), "N/m")
        .number(
            "feed_exponent", [](const P& v) { return v.drill.feed_exponent; },
            [](P& v, double x) { v.drill.feed_exponent = x; }, Range::closed(0, 1))
        .number(
            "speed_exponent", [](const P& v) { return v.drill.speed_exponent; },
            [](P& v, double x) { v.drill.speed_exponent = x; }, Range::closed(0, 1))
        .number(
            "spindle_vibration_axial_n",
            [](const P& v) { return v.sensor.spindle_vibration_axial_n; },
            [](P& v, double x) { v.sensor.spindle_vibration_axial_n = x; }, Range::closed(0, 5),
            "N")
        .number(
            "spindle_vibration_speed_exponent",
            [](const P& v) { return v.sensor.spindle_vibration_speed_exponent; },
            [](P& v, double x) { v.sensor.spindle_vibration_speed_exponent = x; },
            Range::closed(0, 4))
        .number(
            "force_drift_n_per_sqrt_s",
            [](const P& v) { return v.sensor.force_drift_n_per_sqrt_s; },
            [](P& v, double x) { v.sensor.force_drift_n_per_sqrt_s = x; }, Range::closed(0, 0.1),
            "N/sqrt(s)")
        .flag("moving_bone", &P::moving_bone)
        .flag("sensor_tared_at_reset", &P::sensor_tared_at_reset)
        .number("sensor_bias_offset_n", &P::sensor_bias_offset_n, Range::closed(-50, 50), "N")
        .include(ControllerLayoutParams::table(), &P::controllers)
        .include(controllerRulesTable(), &P::controller_rules)
        .include(VentilatorSettings::table(), &P::ventilator, "ventilator/")
        .include(SpecimenDistribution::table(), &P::specimen, "trial_distribution/specimen/")
        .include(PlanImagingParams::table(), &P::plan, "plan/")
        .include(TrialVariability::table(), &P::variability, "trial_distribution/")
        .include(PopulationParams::table(), &P::population, "population/");
    return d;
  }();
  return t;
}

namespace {

/** @brief Throws, naming the parameter, unless @p rate_hz divides the physics rate. */
void requireDividesPhysicsRate(double physics_rate_hz, double rate_hz, const std::string& name,
                               const std::string& examples) {
  const double ratio = physics_rate_hz / rate_hz;
  if (std::abs(ratio - std::round(ratio)) > 1e-9) {
    throw std::invalid_argument(name + " must divide the " + Range::format(physics_rate_hz) +
                                " Hz physics rate (e.g. " + examples + ")");
  }
}

}  // namespace

void DrillingSimulationParams::validate() const {
  table().validate(*this);
  requireDividesPhysicsRate(physics_rate_hz, arm_rate_hz, "arm_rate_hz", "1000, 500, 250");
  requireDividesPhysicsRate(physics_rate_hz, arm_rate_in_air_hz, "arm_rate_in_air_hz",
                            "1000, 500, 250");
  requireDividesPhysicsRate(physics_rate_hz, sensor.output_rate_hz, "force_sensor_rate_hz",
                            "1000, 500, 250, 100");
  ventilator.validate();
  specimen.validate();
  variability.validate();
  plan.validate();
}

TrialConditions drawTrialConditions(std::uint64_t seed, const TrialVariability& variability,
                                    const VentilatorSettings& ventilator, double force_noise_sd_n) {
  variability.validate();
  // Own stream (not the specimen's, sensor's or tracker's): changing a spread never changes
  // the other draws of the same seed. Every deviate is drawn whatever its SD, for the same
  // reason; each is truncated at +-3 SD by resampling.
  NormalSource src(seed * 0x2545F4914F6CDD1DULL + 0x632BE59BD9B4E019ULL);
  auto truncated = [&src]() {
    for (int i = 0; i < 100; ++i) {
      const double z = src.normal();
      if (std::abs(z) <= 3.0) return z;
    }
    return 0.0;
  };
  const double z_amplitude = truncated();
  const double z_rate = truncated();
  const double z_volume = truncated();
  const double z_noise = truncated();
  const double z_stiffness = truncated();
  TrialConditions c;
  c.volunteer_id = 1 + static_cast<int>(seed % 5);
  c.patient_amplitude_scale = 1.0 + variability.patient_amplitude_scale_sd * z_amplitude;
  // Bounded below so that a wide spread cannot produce a non-physical ventilator setting.
  c.ventilator_rate_bpm =
      std::max(1.0, ventilator.rate_bpm + variability.ventilator_rate_sd_bpm * z_rate);
  c.ventilator_tidal_volume_ml =
      std::max(10.0, ventilator.tv_max_ml + variability.ventilator_tidal_volume_sd_ml * z_volume);
  c.force_noise_sd_n = force_noise_sd_n * (1.0 + variability.sensor_noise_scale_sd * z_noise);
  c.arm_stiffness_scale =
      variability.arm_stiffness_scale * (1.0 + variability.arm_stiffness_scale_sd * z_stiffness);
  return c;
}

SpmsGeometry DrillingSimulationParams::urdfSpmsGeometry() {
  SpmsGeometry g;
  g.base_radius_m = 0.10;      // lead screws at 0.12 m, rod pivot 0.02 m inboard
  g.platform_radius_m = 0.04;  // spherical joints on the platform
  g.rod_length_m = 0.12;
  g.rail_inclination_deg = 0.0;
  g.slider_min_m = 0.05;   // slider joint 0 (+0.05 m offset)
  g.slider_max_m = 0.25;   // slider joint 0.20
  g.home_slider_m = 0.15;  // slider joint 0.10 (nominal)
  g.leg_azimuth_offset_deg = 90.0;
  g.max_spherical_tilt_deg = 45.0;  // rods sit at 30 deg to the normal at home
  return g;
}

// ------------------------------------------------------------------------------------------

struct DrillingSimulation::Impl {
  ComponentProfile* profile = nullptr;  ///< setProfile()
  DrillingSimulationParams params;
  std::shared_ptr<const urdf::ModelInterface> model;  // shared: parseUrdfKept
  std::unique_ptr<BulletArm> arm;
  SpmsKinematics spms;
  BreathScheduler ventilator;
  BreathScheduler lagged_ventilator;  // same settings, sampled at t - lag (patient hysteresis)

  /**
   * New settings from the ventilator's next breath, for the patient with the same breath: the
   * patient's breathing is the ventilator's sampled lag_s late, so a request in the first lag_s
   * of a breath must not reach the patient a breath before the ventilator (and its settings
   * stream) has them.
   */
  void requestBreathing(const VentilatorSettings& settings) {
    const long from_breath = ventilator.breathIndex() + 1;
    ventilator.requestSettings(settings, from_breath);
    lagged_ventilator.requestSettings(settings, from_breath);
  }

  VirtualPatient patient;
  std::unique_ptr<DrillingProcess> process;
  std::unique_ptr<ForceSensor> sensor;
  std::mt19937_64 tracker_rng;
  double tracker_phase = 0.0;  // fraction of a tracker period, drawn per trial
  // Separations since the trial started: contact lost for at least kSeparationSteps steps
  // (10 ms, two revolutions at 12000 rpm), so that the lips' step-to-step chatter at first
  // contact is not counted as the drill leaving the bone.
  bool was_in_contact = false;
  int steps_without_contact = 0;
  std::uint32_t contact_losses = 0;

  int steps_per_arm_block = 4;
  int steps_per_air_block = 4;        // in air, clear of the bone (arm_rate_in_air_hz)
  int block_steps = 4;                // the block under way
  int block_phase = 0;                // its next step, 0 = a new block
  double block_decision_depth = 0.0;  // tip_depth when the last block was chosen
  std::uint64_t air_blocks = 0;
  double dt = 1e-3;
  std::uint64_t step_index = 0;
  // The sensed breath start (breath_sensor_rate_hz): the flow sensor's period in steps (0: off),
  // the detector on its samples (the Ventilator nodelet's `flow` source runs the same one), the
  // last breath detected and its start on the pipeline's clock.
  // A detection reaches the pipeline breath_sensor_latency_s later, stamped on its arrival.
  std::uint64_t breath_sensor_period = 0;
  std::optional<BreathStartDetector> breath_detector;
  bool breath_flow_sampled = false;  // this step took a flow-sensor sample (vent_now's flow)
  long detected_breath_index = -1;
  double detection_arrives = std::numeric_limits<double>::infinity();
  long sensed_breath_index = -1;
  double sensed_breath_start = 0.0;

  /**
   * @brief On a flow-sensor sample: a breath not yet detected whose flow passed the trigger is
   *        detected; a detection whose latency has passed becomes the sensed start.
   */
  void senseBreath() {
    breath_flow_sampled = breath_sensor_period != 0 && step_index % breath_sensor_period == 0;
    if (breath_sensor_period == 0) return;
    // The sensor's stream starts with breath 0, so the detector is armed at its start; every
    // breath's inspiration is one run of samples above the trigger and its expiration (negative
    // flow) re-arms it: the first sample of a breath above the trigger, as before the detector.
    if (breath_flow_sampled &&
        breath_detector->add(time, vent_now.flow_ml_s) == FlowSampleStatus::kBreathStart) {
      detected_breath_index = ventilator.breathIndex();
      detection_arrives = time + params.breath_sensor_latency_s;
    }
    if (time >= detection_arrives - 1e-9) {
      sensed_breath_index = detected_breath_index;
      sensed_breath_start = detection_arrives + params.breath_clock_offset_s;
      detection_arrives = std::numeric_limits<double>::infinity();
    }
  }
  double time = 0.0;
  std::uint64_t seed = 1;
  bool moving_bone = true;
  // Fault injection: factor on the patient's AP displacement (1 after every reset).
  double amplitude_factor = 1.0;

  std::vector<std::string> arm_joints;
  std::vector<std::string> commandable;
  std::vector<int> commandable_index;    // index in arm joints
  Eigen::VectorXd block_pos, block_vel;  // advanceArmBlock's targets (kept: no allocation)
  Eigen::VectorXd block_q0, block_q1;    // the references at the block's ends (kept)
  std::vector<TrajectoryState> samples;  // a trajectory sample per controller (kept storage)
  std::vector<int> spindle_index;        // the spindle joint's index in arm joints (one entry)
  Eigen::VectorXd home;                  // all arm joints

  // The arm's controllers (params.controllers), each with its trajectory (JointTrajectory-
  // Controller rules) and, per joint, the index in the commandable joints.
  std::vector<ControllerSpec> controller_specs;
  std::vector<std::unique_ptr<JointTrajectoryExecutor>> controller_trajectories;
  std::vector<std::vector<int>> controller_columns;
  Eigen::VectorXd reference_q;  // reference()'s output (kept: no allocation)
  // The feed joint's drive (index in the commandable joints, -1: none in the chain), and the
  // controller and the column in it that own the feed joint.
  int feed_index = -1;
  std::size_t feed_controller = 0;
  int feed_column = -1;
  // Drive faults (setJointStalled): per commandable joint, its drive holds where it is.
  std::vector<bool> stalled;
  StageAxis feed_drive;
  // The displacement model the bone plays from the next reset on (none: virtual patient).
  std::optional<BoneMotionModel> bone_motion_model;
  // The joint controllers' position setpoint: the commanded reference, moved at most at each
  // joint's URDF velocity limit per arm block (a real controller never outruns its limits).
  Eigen::VectorXd servo_ref;

  // Spindle.
  double spindle_cmd_rpm = 0.0;
  double spindle_rpm = 0.0;
  double spindle_cmd_t = 0.0;      // sim time of the latest accepted speed command
  ForceTare tare;                  // the sensor driver's tare (requestTare)
  int spindle_watchdog_trips = 0;  // the driver's watchdog stopped the spindle
  // The drivers' drill-guard watch (drive_guard_timeout_s > 0), never reset with the specimen:
  // the guard's heartbeat runs across trials.
  std::optional<DriveGuardWatch> drive_guard;
  bool drives_halted = false;
  int drive_guard_trips = 0;

  /** @brief The drill guard's verdict at the physics rate: hold every controller where its
   *         reference is now and stop the spindle once; commands are refused while held. */
  void watchDriveGuard() {
    if (!drive_guard) return;
    const bool allowed = drive_guard->allows(time);
    if (allowed == !drives_halted) return;
    drives_halted = !allowed;
    if (allowed) return;  // commands are taken again; the joints hold until one comes
    ++drive_guard_trips;
    for (std::size_t c = 0; c < controller_trajectories.size(); ++c) holdController(c);
    spindle_cmd_rpm = 0.0;
  }

  /** @brief Controller @p c drops its trajectory and holds where its reference is now. */
  void holdController(std::size_t c) {
    TrajectoryState& st = samples[c];
    controller_trajectories[c]->sample(time, &st);
    controller_trajectories[c]->hold(st.position);
  }
  int controller_aborts = 0;  // abortController() calls

  // SPMS state.
  Eigen::Isometry3d spms_base_world = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d platform_home_in_base = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d bone_in_platform = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d marker_in_platform = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d camera_world = Eigen::Isometry3d::Identity();
  // The camera's true pose: the registered one (camera_world) times the trial's registration
  // error (registrationError).
  Eigen::Isometry3d camera_true_world = Eigen::Isometry3d::Identity();
  Eigen::Vector3d sliders;
  Eigen::Vector3d slider_targets;
  // The sliders' drives (lead-screw servo axes) and, on the paper's bench, the trajectory the
  // SPMS controller streams (slider joints, the SpmsKinematics convention).
  std::array<StageAxis, 3> slider_axes;
  std::unique_ptr<JointTrajectoryExecutor> spms_trajectory;
  TrajectoryState spms_sample;  // kept storage for the SPMS stream's samples
  std::uint64_t bench_period_steps = 125;
  std::uint64_t bench_stream_due = 0;  // 0: stream from now at the next step (after a reset)
  Eigen::Vector3d previous_targets = Eigen::Vector3d::Zero();
  bool have_previous_targets = false;
  PlatformFullPose platform;
  /// platform.rotation(), kept with the pose (updatePlatform sets both from the forward
  /// kinematics' result, whose rotation is the one its last residual computed: the same bits)
  Eigen::Matrix3d platform_rotation = Eigen::Matrix3d::Identity();
  // The rod-length Jacobian the platform's forward kinematics keeps between steps (NaN: none;
  // cleared at every trial's reset, so that the iteration's path does not carry over).
  SpmsFkJacobian platform_jacobian;
  // The sliders of the last forward kinematics, kept when it ended within its 1e-13 m test: the
  // same sliders from that pose pass the test at once and give the same pose, bit for bit, so
  // the solve is skipped (a stationary bench's sliders come to rest). Likewise the
  // inverse of the last heave. Cleared at every reset.
  std::optional<Eigen::Vector3d> converged_sliders;
  // The steps of the platform's last two successful solves (newest first) and the pose before
  // the last: a solve at the step after two consecutive ones starts from their extrapolation
  // (updatePlatform). A reset clears them to step 0, which step_index has passed unless the
  // reset is at step 0, after the constructor's solve there: then step 0 is a real solve of the
  // platform's pose, and steps 1 and 2 extrapolate from it as from any other.
  std::array<std::uint64_t, 2> solved_steps{0, 0};
  PlatformFullPose platform_before;
  std::optional<double> ik_heave;
  SpmsIkResult ik_of_heave;
  double desired_heave = 0.0;
  Eigen::Isometry3d bone_world = Eigen::Isometry3d::Identity();
  Eigen::Vector3d bone_home_world = Eigen::Vector3d::Zero();

  // Arm block interpolation.
  Eigen::Vector3d tip_block_start = Eigen::Vector3d::Zero();
  Eigen::Vector3d tip_block_end = Eigen::Vector3d::Zero();
  Eigen::Vector3d physics_tip = Eigen::Vector3d::Zero();
  Eigen::Vector3d drill_axis = -Eigen::Vector3d::UnitZ();

  // Drilling.
  ForceSample last_force;
  double tip_depth = 0.0;
  double relative_ap0 = 0.0;
  int trial_count = 0;
  VentilatorSample vent_now;
  TrialConditions conditions;
  ImagingPlan imaging_plan;  // the current specimen's plan

  Impl(const DrillingSimulationParams& p)
      : params(p),
        spms(p.spms),
        ventilator(p.ventilator, 0.0),
        lagged_ventilator(p.ventilator, 0.0) {
    if (p.drive_guard_timeout_s > 0.0) {
      drive_guard.emplace(p.drive_guard_timeout_s);
      drives_halted = true;  // fails closed: held until the first enable (not a trip)
    }
  }

  static Eigen::Isometry3d fixedChainPose(const urdf::ModelInterface& m, const std::string& root,
                                          const std::string& link) {
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    urdf::LinkConstSharedPtr l = m.getLink(link);
    if (!l) throw std::runtime_error("DrillingSimulation: URDF has no link '" + link + "'");
    while (l->name != root) {
      if (!l->parent_joint) {
        throw std::runtime_error("DrillingSimulation: URDF link '" + link +
                                 "' does not descend from '" + root + "'");
      }
      t = toIsometry(l->parent_joint->parent_to_joint_origin_transform) * t;
      l = m.getLink(l->parent_joint->parent_link_name);
      if (!l) throw std::runtime_error("DrillingSimulation: broken URDF tree above " + link);
    }
    return t;
  }

  void checkSpmsAgainstUrdf() {
    // The closed chains are not in the URDF; the kinematic model must match its nominal pose.
    spms_base_world = fixedChainPose(*model, params.base_link, "spms_base");
    urdf::JointConstSharedPtr pj = model->getJoint("spms_platform_joint");
    if (!pj) throw std::runtime_error("DrillingSimulation: URDF has no spms_platform_joint");
    platform_home_in_base = toIsometry(pj->parent_to_joint_origin_transform);
    bone_in_platform = fixedChainPose(*model, "spms_platform", "bone");
    marker_in_platform = fixedChainPose(*model, "spms_platform", "tracker_marker");
    camera_world = fixedChainPose(*model, params.base_link, "tracker_camera");
    const double urdf_home = platform_home_in_base.translation().z();
    if (std::abs(urdf_home - spms.homeHeight()) > 1e-5) {
      std::ostringstream os;
      os << "DrillingSimulation: SPMS geometry gives a home platform height of "
         << spms.homeHeight() << " m but the URDF's spms_platform_joint is at " << urdf_home
         << " m";
      throw std::runtime_error(os.str());
    }
    for (int i = 1; i <= 3; ++i) {
      for (const std::string& j :
           {"slider" + std::to_string(i) + "_joint", "rod" + std::to_string(i) + "_joint"}) {
        if (!model->getJoint(j)) {
          throw std::runtime_error("DrillingSimulation: URDF has no SPMS joint '" + j + "'");
        }
      }
      checkSpmsLegAgainstUrdf(i);
    }
  }

  /**
   * Leg i of the URDF against the kinematic model: the rod pivot (slider joint at 0) at the
   * model's base radius and leg azimuth, at the lower end of the slider stroke, and the slider
   * joint's limits spanning the model's stroke.
   */
  void checkSpmsLegAgainstUrdf(int i) {
    const std::string slider = "slider" + std::to_string(i) + "_joint";
    const urdf::JointConstSharedPtr sj = model->getJoint(slider);
    const urdf::JointConstSharedPtr rj = model->getJoint("rod" + std::to_string(i) + "_joint");
    const SpmsGeometry& g = spms.geometry();
    const Eigen::Isometry3d slider_origin = toIsometry(sj->parent_to_joint_origin_transform);
    const Eigen::Vector3d pivot =
        slider_origin * toIsometry(rj->parent_to_joint_origin_transform).translation();
    const double azimuth = (g.leg_azimuth_offset_deg + 120.0 * (i - 1)) * kPi / 180.0;
    const Eigen::Vector3d expected(g.base_radius_m * std::cos(azimuth),
                                   g.base_radius_m * std::sin(azimuth), g.slider_min_m);
    std::ostringstream os;
    if ((pivot - expected).norm() > 1e-6) {
      os << "DrillingSimulation: URDF rod pivot of leg " << i << " (" << slider << " at 0) is at ("
         << pivot.transpose() << ") m in spms_base, the SPMS geometry puts it "
         << "at (" << expected.transpose() << ") m (base radius " << g.base_radius_m << " m)";
      throw std::runtime_error(os.str());
    }
    if (!sj->limits ||
        std::abs(slider_origin.translation().z() + sj->limits->lower - g.slider_min_m) > 1e-9 ||
        std::abs(slider_origin.translation().z() + sj->limits->upper - g.slider_max_m) > 1e-9) {
      os << "DrillingSimulation: URDF " << slider << " limits do not span the SPMS slider stroke ["
         << g.slider_min_m << ", " << g.slider_max_m << "] m along the rail";
      throw std::runtime_error(os.str());
    }
  }

  // The patient's AP heave [m] at time t when the bone plays a model (the paper's bench): a
  // copy of the internal ventilator sampled ahead (pending settings take effect at their
  // breath, as on the ventilator itself), q1 Tv + q2 dTv/dt, and the fault's amplitude factor.
  double benchHeave(BreathScheduler* vent, double t) const {
    const VentilatorSample v = vent->sample(t);
    return 1e-3 * amplitude_factor *
           (patient.q1_ap_mm_per_ml * v.volume_ml + patient.q2_ap_mm_s_per_ml * v.flow_ml_s);
  }

  // Times in (t0, t1] where the ventilator's flow steps (breath start, end of the inspiratory
  // flow, end of the pause), breath by breath on a copy of the ventilator.
  std::vector<double> benchFlowSteps(double t0, double t1) const {
    std::vector<double> out;
    BreathScheduler vent = ventilator;
    double t = t0;
    for (int guard = 0; guard < 100; ++guard) {
      vent.sample(t);
      const double start = vent.breathStart();
      const VentilatorModel& m = vent.model();
      for (double tau : {0.0, m.flowTime(), m.inspiratoryTime(), m.period()}) {
        const double ts = start + tau;
        if (ts > t0 && ts <= t1 && (out.empty() || ts > out.back() + 1e-9)) out.push_back(ts);
      }
      t = start + m.period();
      if (t > t1) break;
    }
    return out;
  }

  // The SPMS controller of the paper's bench plays the model: every bench_period_s it streams
  // the next period, one period ahead, as a trajectory of the slider joints (points every
  // period / bench_points, knots on both sides of each flow step, velocities from one-sided
  // differences), executed like the arm's (JointTrajectoryExecutor).
  void streamBench(bool first) {
    const double period = bench_period_steps * dt;
    const double t0 = first ? time : time + period;
    const double t1 = time + 2.0 * period;
    struct Knot {
      double t;
      bool left;
    };
    std::vector<Knot> knots;
    const int n = static_cast<int>(std::lround((t1 - t0) / period * kBenchPointsPerPeriod));
    for (int i = 1; i <= n; ++i) knots.push_back({t0 + (t1 - t0) * i / n, true});
    constexpr double kStepWidth = 1e-3;
    for (double ts : benchFlowSteps(t0, t1)) {
      knots.push_back({ts, true});
      if (ts + kStepWidth < t1) knots.push_back({ts + kStepWidth, false});
    }
    std::sort(knots.begin(), knots.end(), [](const Knot& a, const Knot& b) { return a.t < b.t; });
    TrajectoryCommand command;
    command.joint_names = spms_trajectory->jointNames();
    command.start_time_s = first ? std::numeric_limits<double>::quiet_NaN() : t0;
    BreathScheduler vent = ventilator;
    constexpr double h = 1e-6;  // exact on the linear pieces of a square flow
    constexpr double dz = 1e-7;
    for (std::size_t i = 0; i < knots.size(); ++i) {
      if (i > 0 && knots[i].t <= knots[i - 1].t + 1e-9) continue;
      const double ta = knots[i].left ? knots[i].t - h : knots[i].t;
      const double za = benchHeave(&vent, ta);
      const double zb = benchHeave(&vent, ta + h);
      const double z = knots[i].left ? zb : za;
      const double zdot = (zb - za) / h;
      const SpmsIkResult ik = spms.inverseHeave(z);
      const SpmsIkResult ik2 = spms.inverseHeave(z + dz);
      if (!ik.reachable || !ik2.reachable) break;  // outside the stroke: hold the last point
      TrajectoryPoint pt;
      pt.time_s = knots[i].t;
      for (int j = 0; j < 3; ++j) {
        pt.positions.push_back(ik.sliders[j]);
        pt.velocities.push_back((ik2.sliders[j] - ik.sliders[j]) / dz * zdot);
      }
      command.points.push_back(pt);
    }
    if (!command.points.empty()) spms_trajectory->command(command, time);
  }

  void updatePlatform() {
    Eigen::Vector3d ref_velocity = Eigen::Vector3d::Zero();
    Eigen::Vector3d set_point = slider_targets;
    if (moving_bone && bone_motion_model) {
      if (bench_stream_due == 0 || step_index >= bench_stream_due) {
        streamBench(bench_stream_due == 0);
        bench_stream_due = step_index + bench_period_steps;
      }
      BreathScheduler vent = ventilator;
      desired_heave = benchHeave(&vent, time);
      // The drives read the set-point at the start of the step (time - dt).
      spms_trajectory->sample(time - dt, &spms_sample);
      spms_trajectory->prune(time - dt);
      set_point = spms_sample.position;
      ref_velocity = spms_sample.velocity;
      spms_trajectory->sample(time, &spms_sample);
      slider_targets = spms_sample.position;
    } else {
      const double t_lag = std::max(0.0, time - patient.lag_s);
      // Earlier times than the last call are clamped by the scheduler (lag change on reset).
      const VentilatorSample lagged = lagged_ventilator.sample(t_lag);
      // The volume this breath delivered against the setting (1 for a virtual volunteer).
      const double delivered = patient.delivered_volume_bias *
                               (patient.delivered_volume_cv > 0.0
                                    ? deliveredVolumeFactor(seed, lagged_ventilator.breathIndex(),
                                                            patient.delivered_volume_cv)
                                    : 1.0);
      desired_heave = moving_bone ? 1e-3 * amplitude_factor *
                                        patient.apDisplacementMm(delivered * lagged.volume_ml, time,
                                                                 delivered * lagged.flow_ml_s)
                                  : 0.0;
      if (!(ik_heave && *ik_heave == desired_heave)) {
        ik_of_heave = spms.inverseHeave(desired_heave);
        ik_heave = desired_heave;
      }
      const SpmsIkResult& ik = ik_of_heave;
      if (ik.reachable) slider_targets = ik.sliders;  // else keep the last reachable targets
      // The drive streams the patient's motion as position set-points, each with the velocity to
      // the next as feed-forward: over this step, from the last set-point to this one.
      set_point = have_previous_targets ? previous_targets : slider_targets;
      if (have_previous_targets) ref_velocity = (slider_targets - previous_targets) / dt;
      previous_targets = slider_targets;
      have_previous_targets = true;
    }
    for (int i = 0; i < 3; ++i) {
      sliders[i] = slider_axes[static_cast<std::size_t>(i)].step(dt, set_point[i], ref_velocity[i]);
    }
    if (!(converged_sliders && *converged_sliders == sliders)) {
      PlatformPose guess;
      guess.z_m = platform.z_m;
      guess.roll_rad = platform.roll_rad;
      guess.pitch_rad = platform.pitch_rad;
      if (solved_steps[0] + 1 == step_index && solved_steps[1] + 2 == step_index) {
        // Solved at the last two steps: start from their linear extrapolation, a breathing
        // platform's next pose to second order (one chord iteration fewer than from the last
        // pose; the same 1e-13 m test ends it).
        guess.z_m = 2.0 * platform.z_m - platform_before.z_m;
        guess.roll_rad = 2.0 * platform.roll_rad - platform_before.roll_rad;
        guess.pitch_rad = 2.0 * platform.pitch_rad - platform_before.pitch_rad;
      }
      const SpmsFkResult fk = spms.forward(sliders, guess, &platform_jacobian);
      if (fk.ok) {
        platform_before = platform;
        platform = fk.pose;
        platform_rotation = fk.rotation;
        solved_steps = {step_index, solved_steps[0]};
      }
      converged_sliders.reset();
      // (A pose of exactly zero height, roll and pitch would be a different guess: forward()
      // starts a zero guess from the sliders' mean. Not kept then.)
      const bool zero_pose =
          fk.pose.z_m == 0.0 && fk.pose.roll_rad == 0.0 && fk.pose.pitch_rad == 0.0;
      if (fk.ok && fk.residual_m < 1e-13 && !zero_pose) converged_sliders = sliders;
    }
    bone_world = spms_base_world * platformInBase() * bone_in_platform;
  }

  // Layer at the deepest cut; air before the first cut.
  Material cutLayer() const {
    return process->maxDepthCut() > 0.0 ? process->currentLayer() : Material::kAir;
  }

  Eigen::Isometry3d platformInBase() const {
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    t.linear() = platform_rotation;
    t.translation() = platform.position(spms.homeHeight());
    return t;
  }

  /** @brief The arm's controllers (params.controllers) and the feed joint's drive. */
  void makeControllers(const DrillingSimulationParams& params) {
    std::vector<JointLimit> limits;
    Eigen::VectorXd hold_q(static_cast<int>(commandable.size()));
    for (size_t j = 0; j < commandable.size(); ++j) {
      const ArmJointInfo& info = arm->jointInfo()[commandable_index[j]];
      limits.push_back(
          {info.lower, info.upper,
           info.velocity > 0.0 ? info.velocity : std::numeric_limits<double>::infinity()});
      hold_q[static_cast<int>(j)] = home[commandable_index[j]];
    }
    controller_specs = controllerLayout(params.controllers, commandable);
    stalled.assign(commandable.size(), false);
    for (const ControllerSpec& spec : controller_specs) {
      std::vector<int> columns;
      std::vector<JointLimit> own_limits;
      Eigen::VectorXd own_hold(static_cast<Eigen::Index>(spec.joints.size()));
      for (const std::string& joint : spec.joints) {
        const auto at = std::find(commandable.begin(), commandable.end(), joint);
        const int column = static_cast<int>(at - commandable.begin());
        own_hold[static_cast<Eigen::Index>(columns.size())] = hold_q[column];
        columns.push_back(column);
        own_limits.push_back(limits[static_cast<std::size_t>(column)]);
      }
      controller_trajectories.push_back(std::make_unique<JointTrajectoryExecutor>(
          spec.joints, own_limits, own_hold, params.controller_rules));
      controller_columns.push_back(std::move(columns));
    }
    samples.resize(controller_trajectories.size());  // reference() and advanceArmBlock() fill them
    const auto feed = std::find(commandable.begin(), commandable.end(), "feed_joint");
    if (feed != commandable.end()) {
      feed_index = static_cast<int>(feed - commandable.begin());
      for (std::size_t c = 0; c < controller_columns.size(); ++c) {
        const std::vector<int>& columns = controller_columns[c];
        const auto at = std::find(columns.begin(), columns.end(), feed_index);
        if (at != columns.end()) {
          feed_controller = c;
          feed_column = static_cast<int>(at - columns.begin());
        }
      }
      StageAxisParams drive;
      drive.max_speed_m_s = limits[static_cast<std::size_t>(feed_index)].velocity;
      drive.max_accel_m_s2 = params.feed_max_accel_m_s2;
      drive.bandwidth_hz = params.feed_bandwidth_hz;
      feed_drive = StageAxis(drive, hold_q[feed_index]);
    }
  }

  /**
   * @brief A command to controller @p index, its stamps read on the controllers' clock
   *        (arm_clock_offset_s, arm_clock_drift_ppm): in sim time, stamp s is
   *        (s - offset) / (1 + drift).
   */
  TargetResult commandController(std::size_t index, const TrajectoryCommand& command) {
    if (params.arm_clock_offset_s == 0.0 && params.arm_clock_drift_ppm == 0.0) {
      return controller_trajectories[index]->command(command, time);
    }
    const double scale = 1.0 + params.arm_clock_drift_ppm * 1e-6;
    const auto sim_time = [this, scale](double stamp) {
      return (stamp - params.arm_clock_offset_s) / scale;
    };
    TrajectoryCommand local = command;
    if (std::isfinite(local.start_time_s)) local.start_time_s = sim_time(local.start_time_s);
    for (TrajectoryPoint& p : local.points) p.time_s = sim_time(p.time_s);
    return controller_trajectories[index]->command(local, time);
  }

  /** @brief The controllers' reference positions at t, in the commandable joints' order. */
  const Eigen::VectorXd& reference(double t) {
    reference_q.resize(static_cast<Eigen::Index>(commandable.size()));
    for (std::size_t c = 0; c < controller_trajectories.size(); ++c) {
      TrajectoryState& st = samples[c];
      controller_trajectories[c]->sample(t, &st);
      const std::vector<int>& columns = controller_columns[c];
      for (std::size_t j = 0; j < columns.size(); ++j) {
        reference_q[columns[j]] = st.position[static_cast<Eigen::Index>(j)];
      }
    }
    return reference_q;
  }

  /** @brief The next arm block's steps: the air rate's only out of contact and well clear. */
  int chooseBlockSteps() {
    const int steps = [this] {
      if (steps_per_air_block == steps_per_arm_block || last_force.contact) {
        return steps_per_arm_block;
      }
      const double approach_per_step =
          std::max(0.0, tip_depth - block_decision_depth) / static_cast<double>(block_steps);
      const double reach = 2.0 * steps_per_air_block * approach_per_step;
      return -tip_depth > params.arm_air_clearance_m + reach ? steps_per_air_block
                                                             : steps_per_arm_block;
    }();
    block_decision_depth = tip_depth;
    if (steps != steps_per_arm_block) ++air_blocks;
    return steps;
  }

  void advanceArmBlock() {
    ComponentLaps laps(profile);
    const double block = block_steps * dt;
    Eigen::VectorXd& q0 = block_q0;
    Eigen::VectorXd& q1 = block_q1;
    q0 = reference(time);
    q1 = reference(time + block);
    if (feed_index >= 0) {
      // The drill device's feed drive (a lead-screw axis like the SPMS sliders) follows the
      // trajectory with its own limits, stepped at the physics rate over the coming block.
      q0[feed_index] = feed_drive.position();
      const JointTrajectoryExecutor& feed_trajectory = *controller_trajectories[feed_controller];
      for (int k = 0; k < block_steps && !stalled[static_cast<std::size_t>(feed_index)]; ++k) {
        TrajectoryState& ref = samples[feed_controller];
        feed_trajectory.sample(time + k * dt, &ref);
        feed_drive.step(dt, ref.position[feed_column], ref.velocity[feed_column]);
      }
      q1[feed_index] = feed_drive.position();
    }
    for (auto& trajectory : controller_trajectories) trajectory->prune(time);
    block_pos.resize(static_cast<Eigen::Index>(commandable.size()));
    block_vel.resize(static_cast<Eigen::Index>(commandable.size()));
    for (size_t j = 0; j < commandable.size(); ++j) {
      if (stalled[j] && static_cast<int>(j) != feed_index) {  // the stalled joint's setpoint
        q0[static_cast<Eigen::Index>(j)] = q1[static_cast<Eigen::Index>(j)] = servo_ref[j];
      }
      const double limit = arm->jointInfo()[commandable_index[j]].velocity * block;
      // Not lagging: the setpoint is the reference now (q0). Lagging: it keeps its own value.
      const double from = std::abs(servo_ref[j] - q0[j]) <= limit ? q0[j] : servo_ref[j];
      const double to = from + std::clamp(q1[j] - from, -limit, limit);
      block_pos[static_cast<Eigen::Index>(j)] = from;
      block_vel[static_cast<Eigen::Index>(j)] = (to - from) / block;  // the reference ramps to `to`
      servo_ref[j] = to;
    }
    arm->setJointPositionTargets(commandable_index, block_pos);
    arm->setJointVelocityTargets(commandable_index, block_vel);
    // Thrust on the tip, opposite to the feed (zero-order hold over the block).
    const Eigen::Matrix3d r = arm->tipPose().linear();
    arm->applyTipForce(-last_force.thrust_N * r.col(2));
    tip_block_start = arm->tipPose().translation();
    laps.mark(Component::kArmControllers);
    arm->setSubstep(block);
    arm->step(block);
    laps.mark(Component::kArmStep);
    const Eigen::Isometry3d tip = arm->tipPose();
    tip_block_end = tip.translation();
    drill_axis = tip.linear().col(2);
  }

  void resetTrial(std::uint64_t new_seed, bool moving) {
    // Everything that can throw first, so that a bad distribution leaves the trial unchanged.
    if (bone_motion_model && params.variability.patient_lag_error_s != 0.0) {
      throw std::invalid_argument(
          "trial_distribution/patient/lag_error_s: the paper's bench plays the model without a "
          "lag; a lag error needs the bone to move as the patient (bone motion virtual_patient)");
    }
    if (bone_motion_model && params.population.enabled) {
      throw std::invalid_argument(
          "population/enabled: the paper's bench plays the model; a population patient needs the "
          "bone to move as the patient (bone motion virtual_patient)");
    }
    const TrialConditions drawn = drawTrialConditions(
        new_seed, params.variability, params.ventilator, params.sensor.force_noise_sd_n);
    auto new_process =
        std::make_unique<DrillingProcess>(sample(new_seed, params.specimen), params.drill);
    ImagingPlan new_plan =
        makeImagingPlan(new_process->specimen(), marker_in_platform.inverse() * bone_in_platform,
                        params.plan, new_seed);
    VentilatorSettings breathing = params.ventilator;
    breathing.rate_bpm = drawn.ventilator_rate_bpm;
    breathing.tv_max_ml = drawn.ventilator_tidal_volume_ml;
    breathing.validate();
    ForceSensorParams sensor_params = params.sensor;
    sensor_params.rate_hz = params.physics_rate_hz;  // sample() is called every physics step
    if (params.sensor.force_noise_sd_n > 0.0) {
      const double noise_scale = drawn.force_noise_sd_n / params.sensor.force_noise_sd_n;
      sensor_params.force_noise_sd_n = drawn.force_noise_sd_n;
      sensor_params.torque_noise_sd_nm *= noise_scale;
    }

    seed = new_seed;
    moving_bone = moving;
    amplitude_factor = 1.0;
    conditions = drawn;
    if (params.population.enabled) {
      const PopulationPatient drawn_patient = drawPopulationPatient(seed, params.population);
      patient = populationVirtualPatient(seed, drawn_patient, time,
                                         params.variability.patient_movement_scale);
      conditions.volunteer_id = 0;
      conditions.patient_gain_change = drawn_patient.surgery.gain;
    } else {
      patient = drawVirtualPatient(seed, time, params.variability.patient_movement_scale);
    }
    if (bone_motion_model) {
      // The paper's bench: the SPMS plays the model, nothing else.
      patient.q1_ap_mm_per_ml = bone_motion_model->q1_ap_mm_per_ml;
      patient.q2_ap_mm_s_per_ml = bone_motion_model->q2_ap_mm_s_per_ml;
      patient.lag_s = 0.0;
      patient.drift_mm = 0.0;
      patient.movements.clear();
    }
    patient.q1_ap_mm_per_ml *= drawn.patient_amplitude_scale;
    if (params.population.enabled) {
      // The bench's approach clears about 7 mm above the bone's end-expiratory surface: a patient
      // whose vertebra would move more at this trial's delivered volume moves that much.
      const double stroke =
          patient.q1_ap_mm_per_ml * breathing.tv_max_ml * patient.delivered_volume_bias;
      if (stroke > params.population.max_stroke_mm) {
        patient.q1_ap_mm_per_ml *= params.population.max_stroke_mm / stroke;
        conditions.patient_gain_change *= params.population.max_stroke_mm / stroke;
      }
    }
    patient.q1_ap_mm_per_ml *= params.variability.patient_gain_error;
    patient.lag_s = std::max(0.0, patient.lag_s + params.variability.patient_lag_error_s);
    conditions.patient_ap_slope_mm_per_ml = patient.q1_ap_mm_per_ml;
    conditions.patient_lag_s = patient.lag_s;
    process = std::move(new_process);
    imaging_plan = std::move(new_plan);
    sensor = std::make_unique<ForceSensor>(seed * 2654435761ULL + 17ULL, sensor_params);
    arm->setStiffnessScale(drawn.arm_stiffness_scale);
    // The trial's breathing takes effect at the next breath (a ventilator never cuts one).
    const VentilatorSettings& current = ventilator.model().settings();
    if (breathing.rate_bpm != current.rate_bpm || breathing.tv_max_ml != current.tv_max_ml) {
      requestBreathing(breathing);
    }
    if (params.sensor_tared_at_reset) sensor->tare();  // the benches: tared before the trial
    tare.reset();
    // The SPMS controller starts its stream from where the sliders are.
    spms_trajectory->hold(sliders);
    platform_jacobian.reset();
    converged_sliders.reset();
    solved_steps = {0, 0};
    ik_heave.reset();
    bench_stream_due = 0;
    have_previous_targets = false;
    tracker_rng.seed(seed * 40503ULL + 3ULL);
    tracker_phase = trackerPhaseFraction(seed);
    camera_true_world = camera_world * registrationError(seed, params.registration_error_mm,
                                                         params.registration_error_deg);
    was_in_contact = false;
    steps_without_contact = 0;
    contact_losses = 0;
    arm->applyTipForce(Eigen::Vector3d::Zero());
    const TargetResult r = arm->resetJointState(home);
    if (!r.ok()) throw std::invalid_argument("DrillingSimulation: home pose: " + r.message);
    Eigen::VectorXd hold_q(static_cast<int>(commandable.size()));
    for (size_t j = 0; j < commandable.size(); ++j) hold_q[j] = home[commandable_index[j]];
    for (std::size_t c = 0; c < controller_trajectories.size(); ++c) {
      const std::vector<int>& columns = controller_columns[c];
      Eigen::VectorXd q(static_cast<Eigen::Index>(columns.size()));
      for (std::size_t j = 0; j < columns.size(); ++j)
        q[static_cast<Eigen::Index>(j)] = hold_q[columns[j]];
      controller_trajectories[c]->hold(q);
    }
    if (feed_index >= 0) feed_drive.reset(hold_q[feed_index]);
    servo_ref = hold_q;
    stalled.assign(commandable.size(), false);
    spindle_cmd_rpm = 0.0;
    spindle_rpm = 0.0;
    spindle_cmd_t = time;
    spindle_watchdog_trips = 0;
    arm->setJointVelocityTargets(std::map<std::string, double>{{"spindle_joint", 0.0}});
    last_force = ForceSample{};
    tip_block_start = tip_block_end = physics_tip = arm->tipPose().translation();
    drill_axis = arm->tipPose().linear().col(2);
    tip_depth = -(bone_world.inverse() * physics_tip).z();
    block_decision_depth = tip_depth;
    relative_ap0 = physics_tip.z() - bone_world.translation().z();
  }
};

DrillingSimulation::DrillingSimulation(const std::string& urdf_xml,
                                       const DrillingSimulationParams& params, std::uint64_t seed)
    : impl_(std::make_unique<Impl>(params)) {
  Impl& s = *impl_;
  params.validate();
  if (!(params.physics_rate_hz > 0.0) || !(params.arm_rate_hz > 0.0) ||
      !(params.arm_rate_hz <= params.physics_rate_hz)) {
    throw std::invalid_argument("DrillingSimulation: need 0 < arm_rate_hz <= physics_rate_hz");
  }
  const double ratio = params.physics_rate_hz / params.arm_rate_hz;
  s.steps_per_arm_block = static_cast<int>(std::lround(ratio));
  if (std::abs(ratio - s.steps_per_arm_block) > 1e-9) {
    throw std::invalid_argument(
        "DrillingSimulation: physics_rate_hz / arm_rate_hz must be an integer");
  }
  // Never faster than the arm's own rate (a lower arm_rate_hz runs at it in air as well).
  s.steps_per_air_block =
      std::max(s.steps_per_arm_block,
               static_cast<int>(std::lround(params.physics_rate_hz / params.arm_rate_in_air_hz)));
  s.block_steps = s.steps_per_arm_block;
  if (!(params.slider_max_accel_m_s2 > 0.0) || !std::isfinite(params.slider_max_accel_m_s2) ||
      !(params.slider_bandwidth_hz > 0.0) || !std::isfinite(params.slider_bandwidth_hz)) {
    throw std::invalid_argument(
        "DrillingSimulation: slider_max_accel_m_s2 and slider_bandwidth_hz must be finite and > 0");
  }
  if (!(params.bench_period_s >= 0.01 && params.bench_period_s <= 1.0)) {
    throw std::invalid_argument("DrillingSimulation: bench_period_s must be in [0.01, 1] s");
  }
  if (!(params.slider_max_speed_m_s > 0.0) || !(params.spindle_accel_rpm_s > 0.0) ||
      !(params.spindle_max_rpm > 0.0) || !(params.tracker_noise_rms_mm >= 0.0)) {
    throw std::invalid_argument("DrillingSimulation: speeds and noise must be positive");
  }
  s.dt = 1.0 / params.physics_rate_hz;
  s.model = parseUrdfKept(urdf_xml);
  if (!s.model) {
    throw std::runtime_error(
        "DrillingSimulation: urdfdom could not parse the URDF (malformed XML or invalid robot "
        "description)");
  }
  BulletArmParams arm_params = params.arm;
  arm_params.substep = 1.0 / params.arm_rate_hz;
  arm_params.inverse_inertia_tolerance = params.arm_inverse_inertia_tolerance;
  s.arm = std::make_unique<BulletArm>(urdf_xml, params.base_link, params.tip_link, arm_params);
  s.arm_joints = s.arm->jointNames();
  for (int k = 0; k < s.arm->numJoints(); ++k) {
    if (s.arm->jointInfo()[k].type != ArmJointType::kContinuous) {
      s.commandable.push_back(s.arm_joints[k]);
      s.commandable_index.push_back(k);
    }
  }
  const auto spindle = std::find(s.arm_joints.begin(), s.arm_joints.end(), "spindle_joint");
  if (spindle == s.arm_joints.end()) {
    throw std::runtime_error("DrillingSimulation: the arm chain has no spindle_joint");
  }
  s.spindle_index = {static_cast<int>(spindle - s.arm_joints.begin())};
  s.home = Eigen::VectorXd::Zero(s.arm->numJoints());
  for (const auto& kv : params.home_pose) {
    auto it = std::find(s.arm_joints.begin(), s.arm_joints.end(), kv.first);
    if (it == s.arm_joints.end()) {
      throw std::invalid_argument("DrillingSimulation: home pose names unknown joint '" + kv.first +
                                  "'");
    }
    s.home[it - s.arm_joints.begin()] = kv.second;
  }
  s.makeControllers(params);
  s.checkSpmsAgainstUrdf();
  s.sliders = Eigen::Vector3d::Constant(params.spms.home_slider_m);
  s.slider_targets = s.sliders;
  {
    StageAxisParams drive;
    drive.max_speed_m_s = params.slider_max_speed_m_s;
    drive.max_accel_m_s2 = params.slider_max_accel_m_s2;
    drive.bandwidth_hz = params.slider_bandwidth_hz;
    for (StageAxis& axis : s.slider_axes) axis = StageAxis(drive, params.spms.home_slider_m);
    const SpmsGeometry& g = params.spms;
    const JointLimit stroke{g.slider_min_m, g.slider_max_m, params.slider_max_speed_m_s};
    s.spms_trajectory = std::make_unique<JointTrajectoryExecutor>(
        std::vector<std::string>{"slider1_joint", "slider2_joint", "slider3_joint"},
        std::vector<JointLimit>{stroke, stroke, stroke}, s.sliders);
    s.bench_period_steps = streamPeriodSteps(params.physics_rate_hz, 1.0 / params.bench_period_s,
                                             "bench_period_s (as a rate)");
    s.breath_sensor_period =
        params.breath_sensor_rate_hz > 0.0
            ? streamPeriodSteps(params.physics_rate_hz, params.breath_sensor_rate_hz,
                                "breath_sensor_rate_hz")
            : 0;
    BreathDetectorParams detector;
    detector.trigger_flow_ml_s = params.breath_trigger_flow_ml_s;
    detector.rearm_flow_ml_s = 0.0;
    detector.min_interval_s = 0.0;
    detector.armed_at_start = true;
    s.breath_detector.emplace(detector);
  }
  s.updatePlatform();  // home pose at t = 0 (platform not moving yet)
  {
    Eigen::Isometry3d home = Eigen::Isometry3d::Identity();
    home.translation() = PlatformFullPose().position(s.spms.homeHeight());
    s.bone_home_world = (s.spms_base_world * home * s.bone_in_platform).translation();
  }
  s.vent_now = s.ventilator.sample(0.0);
  s.resetTrial(seed, params.moving_bone);
  s.updatePlatform();
}

DrillingSimulation::~DrillingSimulation() = default;

void DrillingSimulation::reset(std::uint64_t seed, bool moving_bone) {
  impl_->resetTrial(seed, moving_bone);
}

SimulationStep DrillingSimulation::stepOnce() {
  Impl& s = *impl_;
  s.watchDriveGuard();
  // The spindle's driver (its watchdog and its rate-limited run-up) at the physics rate, whatever
  // the arm's block: the speed the drilling physics and the sensor's spindle-synchronous
  // vibration integrate every step.
  if (s.params.spindle_watchdog_s > 0.0 && s.spindle_cmd_rpm > 0.0 &&
      s.time - s.spindle_cmd_t > s.params.spindle_watchdog_s) {
    s.spindle_cmd_rpm = 0.0;  // the driver heard nothing for too long: it stops the spindle
    ++s.spindle_watchdog_trips;
  }
  const double max_change = s.params.spindle_accel_rpm_s * s.dt;
  s.spindle_rpm += std::clamp(s.spindle_cmd_rpm - s.spindle_rpm, -max_change, max_change);
  const int phase = s.block_phase;
  if (phase == 0) {
    // The arm block, its spindle joint at the driver's speed.
    s.block_steps = s.chooseBlockSteps();
    s.arm->setJointVelocityTargets(s.spindle_index,
                                   Eigen::VectorXd::Constant(1, s.spindle_rpm * 2.0 * kPi / 60.0));
    s.advanceArmBlock();
  }
  ComponentLaps laps(s.profile);
  ++s.step_index;
  s.time = static_cast<double>(s.step_index) * s.dt;
  const double frac = static_cast<double>(phase + 1) / s.block_steps;
  s.block_phase = (phase + 1) % s.block_steps;
  s.physics_tip = s.tip_block_start + frac * (s.tip_block_end - s.tip_block_start);

  s.vent_now = s.ventilator.sample(s.time);
  s.senseBreath();
  laps.mark(Component::kPatient);
  s.updatePlatform();
  laps.mark(Component::kPlatform);

  // Tip depth below the bone's top surface along the surface normal (the bone frame's z; the
  // layers are parallel to the surface), so platform roll and pitch tilt the layers with the
  // bone. The paper drills perpendicular to the surface, where this is the depth along the drill
  // axis; the 1-D force law does not model an oblique entry. Beside the bone's footprint there
  // is no bone under the tip.
  const Eigen::Vector3d tip_in_bone = s.bone_world.inverse() * s.physics_tip;
  s.tip_depth = -tip_in_bone.z();
  const bool over_bone = std::abs(tip_in_bone.x()) <= s.params.bone_half_x_m &&
                         std::abs(tip_in_bone.y()) <= s.params.bone_half_y_m;
  const Material before = s.cutLayer();
  s.last_force = s.process->step(s.dt, over_bone ? s.tip_depth : -1.0, s.spindle_rpm);
  if (s.last_force.contact) {
    s.was_in_contact = true;
    s.steps_without_contact = 0;
  } else if (s.was_in_contact && ++s.steps_without_contact == kSeparationSteps) {
    ++s.contact_losses;  // one separation per gap, counted once it lasted 10 ms
  }
  laps.mark(Component::kDrilling);

  SimulationStep out;
  out.time_s = s.time;
  out.force = s.last_force;
  out.tip_depth_m = s.tip_depth;
  out.layer_changed = s.cutLayer() != before;
  // The true wrench on the sensor, in its frame (z the drill axis, towards the bone), with the
  // sign the sensor reports: the drill side's load on the bone, so the bone's resistance reads
  // positive. Fz: the thrust. Tz: the cutting torque, which resists the spindle's rotation
  // (+z, the joint's positive direction): the bone turns the bit by -T about +z, and the sensor
  // reads +T (the thrust's line is the axis through the sensor's origin: no Tx, Ty). No lateral
  // force: the two lips' tangential forces are a couple (doc/simulator_physics.md §2c).
  Wrench truth = Wrench::Zero();
  truth[2] = s.last_force.thrust_N;
  truth[5] = s.last_force.torque_Nm;
  out.force_sampled =
      s.sensor->sample(truth, s.spindle_rpm, s.last_force.contact, &out.measured_wrench);
  if (out.force_sampled) {
    // The tool's weight on an untared sensor; then the driver's tare (raw - 0 before any: the
    // sample unchanged, bit for bit).
    if (!s.params.sensor_tared_at_reset) out.measured_wrench[2] += s.params.sensor_bias_offset_n;
    out.measured_wrench = s.tare.apply(s.time, out.measured_wrench);
  }
  laps.mark(Component::kSensor);
  return out;
}

void DrillingSimulation::setProfile(ComponentProfile* profile) {
  impl_->profile = profile;
  impl_->arm->setProfile(profile);
}

int DrillingSimulation::step(double dt) {
  if (!std::isfinite(dt) || dt <= 0.0) return 0;
  const double end = impl_->time + dt - 1e-9;
  int n = 0;
  while (impl_->time < end) {
    stepOnce();
    ++n;
  }
  return n;
}

namespace {

TargetResult heldByTheGuard() {
  return {TargetStatus::kRejected,
          "the drives hold: no enable from the drill guard (drill_guard/enable)"};
}

}  // namespace

TargetResult DrillingSimulation::commandTrajectory(const TrajectoryCommand& command) {
  if (impl_->drives_halted) return heldByTheGuard();
  for (const std::string& name : command.joint_names) {
    if (name == "spindle_joint") {
      return {TargetStatus::kRejected,
              "spindle_joint is not commandable by trajectory: it is commanded through the "
              "spindle speed"};
    }
  }
  const std::vector<ControllerSpec>& specs = impl_->controller_specs;
  for (const std::string& name : command.joint_names) {
    if (ownerOf(specs, name) < 0) {
      return {TargetStatus::kRejected, "joint '" + name + "' is owned by no controller"};
    }
  }
  TargetResult result;
  for (auto& [index, part] : splitByController(command, specs)) {
    const TargetResult r = impl_->commandController(index, part);
    if (result.status == TargetStatus::kAccepted && r.status != TargetStatus::kAccepted) {
      result = r;
      result.message = specs[index].name + ": " + r.message;
    }
  }
  return result;
}

TargetResult DrillingSimulation::commandTrajectory(const std::string& controller,
                                                   const TrajectoryCommand& command) {
  if (impl_->drives_halted) return heldByTheGuard();
  const std::vector<ControllerSpec>& specs = impl_->controller_specs;
  for (std::size_t c = 0; c < specs.size(); ++c) {
    if (specs[c].name == controller) return impl_->commandController(c, command);
  }
  return {TargetStatus::kRejected, "no controller named '" + controller + "'"};
}

void DrillingSimulation::setJointStalled(const std::string& joint, bool stalled) {
  const auto at = std::find(impl_->commandable.begin(), impl_->commandable.end(), joint);
  if (at == impl_->commandable.end()) {
    throw std::invalid_argument("setJointStalled: '" + joint + "' is not a commandable joint");
  }
  impl_->stalled[static_cast<std::size_t>(at - impl_->commandable.begin())] = stalled;
}

const std::vector<ControllerSpec>& DrillingSimulation::controllers() const {
  return impl_->controller_specs;
}

ControllerStateSample DrillingSimulation::controllerState(std::size_t index) const {
  const Impl& s = *impl_;
  if (index >= s.controller_specs.size()) {
    throw std::out_of_range("DrillingSimulation::controllerState: no controller " +
                            std::to_string(index));
  }
  ControllerStateSample out;
  out.stamp = s.time;
  out.joint_names = s.controller_specs[index].joints;
  const TrajectoryState desired = s.controller_trajectories[index]->sample(s.time);
  const Eigen::VectorXd q = s.arm->jointPositions();
  const Eigen::VectorXd qd = s.arm->jointVelocities();
  const std::vector<int>& columns = s.controller_columns[index];
  for (std::size_t j = 0; j < columns.size(); ++j) {
    const int arm_index = s.commandable_index[static_cast<std::size_t>(columns[j])];
    const auto k = static_cast<Eigen::Index>(j);
    out.desired_positions.push_back(desired.position[k]);
    out.desired_velocities.push_back(desired.velocity[k]);
    out.actual_positions.push_back(q[arm_index]);
    out.actual_velocities.push_back(qd[arm_index]);
    out.error_positions.push_back(desired.position[k] - q[arm_index]);
    out.error_velocities.push_back(desired.velocity[k] - qd[arm_index]);
  }
  return out;
}

double DrillingSimulation::armTrajectoryEnd() const {
  double end = -std::numeric_limits<double>::infinity();
  for (const auto& trajectory : impl_->controller_trajectories) {
    end = std::max(end, trajectory->endTime());
  }
  return end;
}

TargetResult DrillingSimulation::commandSpindle(double rpm) {
  if (!std::isfinite(rpm)) return {TargetStatus::kRejected, "spindle speed is NaN/inf"};
  if (rpm < 0.0) return {TargetStatus::kRejected, "spindle speed must be >= 0 rpm"};
  if (rpm > 0.0 && impl_->drives_halted) return heldByTheGuard();
  TargetResult r;
  if (rpm > impl_->params.spindle_max_rpm) {
    r.status = TargetStatus::kClamped;
    r.message = "spindle speed " + std::to_string(rpm) + " rpm clamped to " +
                std::to_string(impl_->params.spindle_max_rpm);
    rpm = impl_->params.spindle_max_rpm;
  }
  impl_->spindle_cmd_rpm = rpm;
  impl_->spindle_cmd_t = impl_->time;
  return r;
}

void DrillingSimulation::requestTare(const TareRequest& request) { impl_->tare.request(request); }

std::optional<TareResult> DrillingSimulation::takeTareResult() { return impl_->tare.takeResult(); }

int DrillingSimulation::spindleWatchdogTrips() const { return impl_->spindle_watchdog_trips; }

void DrillingSimulation::onDriveEnable(bool enable) {
  if (impl_->drive_guard) impl_->drive_guard->onEnable(impl_->time, enable);
}

bool DrillingSimulation::drivesHalted() const { return impl_->drives_halted; }

int DrillingSimulation::driveGuardTrips() const { return impl_->drive_guard_trips; }

void DrillingSimulation::abortController(const std::string& controller) {
  const std::vector<ControllerSpec>& specs = impl_->controller_specs;
  for (std::size_t c = 0; c < specs.size(); ++c) {
    if (specs[c].name != controller) continue;
    impl_->holdController(c);
    ++impl_->controller_aborts;
    return;
  }
  throw std::invalid_argument("abortController: no controller named '" + controller + "'");
}

void DrillingSimulation::holdController(const std::string& controller) {
  const std::vector<ControllerSpec>& specs = impl_->controller_specs;
  for (std::size_t c = 0; c < specs.size(); ++c) {
    if (specs[c].name != controller) continue;
    impl_->holdController(c);
    return;
  }
  throw std::invalid_argument("holdController: no controller named '" + controller + "'");
}

double DrillingSimulation::controllerTrajectoryEnd(std::size_t index) const {
  if (index >= impl_->controller_trajectories.size()) {
    throw std::out_of_range("DrillingSimulation::controllerTrajectoryEnd: no controller " +
                            std::to_string(index));
  }
  return impl_->controller_trajectories[index]->endTime();
}

int DrillingSimulation::controllerAborts() const { return impl_->controller_aborts; }

void DrillingSimulation::requestVentilatorSettings(const VentilatorSettings& settings) {
  impl_->requestBreathing(settings);
  impl_->params.ventilator = settings;  // the base the next trials' breathing is drawn around
}

void DrillingSimulation::setTrialDistribution(const SpecimenDistribution& specimen,
                                              const TrialVariability& variability) {
  specimen.validate();
  variability.validate();
  impl_->params.specimen = specimen;
  impl_->params.variability = variability;
}

void DrillingSimulation::setPatientAmplitudeFactor(double factor) {
  if (!(std::isfinite(factor) && factor >= 0.0 && factor <= 10.0)) {
    throw std::invalid_argument("patient amplitude factor: must be in [0, 10]");
  }
  impl_->amplitude_factor = factor;
}

void DrillingSimulation::setBoneMotionModel(const std::optional<BoneMotionModel>& model) {
  if (model &&
      !(std::isfinite(model->q1_ap_mm_per_ml) && std::isfinite(model->q2_ap_mm_s_per_ml))) {
    throw std::invalid_argument("bone motion model: q1 and q2 must be finite");
  }
  impl_->bone_motion_model = model;
}

Eigen::VectorXd DrillingSimulation::armJointStiffness() const {
  return impl_->arm->jointStiffness();
}

const TrialConditions& DrillingSimulation::trialConditions() const { return impl_->conditions; }

double DrillingSimulation::time() const { return impl_->time; }
double DrillingSimulation::physicsDt() const { return impl_->dt; }
const std::vector<std::string>& DrillingSimulation::armJointNames() const {
  return impl_->arm_joints;
}
Eigen::VectorXd DrillingSimulation::armJointPositions() const {
  return impl_->arm->jointPositions();
}
Eigen::VectorXd DrillingSimulation::armJointVelocities() const {
  return impl_->arm->jointVelocities();
}
Eigen::VectorXd DrillingSimulation::armJointEfforts() const { return impl_->arm->jointEfforts(); }

std::vector<std::pair<std::string, double>> DrillingSimulation::spmsJointStates() const {
  const Impl& s = *impl_;
  std::vector<std::pair<std::string, double>> out;
  for (int i = 0; i < 3; ++i) {
    out.emplace_back("slider" + std::to_string(i + 1) + "_joint",
                     s.sliders[i] - s.params.spms_slider_joint_offset_m);
  }
  for (int i = 0; i < 3; ++i) {
    // Rod angle in the leg's radial plane: 0 = vertical, negative = leaning inwards.
    const Eigen::Vector3d d =
        s.spms.platformJoint(i, s.platform) - s.spms.sliderPoint(i, s.sliders[i]);
    const double th = (s.params.spms.leg_azimuth_offset_deg + 120.0 * i) * kPi / 180.0;
    const Eigen::Vector3d er(std::cos(th), std::sin(th), 0.0);
    out.emplace_back("rod" + std::to_string(i + 1) + "_joint", std::atan2(d.dot(er), d.z()));
  }
  return out;
}

Eigen::Vector3d DrillingSimulation::sliderPositions() const { return impl_->sliders; }
const PlatformFullPose& DrillingSimulation::platformPose() const { return impl_->platform; }
double DrillingSimulation::desiredHeave() const { return impl_->desired_heave; }
Eigen::Isometry3d DrillingSimulation::tipPose() const { return impl_->arm->tipPose(); }
double DrillingSimulation::boneTopZ() const { return impl_->bone_world.translation().z(); }
double DrillingSimulation::spindleRpm() const { return impl_->spindle_rpm; }
const DrillingProcess& DrillingSimulation::process() const { return *impl_->process; }
const VirtualPatient& DrillingSimulation::patient() const { return impl_->patient; }
const VentilatorSample& DrillingSimulation::ventilatorSample() const { return impl_->vent_now; }

double DrillingSimulation::sensedTimeInBreath() const {
  const Impl& s = *impl_;
  const double start = s.breath_sensor_period == 0 || s.sensed_breath_index < 0
                           ? s.ventilator.breathStart()
                           : s.sensed_breath_start;
  return std::max(0.0, s.vent_now.t - start);
}

bool DrillingSimulation::breathFlowSampled() const { return impl_->breath_flow_sampled; }

const BreathScheduler& DrillingSimulation::ventilator() const { return impl_->ventilator; }

const BreathScheduler& DrillingSimulation::patientBreathing() const {
  return impl_->lagged_ventilator;
}

bool DrillingSimulation::startTrial() {
  const bool remount = impl_->process->maxDepthCut() > 0.0;
  if (remount) impl_->resetTrial(impl_->seed + 1, impl_->moving_bone);
  impl_->relative_ap0 = impl_->physics_tip.z() - impl_->bone_world.translation().z();
  impl_->was_in_contact = false;
  impl_->steps_without_contact = 0;
  impl_->contact_losses = 0;
  ++impl_->trial_count;
  return remount;
}

int DrillingSimulation::trialCount() const { return impl_->trial_count; }
int DrillingSimulation::armBlockSteps() const { return impl_->block_steps; }
std::uint64_t DrillingSimulation::armBlocksInAir() const { return impl_->air_blocks; }
bool DrillingSimulation::movingBone() const { return impl_->moving_bone; }
std::uint64_t DrillingSimulation::seed() const { return impl_->seed; }

const ImagingPlan& DrillingSimulation::imagingPlan() const { return impl_->imaging_plan; }
const BulletArm& DrillingSimulation::arm() const { return *impl_->arm; }
const DrillingSimulationParams& DrillingSimulation::params() const { return impl_->params; }

Eigen::Isometry3d DrillingSimulation::linkPose(const std::string& link) const {
  const Impl& s = *impl_;
  if (s.arm->hasLink(link)) return s.arm->linkPose(link);
  if (link == s.params.base_link) return Eigen::Isometry3d::Identity();
  // Walk up the URDF until an arm link, the base, or the floating platform joint.
  urdf::LinkConstSharedPtr l = s.model->getLink(link);
  if (!l) throw std::out_of_range("DrillingSimulation: no link '" + link + "'");
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  const std::map<std::string, double> spms_q = [&] {
    std::map<std::string, double> q;
    for (const auto& kv : spmsJointStates()) q[kv.first] = kv.second;
    return q;
  }();
  while (true) {
    if (s.arm->hasLink(l->name)) return s.arm->linkPose(l->name) * t;
    if (l->name == s.params.base_link) return t;
    if (!l->parent_joint) throw std::out_of_range("DrillingSimulation: link '" + link + "'");
    const urdf::Joint& j = *l->parent_joint;
    if (j.name == "spms_platform_joint") {
      t = s.platformInBase() * t;
    } else {
      auto it = spms_q.find(j.name);
      const double q = it == spms_q.end() ? 0.0 : it->second;
      t = toIsometry(j.parent_to_joint_origin_transform) * jointMotion(j, q) * t;
    }
    l = s.model->getLink(j.parent_link_name);
  }
}

SimulationGroundTruth DrillingSimulation::groundTruth() const {
  const Impl& s = *impl_;
  SimulationGroundTruth g;
  const DrillingProcess& p = *s.process;
  g.seed = s.seed;
  g.layer = s.cutLayer();
  g.tip_depth_m = s.tip_depth;
  g.max_depth_cut_m = p.maxDepthCut();
  g.outer_cortical_end_m = p.specimen().outerCorticalEnd();
  g.inner_cortical_start_m = p.specimen().innerCorticalStart();
  g.inner_cortical_end_m = p.specimen().innerCorticalEnd();
  g.residual_inner_cortical_m = p.residualInnerCorticalThickness();
  g.breakthrough = p.breakthrough();
  g.thrust_n = s.last_force.thrust_N;
  g.contact = s.last_force.contact;
  g.contact_loss_count = s.contact_losses;
  g.feed_per_rev_m = s.last_force.feed_per_rev_m;
  const Eigen::Vector3d d = s.bone_world.translation() - s.bone_home_world;
  g.bone_displacement_m = Eigen::Vector3d(d.y(), d.x(), d.z());  // LR = y, SI = x, AP = z
  g.tidal_volume_ml = s.vent_now.volume_ml;
  g.relative_ap_m = (s.physics_tip.z() - s.bone_world.translation().z()) - s.relative_ap0;
  g.spindle_rpm = s.spindle_rpm;
  g.feed_joint_m = s.feed_index >= 0 ? s.feed_drive.position() : 0.0;
  g.drives_halted = s.drives_halted;
  g.drive_guard_trips = static_cast<std::uint32_t>(s.drive_guard_trips);
  g.controller_aborts = static_cast<std::uint32_t>(s.controller_aborts);
  return g;
}

bool DrillingSimulation::trackerDue(std::uint64_t period_steps) const {
  const Impl& s = *impl_;
  if (period_steps == 0) return false;
  const auto offset = static_cast<std::uint64_t>(s.tracker_phase * period_steps);
  return (s.step_index + offset) % period_steps == 0;
}

Eigen::Isometry3d DrillingSimulation::measureMarkerPose() {
  Impl& s = *impl_;
  const Eigen::Isometry3d marker_world =
      s.spms_base_world * s.platformInBase() * s.marker_in_platform;
  // The tracker measures in its true frame; the pipeline reads it in the registered one.
  Eigen::Isometry3d m = s.camera_true_world.inverse() * marker_world;
  // A fresh generator per measurement (a pair's second deviate is not kept across samples), as
  // every trial recorded so far drew it; portable (common/portable_random.hpp).
  PolarNormal n(0.0, 1e-3 * s.params.tracker_noise_rms_mm / std::sqrt(3.0));
  m.translation() += Eigen::Vector3d(n(s.tracker_rng), n(s.tracker_rng), n(s.tracker_rng));
  return m;
}

std::vector<FrameTransform> DrillingSimulation::frameTransforms(bool fixed) const {
  const Impl& s = *impl_;
  std::vector<FrameTransform> out;
  std::map<std::string, double> spms_q;
  for (const auto& kv : spmsJointStates()) spms_q[kv.first] = kv.second;
  for (const auto& kv : s.model->joints_) {
    const urdf::Joint& j = *kv.second;
    const bool is_fixed = j.type == urdf::Joint::FIXED;
    if (is_fixed != fixed) continue;
    FrameTransform f;
    f.parent = j.parent_link_name;
    f.child = j.child_link_name;
    const Eigen::Isometry3d origin = toIsometry(j.parent_to_joint_origin_transform);
    if (is_fixed) {
      f.transform = origin;
    } else if (s.arm->hasLink(f.parent) && s.arm->hasLink(f.child)) {
      f.transform = s.arm->linkPose(f.parent).inverse() * s.arm->linkPose(f.child);
    } else if (j.name == "spms_platform_joint") {
      f.transform = s.platformInBase();
    } else {
      auto it = spms_q.find(j.name);
      f.transform = origin * jointMotion(j, it == spms_q.end() ? 0.0 : it->second);
    }
    out.push_back(f);
  }
  return out;
}

}  // namespace pedicle_drilling::core
