// The transforms of a URDF's joints below a base link (link_transforms.hpp), for a tf tree. The
// document is read and checked as for RobotModel (urdf_parse.cpp); each joint's motion is KDL's.

#include "cartesian_impedance/model/link_transforms.hpp"

#include <algorithm>
#include <kdl/frames.hpp>
#include <kdl/joint.hpp>
#include <map>
#include <utility>

#include "cartesian_impedance/core/error.hpp"
#include "urdf/urdf_parse.hpp"
#include "urdf/urdf_to_kdl.hpp"

namespace cartesian_impedance {
namespace {

using detail::quoted;

constexpr int kFixed = 0;
constexpr int kRotation = 1;
constexpr int kTranslation = 2;

Eigen::Isometry3d to_eigen(const KDL::Frame& frame) {
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    transform.translation()[r] = frame.p[r];
    for (int c = 0; c < 3; ++c) transform.linear()(r, c) = frame.M(r, c);
  }
  return transform;
}

}  // namespace

LinkTransforms LinkTransforms::from_urdf_string(const std::string& xml,
                                                const std::string& base_link,
                                                const std::vector<std::string>& chain_joints) {
  const std::string source = "the URDF text";
  try {
    detail::check_tree(detail::prescan_urdf(xml, source), source);
    const detail::ModelOwner owner(detail::parse_urdf(xml, source));
    const urdf::ModelInterface& model = *owner.model;
    const auto base = model.links_.find(base_link);
    if (base == model.links_.end() || !base->second) {
      throw Error("base link " + quoted(base_link) + " is not a link of " + source);
    }

    LinkTransforms result;
    result.base_link_ = base_link;
    result.num_chain_joints_ = static_cast<int>(chain_joints.size());
    std::vector<bool> found(chain_joints.size(), false);
    // Depth first from the base: parents before children. A tree (check_tree), so it ends.
    std::vector<const urdf::Link*> pending = {base->second.get()};
    while (!pending.empty()) {
      const urdf::Link* link = pending.back();
      pending.pop_back();
      for (const urdf::JointSharedPtr& joint : link->child_joints) {
        if (!joint) continue;
        LinkJoint entry{joint->name, joint->parent_link_name, joint->child_link_name, -1};
        Motion motion;
        motion.origin = detail::to_eigen(joint->parent_to_joint_origin_transform);
        if (!motion.origin.matrix().allFinite()) {
          throw Error("joint " + quoted(joint->name) + " has an origin that is not finite");
        }
        const Eigen::Vector3d axis(joint->axis.x, joint->axis.y, joint->axis.z);
        switch (joint->type) {
          case urdf::Joint::REVOLUTE:
          case urdf::Joint::CONTINUOUS:
            motion.type = kRotation;
            break;
          case urdf::Joint::PRISMATIC:
            motion.type = kTranslation;
            break;
          default:  // fixed; floating and planar joints are drawn at their origin
            motion.type = kFixed;
        }
        if (motion.type != kFixed) {
          if (!axis.allFinite() || !(axis.norm() > 1e-9)) {
            throw Error("joint " + quoted(joint->name) + " has axis " +
                        detail::format_vector(axis) + "; expected a finite non-zero direction");
          }
          motion.axis = axis.normalized();
        }
        const auto in_chain = std::find(chain_joints.begin(), chain_joints.end(), joint->name);
        if (in_chain != chain_joints.end()) {
          if (motion.type == kFixed) {
            throw Error("joint " + quoted(joint->name) +
                        " is not a revolute, continuous or prismatic joint");
          }
          entry.chain_index = static_cast<int>(in_chain - chain_joints.begin());
          found[static_cast<std::size_t>(entry.chain_index)] = true;
        } else if (motion.type != kFixed && joint->mimic) {
          motion.position = joint->mimic->offset;
        }
        result.joints_.push_back(std::move(entry));
        result.motions_.push_back(motion);
        const auto child = model.links_.find(joint->child_link_name);
        if (child != model.links_.end() && child->second) {
          if (!child->second->visual_array.empty() || child->second->visual) {
            result.visual_links_.push_back(child->first);
          }
          pending.push_back(child->second.get());
        }
      }
    }
    if (!base->second->visual_array.empty() || base->second->visual) {
      result.visual_links_.insert(result.visual_links_.begin(), base_link);
    }
    for (std::size_t i = 0; i < found.size(); ++i) {
      if (!found[i]) {
        throw Error("joint " + quoted(chain_joints[i]) + " is not below base link " +
                    quoted(base_link) + " in " + source);
      }
    }
    return result;
  } catch (const LoadError&) {
    throw;
  } catch (const Error& error) {
    throw LoadError(error.what());
  }
}

void LinkTransforms::compute(const JointVector& q,
                             std::vector<Eigen::Isometry3d>& transforms) const {
  if (q.size() != num_chain_joints_) {
    throw Error("LinkTransforms::compute: q has " + std::to_string(q.size()) +
                " values; expected " + std::to_string(num_chain_joints_));
  }
  transforms.resize(joints_.size());
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    const Motion& motion = motions_[i];
    if (motion.type == kFixed) {
      transforms[i] = motion.origin;
      continue;
    }
    const double position =
        joints_[i].chain_index >= 0 ? q[joints_[i].chain_index] : motion.position;
    // KDL's joint at the joint frame's origin, about (along) its axis.
    const KDL::Joint joint(KDL::Vector::Zero(),
                           KDL::Vector(motion.axis.x(), motion.axis.y(), motion.axis.z()),
                           motion.type == kRotation ? KDL::Joint::RotAxis : KDL::Joint::TransAxis);
    transforms[i] = motion.origin * to_eigen(joint.pose(position));
  }
}

Eigen::Isometry3d LinkTransforms::link_pose(const std::string& link, const JointVector& q) const {
  std::vector<Eigen::Isometry3d> transforms;
  compute(q, transforms);
  std::map<std::string, Eigen::Isometry3d> poses = {{base_link_, Eigen::Isometry3d::Identity()}};
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    poses[joints_[i].child] = poses.at(joints_[i].parent) * transforms[i];
  }
  const auto found = poses.find(link);
  if (found == poses.end()) {
    throw Error("link " + quoted(link) + " is not below base link " + quoted(base_link_));
  }
  return found->second;
}

}  // namespace cartesian_impedance
