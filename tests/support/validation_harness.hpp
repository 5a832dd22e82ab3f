#pragma once
// The harness of the validation tests: a running 7-joint controller on a made-up robot state,
// exact (bit for bit) comparison of what a command could change, and the project's rule for a
// rejected command (expect_rejected): it throws cartesian_impedance::Error whose message names the
// field, the offending value and the valid range, and changes nothing.

#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <functional>
#include <initializer_list>
#include <limits>
#include <random>
#include <string>
#include <variant>
#include <vector>

#include "cartesian_impedance/core/controller.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/parameters.hpp"

namespace validation_harness {

namespace ci = cartesian_impedance;

inline constexpr int kJoints = 7;
inline constexpr double kDt = 1e-3;
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
inline constexpr double kInf = std::numeric_limits<double>::infinity();

/// A non-finite value and how every message of the library prints it.
struct Poison {
  double value;
  const char* text;
};
inline constexpr std::array<Poison, 3> kPoisons{{{kNaN, "nan"}, {kInf, "inf"}, {-kInf, "-inf"}}};

/// "name = nan": the field and the offending value, as the library prints them.
inline std::string assigned(const std::string& name, const std::string& value) {
  return name + " = " + value;
}

inline ci::JointVector joints(std::initializer_list<double> values) {
  ci::JointVector result(static_cast<Eigen::Index>(values.size()));
  Eigen::Index i = 0;
  for (double value : values) result[i++] = value;
  return result;
}

// ---------------------------------------------------------------------------------------------
// Messages

inline ::testing::AssertionResult contains_all(const std::string& message,
                                               const std::vector<std::string>& parts) {
  for (const std::string& part : parts) {
    if (message.find(part) == std::string::npos) {
      return ::testing::AssertionFailure()
             << "message \"" << message << "\" does not contain \"" << part << "\"";
    }
  }
  return ::testing::AssertionSuccess();
}

/// Succeeds if `call` throws ci::Error; its message is stored in `message`.
template <typename Call>
::testing::AssertionResult throws_error(Call&& call, std::string& message) {
  try {
    call();
  } catch (const ci::Error& error) {
    message = error.what();
    return ::testing::AssertionSuccess();
  } catch (const std::exception& error) {
    return ::testing::AssertionFailure()
           << "threw an exception that is not cartesian_impedance::Error: " << error.what();
  }
  return ::testing::AssertionFailure() << "did not throw";
}

/// Succeeds if `call` throws ci::Error whose message contains every one of `parts`.
template <typename Call>
::testing::AssertionResult rejected_with(Call&& call, const std::vector<std::string>& parts) {
  std::string message;
  ::testing::AssertionResult thrown = throws_error(call, message);
  if (!thrown) return thrown;
  return contains_all(message, parts);
}

// ---------------------------------------------------------------------------------------------
// Exact comparison of parameters, targets and torques

inline bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof(double)) == 0;
}

template <typename A, typename B>
bool same_bits(const Eigen::MatrixBase<A>& a, const Eigen::MatrixBase<B>& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols()) return false;
  for (Eigen::Index col = 0; col < a.cols(); ++col) {
    for (Eigen::Index row = 0; row < a.rows(); ++row) {
      if (!same_bits(a(row, col), b(row, col))) return false;
    }
  }
  return true;
}

inline bool same_value(double* a, double* b) {
  return same_bits(*a, *b);
}
inline bool same_value(Eigen::Vector3d* a, Eigen::Vector3d* b) {
  return same_bits(*a, *b);
}
inline bool same_value(ci::JointVector* a, ci::JointVector* b) {
  return same_bits(*a, *b);
}
inline bool same_value(ci::Frame* a, ci::Frame* b) {
  return *a == *b;
}
inline bool same_value(ci::CollisionReaction* a, ci::CollisionReaction* b) {
  return *a == *b;
}
inline bool same_value(ci::BodyRegion* a, ci::BodyRegion* b) {
  return *a == *b;
}
inline bool same_value(bool* a, bool* b) {
  return *a == *b;
}

/// Name and values of the first table row in which `a` and `b` differ (bit for bit), or "".
/// Independent of the YAML emitter, so it stays meaningful whatever that emits.
inline std::string first_difference(const ci::Parameters& a, const ci::Parameters& b) {
  ci::Parameters left = a;
  ci::Parameters right = b;
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    const ci::ParameterField left_field = info.in(left);
    const ci::ParameterField right_field = info.in(right);
    const bool same = std::visit(
        [&](auto* pointer) {
          using Pointer = decltype(pointer);
          return same_value(pointer, std::get<Pointer>(right_field));
        },
        left_field);
    if (!same) {
      return std::string(info.name) + ": " + ci::value_text(a, info) + " vs " +
             ci::value_text(b, info);
    }
  }
  return "";
}

inline std::string first_difference(const ci::Targets& a, const ci::Targets& b) {
  if (!same_bits(a.pose.position, b.pose.position)) return "pose.position";
  if (!same_bits(a.pose.orientation.coeffs(), b.pose.orientation.coeffs())) {
    return "pose.orientation";
  }
  if (!same_bits(a.stiffness, b.stiffness)) return "stiffness";
  if (!same_bits(a.damping_ratio, b.damping_ratio)) return "damping_ratio";
  if (!same_bits(a.nullspace_q, b.nullspace_q)) return "nullspace_q";
  if (!same_bits(a.nullspace_stiffness, b.nullspace_stiffness)) return "nullspace_stiffness";
  if (!same_bits(a.nullspace_damping_ratio, b.nullspace_damping_ratio)) {
    return "nullspace_damping_ratio";
  }
  if (!same_bits(a.wrench, b.wrench)) return "wrench";
  return "";
}

inline std::string first_difference(const ci::ActiveLimits& a, const ci::ActiveLimits& b) {
  if (a.stiffness_saturated != b.stiffness_saturated) return "stiffness_saturated";
  if (a.damping_ratio_saturated != b.damping_ratio_saturated) return "damping_ratio_saturated";
  if (a.nullspace_stiffness_saturated != b.nullspace_stiffness_saturated) {
    return "nullspace_stiffness_saturated";
  }
  if (a.wrench_saturated != b.wrench_saturated) return "wrench_saturated";
  if (a.translation_error_clipped != b.translation_error_clipped) {
    return "translation_error_clipped";
  }
  if (a.rotation_error_clipped != b.rotation_error_clipped) return "rotation_error_clipped";
  if (a.joint_torque_saturated != b.joint_torque_saturated) return "joint_torque_saturated";
  if (a.torque_rate_limited != b.torque_rate_limited) return "torque_rate_limited";
  return "";
}

/// Everything a command could change, as seen from outside.
struct Snapshot {
  ci::Parameters parameters;
  ci::Targets commanded;
  ci::Targets filtered;
  ci::ActiveLimits limits;
  bool started;
  ci::Status status;
  ci::JointVector tau;
};

inline Snapshot snapshot(const ci::CartesianImpedanceController& controller) {
  const ci::ControllerState& state = controller.state();
  return {controller.parameters(), state.commanded, state.filtered, state.limits,
          controller.started(),    state.status,    state.tau};
}

inline ::testing::AssertionResult unchanged(const Snapshot& before, const Snapshot& after) {
  std::string difference = first_difference(before.parameters, after.parameters);
  if (!difference.empty()) {
    return ::testing::AssertionFailure() << "parameters changed: " << difference;
  }
  difference = first_difference(before.commanded, after.commanded);
  if (!difference.empty()) {
    return ::testing::AssertionFailure() << "commanded target changed: " << difference;
  }
  difference = first_difference(before.filtered, after.filtered);
  if (!difference.empty()) {
    return ::testing::AssertionFailure() << "filtered target changed: " << difference;
  }
  difference = first_difference(before.limits, after.limits);
  if (!difference.empty()) {
    return ::testing::AssertionFailure() << "active limit flag changed: " << difference;
  }
  if (before.started != after.started) return ::testing::AssertionFailure() << "started changed";
  if (before.status != after.status) return ::testing::AssertionFailure() << "status changed";
  if (!same_bits(before.tau, after.tau)) return ::testing::AssertionFailure() << "tau changed";
  return ::testing::AssertionSuccess();
}

/// Runs both controllers for `cycles` cycles on the same input; succeeds if status and torque
/// are identical bit for bit in every cycle.
inline ::testing::AssertionResult same_torque_as_twin(ci::CartesianImpedanceController& controller,
                                                      ci::CartesianImpedanceController& twin,
                                                      const ci::RobotState& robot, int cycles) {
  for (int cycle = 0; cycle < cycles; ++cycle) {
    const ci::Status status = controller.update(robot, kDt);
    const ci::Status twin_status = twin.update(robot, kDt);
    if (status != twin_status) {
      return ::testing::AssertionFailure()
             << "cycle " << cycle << ": status " << ci::to_string(status) << " vs twin "
             << ci::to_string(twin_status);
    }
    if (!same_bits(controller.torque(), twin.torque())) {
      return ::testing::AssertionFailure()
             << "cycle " << cycle << ": torque [" << controller.torque().transpose()
             << "] differs from the twin's [" << twin.torque().transpose() << "]";
    }
  }
  return ::testing::AssertionSuccess();
}

// ---------------------------------------------------------------------------------------------
// A running 7-joint controller on a made-up, constant robot state

/// Parameters with per-joint fields given per joint, and filters fast enough that 30 cycles are
/// mid-transition (so the filtered state matters for the twin comparison).
inline ci::Parameters rig_parameters() {
  ci::Parameters p;
  p.nullspace.stiffness = joints({12, 11, 10, 9, 8, 7, 6});
  p.limits.joint_torque = joints({87, 87, 87, 87, 12, 12, 12});
  p.limits.joint_torque_rate = joints({1000, 950, 900, 850, 800, 750, 700});
  p.filter.pose.time = 0.05;
  p.filter.stiffness.time = 0.04;
  p.filter.nullspace.time = 0.06;
  p.filter.wrench.time = 0.03;
  return p;
}

/// Valid parameters that differ from rig_parameters() (and from the defaults) in every row, so a
/// partly applied set_parameters() would show.
inline ci::Parameters other_valid_parameters() {
  ci::Parameters p;
  p.stiffness.translation = {700, 650, 600};
  p.stiffness.rotation = {70, 65, 60};
  p.stiffness.frame = ci::Frame::end_effector;
  p.damping_ratio.translation = {0.8, 0.9, 1.1};
  p.damping_ratio.rotation = {0.7, 0.75, 0.85};
  p.nullspace.stiffness = joints({20, 19, 18, 17, 16, 15, 14});
  p.nullspace.damping_ratio = 0.9;
  p.nullspace.pseudo_inverse_damping = 0.02;
  p.wrench.force = {1, 2, 3};
  p.wrench.torque = {0.1, 0.2, 0.3};
  p.wrench.frame = ci::Frame::end_effector;
  p.filter.pose = {0.1, 0.9};
  p.filter.stiffness = {0.15, 0.93};
  p.filter.nullspace = {0.12, 0.96};
  p.filter.wrench = {0.08, 0.99};
  p.limits.stiffness.translation = {10, 3000};
  p.limits.stiffness.rotation = {1, 300};
  p.limits.damping_ratio = {0.1, 2};
  p.limits.nullspace_stiffness = {0.5, 100};
  p.limits.wrench = {50, 10};
  p.limits.pose_error = {0.05, 0.3};
  p.limits.joint_torque = joints({80, 81, 82, 83, 11, 11.5, 11.75});
  p.limits.joint_torque_rate = joints({900, 901, 902, 903, 904, 905, 906});
  p.joint_limit_avoidance = {0.15, 35.0};
  p.minimum_damping = {12.0, 1.5, 0.75};
  p.trajectory = {0.02, 0.75};
  p.dynamics.armature = joints({0.3, 0.3, 0.2, 0.2, 0.1, 0.05, 0.05});
  p.plausibility.dt = {2e-5, 0.015};
  p.plausibility.joint_velocity = joints({5, 5, 5, 5, 6, 6, 6});
  p.plausibility.joint_position_margin = 0.3;
  p.safety.max_speed = {0.25, 1.5};
  p.safety.max_force = {40.0, 8.0};
  p.safety.workspace.min = Eigen::Vector3d(-0.8, -0.7, 0.05);
  p.safety.workspace.max = Eigen::Vector3d(0.8, 0.7, 1.1);
  p.safety.workspace.stiffness = 1500.0;
  p.safety.workspace.damping = 80.0;
  p.safety.energy_tank.enabled = false;
  p.safety.energy_tank.capacity = 0.02;
  p.safety.energy_tank.initial = 0.01;
  p.safety.passivity.threshold = 0.25;
  p.safety.passivity.delay = 0.004;
  p.payload.mass = 0.7;
  p.payload.center_of_mass = Eigen::Vector3d(0.0, 0.01, 0.05);
  p.safety.pfl.body_region = ci::BodyRegion::chest;
  p.collision.detection = false;
  p.collision.reaction = ci::CollisionReaction::stop;
  p.collision.observer_gain = 80.0;
  p.collision.threshold = joints({6, 6, 5, 5, 3, 3, 3});
  p.collision.threshold_fraction = 0.25;
  p.collision.velocity_noise = 0.004;
  p.collision.contact_force = 5.0;
  p.collision.contact_torque = 0.5;
  p.collision.retract_distance = 0.04;
  p.collision.measured_torque = true;
  return p;
}

/// Seeded, made-up kinematics: a dense Jacobian, a pose away from identity, moving joints.
inline ci::RobotState rig_robot() {
  ci::RobotState robot = ci::make_robot_state(kJoints);
  std::mt19937 random(20240611);
  std::uniform_real_distribution<double> entry(-0.6, 0.6);
  for (Eigen::Index i = 0; i < robot.jacobian.size(); ++i) robot.jacobian.data()[i] = entry(random);
  for (Eigen::Index i = 0; i < kJoints; ++i) {
    robot.q[i] = 0.1 * static_cast<double>(i + 1) - 0.3;
    robot.dq[i] = (i % 2 == 0 ? 0.03 : -0.02) * static_cast<double>(i + 1);
  }
  robot.pose.position = {0.45, 0.05, 0.55};
  robot.pose.orientation =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()));
  // A symmetric positive definite M(q), for the damping shaped by the task-space inertia.
  ci::JointMatrix root(kJoints, kJoints);
  for (Eigen::Index i = 0; i < root.size(); ++i) root.data()[i] = entry(random);
  robot.mass = root * root.transpose() + 0.5 * ci::JointMatrix::Identity(kJoints, kJoints);
  return robot;
}

struct Rig {
  ci::CartesianImpedanceController controller{kJoints, rig_parameters()};
  ci::RobotState robot = rig_robot();
};

/// A started controller, 30 cycles into moving toward a displaced reference with a wrench, so
/// torques, filtered targets and the rate limiter all carry state.
inline Rig make_running_rig() {
  Rig rig;
  ci::JointVector tau_previous(kJoints);
  for (Eigen::Index i = 0; i < kJoints; ++i) tau_previous[i] = 0.5 * static_cast<double>(i - 3);
  rig.controller.start(rig.robot, tau_previous);
  ci::Pose reference = rig.robot.pose;
  reference.position += Eigen::Vector3d(0.04, -0.03, 0.02);
  reference.orientation =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.15, Eigen::Vector3d::UnitZ())) * reference.orientation;
  rig.controller.set_reference_pose(reference);
  ci::Vector6d wrench;
  wrench << 4, -2, 3, 0.3, 0, -0.2;
  rig.controller.set_wrench(wrench);
  rig.controller.set_nullspace_target(rig.robot.q + ci::JointVector::Constant(kJoints, 0.2));
  ci::Vector6d stiffness;
  stiffness << 600, 500, 400, 40, 50, 60;
  rig.controller.set_stiffness(stiffness);
  for (int cycle = 0; cycle < 30; ++cycle) rig.controller.update(rig.robot, kDt);
  return rig;
}

using Command = std::function<void(ci::CartesianImpedanceController&)>;

/// The project's rule for one bad command: on a running controller it throws ci::Error whose
/// message contains every one of `expected`, changes nothing visible, and the following cycles
/// give the same torque, bit for bit, as a twin controller that never saw the command.
inline void expect_rejected(const std::string& label, const Command& command,
                            const std::vector<std::string>& expected) {
  SCOPED_TRACE(label);
  Rig rig = make_running_rig();
  ci::CartesianImpedanceController twin = rig.controller;
  const Snapshot before = snapshot(rig.controller);
  std::string message;
  ASSERT_TRUE(throws_error([&] { command(rig.controller); }, message));
  EXPECT_TRUE(contains_all(message, expected));
  EXPECT_TRUE(unchanged(before, snapshot(rig.controller)));
  EXPECT_TRUE(same_torque_as_twin(rig.controller, twin, rig.robot, 20));
}

inline ci::Vector6d six(double a, double b, double c, double d, double e, double f) {
  ci::Vector6d v;
  v << a, b, c, d, e, f;
  return v;
}

inline constexpr std::array<const char*, 3> kAxes{{"x", "y", "z"}};

/// Calls `function(element_name, element)` for every number of one table row in `parameters`:
/// "stiffness.translation.y", "limits.joint_torque[3]", "filter.pose.time". Frames have none.
inline void for_each_element(const ci::ParameterInfo& info, ci::Parameters& parameters,
                             const std::function<void(const std::string&, double&)>& function) {
  const ci::ParameterField field = info.in(parameters);
  const std::string name(info.name);
  if (auto* value = std::get_if<double*>(&field)) {
    function(name, **value);
  } else if (auto* vector = std::get_if<Eigen::Vector3d*>(&field)) {
    for (int i = 0; i < 3; ++i) function(name + "." + kAxes[i], (**vector)[i]);
  } else if (auto* values = std::get_if<ci::JointVector*>(&field)) {
    for (Eigen::Index i = 0; i < (*values)->size(); ++i) {
      function(name + "[" + std::to_string(i) + "]", (**values)[i]);
    }
  }
}

}  // namespace validation_harness
