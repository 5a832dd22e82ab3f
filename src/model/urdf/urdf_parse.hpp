#pragma once
// Private to the model library: reads a URDF document safely. The text is checked first, the way
// TinyXML (under urdfdom) reads it, for what would make TinyXML recurse without bound or read it
// differently, and for a tree of joints; then urdfdom parses it, its logged errors captured.
// urdf_to_kdl.cpp turns the parsed model into a KDL chain.

#include <urdf_parser/urdf_parser.h>

#include <Eigen/Geometry>

#include <string>
#include <utility>
#include <vector>

namespace cartesian_impedance::detail {

/// "'name'", for messages.
std::string quoted(const std::string& name);

/// A joint as the tree check sees it.
struct TreeJoint {
  std::string name;
  std::string parent;  // link names
  std::string child;
};

/// Throws Error unless `joints` form a forest: unique joint names, no joint from a link to itself,
/// at most one parent joint per link and no loop. urdfdom itself requires exactly one root.
/// `source` names the document in the message ("URDF file '/a/b.urdf'").
void check_tree(const std::vector<TreeJoint>& joints, const std::string& source);

/// Checks the text of a URDF before urdfdom parses it (see urdf_parse.cpp) and returns the joints
/// of its <robot> element, with parent and child as written (entities not decoded).
/// @throw Error naming `source` and the line for text that is rejected.
std::vector<TreeJoint> prescan_urdf(const std::string& xml, const std::string& source);

/// urdfdom's model of `xml`. @throw Error with urdfdom's messages if it fails or logs an error.
urdf::ModelInterfaceSharedPtr parse_urdf(const std::string& xml, const std::string& source);

/// urdfdom's model, released without leaks: its links own their children, so a loop of links
/// (which check_tree() rejects after urdfdom built it) would keep itself alive.
struct ModelOwner {
  explicit ModelOwner(urdf::ModelInterfaceSharedPtr parsed) : model(std::move(parsed)) {}
  ModelOwner(const ModelOwner&) = delete;
  ModelOwner& operator=(const ModelOwner&) = delete;
  ~ModelOwner() {
    for (const auto& entry : model->links_) {
      if (!entry.second) continue;
      entry.second->child_links.clear();
      entry.second->child_joints.clear();
    }
  }
  urdf::ModelInterfaceSharedPtr model;
};

/// `pose` (urdfdom stores the rpy of the file as a unit quaternion) as an Eigen transform.
inline Eigen::Isometry3d to_eigen(const urdf::Pose& pose) {
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  transform.translation() = Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z);
  const Eigen::Quaterniond rotation(pose.rotation.w, pose.rotation.x, pose.rotation.y,
                                    pose.rotation.z);
  transform.linear() = rotation.normalized().toRotationMatrix();
  return transform;
}

}  // namespace cartesian_impedance::detail
