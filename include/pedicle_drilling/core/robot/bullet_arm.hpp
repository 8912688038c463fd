// Copyright 2024 pedicle_drilling authors.
//
// Bullet (Featherstone btMultiBody) simulation of a serial robot chain built directly from a
// urdfdom model. Debian's Bullet 3.24 ships no URDF importer, so the multibody is assembled
// here: every moving joint on the chain base_link -> tip_link (revolute, continuous,
// prismatic) becomes one btMultibodyLink; links attached through fixed joints are merged into
// their moving parent (mass, centre of mass and inertia combined, frame offsets kept so that
// every merged URDF link frame can still be reported).
//
// Joint servo model (the "finite joint stiffness" of the arm)
// -------------------------------------------------------------
// Every joint is driven by a spring-damper about a reference position q_ref(t):
//
//   tau_i = g_i(q) - K_i (q_i - q_ref_i) - D_i (qdot_i - qdot_ref_i),   |tau_i| <= effort_i
//
// g(q) is model-based gravity compensation computed from the same link masses and centres of
// mass Bullet integrates (exact static balance of gravity, so the only static deflection left
// comes from external forces: delta_q = K^-1 J^T F). K_i is a real, finite stiffness in Nm/rad
// or N/m, D_i = 2 zeta sqrt(K_i m_i) with m_i the effective inertia 1/(M^-1)_ii seen by the
// joint. The spring-damper is integrated IMPLICITLY each sub-step (the torque is solved from the
// velocity at the end of the sub-step, using the joint-space inverse mass matrix obtained from
// Bullet's articulated-body algorithm), so stiff joints carrying tiny inertias (spindle,
// flange roll) stay stable at a 1 kHz sub-step.
//
// Stiffness defaults: revolute joints K = 60 rad^-1 x URDF effort limit, which gives
// 1.98e4 Nm/rad for the 330 Nm shoulder/base joints of RSSSII, 9.0e3 Nm/rad for the 150 Nm
// elbow and 1.7e3-3.4e3 Nm/rad for the wrist. 2e4 Nm/rad is the order of magnitude of the
// torsional stiffness of a size 25-32 strain-wave gear once motor-side servo and structural
// compliance are put in series (manufacturer catalogues give 1e4-1e5 Nm/rad for the gear
// alone). The paper (Sec. V-E) blames one failure of the stationary case on the 6-DoF serial
// arm being less stiff than a 3-axis linear robot: with these values a 3 N axial drilling force
// at the drilling pose (config/drilling_pose.yaml) deflects the tip by 0.154 mm (0.120 mm along
// the force; lateral 3 N forces give 0.26-0.34 mm), measured in test_bullet_arm.cpp and equal
// within 1 % to the joint-compliance prediction J K^-1 J^T F. That is the same order as the
// 0.06 mm feed of one 125 ms compensation segment at 0.5 mm/s. Feed axis: 5e5 N/m
// (ball/lead-screw servo, 6 um at 3 N). Continuous joints (spindle): 1 Nm/rad (the spindle is
// velocity-controlled; its reference angle is integrated from the velocity target).
//
// Frames: all poses are expressed in the frame of base_link (the fixed base). Gravity is a
// vector in that frame (default (0, 0, -9.81)).
#ifndef PEDICLE_DRILLING_CORE_BULLET_ARM_HPP
#define PEDICLE_DRILLING_CORE_BULLET_ARM_HPP

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "pedicle_drilling/core/common/component_profile.hpp"

#include "pedicle_drilling/core/robot/target_result.hpp"

namespace pedicle_drilling::core {

/// @brief Parameters of the Bullet arm simulation and its joint servos.
struct BulletArmParams {
  /// @brief Fixed physics sub-step [s]; step(dt) runs as many sub-steps as fit in dt.
  double substep = 1.0e-3;
  /// @brief Gravity in the base_link frame [m/s^2].
  Eigen::Vector3d gravity = Eigen::Vector3d(0.0, 0.0, -9.81);
  /// @brief Add model-based gravity compensation torques to the servo command.
  bool gravity_compensation = true;
  /// @brief Revolute joint stiffness per Nm of URDF effort limit [Nm/rad per Nm] (K = c * effort).
  double revolute_stiffness_per_effort = 60.0;
  /// @brief Revolute stiffness used when the URDF gives no effort limit [Nm/rad].
  double revolute_stiffness_default = 2.0e4;
  /// @brief Prismatic joint stiffness [N/m].
  double prismatic_stiffness = 5.0e5;
  /// @brief Continuous joint stiffness about the integrated reference angle [Nm/rad].
  double continuous_stiffness = 1.0;
  /// @brief Per-joint stiffness overrides by joint name [Nm/rad or N/m]; take precedence.
  std::map<std::string, double> joint_stiffness;
  /// @brief Damping ratio zeta of every joint servo, relative to the joint's effective inertia.
  double damping_ratio = 1.0;
  /// @brief Out-of-limit position targets: true = clamp to the limit (status kClamped),
  /// false = reject the whole command (status kRejected).
  bool clamp_out_of_limit_targets = true;
  /// @brief Saturate each joint command at the URDF effort limit (if the URDF gives one > 0).
  bool enforce_effort_limits = true;
  /// @brief Add Bullet joint-limit constraints (hard stops) at the URDF position limits.
  bool hard_joint_limits = true;
  /// @brief The servo's implicit solve reuses the joint-space inverse inertia M^-1 until a joint
  /// has moved more than this from where it was computed [rad for revolute, m for prismatic
  /// joints]; 0 = computed every sub-step (one articulated-body pass per joint). A rotor (a
  /// continuous last joint whose body is symmetric about its axis: the spindle) does not change
  /// M and is not watched. M^-1 sets only the servo's damping and the implicit step's
  /// stability, never a static deflection (K (q - q_ref) balances the loads whatever it is).
  double inverse_inertia_tolerance = 0.0;
  /// @brief Advance the multibody through Bullet's own passes, in the order
  /// btMultiBodyDynamicsWorld::stepSimulation runs them (forces and gravity, the articulated-body
  /// pass, the solver's velocity deltas, position integration), without the world's collision,
  /// island and constraint-solver passes, whenever they have nothing to do: the world holds only
  /// this arm (no collision object, no other constraint) and every limited joint is strictly
  /// inside its limits (Bullet 3.24's joint-limit constraint makes a row only at or beyond a
  /// limit). Otherwise, or when false, the world's stepSimulation. Bit-identical to it (gtest).
  bool direct_world_step = true;
};

/// @brief Type of a simulated (moving) joint.
enum class ArmJointType { kRevolute, kContinuous, kPrismatic };

/// @brief Static description of one simulated joint (from the URDF plus the servo model).
struct ArmJointInfo {
  std::string name;
  ArmJointType type = ArmJointType::kRevolute;
  double lower = 0.0;      ///< position limit [rad or m] (-inf for continuous)
  double upper = 0.0;      ///< position limit [rad or m] (+inf for continuous)
  double velocity = 0.0;   ///< velocity limit [rad/s or m/s] (inf if the URDF gives none)
  double effort = 0.0;     ///< effort limit [Nm or N] (inf if the URDF gives none)
  double stiffness = 0.0;  ///< servo stiffness [Nm/rad or N/m]
};

/// @brief Fixed-base Bullet multibody of the URDF chain base_link -> tip_link with stiff
/// (finite-stiffness) joint position/velocity servos, gravity and gravity compensation.
class BulletArm {
 public:
  /// @brief Builds the world and the multibody from URDF XML text.
  /// @param urdf_xml   URDF document (not a file name).
  /// @param base_link  fixed root link of the simulated chain (e.g. "world").
  /// @param tip_link   last link of the chain (e.g. "drill_tip"); must descend from base_link.
  /// @throws std::runtime_error if the URDF does not parse, a link is missing, tip_link does
  ///         not descend from base_link, or the chain contains floating/planar joints.
  BulletArm(const std::string& urdf_xml, const std::string& base_link, const std::string& tip_link,
            const BulletArmParams& params = BulletArmParams());
  ~BulletArm();
  BulletArm(const BulletArm&) = delete;
  BulletArm& operator=(const BulletArm&) = delete;

  /// @brief Names of the simulated joints, base to tip (fixed joints excluded).
  const std::vector<std::string>& jointNames() const;
  /// @brief Number of simulated joints.
  int numJoints() const;
  /// @brief Limits, type and servo stiffness of every simulated joint, base to tip.
  const std::vector<ArmJointInfo>& jointInfo() const;
  /// @brief True if linkPose(name) is available.
  bool hasLink(const std::string& name) const;

  /// @brief Sets position targets for all joints (velocity feed-forward reset to zero).
  /// NaN/inf or a wrong size rejects the command; out-of-limit values are clamped or rejected
  /// per BulletArmParams::clamp_out_of_limit_targets. A rejected command changes nothing.
  TargetResult setJointPositionTargets(const Eigen::VectorXd& q);
  /// @brief Sets position targets for the named joints only (others keep their targets).
  TargetResult setJointPositionTargets(const std::map<std::string, double>& q);
  /// @brief Sets velocity targets for all joints. The servo keeps its stiffness: the reference
  /// position is integrated from the velocity target each sub-step and stops at the position
  /// limits. Values above the URDF velocity limit are clamped; NaN/inf rejects the command.
  TargetResult setJointVelocityTargets(const Eigen::VectorXd& qdot);
  /// @brief Velocity targets for the named joints only (others keep their targets).
  TargetResult setJointVelocityTargets(const std::map<std::string, double>& qdot);
  /// @brief Position targets for the joints at `index` (positions in jointNames()), the others
  /// keeping theirs: setJointPositionTargets(named) without the names, for a per-step caller
  /// that resolved them once. An index out of range rejects the command.
  TargetResult setJointPositionTargets(const std::vector<int>& index,
                                       const Eigen::VectorXd& positions);
  /// @brief Velocity targets for the joints at `index`: setJointVelocityTargets(named) without
  /// the names.
  TargetResult setJointVelocityTargets(const std::vector<int>& index,
                                       const Eigen::VectorXd& velocities);
  /// @brief Teleports the joints to q (zero velocity) and sets the position targets to q.
  TargetResult resetJointState(const Eigen::VectorXd& q);

  /// @brief Advances the simulation by dt using fixed sub-steps of params.substep; a remainder
  /// shorter than one sub-step is carried over to the next call. Returns the sub-steps run.
  int step(double dt);
  /// @brief Times Bullet's world steps into @p profile (Component::kBulletWorld; nullptr: off;
  /// not owned, must outlive the arm or be reset to nullptr).
  void setProfile(ComponentProfile* profile);
  /// @brief Simulated time [s].
  double simTime() const;

  /// @brief How many times the joint-space inverse inertia has been computed (one per sub-step
  /// when inverse_inertia_tolerance is 0).
  std::uint64_t inverseInertiaUpdates() const;
  /// @brief How many sub-steps advanced the multibody directly (BulletArmParams::
  /// direct_world_step) rather than through the world's stepSimulation.
  std::uint64_t directWorldSteps() const;

  /// @brief Joint positions [rad or m], base to tip.
  Eigen::VectorXd jointPositions() const;
  /// @brief Joint velocities [rad/s or m/s], base to tip.
  Eigen::VectorXd jointVelocities() const;
  /// @brief Current servo reference positions.
  Eigen::VectorXd jointPositionTargets() const;
  /// @brief Current servo reference velocities.
  Eigen::VectorXd jointVelocityTargets() const;
  /// @brief Joint torques/forces commanded in the last sub-step (gravity comp + servo).
  Eigen::VectorXd jointEfforts() const;
  /// @brief Servo stiffness of every joint [Nm/rad or N/m].
  Eigen::VectorXd jointStiffness() const;
  /**
   * @brief Scales the servo stiffness of every revolute and prismatic joint by `scale` relative
   *        to the URDF-derived value (continuous joints keep theirs); damping follows, as it is
   *        recomputed from the stiffness each step. @throws std::invalid_argument unless
   *        0 < scale <= 10 and finite.
   */
  void setStiffnessScale(double scale);
  /// @brief Sets the sub-step [s] of the following step() calls (the servo's implicit step is
  /// refactorised for it). @throws std::invalid_argument unless positive and finite.
  void setSubstep(double h);

  /// @brief Pose of any URDF link of the chain (including links merged through fixed joints)
  /// in the base_link frame. @throws std::out_of_range for an unknown link.
  Eigen::Isometry3d linkPose(const std::string& name) const;
  /// @brief Pose of tip_link in the base_link frame.
  Eigen::Isometry3d tipPose() const;
  /// @brief Geometric Jacobian of the tip_link origin, 6 x n: rows 0-2 linear velocity, rows
  /// 3-5 angular velocity, both in the base_link frame.
  Eigen::MatrixXd tipJacobian() const;
  /// @brief Quasi-static tip displacement predicted from the joint stiffness alone for a force
  /// F at the tip: J_v K^-1 J_v^T F (rigid links, linearised at the current configuration).
  Eigen::Vector3d predictedTipDeflection(const Eigen::Vector3d& force) const;

  /// @brief Applies a constant force [N] (base_link frame) at the tip_link origin from the
  /// next sub-step on, until changed. Pass zero to release. Non-finite forces are ignored and
  /// reported by returning false.
  bool applyTipForce(const Eigen::Vector3d& world_force);
  /// @brief The force currently applied at the tip.
  Eigen::Vector3d tipForce() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_BULLET_ARM_HPP
