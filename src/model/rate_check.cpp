#include "cartesian_impedance/model/rate_check.hpp"

#include <Eigen/Cholesky>
#include <cmath>
#include <cstdio>
#include <limits>

#include "cartesian_impedance/core/checks.hpp"

namespace cartesian_impedance {

RateCheck check_rate_limit(const RobotModel& model, const JointVector& q,
                           const Parameters& parameters) {
  const int n = model.num_joints();
  checks::raise(checks::measurement(q, JointVector::Zero(q.size()), n), "check_rate_limit: ");
  ModelWorkspace workspace(model);
  Kinematics kinematics = workspace.make_kinematics();
  if (!workspace.compute(q, JointVector::Zero(n), kinematics, ModelTerms::mass)) {
    throw Error("check_rate_limit: the robot model cannot be evaluated at q");
  }
  JointMatrix mass = kinematics.mass;
  mass.diagonal() += per_joint(parameters.dynamics.armature, n);
  const Eigen::LLT<JointMatrix> factor(mass);
  if (factor.info() != Eigen::Success) {
    throw Error("check_rate_limit: M(q) + armature is not positive definite at q");
  }
  const Eigen::Matrix<double, Eigen::Dynamic, 6, 0, kMaxJoints, 6> inverse_mass_jt =
      factor.solve(kinematics.jacobian.transpose());
  const Matrix6d inverse_inertia = kinematics.jacobian * inverse_mass_jt;  // J M^-1 J^T
  const JointVector rate = per_joint(parameters.limits.joint_torque_rate, n);

  RateCheck check;
  static constexpr const char* kAxes[6] = {"x", "y", "z", "x", "y", "z"};
  for (int axis = 0; axis < 6; ++axis) {
    const bool translation = axis < 3;
    const double k = translation ? parameters.limits.stiffness.translation.max
                                 : parameters.limits.stiffness.rotation.max;
    check.stiffness[axis] = k;
    check.mass[axis] = 1.0 / inverse_inertia(axis, axis);
    check.frequency[axis] = std::sqrt(k / check.mass[axis]);
    check.followed[axis] = std::numeric_limits<double>::infinity();
    check.joint[axis] = -1;
    check.lever[axis] = 0.0;
    for (int i = 0; i < n; ++i) {
      const double lever = std::abs(kinematics.jacobian(axis, i));
      const double followed = rate[i] / (k * lever * check.frequency[axis]);
      if (lever > 1e-9 && followed < check.followed[axis]) {
        check.followed[axis] = followed;
        check.joint[axis] = i;
        check.lever[axis] = lever;
      }
    }
  }
  // One warning per group (translation, rotation), for the axis the rate follows least.
  for (const int first : {0, 3}) {
    int axis = first;
    for (int a = first + 1; a < first + 3; ++a) {
      if (check.followed[a] < check.followed[axis]) axis = a;
    }
    const bool translation = first == 0;
    const double k = check.stiffness[axis];
    const double threshold = translation ? kFollowedTranslation : kFollowedRotation;
    if (!(check.followed[axis] < threshold) || check.joint[axis] < 0) continue;
    const int i = check.joint[axis];
    const char* unit = translation ? "m" : "rad";
    char text[700];
    std::snprintf(
        text, sizeof(text),
        "limits.stiffness.%s.max = %s %s is more than limits.joint_torque_rate can follow here: "
        "%s %s the end effector's mode (%.3g %s) oscillates at sqrt(k / m) = %.3g rad/s, and "
        "%s (lever %.3g %s/rad) must change its torque at k x lever x w = %.3g Nm/s per %s of "
        "oscillation, so its %s Nm/s follow oscillations up to %.3g m%s only (below %s m%s a "
        "step or a push has oscillated for good); lower limits.stiffness.%s.max or raise "
        "limits.joint_torque_rate",
        translation ? "translation" : "rotation", format_number(k).c_str(),
        translation ? "N/m" : "Nm/rad", translation ? "along" : "about", kAxes[axis],
        check.mass[axis], translation ? "kg" : "kg m^2", check.frequency[axis],
        model.joint_names()[static_cast<std::size_t>(i)].c_str(), check.lever[axis], unit,
        k * check.lever[axis] * check.frequency[axis], unit, format_number(rate[i]).c_str(),
        1e3 * check.followed[axis], translation ? "m" : "rad",
        format_number(1e3 * threshold).c_str(), translation ? "m" : "rad",
        translation ? "translation" : "rotation");
    check.warnings.emplace_back(text);
  }
  return check;
}

}  // namespace cartesian_impedance
