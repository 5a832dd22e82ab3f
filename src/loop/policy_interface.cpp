#include "cartesian_impedance/loop/policy_interface.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Geometry>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/math.hpp"

namespace cartesian_impedance {
namespace {

// The unit quaternion of `q` with w >= 0 (one of its two signs), so that an observation does
// not jump between q and -q.
Eigen::Quaterniond positive_w(const Eigen::Quaterniond& q) {
  Eigen::Quaterniond unit = q.normalized();
  if (unit.w() < 0.0) unit.coeffs() = -unit.coeffs();
  return unit;
}

Eigen::Quaterniond from_rotation_vector(const Eigen::Vector3d& rotation_vector) {
  const double angle = rotation_vector.norm();
  if (angle < 1e-12) return Eigen::Quaterniond::Identity();
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, rotation_vector / angle));
}

void require_finite_at_least(double value, double bound, const std::string& field) {
  if (!std::isfinite(value) || value < bound) {
    throw Error("action limits: " + field + " = " + format_number(value) +
                " must be finite and >= " + format_number(bound));
  }
}

void check_range(const Range& range, const std::string& field) {
  require_finite_at_least(range.min, 0.0, field + ".min");
  require_finite_at_least(range.max, 0.0, field + ".max");
  if (range.min > range.max) {
    throw Error("action limits: " + field + " = [" + format_number(range.min) + ", " +
                format_number(range.max) + "] has min > max");
  }
}

}  // namespace

PolicyInterface::PolicyInterface(const RobotModel& model, const Parameters& parameters, bool wrench,
                                 const PolicyActionLimits& limits)
    : limits_(limits),
      wrench_(wrench),
      workspace_(model),
      kinematics_(workspace_.make_kinematics()),
      jacobian_transpose_(model.num_joints(), 6),
      svd_(model.num_joints(), 6, Eigen::ComputeFullU | Eigen::ComputeFullV) {
  require_finite_at_least(limits.max_translation_step, 0.0, "max_translation_step");
  require_finite_at_least(limits.max_rotation_step, 0.0, "max_rotation_step");
  check_range(limits.stiffness_translation, "stiffness_translation");
  check_range(limits.stiffness_rotation, "stiffness_rotation");
  require_finite_at_least(limits.max_force, 0.0, "max_force");
  require_finite_at_least(limits.max_torque, 0.0, "max_torque");
  if (limits.reference_leash) {
    const char* names[] = {"reference_leash[0] (translation)", "reference_leash[1] (rotation)"};
    for (int i = 0; i < 2; ++i) {
      const double value = (*limits.reference_leash)[static_cast<std::size_t>(i)];
      if (!(value > 0.0) || !std::isfinite(value)) {
        throw Error(std::string("action limits: ") + names[i] + " = " + format_number(value) +
                    " must be finite and > 0");
      }
    }
    leash_ = *limits.reference_leash;
  } else {
    leash_ = {parameters.limits.pose_error.translation, parameters.limits.pose_error.rotation};
  }
  const double translation_max =
      std::min(limits.stiffness_translation.max, parameters.limits.stiffness.translation.max);
  const double rotation_max =
      std::min(limits.stiffness_rotation.max, parameters.limits.stiffness.rotation.max);
  stiffness_high_ << Eigen::Vector3d::Constant(translation_max),
      Eigen::Vector3d::Constant(rotation_max);
  stiffness_low_ << Eigen::Vector3d::Constant(limits.stiffness_translation.min),
      Eigen::Vector3d::Constant(limits.stiffness_rotation.min);
  stiffness_low_ = stiffness_low_.cwiseMin(stiffness_high_);
  max_force_ = std::min(limits.max_force, parameters.limits.wrench.force);
  max_torque_ = std::min(limits.max_torque, parameters.limits.wrench.torque);
  commands_.reserve(3);
  svd_.setThreshold(1e-9);  // as documented for observe(); compute() keeps it
}

const char* PolicyInterface::field(int index) noexcept {
  static const char* const names[kWrenchActionSize] = {"translation.x",
                                                       "translation.y",
                                                       "translation.z",
                                                       "rotation.x",
                                                       "rotation.y",
                                                       "rotation.z",
                                                       "stiffness.translation.x",
                                                       "stiffness.translation.y",
                                                       "stiffness.translation.z",
                                                       "stiffness.rotation.x",
                                                       "stiffness.rotation.y",
                                                       "stiffness.rotation.z",
                                                       "force.x",
                                                       "force.y",
                                                       "force.z",
                                                       "torque.x",
                                                       "torque.y",
                                                       "torque.z"};
  return index >= 0 && index < kWrenchActionSize ? names[index] : "?";
}

std::string PolicyInterface::layout() const {
  return std::string(
             "translation [0:3], rotation [3:6], stiffness translation [6:9], rotation "
             "[9:12]") +
         (wrench_ ? ", force [12:15], torque [15:18]" : "");
}

PolicyInterface::Action PolicyInterface::check(
    const Eigen::Ref<const Eigen::VectorXd>& action) const {
  if (action.size() != action_size()) {
    throw Error("action has " + std::to_string(action.size()) + " values, expected " +
                std::to_string(action_size()) + " (" + layout() + ")");
  }
  for (int i = 0; i < action_size(); ++i) {
    if (!std::isfinite(action[i])) {
      throw Error("action[" + std::to_string(i) + "] = " + format_number(action[i]) +
                  " is not finite; expected a value in [-1, 1] (" + field(i) + ")");
    }
  }
  return action.cwiseMax(-1.0).cwiseMin(1.0);
}

Vector6d PolicyInterface::stiffness(const Action& checked) const noexcept {
  return stiffness_low_ + 0.5 * (checked.segment<6>(6).array() + 1.0)
                                    .matrix()
                                    .cwiseProduct(stiffness_high_ - stiffness_low_);
}

Vector6d PolicyInterface::stiffness_action(const Vector6d& stiffness) const noexcept {
  Vector6d action;
  for (int i = 0; i < 6; ++i) {
    const double span = stiffness_high_[i] - stiffness_low_[i];
    action[i] = span > 0.0 ? 2.0 * (stiffness[i] - stiffness_low_[i]) / span - 1.0 : -1.0;
  }
  return action.cwiseMax(-1.0).cwiseMin(1.0);
}

void PolicyInterface::reset(const Pose& measured) noexcept {
  reference_.position = measured.position;
  reference_.orientation = positive_w(measured.orientation);
}

void PolicyInterface::apply(const Action& checked, ControlLoop& loop, const Pose& measured) {
  Eigen::Vector3d position =
      reference_.position + checked.segment<3>(0) * limits_.max_translation_step;
  Eigen::Quaterniond rotation =
      from_rotation_vector(checked.segment<3>(3) * limits_.max_rotation_step) *
      reference_.orientation;
  // The leash: the reference stays within reach of the measured pose.
  const Eigen::Vector3d offset = position - measured.position;
  const double distance = offset.norm();
  if (distance > leash_[0]) position = measured.position + offset * (leash_[0] / distance);
  const Eigen::Quaterniond measured_rotation = measured.orientation.normalized();
  const Eigen::Vector3d turn = orientation_error(rotation, measured_rotation);
  const double angle = turn.norm();
  if (angle > leash_[1]) {
    rotation = from_rotation_vector(turn * (leash_[1] / angle)) * measured_rotation;
  }
  const Pose reference{position, positive_w(rotation)};

  commands_.clear();
  commands_.emplace_back(ReferencePose{reference});
  commands_.emplace_back(Stiffness::diagonal(stiffness(checked), Frame::base));
  if (wrench_) {
    Vector6d wrench;
    wrench << checked.segment<3>(12) * max_force_, checked.segment<3>(15) * max_torque_;
    commands_.emplace_back(Wrench(wrench, Frame::base));
  }
  loop.send_all(commands_);
  reference_ = reference;
}

void PolicyInterface::observe(const LoopState& state, Eigen::Ref<Eigen::VectorXd> out) noexcept {
  const int n = num_joints();
  const ControllerState& controller = state.controller;
  out.segment(0, n) = state.q;
  out.segment(n, n) = state.dq;
  int at = 2 * n;
  out.segment<3>(at) = controller.pose.position;
  out.segment<4>(at + 3) = positive_w(controller.pose.orientation).coeffs();
  at += 7;
  if (workspace_.compute(state.q, state.dq, kinematics_, ModelTerms::none)) {
    out.segment<6>(at) = kinematics_.jacobian * state.dq;
    jacobian_transpose_ = kinematics_.jacobian.transpose();
    svd_.compute(jacobian_transpose_, Eigen::ComputeFullU | Eigen::ComputeFullV);
    out.segment<6>(at + 6) = -svd_.solve(controller.tau_cartesian + controller.tau_wrench);
  } else {
    out.segment<12>(at).setZero();
  }
  at += 12;
  out.segment<3>(at) = reference_.position;
  out.segment<4>(at + 3) = reference_.orientation.coeffs();
  at += 7;
  out.segment<6>(at) = controller.stiffness_base().diagonal();
}

}  // namespace cartesian_impedance
