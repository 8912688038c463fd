// Copyright 2024 pedicle_drilling authors.
//
// Bullet multibody built from a urdfdom model; see bullet_arm.hpp for the servo model.
//
// Mapping URDF -> btMultiBody (written from the Bullet and URDF conventions, not from Bullet's
// example importer):
//  * A "body" is one moving URDF link (or base_link) plus every link hanging off it through
//    fixed joints. Its reference frame H is the URDF frame of that moving link.
//  * Bullet wants each link frame at the centre of mass with a diagonal inertia tensor, so each
//    body gets C = (com, principal axes) expressed in H; the Bullet link frame is B = H * C.
//  * For a joint with frame J (in the parent body's H_p) and axis a (in J):
//      rotParentToThis            = rotation of (C_p^-1 * J * C_c)^-1        (q = 0)
//      jointAxis (in B_c)         = R_Cc^T a
//      parentComToThisPivotOffset = C_p^-1 * origin(J)                       (in B_p)
//      thisPivotToThisComOffset   = R_Cc^T com_c                             (in B_c)
//    which holds for revolute (H_c = J * Rot(a, q)) and prismatic (H_c = J * Trans(a q)) joints.
#include "pedicle_drilling/core/robot/bullet_arm.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <utility>

#include <urdf_model/model.h>
#include <Eigen/Dense>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter"
#pragma GCC diagnostic ignored "-Wunused-variable"
#pragma GCC diagnostic ignored "-Wreorder"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wclass-memaccess"
#include <BulletCollision/BroadphaseCollision/btDbvtBroadphase.h>
#include <BulletCollision/CollisionDispatch/btCollisionDispatcher.h>
#include <BulletCollision/CollisionDispatch/btDefaultCollisionConfiguration.h>
#include <BulletDynamics/Featherstone/btMultiBody.h>
#include <BulletDynamics/Featherstone/btMultiBodyConstraintSolver.h>
#include <BulletDynamics/Featherstone/btMultiBodyDynamicsWorld.h>
#include <BulletDynamics/Featherstone/btMultiBodyJointLimitConstraint.h>
#include <BulletDynamics/Featherstone/btMultiBodyLink.h>
#pragma GCC diagnostic pop

#include "pedicle_drilling/core/robot/urdf_model.hpp"

namespace pedicle_drilling::core {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
/// Tolerance on position limits before a target counts as out of range.
constexpr double kLimitTolerance = 1e-9;
/// Minimum mass/inertia given to a moving body that has none in the URDF (keeps the
/// articulated-body algorithm non-singular).
constexpr double kMinMass = 1e-3;
constexpr double kMinInertia = 1e-9;

Eigen::Isometry3d toEigen(const urdf::Pose& p) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  double x, y, z, w;
  p.rotation.getQuaternion(x, y, z, w);
  t.linear() = Eigen::Quaterniond(w, x, y, z).normalized().toRotationMatrix();
  t.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  return t;
}

btVector3 toBt(const Eigen::Vector3d& v) {
  return btVector3(btScalar(v.x()), btScalar(v.y()), btScalar(v.z()));
}

Eigen::Vector3d toEigen(const btVector3& v) { return Eigen::Vector3d(v.x(), v.y(), v.z()); }

btQuaternion toBtQuat(const Eigen::Matrix3d& r) {
  Eigen::Quaterniond q(r);
  q.normalize();
  return btQuaternion(btScalar(q.x()), btScalar(q.y()), btScalar(q.z()), btScalar(q.w()));
}

Eigen::Isometry3d toEigen(const btTransform& t) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  const btQuaternion q = t.getRotation();
  out.linear() = Eigen::Quaterniond(q.w(), q.x(), q.y(), q.z()).normalized().toRotationMatrix();
  out.translation() = toEigen(t.getOrigin());
  return out;
}

btTransform toBt(const Eigen::Isometry3d& t) {
  return btTransform(toBtQuat(t.linear()), toBt(Eigen::Vector3d(t.translation())));
}

}  // namespace

struct BulletArm::Impl {
  ComponentProfile* profile = nullptr;  ///< setProfile(): Bullet's world steps timed into it
  /// One rigid body of the multibody (index 0 = fixed base).
  struct Body {
    std::string head_link;
    Eigen::Isometry3d com_frame = Eigen::Isometry3d::Identity();  ///< C, in the head frame
    double mass = 0.0;
    Eigen::Vector3d inertia = Eigen::Vector3d::Zero();  ///< principal moments
  };
  /// Where a URDF link lives: body index and its frame in the body's head frame.
  struct LinkRef {
    int body = 0;
    Eigen::Isometry3d head_to_link = Eigen::Isometry3d::Identity();
  };
  /// Moving joint data needed at run time.
  struct JointData {
    Eigen::Vector3d axis_local = Eigen::Vector3d::UnitZ();   ///< axis in the Bullet frame
    Eigen::Vector3d pivot_to_com = Eigen::Vector3d::Zero();  ///< in the Bullet frame
  };

  BulletArmParams params;
  std::string base_link;
  std::string tip_link;
  const LinkRef* tip_ref = nullptr;  // links[tip_link] (set by build; map nodes are stable)
  std::vector<Body> bodies;
  std::map<std::string, LinkRef> links;
  std::vector<ArmJointInfo> joint_info;
  std::vector<std::string> joint_names;
  std::vector<JointData> joint_data;

  // Bullet objects (destroyed in reverse order in ~Impl).
  std::unique_ptr<btDefaultCollisionConfiguration> collision_config;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btDbvtBroadphase> broadphase;
  std::unique_ptr<btMultiBodyConstraintSolver> solver;
  std::unique_ptr<btMultiBodyDynamicsWorld> world;
  std::unique_ptr<btMultiBody> mb;
  std::vector<std::unique_ptr<btMultiBodyJointLimitConstraint>> limit_constraints;

  // Servo state.
  Eigen::VectorXd q_ref, qd_ref, stiffness, tau_last;
  Eigen::Vector3d tip_force = Eigen::Vector3d::Zero();
  double sim_time = 0.0;
  double time_accum = 0.0;

  // Scratch.
  btAlignedObjectArray<btScalar> scratch_r;
  btAlignedObjectArray<btVector3> scratch_v;
  btAlignedObjectArray<btMatrix3x3> scratch_m;
  btAlignedObjectArray<btQuaternion> scratch_q;
  btAlignedObjectArray<btVector3> scratch_p;
  std::vector<btScalar> force_buf, accel_buf;
  std::vector<Eigen::Isometry3d> body_pose;  // by body index, as of the last forwardKinematics()
  // The sub-step's and the target setters' vectors, kept so that a step allocates less.
  Eigen::VectorXd step_q, step_qd, step_gravity, step_tau_gc, step_v_free, step_tau0, step_v_plus,
      step_load, step_tau;
  Eigen::VectorXd target_values;
  std::vector<bool> target_mask;
  std::vector<Eigen::Vector3d> gravity_com;

  // The joint-space inverse inertia and the joint positions it was computed at (size 0: none).
  Eigen::MatrixXd a_inv;
  Eigen::VectorXd q_at_a_inv;
  std::vector<bool> rotor;  // joints whose motion leaves M unchanged (not watched)
  std::uint64_t a_inv_updates = 0;
  std::uint64_t direct_steps = 0;
  // The implicit servo's damping, I + h A B's factorisation and B (valid until A or K change).
  Eigen::PartialPivLU<Eigen::MatrixXd> servo_lu;
  Eigen::VectorXd servo_damping, servo_b;
  bool servo_valid = false;
  bool inverseInertiaStale(const Eigen::VectorXd& q) const;
  void updateInverseInertia(const Eigen::VectorXd& q);
  bool isRotor(int k) const;

  ~Impl() {
    if (world) {
      for (auto& c : limit_constraints) world->removeMultiBodyConstraint(c.get());
      if (mb) world->removeMultiBody(mb.get());
    }
    limit_constraints.clear();
    mb.reset();
    world.reset();
    solver.reset();
    broadphase.reset();
    dispatcher.reset();
    collision_config.reset();
  }

  int n() const { return static_cast<int>(joint_info.size()); }

  void build(const std::string& urdf_xml);
  std::shared_ptr<const urdf::ModelInterface> parseModel(const std::string& urdf_xml) const;
  std::vector<urdf::JointConstSharedPtr> movingJoints(const urdf::ModelInterface& model) const;
  void mergeBodies(const urdf::ModelInterface& model,
                   const std::vector<urdf::JointConstSharedPtr>& moving);
  ArmJointInfo jointInfo(const urdf::Joint& joint) const;
  std::vector<Eigen::Isometry3d> jointFrames(const std::vector<urdf::JointConstSharedPtr>& moving);
  void buildBullet(const std::vector<Eigen::Isometry3d>& joint_frame);
  void forwardKinematics();
  const Eigen::Isometry3d& bodyPose(int body) const;  // Bullet frame B of a body
  Eigen::Isometry3d linkPose(const std::string& name) const;
  Eigen::Isometry3d linkPose(const LinkRef& ref) const;
  Eigen::Isometry3d tipLinkPose() const { return linkPose(*tip_ref); }
  Eigen::Vector3d jointAxisWorld(int j) const;
  Eigen::Vector3d jointPivotWorld(int j) const;
  // The generalized gravity force G (M qdd = G + ...) into *g.
  void gravityForce(Eigen::VectorXd* g);
  Eigen::MatrixXd jacobianAt(int body, const Eigen::Vector3d& point) const;
  Eigen::MatrixXd tipJacobian() const {
    return jacobianAt(tip_ref->body, tipLinkPose().translation());
  }
  void applyExternalLoads(bool with_gravity);
  void subStep(double h);
  bool worldStepHasNothingToSolve() const;
  void directWorldStep(double h);
  void integrateReference(double h);
  TargetResult validatePositions(Eigen::VectorXd* q, const std::vector<bool>* mask) const;
  TargetResult validateVelocities(Eigen::VectorXd* qd, const std::vector<bool>* mask) const;
  /** Overlays named targets on *values and marks them in *mask; rejects unknown names. */
  // The joints a named command sets, as indices into jointNames() with their values.
  TargetResult indicesOf(const std::map<std::string, double>& named, std::vector<int>* index,
                         Eigen::VectorXd* values) const {
    index->clear();
    values->resize(static_cast<Eigen::Index>(named.size()));
    for (const auto& kv : named) {
      auto it = std::find(joint_names.begin(), joint_names.end(), kv.first);
      if (it == joint_names.end()) {
        return {TargetStatus::kRejected, "unknown joint '" + kv.first + "'"};
      }
      (*values)[static_cast<Eigen::Index>(index->size())] = kv.second;
      index->push_back(static_cast<int>(it - joint_names.begin()));
    }
    return {};
  }
  // The joints at `index` take `values` in `out`; `mask` marks them.
  TargetResult overlayIndexed(const std::vector<int>& index, const Eigen::VectorXd& values,
                              Eigen::VectorXd* out, std::vector<bool>* mask) const {
    if (values.size() != static_cast<Eigen::Index>(index.size())) {
      return {TargetStatus::kRejected, "expected " + std::to_string(index.size()) +
                                           " targets, got " + std::to_string(values.size())};
    }
    mask->assign(n(), false);
    for (size_t j = 0; j < index.size(); ++j) {
      if (index[j] < 0 || index[j] >= n()) {
        return {TargetStatus::kRejected, "joint index " + std::to_string(index[j]) +
                                             " is not in [0, " + std::to_string(n()) + ")"};
      }
      (*mask)[index[j]] = true;
      (*out)[index[j]] = values[static_cast<Eigen::Index>(j)];
    }
    return {};
  }
};

// ------------------------------------------------------------------------------------------
// Construction
// ------------------------------------------------------------------------------------------

void BulletArm::Impl::build(const std::string& urdf_xml) {
  const std::shared_ptr<const urdf::ModelInterface> model = parseModel(urdf_xml);
  const std::vector<urdf::JointConstSharedPtr> moving = movingJoints(*model);
  mergeBodies(*model, moving);
  tip_ref = &links.at(tip_link);
  for (const auto& j : moving) {
    joint_info.push_back(jointInfo(*j));
    joint_names.push_back(j->name);
  }
  buildBullet(jointFrames(moving));
}

std::shared_ptr<const urdf::ModelInterface> BulletArm::Impl::parseModel(
    const std::string& urdf_xml) const {
  if (urdf_xml.find_first_not_of(" \t\r\n") == std::string::npos) {
    throw std::runtime_error("BulletArm: empty URDF string");
  }
  std::shared_ptr<const urdf::ModelInterface> model = parseUrdfKept(urdf_xml);
  if (!model) {
    throw std::runtime_error(
        "BulletArm: urdfdom could not parse the URDF (malformed XML or invalid robot "
        "description)");
  }
  urdf::LinkConstSharedPtr base = model->getLink(base_link);
  if (!base) {
    throw std::runtime_error("BulletArm: base link '" + base_link + "' not found in URDF '" +
                             model->getName() + "'");
  }
  urdf::LinkConstSharedPtr tip = model->getLink(tip_link);
  if (!tip) {
    throw std::runtime_error("BulletArm: tip link '" + tip_link + "' not found in URDF '" +
                             model->getName() + "'");
  }

  return model;
}

std::vector<urdf::JointConstSharedPtr> BulletArm::Impl::movingJoints(
    const urdf::ModelInterface& model) const {
  urdf::LinkConstSharedPtr tip = model.getLink(tip_link);
  // Path tip -> base through parent joints.
  std::vector<urdf::JointConstSharedPtr> path;
  {
    urdf::LinkConstSharedPtr l = tip;
    while (l->name != base_link) {
      if (!l->parent_joint) {
        throw std::runtime_error("BulletArm: tip link '" + tip_link +
                                 "' does not descend from base link '" + base_link + "'");
      }
      path.push_back(l->parent_joint);
      l = model.getLink(l->parent_joint->parent_link_name);
      if (!l) throw std::runtime_error("BulletArm: broken URDF tree above '" + tip_link + "'");
    }
    std::reverse(path.begin(), path.end());
  }

  // Body heads: base_link, then the child of each moving joint on the path.
  std::vector<urdf::JointConstSharedPtr> moving;
  for (const auto& j : path) {
    switch (j->type) {
      case urdf::Joint::FIXED:
        break;
      case urdf::Joint::REVOLUTE:
      case urdf::Joint::CONTINUOUS:
      case urdf::Joint::PRISMATIC:
        moving.push_back(j);
        break;
      default:
        throw std::runtime_error("BulletArm: joint '" + j->name +
                                 "' on the chain is floating/planar/unknown; only revolute, "
                                 "continuous, prismatic and fixed joints are supported");
    }
  }
  if (moving.empty()) {
    throw std::runtime_error("BulletArm: no moving joint between '" + base_link + "' and '" +
                             tip_link + "'");
  }

  return moving;
}

void BulletArm::Impl::mergeBodies(const urdf::ModelInterface& model,
                                  const std::vector<urdf::JointConstSharedPtr>& moving) {
  bodies.resize(moving.size() + 1);
  bodies[0].head_link = base_link;
  for (std::size_t k = 0; k < moving.size(); ++k) {
    bodies[k + 1].head_link = moving[k]->child_link_name;
  }

  // Merge fixed descendants into each body and accumulate mass properties in the head frame.
  for (std::size_t b = 0; b < bodies.size(); ++b) {
    double m_total = 0.0;
    Eigen::Vector3d m_c = Eigen::Vector3d::Zero();
    struct Part {
      double m;
      Eigen::Vector3d c;
      Eigen::Matrix3d i;
    };
    std::vector<Part> parts;
    std::function<void(const urdf::LinkConstSharedPtr&, const Eigen::Isometry3d&)> visit =
        [&](const urdf::LinkConstSharedPtr& l, const Eigen::Isometry3d& t) {
          if (links.count(l->name)) {
            throw std::runtime_error("BulletArm: link '" + l->name + "' reached twice");
          }
          links[l->name] = LinkRef{static_cast<int>(b), t};
          if (l->inertial && l->inertial->mass > 0.0) {
            const urdf::Inertial& in = *l->inertial;
            const Eigen::Isometry3d ti = t * toEigen(in.origin);
            Eigen::Matrix3d i_local;
            i_local << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
            const Eigen::Matrix3d r = ti.linear();
            parts.push_back(Part{in.mass, ti.translation(), r * i_local * r.transpose()});
            m_total += in.mass;
            m_c += in.mass * ti.translation();
          }
          for (const auto& cj : l->child_joints) {
            if (cj->type != urdf::Joint::FIXED) continue;
            urdf::LinkConstSharedPtr child = model.getLink(cj->child_link_name);
            if (!child) continue;
            visit(child, t * toEigen(cj->parent_to_joint_origin_transform));
          }
        };
    visit(model.getLink(bodies[b].head_link), Eigen::Isometry3d::Identity());

    Body& body = bodies[b];
    Eigen::Vector3d com = Eigen::Vector3d::Zero();
    Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
    if (m_total > 0.0) {
      com = m_c / m_total;
      for (const Part& p : parts) {
        const Eigen::Vector3d d = p.c - com;
        inertia += p.i + p.m * (d.squaredNorm() * Eigen::Matrix3d::Identity() - d * d.transpose());
      }
    }
    if (m_total < kMinMass) {
      // Massless moving link (or massless base): give it a tiny, documented placeholder.
      m_total = std::max(m_total, kMinMass);
      inertia += Eigen::Matrix3d::Identity() * 1e-6;
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(inertia);
    Eigen::Matrix3d v = es.eigenvectors();
    if (v.determinant() < 0.0) v.col(2) = -v.col(2);
    body.mass = m_total;
    body.inertia = es.eigenvalues().cwiseMax(kMinInertia);
    body.com_frame = Eigen::Isometry3d::Identity();
    body.com_frame.linear() = v;
    body.com_frame.translation() = com;
  }
}

ArmJointInfo BulletArm::Impl::jointInfo(const urdf::Joint& joint) const {
  const urdf::Joint* j = &joint;
  ArmJointInfo info;
  info.name = j->name;
  info.type = j->type == urdf::Joint::PRISMATIC    ? ArmJointType::kPrismatic
              : j->type == urdf::Joint::CONTINUOUS ? ArmJointType::kContinuous
                                                   : ArmJointType::kRevolute;
  info.lower = -kInf;
  info.upper = kInf;
  info.velocity = kInf;
  info.effort = kInf;
  if (j->limits) {
    if (info.type != ArmJointType::kContinuous) {
      info.lower = j->limits->lower;
      info.upper = j->limits->upper;
      if (!(info.lower <= info.upper) || (info.lower == 0.0 && info.upper == 0.0)) {
        throw std::runtime_error("BulletArm: joint '" + j->name +
                                 "' has an empty or invalid position range");
      }
    }
    if (j->limits->velocity > 0.0) info.velocity = j->limits->velocity;
    if (j->limits->effort > 0.0) info.effort = j->limits->effort;
  } else if (info.type != ArmJointType::kContinuous) {
    throw std::runtime_error("BulletArm: joint '" + j->name + "' has no <limit> element");
  }
  switch (info.type) {
    case ArmJointType::kRevolute:
      info.stiffness = std::isfinite(info.effort)
                           ? params.revolute_stiffness_per_effort * info.effort
                           : params.revolute_stiffness_default;
      break;
    case ArmJointType::kContinuous:
      info.stiffness = params.continuous_stiffness;
      break;
    case ArmJointType::kPrismatic:
      info.stiffness = params.prismatic_stiffness;
      break;
  }
  auto it = params.joint_stiffness.find(j->name);
  if (it != params.joint_stiffness.end()) info.stiffness = it->second;
  if (!(info.stiffness >= 0.0) || !std::isfinite(info.stiffness)) {
    throw std::runtime_error("BulletArm: invalid stiffness for joint '" + j->name + "'");
  }
  return info;
}

std::vector<Eigen::Isometry3d> BulletArm::Impl::jointFrames(
    const std::vector<urdf::JointConstSharedPtr>& moving) {
  // Bullet link geometry per moving joint.
  joint_data.resize(moving.size());
  std::vector<Eigen::Isometry3d> joint_frame(moving.size());  // J in parent head frame
  std::vector<Eigen::Vector3d> joint_axis(moving.size());     // a in J
  for (std::size_t k = 0; k < moving.size(); ++k) {
    const auto& j = moving[k];
    const LinkRef& parent = links.at(j->parent_link_name);
    if (parent.body != static_cast<int>(k)) {
      throw std::runtime_error("BulletArm: internal error, joint '" + j->name +
                               "' does not connect consecutive bodies");
    }
    joint_frame[k] = parent.head_to_link * toEigen(j->parent_to_joint_origin_transform);
    Eigen::Vector3d a(j->axis.x, j->axis.y, j->axis.z);
    if (a.norm() < 1e-12) {
      throw std::runtime_error("BulletArm: joint '" + j->name + "' has a zero axis");
    }
    joint_axis[k] = a.normalized();
    const Body& child = bodies[k + 1];
    joint_data[k].axis_local = child.com_frame.linear().transpose() * joint_axis[k];
    joint_data[k].pivot_to_com =
        child.com_frame.linear().transpose() * child.com_frame.translation();
  }

  return joint_frame;
}

void BulletArm::Impl::buildBullet(const std::vector<Eigen::Isometry3d>& joint_frame) {
  // Bullet objects.
  collision_config = std::make_unique<btDefaultCollisionConfiguration>();
  dispatcher = std::make_unique<btCollisionDispatcher>(collision_config.get());
  broadphase = std::make_unique<btDbvtBroadphase>();
  solver = std::make_unique<btMultiBodyConstraintSolver>();
  world = std::make_unique<btMultiBodyDynamicsWorld>(dispatcher.get(), broadphase.get(),
                                                     solver.get(), collision_config.get());
  world->setGravity(toBt(params.gravity));

  const int nl = static_cast<int>(joint_frame.size());
  mb = std::make_unique<btMultiBody>(nl, btScalar(bodies[0].mass), toBt(bodies[0].inertia),
                                     /*fixedBase=*/true, /*canSleep=*/false);
  mb->setBaseWorldTransform(toBt(bodies[0].com_frame));
  for (int k = 0; k < nl; ++k) {
    const Body& p = bodies[k];
    const Body& c = bodies[k + 1];
    const Eigen::Isometry3d x = p.com_frame.inverse() * joint_frame[k] * c.com_frame;
    const btQuaternion rot_parent_to_this = toBtQuat(x.linear().transpose());
    const Eigen::Vector3d parent_com_to_pivot =
        p.com_frame.inverse() * joint_frame[k].translation();
    if (joint_info[k].type == ArmJointType::kPrismatic) {
      mb->setupPrismatic(k, btScalar(c.mass), toBt(c.inertia), k - 1, rot_parent_to_this,
                         toBt(joint_data[k].axis_local), toBt(parent_com_to_pivot),
                         toBt(joint_data[k].pivot_to_com), true);
    } else {
      mb->setupRevolute(k, btScalar(c.mass), toBt(c.inertia), k - 1, rot_parent_to_this,
                        toBt(joint_data[k].axis_local), toBt(parent_com_to_pivot),
                        toBt(joint_data[k].pivot_to_com), true);
    }
  }
  mb->finalizeMultiDof();
  mb->setLinearDamping(0.0);
  mb->setAngularDamping(0.0);
  mb->setUseGyroTerm(true);
  mb->setHasSelfCollision(false);
  double vmax = 100.0;
  for (const auto& info : joint_info) {
    if (std::isfinite(info.velocity)) vmax = std::max(vmax, 4.0 * info.velocity);
  }
  mb->setMaxCoordinateVelocity(btScalar(vmax));
  world->addMultiBody(mb.get());

  if (params.hard_joint_limits) {
    for (int k = 0; k < nl; ++k) {
      if (joint_info[k].type == ArmJointType::kContinuous) continue;
      limit_constraints.push_back(std::make_unique<btMultiBodyJointLimitConstraint>(
          mb.get(), k, btScalar(joint_info[k].lower), btScalar(joint_info[k].upper)));
      world->addMultiBodyConstraint(limit_constraints.back().get());
    }
  }

  // Initial state: zero, clamped into the limits.
  q_ref = Eigen::VectorXd::Zero(nl);
  qd_ref = Eigen::VectorXd::Zero(nl);
  tau_last = Eigen::VectorXd::Zero(nl);
  stiffness = Eigen::VectorXd::Zero(nl);
  for (int k = 0; k < nl; ++k) {
    q_ref[k] = std::min(std::max(0.0, joint_info[k].lower), joint_info[k].upper);
    stiffness[k] = joint_info[k].stiffness;
    mb->setJointPos(k, btScalar(q_ref[k]));
    mb->setJointVel(k, btScalar(0.0));
  }
  force_buf.assign(6 + nl, btScalar(0));
  accel_buf.assign(6 + nl, btScalar(0));
  rotor.assign(nl, false);
  for (int k = 0; k < nl; ++k) rotor[k] = isRotor(k);
  forwardKinematics();
}

// ------------------------------------------------------------------------------------------
// Kinematics helpers
// ------------------------------------------------------------------------------------------

void BulletArm::Impl::forwardKinematics() {
  scratch_q.resize(n() + 1);
  scratch_p.resize(n() + 1);
  mb->forwardKinematics(scratch_q, scratch_p);
  // Every body's pose once per state change, not once per query (the servo, gravity and
  // Jacobians ask for each several times per sub-step).
  body_pose.resize(static_cast<std::size_t>(n() + 1));
  body_pose[0] = toEigen(mb->getBaseWorldTransform());
  for (int b = 1; b <= n(); ++b) body_pose[b] = toEigen(mb->getLink(b - 1).m_cachedWorldTransform);
}

const Eigen::Isometry3d& BulletArm::Impl::bodyPose(int body) const { return body_pose[body]; }

Eigen::Isometry3d BulletArm::Impl::linkPose(const std::string& name) const {
  auto it = links.find(name);
  if (it == links.end()) {
    throw std::out_of_range("BulletArm::linkPose: link '" + name +
                            "' is not part of the simulated chain");
  }
  return linkPose(it->second);
}

Eigen::Isometry3d BulletArm::Impl::linkPose(const LinkRef& ref) const {
  const Body& b = bodies[ref.body];
  return bodyPose(ref.body) * b.com_frame.inverse() * ref.head_to_link;
}

Eigen::Vector3d BulletArm::Impl::jointAxisWorld(int j) const {
  return bodyPose(j + 1).linear() * joint_data[j].axis_local;
}

Eigen::Vector3d BulletArm::Impl::jointPivotWorld(int j) const {
  const Eigen::Isometry3d b = bodyPose(j + 1);
  return b.translation() - b.linear() * joint_data[j].pivot_to_com;
}

void BulletArm::Impl::gravityForce(Eigen::VectorXd* out) {
  const int nj = n();
  Eigen::VectorXd& g = *out;
  g.setZero(nj);
  std::vector<Eigen::Vector3d>& com = gravity_com;
  com.resize(static_cast<std::size_t>(nj + 1));
  for (int b = 1; b <= nj; ++b) com[b] = bodyPose(b).translation();
  for (int j = 0; j < nj; ++j) {
    const Eigen::Vector3d a = jointAxisWorld(j);
    const Eigen::Vector3d p = jointPivotWorld(j);
    double s = 0.0;
    for (int b = j + 1; b <= nj; ++b) {
      const Eigen::Vector3d f = bodies[b].mass * params.gravity;
      if (joint_info[j].type == ArmJointType::kPrismatic) {
        s += f.dot(a);
      } else {
        s += (com[b] - p).cross(f).dot(a);
      }
    }
    g[j] = s;
  }
}

Eigen::MatrixXd BulletArm::Impl::jacobianAt(int body, const Eigen::Vector3d& point) const {
  const int nj = n();
  Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(6, nj);
  for (int j = 0; j < nj && j + 1 <= body; ++j) {
    const Eigen::Vector3d a = jointAxisWorld(j);
    if (joint_info[j].type == ArmJointType::kPrismatic) {
      jac.block<3, 1>(0, j) = a;
    } else {
      jac.block<3, 1>(0, j) = a.cross(point - jointPivotWorld(j));
      jac.block<3, 1>(3, j) = a;
    }
  }
  return jac;
}

// ------------------------------------------------------------------------------------------
// Dynamics
// ------------------------------------------------------------------------------------------

void BulletArm::Impl::applyExternalLoads(bool with_gravity) {
  mb->clearForcesAndTorques();
  const int nj = n();
  if (with_gravity) {
    for (int k = 0; k < nj; ++k) {
      mb->addLinkForce(k, toBt(Eigen::Vector3d(bodies[k + 1].mass * params.gravity)));
    }
  }
  const LinkRef& tip = *tip_ref;
  if (tip.body > 0 && tip_force.squaredNorm() > 0.0) {
    const Eigen::Vector3d p = tipLinkPose().translation();
    const Eigen::Vector3d c = bodyPose(tip.body).translation();
    mb->addLinkForce(tip.body - 1, toBt(tip_force));
    mb->addLinkTorque(tip.body - 1, toBt(Eigen::Vector3d((p - c).cross(tip_force))));
  }
}

void BulletArm::Impl::integrateReference(double h) {
  for (int k = 0; k < n(); ++k) {
    if (qd_ref[k] == 0.0) continue;
    q_ref[k] += h * qd_ref[k];
    if (q_ref[k] > joint_info[k].upper) {
      q_ref[k] = joint_info[k].upper;
      qd_ref[k] = 0.0;
    } else if (q_ref[k] < joint_info[k].lower) {
      q_ref[k] = joint_info[k].lower;
      qd_ref[k] = 0.0;
    }
  }
}

bool BulletArm::Impl::isRotor(int k) const {
  // A continuous last joint whose body has its centre of mass on the axis and an inertia
  // symmetric about it: turning it leaves the mass distribution, hence M, unchanged.
  if (k != n() - 1 || joint_info[k].type != ArmJointType::kContinuous) return false;
  const Eigen::Vector3d a = joint_data[k].axis_local.normalized();
  if (joint_data[k].pivot_to_com.cross(a).norm() > 1e-12) return false;
  const Eigen::Matrix3d inertia = bodies[k + 1].inertia.asDiagonal();
  const double axial = a.dot(inertia * a);
  const double transverse = 0.5 * (inertia.trace() - axial);
  const Eigen::Matrix3d symmetric =
      axial * a * a.transpose() + transverse * (Eigen::Matrix3d::Identity() - a * a.transpose());
  return (inertia - symmetric).norm() <= 1e-12 * std::max(1e-30, inertia.norm());
}

bool BulletArm::Impl::inverseInertiaStale(const Eigen::VectorXd& q) const {
  if (a_inv.size() == 0 || !(params.inverse_inertia_tolerance > 0.0)) return true;
  for (int k = 0; k < n(); ++k) {
    if (rotor[k]) continue;
    if (!(std::abs(q[k] - q_at_a_inv[k]) <= params.inverse_inertia_tolerance)) return true;
  }
  return false;
}

void BulletArm::Impl::updateInverseInertia(const Eigen::VectorXd& q) {
  // Column k: the joint accelerations a unit generalized force on joint k causes (uses the
  // articulated inertias of the pre-pass, at the current state).
  const int nj = n();
  a_inv.resize(nj, nj);
  for (int k = 0; k < nj; ++k) {
    std::fill(force_buf.begin(), force_buf.end(), btScalar(0));
    force_buf[6 + k] = btScalar(1);
    mb->calcAccelerationDeltasMultiDof(force_buf.data(), accel_buf.data(), scratch_r, scratch_v);
    for (int r = 0; r < nj; ++r) a_inv(r, k) = accel_buf[6 + r];
  }
  q_at_a_inv = q;
  ++a_inv_updates;
  servo_valid = false;
}

void BulletArm::Impl::subStep(double h) {
  const int nj = n();
  // The bodies' poses are those of the state: every change of it ends in forwardKinematics().
  integrateReference(h);

  Eigen::VectorXd& q = step_q;
  Eigen::VectorXd& qd = step_qd;
  q.resize(nj);
  qd.resize(nj);
  for (int k = 0; k < nj; ++k) {
    q[k] = mb->getJointPos(k);
    qd[k] = mb->getJointVel(k);
  }
  gravityForce(&step_gravity);
  const Eigen::VectorXd& gravity = step_gravity;
  Eigen::VectorXd& tau_gc = step_tau_gc;
  if (params.gravity_compensation) {
    tau_gc = -gravity;
  } else {
    tau_gc.setZero(nj);
  }

  Eigen::VectorXd& v_free = step_v_free;
  v_free.resize(nj);
  if (inverseInertiaStale(q)) {
    // Pre-pass: free velocity after one step under gravity, tip load and gravity compensation,
    // and the joint-space inverse mass matrix A = M^-1 at the current state.
    applyExternalLoads(/*with_gravity=*/true);
    for (int k = 0; k < nj; ++k) mb->addJointTorque(k, btScalar(tau_gc[k]));
    scratch_r.resize(nj + 1);
    scratch_v.resize(nj + 1);
    scratch_m.resize(nj + 1);
    mb->computeAccelerationsArticulatedBodyAlgorithmMultiDof(btScalar(h), scratch_r, scratch_v,
                                                             scratch_m, false, false, false);
    for (int k = 0; k < nj; ++k) v_free[k] = mb->getJointVel(k);
    updateInverseInertia(q);
    for (int k = 0; k < nj; ++k) mb->setJointVel(k, btScalar(qd[k]));
  } else {
    // The arm has barely moved since A was computed: the free velocity from the same loads
    // through the kept A, without the pre-pass's velocity-product (Coriolis, gyroscopic) terms.
    Eigen::VectorXd& load = step_load;
    load = gravity + tau_gc;
    if (tip_ref->body > 0 && tip_force.squaredNorm() > 0.0) {
      load += tipJacobian().topRows<3>().transpose() * tip_force;
    }
    v_free = qd + h * (a_inv * load);
  }

  // Implicit spring-damper: tau = tau0 - B v+, v+ = v_free + h A tau. The factorisation of
  // I + h A B changes only with A and the stiffness: kept between them.
  if (!servo_valid) {
    servo_damping.resize(nj);
    servo_b.resize(nj);
    for (int k = 0; k < nj; ++k) {
      const double m_eff = a_inv(k, k) > 0.0 ? 1.0 / a_inv(k, k) : 0.0;
      servo_damping[k] = 2.0 * params.damping_ratio * std::sqrt(stiffness[k] * m_eff);
      servo_b[k] = h * stiffness[k] + servo_damping[k];
    }
    servo_lu.compute(Eigen::MatrixXd::Identity(nj, nj) + h * a_inv * servo_b.asDiagonal());
    servo_valid = true;
  }
  const Eigen::VectorXd& b = servo_b;
  Eigen::VectorXd& tau0 = step_tau0;
  tau0.resize(nj);
  for (int k = 0; k < nj; ++k) {
    tau0[k] = -stiffness[k] * (q[k] - q_ref[k]) + servo_damping[k] * qd_ref[k];
  }
  Eigen::VectorXd& v_plus = step_v_plus;
  v_plus = servo_lu.solve(v_free + h * a_inv * tau0);
  Eigen::VectorXd& tau = step_tau;
  tau = tau_gc + tau0 - b.cwiseProduct(v_plus);
  if (params.enforce_effort_limits) {
    for (int k = 0; k < nj; ++k) {
      const double e = joint_info[k].effort;
      if (std::isfinite(e)) tau[k] = std::min(std::max(tau[k], -e), e);
    }
  }
  if (!tau.allFinite()) {
    throw std::runtime_error("BulletArm: non-finite joint command (state diverged)");
  }
  tau_last = tau;

  // Real step: the world adds gravity itself.
  applyExternalLoads(/*with_gravity=*/false);
  for (int k = 0; k < nj; ++k) mb->addJointTorque(k, btScalar(tau[k]));
  {
    const ScopedComponentTimer timer(profile, Component::kBulletWorld);
    if (params.direct_world_step && worldStepHasNothingToSolve()) {
      directWorldStep(h);
      ++direct_steps;
    } else {
      world->stepSimulation(btScalar(h), 0, btScalar(h));
    }
  }
  forwardKinematics();
  sim_time += h;
}

bool BulletArm::Impl::worldStepHasNothingToSolve() const {
  // Nothing but this arm in the world: no collision object to test, no rigid body or typed
  // constraint, no other multibody or multibody constraint.
  if (world->getNumCollisionObjects() != 0 || world->getNumConstraints() != 0 ||
      world->getNumMultibodies() != 1 ||
      world->getNumMultiBodyConstraints() != static_cast<int>(limit_constraints.size())) {
    return false;
  }
  // btMultiBodyJointLimitConstraint::createConstraintRows (Bullet 3.24) skips a bound whose
  // "penetration" (the same two differences, in btScalar) is positive: no row, no impulse.
  for (const auto& c : limit_constraints) {
    const int k = c->getLinkA();
    const btScalar q = mb->getJointPos(k);
    if (!(q - c->getLowerBound() > btScalar(0)) || !(c->getUpperBound() - q > btScalar(0))) {
      return false;
    }
  }
  return !mb->isUsingRK4Integration() && !mb->internalNeedsJointFeedback();
}

void BulletArm::Impl::directWorldStep(double h) {
  // btMultiBodyDynamicsWorld's step for one awake multibody without colliders and with no
  // constraint row, call for call (Bullet 3.24): solveExternalForces (the link transforms are
  // already those of this state: every change of it ends in forwardKinematics()), the
  // constraint solver's velocity deltas (zero, applied as the solver applies them), and
  // integrateMultiBodyTransforms without the colliders' transforms (there are none).
  const btScalar dt = btScalar(h);
  const btVector3 g = world->getGravity();
  mb->clearConstraintForces();
  mb->addBaseForce(g * mb->getBaseMass());
  for (int j = 0; j < mb->getNumLinks(); ++j) mb->addLinkForce(j, g * mb->getLinkMass(j));
  scratch_r.resize(mb->getNumLinks() + 1);
  scratch_v.resize(mb->getNumLinks() + 1);
  scratch_m.resize(mb->getNumLinks() + 1);
  const btContactSolverInfo& info = world->getSolverInfo();
  mb->computeAccelerationsArticulatedBodyAlgorithmMultiDof(
      dt, scratch_r, scratch_v, scratch_m, /*isConstraintPass=*/false,
      info.m_jointFeedbackInWorldSpace, info.m_jointFeedbackInJointFrame);
  mb->clearForcesAndTorques();
  mb->processDeltaVeeMultiDof2();
  mb->addSplitV();
  mb->stepPositionsMultiDof(dt);
  mb->substractSplitV();
}

// ------------------------------------------------------------------------------------------
// Target validation
// ------------------------------------------------------------------------------------------

TargetResult BulletArm::Impl::validatePositions(Eigen::VectorXd* q,
                                                const std::vector<bool>* mask) const {
  TargetResult res;
  std::optional<std::ostringstream> msg;  // built on the first clamp only (called every 1 ms)
  for (int k = 0; k < n(); ++k) {
    if (mask && !(*mask)[k]) continue;
    const double v = (*q)[k];
    if (!std::isfinite(v)) {
      res.status = TargetStatus::kRejected;
      res.message = "non-finite position target for joint '" + joint_names[k] + "'";
      return res;
    }
    const ArmJointInfo& info = joint_info[k];
    if (v < info.lower - kLimitTolerance || v > info.upper + kLimitTolerance) {
      if (!params.clamp_out_of_limit_targets) {
        std::ostringstream m;
        m << "position target " << v << " for joint '" << info.name << "' outside [" << info.lower
          << ", " << info.upper << "]";
        res.status = TargetStatus::kRejected;
        res.message = m.str();
        return res;
      }
      const double c = std::min(std::max(v, info.lower), info.upper);
      if (!msg) msg.emplace();
      *msg << (res.status == TargetStatus::kClamped ? "; " : "") << "joint '" << info.name
           << "' target " << v << " clamped to " << c;
      (*q)[k] = c;
      res.status = TargetStatus::kClamped;
    } else {
      (*q)[k] = std::min(std::max(v, info.lower), info.upper);
    }
  }
  if (msg) res.message = msg->str();
  return res;
}

TargetResult BulletArm::Impl::validateVelocities(Eigen::VectorXd* qd,
                                                 const std::vector<bool>* mask) const {
  TargetResult res;
  std::optional<std::ostringstream> msg;  // built on the first clamp only (called every 1 ms)
  for (int k = 0; k < n(); ++k) {
    if (mask && !(*mask)[k]) continue;
    const double v = (*qd)[k];
    if (!std::isfinite(v)) {
      res.status = TargetStatus::kRejected;
      res.message = "non-finite velocity target for joint '" + joint_names[k] + "'";
      return res;
    }
    const double lim = joint_info[k].velocity;
    if (std::abs(v) > lim) {
      const double c = std::copysign(lim, v);
      if (!msg) msg.emplace();
      *msg << (res.status == TargetStatus::kClamped ? "; " : "") << "joint '" << joint_names[k]
           << "' velocity target " << v << " clamped to " << c;
      (*qd)[k] = c;
      res.status = TargetStatus::kClamped;
    }
  }
  if (msg) res.message = msg->str();
  return res;
}

// ------------------------------------------------------------------------------------------
// Public API
// ------------------------------------------------------------------------------------------

BulletArm::BulletArm(const std::string& urdf_xml, const std::string& base_link,
                     const std::string& tip_link, const BulletArmParams& params)
    : impl_(std::make_unique<Impl>()) {
  if (!(params.substep > 0.0) || !std::isfinite(params.substep)) {
    throw std::runtime_error("BulletArm: substep must be a positive finite number of seconds");
  }
  if (!params.gravity.allFinite() || !(params.damping_ratio >= 0.0)) {
    throw std::runtime_error("BulletArm: gravity must be finite and damping_ratio >= 0");
  }
  if (!(params.inverse_inertia_tolerance >= 0.0) ||
      !std::isfinite(params.inverse_inertia_tolerance)) {
    throw std::runtime_error("BulletArm: inverse_inertia_tolerance must be finite and >= 0");
  }
  impl_->params = params;
  impl_->base_link = base_link;
  impl_->tip_link = tip_link;
  impl_->build(urdf_xml);
}

BulletArm::~BulletArm() = default;

const std::vector<std::string>& BulletArm::jointNames() const { return impl_->joint_names; }

int BulletArm::numJoints() const { return impl_->n(); }

const std::vector<ArmJointInfo>& BulletArm::jointInfo() const { return impl_->joint_info; }

bool BulletArm::hasLink(const std::string& name) const { return impl_->links.count(name) > 0; }

TargetResult BulletArm::setJointPositionTargets(const Eigen::VectorXd& q) {
  if (q.size() != impl_->n()) {
    return {TargetStatus::kRejected, "expected " + std::to_string(impl_->n()) +
                                         " position targets, got " + std::to_string(q.size())};
  }
  Eigen::VectorXd v = q;
  TargetResult r = impl_->validatePositions(&v, nullptr);
  if (!r.ok()) return r;
  impl_->q_ref = v;
  impl_->qd_ref.setZero();
  return r;
}

TargetResult BulletArm::setJointPositionTargets(const std::map<std::string, double>& q) {
  std::vector<int> index;
  Eigen::VectorXd values;
  const TargetResult named = impl_->indicesOf(q, &index, &values);
  return named.ok() ? setJointPositionTargets(index, values) : named;
}

TargetResult BulletArm::setJointPositionTargets(const std::vector<int>& index,
                                                const Eigen::VectorXd& positions) {
  std::vector<bool>& mask = impl_->target_mask;
  Eigen::VectorXd& v = impl_->target_values;
  v = impl_->q_ref;
  const TargetResult indexed = impl_->overlayIndexed(index, positions, &v, &mask);
  if (!indexed.ok()) return indexed;
  TargetResult r = impl_->validatePositions(&v, &mask);
  if (!r.ok()) return r;
  for (int k = 0; k < impl_->n(); ++k) {
    if (!mask[k]) continue;
    impl_->q_ref[k] = v[k];
    impl_->qd_ref[k] = 0.0;
  }
  return r;
}

TargetResult BulletArm::setJointVelocityTargets(const std::vector<int>& index,
                                                const Eigen::VectorXd& velocities) {
  std::vector<bool>& mask = impl_->target_mask;
  Eigen::VectorXd& v = impl_->target_values;
  v = impl_->qd_ref;
  const TargetResult indexed = impl_->overlayIndexed(index, velocities, &v, &mask);
  if (!indexed.ok()) return indexed;
  TargetResult r = impl_->validateVelocities(&v, &mask);
  if (!r.ok()) return r;
  for (int k = 0; k < impl_->n(); ++k) {
    if (mask[k]) impl_->qd_ref[k] = v[k];
  }
  return r;
}

TargetResult BulletArm::setJointVelocityTargets(const Eigen::VectorXd& qdot) {
  if (qdot.size() != impl_->n()) {
    return {TargetStatus::kRejected, "expected " + std::to_string(impl_->n()) +
                                         " velocity targets, got " + std::to_string(qdot.size())};
  }
  Eigen::VectorXd v = qdot;
  TargetResult r = impl_->validateVelocities(&v, nullptr);
  if (!r.ok()) return r;
  impl_->qd_ref = v;
  return r;
}

TargetResult BulletArm::setJointVelocityTargets(const std::map<std::string, double>& qdot) {
  std::vector<int> index;
  Eigen::VectorXd values;
  const TargetResult named = impl_->indicesOf(qdot, &index, &values);
  return named.ok() ? setJointVelocityTargets(index, values) : named;
}

TargetResult BulletArm::resetJointState(const Eigen::VectorXd& q) {
  if (q.size() != impl_->n()) {
    return {TargetStatus::kRejected, "expected " + std::to_string(impl_->n()) +
                                         " joint positions, got " + std::to_string(q.size())};
  }
  Eigen::VectorXd v = q;
  TargetResult r = impl_->validatePositions(&v, nullptr);
  if (!r.ok()) return r;
  for (int k = 0; k < impl_->n(); ++k) {
    impl_->mb->setJointPos(k, btScalar(v[k]));
    impl_->mb->setJointVel(k, btScalar(0.0));
  }
  impl_->a_inv.resize(0, 0);  // a jump: computed afresh at the next sub-step
  impl_->q_ref = v;
  impl_->qd_ref.setZero();
  impl_->forwardKinematics();
  return r;
}

void BulletArm::setProfile(ComponentProfile* profile) { impl_->profile = profile; }

void BulletArm::setSubstep(double h) {
  if (!(h > 0.0) || !std::isfinite(h)) {
    throw std::invalid_argument("BulletArm: substep must be a positive finite number of seconds");
  }
  if (h == impl_->params.substep) return;
  impl_->params.substep = h;
  impl_->servo_valid = false;  // B = h K + D and I + h A B depend on h
}

int BulletArm::step(double dt) {
  if (!std::isfinite(dt) || dt <= 0.0) return 0;
  const double h = impl_->params.substep;
  impl_->time_accum += dt;
  int count = 0;
  while (impl_->time_accum >= h * (1.0 - 1e-9)) {
    impl_->subStep(h);
    impl_->time_accum -= h;
    ++count;
  }
  if (impl_->time_accum < 0.0) impl_->time_accum = 0.0;
  return count;
}

double BulletArm::simTime() const { return impl_->sim_time; }

std::uint64_t BulletArm::inverseInertiaUpdates() const { return impl_->a_inv_updates; }

std::uint64_t BulletArm::directWorldSteps() const { return impl_->direct_steps; }

Eigen::VectorXd BulletArm::jointPositions() const {
  Eigen::VectorXd q(impl_->n());
  for (int k = 0; k < impl_->n(); ++k) q[k] = impl_->mb->getJointPos(k);
  return q;
}

Eigen::VectorXd BulletArm::jointVelocities() const {
  Eigen::VectorXd qd(impl_->n());
  for (int k = 0; k < impl_->n(); ++k) qd[k] = impl_->mb->getJointVel(k);
  return qd;
}

Eigen::VectorXd BulletArm::jointPositionTargets() const { return impl_->q_ref; }

Eigen::VectorXd BulletArm::jointVelocityTargets() const { return impl_->qd_ref; }

Eigen::VectorXd BulletArm::jointEfforts() const { return impl_->tau_last; }

Eigen::VectorXd BulletArm::jointStiffness() const { return impl_->stiffness; }

void BulletArm::setStiffnessScale(double scale) {
  if (!std::isfinite(scale) || !(scale > 0.0) || scale > 10.0) {
    throw std::invalid_argument("BulletArm: stiffness scale must be in (0, 10]");
  }
  for (int k = 0; k < impl_->stiffness.size(); ++k) {
    const ArmJointInfo& info = impl_->joint_info[k];
    impl_->stiffness[k] =
        info.type == ArmJointType::kContinuous ? info.stiffness : scale * info.stiffness;
  }
  impl_->servo_valid = false;
}

Eigen::Isometry3d BulletArm::linkPose(const std::string& name) const {
  return impl_->linkPose(name);
}

Eigen::Isometry3d BulletArm::tipPose() const { return impl_->tipLinkPose(); }

Eigen::MatrixXd BulletArm::tipJacobian() const { return impl_->tipJacobian(); }

Eigen::Vector3d BulletArm::predictedTipDeflection(const Eigen::Vector3d& force) const {
  const Eigen::MatrixXd jv = tipJacobian().topRows(3);
  Eigen::VectorXd compliance(impl_->n());
  for (int k = 0; k < impl_->n(); ++k) {
    compliance[k] = impl_->stiffness[k] > 0.0 ? 1.0 / impl_->stiffness[k] : 0.0;
  }
  return jv * compliance.asDiagonal() * jv.transpose() * force;
}

bool BulletArm::applyTipForce(const Eigen::Vector3d& world_force) {
  if (!world_force.allFinite()) return false;
  impl_->tip_force = world_force;
  return true;
}

Eigen::Vector3d BulletArm::tipForce() const { return impl_->tip_force; }

}  // namespace pedicle_drilling::core
