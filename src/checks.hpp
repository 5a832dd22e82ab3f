#pragma once
// Validation helpers shared by the library's boundary code (commands, start, loaders). Each throws
// Error with a message naming the field, the value and what was expected. Not for the cycle.

#include <string>
#include <string_view>

#include "cartesian_impedance/error.hpp"
#include "cartesian_impedance/parameters.hpp"
#include "cartesian_impedance/types.hpp"

namespace cartesian_impedance::checks {

/// Largest believable coordinate of a pose in the base frame [m]: beyond it a reference is a
/// typo, and the pose error (clipped anyway) would lose all precision.
inline constexpr double kMaxPosition = 1000.0;
/// Largest believable joint position [rad or m] (a continuous joint may have turned many times).
inline constexpr double kMaxJointPosition = 1000.0;

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
