#include "conversions.hpp"

#include <algorithm>
#include <string>
#include <string_view>

#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/node/state_message.hpp>

namespace cartesian_impedance_ros {

namespace ci = cartesian_impedance;

ci::node::JointStateView joint_state_view(const sensor_msgs::JointState& message) {
  ci::node::JointStateView view;
  view.names.assign(message.name.begin(), message.name.end());
  view.position = {message.position.data(), message.position.size()};
  view.velocity = {message.velocity.data(), message.velocity.size()};
  view.effort = {message.effort.data(), message.effort.size()};
  view.stamp_ns = static_cast<std::int64_t>(message.header.stamp.toNSec());
  return view;
}

ci::Pose pose_from_message(const geometry_msgs::Pose& message) {
  ci::Pose pose;
  pose.position = Eigen::Vector3d(message.position.x, message.position.y, message.position.z);
  pose.orientation = Eigen::Quaterniond(message.orientation.w, message.orientation.x,
                                        message.orientation.y, message.orientation.z);
  return pose;
}

void pose_to_message(const ci::Pose& pose, geometry_msgs::Pose& message) {
  ci::node::fill_pose(pose, message);
}

ci::Vector6d vector_from_wrench(const geometry_msgs::Wrench& message) {
  ci::Vector6d vector;
  vector << message.force.x, message.force.y, message.force.z, message.torque.x, message.torque.y,
      message.torque.z;
  return vector;
}

void vector_to_wrench(const ci::Vector6d& vector, geometry_msgs::Wrench& message) {
  ci::node::fill_wrench(vector, message);
}

Eigen::Isometry3d isometry_from_transform(const geometry_msgs::Transform& message) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() =
      Eigen::Vector3d(message.translation.x, message.translation.y, message.translation.z);
  Eigen::Quaterniond rotation(message.rotation.w, message.rotation.x, message.rotation.y,
                              message.rotation.z);
  // tf2 keeps its quaternions normalised; guard against a degenerate one anyway.
  if (rotation.norm() > 0.0) rotation.normalize();
  T.linear() = rotation.toRotationMatrix();
  return T;
}

void transform_to_message(const Eigen::Isometry3d& T, geometry_msgs::Transform& message) {
  message.translation.x = T.translation().x();
  message.translation.y = T.translation().y();
  message.translation.z = T.translation().z();
  const Eigen::Quaterniond rotation(T.linear());
  message.rotation.x = rotation.x();
  message.rotation.y = rotation.y();
  message.rotation.z = rotation.z();
  message.rotation.w = rotation.w();
}

ci::Pose transform_pose(const Eigen::Isometry3d& T_base_frame, const ci::Pose& pose_frame) {
  ci::Pose pose_base;
  pose_base.position = T_base_frame * pose_frame.position;
  // Quaternion product keeps the norm of the given quaternion, so the library's unit-norm check
  // still sees what was sent.
  pose_base.orientation = Eigen::Quaterniond(T_base_frame.linear()) * pose_frame.orientation;
  return pose_base;
}

ci::Vector6d rotate_wrench(const Eigen::Matrix3d& R_base_frame, const ci::Vector6d& wrench_frame) {
  ci::Vector6d wrench_base;
  wrench_base.head<3>() = R_base_frame * wrench_frame.head<3>();
  wrench_base.tail<3>() = R_base_frame * wrench_frame.tail<3>();
  return wrench_base;
}

ci::Matrix6d rotate_stiffness(const Eigen::Matrix3d& R_base_frame, const ci::Vector6d& diagonal) {
  ci::Matrix6d stiffness = ci::Matrix6d::Zero();
  stiffness.topLeftCorner<3, 3>() =
      R_base_frame * diagonal.head<3>().asDiagonal() * R_base_frame.transpose();
  stiffness.bottomRightCorner<3, 3>() =
      R_base_frame * diagonal.tail<3>().asDiagonal() * R_base_frame.transpose();
  return stiffness;
}

ci::JointTrajectory trajectory_from_message(const trajectory_msgs::JointTrajectory& message) {
  ci::JointTrajectory trajectory;
  trajectory.joint_names = message.joint_names;
  const std::size_t with_velocities =
      static_cast<std::size_t>(std::count_if(message.points.begin(), message.points.end(),
                                             [](const auto& p) { return !p.velocities.empty(); }));
  if (with_velocities != 0 && with_velocities != message.points.size()) {
    throw ci::Error("joint_trajectory: " + std::to_string(with_velocities) + " of " +
                    std::to_string(message.points.size()) +
                    " points have velocities; give them for every point or for none");
  }
  for (const trajectory_msgs::JointTrajectoryPoint& point : message.points) {
    trajectory.times.push_back(point.time_from_start.toSec());
    trajectory.positions.push_back(point.positions);
    if (with_velocities != 0) trajectory.velocities.push_back(point.velocities);
  }
  return trajectory;
}

namespace {

// How node::fill_state_message() writes ROS 1's strings and arrays.
struct Ros1Fields {
  void text(std::string& field, std::string_view value) {
    field.assign(value.data(), value.size());
  }
  template <typename Vector>
  void array(std::vector<double>& field, const Vector& values) {
    field.assign(values.data(), values.data() + values.size());
  }
  void clear(std::vector<double>& field) { field.clear(); }
  void names(std::vector<std::string>& field, const std::vector<std::string>& names) {
    field = names;
  }
};

}  // namespace

void fill_state_message(const ci::LoopState& state, const std::vector<std::string>& joint_names,
                        const JointSample* measured, ControllerState& message) {
  Ros1Fields fields;
  ci::node::fill_state_message(state, joint_names, measured, message, fields);
}

void fill_timing(const ci::runtime::ControlThreadStatistics& statistics, ControllerState& message) {
  ci::node::fill_timing(statistics, message);
}

}  // namespace cartesian_impedance_ros
