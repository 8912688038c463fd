/**
 * @file spms_kinematics.hpp
 * @brief Kinematics of the SPMS 3-PRS parallel platform (paper Sec. II-B, Fig. 3).
 *
 * Three identical legs at 120 deg: a motor drives a lead screw (via a belt), the screw moves a
 * slider along its rail (P, actuated), a revolute joint on the slider (R, axis tangential to the
 * base circle) carries a fixed-length rod, and a spherical joint (S) connects the rod to the
 * moving platform. The platform has 3 DoF: heave z, roll, pitch. The remaining coordinates
 * x, y, yaw are not free: each rod is confined to the vertical radial plane of its leg, which
 * forces small "parasitic" x, y, yaw motions that are computed as dependent coordinates.
 *
 * Frames: base frame with origin at the centre of the base circle, z up. Leg i (i = 0, 1, 2) is
 * at azimuth theta_i = leg_azimuth_offset + i * 120 deg. Platform orientation is
 * R = Rz(yaw) * Ry(pitch) * Rx(roll). Pose z is the heave relative to the home height (all
 * sliders at home_slider_m, zero tilt). Geometry defaults are plausible bench-top dimensions
 * (the paper gives none), see doc/simulator_physics.md.
 *
 * No ROS headers; C++17 and Eigen only.
 */
#ifndef PEDICLE_DRILLING_CORE_SPMS_KINEMATICS_HPP
#define PEDICLE_DRILLING_CORE_SPMS_KINEMATICS_HPP

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <limits>
#include <string>

namespace pedicle_drilling::core {

/** @brief SPMS geometry (metres / degrees). */
struct SpmsGeometry {
  double base_radius_m = 0.150;          ///< radius of the rail base points on the base plane
  double platform_radius_m = 0.100;      ///< radius of the spherical-joint centres on the platform
  double rod_length_m = 0.200;           ///< revolute-to-spherical joint distance
  double rail_inclination_deg = 0.0;     ///< rail tilt from vertical, + = top leans toward centre
  double slider_min_m = 0.050;           ///< lower end of slider travel along the rail
  double slider_max_m = 0.250;           ///< upper end of slider travel along the rail
  double home_slider_m = 0.150;          ///< slider position at the home pose (mid-stroke)
  double leg_azimuth_offset_deg = 90.0;  ///< azimuth of leg 0
  double max_spherical_tilt_deg = 30.0;  ///< max angle between rod and platform normal
};

/** @brief The three independent platform coordinates of a 3-PRS. */
struct PlatformPose {
  double z_m = 0.0;        ///< heave relative to the home height (AP direction in the setup)
  double roll_rad = 0.0;   ///< rotation about base x
  double pitch_rad = 0.0;  ///< rotation about base y
};

/** @brief Full 6-D platform pose: independent z, roll, pitch plus dependent x, y, yaw. */
struct PlatformFullPose {
  double x_m = 0.0;        ///< parasitic translation x (dependent)
  double y_m = 0.0;        ///< parasitic translation y (dependent)
  double z_m = 0.0;        ///< heave relative to the home height
  double roll_rad = 0.0;   ///< rotation about base x
  double pitch_rad = 0.0;  ///< rotation about base y
  double yaw_rad = 0.0;    ///< parasitic rotation about z (dependent)
  /** @brief Rotation Rz(yaw) Ry(pitch) Rx(roll). */
  Eigen::Matrix3d rotation() const;
  /** @brief Platform-centre position in the base frame (includes the home height). */
  Eigen::Vector3d position(double home_height_m) const;
};

/** @brief Result of an inverse-kinematics query. */
struct SpmsIkResult {
  bool reachable = false;  ///< all checks passed
  std::string reason;      ///< empty if reachable, otherwise the first failed check
  Eigen::Vector3d sliders = Eigen::Vector3d::Zero();  ///< slider positions along the rails [m]
  PlatformFullPose pose;  ///< full pose including the dependent coordinates
};

/** @brief Result of a forward-kinematics query. */
struct SpmsFkResult {
  bool ok = false;        ///< converged and all checks passed
  std::string reason;     ///< empty if ok
  PlatformFullPose pose;  ///< solved pose
  /// pose.rotation(), as computed for the last residual (the same bits: no second evaluation)
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  int iterations = 0;       ///< Newton iterations used
  double residual_m = 0.0;  ///< max |rod length error| at the solution [m]
};

/**
 * @brief A rod-length Jacobian kept between SpmsKinematics::forward() calls, with its
 * factorisation (a caller stepping the platform every millisecond keeps one).
 */
struct SpmsFkJacobian {
  /// The Jacobian; non-finite (the default) makes forward() compute one.
  Eigen::Matrix3d matrix = Eigen::Matrix3d::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::FullPivLU<Eigen::Matrix3d> lu;  ///< the factorisation of `matrix` when `factorised`
  bool factorised = false;               ///< `lu` is of the present `matrix`
  /** @brief Forget the Jacobian (the next forward() computes one). */
  void reset() {
    matrix.setConstant(std::numeric_limits<double>::quiet_NaN());
    factorised = false;
  }
};

/**
 * @brief Lead-screw drive of one leg: motor -> belt -> screw -> slider.
 *
 * Default: 5 mm lead (e.g. a 16 mm ball screw with 5 mm lead, "1605" catalogue size) with a 1:1
 * belt; slider position = zero_offset + lead * motor_angle / (2 pi * belt_reduction).
 */
struct LeadScrew {
  double lead_m_per_rev = 0.005;  ///< slider travel per screw revolution
  double belt_reduction = 1.0;    ///< motor revolutions per screw revolution
  double zero_offset_m = 0.0;     ///< slider position at motor angle 0
  /** @brief Slider position [m] from the motor angle [rad]. */
  double sliderFromMotorAngle(double motor_angle_rad) const;
  /** @brief Motor angle [rad] for a slider position [m]. */
  double motorAngleFromSlider(double slider_m) const;
};

/**
 * @brief Inverse/forward kinematics and workspace checks of the 3-PRS SPMS.
 */
class SpmsKinematics {
 public:
  /** @brief Builds the model; throws std::invalid_argument for inconsistent geometry. */
  explicit SpmsKinematics(SpmsGeometry geometry = {});

  /**
   * @brief Inverse kinematics: slider positions for a desired (z, roll, pitch).
   *
   * Also returns the dependent x, y, yaw. Unreachable poses return reachable = false with the
   * reason (rod cannot reach, slider out of stroke, spherical joint over its tilt limit,
   * dependent-coordinate solve failed).
   */
  SpmsIkResult inverse(const PlatformPose& pose) const;

  /** @brief Convenience: pure displacement along the platform normal (AP heave), no tilt. */
  SpmsIkResult inverseHeave(double z_m) const;

  /**
   * @brief Forward kinematics: (z, roll, pitch) and dependent x, y, yaw from slider positions.
   *
   * Newton iteration on the three rod-length constraints in (z, roll, pitch); for each iterate
   * the dependent x, y, yaw are solved from the three leg-plane constraints. Starts from
   * `initial_guess` (default: home). Converges to < 1e-12 m on the rod-length residual.
   *
   * `jacobian` (optional, in/out): a rod-length Jacobian from an earlier call near this pose,
   * and its factorisation; the iteration reuses both (a chord iteration, one residual per step
   * instead of seven, no new factorisation) and recomputes them by central differences only
   * when the residual stops falling tenfold per step. Same convergence test; a caller stepping
   * the platform every millisecond passes the same object each time. A non-finite matrix is
   * recomputed.
   */
  SpmsFkResult forward(const Eigen::Vector3d& sliders,
                       const PlatformPose& initial_guess = PlatformPose{},
                       SpmsFkJacobian* jacobian = nullptr) const;

  /**
   * @brief Dependent coordinates: the x, y, yaw forced by the leg planes for (roll, pitch).
   * @return false if the solve did not converge
   */
  bool dependentCoordinates(const PlatformPose& pose, PlatformFullPose* full) const;

  /** @brief Workspace check only (same as inverse(pose).reachable, with reason). */
  bool isReachable(const PlatformPose& pose, std::string* reason = nullptr) const;

  /** @brief Platform-centre height above the base plane at the home pose [m]. */
  double homeHeight() const { return home_height_m_; }
  /** @brief Spherical-joint centre i in the base frame for a full pose. */
  Eigen::Vector3d platformJoint(int i, const PlatformFullPose& pose) const;
  /** @brief The same with the pose's rotation() already computed (once per pose, not per leg). */
  Eigen::Vector3d platformJoint(int i, const PlatformFullPose& pose,
                                const Eigen::Matrix3d& rotation) const;
  /** @brief Revolute-joint (slider) centre i in the base frame for slider position s [m]. */
  Eigen::Vector3d sliderPoint(int i, double s_m) const;
  /** @brief Unit rail direction of leg i. */
  const Eigen::Vector3d& railDirection(int i) const { return rail_dir_[i]; }
  /** @brief The geometry in use. */
  const SpmsGeometry& geometry() const { return geometry_; }

 private:
  /** @brief Why a converged forward solution is not an assembly of the platform ("": it is):
   * the slider-above-joint branch or a spherical joint over its tilt limit. */
  std::string assemblyProblem(const Eigen::Vector3d& sliders, const PlatformFullPose& pose,
                              const Eigen::Matrix3d& rotation) const;
  SpmsGeometry geometry_;
  double tilt_certainly_within_cos_ = 1.0;  ///< see the constructor
  Eigen::Vector3d base_point_[3];
  Eigen::Vector3d rail_dir_[3];
  Eigen::Vector3d tangent_[3];
  Eigen::Vector3d platform_local_[3];
  double home_height_m_ = 0.0;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_SPMS_KINEMATICS_HPP
