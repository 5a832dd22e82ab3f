// The KDL chain from base link to tip link of a parsed URDF (urdf_to_kdl.hpp): bounds on its
// numbers, lumped inertias, joints and limits. The document itself is read and checked in
// urdf_parse.cpp.

#include "urdf_to_kdl.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <kdl/frames.hpp>
#include <kdl/joint.hpp>
#include <kdl/rigidbodyinertia.hpp>
#include <kdl/rotationalinertia.hpp>
#include <kdl/segment.hpp>
#include <limits>
#include <sstream>
#include <utility>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/model/link_inertia.hpp"
#include "urdf_parse.hpp"

namespace cartesian_impedance::detail {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// Bounds on the numbers of a URDF. They are far beyond any robot arm, so that they only catch
// typos and garbage, and small enough that nothing a model computes from them can overflow: even
// 10^4 links of the largest mass, each at the largest distance from the last, make inertias of
// about 1e24 kg m^2 (gravity torques about 1e18 Nm), far from the overflow at 1e308.
// A robot bigger than a kilometre is a unit mistake or garbage; the largest gantries span tens of
// metres.
constexpr double kMaxDistance = 1000.0;  // [m] every coordinate of an origin, a prismatic limit
// An axis is a direction, which URDF writes with norm 1: a norm far from it is a typo for zero or
// garbage, not a direction.
constexpr double kMinAxisNorm = 1e-9;
constexpr double kMaxAxisNorm = 1e9;

// ---------------------------------------------------------------------------------------------
// Conversions.

KDL::Vector to_kdl(const Eigen::Vector3d& v) {
  return KDL::Vector(v.x(), v.y(), v.z());
}

// `pose` as a transform; `what` ("joint 'j' has origin") names it if it is out of bounds.
Eigen::Isometry3d checked_pose(const urdf::Pose& pose, const std::string& what) {
  const Eigen::Vector3d xyz(pose.position.x, pose.position.y, pose.position.z);
  if (!(xyz.cwiseAbs().maxCoeff() <= kMaxDistance) || !xyz.allFinite()) {
    std::ostringstream message;
    message << what << " xyz = " << format_vector(xyz) << "; expected finite coordinates within +-"
            << kMaxDistance << " m";
    throw Error(message.str());
  }
  const Eigen::Isometry3d transform = to_eigen(pose);
  if (!transform.matrix().allFinite()) {
    throw Error(what + " with a rotation that is not finite; expected finite rpy angles");
  }
  return transform;
}

Eigen::Isometry3d checked_origin(const urdf::Joint& joint) {
  return checked_pose(joint.parent_to_joint_origin_transform,
                      "joint " + quoted(joint.name) + " has origin");
}

const char* joint_type_name(int type) {
  switch (type) {
    case urdf::Joint::REVOLUTE:
      return "revolute";
    case urdf::Joint::CONTINUOUS:
      return "continuous";
    case urdf::Joint::PRISMATIC:
      return "prismatic";
    case urdf::Joint::FLOATING:
      return "floating";
    case urdf::Joint::PLANAR:
      return "planar";
    case urdf::Joint::FIXED:
      return "fixed";
    default:
      return "of unknown type";
  }
}

// Mass, centre of mass and rotational inertia about the centre of mass, all in one link's frame.
struct MassProperties {
  double mass = 0.0;
  Eigen::Vector3d com = Eigen::Vector3d::Zero();
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
};

// The same body seen from a frame in which the current one is at `T`.
MassProperties transformed(const Eigen::Isometry3d& T, const MassProperties& body) {
  MassProperties result;
  result.mass = body.mass;
  result.com = T * body.com;
  result.inertia = T.linear() * body.inertia * T.linear().transpose();
  return result;
}

// Two rigidly joined bodies as one (parallel-axis theorem about the joint centre of mass).
MassProperties combined(const MassProperties& a, const MassProperties& b) {
  MassProperties result;
  result.mass = a.mass + b.mass;
  if (result.mass > 0.0) result.com = (a.mass * a.com + b.mass * b.com) / result.mass;
  const auto shifted = [&result](const MassProperties& body) {
    const Eigen::Vector3d d = body.com - result.com;
    return Eigen::Matrix3d(body.inertia +
                           body.mass *
                               (d.squaredNorm() * Eigen::Matrix3d::Identity() - d * d.transpose()));
  };
  result.inertia = shifted(a) + shifted(b);
  return result;
}

// A link's <inertial> as the model and both simulation engines take it (link_inertia.hpp).
LinkInertia checked_inertial(const urdf::Link& link) {
  const urdf::Inertial& inertial = *link.inertial;
  Eigen::Matrix3d tensor;
  tensor << inertial.ixx, inertial.ixy, inertial.ixz,  //
      inertial.ixy, inertial.iyy, inertial.iyz,        //
      inertial.ixz, inertial.iyz, inertial.izz;
  return physical_link_inertia(link.name, inertial.mass, tensor);
}

// A link's own inertial, converted from the URDF inertial frame to the link frame: the centre of
// mass is the inertial origin, the tensor (given in the axes of the inertial frame) is rotated
// into the link axes, R I R^T.
MassProperties link_mass_properties(const urdf::Link& link) {
  MassProperties body;
  if (!link.inertial) return body;
  const urdf::Inertial& inertial = *link.inertial;
  const LinkInertia checked = checked_inertial(link);
  const Eigen::Isometry3d T_link_inertial =
      checked_pose(inertial.origin, "link " + quoted(link.name) + " has inertial origin");
  body.mass = checked.mass;
  body.com = T_link_inertial.translation();
  body.inertia = T_link_inertial.linear() * checked.inertia * T_link_inertial.linear().transpose();
  return body;
}

// `link` and every link attached to it through fixed joints, except the branch of `on_chain`.
// A file may attach any number of links in a row, so the sub-tree is walked with a worklist, not
// by recursion.
MassProperties rigid_body_of(const urdf::Link& link, const urdf::Link* on_chain) {
  struct Attached {
    const urdf::Link* link;
    Eigen::Isometry3d T_top_link;  // its frame in the frame of `link`
  };
  MassProperties body = link_mass_properties(link);
  std::vector<Attached> pending{{&link, Eigen::Isometry3d::Identity()}};
  while (!pending.empty()) {
    const Attached parent = pending.back();
    pending.pop_back();
    if (parent.link != &link) {
      body = combined(body, transformed(parent.T_top_link, link_mass_properties(*parent.link)));
    }
    for (const urdf::LinkSharedPtr& child : parent.link->child_links) {
      if (!child || child.get() == on_chain) continue;
      const urdf::JointSharedPtr& joint = child->parent_joint;
      if (!joint || joint->type != urdf::Joint::FIXED) continue;
      pending.push_back({child.get(), parent.T_top_link * checked_origin(*joint)});
    }
  }
  return body;
}

KDL::RigidBodyInertia to_kdl(const MassProperties& body) {
  const Eigen::Matrix3d& i = body.inertia;
  // KDL wants the rotational inertia about the centre of mass, in the link frame's axes.
  return KDL::RigidBodyInertia(
      body.mass, to_kdl(body.com),
      KDL::RotationalInertia(i(0, 0), i(1, 1), i(2, 2), i(0, 1), i(0, 2), i(1, 2)));
}

std::string describe_links(const urdf::ModelInterface& model) {
  // urdfdom keeps links in a std::map, so they come sorted by name.
  constexpr std::size_t kShown = 12;
  std::ostringstream text;
  std::size_t shown = 0;
  for (const auto& entry : model.links_) {
    if (shown == kShown) break;
    text << (shown ? ", " : "") << entry.first;
    ++shown;
  }
  if (model.links_.size() > kShown) text << ", ... (" << model.links_.size() << " in all)";
  return text.str();
}

const urdf::Link& find_link(const urdf::ModelInterface& model, const std::string& name,
                            const char* role, const std::string& source) {
  const auto found = model.links_.find(name);
  if (found == model.links_.end() || !found->second) {
    throw Error(std::string(role) + " " + quoted(name) + " is not a link of " + source +
                " (robot " + quoted(model.name_) + "; its links are: " + describe_links(model) +
                ")");
  }
  return *found->second;
}

// The walks towards the root below end because check_tree() ruled out loops; the bound on the
// steps is a second line of defence against a walk without end.
bool is_ancestor(const urdf::Link& ancestor, const urdf::Link& link, std::size_t links) {
  std::size_t steps = 0;
  for (urdf::LinkConstSharedPtr up = link.getParent(); up && steps <= links;
       up = up->getParent(), ++steps) {
    if (up.get() == &ancestor) return true;
  }
  return false;
}

std::string path_to_root(const urdf::Link& link, std::size_t links) {
  std::string text = link.name;
  std::size_t steps = 0;
  for (urdf::LinkConstSharedPtr up = link.getParent(); up && steps <= links;
       up = up->getParent(), ++steps) {
    text += " <- " + up->name;
  }
  return text;
}

KDL::Joint to_kdl_joint(const urdf::Joint& joint, const Eigen::Isometry3d& T_parent_joint) {
  const Eigen::Vector3d axis(joint.axis.x, joint.axis.y, joint.axis.z);
  // Scaled by its largest component first, so that the norm of a large axis does not overflow
  // (the norm of (1e200, 0, 0) is 1e200, not sqrt(inf)).
  const double largest = axis.allFinite() ? axis.cwiseAbs().maxCoeff() : kInfinity;
  const Eigen::Vector3d scaled = largest > 0.0 ? Eigen::Vector3d(axis / largest) : axis;
  const double norm = axis.allFinite() ? largest * scaled.norm() : kInfinity;
  if (!(norm >= kMinAxisNorm && norm <= kMaxAxisNorm)) {
    std::ostringstream message;
    message << "joint " << quoted(joint.name) << " has axis = " << format_vector(axis)
            << " of norm " << norm << "; expected a finite non-zero direction: finite components "
            << "and a norm in [" << kMinAxisNorm << ", " << kMaxAxisNorm << "]";
    throw Error(message.str());
  }
  // As kdl_parser: the joint sits at the joint origin, its axis rotated into the parent frame.
  const KDL::Vector origin = to_kdl(T_parent_joint.translation());
  const KDL::Vector axis_parent = to_kdl(T_parent_joint.linear() * scaled.normalized());
  const KDL::Joint::JointType kdl_type =
      joint.type == urdf::Joint::PRISMATIC ? KDL::Joint::TransAxis : KDL::Joint::RotAxis;
  return KDL::Joint(joint.name, origin, axis_parent, kdl_type);
}

void read_limits(const urdf::Joint& joint, JointType type, int index, JointLimits& limits) {
  const auto fail = [&joint](const std::string& what) {
    throw Error("joint " + quoted(joint.name) + " has " + what);
  };
  double lower = -kInfinity, upper = kInfinity, velocity = kInfinity, effort = kInfinity;
  if (joint.limits) {
    const urdf::JointLimits& given = *joint.limits;
    if (type != JointType::continuous) {
      lower = given.lower;
      upper = given.upper;
      // A prismatic joint's travel is a distance like any other.
      const double bound = type == JointType::prismatic ? kMaxDistance : kInfinity;
      if (!std::isfinite(lower) || !std::isfinite(upper) || lower > upper ||
          std::abs(lower) > bound || std::abs(upper) > bound) {
        std::ostringstream what;
        what << "position limits [" << lower << ", " << upper
             << "]; expected finite lower <= upper";
        if (type == JointType::prismatic) what << " within +-" << kMaxDistance << " m";
        fail(what.str());
      }
    }
    velocity = given.velocity;
    effort = given.effort;
    if (std::isnan(velocity) || velocity < 0.0) {
      std::ostringstream what;
      what << "velocity limit = " << velocity << "; expected a value >= 0";
      fail(what.str());
    }
    if (std::isnan(effort) || effort < 0.0) {
      std::ostringstream what;
      what << "effort limit = " << effort << "; expected a value >= 0";
      fail(what.str());
    }
  }
  limits.position_lower[index] = lower;
  limits.position_upper[index] = upper;
  limits.velocity[index] = velocity;
  limits.effort[index] = effort;
}

}  // namespace

KDL::Frame to_kdl_frame(const Eigen::Isometry3d& transform) {
  const Eigen::Matrix3d& r = transform.linear();
  return KDL::Frame(KDL::Rotation(r(0, 0), r(0, 1), r(0, 2), r(1, 0), r(1, 1), r(1, 2), r(2, 0),
                                  r(2, 1), r(2, 2)),
                    to_kdl(transform.translation()));
}

std::string format_vector(const Eigen::Vector3d& v) {
  std::ostringstream text;
  text << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return text.str();
}

UrdfChain urdf_to_kdl_chain(const std::string& xml, const std::string& source,
                            const std::string& base_link, const std::string& tip_link) {
  // On the text first: neither TinyXML's recursion nor urdfdom's leak on a loop may be reached.
  check_tree(prescan_urdf(xml, source), source);
  const ModelOwner owner(parse_urdf(xml, source));
  const urdf::ModelInterface& model = *owner.model;
  // Again on urdfdom's model, which decoded the names (and is what the walks below follow).
  std::vector<TreeJoint> joints;
  joints.reserve(model.joints_.size());
  for (const auto& entry : model.joints_) {
    if (entry.second) {
      joints.push_back(
          {entry.second->name, entry.second->parent_link_name, entry.second->child_link_name});
    }
  }
  check_tree(joints, source);
  const std::size_t link_count = model.links_.size();
  const urdf::Link& base = find_link(model, base_link, "base link", source);
  const urdf::Link& tip = find_link(model, tip_link, "tip link", source);

  if (&base == &tip) {
    throw Error("tip link " + quoted(tip_link) + " is the base link; the chain from base to tip " +
                "must contain at least one movable joint");
  }
  if (!is_ancestor(base, tip, link_count)) {
    if (is_ancestor(tip, base, link_count)) {
      throw Error("tip link " + quoted(tip_link) + " is above base link " + quoted(base_link) +
                  " in the URDF tree of " + source +
                  "; expected the tip below the base (swap them?)");
    }
    throw Error("tip link " + quoted(tip_link) + " is not below base link " + quoted(base_link) +
                " in the URDF tree of " + source +
                " (path from the tip to the root: " + path_to_root(tip, link_count) + ")");
  }

  // Links from just below the base down to the tip.
  std::vector<const urdf::Link*> links;
  for (const urdf::Link* link = &tip; link != &base; link = link->getParent().get()) {
    links.push_back(link);
  }
  std::reverse(links.begin(), links.end());

  UrdfChain result;
  result.robot_name = model.name_;
  // Every link's inertial, not only the chain's: the simulation loads them all (fingers, side
  // branches), and the model and the engines accept, repair and refuse the same files.
  for (const auto& entry : model.links_) {
    if (!entry.second || !entry.second->inertial) continue;
    const LinkInertia checked = checked_inertial(*entry.second);
    if (!checked.repair.empty()) result.warnings.push_back(checked.repair);
  }
  std::vector<const urdf::Joint*> movable;
  for (const urdf::Link* link : links) {
    const urdf::Joint& joint = *link->parent_joint;
    switch (joint.type) {
      case urdf::Joint::REVOLUTE:
      case urdf::Joint::CONTINUOUS:
      case urdf::Joint::PRISMATIC:
      case urdf::Joint::FIXED:
        break;
      default:
        throw Error("joint " + quoted(joint.name) + " between " + quoted(joint.parent_link_name) +
                    " and " + quoted(joint.child_link_name) + " is " + joint_type_name(joint.type) +
                    "; the chain from " + quoted(base_link) + " to " + quoted(tip_link) +
                    " may contain only revolute, continuous, prismatic and fixed joints");
    }
    if (joint.mimic && joint.type != urdf::Joint::FIXED) {
      throw Error("joint " + quoted(joint.name) + " mimics joint " +
                  quoted(joint.mimic->joint_name) +
                  "; mimic joints are not supported in the chain");
    }
    if (joint.type != urdf::Joint::FIXED) movable.push_back(&joint);
  }
  const int n = static_cast<int>(movable.size());
  if (n == 0) {
    throw Error("the chain from " + quoted(base_link) + " to " + quoted(tip_link) + " of " +
                source + " has no movable joint; expected at least 1");
  }
  if (n > kMaxJoints) {
    throw Error("the chain from " + quoted(base_link) + " to " + quoted(tip_link) + " has " +
                std::to_string(n) + " movable joints; at most kMaxJoints = " +
                std::to_string(kMaxJoints) + " are supported");
  }

  result.limits.position_lower.resize(n);
  result.limits.position_upper.resize(n);
  result.limits.velocity.resize(n);
  result.limits.effort.resize(n);
  std::vector<MassProperties> bodies;       // of each segment, base to tip
  std::vector<std::size_t> joint_segments;  // the segment of each movable joint
  for (std::size_t i = 0; i < links.size(); ++i) {
    const urdf::Link& link = *links[i];
    const urdf::Joint& joint = *link.parent_joint;
    const Eigen::Isometry3d T_parent_joint = checked_origin(joint);
    KDL::Joint kdl_joint(joint.name, KDL::Joint::None);
    if (joint.type != urdf::Joint::FIXED) {
      const JointType type = joint.type == urdf::Joint::PRISMATIC    ? JointType::prismatic
                             : joint.type == urdf::Joint::CONTINUOUS ? JointType::continuous
                                                                     : JointType::revolute;
      read_limits(joint, type, static_cast<int>(result.joint_names.size()), result.limits);
      result.joint_names.push_back(joint.name);
      result.joint_types.push_back(type);
      result.joint_links.push_back(link.name);
      joint_segments.push_back(i);
      kdl_joint = to_kdl_joint(joint, T_parent_joint);
    }
    const urdf::Link* next_on_chain = i + 1 < links.size() ? links[i + 1] : nullptr;
    const MassProperties body = rigid_body_of(link, next_on_chain);
    bodies.push_back(body);
    result.moving_mass += body.mass;
    // The segment's tip frame is the joint origin (at q = 0), i.e. the child link's frame.
    result.chain.addSegment(
        KDL::Segment(link.name, kdl_joint, to_kdl_frame(T_parent_joint), to_kdl(body)));
  }
  // A joint moves the segments from its own to the tip. If they carry no mass (and, for a
  // rotation, no rotational inertia either), M(q) has a zero row and column for the joint at
  // every q: not an accident of the pose but of the file, so it is found here once.
  for (std::size_t j = 0; j < joint_segments.size(); ++j) {
    double mass = 0.0, inertia = 0.0;
    for (std::size_t i = joint_segments[j]; i < bodies.size(); ++i) {
      mass += bodies[i].mass;
      inertia += bodies[i].inertia.cwiseAbs().sum();
    }
    const bool rotates = result.joint_types[j] != JointType::prismatic;
    if (mass == 0.0 && (!rotates || inertia == 0.0)) {
      result.massless_joints.push_back(static_cast<int>(j));
    }
  }
  return result;
}

}  // namespace cartesian_impedance::detail
