// Thin wrapper over KDL: serial chain from a urdfdom model (converted by kdl_parser), forward
// kinematics and position + orientation inverse kinematics with joint limits.
#ifndef PEDICLE_DRILLING_CORE_KINEMATICS_HPP_
#define PEDICLE_DRILLING_CORE_KINEMATICS_HPP_

#include <string>
#include <vector>

#include <urdf_model/model.h>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <kdl/chain.hpp>

namespace pedicle_drilling::core {

/** @brief Options of KinematicChain::inverse(). */
struct IkOptions {
  /** @brief LMA stop threshold on the weighted pose-error norm. */
  double eps = 1e-12;
  /** @brief LMA iterations per attempt. */
  int max_iterations = 500;
  /** @brief Attempts (1 from the seed, the rest from random configurations within limits). */
  int max_attempts = 20;
  /** @brief Success requires a position error below this [m]. */
  double position_tolerance_m = 1e-6;
  /** @brief Success requires an orientation error below this [rad]. */
  double orientation_tolerance_rad = 1e-6;
  /** @brief Seed of the random restarts (deterministic). */
  unsigned random_seed = 42;
};

/** @brief Result of KinematicChain::inverse(). */
struct IkResult {
  bool success = false;                ///< Within tolerances and joint limits.
  Eigen::VectorXd q;                   ///< Best joint vector found (within limits).
  double position_error_m = 0.0;       ///< |p(q) - p_target| [m].
  double orientation_error_rad = 0.0;  ///< Angle of R_target^T R(q) [rad].
  int attempts = 0;                    ///< Attempts used.
  std::string message;                 ///< Explanation on failure.
};

/** @brief A KDL serial chain between two links of a URDF model. */
class KinematicChain {
 public:
  /**
   * @brief Build the chain base_link -> tip_link. Supports revolute, continuous, prismatic and
   * fixed joints (origins and axes as in the URDF; mimic joints are treated as independent).
   * @throws std::invalid_argument for unknown links, base not an ancestor of tip, or floating /
   * planar / unknown joints on the path.
   */
  KinematicChain(const urdf::ModelInterface& model, const std::string& base_link,
                 const std::string& tip_link);

  /**
   * @brief Parse URDF XML with urdf::parseURDF and build the chain.
   * @throws std::invalid_argument if the XML does not parse or the chain cannot be built.
   */
  static KinematicChain fromUrdfString(const std::string& xml, const std::string& base_link,
                                       const std::string& tip_link);

  /** @brief Number of movable joints. */
  unsigned int numJoints() const { return chain_.getNrOfJoints(); }
  /** @brief Names of the movable joints, base to tip. */
  const std::vector<std::string>& jointNames() const { return joint_names_; }
  /** @brief Lower joint limits (-inf for continuous joints). */
  const Eigen::VectorXd& lowerLimits() const { return lower_; }
  /** @brief Upper joint limits (+inf for continuous joints). */
  const Eigen::VectorXd& upperLimits() const { return upper_; }
  /** @brief The underlying KDL chain. */
  const KDL::Chain& chain() const { return chain_; }
  /** @brief Base link name. */
  const std::string& baseLink() const { return base_; }
  /** @brief Tip link name. */
  const std::string& tipLink() const { return tip_; }

  /** @brief True if every q_i is within [lower_i - tol, upper_i + tol]. */
  bool withinLimits(const Eigen::VectorXd& q, double tol = 1e-9) const;

  /**
   * @brief Pose of the tip link in the base link frame.
   * @throws std::invalid_argument if q has the wrong size or is not finite.
   */
  Eigen::Isometry3d forward(const Eigen::VectorXd& q) const;

  /**
   * @brief Joint vector reaching `target` (tip pose in the base frame), position and
   * orientation, within joint limits. Levenberg-Marquardt (KDL::ChainIkSolverPos_LMA) from the
   * seed, then from random configurations within limits; revolute results are wrapped by 2 pi
   * into their limits when possible; a result still outside the limits is clamped and refined
   * with KDL::ChainIkSolverPos_NR_JL (joint-limited Newton-Raphson).
   * @throws std::invalid_argument if seed has the wrong size or is not finite.
   */
  IkResult inverse(const Eigen::Isometry3d& target, const Eigen::VectorXd& seed,
                   const IkOptions& options = IkOptions()) const;

 private:
  KDL::Chain chain_;
  std::string base_;
  std::string tip_;
  std::vector<std::string> joint_names_;
  std::vector<bool> revolute_;
  Eigen::VectorXd lower_;
  Eigen::VectorXd upper_;
};

}  // namespace pedicle_drilling::core

#endif  // PEDICLE_DRILLING_CORE_KINEMATICS_HPP_
