// DART as the physics engine behind a Simulation (Engine::dart).
//
// The MuJoCo model of Simulation::Impl stays the scene: joint names and order, the start state,
// rendering. DART parses the same URDF files with its own loader (its own kinematics, inertias
// and collision shapes), takes from the MuJoCo scene only what a URDF does not say the same way
// to both (armature, damping and friction per joint, which the MuJoCo import completes), and
// integrates. After each step its state is written back into the MuJoCo data.

#include <string>

#include "simulation_impl.hpp"

#if CARTESIAN_IMPEDANCE_HAVE_DART

#include <tinyxml2.h>

#include <algorithm>
#include <dart/collision/CollisionFilter.hpp>
#include <dart/collision/CollisionObject.hpp>
#include <dart/collision/fcl/FCLCollisionDetector.hpp>
#include <dart/constraint/ConstraintSolver.hpp>
#include <dart/dynamics/BodyNode.hpp>
#include <dart/dynamics/BoxShape.hpp>
#include <dart/dynamics/PrismaticJoint.hpp>
#include <dart/dynamics/RevoluteJoint.hpp>
#include <dart/dynamics/ShapeNode.hpp>
#include <dart/dynamics/Skeleton.hpp>
#include <dart/dynamics/WeldJoint.hpp>
#include <dart/simulation/World.hpp>
#include <dart/utils/urdf/DartLoader.hpp>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>
#include <unordered_map>
#include <vector>

namespace cartesian_impedance::sim::detail {
namespace {

namespace dd = dart::dynamics;

// DART 6.12's joints have no armature. A rotor's reflected inertia A acts on its joint's own
// coordinate only: the joint's equation of motion gains A ddq. In the articulated-body algorithm
// that is the joint's projected articulated inertia S^T I^A S, whose inverse DART keeps per joint
// (for the explicit and the implicit-damping pass): adding A there gives forward dynamics,
// impulse responses (contacts) and the inverse mass matrix of M(q) + diag(A), exactly as
// MuJoCo's armature does.
template <class Base>
class WithArmature : public Base {
 public:
  using Properties = typename Base::Properties;
  explicit WithArmature(const Properties& properties) : Base(properties) {}
  void set_armature(double armature) { armature_ = armature; }
  double armature() const { return armature_; }

 protected:
  void updateInvProjArtInertia(const Eigen::Matrix6d& articulated_inertia) override {
    Base::updateInvProjArtInertia(articulated_inertia);
    add_armature(this->mInvProjArtInertia);
  }
  void updateInvProjArtInertiaImplicit(const Eigen::Matrix6d& articulated_inertia,
                                       double timestep) override {
    Base::updateInvProjArtInertiaImplicit(articulated_inertia, timestep);
    add_armature(this->mInvProjArtInertiaImplicit);
  }

 private:
  void add_armature(Eigen::Matrix<double, 1, 1>& inverse) const {
    inverse(0, 0) = 1.0 / (1.0 / inverse(0, 0) + armature_);
  }
  double armature_ = 0.0;
};
using ArmatureRevoluteJoint = WithArmature<dd::RevoluteJoint>;
using ArmaturePrismaticJoint = WithArmature<dd::PrismaticJoint>;

// MuJoCo's scene: robots collide with the environment (boxes), not with themselves or each other.
class EnvironmentOnly : public dart::collision::CollisionFilter {
 public:
  explicit EnvironmentOnly(const dd::Skeleton* environment) : environment_(environment) {}
  bool ignoresCollision(const dart::collision::CollisionObject* a,
                        const dart::collision::CollisionObject* b) const override {
    const bool a_environment = skeleton(a) == environment_;
    const bool b_environment = skeleton(b) == environment_;
    return a_environment == b_environment;
  }

 private:
  static const dd::Skeleton* skeleton(const dart::collision::CollisionObject* object) {
    return object->getShapeFrame()->asShapeNode()->getSkeleton().get();
  }
  const dd::Skeleton* environment_;
};

// DART's loader reports problems on std::cerr (dterr) and returns null; this keeps the text for
// the exception. It also warns (on std::cout) about every massless link (a URDF tool frame):
// not a problem here, so that goes too. Loading is single-threaded (Simulation's loaders are
// documented so).
class CerrCapture {
 public:
  CerrCapture()
      : previous_(std::cerr.rdbuf(text_.rdbuf())), previous_out_(std::cout.rdbuf(text_.rdbuf())) {}
  ~CerrCapture() {
    std::cerr.rdbuf(previous_);
    std::cout.rdbuf(previous_out_);
  }
  CerrCapture(const CerrCapture&) = delete;
  CerrCapture& operator=(const CerrCapture&) = delete;
  std::string text() const {
    std::string t = text_.str();
    while (!t.empty() && (t.back() == '\n' || t.back() == ' ')) t.pop_back();
    return t.empty() ? "no reason given" : t;
  }

 private:
  std::ostringstream text_;
  std::streambuf* previous_;
  std::streambuf* previous_out_;
};

[[noreturn]] void fail(const std::string& message) {
  throw Error("engine 'dart': " + message);
}

// The URDF without its <visual> elements (not simulated) and with its collision meshes at
// absolute paths, found as for the MuJoCo scene: DART's own retrievers know no package://
// without a registered package folder and do not look beside or above the URDF.
std::string collision_only_urdf(const std::string& path, bool boxes_for_missing_meshes) {
  std::ifstream file(path, std::ios::binary);
  std::stringstream content;
  content << file.rdbuf();
  if (!file) fail("cannot read URDF file '" + path + "'");
  tinyxml2::XMLDocument document;
  if (document.Parse(content.str().c_str()) != tinyxml2::XML_SUCCESS) {
    fail("URDF file '" + path + "' is not well-formed XML: " + document.ErrorStr());
  }
  tinyxml2::XMLElement* robot = document.FirstChildElement("robot");
  if (robot == nullptr) fail("URDF file '" + path + "' has no <robot> element");
  UrdfImportOptions import;
  import.boxes_for_missing_meshes = boxes_for_missing_meshes;
  resolve_collision_meshes(robot, path, import);
  apply_physical_inertias(robot, path);
  tinyxml2::XMLPrinter printer;
  document.Print(&printer);
  return printer.CStr();
}

dd::SkeletonPtr load_robot(const SceneRobot& robot, bool boxes_for_missing_meshes) {
  // Until the end: the massless default inertia and the joints moved below warn as well.
  CerrCapture capture;
  dart::utils::DartLoader loader;
  dart::utils::DartLoader::Options options;
  options.mDefaultRootJointType = dart::utils::DartLoader::RootJointType::FIXED;
  // A URDF link without <inertial> is massless; DART's default would give it 1 kg.
  options.mDefaultInertia = dd::Inertia(0.0, Eigen::Vector3d::Zero(), Eigen::Matrix3d::Zero());
  loader.setOptions(options);
  const std::string absolute = std::filesystem::absolute(robot.urdf).string();
  const std::string text = collision_only_urdf(absolute, boxes_for_missing_meshes);
  const dd::SkeletonPtr skeleton =
      loader.parseSkeletonString(text, dart::common::Uri::createFromPath(absolute));
  if (!skeleton) fail("DART's URDF loader cannot load '" + robot.urdf + "': " + capture.text());
  skeleton->setName(robot.prefix + skeleton->getName());
  for (std::size_t i = 0; i < skeleton->getNumBodyNodes(); ++i) {
    dd::BodyNode* body = skeleton->getBodyNode(i);
    body->setName(robot.prefix + body->getName());
    dd::Joint* joint = body->getParentJoint();
    joint->setName(robot.prefix + joint->getName());
  }
  // Give every moving joint its armature slot. changeParentJointType keeps the joint's
  // properties (name, frames, axis, limits, damping, friction) and the subtree, but may reorder
  // the skeleton's bodies, so they are listed first.
  std::vector<dd::BodyNode*> bodies;
  for (std::size_t i = 0; i < skeleton->getNumBodyNodes(); ++i) {
    bodies.push_back(skeleton->getBodyNode(i));
  }
  for (dd::BodyNode* body : bodies) {
    dd::Joint* joint = body->getParentJoint();
    dd::Joint* changed = nullptr;
    if (auto* revolute = dynamic_cast<dd::RevoluteJoint*>(joint)) {
      changed = body->changeParentJointType<ArmatureRevoluteJoint>(
          revolute->getRevoluteJointProperties());
    } else if (auto* prismatic = dynamic_cast<dd::PrismaticJoint*>(joint)) {
      changed = body->changeParentJointType<ArmaturePrismaticJoint>(
          prismatic->getPrismaticJointProperties());
    }
    // A URDF <mimic> (a hand's second finger) would keep a pointer to the joint it follows,
    // which the change above replaces; and MuJoCo 2.2's import ignores <mimic>. Both engines
    // simulate it as a joint of its own.
    if (changed != nullptr) changed->setActuatorType(dd::Joint::FORCE);
  }
  // Attached boxes: welded bodies with the box's inertia and shape, as in the MuJoCo scene.
  for (std::size_t i = 0; i < robot.attached.size(); ++i) {
    const AttachedBox& box = robot.attached[i];
    dd::BodyNode* parent = skeleton->getBodyNode(robot.prefix + box.body);
    if (parent == nullptr) {
      fail("attached[" + std::to_string(i) + "].body = '" + box.body + "' is not a link of '" +
           robot.urdf + "'");
    }
    dd::WeldJoint::Properties joint;
    joint.mName = robot.prefix + attached_name(box, i) + "_joint";
    joint.mT_ParentBodyToJoint.linear() = box.orientation.normalized().toRotationMatrix();
    joint.mT_ParentBodyToJoint.translation() = box.position;
    dd::BodyNode::Properties body;
    body.mName = robot.prefix + attached_name(box, i);
    const Eigen::Vector3d& s = box.half_size;
    const double third = box.mass / 3.0;
    body.mInertia = dd::Inertia(box.mass, Eigen::Vector3d::Zero(),
                                Eigen::Vector3d(third * (s.y() * s.y() + s.z() * s.z()),
                                                third * (s.x() * s.x() + s.z() * s.z()),
                                                third * (s.x() * s.x() + s.y() * s.y()))
                                    .asDiagonal());
    auto pair = skeleton->createJointAndBodyNodePair<dd::WeldJoint>(parent, joint, body);
    pair.second->createShapeNodeWith<dd::CollisionAspect, dd::DynamicsAspect>(
        std::make_shared<dd::BoxShape>(2.0 * box.half_size));
  }
  dd::Joint* root = skeleton->getRootJoint();
  Eigen::Isometry3d base = root->getTransformFromParentBodyNode();
  base.translation() += robot.base_position;
  root->setTransformFromParentBodyNode(base);
  return skeleton;
}

dd::SkeletonPtr make_environment(const std::vector<Box>& boxes) {
  dd::SkeletonPtr environment = dd::Skeleton::create("cartesian_impedance_environment");
  for (std::size_t i = 0; i < boxes.size(); ++i) {
    const Box& box = boxes[i];
    if (box.time_constant > 0.0) {
      fail("boxes[" + std::to_string(i) + "].time_constant = " + format_number(box.time_constant) +
           " s: DART's contacts are rigid, it has no soft box; simulate it with MuJoCo");
    }
    dd::WeldJoint::Properties joint;
    joint.mName = "box_" + std::to_string(i) + "_joint";
    dd::BodyNode::Properties body;
    body.mName = box.name.empty() ? "scene_box_" + std::to_string(i) : box.name;
    auto pair = environment->createJointAndBodyNodePair<dd::WeldJoint>(nullptr, joint, body);
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = box.orientation.normalized().toRotationMatrix();
    pose.translation() = box.center;
    pair.first->setTransformFromParentBodyNode(pose);
    pair.second->createShapeNodeWith<dd::CollisionAspect, dd::DynamicsAspect>(
        std::make_shared<dd::BoxShape>(2.0 * box.half_size));
  }
  return environment;
}

class DartPhysics final : public Physics {
 public:
  DartPhysics(const UrdfScene& scene, const Simulation::Impl& impl);

  Engine engine() const noexcept override { return Engine::dart; }
  void set_state(const Simulation::Impl& impl) override;
  void step(Simulation::Impl& impl) noexcept override;
  Pose body_pose(int body) const override;
  Vector6d contact_wrench(int weld, const Eigen::Vector3d& origin, bool beyond) const override;

 private:
  struct JointLink {  // a MuJoCo joint and its DART degree of freedom
    int qpos = 0, dof = 0;
    dd::Skeleton* skeleton = nullptr;
    const dd::Joint* joint = nullptr;
    std::size_t index = 0;  // in the skeleton
  };
  dart::simulation::WorldPtr world_;
  std::vector<dd::SkeletonPtr> robots_;
  std::vector<JointLink> joints_;      // every MuJoCo hinge and slide joint
  std::vector<JointLink> exchanged_;   // in Impl::joint_ids order
  std::vector<dd::BodyNode*> bodies_;  // per MuJoCo body id; null for the world
  // Per DART body: the MuJoCo weld ids of its body and of each body above it, in order.
  std::unordered_map<const dd::BodyNode*, std::vector<int>> welds_up_;
  // (exchanged joint, attached body in its subtree): weight the firmware does not compensate.
  std::vector<std::pair<std::size_t, const dd::BodyNode*>> uncompensated_;
  bool contacts_valid_ = false;
};

DartPhysics::DartPhysics(const UrdfScene& scene, const Simulation::Impl& impl)
    : world_(dart::simulation::World::create("cartesian_impedance")) {
  const mjModel* m = impl.model.get();
  world_->setTimeStep(m->opt.timestep);
  world_->setGravity(Eigen::Vector3d(m->opt.gravity[0], m->opt.gravity[1], m->opt.gravity[2]));
  for (const SceneRobot& robot : scene.robots) {
    robots_.push_back(load_robot(robot, impl.options.boxes_for_missing_meshes));
    world_->addSkeleton(robots_.back());
  }
  // Contacts exist only with an environment; without one, no collision shape is registered
  // and DART's collision detection costs nothing.
  if (!scene.boxes.empty()) {
    const dd::SkeletonPtr environment = make_environment(scene.boxes);
    world_->addSkeleton(environment);
    world_->getConstraintSolver()->getCollisionOption().collisionFilter =
        std::make_shared<EnvironmentOnly>(environment.get());
  } else {
    for (const dd::SkeletonPtr& robot : robots_) {
      for (std::size_t i = 0; i < robot->getNumBodyNodes(); ++i) {
        robot->getBodyNode(i)->removeAllShapeNodesWith<dd::CollisionAspect>();
      }
    }
  }

  auto find_body = [&](const std::string& name) -> dd::BodyNode* {
    for (const dd::SkeletonPtr& robot : robots_) {
      if (dd::BodyNode* body = robot->getBodyNode(name)) return body;
    }
    return nullptr;
  };
  bodies_.assign(static_cast<std::size_t>(m->nbody), nullptr);
  for (int body = 1; body < m->nbody; ++body) {
    const char* name = mj_id2name(m, mjOBJ_BODY, body);
    if (name == nullptr) continue;
    bodies_[static_cast<std::size_t>(body)] = find_body(name);
    if (bodies_[static_cast<std::size_t>(body)] == nullptr) {
      fail("body '" + std::string(name) + "' of the scene is not a link of DART's model");
    }
    std::vector<int>& welds = welds_up_[bodies_[static_cast<std::size_t>(body)]];
    for (int up = body; up > 0; up = m->body_parentid[up]) welds.push_back(m->body_weldid[up]);
  }
  // A plant's model error (SimulationOptions::plant) is drawn once, into the MuJoCo model: the
  // same links get the same mass, centre of mass and inertia here (both keep the URDF's link
  // frames as body frames).
  for (const int body : impl.perturbed_bodies) {
    if (bodies_[static_cast<std::size_t>(body)] == nullptr) continue;  // unnamed: not DART's
    const mjtNum* turn = m->body_iquat + 4 * body;
    const Eigen::Matrix3d axes =
        Eigen::Quaterniond(turn[0], turn[1], turn[2], turn[3]).toRotationMatrix();
    const Eigen::Vector3d moments(m->body_inertia[3 * body], m->body_inertia[3 * body + 1],
                                  m->body_inertia[3 * body + 2]);
    const Eigen::Vector3d center(m->body_ipos[3 * body], m->body_ipos[3 * body + 1],
                                 m->body_ipos[3 * body + 2]);
    bodies_[static_cast<std::size_t>(body)]->setInertia(
        dd::Inertia(m->body_mass[body], center, axes * moments.asDiagonal() * axes.transpose()));
  }

  exchanged_.resize(impl.joint_ids.size());
  for (int joint = 0; joint < m->njnt; ++joint) {
    const int type = m->jnt_type[joint];
    if (type != mjJNT_HINGE && type != mjJNT_SLIDE) continue;
    const char* name = mj_id2name(m, mjOBJ_JOINT, joint);
    dd::Joint* dart_joint = nullptr;
    for (const dd::SkeletonPtr& robot : robots_) {
      if (name != nullptr && (dart_joint = robot->getJoint(name)) != nullptr) break;
    }
    if (dart_joint == nullptr || dart_joint->getNumDofs() != 1) {
      fail("joint '" + std::string(name != nullptr ? name : "(unnamed)") +
           "' of the scene is not a revolute or prismatic joint of DART's model");
    }
    const int dof = m->jnt_dofadr[joint];
    const double armature = m->dof_armature[dof];
    if (auto* revolute = dynamic_cast<ArmatureRevoluteJoint*>(dart_joint)) {
      revolute->set_armature(armature);
    } else if (auto* prismatic = dynamic_cast<ArmaturePrismaticJoint*>(dart_joint)) {
      prismatic->set_armature(armature);
    } else {
      fail("joint '" + std::string(name) + "' is a " + dart_joint->getType() +
           " in DART's model; expected a revolute or prismatic joint");
    }
    // The same joint as MuJoCo's: damping, Coulomb friction and range; no velocity or force
    // limit (the MuJoCo scene of a URDF has none either).
    dart_joint->setDampingCoefficient(0, m->dof_damping[dof]);
    dart_joint->setCoulombFriction(0, m->dof_frictionloss[dof]);
    dart_joint->setLimitEnforcement(m->jnt_limited[joint] != 0);
    if (m->jnt_limited[joint]) {
      dart_joint->setPositionLowerLimit(0, m->jnt_range[2 * joint]);
      dart_joint->setPositionUpperLimit(0, m->jnt_range[2 * joint + 1]);
    }
    const double infinity = std::numeric_limits<double>::infinity();
    dart_joint->setVelocityLowerLimit(0, -infinity);
    dart_joint->setVelocityUpperLimit(0, infinity);
    dart_joint->setForceLowerLimit(0, -infinity);
    dart_joint->setForceUpperLimit(0, infinity);

    JointLink link;
    link.qpos = m->jnt_qposadr[joint];
    link.dof = dof;
    link.skeleton = dart_joint->getSkeleton().get();
    link.joint = dart_joint;
    link.index = dart_joint->getDof(0)->getIndexInSkeleton();
    joints_.push_back(link);
    const auto exchanged = std::find(impl.joint_ids.begin(), impl.joint_ids.end(), joint);
    if (exchanged != impl.joint_ids.end()) exchanged_[exchanged - impl.joint_ids.begin()] = link;
  }
  for (const auto& [k, body] : impl.uncompensated) {
    const char* name = mj_id2name(m, mjOBJ_BODY, body);
    uncompensated_.emplace_back(static_cast<std::size_t>(k),
                                bodies_[static_cast<std::size_t>(body)]);
    if (uncompensated_.back().second == nullptr) {
      fail("attached body '" + std::string(name != nullptr ? name : "") +
           "' is not in DART's model");
    }
  }
  set_state(impl);
}

// What gravity acting on `body` contributes to the generalized force of joint `link` (a
// revolute or prismatic joint with `body` in its subtree): a . ((c - p) x m g) for a hinge of
// world axis a at p, a . m g for a slide, c the body's centre of mass.
double gravity_moment(const dd::Joint& joint, const dd::BodyNode& body,
                      const Eigen::Vector3d& gravity) {
  const Eigen::Isometry3d frame =
      joint.getChildBodyNode()->getWorldTransform() * joint.getTransformFromChildBodyNode();
  const Eigen::Vector3d weight = body.getMass() * gravity;
  if (const auto* revolute = dynamic_cast<const dd::RevoluteJoint*>(&joint)) {
    const Eigen::Vector3d axis = frame.linear() * revolute->getAxis();
    return axis.dot((body.getCOM() - frame.translation()).cross(weight));
  }
  const auto& prismatic = static_cast<const dd::PrismaticJoint&>(joint);
  return (frame.linear() * prismatic.getAxis()).dot(weight);
}

void DartPhysics::set_state(const Simulation::Impl& impl) {
  const mjData* d = impl.data.get();
  for (const JointLink& joint : joints_) {
    joint.skeleton->setPosition(joint.index, d->qpos[joint.qpos]);
    joint.skeleton->setVelocity(joint.index, d->qvel[joint.dof]);
    joint.skeleton->setAcceleration(joint.index, 0.0);
  }
  world_->setTime(d->time);
  contacts_valid_ = false;
}

void DartPhysics::step(Simulation::Impl& impl) noexcept {
  const mjModel* m = impl.model.get();
  mjData* d = impl.data.get();
  // Gravity compensation as the firmware does it: g(q) at the current state, per joint.
  for (std::size_t k = 0; k < exchanged_.size(); ++k) {
    const JointLink& joint = exchanged_[k];
    double force = impl.tau[static_cast<Eigen::Index>(k)];
    if (impl.gravity_on) force += joint.skeleton->getGravityForces()[joint.index];
    joint.skeleton->setForce(joint.index, force);
  }
  if (impl.gravity_on) {
    const Eigen::Vector3d gravity = world_->getGravity();
    for (const auto& [k, body] : uncompensated_) {
      const JointLink& joint = exchanged_[k];
      joint.skeleton->setForce(joint.index, joint.skeleton->getForce(joint.index) +
                                                gravity_moment(*joint.joint, *body, gravity));
    }
  }
  for (std::size_t k = 0; k < exchanged_.size(); ++k) {
    const JointLink& joint = exchanged_[k];
    impl.true_torque[static_cast<Eigen::Index>(k)] = joint.skeleton->getForce(joint.index);
  }
  impl.expire_pushes();
  for (const Push& push : impl.pushes) {
    dd::BodyNode* body = bodies_[static_cast<std::size_t>(push.body)];
    const Eigen::Vector3d offset =
        push.site >= 0
            ? Eigen::Vector3d(Eigen::Map<const Eigen::Vector3d>(m->site_pos + 3 * push.site))
            : Eigen::Vector3d::Zero();
    body->addExtForce(push.wrench_world.head<3>(), offset, false, true);
    body->addExtTorque(push.wrench_world.tail<3>(), false);
  }
  world_->step();  // clears the forces it was given
  contacts_valid_ = true;
  // The links' side of each joint: the drive's force less the Coulomb friction (the impulse of
  // the joint's own constraint, which also holds a joint limit's), the damping (implicit: at the
  // new velocity) and what turned the rotor.
  const double h = world_->getTimeStep();
  for (std::size_t k = 0; k < exchanged_.size(); ++k) {
    const JointLink& joint = exchanged_[k];
    const auto i = static_cast<Eigen::Index>(k);
    const double velocity = joint.skeleton->getVelocity(joint.index);
    impl.true_torque[i] += joint.joint->getConstraintImpulse(0) / h -
                           joint.joint->getDampingCoefficient(0) * velocity -
                           m->dof_armature[joint.dof] * (velocity - impl.true_dq[i]) / h;
  }
  for (const JointLink& joint : joints_) {
    d->qpos[joint.qpos] = joint.skeleton->getPosition(joint.index);
    d->qvel[joint.dof] = joint.skeleton->getVelocity(joint.index);
  }
  d->time = world_->getTime();
}

Pose DartPhysics::body_pose(int body) const {
  const dd::BodyNode* node = bodies_[static_cast<std::size_t>(body)];
  if (node == nullptr) return Pose{};  // the world
  const Eigen::Isometry3d& transform = node->getWorldTransform();
  Pose pose;
  pose.position = transform.translation();
  pose.orientation = Eigen::Quaterniond(transform.linear()).normalized();
  return pose;
}

Vector6d DartPhysics::contact_wrench(int weld, const Eigen::Vector3d& origin, bool beyond) const {
  Vector6d wrench = Vector6d::Zero();
  if (!contacts_valid_) return wrench;
  const auto on = [&](const dart::collision::CollisionObject* object) {
    const auto it = welds_up_.find(object->getShapeFrame()->asShapeNode()->getBodyNodePtr().get());
    if (it == welds_up_.end() || it->second.empty()) return false;
    if (!beyond) return it->second.front() == weld;
    return std::find(it->second.begin(), it->second.end(), weld) != it->second.end();
  };
  for (const dart::collision::Contact& contact : world_->getLastCollisionResult().getContacts()) {
    const bool on_first = on(contact.collisionObject1);
    const bool on_second = on(contact.collisionObject2);
    if (on_first == on_second) continue;
    // contact.force acts on the first object; the second gets its opposite.
    const Eigen::Vector3d force = on_first ? contact.force : Eigen::Vector3d(-contact.force);
    wrench.head<3>() += force;
    wrench.tail<3>() += (contact.point - origin).cross(force);
  }
  return wrench;
}

}  // namespace

std::unique_ptr<Physics> make_dart_physics(const UrdfScene& scene, const Simulation::Impl& impl) {
  return std::make_unique<DartPhysics>(scene, impl);
}

}  // namespace cartesian_impedance::sim::detail

namespace cartesian_impedance::sim {
bool engine_available(Engine, std::string* reason) {
  if (reason != nullptr) reason->clear();
  return true;
}
}  // namespace cartesian_impedance::sim

#else  // no DART in this build

namespace cartesian_impedance::sim {
namespace {
const char* const kNoDart =
    "this build has no DART (configure with -DCARTESIAN_IMPEDANCE_BUILD_DART=ON; Debian: "
    "libdart-dev libdart-utils-urdf-dev)";
}

bool engine_available(Engine engine, std::string* reason) {
  const bool available = engine == Engine::mujoco;
  if (reason != nullptr) *reason = available ? "" : kNoDart;
  return available;
}

namespace detail {
std::unique_ptr<Physics> make_dart_physics(const UrdfScene&, const Simulation::Impl&) {
  throw Error(std::string("engine 'dart' is not available: ") + kNoDart);
}
}  // namespace detail
}  // namespace cartesian_impedance::sim

#endif
