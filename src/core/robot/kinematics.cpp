// The KDL chain of a urdfdom model (kdl_parser), FK and IK.
#include "pedicle_drilling/core/robot/kinematics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include <urdf_parser/urdf_parser.h>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainiksolverpos_lma.hpp>
#include <kdl/chainiksolverpos_nr_jl.hpp>
#include <kdl/chainiksolvervel_pinv.hpp>
#include <kdl/frames.hpp>
#include <kdl/jntarray.hpp>
#include <kdl/tree.hpp>
#include <kdl_parser/kdl_parser.hpp>

#include "pedicle_drilling/core/common/portable_random.hpp"

namespace pedicle_drilling::core {

namespace {

/**
 * The links from the child of @p base_link down to @p tip_link, base first.
 * @throws std::invalid_argument for an unknown link or a base that is not an ancestor of the tip.
 */
std::vector<urdf::LinkConstSharedPtr> linkPath(const urdf::ModelInterface& model,
                                               const std::string& base_link,
                                               const std::string& tip_link) {
  if (!model.getLink(base_link)) {
    throw std::invalid_argument("base_link: unknown link '" + base_link + "'");
  }
  urdf::LinkConstSharedPtr link = model.getLink(tip_link);
  if (!link) throw std::invalid_argument("tip_link: unknown link '" + tip_link + "'");
  std::vector<urdf::LinkConstSharedPtr> path;  // tip ... first child of base
  while (link->name != base_link) {
    if (!link->parent_joint || !link->getParent()) {
      throw std::invalid_argument("base_link: '" + base_link + "' is not an ancestor of '" +
                                  tip_link + "'");
    }
    path.push_back(link);
    link = link->getParent();
  }
  std::reverse(path.begin(), path.end());
  return path;
}

/** kdl_parser converts other joint types to fixed ones (with a warning): refused here. */
void checkJointType(const urdf::Joint& j) {
  switch (j.type) {
    case urdf::Joint::FIXED:
    case urdf::Joint::REVOLUTE:
    case urdf::Joint::CONTINUOUS:
    case urdf::Joint::PRISMATIC:
      return;
    default:
      throw std::invalid_argument("joint '" + j.name +
                                  "': unsupported type (only revolute, continuous, prismatic, "
                                  "fixed)");
  }
}

/**
 * @p path (linkPath()) below a root named @p base_link, as a model of its own: copies of the
 * links, each with its joint (shared) and its one child on the path. kdl_parser converts a
 * whole model and warns through rosconsole, at every conversion, about each joint of the model
 * it cannot convert (the workcell's floating SPMS platform, on another branch) and about an
 * inertia of the root link; the path alone has neither.
 */
urdf::ModelInterface pathModel(const std::vector<urdf::LinkConstSharedPtr>& path,
                               const std::string& base_link) {
  urdf::ModelInterface m;
  m.root_link_ = std::make_shared<urdf::Link>();
  m.root_link_->name = base_link;
  m.links_[base_link] = m.root_link_;
  urdf::LinkSharedPtr parent = m.root_link_;
  for (const urdf::LinkConstSharedPtr& l : path) {
    auto link = std::make_shared<urdf::Link>(*l);
    link->child_links.clear();
    link->child_joints.clear();
    link->setParent(parent);
    parent->child_links.push_back(link);
    parent->child_joints.push_back(link->parent_joint);
    m.links_[link->name] = link;
    m.joints_[link->parent_joint->name] = link->parent_joint;
    parent = link;
  }
  return m;
}

/**
 * The KDL chain of @p path, converted by kdl_parser (the ROS convention: a segment's tip frame
 * is its joint's origin, the joint axis expressed in the parent link's frame).
 */
KDL::Chain kdlChain(const std::vector<urdf::LinkConstSharedPtr>& path, const std::string& base_link,
                    const std::string& tip_link) {
  KDL::Tree tree;
  KDL::Chain chain;
  if (!kdl_parser::treeFromUrdfModel(pathModel(path, base_link), tree) ||
      !tree.getChain(base_link, tip_link, chain)) {
    throw std::invalid_argument("urdf: kdl_parser cannot convert the chain '" + base_link +
                                "' -> '" + tip_link + "'");
  }
  return chain;
}

Eigen::Isometry3d toEigen(const KDL::Frame& f) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.linear()(r, c) = f.M(r, c);
    out.translation()(r) = f.p(r);
  }
  return out;
}

KDL::Frame toKdl(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d& R = T.linear();
  return KDL::Frame(KDL::Rotation(R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0),
                                  R(2, 1), R(2, 2)),
                    KDL::Vector(T.translation().x(), T.translation().y(), T.translation().z()));
}

void checkVector(const Eigen::VectorXd& q, unsigned int n, const char* what) {
  if (q.size() != static_cast<Eigen::Index>(n)) {
    throw std::invalid_argument(std::string(what) + ": expected " + std::to_string(n) +
                                " joint values, got " + std::to_string(q.size()));
  }
  if (!q.allFinite()) throw std::invalid_argument(std::string(what) + ": not finite");
}

}  // namespace

KinematicChain::KinematicChain(const urdf::ModelInterface& model, const std::string& base_link,
                               const std::string& tip_link)
    : base_(base_link), tip_(tip_link) {
  const std::vector<urdf::LinkConstSharedPtr> path = linkPath(model, base_link, tip_link);
  std::vector<double> lo, hi;
  for (const auto& l : path) {
    const urdf::Joint& j = *l->parent_joint;
    checkJointType(j);
    if (j.type == urdf::Joint::FIXED) continue;
    joint_names_.push_back(j.name);
    revolute_.push_back(j.type != urdf::Joint::PRISMATIC);
    if (j.type == urdf::Joint::CONTINUOUS || !j.limits) {
      lo.push_back(-std::numeric_limits<double>::infinity());
      hi.push_back(std::numeric_limits<double>::infinity());
    } else {
      if (!(j.limits->lower <= j.limits->upper)) {
        throw std::invalid_argument("joint '" + j.name + "': lower limit above upper limit");
      }
      lo.push_back(j.limits->lower);
      hi.push_back(j.limits->upper);
    }
  }
  chain_ = kdlChain(path, base_link, tip_link);
  lower_ = Eigen::Map<const Eigen::VectorXd>(lo.data(), static_cast<Eigen::Index>(lo.size()));
  upper_ = Eigen::Map<const Eigen::VectorXd>(hi.data(), static_cast<Eigen::Index>(hi.size()));
}

KinematicChain KinematicChain::fromUrdfString(const std::string& xml, const std::string& base_link,
                                              const std::string& tip_link) {
  const urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(xml);
  if (!model) throw std::invalid_argument("urdf: cannot parse the URDF XML");
  return KinematicChain(*model, base_link, tip_link);
}

bool KinematicChain::withinLimits(const Eigen::VectorXd& q, double tol) const {
  if (q.size() != lower_.size()) return false;
  for (Eigen::Index i = 0; i < q.size(); ++i) {
    if (q(i) < lower_(i) - tol || q(i) > upper_(i) + tol) return false;
  }
  return true;
}

Eigen::Isometry3d KinematicChain::forward(const Eigen::VectorXd& q) const {
  checkVector(q, numJoints(), "q");
  KDL::ChainFkSolverPos_recursive fk(chain_);
  KDL::JntArray jq(numJoints());
  jq.data = q;
  KDL::Frame f;
  if (fk.JntToCart(jq, f) < 0) throw std::runtime_error("forward kinematics failed");
  return toEigen(f);
}

IkResult KinematicChain::inverse(const Eigen::Isometry3d& target, const Eigen::VectorXd& seed,
                                 const IkOptions& options) const {
  const unsigned int n = numJoints();
  checkVector(seed, n, "seed");
  if (!target.matrix().allFinite()) throw std::invalid_argument("target: not finite");
  Eigen::Matrix<double, 6, 1> weights = Eigen::Matrix<double, 6, 1>::Ones();
  KDL::ChainIkSolverPos_LMA ik(chain_, weights, options.eps, options.max_iterations);
  // Second stage for LMA results outside the joint limits: Newton-Raphson with clamping.
  KDL::ChainFkSolverPos_recursive fk(chain_);
  KDL::ChainIkSolverVel_pinv ik_vel(chain_);
  KDL::JntArray q_min(n), q_max(n);
  for (unsigned int i = 0; i < n; ++i) {
    q_min(i) = std::isfinite(lower_(i)) ? lower_(i) : -1e9;
    q_max(i) = std::isfinite(upper_(i)) ? upper_(i) : 1e9;
  }
  KDL::ChainIkSolverPos_NR_JL ik_jl(
      chain_, q_min, q_max, fk, ik_vel, options.max_iterations,
      std::min(options.position_tolerance_m, options.orientation_tolerance_rad) * 1e-2);
  const KDL::Frame goal = toKdl(target);
  std::mt19937 rng(options.random_seed);

  IkResult best;
  best.q = seed;
  double best_cost = std::numeric_limits<double>::infinity();
  const double kPi = 3.14159265358979323846;
  for (int attempt = 0; attempt < std::max(1, options.max_attempts); ++attempt) {
    KDL::JntArray q0(n), q(n);
    if (attempt == 0) {
      q0.data = seed;
    } else {
      for (unsigned int i = 0; i < n; ++i) {
        const double lo = std::isfinite(lower_(i)) ? lower_(i) : -kPi;
        const double hi = std::isfinite(upper_(i)) ? upper_(i) : kPi;
        q0(i) = uniform(rng, lo, hi);
      }
    }
    ik.CartToJnt(q0, goal, q);
    Eigen::VectorXd qe = q.data;
    if (!qe.allFinite()) continue;
    for (unsigned int i = 0; i < n; ++i) {  // wrap revolute joints into their limits
      if (!revolute_[i]) continue;
      if (!std::isfinite(lower_(i))) {
        qe(i) = std::remainder(qe(i), 2.0 * kPi);
        continue;
      }
      while (qe(i) > upper_(i) && qe(i) - 2.0 * kPi >= lower_(i)) qe(i) -= 2.0 * kPi;
      while (qe(i) < lower_(i) && qe(i) + 2.0 * kPi <= upper_(i)) qe(i) += 2.0 * kPi;
    }
    if (!withinLimits(qe)) {
      KDL::JntArray qc(n), qj(n);
      for (unsigned int i = 0; i < n; ++i) qc(i) = std::clamp(qe(i), q_min(i), q_max(i));
      ik_jl.CartToJnt(qc, goal, qj);
      qe = qj.data;
      if (!qe.allFinite() || !withinLimits(qe)) continue;
    }
    const Eigen::Isometry3d reached = forward(qe);
    const double pe = (reached.translation() - target.translation()).norm();
    const double oe = Eigen::AngleAxisd(target.linear().transpose() * reached.linear()).angle();
    const double cost = pe / options.position_tolerance_m + oe / options.orientation_tolerance_rad;
    if (cost < best_cost) {
      best_cost = cost;
      best.q = qe;
      best.position_error_m = pe;
      best.orientation_error_rad = oe;
    }
    best.attempts = attempt + 1;
    if (pe < options.position_tolerance_m && oe < options.orientation_tolerance_rad) {
      best.success = true;
      best.message.clear();
      return best;
    }
  }
  best.attempts = std::max(1, options.max_attempts);
  if (!std::isfinite(best_cost)) {
    best.position_error_m = std::numeric_limits<double>::infinity();
    best.orientation_error_rad = std::numeric_limits<double>::infinity();
    best.message = "no solution within joint limits";
  } else {
    best.message = "did not converge: position error " + std::to_string(best.position_error_m) +
                   " m, orientation error " + std::to_string(best.orientation_error_rad) + " rad";
  }
  return best;
}

}  // namespace pedicle_drilling::core
