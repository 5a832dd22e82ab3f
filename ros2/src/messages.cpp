#include "messages.hpp"

#include <chrono>
#include <cmath>
#include <cstring>
#include <string_view>
#include <unordered_map>

#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/node/log_throttle.hpp>
#include <cartesian_impedance/node/state_message.hpp>

namespace cartesian_impedance_ros2 {

namespace ci = cartesian_impedance;

namespace {

std::string_view text(const char* value) {
  return value == nullptr ? std::string_view() : value;
}

// The frame a stiffness or wrench message names. The node has no tf: other frames are refused
// rather than silently taken as the base frame.
std::optional<ci::Frame> frame_of(const char* frame_id, const Frames& frames, const char* topic) {
  const std::string_view frame = text(frame_id);
  if (frame.empty()) return std::nullopt;
  if (frames.is_base(frame)) return ci::Frame::base;
  if (frames.is_tip(frame)) return ci::Frame::end_effector;
  throw ci::Error(std::string(topic) + ": header.frame_id = " + ci::node::quoted(frame) +
                  " is not a frame of this controller (valid: '', '" + frames.base_link + "', '" +
                  frames.tip_link + "'; the ROS 2 node does not look up other frames)");
}

void set_text(char*& field, std::string& storage) {
  field = storage.data();
}

}  // namespace

bool Frames::is_base(std::string_view frame) const {
  return frame == base_link || (frame.size() == tf_prefix.size() + base_link.size() &&
                                frame.substr(0, tf_prefix.size()) == tf_prefix &&
                                frame.substr(tf_prefix.size()) == base_link);
}

bool Frames::is_tip(std::string_view frame) const {
  return frame == tip_link || (frame.size() == tf_prefix.size() + tip_link.size() &&
                               frame.substr(0, tf_prefix.size()) == tf_prefix &&
                               frame.substr(tf_prefix.size()) == tip_link);
}

ci::Pose pose_from_message(const geometry_msgs_msg_dds__Pose_& message) {
  ci::Pose pose;
  pose.position = Eigen::Vector3d(message.position.x, message.position.y, message.position.z);
  pose.orientation = Eigen::Quaterniond(message.orientation.w, message.orientation.x,
                                        message.orientation.y, message.orientation.z);
  return pose;
}

ci::Vector6d vector_from_wrench(const WrenchMessage& message) {
  ci::Vector6d vector;
  vector << message.force.x, message.force.y, message.force.z, message.torque.x, message.torque.y,
      message.torque.z;
  return vector;
}

ci::Command reference_from_message(const PoseStamped& message, const Frames& frames) {
  const std::string_view frame = text(message.header.frame_id);
  if (!frame.empty() && !frames.is_base(frame)) {
    throw ci::Error("reference_pose: header.frame_id = " + ci::node::quoted(frame) +
                    " is not the base frame (valid: '' or '" + frames.base_link +
                    "'; the ROS 2 node does not look up other frames)");
  }
  return ci::ReferencePose{pose_from_message(message.pose)};
}

ci::Command stiffness_from_message(const WrenchStamped& message, const Frames& frames) {
  return ci::Stiffness::diagonal(
      vector_from_wrench(message.wrench),
      frame_of(message.header.frame_id, frames, "set_cartesian_stiffness"));
}

ci::Command wrench_from_message(const WrenchStamped& message, const Frames& frames) {
  return ci::Wrench(vector_from_wrench(message.wrench),
                    frame_of(message.header.frame_id, frames, "set_cartesian_wrench"));
}

std::vector<ci::Command> config_from_message(const ControllerConfig& message, int num_joints) {
  std::vector<ci::Command> commands;
  commands.emplace_back(ci::Stiffness::diagonal(vector_from_wrench(message.cartesian_stiffness)));
  commands.emplace_back(ci::DampingRatio{vector_from_wrench(message.cartesian_damping_factors)});
  commands.emplace_back(
      ci::NullspaceStiffness(Eigen::VectorXd::Constant(1, message.nullspace_stiffness)));
  commands.emplace_back(ci::NullspaceDampingRatio{message.nullspace_damping_factor});
  const std::uint32_t count = message.q_d_nullspace._length;
  if (count != 0) {
    if (count != static_cast<std::uint32_t>(num_joints)) {
      throw ci::Error("set_config: q_d_nullspace has " + std::to_string(count) +
                      " values; expected none (unchanged) or one per joint (" +
                      std::to_string(num_joints) + ")");
    }
    commands.emplace_back(ci::NullspaceTarget(
        Eigen::Map<const Eigen::VectorXd>(message.q_d_nullspace._buffer, num_joints)));
  }
  return commands;
}

ci::JointTrajectory trajectory_from_message(const JointTrajectoryMessage& message,
                                            std::uint32_t max_points) {
  // Bounds first: the loop would refuse a larger trajectory, but only after the node had copied
  // all of it (a million points were a million allocations on the command thread).
  constexpr std::size_t kMaxNameLength = 256;
  const std::uint32_t joints = static_cast<std::uint32_t>(ci::kMaxJoints);
  if (message.points._length > max_points) {
    throw ci::Error("joint_trajectory: " + std::to_string(message.points._length) +
                    " points; at most " + std::to_string(max_points) + " are accepted");
  }
  if (message.joint_names._length > joints) {
    throw ci::Error("joint_trajectory: " + std::to_string(message.joint_names._length) +
                    " joint names; a chain has at most " + std::to_string(joints) + " joints");
  }
  for (std::uint32_t i = 0; i < message.joint_names._length; ++i) {
    const std::string_view name = text(message.joint_names._buffer[i]);
    if (name.size() > kMaxNameLength) {
      throw ci::Error("joint_trajectory: joint_names[" + std::to_string(i) +
                      "] = " + ci::node::quoted(name) + " is longer than " +
                      std::to_string(kMaxNameLength) + " characters");
    }
  }
  for (std::uint32_t k = 0; k < message.points._length; ++k) {
    const auto& point = message.points._buffer[k];
    for (const std::uint32_t count : {point.positions._length, point.velocities._length,
                                      point.accelerations._length, point.effort._length}) {
      if (count > joints) {
        throw ci::Error("joint_trajectory: points[" + std::to_string(k) + "] has " +
                        std::to_string(count) + " values in an array; a chain has at most " +
                        std::to_string(joints) + " joints");
      }
    }
  }
  ci::JointTrajectory trajectory;
  for (std::uint32_t i = 0; i < message.joint_names._length; ++i) {
    trajectory.joint_names.emplace_back(text(message.joint_names._buffer[i]));
  }
  std::uint32_t with_velocities = 0;
  for (std::uint32_t k = 0; k < message.points._length; ++k) {
    if (message.points._buffer[k].velocities._length != 0) ++with_velocities;
  }
  if (with_velocities != 0 && with_velocities != message.points._length) {
    throw ci::Error("joint_trajectory: " + std::to_string(with_velocities) + " of " +
                    std::to_string(message.points._length) +
                    " points have velocities; give them for every point or for none");
  }
  const auto values = [](const dds_sequence_double& sequence) {
    return std::vector<double>(sequence._buffer, sequence._buffer + sequence._length);
  };
  for (std::uint32_t k = 0; k < message.points._length; ++k) {
    const trajectory_msgs_msg_dds__JointTrajectoryPoint_& point = message.points._buffer[k];
    trajectory.times.push_back(point.time_from_start.sec + 1e-9 * point.time_from_start.nanosec);
    trajectory.positions.push_back(values(point.positions));
    if (with_velocities != 0) trajectory.velocities.push_back(values(point.velocities));
  }
  return trajectory;
}

ci::node::JointStateView joint_state_view(const JointStateMessage& message) {
  ci::node::JointStateView view;
  view.names.reserve(message.name._length);
  for (std::uint32_t i = 0; i < message.name._length; ++i) {
    view.names.push_back(text(message.name._buffer[i]));
  }
  view.position = {message.position._buffer, message.position._length};
  view.velocity = {message.velocity._buffer, message.velocity._length};
  view.effort = {message.effort._buffer, message.effort._length};
  view.stamp_ns =
      std::int64_t{message.header.stamp.sec} * 1000000000 + message.header.stamp.nanosec;
  return view;
}

builtin_interfaces_msg_dds__Time_ stamp_now() {
  const auto since_epoch = std::chrono::system_clock::now().time_since_epoch();
  const auto nanoseconds =
      std::chrono::duration_cast<std::chrono::nanoseconds>(since_epoch).count();
  builtin_interfaces_msg_dds__Time_ stamp{};
  stamp.sec = static_cast<std::int32_t>(nanoseconds / 1000000000);
  stamp.nanosec = static_cast<std::uint32_t>(nanoseconds % 1000000000);
  return stamp;
}

// ---- outgoing messages --------------------------------------------------------------------------

// Storage of the outgoing messages' strings and arrays, by the address of the field they back:
// the same fields are filled every time, so after the first fill nothing is allocated (the
// strings here are short; an array keeps its capacity).
struct OutgoingMessages::Storage {
  std::unordered_map<const void*, std::string> strings;
  std::unordered_map<const void*, std::vector<double>> arrays;
  std::vector<char*>
      name_pointers;  // the joint names, pointing into OutgoingMessages::joint_names_

  void text(char*& field, std::string_view value) {
    std::string& stored = strings[&field];
    stored.assign(value.data(), value.size());
    field = stored.data();
  }
  template <typename Vector>
  void array(dds_sequence_double& field, const Vector& values) {
    std::vector<double>& stored = arrays[&field];
    stored.assign(values.data(), values.data() + values.size());
    field._buffer = stored.data();
    field._length = field._maximum = static_cast<std::uint32_t>(stored.size());
    field._release = false;
  }
  void clear(dds_sequence_double& field) {
    field._buffer = nullptr;
    field._length = field._maximum = 0;
    field._release = false;
  }
  void names_of(dds_sequence_string& field) {
    field._buffer = name_pointers.data();
    field._length = field._maximum = static_cast<std::uint32_t>(name_pointers.size());
    field._release = false;
  }
  // The interface node::fill_state_message() writes through.
  void names(dds_sequence_string& field, const std::vector<std::string>&) { names_of(field); }
};

OutgoingMessages::OutgoingMessages(const ci::RobotModel& model, const Frames& frames)
    : joint_names_(model.joint_names()),
      frames_(frames),
      base_frame_(frames.base_frame()),
      workspace_(model),
      kinematics_(workspace_.make_kinematics()),
      storage_(std::make_unique<Storage>()),
      torques_(model.num_joints()) {
  for (std::string& name : joint_names_) storage_->name_pointers.push_back(name.data());
}

OutgoingMessages::~OutgoingMessages() = default;

void OutgoingMessages::fill(const ci::LoopState& state,
                            const ci::runtime::ControlThreadStatistics& timing,
                            const ci::runtime::JointMeasurement* measured) {
  Storage& out = *storage_;
  const builtin_interfaces_msg_dds__Time_ stamp = stamp_now();
  const ci::ControllerState& controller = state.controller;

  // This project's full state.
  full_.header.stamp = stamp;
  out.text(full_.header.frame_id, base_frame_);
  ci::node::fill_state_message(state, joint_names_, measured, full_, out);
  ci::node::fill_timing(timing, full_);
  full_.joint_state.header.stamp = stamp;
  out.text(full_.joint_state.header.frame_id, "");

  // The published controller's state, field for field.
  published_.header = full_.header;
  ci::node::fill_pose(controller.pose, published_.current_pose);
  ci::node::fill_pose(controller.filtered.pose, published_.reference_pose);
  // Its pose error: the translation, and the rotation as a quaternion.
  const Eigen::Vector3d rotation = controller.pose_error.tail<3>();
  const double angle = rotation.norm();
  const Eigen::Quaterniond error_rotation =
      angle > 0.0 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, rotation / angle))
                  : Eigen::Quaterniond::Identity();
  ci::Pose error;
  error.position = controller.pose_error.head<3>();
  error.orientation = error_rotation;
  ci::node::fill_pose(error, published_.pose_error);
  published_.joint_state = full_.joint_state;
  out.array(published_.commanded_torques, controller.tau);
  ci::node::fill_wrench(controller.filtered.stiffness.diagonal(), published_.cartesian_stiffness);
  ci::node::fill_wrench(controller.damping.diagonal(), published_.cartesian_damping);
  // One number for the whole nullspace, as the published controller has it: the first joint's.
  const double nullspace_stiffness = controller.filtered.nullspace_stiffness.size() > 0
                                         ? controller.filtered.nullspace_stiffness[0]
                                         : 0.0;
  published_.nullspace_stiffness = nullspace_stiffness;
  published_.nullspace_damping = 2.0 * controller.filtered.nullspace_damping_ratio *
                                 std::sqrt(std::max(0.0, nullspace_stiffness));
  out.array(published_.nullspace_config, controller.filtered.nullspace_q);
  ci::node::fill_wrench(controller.wrench_base, published_.commanded_wrench);
  published_.cartesian_velocity = 0.0;
  if (state.q.size() == static_cast<Eigen::Index>(joint_names_.size()) &&
      workspace_.compute(state.q, state.dq, kinematics_)) {
    published_.cartesian_velocity = (kinematics_.jacobian.topRows<3>() * state.dq).norm();
  }

  torques_.set(controller.tau);

  joint_state_ = full_.joint_state;
}

TransformArray::TransformArray(const ci::LinkTransforms& links, const std::string& tf_prefix,
                               bool moving) {
  const std::vector<ci::LinkJoint>& joints = links.joints();
  for (std::size_t i = 0; i < joints.size(); ++i) {
    if ((joints[i].chain_index >= 0) != moving) continue;
    indices_.push_back(i);
    frames_.push_back(tf_prefix + joints[i].parent);
    frames_.push_back(tf_prefix + joints[i].child);
  }
  items_.resize(indices_.size());
  for (std::size_t k = 0; k < items_.size(); ++k) {
    set_text(items_[k].header.frame_id, frames_[2 * k]);
    set_text(items_[k].child_frame_id, frames_[2 * k + 1]);
  }
  message_.transforms._buffer = items_.data();
  message_.transforms._length = message_.transforms._maximum =
      static_cast<std::uint32_t>(items_.size());
  message_.transforms._release = false;
}

const TFMessage& TransformArray::set(const std::vector<Eigen::Isometry3d>& transforms,
                                     const builtin_interfaces_msg_dds__Time_& stamp) {
  for (std::size_t k = 0; k < items_.size(); ++k) {
    const Eigen::Isometry3d& T = transforms[indices_[k]];
    geometry_msgs_msg_dds__TransformStamped_& item = items_[k];
    item.header.stamp = stamp;
    item.transform.translation = {T.translation().x(), T.translation().y(), T.translation().z()};
    const Eigen::Quaterniond rotation(T.linear());
    item.transform.rotation = {rotation.x(), rotation.y(), rotation.z(), rotation.w()};
  }
  return message_;
}

TorqueArray::TorqueArray(int num_joints) : data_(static_cast<std::size_t>(num_joints)) {
  dimension_.label = label_.data();
  dimension_.size = dimension_.stride = static_cast<std::uint32_t>(num_joints);
  message_.layout.dim._buffer = &dimension_;
  message_.layout.dim._length = message_.layout.dim._maximum = 1;
}

const Float64MultiArray& TorqueArray::set(const ci::JointVector& tau) {
  data_.assign(tau.data(), tau.data() + tau.size());
  message_.data._buffer = data_.data();
  message_.data._length = message_.data._maximum = static_cast<std::uint32_t>(data_.size());
  return message_;
}

}  // namespace cartesian_impedance_ros2
