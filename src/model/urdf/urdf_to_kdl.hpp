#pragma once
// Private to the model library: parses a URDF with urdfdom and turns the path from a base link
// down to a tip link into a KDL chain, the same way kdl_parser does (without ROS).

#include <Eigen/Geometry>
#include <kdl/chain.hpp>
#include <string>
#include <vector>

#include "cartesian_impedance/model/robot_model.hpp"

namespace cartesian_impedance::detail {

/// The serial chain between two links of a URDF, ready for KDL's solvers.
struct UrdfChain {
  std::string robot_name;
  /// One segment per URDF joint from the base link down to the tip link (fixed joints included,
  /// as Joint::None segments). Segment i ends in the child link of joint i; its inertia is that
  /// link's plus that of every link rigidly attached to it (fixed joints) off the chain.
  KDL::Chain chain;
  std::vector<std::string> joint_names;  ///< movable joints, base to tip
  std::vector<JointType> joint_types;
  JointLimits limits;
  double moving_mass = 0.0;  ///< [kg] sum of the segment masses
  /// The child link of each movable joint, base to tip.
  std::vector<std::string> joint_links;
  /// The movable joints (indices, base to tip) that move no mass: see
  /// RobotModel::massless_joints().
  std::vector<int> massless_joints;
  /// What was repaired on loading (RobotModel::warnings()).
  std::vector<std::string> warnings;
};

/// The same transform as a KDL frame.
KDL::Frame to_kdl_frame(const Eigen::Isometry3d& transform);

/// "(x, y, z)" for error messages.
std::string format_vector(const Eigen::Vector3d& v);

/// Parses `xml` (a URDF document) and extracts the chain base_link -> tip_link.
/// `source` describes where the text came from for error messages ("URDF file '/a/b.urdf'").
/// @throw Error on any problem with the document or the chain (see RobotModel::from_urdf_string).
UrdfChain urdf_to_kdl_chain(const std::string& xml, const std::string& source,
                            const std::string& base_link, const std::string& tip_link);

}  // namespace cartesian_impedance::detail
