#pragma once
/// @file
/// What an arm's URDF says it can do, and the parameters that follow from it for an arm nobody
/// tuned. The URDF's `<limit effort>` is the torque bound (limits.joint_torque, which a
/// configuration may lower but not raise); the stiffness, wrench and torque-rate limits and the
/// plausible joint speed are derived from the efforts, the velocities and the arm's levers, so
/// that the stiffest spring the limits allow can be delivered by the joints at the largest pose
/// error the law uses. Not for the control cycle: it builds a workspace and samples the arm.

#include <string>
#include <vector>

#include "cartesian_impedance/core/parameters.hpp"
#include "cartesian_impedance/model/robot_model.hpp"

namespace cartesian_impedance {

/// The share of a joint's effort the derived stiffness and wrench limits may take at the largest
/// pose error (limits.pose_error): the rest is left for the damping, the nullspace and the
/// acceleration of the links.
inline constexpr double kEffortShare = 0.5;
/// The derived torque-rate limit lets a joint go from zero to its effort in this time [s].
inline constexpr double kTorqueRiseTime = 0.05;
/// The derived plausible joint speed is this multiple of the URDF's velocity limit: the drives
/// keep to the limit, a push from outside may exceed it for a moment.
inline constexpr double kPlausibleSpeedFactor = 2.0;
/// Where the URDF gives a joint no velocity limit, the plausible speed [rad/s or m/s].
inline constexpr double kDefaultJointVelocity = 10.0;

/// What the arm can do, from its URDF and its kinematics.
struct ArmCapabilities {
  /// Per joint: the URDF's <limit effort> [Nm or N], kDefaultJointTorque where it gives none.
  JointVector effort;
  /// Per joint: the URDF's <limit velocity> [rad/s or m/s], kDefaultJointVelocity where none.
  JointVector velocity;
  /// Per joint: the largest distance from its axis to the flange over the sampled configurations
  /// [m] (1 for a prismatic joint: its force acts at the flange whole).
  JointVector lever;
  /// Largest distance from the base to the flange over the sampled configurations [m].
  double reach = 0.0;
  /// The force every joint can hold at its largest lever: min_i effort_i / lever_i [N].
  double force = 0.0;
  /// The torque every revolute joint can hold: min_i effort_i [Nm] (+inf without one).
  double torque = 0.0;
  /// How many configurations were sampled (seeded, uniform within the position limits).
  int samples = 0;
};

/// Samples `model` (256 configurations, a fixed seed: the result is the same on every run).
ArmCapabilities arm_capabilities(const RobotModel& model);

/// The library's defaults made to suit `model` (each derivation is in the README's "Your own
/// robot"):
/// - limits.joint_torque: the URDF's efforts;
/// - limits.joint_torque_rate: effort / kTorqueRiseTime per joint;
/// - plausibility.joint_velocity: kPlausibleSpeedFactor x the URDF's velocity limits;
/// - limits.stiffness.translation.max: kEffortShare x force / limits.pose_error.translation,
///   limits.stiffness.rotation.max: kEffortShare x torque / limits.pose_error.rotation (each
///   rounded down to two significant digits, never above the library's default);
/// - stiffness.*: the library's default, or the derived maximum where that is lower;
/// - limits.wrench.force and .torque: kEffortShare x force and x torque, never above the
///   library's defaults.
/// A configuration file is read on top of these (load_parameters(path, defaults)).
Parameters default_parameters(const RobotModel& model);

/// `parameters` as the control loop uses them on `model`: limits.joint_torque left empty becomes
/// the URDF's efforts (kDefaultJointTorque for a joint without one).
/// @throws Error if a given limits.joint_torque is above a joint's URDF effort, naming the joint
///         and both values.
Parameters with_robot_limits(const Parameters& parameters, const RobotModel& model);

}  // namespace cartesian_impedance
