#include "conversions.hpp"

#include <algorithm>
#include <string>

#include <cartesian_impedance/error.hpp>

namespace cartesian_impedance_ros {

namespace ci = cartesian_impedance;

ci::runtime::JointStateView joint_state_view(const sensor_msgs::JointState& message) {
  ci::runtime::JointStateView view;
  view.names.assign(message.name.begin(), message.name.end());
  view.position = {message.position.data(), message.position.size()};
  view.velocity = {message.velocity.data(), message.velocity.size()};
  view.effort = {message.effort.data(), message.effort.size()};
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
  message.position.x = pose.position.x();
  message.position.y = pose.position.y();
  message.position.z = pose.position.z();
  message.orientation.x = pose.orientation.x();
  message.orientation.y = pose.orientation.y();
  message.orientation.z = pose.orientation.z();
  message.orientation.w = pose.orientation.w();
}

ci::Vector6d vector_from_wrench(const geometry_msgs::Wrench& message) {
  ci::Vector6d vector;
  vector << message.force.x, message.force.y, message.force.z, message.torque.x, message.torque.y,
      message.torque.z;
  return vector;
}

void vector_to_wrench(const ci::Vector6d& vector, geometry_msgs::Wrench& message) {
  message.force.x = vector[0];
  message.force.y = vector[1];
  message.force.z = vector[2];
  message.torque.x = vector[3];
  message.torque.y = vector[4];
  message.torque.z = vector[5];
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

template <typename Vector>
void copy(const Vector& from, std::vector<double>& to) {
  to.assign(from.data(), from.data() + from.size());
}

}  // namespace

void fill_state_message(const ci::LoopState& state, const std::vector<std::string>& joint_names,
                        const JointSample* measured, ControllerState& message) {
  const ci::ControllerState& controller = state.controller;
  message.status = ci::to_string(controller.status);
  message.cycle = state.cycle;
  message.time = state.time;

  pose_to_message(controller.pose, message.current_pose);
  pose_to_message(controller.filtered.pose, message.reference_pose);
  pose_to_message(controller.commanded.pose, message.commanded_reference_pose);
  message.pose_error_translation.x = controller.pose_error[0];
  message.pose_error_translation.y = controller.pose_error[1];
  message.pose_error_translation.z = controller.pose_error[2];
  message.pose_error_rotation.x = controller.pose_error[3];
  message.pose_error_rotation.y = controller.pose_error[4];
  message.pose_error_rotation.z = controller.pose_error[5];

  message.stiffness_frame = std::string(ci::frame_name(controller.stiffness_frame));
  vector_to_wrench(controller.filtered.stiffness.diagonal(), message.cartesian_stiffness);
  vector_to_wrench(controller.commanded.stiffness.diagonal(),
                   message.commanded_cartesian_stiffness);
  vector_to_wrench(controller.filtered.damping_ratio, message.damping_ratio);
  // The damping the law used, in the stiffness frame.
  vector_to_wrench(controller.damping.diagonal(), message.cartesian_damping);

  message.wrench_frame = std::string(ci::frame_name(controller.wrench_frame));
  vector_to_wrench(controller.commanded.wrench, message.commanded_wrench);
  vector_to_wrench(controller.wrench_base, message.wrench);

  message.joint_state.name = joint_names;
  copy(state.q, message.joint_state.position);
  copy(state.dq, message.joint_state.velocity);
  message.joint_state.effort.clear();
  message.external_torques.clear();
  if (measured != nullptr && measured->effort.size() == controller.tau.size()) {
    copy(measured->effort, message.joint_state.effort);
    const ci::JointVector external = measured->effort - controller.tau;
    copy(external, message.external_torques);
  }
  copy(controller.filtered.nullspace_q, message.nullspace_config);
  copy(controller.filtered.nullspace_stiffness, message.nullspace_stiffness);
  message.nullspace_damping_ratio = controller.filtered.nullspace_damping_ratio;

  copy(controller.tau, message.commanded_torques);
  copy(controller.tau_cartesian, message.cartesian_torques);
  copy(controller.tau_nullspace, message.nullspace_torques);
  copy(controller.tau_wrench, message.wrench_torques);
  copy(controller.tau_gravity, message.gravity_torques);

  const ci::ActiveLimits& limits = controller.limits;
  message.stiffness_saturated = limits.stiffness_saturated;
  message.damping_ratio_saturated = limits.damping_ratio_saturated;
  message.nullspace_stiffness_saturated = limits.nullspace_stiffness_saturated;
  message.wrench_saturated = limits.wrench_saturated;
  message.translation_error_clipped = limits.translation_error_clipped;
  message.rotation_error_clipped = limits.rotation_error_clipped;
  message.joint_torque_saturated = limits.joint_torque_saturated;
  message.torque_rate_limited = limits.torque_rate_limited;

  const ci::TrajectoryProgress& trajectory = state.trajectory;
  message.trajectory_state = ci::to_string(trajectory.state);
  message.trajectory_id = trajectory.id;
  message.trajectory_time = trajectory.time;
  message.trajectory_duration = trajectory.duration;
  message.trajectory_progress =
      trajectory.duration > 0.0 ? std::clamp(trajectory.time / trajectory.duration, 0.0, 1.0)
                                : (trajectory.state == ci::TrajectoryState::finished ? 1.0 : 0.0);
  message.trajectory_goal_error = trajectory.goal_error;
}

void fill_timing(const ci::runtime::ControlThreadStatistics& statistics, ControllerState& message) {
  message.overruns = statistics.overruns;
  message.latest_lateness_us = statistics.latest_lateness_us;
  message.worst_lateness_us = statistics.worst_lateness_us;
  message.period_min_us = statistics.period_min_us;
  message.period_p50_us = statistics.period_p50_us;
  message.period_p99_us = statistics.period_p99_us;
  message.period_max_us = statistics.period_max_us;
  message.stale_episodes = statistics.stale_episodes;
  message.realtime = statistics.realtime;
}

}  // namespace cartesian_impedance_ros
