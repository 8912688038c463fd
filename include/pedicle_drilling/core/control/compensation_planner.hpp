// Active compensation planner of Algorithm 1 (paper Sec. IV-B), without ROS.
//
//   ventilator settings --VentilatorModel--> F(t), Tv(t)   (breath phase from the ventilator)
//   Tv(t), dTv/dt      --patient MotionModel--> predicted vertebra displacement y(t) (AP/SI/LR)
//   drill reference r(t) = feed_rate * (t - t_reg) * axis
//                          + [compensated] y(t + latency) - y(t_reg)
//   r(t)               --TrapezoidSegmenter (125 ms, a = 10 v)--> segments sent to the arm
//
// Frames: everything is in the world frame (metres). The displacement axes map to world
// directions (default AP = +z, SI = +y, LR = +x, as the simulator's SPMS platform). The drill axis
// is the unit drilling direction (default -z, straight down). The feed-joint coordinate of an
// offset r is r . axis; the lateral part r - (r . axis) axis goes to the arm (kinematics.hpp).
//
// Modes (StartTrial.mode, paper cases a-c): stationary (bone not moving; no prediction), uncom-
// pensated (bone moving, drill follows the feed only; the prediction still feeds the monitor),
// compensated (feed + predicted displacement).
#ifndef PEDICLE_DRILLING_CORE_COMPENSATION_PLANNER_HPP_
#define PEDICLE_DRILLING_CORE_COMPENSATION_PLANNER_HPP_

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "pedicle_drilling/core/breathing/motion_model.hpp"
#include "pedicle_drilling/core/breathing/ventilator.hpp"
#include "pedicle_drilling/core/common/param_table.hpp"
#include "pedicle_drilling/core/control/compensator_interface.hpp"
#include "pedicle_drilling/core/control/trapezoid_segmenter.hpp"
#include "pedicle_drilling/core/robot/kinematics.hpp"

namespace pedicle_drilling::core {

/** @brief Trial mode: the three cases of the paper's experiments (Sec. V). */
enum class CompensationMode {
  kStationary,     ///< case a: the bone does not move, the drill only feeds
  kUncompensated,  ///< case b: the bone moves, the drill only feeds
  kCompensated,    ///< case c: the bone moves, the drill feeds + follows the predicted motion
};

/** @brief "stationary", "uncompensated" or "compensated". */
const char* toString(CompensationMode mode);

/** @brief Parses a mode name (exact, lower case); returns false for an unknown name. */
bool parseCompensationMode(const std::string& name, CompensationMode* mode);

/** @brief Parameters of the planner (SI units: m, s). */
struct CompensationParams {
  /** @brief Feed rate along the drill axis [m/s] (paper: 0.5 mm/s). */
  double feed_rate_m_s = 0.5e-3;
  /** @brief Segment period T [s] (paper: 125 ms). */
  double period_s = 0.125;
  /** @brief Acceleration / cruise velocity ratio of the trapezoid [1/s] (paper: 10). */
  double accel_ratio = 10.0;
  /** @brief The planner commands the displacement predicted for now + latency_s [s], >= 0. */
  double latency_s = 0.0;
  /** @brief Trajectory points per segment, sampled from its trapezoid (>= 1; last = end). */
  int points_per_segment = 5;
  /**
   * @brief How the 125 ms segments join: kRestToRest (default, the paper's; each segment a
   *        trapezoid from rest to rest) or kExact (beyond the
   *        paper: the reference itself, points_per_segment samples per period with analytic
   *        velocities, plus knots at the flow steps).
   */
  SegmentProfile segment_profile = SegmentProfile::kRestToRest;
  /** @brief Which model axes are predicted (paper's experiments: AP only). */
  std::array<bool, 3> predict_axis{{true, false, false}};
  /** @brief If true, the lateral (off-drill-axis) part of the prediction is compensated. */
  bool compensate_lateral = false;
  /** @brief Unit drilling direction in the world frame. */
  Eigen::Vector3d drill_axis{0.0, 0.0, -1.0};
  /** @brief World directions of positive AP, SI and LR displacement (unit vectors). */
  std::array<Eigen::Vector3d, 3> axis_direction{
      {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 1, 0), Eigen::Vector3d(1, 0, 0)}};

  /**
   * @brief Check every field.
   * @throws std::invalid_argument whose message starts with the field name.
   */
  void validate() const;

  /** @brief The declaration of the fields a node sets (names as the ROS parameters). */
  static const ParamTable<CompensationParams>& table();
};

/**
 * @brief Predicted vertebra displacement from the ventilator settings, the breath phase and the
 * patient's model (Algorithm 1 lines 1-4).
 */
class DisplacementPredictor {
 public:
  /** @brief Predictor of `model`, using only the axes flagged in `params.predict_axis`. */
  DisplacementPredictor(const MotionModel& model, const CompensationParams& params);

  /** @brief New ventilator settings (solves the flow constants). @throws on invalid settings. */
  void setVentilator(const VentilatorSettings& settings);

  /** @brief Start time [s] of a breath (e.g. TidalVolume stamp - time_in_breath). */
  void setBreathStart(double t);

  /** @brief True once both the settings and a breath start are known. */
  bool ready() const { return ventilator_ != nullptr && have_phase_; }

  /** @brief Tidal volume [ml] and flow [ml/s] at time t (periodic extension of the breath). */
  VentilatorSample ventilatorAt(double t) const;

  /** @brief Predicted displacement [m] in the world frame at time t (absolute, includes q0). */
  Eigen::Vector3d displacement(double t) const;

  /**
   * @brief Times in (t0, t1] where the ventilator's flow is discontinuous (inspiration start,
   *        end of the inspiratory flow, end of the pause), where the predicted velocity steps.
   */
  std::vector<double> flowSteps(double t0, double t1) const;

  /** @brief The ventilator model (nullptr before setVentilator()). */
  const VentilatorModel* ventilator() const { return ventilator_.get(); }

 private:
  MotionModel model_;
  CompensationParams params_;
  std::shared_ptr<VentilatorModel> ventilator_;
  bool have_phase_ = false;
  double breath_start_ = 0.0;
};

/** @brief One trajectory point of a segment. */
struct PlannedPoint {
  double t = 0.0;                                       ///< absolute time [s]
  double feed_m = 0.0;                                  ///< feed offset along the axis [m]
  double feed_velocity_m_s = 0.0;                       ///< its velocity [m/s]
  Eigen::Vector3d lateral_m = Eigen::Vector3d::Zero();  ///< off-axis offset [m], world
};

/** @brief One 125 ms segment: start/end offsets and points sampled from its trapezoid. */
struct PlannedSegment {
  int index = 0;                     ///< k, counted from the registration time
  double t0 = 0.0;                   ///< start time [s]
  double t1 = 0.0;                   ///< end time [s]
  double feed_start_m = 0.0;         ///< feed offset at t0 [m]
  double feed_end_m = 0.0;           ///< feed offset at t1 [m]
  std::vector<PlannedPoint> points;  ///< points at t0 + i T / n, i = 1..n
};

/**
 * @brief Drill trajectory of one trial: feed + (mode-dependent) predicted displacement, cut into
 * trapezoidal segments. Offsets are relative to the tip position at registration time.
 */
class CompensationPlanner {
 public:
  /**
   * @brief Construct with the paper's compensator (PaperCompensator) of `model`.
   * @throws std::invalid_argument if params.validate() fails.
   */
  CompensationPlanner(const CompensationParams& params, const MotionModel& model);

  /**
   * @brief Construct with a compensator of any class, configured; setPatient(model,
   *        params) is called here. @throws std::invalid_argument if params.validate() fails or
   *        `compensator` is null.
   */
  CompensationPlanner(const CompensationParams& params, const MotionModel& model,
                      std::unique_ptr<CompensatorInterface> compensator);

  /** @brief The compensator (ventilator settings, breath phase, tracked marker go in here). */
  CompensatorInterface& compensator() { return *compensator_; }
  /** @brief The compensator (read only). */
  const CompensatorInterface& compensator() const { return *compensator_; }

  /**
   * @brief Start a trial at t_reg (the registration time of the marker).
   * @throws std::logic_error if the mode needs the compensator and it is not ready.
   */
  void start(CompensationMode mode, double t_reg);

  /**
   * @brief Stop the feed at time t: from then on the reference keeps the feed progress reached
   * at t but (in compensated mode) still follows the predicted bone motion, so that a stopped
   * drill does not collide with a bone moving towards it.
   */
  void holdFeed(double t);

  /** @brief True after holdFeed(). */
  bool feedHeld() const { return feed_held_; }

  /** @brief Mode of the current trial. */
  CompensationMode mode() const { return mode_; }
  /** @brief Registration time [s]. */
  double registrationTime() const { return t_reg_; }

  /**
   * @brief Predicted bone displacement [m, world] since registration, at t (zero when
   * stationary). This is what the monitor compares with the tracker.
   */
  Eigen::Vector3d boneDisplacementSinceStart(double t) const;

  /** @brief Commanded tip offset [m, world] at t: feed + compensation (at t + latency). */
  Eigen::Vector3d reference(double t) const;

  /** @brief The nominal feed at t [m]: feed rate x time since the registration, held by
   *         holdFeed() (reference() without the compensation). */
  double nominalFeed(double t) const;

  /** @brief Feed-axis part of reference(t) [m]. */
  double referenceFeed(double t) const { return reference(t).dot(axis_); }

  /**
   * @brief The tip's predicted advance into the bone along the drill axis since registration
   *        [m]: referenceFeed(t) minus the predicted bone displacement along the axis (the
   *        nominal feed when compensated or stationary; the feed against the breathing when
   *        uncompensated).
   */
  double predictedAdvance(double t) const {
    return referenceFeed(t) - boneDisplacementSinceStart(t).dot(axis_);
  }

  /**
   * @brief Segment k (t_k = t_reg + k T to t_k + T): points_per_segment samples of the segmented
   *        trajectory with their velocities; rest-to-rest segments go from reference(t_k) to
   *        reference(t_k + T) and end at rest; exact ones sample the reference itself.
   */
  PlannedSegment segment(int k) const;

  /** @brief Index of the segment containing t (0 before t_reg). */
  int segmentIndexAt(double t) const;

  /** @brief Position of the segmented trajectory at t (what an ideal controller executes). */
  Eigen::Vector3d segmentedReference(double t) const;

  /** @brief Position and velocity of the segmented trajectory at t (params().segment_profile). */
  SegmentSample segmentedSample(double t) const;

  /** @brief Parameters in use. */
  const CompensationParams& params() const { return params_; }
  /** @brief Unit drill axis. */
  const Eigen::Vector3d& axis() const { return axis_; }

  /**
   * @brief Velocity of reference() at t [m/s, world], one-sided: from the left (`left`) or
   *        the right, so that at a flow step it is the velocity before or after the step.
   */
  Eigen::Vector3d referenceVelocity(double t, bool left) const;

 private:
  PlannedSegment exactSegment(int k) const;

  CompensationParams params_;
  Eigen::Vector3d axis_;
  std::unique_ptr<CompensatorInterface> compensator_;
  TrapezoidSegmenter segmenter_;
  CompensationMode mode_ = CompensationMode::kStationary;
  double t_reg_ = 0.0;
  bool feed_held_ = false;
  double t_hold_ = 0.0;
  Eigen::Vector3d y_reg_ = Eigen::Vector3d::Zero();
};

/**
 * @brief Arm-side execution of the drill trajectory: the 6 arm joints hold the device base
 * `feed_home_m` behind the drilling pose along the drill axis (so that the feed joint at
 * `feed_home_m` puts the tip where the drilling pose puts it, and can retract for compensation),
 * and move it laterally by KDL inverse kinematics for SI/LR compensation.
 */
class ArmCompensation {
 public:
  /**
   * @brief Construct from the arm chain (base -> device base, 6 joints, drill axis = +z of the
   * chain tip) and the drilling-pose joint values of that chain.
   * @throws std::invalid_argument if the IK of the backed-off pose fails or inputs are bad.
   */
  ArmCompensation(const KinematicChain& arm, const Eigen::VectorXd& drilling_q, double feed_home_m);

  /** @brief Unit drill axis in the chain base frame (+z of the device base at the pose). */
  const Eigen::Vector3d& drillAxis() const { return axis_; }
  /** @brief Arm joints of the backed-off home pose. */
  const Eigen::VectorXd& homeJoints() const { return home_q_; }
  /** @brief Feed-joint value at home [m]. */
  double feedHome() const { return feed_home_; }
  /** @brief The drill tip at the drilling pose (feed home), world [m]: from the chain to the
   *         tip link (setTipAtPose), for the depth limit. */
  const std::optional<Eigen::Vector3d>& tipAtPose() const { return tip_at_pose_; }
  /** @brief Sets tipAtPose(). @throws std::invalid_argument if not finite. */
  void setTipAtPose(const Eigen::Vector3d& tip);
  /**
   * @brief The tip link's position [m, base frame] with the arm's joints at @p arm_q and every
   *        joint after them (the feed, the spindle) at 0: the drilling pose's tip.
   * @throws std::invalid_argument when the chain base -> tip_link does not start with the
   *         arm's joints @p arm_joints.
   */
  static Eigen::Vector3d tipAt(const std::string& urdf_xml, const std::string& base_link,
                               const std::string& tip_link,
                               const std::vector<std::string>& arm_joints,
                               const Eigen::VectorXd& arm_q);

  /**
   * @brief Arm joints moving the device base by `lateral` (world, m) from home; the IK is seeded
   * with `seed`. @throws std::runtime_error if the IK fails.
   */
  Eigen::VectorXd lateral(const Eigen::Vector3d& lateral, const Eigen::VectorXd& seed) const;

  /** @brief Arm joints of the drilling pose this was built with. */
  const Eigen::VectorXd& drillingJoints() const { return drilling_q_; }

  /**
   * @brief The drilling pose aimed at a target instead: the drill axis along @p direction and
   *        the tip (tipAtPose()'s point, carried with the device) @p standoff_m before @p entry
   *        on that axis, the device turned from this pose by the smallest rotation (its roll
   *        about the axis kept), solved by the arm's IK from this pose's joints within the
   *        joint limits. World frame (the chain's base).
   * @param why set when nothing is returned: the target is not finite, the tip is unknown,
   *        or the arm cannot reach the pose or back off from it by the feed's home.
   * @return the aimed arm (its tipAtPose() set), or nullopt.
   */
  std::optional<ArmCompensation> aimedAt(const Eigen::Vector3d& entry,
                                         const Eigen::Vector3d& direction, double standoff_m,
                                         std::string* why) const;

 private:
  KinematicChain arm_;
  Eigen::VectorXd drilling_q_;
  Eigen::Isometry3d drilling_pose_;
  Eigen::Isometry3d home_pose_;
  Eigen::Vector3d axis_;
  Eigen::VectorXd home_q_;
  double feed_home_;
  std::optional<Eigen::Vector3d> tip_at_pose_;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_COMPENSATION_PLANNER_HPP_
