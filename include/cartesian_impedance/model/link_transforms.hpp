#pragma once
/// @file
/// The transform of every joint of a URDF below a base link, parent link to child link, for a
/// transform tree (ROS's tf): what a robot_state_publisher computes, from the controlled chain's
/// joint positions. Joints outside the chain (a gripper's fingers, a side branch) sit at position
/// 0 (a mimic joint at its offset); fixed joints at their origin. Like RobotModel, this header
/// needs only Eigen (urdfdom and KDL stay private to the model library).
///
/// Not for the control cycle: compute() allocates nothing but is meant for a publisher thread.

#include <string>
#include <vector>

#include "cartesian_impedance/core/types.hpp"

namespace cartesian_impedance {

/// One joint of the tree: the transform from `parent` link to `child` link.
struct LinkJoint {
  std::string name;    ///< the URDF joint
  std::string parent;  ///< parent link
  std::string child;   ///< child link
  /// Index into the chain's joint positions, or -1 if the transform never changes (a fixed
  /// joint, or a joint outside the chain, held at its position 0).
  int chain_index = -1;
};

/// The joints below a base link of a URDF with their transforms. Constant after construction.
class LinkTransforms {
 public:
  /// Every joint of the subtree below `base_link`, parents before children.
  /// @param chain_joints  the movable joints whose positions compute() takes, in that order (a
  ///                      RobotModel's joint_names())
  /// @throw LoadError or Error as RobotModel::from_urdf_string() for a document it rejects, if
  ///        base_link is not a link of it, or if a name of chain_joints is not a revolute,
  ///        continuous or prismatic joint below base_link.
  static LinkTransforms from_urdf_string(const std::string& xml, const std::string& base_link,
                                         const std::vector<std::string>& chain_joints);

  const std::string& base_link() const noexcept { return base_link_; }
  const std::vector<LinkJoint>& joints() const noexcept { return joints_; }
  /// Links below base_link that have a <visual> (what a robot display draws).
  const std::vector<std::string>& visual_links() const noexcept { return visual_links_; }

  /// T_parent_child of every joint at the chain's positions `q` (chain_joints order), in joints()
  /// order; `transforms` is resized to joints().size().
  /// @throw Error if q has the wrong size.
  void compute(const JointVector& q, std::vector<Eigen::Isometry3d>& transforms) const;

  /// T_base_link of `link` (base_link itself: identity) at `q`, composed from compute().
  /// @throw Error if the link is not base_link or below it.
  Eigen::Isometry3d link_pose(const std::string& link, const JointVector& q) const;

  /// Internal: how each joint moves (defined in link_transforms.cpp).
  struct Motion {
    Eigen::Isometry3d origin = Eigen::Isometry3d::Identity();  ///< T_parent_joint
    Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();           ///< unit, joint frame
    int type = 0;         ///< 0 fixed, 1 rotation, 2 translation
    double position = 0;  ///< outside the chain: the position held
  };

 private:
  std::string base_link_;
  int num_chain_joints_ = 0;
  std::vector<LinkJoint> joints_;
  std::vector<Motion> motions_;
  std::vector<std::string> visual_links_;
};

}  // namespace cartesian_impedance
