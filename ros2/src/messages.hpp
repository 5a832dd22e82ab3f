#pragma once
/// @file
/// Conversions between the generated DDS message types (ROS 2's messages in C, from idlc) and the
/// library's types, and the node's outgoing messages with storage of their own. Values are
/// checked by the library (validate_command() throws Error naming the field); these throw the
/// same type for what only a message can get wrong (array sizes, frames, joint names). Incoming
/// messages are read where DDS loaned them; nothing here keeps a pointer into one.

#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <cartesian_impedance/core/command.hpp>
#include <cartesian_impedance/core/trajectory.hpp>
#include <cartesian_impedance/loop/control_loop.hpp>
#include <cartesian_impedance/model/link_transforms.hpp>
#include <cartesian_impedance/model/robot_model.hpp>
#include <cartesian_impedance/node/joint_states.hpp>
#include <cartesian_impedance/runtime/control_thread.hpp>

#include "ros2_messages.h"

namespace cartesian_impedance_ros2 {

using PoseStamped = geometry_msgs_msg_dds__PoseStamped_;
using WrenchStamped = geometry_msgs_msg_dds__WrenchStamped_;
using WrenchMessage = geometry_msgs_msg_dds__Wrench_;
using JointStateMessage = sensor_msgs_msg_dds__JointState_;
using JointTrajectoryMessage = trajectory_msgs_msg_dds__JointTrajectory_;
using Float64MultiArray = std_msgs_msg_dds__Float64MultiArray_;
using ControllerConfig = cartesian_impedance_controller_msg_dds__ControllerConfig_;
/// The published controller's state message (topic controller_state).
using PublishedState = cartesian_impedance_controller_msg_dds__ControllerState_;
/// This project's full state message (topic full_state).
using FullState = cartesian_impedance_msgs_msg_dds__ControllerState_;
using TFMessage = tf2_msgs_msg_dds__TFMessage_;
using StringMessage = std_msgs_msg_dds__String_;
using EmptyMessage = std_msgs_msg_dds__Empty_;

/// The chain's two frames, as messages name them in header.frame_id: the link names, or the link
/// names with tf_prefix in front (the tf frames, which outgoing messages use).
struct Frames {
  std::string base_link;
  std::string tip_link;
  std::string tf_prefix;

  bool is_base(std::string_view frame) const;
  bool is_tip(std::string_view frame) const;
  std::string base_frame() const { return tf_prefix + base_link; }
};

/// Position and quaternion (x, y, z, w), not normalised: the library checks the unit norm.
cartesian_impedance::Pose pose_from_message(const geometry_msgs_msg_dds__Pose_& message);
/// [force; torque] (also stiffness and damping-ratio diagonals).
cartesian_impedance::Vector6d vector_from_wrench(const WrenchMessage& message);

/// The reference pose of a PoseStamped in the base frame ("" or the base link).
/// @throws cartesian_impedance::Error for any other frame (the node has no tf).
cartesian_impedance::Command reference_from_message(const PoseStamped& message,
                                                    const Frames& frames);
/// A stiffness diagonal or wrench in the frame the message names: "" = the configured frame, the
/// base link = base, the tip link = end_effector.
/// @throws cartesian_impedance::Error for any other frame.
cartesian_impedance::Command stiffness_from_message(const WrenchStamped& message,
                                                    const Frames& frames);
cartesian_impedance::Command wrench_from_message(const WrenchStamped& message,
                                                 const Frames& frames);
/// The published controller's set_config: stiffness diagonal, damping ratios, nullspace
/// stiffness (every joint), nullspace damping ratio and, if not empty, the nullspace
/// configuration. Applied together or not at all.
/// @throws cartesian_impedance::Error if q_d_nullspace is neither empty nor one value per joint.
std::vector<cartesian_impedance::Command> config_from_message(const ControllerConfig& message,
                                                              int num_joints);
/// The library's trajectory (header.stamp is ignored: execution starts at the next cycle).
/// Velocities are used if every point has them.
/// @throws cartesian_impedance::Error if some points have velocities and others not, or before
///         anything is copied if the message is larger than any trajectory the loop takes: more
///         than `max_points` points (LoopCapacity::trajectory_points), more than kMaxJoints joint
///         names or values in a point, or a joint name beyond 256 characters.
cartesian_impedance::JointTrajectory trajectory_from_message(const JointTrajectoryMessage& message,
                                                             std::uint32_t max_points);
/// Views of a JointState's arrays for node::JointStateMapper.
cartesian_impedance::node::JointStateView joint_state_view(const JointStateMessage& message);

/// builtin_interfaces/Time of a wall-clock instant (ROS 2 stamps are system time).
builtin_interfaces_msg_dds__Time_ stamp_now();

/// A Float64MultiArray of joint torques with storage of its own and the layout the ROS 1 node
/// writes (one dimension, "joints"): commanded_torques, and the effort controller's commands.
class TorqueArray {
 public:
  explicit TorqueArray(int num_joints);
  TorqueArray(const TorqueArray&) = delete;
  TorqueArray& operator=(const TorqueArray&) = delete;

  /// The message holding `tau` (valid until the next call). No allocation after the first.
  const Float64MultiArray& set(const cartesian_impedance::JointVector& tau);
  const Float64MultiArray& message() const noexcept { return message_; }

 private:
  std::vector<double> data_;
  std::string label_ = "joints";
  std_msgs_msg_dds__MultiArrayDimension_ dimension_{};
  Float64MultiArray message_{};
};

/// A tf2_msgs/TFMessage of some joints of a LinkTransforms (parent and child links as frames,
/// with the prefix), with storage of its own: set() allocates nothing.
class TransformArray {
 public:
  /// The joints whose transforms change with the chain's q (`moving`), or all the others.
  TransformArray(const cartesian_impedance::LinkTransforms& links, const std::string& tf_prefix,
                 bool moving);
  TransformArray(const TransformArray&) = delete;
  TransformArray& operator=(const TransformArray&) = delete;

  /// The message with `transforms` (LinkTransforms::compute()'s, all joints) stamped `stamp`.
  const TFMessage& set(const std::vector<Eigen::Isometry3d>& transforms,
                       const builtin_interfaces_msg_dds__Time_& stamp);
  std::size_t size() const noexcept { return indices_.size(); }

 private:
  std::vector<std::size_t> indices_;  // into the joints of the LinkTransforms
  std::vector<std::string> frames_;   // parent, child, parent, child, ...
  std::vector<geometry_msgs_msg_dds__TransformStamped_> items_;
  TFMessage message_{};
};

/// The node's outgoing messages. Their strings and sequences point into this object's storage,
/// which is sized at construction and reused: filling allocates nothing once the strings have
/// reached their length. One thread fills and writes them.
class OutgoingMessages {
 public:
  OutgoingMessages(const cartesian_impedance::RobotModel& model, const Frames& frames);
  ~OutgoingMessages();
  OutgoingMessages(const OutgoingMessages&) = delete;
  OutgoingMessages& operator=(const OutgoingMessages&) = delete;

  /// Fills every message from one loop state; `measured` (topics mode) gives the reported
  /// efforts, null in sim mode.
  void fill(const cartesian_impedance::LoopState& state,
            const cartesian_impedance::runtime::ControlThreadStatistics& timing,
            const cartesian_impedance::runtime::JointMeasurement* measured);

  const PublishedState& published_state() const noexcept { return published_; }
  const FullState& full_state() const noexcept { return full_; }
  const Float64MultiArray& commanded_torques() const noexcept { return torques_.message(); }
  const JointStateMessage& joint_state() const noexcept { return joint_state_; }
  /// The stamp of the last fill() (every message of it carries this one).
  const builtin_interfaces_msg_dds__Time_& stamp() const noexcept { return full_.header.stamp; }

  struct Storage;  // how strings and arrays are kept (messages.cpp)

 private:
  std::vector<std::string> joint_names_;
  Frames frames_;
  std::string base_frame_;                         // frames_.base_frame()
  cartesian_impedance::ModelWorkspace workspace_;  // the published state's cartesian_velocity
  cartesian_impedance::Kinematics kinematics_;
  std::unique_ptr<Storage> storage_;
  PublishedState published_{};
  FullState full_{};
  TorqueArray torques_;
  JointStateMessage joint_state_{};
};

}  // namespace cartesian_impedance_ros2
