#pragma once
/// @file
/// The fields of the controller's state message (ControllerState.msg: the ROS 1 node's
/// cartesian_impedance_ros/ControllerState and the ROS 2 node's
/// cartesian_impedance_msgs/msg/ControllerState, one definition) filled from a loop state, for any
/// generated message type with those field names. Each message representation stores strings and
/// arrays its own way (std::string and std::vector in ROS 1, pointers and DDS sequences in the
/// ROS 2 node's C types), so the caller passes `out`, which writes them:
///
///     out.text(field, std::string_view)           // a string field
///     out.array(field, const JointVector&)         // a float64[] field
///     out.clear(field)                             // an empty float64[] field
///     out.names(field, const std::vector<std::string>&)  // a string[] field
///
/// Pose, Wrench and Vector3 fields (position.x, orientation.w, force.x, x, ...) are set directly.
/// Header and timing fields are the caller's.

#include <algorithm>
#include <string>
#include <vector>

#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/runtime/control_thread.hpp"
#include "cartesian_impedance/runtime/robot_io.hpp"

namespace cartesian_impedance::node {

/// Sets a geometry_msgs Pose's fields (quaternion x, y, z, w).
template <typename PoseMessage>
void fill_pose(const Pose& pose, PoseMessage& message) {
  message.position.x = pose.position.x();
  message.position.y = pose.position.y();
  message.position.z = pose.position.z();
  message.orientation.x = pose.orientation.x();
  message.orientation.y = pose.orientation.y();
  message.orientation.z = pose.orientation.z();
  message.orientation.w = pose.orientation.w();
}

/// Sets a geometry_msgs Vector3's fields.
template <typename Vector3Message>
void fill_vector3(const Eigen::Vector3d& vector, Vector3Message& message) {
  message.x = vector.x();
  message.y = vector.y();
  message.z = vector.z();
}

/// Sets a geometry_msgs Wrench's fields from [force; torque] (also stiffness and damping
/// diagonals).
template <typename WrenchMessage>
void fill_wrench(const Vector6d& vector, WrenchMessage& message) {
  message.force.x = vector[0];
  message.force.y = vector[1];
  message.force.z = vector[2];
  message.torque.x = vector[3];
  message.torque.y = vector[4];
  message.torque.z = vector[5];
}

/// Every field of ControllerState.msg but the header and the timing fields (the limits', the safety
/// layer's and the trajectory's included). `measured` gives the
/// efforts the robot reported (may be null or have none).
template <typename Message, typename Out>
void fill_state_message(const LoopState& state, const std::vector<std::string>& joint_names,
                        const runtime::JointMeasurement* measured, Message& message, Out& out) {
  const ControllerState& controller = state.controller;
  out.text(message.status, to_string(controller.status));
  message.cycle = state.cycle;
  message.time = state.time;

  fill_pose(controller.pose, message.current_pose);
  fill_pose(controller.filtered.pose, message.reference_pose);
  fill_pose(controller.commanded.pose, message.commanded_reference_pose);
  message.pose_error_translation.x = controller.pose_error[0];
  message.pose_error_translation.y = controller.pose_error[1];
  message.pose_error_translation.z = controller.pose_error[2];
  message.pose_error_rotation.x = controller.pose_error[3];
  message.pose_error_rotation.y = controller.pose_error[4];
  message.pose_error_rotation.z = controller.pose_error[5];

  out.text(message.stiffness_frame, frame_name(controller.stiffness_frame));
  fill_wrench(controller.filtered.stiffness.diagonal(), message.cartesian_stiffness);
  fill_wrench(controller.commanded.stiffness.diagonal(), message.commanded_cartesian_stiffness);
  fill_wrench(controller.filtered.damping_ratio, message.damping_ratio);
  // The damping the law used, in the stiffness frame.
  fill_wrench(controller.damping.diagonal(), message.cartesian_damping);

  out.text(message.wrench_frame, frame_name(controller.wrench_frame));
  fill_wrench(controller.commanded.wrench, message.commanded_wrench);
  fill_wrench(controller.wrench_base, message.wrench);

  out.names(message.joint_state.name, joint_names);
  out.array(message.joint_state.position, state.q);
  out.array(message.joint_state.velocity, state.dq);
  if (measured != nullptr && measured->effort.size() == controller.tau.size()) {
    out.array(message.joint_state.effort, measured->effort);
    out.array(message.external_torques, JointVector(measured->effort - controller.tau));
  } else {
    out.clear(message.joint_state.effort);
    out.clear(message.external_torques);
  }
  out.array(message.nullspace_config, controller.filtered.nullspace_q);
  out.array(message.nullspace_stiffness, controller.filtered.nullspace_stiffness);
  message.nullspace_damping_ratio = controller.filtered.nullspace_damping_ratio;

  out.array(message.commanded_torques, controller.tau);
  out.array(message.cartesian_torques, controller.tau_cartesian);
  out.array(message.nullspace_torques, controller.tau_nullspace);
  out.array(message.wrench_torques, controller.tau_wrench);
  out.array(message.gravity_torques, controller.tau_gravity);

  const ActiveLimits& limits = controller.limits;
  message.stiffness_saturated = limits.stiffness_saturated;
  message.damping_ratio_saturated = limits.damping_ratio_saturated;
  message.nullspace_stiffness_saturated = limits.nullspace_stiffness_saturated;
  message.wrench_saturated = limits.wrench_saturated;
  message.translation_error_clipped = limits.translation_error_clipped;
  message.rotation_error_clipped = limits.rotation_error_clipped;
  message.joint_torque_saturated = limits.joint_torque_saturated;
  message.torque_rate_limited = limits.torque_rate_limited;

  const TrajectoryProgress& trajectory = state.trajectory;
  out.text(message.trajectory_state, to_string(trajectory.state));
  message.trajectory_id = trajectory.id;
  message.trajectory_time = trajectory.time;
  message.trajectory_duration = trajectory.duration;
  message.trajectory_progress = trajectory.duration > 0.0
                                    ? std::clamp(trajectory.time / trajectory.duration, 0.0, 1.0)
                                    : (trajectory.state == TrajectoryState::finished ? 1.0 : 0.0);
  message.trajectory_goal_error = trajectory.goal_error;

  out.text(message.torque_shaping, to_string(limits.torque_shaping));
  message.torque_shaping_scale = limits.torque_shaping_scale;
  message.holding = limits.holding;

  const SafetyState& safety = controller.safety;
  message.reference_speed_limited = safety.reference_speed_limited;
  message.translation_drive_scale = safety.translation_drive_scale;
  message.rotation_drive_scale = safety.rotation_drive_scale;
  message.braking = safety.braking;
  message.force_scale = safety.force_scale;
  message.torque_scale = safety.torque_scale;
  message.reference_clipped = safety.reference_clipped;
  fill_vector3(safety.workspace_penetration, message.workspace_penetration);
  fill_vector3(safety.wall_force, message.wall_force);
  message.tank_level = safety.tank_level;
  message.tank_draw = safety.tank_draw;
  message.stiffness_change_scale = safety.stiffness_change_scale;
  message.payload_mass = safety.payload_mass;
  fill_vector3(safety.payload_center_of_mass, message.payload_center_of_mass);
  message.payload_estimate_valid = safety.payload_estimate_valid;
  message.payload_estimate_mass = safety.payload_estimate_mass;
  fill_vector3(safety.payload_estimate_center_of_mass, message.payload_estimate_center_of_mass);
  message.oscillation_scale = safety.oscillation_scale;
  message.oscillations = static_cast<std::uint64_t>(safety.oscillations);
  message.generated_energy = safety.generated_energy;
  message.passivity_scale_translation = safety.passivity_scale[0];
  message.passivity_scale_rotation = safety.passivity_scale[1];
  message.passivity_scale_nullspace = safety.passivity_scale[2];
  message.passivity_halvings = static_cast<std::uint64_t>(safety.passivity_halvings);
  message.max_speed_translation_in_force = safety.max_speed_in_force.translation;
  message.max_force_in_force = safety.max_force_in_force.force;
  message.pfl_speed_limit = safety.pfl_speed_limit;
  message.pfl_effective_mass = safety.pfl_effective_mass;

  const CollisionState& collision = controller.collision;
  message.collision_detected = collision.detected;
  message.collision_time = collision.time;
  const bool named =
      collision.joint >= 0 && static_cast<std::size_t>(collision.joint) < joint_names.size();
  out.text(message.collision_joint,
           named ? std::string_view(joint_names[static_cast<std::size_t>(collision.joint)])
                 : std::string_view());
  out.text(message.collision_reaction, reaction_name(collision.reaction));
  message.collisions = static_cast<std::uint64_t>(collision.collisions);
  out.array(message.collision_residual, collision.residual);
  out.array(message.collision_threshold, collision.threshold);
}

/// The timing fields of ControllerState.msg from the control thread's statistics since it
/// started.
template <typename Message>
void fill_timing(const runtime::ControlThreadStatistics& statistics, Message& message) {
  message.overruns = statistics.overruns;
  message.latest_lateness_us = statistics.latest_lateness_us;
  message.worst_lateness_us = statistics.worst_lateness_us;
  message.period_min_us = statistics.period_min_us;
  message.period_p50_us = statistics.period_p50_us;
  message.period_p99_us = statistics.period_p99_us;
  message.period_max_us = statistics.period_max_us;
  message.stale_episodes = statistics.stale_episodes;
  message.realtime = statistics.realtime;
  message.measurement_age_p50_us = statistics.measurement_age_p50_us;
  message.measurement_age_p99_us = statistics.measurement_age_p99_us;
  message.measurement_age_max_us = statistics.measurement_age_max_us;
}

}  // namespace cartesian_impedance::node
