#include "cartesian_impedance/model/robot_limits.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>

namespace cartesian_impedance {

namespace {

constexpr int kSamples = 256;
constexpr std::uint32_t kSeed = 29;

// A value read by people ("700 N/m", not "734.2"): rounded down to two significant digits.
double round_down_two_digits(double value) {
  if (!(value > 0.0) || !std::isfinite(value)) return value;
  const double unit = std::pow(10.0, std::floor(std::log10(value)) - 1.0);
  return std::floor(value / unit + 1e-9) * unit;
}

// Uniform in [0, 1) from mt19937's 32 bits, the same on every standard library (unlike
// std::uniform_real_distribution).
double uniform(std::mt19937& generator) {
  return static_cast<double>(generator()) / 4294967296.0;
}

// The URDF's efforts, kDefaultJointTorque where a joint has none.
JointVector urdf_efforts(const RobotModel& model) {
  JointVector effort = model.limits().effort;
  for (Eigen::Index i = 0; i < effort.size(); ++i) {
    if (!std::isfinite(effort[i]) || effort[i] <= 0.0) effort[i] = kDefaultJointTorque;
  }
  return effort;
}

}  // namespace

ArmCapabilities arm_capabilities(const RobotModel& model) {
  const int n = model.num_joints();
  const JointLimits& limits = model.limits();
  ArmCapabilities arm;
  arm.effort = urdf_efforts(model);
  arm.velocity = limits.velocity;
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(arm.velocity[i]) || arm.velocity[i] <= 0.0) {
      arm.velocity[i] = kDefaultJointVelocity;
    }
  }
  arm.lever = JointVector::Zero(n);
  ModelWorkspace workspace(model);
  Kinematics kinematics = workspace.make_kinematics();
  std::mt19937 generator(kSeed);
  JointVector q(n);
  for (int sample = 0; sample < kSamples; ++sample) {
    for (int i = 0; i < n; ++i) {
      double lower = limits.position_lower[i], upper = limits.position_upper[i];
      if (!std::isfinite(lower) || !std::isfinite(upper)) lower = -M_PI, upper = M_PI;
      q[i] = sample == 0 ? std::clamp(0.0, lower, upper)
                         : lower + (upper - lower) * uniform(generator);
    }
    if (!workspace.compute(q, JointVector::Zero(n), kinematics, ModelTerms::none)) continue;
    ++arm.samples;
    arm.reach = std::max(arm.reach, kinematics.pose.position.norm());
    for (int i = 0; i < n; ++i) {
      arm.lever[i] = std::max(arm.lever[i], kinematics.jacobian.col(i).head<3>().norm());
    }
  }
  if (arm.samples == 0) throw Error("arm_capabilities: the robot model cannot be evaluated");
  arm.force = std::numeric_limits<double>::infinity();
  arm.torque = std::numeric_limits<double>::infinity();
  const std::vector<JointType>& types = model.joint_types();
  for (int i = 0; i < n; ++i) {
    if (types[static_cast<std::size_t>(i)] == JointType::prismatic) {
      arm.lever[i] = 1.0;
      arm.force = std::min(arm.force, arm.effort[i]);
      continue;
    }
    arm.torque = std::min(arm.torque, arm.effort[i]);
    // A joint whose axis passes through the flange everywhere (lever 0) resists no force.
    if (arm.lever[i] > 1e-6) arm.force = std::min(arm.force, arm.effort[i] / arm.lever[i]);
  }
  return arm;
}

Parameters default_parameters(const RobotModel& model) {
  const ArmCapabilities arm = arm_capabilities(model);
  Parameters parameters;
  LimitParameters& limits = parameters.limits;
  limits.joint_torque = arm.effort;
  const ParameterInfo& rate = parameter_info("limits.joint_torque_rate");
  limits.joint_torque_rate = (arm.effort / kTorqueRiseTime).cwiseMax(rate.min).cwiseMin(rate.max);
  const ParameterInfo& speed = parameter_info("plausibility.joint_velocity");
  parameters.plausibility.joint_velocity =
      (kPlausibleSpeedFactor * arm.velocity).cwiseMax(speed.min).cwiseMin(speed.max);

  const double translation =
      round_down_two_digits(kEffortShare * arm.force / limits.pose_error.translation);
  const double rotation =
      round_down_two_digits(kEffortShare * arm.torque / limits.pose_error.rotation);
  limits.stiffness.translation.max = std::min(limits.stiffness.translation.max, translation);
  limits.stiffness.rotation.max = std::min(limits.stiffness.rotation.max, rotation);
  parameters.stiffness.translation =
      parameters.stiffness.translation.cwiseMin(limits.stiffness.translation.max);
  parameters.stiffness.rotation =
      parameters.stiffness.rotation.cwiseMin(limits.stiffness.rotation.max);
  limits.wrench.force =
      std::min(limits.wrench.force, round_down_two_digits(kEffortShare * arm.force));
  limits.wrench.torque =
      std::min(limits.wrench.torque, round_down_two_digits(kEffortShare * arm.torque));
  validate(parameters, model.num_joints());
  return parameters;
}

Parameters with_robot_limits(const Parameters& parameters, const RobotModel& model) {
  const int n = model.num_joints();
  const JointVector& effort = model.limits().effort;
  Parameters resolved = parameters;
  JointVector& torque = resolved.limits.joint_torque;
  if (torque.size() == 0) {
    torque = urdf_efforts(model);
    return resolved;
  }
  const JointVector given = per_joint(torque, n);
  for (int i = 0; i < n; ++i) {
    if (std::isfinite(effort[i]) && effort[i] > 0.0 && given[i] > effort[i]) {
      const std::string& joint = model.joint_names()[static_cast<std::size_t>(i)];
      throw Error(Fault{"limits.joint_torque", i, given[i], "is above the URDF's effort limit",
                        effort[i], true, "Nm"},
                  "limits.joint_torque[" + std::to_string(i) + "] = " + format_number(given[i]) +
                      " Nm is above the effort limit of joint '" + joint + "' in the URDF (" +
                      format_number(effort[i]) +
                      " Nm): a configuration may lower the URDF's limits, not raise them");
    }
  }
  return resolved;
}

}  // namespace cartesian_impedance
