#pragma once
/// @file
/// The checks of the library's inputs, each written once. The checks of what the control cycle
/// reads (a measurement, the robot state the law uses, the time step) return the first Fault
/// they find: noexcept and allocation-free, so the cycle calls them and fails closed, and a
/// boundary (start(), a loader) passes the same fault to raise(), which throws it as an Error
/// carrying the fault. The helpers for commands and parameters throw at once: they are never on
/// the cycle's path. Messages name the field, the value and what was expected.

#include <string>
#include <string_view>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/parameters.hpp"
#include "cartesian_impedance/core/types.hpp"

namespace cartesian_impedance::checks {

/// Largest believable coordinate of a pose in the base frame [m]: beyond it a reference is a
/// typo, and the pose error (clipped anyway) would lose all precision.
inline constexpr double kMaxPosition = 1000.0;
/// Largest believable joint position [rad or m] (a continuous joint may have turned many times).
inline constexpr double kMaxJointPosition = 1000.0;

// ---- the cycle's inputs: return the fault, raise() throws it ---------------------------------

/// `size` == `expected`, else the fault "input has size counted; expected expected".
Fault count(const char* input, Eigen::Index size, Eigen::Index expected,
            const char* counted = "values") noexcept;

/// What a measurement is checked against besides size and finiteness; a null bound is not
/// checked.
struct MeasurementBounds {
  const JointVector* lower = nullptr;  ///< position limits [rad or m] ...
  const JointVector* upper = nullptr;
  double margin = 0.0;                 ///< ... widened by this (plausibility.joint_position_margin)
  const JointVector* speed = nullptr;  ///< |dq| bound per joint (plausibility.joint_velocity)
};

/// q and dq: `num_joints` values each, finite, q within the limits widened by the margin, |dq|
/// within the speed bound. Faults name "q" or "dq" and the joint.
Fault measurement(const Eigen::Ref<const Eigen::VectorXd>& q,
                  const Eigen::Ref<const Eigen::VectorXd>& dq, int num_joints,
                  const MeasurementBounds& bounds = {}) noexcept;
/// The same for the cycle's own vectors (no Ref to bind).
Fault measurement(const JointVector& q, const JointVector& dq, int num_joints,
                  const MeasurementBounds& bounds = {}) noexcept;

/// What the law reads of a RobotState besides q and dq: a 6 x n Jacobian, a finite pose with a
/// unit quaternion (within kQuaternionNormTolerance), and the optional terms (mass, gravity,
/// secondary_torque, measured_torque) either absent or complete and finite.
Fault kinematics(const RobotState& robot, int num_joints) noexcept;

/// measurement() of q and dq against `speed`, then kinematics(): everything the law reads.
Fault robot_state(const RobotState& robot, int num_joints,
                  const JointVector* speed = nullptr) noexcept;

/// A control period: finite and within `plausible` (plausibility.dt).
Fault time_step(double dt, const Range& plausible) noexcept;

/// Throws Error(fault) with the text `context` + to_string(fault) if there is a fault.
void raise(const Fault& fault, std::string_view context = "");

// ---- the boundary's helpers for commands and parameters: throw Error (with its fault) ---------

/// "name[i]".
std::string indexed(std::string_view name, Eigen::Index i);
void finite(std::string_view name, double value, std::string_view unit = "");
void size(std::string_view name, Eigen::Index size, Eigen::Index expected);
/// A per-joint value given once for all joints or once per joint.
void one_or_per_joint(std::string_view name, Eigen::Index size, Eigen::Index num_joints);
/// Every element finite; elements named name[i].
void finite_vector(std::string_view name, const Eigen::Ref<const Eigen::VectorXd>& values,
                   std::string_view unit = "");
/// Every element finite and within [-bound, bound].
void bounded_vector(std::string_view name, const Eigen::Ref<const Eigen::VectorXd>& values,
                    double bound, std::string_view unit = "");
/// Finite, unit norm within kQuaternionNormTolerance; returns it normalised.
Eigen::Quaterniond unit_quaternion(std::string_view name, const Eigen::Quaterniond& q);
/// Position finite and within +-kMaxPosition, unit quaternion; returns the pose with the
/// quaternion normalised.
Pose pose(std::string_view name, const Pose& pose);
/// Each of x, y, z within the table row's range (names "row.x", ...).
void axes(const ParameterInfo& info, const Eigen::Ref<const Eigen::Vector3d>& values);

}  // namespace cartesian_impedance::checks
