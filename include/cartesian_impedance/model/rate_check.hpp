#pragma once
/// @file
/// Whether the torque-rate limit can follow the stiffest impedance the parameters allow. A spring
/// of stiffness k on the end effector's mode of mass m oscillates at w = sqrt(k / m); a joint i
/// with lever l_i (|J(axis, i)|: how far the end effector moves along the axis per radian of the
/// joint) must then change its torque at k l_i w per metre (or radian) of oscillation. Its rate
/// limit R_i follows oscillations up to R_i / (k l_i w); a larger one, which a reference step or a
/// push causes, is distorted by the limit into one that the limit feeds (measured: a 10 cm step
/// oscillates for good, on the Panda below about 2 mm, on the iiwa below about 1.5 mm; the
/// warning threshold is kept above both). Not for the control cycle: it builds a workspace.

#include <string>
#include <vector>

#include "cartesian_impedance/core/parameters.hpp"
#include "cartesian_impedance/model/robot_model.hpp"

namespace cartesian_impedance {

/// Below these the rate limit is said not to follow the stiffness [m, rad].
inline constexpr double kFollowedTranslation = 0.003;
inline constexpr double kFollowedRotation = 0.005;

/// Per axis of the base frame: x, y, z, then the rotations about them.
struct RateCheck {
  Vector6d stiffness;  ///< k: limits.stiffness.*.max [N/m, Nm/rad]
  Vector6d mass;       ///< the end effector's mode along the axis [kg, kg m^2], armature included
  Vector6d frequency;  ///< w = sqrt(k / m) [rad/s]
  /// The largest oscillation whose torque every joint's rate limit follows [m, rad]; infinite
  /// where no joint moves the axis.
  Vector6d followed;
  Eigen::Matrix<int, 6, 1> joint;  ///< the joint that bounds it (-1: none)
  Vector6d lever;                  ///< that joint's |J(axis, joint)| [m/rad or rad/rad]
  /// One per group (translation, rotation) whose worst axis is below kFollowed*, with the
  /// arithmetic.
  std::vector<std::string> warnings;
};

/// Checks `parameters` (their stiffness limits, torque-rate limit and armature) for `model` at
/// `q`.
/// @throws Error if q has the wrong size or is not finite, or the model cannot be evaluated at q.
RateCheck check_rate_limit(const RobotModel& model, const JointVector& q,
                           const Parameters& parameters);

}  // namespace cartesian_impedance
