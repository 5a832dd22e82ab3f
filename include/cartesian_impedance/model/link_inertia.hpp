#pragma once
/// @file
/// What a URDF link's <inertial> may hold: one decision, taken by the same function for the
/// controller's model (RobotModel) and for both simulation engines, so that all three accept,
/// repair and refuse the same files.
///
/// Refused (an Error naming the link and the value): a mass that is negative, not finite or above
/// 1e6 kg; an inertia entry that is not finite or beyond +-1e6 kg m^2; a tensor with a negative
/// principal moment beyond rounding. These are not rounding in a file but a wrong number, and no
/// repair would say which number was meant.
///
/// Repaired (with a warning naming the link, the moments and the repair): principal moments that
/// break the triangle inequality A + B >= C. No rigid body has them, MuJoCo refuses them, yet
/// published descriptions have them (moments computed from a CAD model's surface, or rounded
/// per entry). The repair is the smallest change of the principal moments onto A + B >= C that
/// keeps their sum (twice the body's polar moment, the integral of |r|^2 dm) and the principal
/// axes. MuJoCo's own `balanceinertia` would set all three to their mean,
/// a far larger change for a small violation.

#include <Eigen/Core>
#include <string>

namespace cartesian_impedance {

/// A link's inertial as the model and the simulation use it.
struct LinkInertia {
  double mass = 0.0;  ///< [kg]
  /// [kg m^2] about the centre of mass, in the axes the URDF gave it in (its inertial frame).
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
  /// Empty if the file's tensor is used as it is; otherwise the warning that says what was
  /// changed (link, moments before and after).
  std::string repair;
};

/// Checks and, where the file only breaks the triangle inequality, repairs the <inertial> of
/// `link` (the URDF's ixx, ixy, ixz, iyy, iyz, izz as the symmetric `inertia`).
/// Moments on the limit (a flat plate) are used as written; a violation within 1e-9 of the sum
/// (rounding in the file) is repaired without a warning, a larger one with it.
/// @throw Error naming the link and the value for what is refused (see the file comment).
LinkInertia physical_link_inertia(const std::string& link, double mass,
                                  const Eigen::Matrix3d& inertia);

}  // namespace cartesian_impedance
