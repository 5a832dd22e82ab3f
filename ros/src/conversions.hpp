#pragma once
/// @file
/// Conversions between ROS messages and the library's types. No ROS master or node is needed,
/// so they are unit-tested on their own. Validation of values (finite, unit quaternion, ranges)
/// is left to the library, which throws cartesian_impedance::Error; these functions throw the same
/// type for what only a message can get wrong (array sizes, joint names).

#include <geometry_msgs/Pose.h>
#include <geometry_msgs/Transform.h>
#include <geometry_msgs/Wrench.h>
#include <sensor_msgs/JointState.h>
#include <trajectory_msgs/JointTrajectory.h>

#include <string>
#include <vector>

#include <cartesian_impedance/core/trajectory.hpp>
#include <cartesian_impedance/core/types.hpp>
#include <cartesian_impedance/loop/control_loop.hpp>
#include <cartesian_impedance/node/joint_states.hpp>
#include <cartesian_impedance/runtime/control_thread.hpp>
#include <cartesian_impedance/runtime/robot_io.hpp>

#include <cartesian_impedance_ros/ControllerState.h>

namespace cartesian_impedance_ros {

/// A measured joint state in the model's joint order, handed from the joint_states callback to
/// the control thread through the runtime's lock-free MeasurementBuffer (fixed-size storage:
/// copying it does not allocate).
using JointSample = cartesian_impedance::runtime::JointMeasurement;

/// A sensor_msgs/JointState as the view the runtime's JointStateMapper maps into the model's
/// joint order (runtime/joint_states.hpp). The view points into `message`: keep it alive.
cartesian_impedance::node::JointStateView joint_state_view(const sensor_msgs::JointState& message);

/// Position and quaternion (x, y, z, w), not normalised: the library checks the unit norm.
cartesian_impedance::Pose pose_from_message(const geometry_msgs::Pose& message);
void pose_to_message(const cartesian_impedance::Pose& pose, geometry_msgs::Pose& message);

/// [force; torque] as a 6-vector (also used for stiffness and damping-ratio diagonals).
cartesian_impedance::Vector6d vector_from_wrench(const geometry_msgs::Wrench& message);
void vector_to_wrench(const cartesian_impedance::Vector6d& vector, geometry_msgs::Wrench& message);

/// T_parent_child of a tf2 transform.
Eigen::Isometry3d isometry_from_transform(const geometry_msgs::Transform& message);
/// A tf2 transform of T_parent_child.
void transform_to_message(const Eigen::Isometry3d& T, geometry_msgs::Transform& message);

/// T_base_frame * pose_frame: a pose given in `frame`, expressed in the base frame.
cartesian_impedance::Pose transform_pose(const Eigen::Isometry3d& T_base_frame,
                                         const cartesian_impedance::Pose& pose_frame);

/// A wrench [force; torque] given in another frame, rotated into the base frame; the point it
/// acts at stays the end-effector origin (as in the published controller).
cartesian_impedance::Vector6d rotate_wrench(const Eigen::Matrix3d& R_base_frame,
                                            const cartesian_impedance::Vector6d& wrench_frame);

/// A diagonal stiffness given in another frame, as a full matrix in the base frame:
/// K_base = R K R^T for the translational and the rotational block.
cartesian_impedance::Matrix6d rotate_stiffness(const Eigen::Matrix3d& R_base_frame,
                                               const cartesian_impedance::Vector6d& diagonal);

/// The library's trajectory from a trajectory_msgs/JointTrajectory (header.stamp is ignored:
/// execution starts at the next control cycle). Velocities are used if every point has them.
/// @throws cartesian_impedance::Error if some points have velocities and others not.
cartesian_impedance::JointTrajectory trajectory_from_message(
    const trajectory_msgs::JointTrajectory& message);

/// Fills every field of `message` but the header from a loop state. `measured` gives the
/// efforts the robot reported (may be null or have no efforts).
void fill_state_message(const cartesian_impedance::LoopState& state,
                        const std::vector<std::string>& joint_names, const JointSample* measured,
                        ControllerState& message);

/// Fills the timing fields of `message` (overruns, lateness, period quantiles, stale episodes,
/// realtime) from the control thread's statistics since it started.
void fill_timing(const cartesian_impedance::runtime::ControlThreadStatistics& statistics,
                 ControllerState& message);

}  // namespace cartesian_impedance_ros
