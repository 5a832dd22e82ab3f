#pragma once
/// @file
/// Fixed-size and bounded-size Eigen types shared by every layer, plus the plain structs that
/// describe a pose and a measured robot state. Joint-sized objects have a compile-time maximum so
/// that nothing on the control path allocates.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace cartesian_impedance {

/// Largest joint count the library supports; joint-sized storage is reserved for this many. Two
/// 7-joint arms in one simulation need 14; a mobile manipulator's arm and torso fit too.
inline constexpr int kMaxJoints = 16;

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;
/// Joint-space vector, sized at run time (1..kMaxJoints) without heap storage.
using JointVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxJoints, 1>;
/// Joint-space square matrix (n x n) without heap storage.
using JointMatrix =
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor, kMaxJoints, kMaxJoints>;
/// Geometric Jacobian, 6 x n: rows [linear; angular], reference point the end-effector origin,
/// expressed in the base frame.
using Jacobian = Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::ColMajor, 6, kMaxJoints>;

/// Quaternions given as four numbers (YAML, messages, Python) are accepted if their norm is this
/// close to one (and then normalised): a message rounded to a few digits passes, a zero or
/// garbage quaternion does not.
inline constexpr double kQuaternionNormTolerance = 1e-3;

/// A frame's position [m] and orientation (unit quaternion), both in the base frame.
struct Pose {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
};

/// Frame in which a stiffness or a wrench is given.
enum class Frame {
  base,         ///< the root link of the kinematic chain
  end_effector  ///< the end-effector (tip) frame, rotated into the base frame every cycle
};

/// What the control cycle reads about the robot: measured joints and the kinematics at them.
struct RobotState {
  JointVector q;      ///< joint positions [rad or m]
  JointVector dq;     ///< joint velocities [rad/s or m/s]
  Pose pose;          ///< end-effector pose T_base_ee
  Jacobian jacobian;  ///< geometric Jacobian at q, 6 x n, base frame

  // Optional model terms, left empty (size 0) when the caller has no dynamics model; a control
  // loop with a model fills them as its options require.
  JointMatrix mass;     ///< M(q) [kg m^2], for the dynamic options of the law
  JointVector gravity;  ///< g(q) [Nm], added when gravity_compensation is on
  /// C(q, dq)^T dq [Nm], for the collision monitor's momentum observer (collision.detection);
  /// without it (or without mass) the monitor does not run.
  JointVector coriolis_transposed;
  /// The joint torques the robot measures [Nm or N]: on the link side of each drive, gravity
  /// included (Franka's tau_J, KUKA's measured torque). Read by the momentum observer only with
  /// collision.measured_torque, which then needs `gravity` too; empty: not measured.
  JointVector measured_torque;
  /// Torque of a secondary task [Nm] (e.g. joint-limit avoidance), added to the nullspace
  /// torque tau_0 before the projection, so it acts only in the nullspace.
  JointVector secondary_torque;
  /// Joint-space torque added to the command as it is, not projected [Nm]: the joint-limit walls
  /// that hold a joint off its limit while teaching (the control loop fills it; see
  /// joint_limit_avoidance). It joins the damping in the torque shaping.
  JointVector joint_wall_torque;
  /// Per-joint bounds on the drive's torque [Nm], J^T (spring + wrench) + the nullspace torque
  /// (-inf, +inf where a joint is free): the control loop lowers the ceiling of a joint inside
  /// joint_limit_avoidance.margin of its upper limit (the floor of one near its lower limit), so
  /// that what the task asks cannot drive the joint into the limit. What a bound takes joins
  /// joint_wall_torque, under the safety caps; a bound never pushes (below zero it counts as
  /// zero). Empty: no bounds.
  JointVector joint_limit_ceiling;
  JointVector joint_limit_floor;
};

/// Returns a RobotState sized for `num_joints` with every value zero and an identity pose.
inline RobotState make_robot_state(int num_joints) {
  RobotState state;
  state.q = JointVector::Zero(num_joints);
  state.dq = JointVector::Zero(num_joints);
  state.jacobian = Jacobian::Zero(6, num_joints);
  return state;
}

}  // namespace cartesian_impedance
