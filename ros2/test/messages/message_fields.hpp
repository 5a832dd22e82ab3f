#pragma once
/// @file
/// The field lists of the .msg files (ros2/msg/*/msg, ros2/interfaces/*/msg), transcribed by hand:
/// for each message, its fields in the order and with the ROS 2 type the .msg file gives, each
/// bound to the member of the generated C struct of the same name. A visitor sees the .msg type
/// (v.float64, v.string, ...), so an encoder driven by these lists writes what the .msg file
/// declares whatever order or type the generator gave the member: a generator that reorders or
/// retypes a field produces bytes that differ from the hand encoder's.
///
/// Visitor interface: boolean, int32, uint32, uint64, float64, string (char*), float64_seq,
/// string_seq, nested (a struct), nested_seq (a sequence of structs).

#include "ros2_messages.h"

namespace ros2_messages_test {

// builtin_interfaces/msg/Duration.msg: int32 sec, uint32 nanosec
template <class V>
void visit(V& v, builtin_interfaces_msg_dds__Duration_& m) {
  v.int32(m.sec);
  v.uint32(m.nanosec);
}

// builtin_interfaces/msg/Time.msg: int32 sec, uint32 nanosec
template <class V>
void visit(V& v, builtin_interfaces_msg_dds__Time_& m) {
  v.int32(m.sec);
  v.uint32(m.nanosec);
}

// std_msgs/msg/Header.msg: builtin_interfaces/Time stamp, string frame_id
template <class V>
void visit(V& v, std_msgs_msg_dds__Header_& m) {
  v.nested(m.stamp);
  v.string(m.frame_id);
}

// std_msgs/msg/MultiArrayDimension.msg: string label, uint32 size, uint32 stride
template <class V>
void visit(V& v, std_msgs_msg_dds__MultiArrayDimension_& m) {
  v.string(m.label);
  v.uint32(m.size);
  v.uint32(m.stride);
}

// std_msgs/msg/MultiArrayLayout.msg: MultiArrayDimension[] dim, uint32 data_offset
template <class V>
void visit(V& v, std_msgs_msg_dds__MultiArrayLayout_& m) {
  v.nested_seq(m.dim);
  v.uint32(m.data_offset);
}

// std_msgs/msg/Float64MultiArray.msg: MultiArrayLayout layout, float64[] data
template <class V>
void visit(V& v, std_msgs_msg_dds__Float64MultiArray_& m) {
  v.nested(m.layout);
  v.float64_seq(m.data);
}

// geometry_msgs/msg/Point.msg: float64 x, y, z
template <class V>
void visit(V& v, geometry_msgs_msg_dds__Point_& m) {
  v.float64(m.x);
  v.float64(m.y);
  v.float64(m.z);
}

// geometry_msgs/msg/Quaternion.msg: float64 x, y, z, w (defaults 0 0 0 1; not on the wire)
template <class V>
void visit(V& v, geometry_msgs_msg_dds__Quaternion_& m) {
  v.float64(m.x);
  v.float64(m.y);
  v.float64(m.z);
  v.float64(m.w);
}

// geometry_msgs/msg/Pose.msg: Point position, Quaternion orientation
template <class V>
void visit(V& v, geometry_msgs_msg_dds__Pose_& m) {
  v.nested(m.position);
  v.nested(m.orientation);
}

// geometry_msgs/msg/PoseStamped.msg: std_msgs/Header header, Pose pose
template <class V>
void visit(V& v, geometry_msgs_msg_dds__PoseStamped_& m) {
  v.nested(m.header);
  v.nested(m.pose);
}

// geometry_msgs/msg/Vector3.msg: float64 x, y, z
template <class V>
void visit(V& v, geometry_msgs_msg_dds__Vector3_& m) {
  v.float64(m.x);
  v.float64(m.y);
  v.float64(m.z);
}

// geometry_msgs/msg/Wrench.msg: Vector3 force, Vector3 torque
template <class V>
void visit(V& v, geometry_msgs_msg_dds__Wrench_& m) {
  v.nested(m.force);
  v.nested(m.torque);
}

// geometry_msgs/msg/WrenchStamped.msg: std_msgs/Header header, Wrench wrench
template <class V>
void visit(V& v, geometry_msgs_msg_dds__WrenchStamped_& m) {
  v.nested(m.header);
  v.nested(m.wrench);
}

// geometry_msgs/msg/Transform.msg: Vector3 translation, Quaternion rotation
template <class V>
void visit(V& v, geometry_msgs_msg_dds__Transform_& m) {
  v.nested(m.translation);
  v.nested(m.rotation);
}

// geometry_msgs/msg/TransformStamped.msg: std_msgs/Header header, string child_frame_id,
// Transform transform
template <class V>
void visit(V& v, geometry_msgs_msg_dds__TransformStamped_& m) {
  v.nested(m.header);
  v.string(m.child_frame_id);
  v.nested(m.transform);
}

// tf2_msgs/msg/TFMessage.msg: geometry_msgs/TransformStamped[] transforms
template <class V>
void visit(V& v, tf2_msgs_msg_dds__TFMessage_& m) {
  v.nested_seq(m.transforms);
}

// rmw_dds_common/msg/Gid.msg: char[16] data (Iron and later)
template <class V>
void visit(V& v, rmw_dds_common_msg_dds__Gid_& m) {
  v.octet_array(m.data);
}

// rmw_dds_common/msg/NodeEntitiesInfo.msg: string<=256 node_namespace, string<=256 node_name,
// Gid[] reader_gid_seq, Gid[] writer_gid_seq
template <class V>
void visit(V& v, rmw_dds_common_msg_dds__NodeEntitiesInfo_& m) {
  v.bounded_string(m.node_namespace);
  v.bounded_string(m.node_name);
  v.nested_seq(m.reader_gid_seq);
  v.nested_seq(m.writer_gid_seq);
}

// rmw_dds_common/msg/ParticipantEntitiesInfo.msg: Gid gid,
// NodeEntitiesInfo[] node_entities_info_seq
template <class V>
void visit(V& v, rmw_dds_common_msg_dds__ParticipantEntitiesInfo_& m) {
  v.nested(m.gid);
  v.nested_seq(m.node_entities_info_seq);
}

// std_msgs/msg/Empty.msg: no field; rosidl's one member, uint8 structure_needs_at_least_one_member
template <class V>
void visit(V& v, std_msgs_msg_dds__Empty_& m) {
  v.uint8(m.structure_needs_at_least_one_member);
}

// std_msgs/msg/String.msg: string data
template <class V>
void visit(V& v, std_msgs_msg_dds__String_& m) {
  v.string(m.data);
}

// sensor_msgs/msg/JointState.msg: std_msgs/Header header, string[] name, float64[] position,
// float64[] velocity, float64[] effort
template <class V>
void visit(V& v, sensor_msgs_msg_dds__JointState_& m) {
  v.nested(m.header);
  v.string_seq(m.name);
  v.float64_seq(m.position);
  v.float64_seq(m.velocity);
  v.float64_seq(m.effort);
}

// trajectory_msgs/msg/JointTrajectoryPoint.msg: float64[] positions, float64[] velocities,
// float64[] accelerations, float64[] effort, builtin_interfaces/Duration time_from_start
template <class V>
void visit(V& v, trajectory_msgs_msg_dds__JointTrajectoryPoint_& m) {
  v.float64_seq(m.positions);
  v.float64_seq(m.velocities);
  v.float64_seq(m.accelerations);
  v.float64_seq(m.effort);
  v.nested(m.time_from_start);
}

// trajectory_msgs/msg/JointTrajectory.msg: std_msgs/Header header, string[] joint_names,
// JointTrajectoryPoint[] points
template <class V>
void visit(V& v, trajectory_msgs_msg_dds__JointTrajectory_& m) {
  v.nested(m.header);
  v.string_seq(m.joint_names);
  v.nested_seq(m.points);
}

// cartesian_impedance_controller/msg/ControllerConfig.msg: geometry_msgs/Wrench
// cartesian_stiffness, geometry_msgs/Wrench cartesian_damping_factors, float64
// nullspace_stiffness, float64 nullspace_damping_factor, float64[] q_d_nullspace
template <class V>
void visit(V& v, cartesian_impedance_controller_msg_dds__ControllerConfig_& m) {
  v.nested(m.cartesian_stiffness);
  v.nested(m.cartesian_damping_factors);
  v.float64(m.nullspace_stiffness);
  v.float64(m.nullspace_damping_factor);
  v.float64_seq(m.q_d_nullspace);
}

// cartesian_impedance_controller/msg/ControllerState.msg
template <class V>
void visit(V& v, cartesian_impedance_controller_msg_dds__ControllerState_& m) {
  v.nested(m.header);          // std_msgs/Header
  v.nested(m.current_pose);    // geometry_msgs/Pose
  v.nested(m.reference_pose);  // geometry_msgs/Pose
  v.nested(m.pose_error);      // geometry_msgs/Pose
  v.nested(m.joint_state);     // sensor_msgs/JointState
  v.float64_seq(m.commanded_torques);
  v.nested(m.cartesian_stiffness);  // geometry_msgs/Wrench
  v.nested(m.cartesian_damping);    // geometry_msgs/Wrench
  v.float64(m.nullspace_stiffness);
  v.float64(m.nullspace_damping);
  v.float64_seq(m.nullspace_config);
  v.nested(m.commanded_wrench);  // geometry_msgs/Wrench
  v.float64(m.cartesian_velocity);
}

// cartesian_impedance_msgs/msg/ControllerState.msg (this project's full state)
template <class V>
void visit(V& v, cartesian_impedance_msgs_msg_dds__ControllerState_& m) {
  v.nested(m.header);  // std_msgs/Header
  v.string(m.status);
  v.uint64(m.cycle);
  v.float64(m.time);
  v.nested(m.current_pose);              // geometry_msgs/Pose
  v.nested(m.reference_pose);            // geometry_msgs/Pose
  v.nested(m.commanded_reference_pose);  // geometry_msgs/Pose
  v.nested(m.pose_error_translation);    // geometry_msgs/Vector3
  v.nested(m.pose_error_rotation);       // geometry_msgs/Vector3
  v.string(m.stiffness_frame);
  v.nested(m.cartesian_stiffness);            // geometry_msgs/Wrench
  v.nested(m.commanded_cartesian_stiffness);  // geometry_msgs/Wrench
  v.nested(m.damping_ratio);                  // geometry_msgs/Wrench
  v.nested(m.cartesian_damping);              // geometry_msgs/Wrench
  v.string(m.wrench_frame);
  v.nested(m.commanded_wrench);  // geometry_msgs/Wrench
  v.nested(m.wrench);            // geometry_msgs/Wrench
  v.nested(m.joint_state);       // sensor_msgs/JointState
  v.float64_seq(m.nullspace_config);
  v.float64_seq(m.nullspace_stiffness);
  v.float64(m.nullspace_damping_ratio);
  v.float64_seq(m.commanded_torques);
  v.float64_seq(m.cartesian_torques);
  v.float64_seq(m.nullspace_torques);
  v.float64_seq(m.wrench_torques);
  v.float64_seq(m.gravity_torques);
  v.float64_seq(m.external_torques);
  v.boolean(m.stiffness_saturated);
  v.boolean(m.damping_ratio_saturated);
  v.boolean(m.nullspace_stiffness_saturated);
  v.boolean(m.wrench_saturated);
  v.boolean(m.translation_error_clipped);
  v.boolean(m.rotation_error_clipped);
  v.boolean(m.joint_torque_saturated);
  v.boolean(m.torque_rate_limited);
  v.string(m.trajectory_state);
  v.uint64(m.trajectory_id);
  v.float64(m.trajectory_time);
  v.float64(m.trajectory_duration);
  v.float64(m.trajectory_progress);
  v.float64(m.trajectory_goal_error);
  v.uint64(m.overruns);
  v.float64(m.latest_lateness_us);
  v.float64(m.worst_lateness_us);
  v.float64(m.period_min_us);
  v.float64(m.period_p50_us);
  v.float64(m.period_p99_us);
  v.float64(m.period_max_us);
  v.uint64(m.stale_episodes);
  v.boolean(m.realtime);
  v.string(m.torque_shaping);
  v.float64(m.torque_shaping_scale);
  v.boolean(m.holding);
  v.boolean(m.reference_speed_limited);
  v.float64(m.translation_drive_scale);
  v.float64(m.rotation_drive_scale);
  v.boolean(m.braking);
  v.float64(m.force_scale);
  v.float64(m.torque_scale);
  v.boolean(m.reference_clipped);
  v.nested(m.workspace_penetration);  // geometry_msgs/Vector3
  v.nested(m.wall_force);             // geometry_msgs/Vector3
  v.float64(m.tank_level);
  v.float64(m.tank_draw);
  v.float64(m.stiffness_change_scale);
  v.float64(m.payload_mass);
  v.nested(m.payload_center_of_mass);  // geometry_msgs/Vector3
  v.boolean(m.payload_estimate_valid);
  v.float64(m.payload_estimate_mass);
  v.nested(m.payload_estimate_center_of_mass);  // geometry_msgs/Vector3
  v.float64(m.measurement_age_p50_us);
  v.float64(m.measurement_age_p99_us);
  v.float64(m.measurement_age_max_us);
  v.float64(m.oscillation_scale);
  v.uint64(m.oscillations);
  v.float64(m.generated_energy);
  v.float64(m.passivity_scale_translation);
  v.float64(m.passivity_scale_rotation);
  v.float64(m.passivity_scale_nullspace);
  v.uint64(m.passivity_halvings);
  v.float64(m.max_speed_translation_in_force);
  v.float64(m.max_force_in_force);
  v.float64(m.pfl_speed_limit);
  v.float64(m.pfl_effective_mass);
  v.boolean(m.collision_detected);
  v.float64(m.collision_time);
  v.string(m.collision_joint);
  v.string(m.collision_reaction);
  v.uint64(m.collisions);
  v.float64_seq(m.collision_residual);
  v.float64_seq(m.collision_threshold);
}

}  // namespace ros2_messages_test
