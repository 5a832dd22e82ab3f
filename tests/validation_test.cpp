// Bad input at every boundary of the library: setters, start(), set_parameters(), the YAML loader
// and the control cycle. The project's rule is checked everywhere: a rejected input raises
// cartesian_impedance::Error whose message names the field, the offending value and the valid
// range, and a rejected command changes nothing (parameters, commanded and filtered targets, and
// the torque of every later cycle, compared bit for bit with a twin that never saw the call).
// In the cycle, bad measurements or a bad dt give a status and a torque that ramps to exactly zero
// within the rate limit. Also: the example parameter files, the YAML round trip, and the
// README parameter table.

#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cartesian_impedance/config.hpp"
#include "cartesian_impedance/controller.hpp"
#include "cartesian_impedance/error.hpp"
#include "cartesian_impedance/parameters.hpp"

namespace ci = cartesian_impedance;

namespace {

constexpr int kJoints = 7;
constexpr double kDt = 1e-3;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

/// A non-finite value and how every message of the library prints it.
struct Poison {
  double value;
  const char* text;
};
constexpr std::array<Poison, 3> kPoisons{{{kNaN, "nan"}, {kInf, "inf"}, {-kInf, "-inf"}}};

/// "name = nan": the field and the offending value, as the library prints them.
std::string assigned(const std::string& name, const std::string& value) {
  return name + " = " + value;
}

ci::JointVector joints(std::initializer_list<double> values) {
  ci::JointVector result(static_cast<Eigen::Index>(values.size()));
  Eigen::Index i = 0;
  for (double value : values) result[i++] = value;
  return result;
}

// ---------------------------------------------------------------------------------------------
// Messages

::testing::AssertionResult contains_all(const std::string& message,
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

bool same_bits(double a, double b) {
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

bool same_value(double* a, double* b) {
  return same_bits(*a, *b);
}
bool same_value(Eigen::Vector3d* a, Eigen::Vector3d* b) {
  return same_bits(*a, *b);
}
bool same_value(ci::JointVector* a, ci::JointVector* b) {
  return same_bits(*a, *b);
}
bool same_value(ci::Frame* a, ci::Frame* b) {
  return *a == *b;
}
bool same_value(bool* a, bool* b) {
  return *a == *b;
}

/// Name and values of the first table row in which `a` and `b` differ (bit for bit), or "".
/// Independent of the YAML emitter, so it stays meaningful whatever that emits.
std::string first_difference(const ci::Parameters& a, const ci::Parameters& b) {
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

std::string first_difference(const ci::Targets& a, const ci::Targets& b) {
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

std::string first_difference(const ci::ActiveLimits& a, const ci::ActiveLimits& b) {
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

Snapshot snapshot(const ci::CartesianImpedanceController& controller) {
  const ci::ControllerState& state = controller.state();
  return {controller.parameters(), state.commanded, state.filtered, state.limits,
          controller.started(),    state.status,    state.tau};
}

::testing::AssertionResult unchanged(const Snapshot& before, const Snapshot& after) {
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
::testing::AssertionResult same_torque_as_twin(ci::CartesianImpedanceController& controller,
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
ci::Parameters rig_parameters() {
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
ci::Parameters other_valid_parameters() {
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
  return p;
}

/// Seeded, made-up kinematics: a dense Jacobian, a pose away from identity, moving joints.
ci::RobotState rig_robot() {
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
Rig make_running_rig() {
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
void expect_rejected(const std::string& label, const Command& command,
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

ci::Vector6d six(double a, double b, double c, double d, double e, double f) {
  ci::Vector6d v;
  v << a, b, c, d, e, f;
  return v;
}

constexpr std::array<const char*, 3> kAxes{{"x", "y", "z"}};

/// Calls `function(element_name, element)` for every number of one table row in `parameters`:
/// "stiffness.translation.y", "limits.joint_torque[3]", "filter.pose.time". Frames have none.
void for_each_element(const ci::ParameterInfo& info, ci::Parameters& parameters,
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

// ---------------------------------------------------------------------------------------------
// The harness itself can fail

TEST(ValidationHarness, DetectsWhatAnAcceptedCommandChanges) {
  Rig rig = make_running_rig();
  ci::CartesianImpedanceController twin = rig.controller;
  const Snapshot before = snapshot(rig.controller);
  rig.controller.set_stiffness(six(800, 800, 800, 80, 80, 80));
  EXPECT_FALSE(unchanged(before, snapshot(rig.controller)));
  EXPECT_FALSE(same_torque_as_twin(rig.controller, twin, rig.robot, 20));

  EXPECT_FALSE(contains_all("a = 1 is outside [0, 2]", {"a = 1", "(0, 2]"}));
  std::string message;
  EXPECT_FALSE(throws_error([] {}, message));
  EXPECT_FALSE(throws_error([] { throw std::runtime_error("not ours"); }, message));

  ci::Parameters p;
  p.limits.joint_torque_rate[0] = 999;
  EXPECT_EQ(first_difference(p, ci::Parameters{}), "limits.joint_torque_rate: 999 vs 1000");
}

// ---------------------------------------------------------------------------------------------
// Constructor

TEST(ConstructorValidation, RejectsJointCountOutsideRange) {
  for (int n : {0, -1, ci::kMaxJoints + 1}) {
    SCOPED_TRACE(n);
    EXPECT_TRUE(rejected_with([&] { ci::CartesianImpedanceController controller(n); },
                              {assigned("num_joints", std::to_string(n)),
                               "[1, " + std::to_string(ci::kMaxJoints) + "]"}));
  }
  EXPECT_NO_THROW(ci::CartesianImpedanceController(1));
  EXPECT_NO_THROW(ci::CartesianImpedanceController(ci::kMaxJoints));
}

TEST(ConstructorValidation, RejectsInvalidParametersNamingTheField) {
  ci::Parameters p = rig_parameters();
  p.damping_ratio.rotation.z() = -0.5;
  EXPECT_TRUE(rejected_with([&] { ci::CartesianImpedanceController controller(kJoints, p); },
                            {assigned("damping_ratio.rotation.z", "-0.5"), "[0, 10]"}));

  p = rig_parameters();
  p.limits.joint_torque = joints({87, 87, 87, 87, 12, 12});
  EXPECT_TRUE(rejected_with([&] { ci::CartesianImpedanceController controller(kJoints, p); },
                            {"limits.joint_torque", "6 values", "7"}));
}

// ---------------------------------------------------------------------------------------------
// Setters

TEST(SetterValidation, ReferencePoseRejectsNonFinitePosition) {
  const Rig rig;
  for (int i = 0; i < 3; ++i) {
    for (const Poison& poison : kPoisons) {
      ci::Pose pose{rig.robot.pose.position + Eigen::Vector3d(0.1, 0.1, 0.1),
                    rig.robot.pose.orientation};
      pose.position[i] = poison.value;
      const std::string name = std::string("reference_pose.position.") + kAxes[i];
      expect_rejected(name + " = " + poison.text, [&](auto& c) { c.set_reference_pose(pose); },
                      {assigned(name, poison.text), "not finite"});
    }
  }
}

TEST(SetterValidation, ReferencePoseRejectsNonFiniteQuaternion) {
  constexpr std::array<const char*, 4> kComponents{{"x", "y", "z", "w"}};
  for (int i = 0; i < 4; ++i) {
    for (const Poison& poison : kPoisons) {
      ci::Pose pose;
      pose.position = {0.3, 0.2, 0.4};
      pose.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()));
      pose.orientation.coeffs()[i] = poison.value;  // coeffs() is (x, y, z, w)
      const std::string name = std::string("reference_pose.orientation.") + kComponents[i];
      expect_rejected(name + " = " + poison.text, [&](auto& c) { c.set_reference_pose(pose); },
                      {assigned(name, poison.text), "not finite"});
    }
  }
}

TEST(SetterValidation, ReferencePoseRejectsZeroAndUnnormalisedQuaternions) {
  const Eigen::Quaterniond unit(Eigen::AngleAxisd(0.3, Eigen::Vector3d(0, 1, 1).normalized()));
  for (double norm : {0.0, 0.5, 2.0, 1.01, 0.99}) {
    ci::Pose pose;
    pose.position = {0.3, 0.2, 0.4};
    pose.orientation.coeffs() = norm * unit.coeffs();
    expect_rejected(
        "norm " + ci::format_number(norm), [&](auto& c) { c.set_reference_pose(pose); },
        {"reference_pose.orientation", "norm " + ci::format_number(norm), "unit quaternion"});
  }
}

TEST(SetterValidation, ReferencePoseAcceptsNearlyUnitQuaternionAndNormalisesIt) {
  const Eigen::Quaterniond unit(Eigen::AngleAxisd(0.3, Eigen::Vector3d(0, 1, 1).normalized()));
  for (double norm : {1.0 + 1e-4, 1.0 - 1e-4}) {
    SCOPED_TRACE(norm);
    Rig rig = make_running_rig();
    ci::Pose pose;
    pose.position = {0.3, 0.2, 0.4};
    pose.orientation.coeffs() = norm * unit.coeffs();
    ASSERT_NO_THROW(rig.controller.set_reference_pose(pose));
    const ci::Pose& commanded = rig.controller.state().commanded.pose;
    EXPECT_NEAR(commanded.orientation.norm(), 1.0, 1e-15);
    EXPECT_TRUE(commanded.orientation.coeffs().isApprox(unit.coeffs(), 1e-14));
    EXPECT_TRUE(same_bits(commanded.position, pose.position));
    EXPECT_EQ(rig.controller.update(rig.robot, kDt), ci::Status::ok);
    EXPECT_TRUE(rig.controller.torque().allFinite());
  }
}

TEST(SetterValidation, StiffnessRejectsNonFiniteDiagonal) {
  const char* groups[2] = {"stiffness.translation.", "stiffness.rotation."};
  for (int i = 0; i < 6; ++i) {
    for (const Poison& poison : kPoisons) {
      ci::Vector6d diagonal = six(800, 750, 700, 80, 75, 70);
      diagonal[i] = poison.value;
      const std::string name = std::string(groups[i / 3]) + kAxes[i % 3];
      expect_rejected(name + " = " + poison.text, [&](auto& c) { c.set_stiffness(diagonal); },
                      {assigned(name, poison.text), i < 3 ? "[0, 100000]" : "[0, 10000]"});
    }
  }
}

TEST(SetterValidation, StiffnessRejectsNegativeDiagonal) {
  expect_rejected(
      "translation.x = -5",
      [](auto& c) { c.set_stiffness(six(-5, 750, 700, 80, 75, 70), ci::Frame::end_effector); },
      {assigned("stiffness.translation.x", "-5 N/m"), "is outside [0, 100000]"});
  expect_rejected("rotation.z = -0.25",
                  [](auto& c) { c.set_stiffness(six(800, 750, 700, 80, 75, -0.25)); },
                  {assigned("stiffness.rotation.z", "-0.25 Nm/rad"), "is outside [0, 10000]"});
}

/// A valid full stiffness, different from anything the rig commands: symmetric, with coupling.
ci::Matrix6d coupled_stiffness() {
  ci::Matrix6d k = six(900, 800, 700, 90, 80, 70).asDiagonal();
  k(0, 1) = k(1, 0) = 100;
  k(2, 4) = k(4, 2) = 5;
  return k;
}

TEST(SetterValidation, StiffnessMatrixRejectsNonFiniteElements) {
  for (int row = 0; row < 6; ++row) {
    for (int col = 0; col < 6; ++col) {
      for (const Poison& poison : kPoisons) {
        ci::Matrix6d k = coupled_stiffness();
        k(row, col) = poison.value;
        const std::string name =
            "stiffness(" + std::to_string(row) + ", " + std::to_string(col) + ")";
        expect_rejected(name + " = " + poison.text, [&](auto& c) { c.set_stiffness_matrix(k); },
                        {assigned(name, poison.text)});
      }
    }
  }
}

TEST(SetterValidation, StiffnessMatrixRejectsNonSymmetric) {
  ci::Matrix6d k = coupled_stiffness();
  k(1, 3) = 10;  // k(3, 1) stays 0
  expect_rejected(
      "k(1, 3) != k(3, 1)", [&](auto& c) { c.set_stiffness_matrix(k, ci::Frame::end_effector); },
      {"not symmetric", assigned("stiffness(1, 3)", "10"), assigned("stiffness(3, 1)", "0")});
}

TEST(SetterValidation, StiffnessMatrixRejectsIndefinite) {
  // Symmetric, but the coupled x-y block [[100, 200], [200, 100]] has eigenvalue -100.
  ci::Matrix6d k = six(100, 100, 700, 90, 80, 70).asDiagonal();
  k(0, 1) = k(1, 0) = 200;
  expect_rejected("eigenvalue -100", [&](auto& c) { c.set_stiffness_matrix(k); },
                  {"stiffness", "positive semi-definite", "-100"});

  ci::Matrix6d negative_diagonal = coupled_stiffness();
  negative_diagonal(5, 5) = -5;
  expect_rejected("negative diagonal", [&](auto& c) { c.set_stiffness_matrix(negative_diagonal); },
                  {"positive semi-definite", "-5"});
}

TEST(SetterValidation, StiffnessMatrixAcceptsSymmetricPsdWithZeroEigenvalue) {
  // x-y block [[400, 200], [200, 100]] has eigenvalues 500 and exactly 0.
  ci::Matrix6d k = six(400, 100, 700, 90, 80, 70).asDiagonal();
  k(0, 1) = k(1, 0) = 200;
  ASSERT_DOUBLE_EQ(k(0, 0) * k(1, 1) - k(0, 1) * k(1, 0), 0.0);
  Rig rig = make_running_rig();
  ASSERT_NO_THROW(rig.controller.set_stiffness_matrix(k));
  EXPECT_TRUE(rig.controller.state().commanded.stiffness.isApprox(k, 1e-12));
  for (int cycle = 0; cycle < 50; ++cycle) {
    ASSERT_EQ(rig.controller.update(rig.robot, kDt), ci::Status::ok);
    ASSERT_TRUE(rig.controller.torque().allFinite());
  }
}

TEST(SetterValidation, DampingRatioRejectsNonFiniteAndNegative) {
  const char* groups[2] = {"damping_ratio.translation.", "damping_ratio.rotation."};
  for (int i = 0; i < 6; ++i) {
    const std::string name = std::string(groups[i / 3]) + kAxes[i % 3];
    for (const Poison& poison : kPoisons) {
      ci::Vector6d ratio = six(0.8, 0.9, 1.1, 0.7, 0.75, 0.85);
      ratio[i] = poison.value;
      expect_rejected(name + " = " + poison.text, [&](auto& c) { c.set_damping_ratio(ratio); },
                      {assigned(name, poison.text), "[0, 10]"});
    }
    ci::Vector6d ratio = six(0.8, 0.9, 1.1, 0.7, 0.75, 0.85);
    ratio[i] = -0.1;
    expect_rejected(name + " = -0.1", [&](auto& c) { c.set_damping_ratio(ratio); },
                    {assigned(name, "-0.1"), "is outside [0, 10]"});
  }
}

TEST(SetterValidation, NullspaceTargetRejectsNonFinite) {
  for (Eigen::Index i = 0; i < kJoints; ++i) {
    for (const Poison& poison : kPoisons) {
      Eigen::VectorXd target = Eigen::VectorXd::LinSpaced(kJoints, -0.5, 0.7);
      target[i] = poison.value;
      const std::string name = "nullspace_target[" + std::to_string(i) + "]";
      expect_rejected(name + " = " + poison.text, [&](auto& c) { c.set_nullspace_target(target); },
                      {assigned(name, poison.text), "not finite"});
    }
  }
}

TEST(SetterValidation, NullspaceTargetRejectsWrongSize) {
  for (int size : {kJoints - 1, kJoints + 1, 0}) {
    const Eigen::VectorXd target = Eigen::VectorXd::LinSpaced(size, -0.5, 0.7);
    expect_rejected("size " + std::to_string(size),
                    [&](auto& c) { c.set_nullspace_target(target); },
                    {"nullspace_target", std::to_string(size) + " values", "expected 7"});
  }
}

TEST(SetterValidation, NullspaceStiffnessRejectsNonFiniteNegativeAndWrongSize) {
  for (Eigen::Index i = 0; i < kJoints; ++i) {
    for (const Poison& poison : kPoisons) {
      Eigen::VectorXd stiffness = Eigen::VectorXd::LinSpaced(kJoints, 20, 14);
      stiffness[i] = poison.value;
      const std::string name = "nullspace.stiffness[" + std::to_string(i) + "]";
      expect_rejected(name + " = " + poison.text,
                      [&](auto& c) { c.set_nullspace_stiffness(stiffness); },
                      {assigned(name, poison.text), "[0, 10000]"});
    }
  }
  const Eigen::VectorXd one_negative = Eigen::VectorXd::Constant(1, -2.0);
  expect_rejected("one value, negative", [&](auto& c) { c.set_nullspace_stiffness(one_negative); },
                  {assigned("nullspace.stiffness[0]", "-2 Nm/rad"), "is outside [0, 10000]"});
  for (int size : {2, kJoints - 1, kJoints + 1, 0}) {
    const Eigen::VectorXd stiffness = Eigen::VectorXd::Constant(size, 20.0);
    expect_rejected("size " + std::to_string(size),
                    [&](auto& c) { c.set_nullspace_stiffness(stiffness); },
                    {"nullspace.stiffness", std::to_string(size) + " values", "expected 1", "7"});
  }
  Rig rig = make_running_rig();
  EXPECT_NO_THROW(rig.controller.set_nullspace_stiffness(Eigen::VectorXd::Constant(1, 25.0)));
  EXPECT_TRUE(same_bits(rig.controller.state().commanded.nullspace_stiffness,
                        ci::JointVector::Constant(kJoints, 25.0)));
  EXPECT_NO_THROW(rig.controller.set_nullspace_stiffness(Eigen::VectorXd::Constant(kJoints, 5)));
}

TEST(SetterValidation, NullspaceDampingRatioRejectsNonFiniteAndNegative) {
  for (const Poison& poison : kPoisons) {
    expect_rejected(poison.text, [&](auto& c) { c.set_nullspace_damping_ratio(poison.value); },
                    {assigned("nullspace.damping_ratio", poison.text), "[0, 10]"});
  }
  expect_rejected("-1", [](auto& c) { c.set_nullspace_damping_ratio(-1); },
                  {assigned("nullspace.damping_ratio", "-1"), "is outside [0, 10]"});
}

TEST(SetterValidation, WrenchRejectsNonFinite) {
  const char* groups[2] = {"wrench.force.", "wrench.torque."};
  for (int i = 0; i < 6; ++i) {
    for (const Poison& poison : kPoisons) {
      ci::Vector6d wrench = six(-3, 5, 7, 0.5, -0.4, 0.3);
      wrench[i] = poison.value;
      const std::string name = std::string(groups[i / 3]) + kAxes[i % 3];
      expect_rejected(name + " = " + poison.text,
                      [&](auto& c) { c.set_wrench(wrench, ci::Frame::end_effector); },
                      {assigned(name, poison.text), "not finite"});
    }
  }
}

// ---------------------------------------------------------------------------------------------
// start()

TEST(StartValidation, RejectsNonFiniteMeasuredState) {
  const ci::RobotState good = rig_robot();
  for (const Poison& poison : kPoisons) {
    for (Eigen::Index i = 0; i < kJoints; ++i) {
      const std::string index = "[" + std::to_string(i) + "]";
      ci::RobotState robot = good;
      robot.q[i] = poison.value;
      expect_rejected("q" + index, [&](auto& c) { c.start(robot); },
                      {assigned("robot.q" + index, poison.text), "not finite"});
      robot = good;
      robot.dq[i] = poison.value;
      expect_rejected("dq" + index, [&](auto& c) { c.start(robot); },
                      {assigned("robot.dq" + index, poison.text), "not finite"});
      Eigen::VectorXd tau_previous = Eigen::VectorXd::Constant(kJoints, 1.5);
      tau_previous[i] = poison.value;
      expect_rejected("tau_previous" + index, [&](auto& c) { c.start(good, tau_previous); },
                      {assigned("tau_previous" + index, poison.text), "not finite"});
    }
    for (Eigen::Index i = 0; i < good.jacobian.size(); ++i) {
      ci::RobotState robot = good;
      robot.jacobian.data()[i] = poison.value;
      expect_rejected("jacobian element " + std::to_string(i), [&](auto& c) { c.start(robot); },
                      {"robot.jacobian", std::string("= ") + poison.text, "not finite"});
    }
    for (int i = 0; i < 3; ++i) {
      ci::RobotState robot = good;
      robot.pose.position[i] = poison.value;
      const std::string name = std::string("robot.pose.position.") + kAxes[i];
      expect_rejected(name, [&](auto& c) { c.start(robot); },
                      {assigned(name, poison.text), "not finite"});
    }
    constexpr std::array<const char*, 4> kComponents{{"x", "y", "z", "w"}};
    for (int i = 0; i < 4; ++i) {
      ci::RobotState robot = good;
      robot.pose.orientation.coeffs()[i] = poison.value;
      const std::string name = std::string("robot.pose.orientation.") + kComponents[i];
      expect_rejected(name, [&](auto& c) { c.start(robot); },
                      {assigned(name, poison.text), "not finite"});
    }
  }
}

TEST(StartValidation, RejectsWronglySizedOrUnnormalisedState) {
  const ci::RobotState good = rig_robot();
  for (int size : {kJoints - 1, kJoints + 1}) {
    const std::string values = std::to_string(size) + " values";
    ci::RobotState robot = good;
    robot.q = ci::JointVector::Zero(size);
    expect_rejected("q of " + values, [&](auto& c) { c.start(robot); },
                    {"robot.q", values, "expected 7"});
    robot = good;
    robot.dq = ci::JointVector::Zero(size);
    expect_rejected("dq of " + values, [&](auto& c) { c.start(robot); },
                    {"robot.dq", values, "expected 7"});
    robot = good;
    robot.jacobian = ci::Jacobian::Ones(6, size);
    expect_rejected("jacobian of " + values, [&](auto& c) { c.start(robot); },
                    {"robot.jacobian", values, "expected 7"});
    const Eigen::VectorXd tau_previous = Eigen::VectorXd::Zero(size);
    expect_rejected("tau_previous of " + values, [&](auto& c) { c.start(good, tau_previous); },
                    {"tau_previous", values, "expected 7"});
  }
  for (double norm : {0.0, 0.5, 2.0}) {
    ci::RobotState robot = good;
    robot.pose.orientation.coeffs() *= norm;
    expect_rejected("orientation norm " + ci::format_number(norm), [&](auto& c) { c.start(robot); },
                    {"robot.pose.orientation", "norm " + ci::format_number(norm)});
  }
}

TEST(StartValidation, FailedFirstStartLeavesTheControllerStopped) {
  ci::CartesianImpedanceController controller(kJoints, rig_parameters());
  ci::RobotState robot = rig_robot();
  robot.dq[2] = kNaN;
  const Snapshot before = snapshot(controller);
  EXPECT_TRUE(rejected_with([&] { controller.start(robot); }, {"robot.dq[2]"}));
  EXPECT_TRUE(unchanged(before, snapshot(controller)));
  EXPECT_FALSE(controller.started());
  EXPECT_EQ(controller.update(rig_robot(), kDt), ci::Status::not_started);
  EXPECT_TRUE(same_bits(controller.torque(), ci::JointVector::Zero(kJoints)));
}

// ---------------------------------------------------------------------------------------------
// set_parameters(): every row of the table

TEST(ParameterValidation, EveryTableRowRejectsNanAndInfinityInEveryElement) {
  int elements_checked = 0;
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    ci::Parameters template_parameters = other_valid_parameters();
    for_each_element(info, template_parameters, [&](const std::string& element, double&) {
      ++elements_checked;
      for (const Poison& poison : kPoisons) {
        ci::Parameters bad = other_valid_parameters();
        // Poison the same element in the copy (the table hands out the field of `bad`).
        for_each_element(info, bad, [&](const std::string& name, double& value) {
          if (name == element) value = poison.value;
        });
        const std::vector<std::string> expected{assigned(element, poison.text), info.range_text()};
        expect_rejected(
            element + " = " + poison.text, [&](auto& c) { c.set_parameters(bad); }, expected);
        EXPECT_TRUE(rejected_with([&] { ci::validate(bad, kJoints); }, expected)) << element;
        EXPECT_TRUE(rejected_with([&] { ci::validate(bad); }, expected)) << element;
        EXPECT_TRUE(rejected_with(
            [&] { ci::CartesianImpedanceController controller(kJoints, bad); }, expected))
            << element;
      }
    });
  }
  // 6 three-axis rows, 5 per-joint rows of 7, 32 single numbers.
  EXPECT_EQ(elements_checked, 6 * 3 + 5 * 7 + 32);
}

TEST(ParameterValidation, EveryTableRowRejectsValuesOutsideItsRange) {
  int elements_checked = 0;
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    std::vector<double> outside;
    if (std::isfinite(info.min)) outside.push_back(info.min_exclusive ? info.min : info.min - 1);
    if (std::isfinite(info.max)) outside.push_back(info.max + 0.5);
    ci::Parameters names = other_valid_parameters();
    for_each_element(info, names, [&](const std::string& element, double&) {
      for (double value : outside) {
        ++elements_checked;
        ci::Parameters bad = other_valid_parameters();
        for_each_element(info, bad, [&](const std::string& name, double& target) {
          if (name == element) target = value;
        });
        expect_rejected(
            element + " = " + ci::format_number(value), [&](auto& c) { c.set_parameters(bad); },
            {assigned(element, ci::format_number(value)), "is outside " + info.range_text()});
      }
    });
  }
  EXPECT_GT(elements_checked, 40);
}

TEST(ParameterValidation, RejectsOutOfRangeValuesNamingFieldValueAndRange) {
  struct Case {
    const char* label;
    std::function<void(ci::Parameters&)> change;
    std::vector<std::string> expected;
  };
  const std::vector<Case> cases{
      {"negative stiffness",
       [](auto& p) { p.stiffness.translation.y() = -5; },
       {"stiffness.translation.y = -5 N/m is outside [0, 100000]"}},
      {"negative damping ratio",
       [](auto& p) { p.damping_ratio.rotation.x() = -0.1; },
       {"damping_ratio.rotation.x = -0.1 is outside [0, 10]"}},
      {"negative nullspace stiffness",
       [](auto& p) { p.nullspace.stiffness[3] = -2; },
       {"nullspace.stiffness[3] = -2 Nm/rad is outside [0, 10000]"}},
      {"negative nullspace damping",
       [](auto& p) { p.nullspace.damping_ratio = -1; },
       {"nullspace.damping_ratio = -1 is outside [0, 10]"}},
      {"negative lambda",
       [](auto& p) { p.nullspace.pseudo_inverse_damping = -0.01; },
       {"nullspace.pseudo_inverse_damping = -0.01 is outside [0, 1]"}},
      {"filter fraction 0",
       [](auto& p) { p.filter.pose.fraction = 0; },
       {"filter.pose.fraction = 0 is outside [0.5, 1]"}},
      {"filter fraction 1.5",
       [](auto& p) { p.filter.wrench.fraction = 1.5; },
       {"filter.wrench.fraction = 1.5 is outside [0.5, 1]"}},
      {"negative filter time",
       [](auto& p) { p.filter.stiffness.time = -0.1; },
       {"filter.stiffness.time = -0.1 s is outside [0, 30]"}},
      {"pose error limit 0",
       [](auto& p) { p.limits.pose_error.translation = 0; },
       {"limits.pose_error.translation = 0 m is outside [0.01, 10]"}},
      {"negative rotation error limit",
       [](auto& p) { p.limits.pose_error.rotation = -1; },
       {"limits.pose_error.rotation = -1 rad is outside [0.01, 3.141592654]"}},
      {"zero torque limit",
       [](auto& p) { p.limits.joint_torque[6] = 0; },
       {"limits.joint_torque[6] = 0 Nm is outside [0.1, 10000]"}},
      {"zero torque rate",
       [](auto& p) { p.limits.joint_torque_rate = joints({0}); },
       {"limits.joint_torque_rate[0] = 0 Nm/s is outside [1, 1000000]"}},
      {"negative force limit",
       [](auto& p) { p.limits.wrench.force = -1; },
       {"limits.wrench.force = -1 N is outside [0, 10000]"}},
      {"negative stiffness limit",
       [](auto& p) { p.limits.stiffness.rotation.max = -1; },
       {"limits.stiffness.rotation.max = -1 Nm/rad is outside [0, 10000]"}},
  };
  for (const Case& c : cases) {
    ci::Parameters bad = other_valid_parameters();
    c.change(bad);
    expect_rejected(
        c.label, [&](auto& controller) { controller.set_parameters(bad); }, c.expected);
  }
}

TEST(ParameterValidation, RejectsLimitsWithMinGreaterThanMax) {
  struct Case {
    const char* name;
    std::function<ci::Range&(ci::Parameters&)> range;
    const char* unit;
  };
  const std::vector<Case> cases{
      {"limits.stiffness.translation",
       [](ci::Parameters& p) -> ci::Range& { return p.limits.stiffness.translation; }, " N/m"},
      {"limits.stiffness.rotation",
       [](ci::Parameters& p) -> ci::Range& { return p.limits.stiffness.rotation; }, " Nm/rad"},
      {"limits.damping_ratio",
       [](ci::Parameters& p) -> ci::Range& { return p.limits.damping_ratio; }, ""},
      {"limits.nullspace_stiffness",
       [](ci::Parameters& p) -> ci::Range& { return p.limits.nullspace_stiffness; }, " Nm/rad"},
  };
  for (const Case& c : cases) {
    ci::Parameters bad = other_valid_parameters();
    c.range(bad) = {6, 5};
    const std::string name(c.name);
    expect_rejected(name, [&](auto& controller) { controller.set_parameters(bad); },
                    {assigned(name + ".min", "6" + std::string(c.unit)),
                     assigned(name + ".max", "5" + std::string(c.unit)), "greater than"});
    ci::Parameters equal = other_valid_parameters();
    c.range(equal) = {5, 5};
    Rig rig = make_running_rig();
    EXPECT_NO_THROW(rig.controller.set_parameters(equal)) << name;
  }
}

TEST(ParameterValidation, RejectsPerJointFieldsWithWrongCount) {
  const std::vector<std::pair<const char*, ci::JointVector ci::LimitParameters::*>> limits{
      {"limits.joint_torque", &ci::LimitParameters::joint_torque},
      {"limits.joint_torque_rate", &ci::LimitParameters::joint_torque_rate}};
  for (int size : {2, kJoints - 1, kJoints + 1}) {
    const std::string values = std::to_string(size) + " values";
    ci::Parameters bad = other_valid_parameters();
    bad.nullspace.stiffness = ci::JointVector::Constant(size, 10);
    expect_rejected("nullspace.stiffness, " + values, [&](auto& c) { c.set_parameters(bad); },
                    {"nullspace.stiffness has " + values, "expected 1 (all joints) or 7"});
    for (const auto& [name, member] : limits) {
      ci::Parameters bad_limit = other_valid_parameters();
      bad_limit.limits.*member = ci::JointVector::Constant(size, 50);
      expect_rejected(std::string(name) + ", " + values,
                      [&](auto& c) { c.set_parameters(bad_limit); },
                      {std::string(name) + " has " + values, "expected 1 (all joints) or 7"});
    }
  }
  ci::Parameters empty = other_valid_parameters();
  empty.limits.joint_torque = ci::JointVector(0);
  expect_rejected("limits.joint_torque, 0 values", [&](auto& c) { c.set_parameters(empty); },
                  {"limits.joint_torque has 0 values"});
}

TEST(ParameterValidation, AcceptsValuesOnTheBoundaryOfTheirRange) {
  ci::Parameters p = other_valid_parameters();
  p.stiffness.translation.setZero();
  p.damping_ratio.rotation.setZero();
  p.nullspace.stiffness = joints({0});
  p.nullspace.pseudo_inverse_damping = 0;
  p.filter.pose = {0.0, 1.0};
  p.filter.wrench.fraction = 1.0;
  p.limits.stiffness.translation = {0, 0};
  p.limits.wrench = {0, 0};
  Rig rig = make_running_rig();
  ASSERT_NO_THROW(rig.controller.set_parameters(p));
  EXPECT_EQ(first_difference(rig.controller.parameters(), p), "");
  EXPECT_EQ(rig.controller.update(rig.robot, kDt), ci::Status::ok);
  EXPECT_TRUE(rig.controller.torque().allFinite());
}

// ---------------------------------------------------------------------------------------------
// The control cycle never throws; bad input gives a status and a torque ramped to zero

/// Largest |change| of each joint's torque per cycle [Nm] for a cycle of `dt` seconds.
ci::JointVector rate_steps(const ci::CartesianImpedanceController& controller, double dt) {
  return ci::per_joint(controller.parameters().limits.joint_torque_rate, controller.num_joints()) *
         dt;
}

/// Runs bad cycles on a running rig and checks: each returns `expected`, the torque is finite,
/// moves toward zero on every joint (never past it) by at most the rate limit times `step_dt`,
/// and becomes exactly zero when the rate limit allows; then one valid cycle returns ok.
void expect_ramp_to_zero(const std::string& label, const std::function<ci::Status(Rig&)>& bad_cycle,
                         ci::Status expected, double step_dt) {
  SCOPED_TRACE(label);
  Rig rig = make_running_rig();
  ci::JointVector previous = rig.controller.torque();
  ASSERT_GT(previous.cwiseAbs().maxCoeff(), 3.0) << "the rig should hold a sizeable torque";
  const ci::JointVector max_step = rate_steps(rig.controller, step_dt);
  // With one scale factor for all joints the slowest joint sets the number of cycles.
  const int cycles_to_zero =
      static_cast<int>(std::ceil(previous.cwiseAbs().cwiseQuotient(max_step).maxCoeff()));
  ASSERT_GT(cycles_to_zero, 2);
  int zero_at = -1;
  for (int cycle = 0; cycle < cycles_to_zero + 5; ++cycle) {
    // update() is noexcept: a throw inside it would terminate the test program.
    const ci::Status status = bad_cycle(rig);
    ASSERT_STREQ(ci::to_string(status), ci::to_string(expected)) << "cycle " << cycle;
    ASSERT_STREQ(ci::to_string(rig.controller.state().status), ci::to_string(expected));
    const ci::JointVector& tau = rig.controller.torque();
    ASSERT_EQ(tau.size(), kJoints);
    ASSERT_TRUE(tau.allFinite()) << "cycle " << cycle << ": " << tau.transpose();
    for (Eigen::Index i = 0; i < kJoints; ++i) {
      EXPECT_LE(std::abs(tau[i] - previous[i]), max_step[i] * (1 + 1e-12))
          << "cycle " << cycle << ", joint " << i;
      EXPECT_LE(std::abs(tau[i]), std::abs(previous[i])) << "cycle " << cycle << ", joint " << i;
      EXPECT_GE(tau[i] * previous[i], 0.0) << "sign flipped: cycle " << cycle << ", joint " << i;
    }
    if (zero_at < 0 && (tau.array() == 0.0).all()) zero_at = cycle;
    previous = tau;
  }
  EXPECT_TRUE((previous.array() == 0.0).all()) << previous.transpose();
  EXPECT_GE(zero_at, cycles_to_zero - 2);
  EXPECT_LE(zero_at, cycles_to_zero);
  EXPECT_TRUE(same_bits(rig.controller.state().tau_cartesian, ci::JointVector::Zero(kJoints)));

  // Valid input again: back to ok, and the torque rises from zero within the rate limit.
  ASSERT_EQ(rig.controller.update(rig.robot, kDt), ci::Status::ok);
  const ci::JointVector& tau = rig.controller.torque();
  ASSERT_TRUE(tau.allFinite());
  EXPECT_GT(tau.cwiseAbs().maxCoeff(), 0.0);
  const ci::JointVector valid_step = rate_steps(rig.controller, kDt);
  for (Eigen::Index i = 0; i < kJoints; ++i) {
    EXPECT_LE(std::abs(tau[i]), valid_step[i] * (1 + 1e-12)) << "joint " << i;
  }
}

TEST(CycleSafety, UpdateBeforeStartReturnsNotStartedWithZeroTorque) {
  ci::CartesianImpedanceController controller(kJoints, rig_parameters());
  ci::RobotState bad = rig_robot();
  bad.q[0] = kNaN;
  for (const ci::RobotState& robot : {rig_robot(), bad}) {
    for (double dt : {kDt, 0.0, kNaN}) {
      EXPECT_EQ(controller.update(robot, dt), ci::Status::not_started);
      EXPECT_EQ(controller.state().status, ci::Status::not_started);
      EXPECT_TRUE(same_bits(controller.torque(), ci::JointVector::Zero(kJoints)));
    }
  }
}

TEST(CycleSafety, NonFiniteOrWronglySizedRobotStateRampsTorqueToZero) {
  struct Case {
    std::string label;
    std::function<void(ci::RobotState&)> spoil;
  };
  std::vector<Case> cases;
  for (const Poison& poison : kPoisons) {
    const double value = poison.value;
    const std::string text = std::string(" = ") + poison.text;
    cases.push_back({"q[3]" + text, [value](auto& r) { r.q[3] = value; }});
    cases.push_back({"dq[6]" + text, [value](auto& r) { r.dq[6] = value; }});
    cases.push_back({"jacobian(4, 2)" + text, [value](auto& r) { r.jacobian(4, 2) = value; }});
    cases.push_back({"position.z" + text, [value](auto& r) { r.pose.position.z() = value; }});
    cases.push_back({"orientation.w" + text, [value](auto& r) { r.pose.orientation.w() = value; }});
  }
  cases.push_back({"orientation norm 0", [](auto& r) { r.pose.orientation.coeffs().setZero(); }});
  cases.push_back({"orientation norm 2", [](auto& r) { r.pose.orientation.coeffs() *= 2; }});
  cases.push_back({"q of 6", [](auto& r) { r.q = ci::JointVector::Zero(kJoints - 1); }});
  cases.push_back({"dq of 8", [](auto& r) { r.dq = ci::JointVector::Zero(kJoints + 1); }});
  cases.push_back({"jacobian 6 x 6", [](auto& r) { r.jacobian = ci::Jacobian::Ones(6, 6); }});
  cases.push_back({"6-joint state", [](auto& r) { r = ci::make_robot_state(kJoints - 1); }});
  for (const Case& c : cases) {
    // A longer dt than the rig's shows the ramp uses the dt of the cycle.
    constexpr double kBadCycleDt = 2e-3;
    expect_ramp_to_zero(
        c.label,
        [&](Rig& rig) {
          ci::RobotState robot = rig.robot;
          c.spoil(robot);
          return rig.controller.update(robot, kBadCycleDt);
        },
        ci::Status::invalid_robot_state, kBadCycleDt);
  }
}

TEST(CycleSafety, InvalidDtRampsTorqueToZeroAtTheLastValidRate) {
  // There is no usable dt in these cycles; the ramp runs at the last valid one (the rig's kDt).
  for (double dt : {0.0, -kDt, -1.0, kNaN, kInf, -kInf}) {
    expect_ramp_to_zero(
        "dt = " + ci::format_number(dt),
        [dt](Rig& rig) { return rig.controller.update(rig.robot, dt); }, ci::Status::invalid_dt,
        kDt);
  }
}

TEST(CycleSafety, OneBadCycleThenValidInputIsOkAgain) {
  Rig rig = make_running_rig();
  const ci::JointVector before = rig.controller.torque();
  ci::RobotState bad = rig.robot;
  bad.dq[1] = kNaN;
  EXPECT_EQ(rig.controller.update(bad, kDt), ci::Status::invalid_robot_state);
  EXPECT_EQ(rig.controller.update(rig.robot, 0.0), ci::Status::invalid_dt);
  EXPECT_EQ(rig.controller.update(rig.robot, kDt), ci::Status::ok);
  EXPECT_EQ(rig.controller.state().status, ci::Status::ok);
  EXPECT_TRUE(rig.controller.torque().allFinite());
  // Two cycles of ramp-down and one of ramp-up: within three rate steps of where it was.
  const ci::JointVector step = rate_steps(rig.controller, kDt);
  for (Eigen::Index i = 0; i < kJoints; ++i) {
    EXPECT_LE(std::abs(rig.controller.torque()[i] - before[i]), 3 * step[i] * (1 + 1e-12));
  }
}

// ---------------------------------------------------------------------------------------------
// YAML loader

/// parameters_from_yaml(yaml, "test.yaml") throws ci::Error whose message contains every part.
::testing::AssertionResult yaml_rejected_with(const std::string& yaml,
                                              const std::vector<std::string>& parts) {
  ::testing::AssertionResult result =
      rejected_with([&] { ci::parameters_from_yaml(yaml, "test.yaml"); }, parts);
  if (!result) result << "\nfor YAML:\n" << yaml;
  return result;
}

/// A file in a fresh scratch directory, removed with the object.
class TemporaryFile {
 public:
  TemporaryFile(const std::string& name, const std::string& text) {
    const ::testing::TestInfo* test = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = ::testing::TempDir() + "validation_test_" + std::to_string(::getpid()) + "_" +
            test->name() + "_" + name;
    std::ofstream(path_) << text;
  }
  ~TemporaryFile() { std::remove(path_.c_str()); }
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

/// Nested block YAML setting the dotted `name` to `value`; `line` receives the value's line.
std::string nested_yaml(std::string_view name, const std::string& value, int& line) {
  std::string yaml;
  std::string indent;
  line = 1;
  for (std::size_t dot; (dot = name.find('.')) != std::string_view::npos; ++line) {
    yaml += indent + std::string(name.substr(0, dot)) + ":\n";
    name.remove_prefix(dot + 1);
    indent += "  ";
  }
  return yaml + indent + std::string(name) + ": " + value + "\n";
}

TEST(YamlConfig, UnknownTopLevelKeyIsNamedWithItsLine) {
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  translation: 500\nstifness:\n  rotation: 5\n",
                                 {"test.yaml:3:", "unknown parameter", "'stifness'"}));
  EXPECT_TRUE(yaml_rejected_with("nullspace:\n  damping_ratio: 1\ngain: 5\n",
                                 {"test.yaml:3:", "unknown parameter", "'gain'"}));
}

TEST(YamlConfig, UnknownNestedKeyIsNamedByItsDottedPathAndLine) {
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  rotation: 5\n  tranlation: [1, 2, 3]\n",
                                 {"test.yaml:3:", "unknown parameter", "'stiffness.tranlation'"}));
  EXPECT_TRUE(
      yaml_rejected_with("limits:\n  stiffness:\n    translation:\n      min: 1\n      mxa: 5\n",
                         {"test.yaml:5:", "'limits.stiffness.translation.mxa'"}));
  EXPECT_TRUE(
      yaml_rejected_with("filter:\n  poses:\n    time: 0.1\n", {"test.yaml:2:", "'filter.poses'"}));
}

TEST(YamlConfig, GroupGivenAsScalarOrListIsRejected) {
  EXPECT_TRUE(yaml_rejected_with("filter: 0.5\n", {"test.yaml:1:", "'filter'", "group"}));
  EXPECT_TRUE(yaml_rejected_with("limits:\n  stiffness: 100\n",
                                 {"test.yaml:2:", "'limits.stiffness'", "group"}));
  EXPECT_TRUE(
      yaml_rejected_with("stiffness: [500, 500, 500]\n", {"test.yaml:1:", "'stiffness'", "group"}));
}

TEST(YamlConfig, ValueOfTheWrongShapeIsRejected) {
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  translation: [500, 500]\n",
                                 {"test.yaml:2:", "stiffness.translation", "3 numbers", "2"}));
  EXPECT_TRUE(yaml_rejected_with("wrench:\n  torque: [1, 2, 3, 4]\n",
                                 {"test.yaml:2:", "wrench.torque", "3 numbers", "4"}));
  EXPECT_TRUE(yaml_rejected_with("limits:\n  joint_torque: []\n",
                                 {"test.yaml:2:", "limits.joint_torque", "one per joint"}));
  std::string too_many = "limits:\n  joint_torque: [1";
  for (int i = 0; i < ci::kMaxJoints; ++i) too_many += ", 1";  // kMaxJoints + 1 values
  EXPECT_TRUE(yaml_rejected_with(too_many + "]\n",
                                 {"test.yaml:2:", "limits.joint_torque", "one per joint"}));
  EXPECT_TRUE(yaml_rejected_with("nullspace:\n  damping_ratio: [1, 2]\n",
                                 {"test.yaml:2:", "nullspace.damping_ratio", "not a number"}));
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  frame: [base]\n",
                                 {"test.yaml:2:", assigned("stiffness.frame", "a list of 1"),
                                  "is not a frame (valid: base, end_effector)"}));
}

TEST(YamlConfig, ParameterGivenAsMapIsAShapeErrorNotAnUnknownKey) {
  // The parameter exists; calling it unknown would send the user looking for a typo.
  const std::vector<std::pair<std::string, std::string>> cases{
      {"stiffness:\n  translation:\n    x: 1\n    y: 2\n    z: 3\n", "stiffness.translation"},
      {"nullspace:\n  damping_ratio:\n    value: 1\n", "nullspace.damping_ratio"},
      {"limits:\n  joint_torque:\n    all: 50\n", "limits.joint_torque"}};
  for (const auto& [yaml, name] : cases) {
    std::string message;
    ASSERT_TRUE(throws_error([&] { ci::parameters_from_yaml(yaml, "test.yaml"); }, message));
    EXPECT_TRUE(contains_all(message, {"test.yaml:", name}));
    EXPECT_EQ(message.find("unknown parameter"), std::string::npos) << message;
  }
}

TEST(YamlConfig, NonNumberIsRejectedNamingTheElement) {
  EXPECT_TRUE(yaml_rejected_with(
      "nullspace:\n  damping_ratio: abc\n",
      {"test.yaml:2:", assigned("nullspace.damping_ratio", "'abc'"), "not a number"}));
  EXPECT_TRUE(yaml_rejected_with(
      "stiffness:\n  rotation: [50, fifty, 50]\n",
      {"test.yaml:2:", assigned("stiffness.rotation.y", "'fifty'"), "not a number"}));
  EXPECT_TRUE(yaml_rejected_with("limits:\n  joint_torque: [87, 87, 87, 87x, 12, 12, 12]\n",
                                 {"test.yaml:2:", assigned("limits.joint_torque[3]", "'87x'")}));
  EXPECT_TRUE(yaml_rejected_with(
      "filter:\n  pose:\n    time: true\n",
      {"test.yaml:3:", assigned("filter.pose.time", "true"), "is not a number [s]"}));
}

TEST(YamlConfig, EveryTableRowRejectsNanAndInfinityWithItsLine) {
  const std::array<std::pair<const char*, const char*>, 3> kYamlPoisons{
      {{".nan", "nan"}, {".inf", "inf"}, {"-.inf", "-inf"}}};
  int elements_checked = 0;
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    ci::Parameters defaults;
    const ci::ParameterField field = info.in(defaults);
    if (std::holds_alternative<ci::Frame*>(field) || std::holds_alternative<bool*>(field)) {
      continue;
    }
    const bool three = std::holds_alternative<Eigen::Vector3d*>(field);
    const bool per_joint = std::holds_alternative<ci::JointVector*>(field);
    const int count = three ? 3 : per_joint ? kJoints : 1;
    for (int i = 0; i < count; ++i) {
      ++elements_checked;
      std::string element(info.name);
      if (three) element += std::string(".") + kAxes[i];
      if (per_joint) element += "[" + std::to_string(i) + "]";
      for (const auto& [yaml_value, text] : kYamlPoisons) {
        std::string value = yaml_value;
        if (count > 1) {
          value = "[";
          for (int j = 0; j < count; ++j)
            value += (j ? ", " : "") + std::string(j == i ? yaml_value : "1");
          value += "]";
        }
        int line = 0;
        const std::string yaml = nested_yaml(info.name, value, line);
        EXPECT_TRUE(yaml_rejected_with(yaml, {"test.yaml:" + std::to_string(line) + ":",
                                              assigned(element, text), info.range_text()}));
      }
    }
  }
  EXPECT_EQ(elements_checked, 6 * 3 + 5 * 7 + 32);
}

TEST(YamlConfig, OutOfRangeValueIsReportedWithFileAndLine) {
  const TemporaryFile file("out_of_range.yaml",
                           "# comment\nstiffness:\n  translation: [500, -5, 500]\n");
  EXPECT_TRUE(rejected_with([&] { ci::load_parameters(file.path()); },
                            {file.path() + ":3:", assigned("stiffness.translation.y", "-5 N/m"),
                             "is outside [0, 100000]"}));
  const TemporaryFile fraction("fraction.yaml", "filter:\n  nullspace:\n    fraction: 1.5\n");
  EXPECT_TRUE(rejected_with([&] { ci::load_parameters(fraction.path()); },
                            {fraction.path() + ":3:", assigned("filter.nullspace.fraction", "1.5"),
                             "is outside [0.5, 1]"}));
  EXPECT_TRUE(yaml_rejected_with(
      "limits:\n  pose_error:\n    translation: 0\n",
      {"test.yaml:3:", assigned("limits.pose_error.translation", "0 m"), "is outside [0.01, 10]"}));
}

TEST(YamlConfig, MinGreaterThanMaxAcrossFieldsIsRejected) {
  EXPECT_TRUE(yaml_rejected_with("limits:\n  damping_ratio:\n    min: 3\n    max: 2\n",
                                 {"test.yaml", assigned("limits.damping_ratio.min", "3"),
                                  assigned("limits.damping_ratio.max", "2"), "greater than"}));
  // max alone below the default min is just as wrong.
  EXPECT_TRUE(
      yaml_rejected_with("limits:\n  stiffness:\n    rotation:\n      min: 100\n      max: 50\n",
                         {assigned("limits.stiffness.rotation.min", "100 Nm/rad"),
                          assigned("limits.stiffness.rotation.max", "50 Nm/rad")}));
}

TEST(YamlConfig, MissingFileIsNamed) {
  const std::string path = "/nonexistent/cartesian_impedance/params.yaml";
  EXPECT_TRUE(rejected_with([&] { ci::load_parameters(path); }, {path}));
}

TEST(YamlConfig, DirectoryIsNotAParameterFile) {
  // Opening a directory succeeds on Linux and reads nothing; it must not pass for an empty file.
  const std::string path = ::testing::TempDir();
  EXPECT_TRUE(rejected_with([&] { ci::load_parameters(path); }, {path}));
}

TEST(YamlConfig, MalformedYamlIsRejected) {
  EXPECT_TRUE(yaml_rejected_with("stiffness: [1, 2\n", {"test.yaml", "malformed YAML"}));
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  translation: 1\n rotation: 2\n",
                                 {"test.yaml", "malformed YAML"}));
  EXPECT_TRUE(yaml_rejected_with("- 1\n- 2\n", {"test.yaml", "top level must be a map"}));
  EXPECT_TRUE(yaml_rejected_with("just text\n", {"test.yaml", "top level must be a map"}));
  const TemporaryFile file("malformed.yaml", "filter: {pose: \n");
  EXPECT_TRUE(
      rejected_with([&] { ci::load_parameters(file.path()); }, {file.path(), "malformed YAML"}));
}

TEST(YamlConfig, ComplexKeyIsAnErrorNotAYamlCppException) {
  // A key that is a list or map made yaml-cpp throw its own TypedBadConversion.
  EXPECT_TRUE(yaml_rejected_with("? [a, b]\n: 1\n", {"test.yaml:1:", "key", "a list"}));
  EXPECT_TRUE(yaml_rejected_with("{[1,2]: 3}\n", {"test.yaml:1:", "key", "a list"}));
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  ? {a: 1}\n  : 1\n",
                                 {"test.yaml:2:", "in stiffness", "key", "a map"}));
  EXPECT_TRUE(
      yaml_rejected_with("stiffness:\n  ~: 1\n", {"test.yaml:2:", "in stiffness", "key", "empty"}));
}

TEST(YamlConfig, DuplicateKeyIsRejectedNamingTheKeyAndBothLines) {
  // yaml-cpp keeps both entries and the loader read the last: a silent override.
  EXPECT_TRUE(yaml_rejected_with("stiffness: {translation: 1}\nstiffness: {translation: 2}\n",
                                 {"test.yaml:2:", "'stiffness'", "twice", "lines 1 and 2"}));
  EXPECT_TRUE(
      yaml_rejected_with("stiffness:\n  translation: 1\n  rotation: 2\n  translation: 3\n",
                         {"test.yaml:4:", "'stiffness.translation'", "twice", "lines 2 and 4"}));
  EXPECT_TRUE(yaml_rejected_with("filter: {pose: {time: 0.1, time: 0.2}}\n",
                                 {"test.yaml:1:", "'filter.pose.time'", "twice", "lines 1 and 1"}));
}

TEST(YamlConfig, SecondDocumentIsRejected) {
  // YAML::Load read the first document and ignored the rest.
  EXPECT_TRUE(
      yaml_rejected_with("stiffness:\n  translation: 1\n---\nstiffness:\n  translation: 2\n",
                         {"test.yaml:4:", "a second YAML document", "only one document"}));
  EXPECT_TRUE(yaml_rejected_with("---\nstiffness:\n  translation: 1\n---\n",
                                 {"test.yaml", "second YAML document", "only one document"}));
  // One document between explicit markers is fine.
  EXPECT_EQ(
      ci::parameters_from_yaml("---\nstiffness:\n  translation: 700\n...\n").stiffness.translation,
      Eigen::Vector3d::Constant(700));
}

TEST(YamlConfig, QuotedNumberOrSwitchIsAStringAndRejected) {
  // yaml-cpp converts the text of any scalar; in YAML quotes make a string, whatever it reads.
  EXPECT_TRUE(yaml_rejected_with("nullspace:\n  damping_ratio: '5'\n",
                                 {"test.yaml:2:", assigned("nullspace.damping_ratio", "'5'"),
                                  "quoted", "string", "without quotes"}));
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  rotation: [50, \"50\", 50]\n",
                                 {"test.yaml:2:", "stiffness.rotation.y", "quoted"}));
  EXPECT_TRUE(yaml_rejected_with("dynamics:\n  gravity_compensation: 'true'\n",
                                 {"test.yaml:2:", "dynamics.gravity_compensation", "quoted"}));
  EXPECT_TRUE(yaml_rejected_with("nullspace:\n  damping_ratio: ' 5'\n",
                                 {"test.yaml:2:", "nullspace.damping_ratio", "quoted"}));
  EXPECT_TRUE(yaml_rejected_with("nullspace:\n  damping_ratio: |\n    5\n",
                                 {"test.yaml:2:", "nullspace.damping_ratio", "string"}));
  EXPECT_TRUE(yaml_rejected_with("nullspace:\n  damping_ratio: !!str 5\n",
                                 {"test.yaml:2:", "nullspace.damping_ratio", "tag", "!!str"}));
  EXPECT_TRUE(yaml_rejected_with("dynamics:\n  gravity_compensation: !!bool true\n",
                                 {"test.yaml:2:", "dynamics.gravity_compensation", "tag"}));
  // A frame is a name, quoted or not.
  EXPECT_EQ(ci::parameters_from_yaml("stiffness:\n  frame: 'end_effector'\n").stiffness.frame,
            ci::Frame::end_effector);
}

TEST(YamlConfig, UnusualNumberSpellingsAreDecidedExplicitly) {
  const std::string range = ci::parameter_info("nullspace.damping_ratio").range_text();
  const auto damping = [](const std::string& value) {
    return "nullspace:\n  damping_ratio: " + value + "\n";
  };
  // Too large for a double: rejected with the range, as .nan and .inf are (see above).
  EXPECT_TRUE(yaml_rejected_with(
      damping("1e400"),
      {"test.yaml:2:", assigned("nullspace.damping_ratio", "1e400"), "overflows", range}));
  EXPECT_TRUE(yaml_rejected_with(damping("-1e400"), {"test.yaml:2:", "-1e400", "overflows"}));
  // Integer forms of YAML 1.1/1.2 that yaml-cpp does not read as numbers, and other words.
  for (const char* spelling : {"0x10", "0o17", "0b101", "1_000", "nan", "inf", "1,5", "5 5"}) {
    EXPECT_TRUE(yaml_rejected_with(
        damping(spelling), {"test.yaml:2:", "'" + std::string(spelling) + "'", "is not a number"}));
  }
  // What is a number is read as one: decimal forms, and values that round to a double (5e-324
  // is the smallest subnormal, 1e-400 rounds to 0 as every decimal parser rounds it).
  const std::vector<std::pair<std::string, double>> numbers{
      {"+0.5", 0.5}, {"0005", 5},        {"1.", 1},      {".5", 0.5},
      {"-0", 0.0},   {"5e-324", 5e-324}, {"1e-400", 0.0}};
  for (const auto& [text, value] : numbers) {
    SCOPED_TRACE(text);
    ci::Parameters p;
    ASSERT_NO_THROW(p = ci::parameters_from_yaml("stiffness:\n  rotation: " + text + "\n"));
    EXPECT_EQ(p.stiffness.rotation, Eigen::Vector3d::Constant(value));
  }
  // An integer beyond 2^53 is a number too, rounded to a double (and then checked against the
  // range, whatever that is).
  try {
    EXPECT_EQ(ci::parameters_from_yaml("stiffness:\n  rotation: 99999999999999999999999\n")
                  .stiffness.rotation,
              Eigen::Vector3d::Constant(1e23));
  } catch (const ci::Error& error) {
    EXPECT_TRUE(contains_all(error.what(), {assigned("stiffness.rotation", "1e+23"), "outside"}));
  }
  // Anchors and aliases are plain YAML; a merge key is a key the loader does not know.
  const ci::Parameters p =
      ci::parameters_from_yaml("stiffness:\n  translation: &k 700\n  rotation: *k\n");
  EXPECT_EQ(p.stiffness.rotation, Eigen::Vector3d::Constant(700));
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  <<: {translation: 1}\n",
                                 {"test.yaml:2:", "'stiffness.<<'", "merge keys"}));
  EXPECT_TRUE(yaml_rejected_with("stiffness: &s\n  translation: 1\n  again: *s\n",
                                 {"test.yaml:3:", "unknown parameter 'stiffness.again'"}));
  // A list or map holding itself ends at the first key the loader does not know.
  EXPECT_TRUE(yaml_rejected_with("stiffness: &s {stiffness: *s}\n",
                                 {"test.yaml:1:", "'stiffness.stiffness'"}));
  EXPECT_TRUE(yaml_rejected_with("limits:\n  joint_torque: &l [1, *l]\n",
                                 {"test.yaml:2:", "limits.joint_torque[1]", "a list"}));
}

TEST(YamlConfig, DeepNestingIsRejectedWithoutCrashing) {
  // yaml-cpp's parser recurses once per level and stops itself at a depth it bounds; the loader
  // reports that, and never descends further than the parameter groups go.
  for (const char* open : {"[", "{", "{a: ", "[{a: "}) {
    std::string yaml = "stiffness:\n  translation: ";
    for (int i = 0; i < 100000; ++i) yaml += open;
    EXPECT_TRUE(yaml_rejected_with(yaml, {"test.yaml:", "nested too deeply"})) << open;
  }
  std::string block;
  for (int i = 0; i < 2000; ++i) block += std::string(static_cast<std::size_t>(i), ' ') + "a:\n";
  EXPECT_TRUE(yaml_rejected_with(block, {"test.yaml:", "nested too deeply"}));
}

TEST(YamlConfig, EmptyInputGivesDefaults) {
  const ci::Parameters defaults;
  for (const char* yaml : {"", "\n", "# nothing set\n", "---\n"}) {
    ci::Parameters p = other_valid_parameters();
    ASSERT_NO_THROW(p = ci::parameters_from_yaml(yaml)) << yaml;
    EXPECT_EQ(first_difference(p, defaults), "") << yaml;
  }
  const TemporaryFile file("empty.yaml", "");
  ci::Parameters p = other_valid_parameters();
  ASSERT_NO_THROW(p = ci::load_parameters(file.path()));
  EXPECT_EQ(first_difference(p, defaults), "");
}

TEST(YamlConfig, OneNumberIsBroadcastToThreeAxesAndAllJoints) {
  const ci::Parameters p = ci::parameters_from_yaml(
      "stiffness:\n  translation: 300\n  rotation: 30\nnullspace:\n  stiffness: 20\n"
      "limits:\n  joint_torque: 40\n");
  EXPECT_TRUE(same_bits(p.stiffness.translation, Eigen::Vector3d::Constant(300)));
  EXPECT_TRUE(same_bits(p.stiffness.rotation, Eigen::Vector3d::Constant(30)));
  EXPECT_TRUE(same_bits(p.nullspace.stiffness, joints({20})));
  EXPECT_TRUE(same_bits(p.limits.joint_torque, joints({40})));

  ci::CartesianImpedanceController controller(kJoints, p);
  EXPECT_TRUE(same_bits(controller.state().commanded.nullspace_stiffness,
                        ci::JointVector::Constant(kJoints, 20)));
  EXPECT_TRUE(same_bits(ci::per_joint(controller.parameters().limits.joint_torque, kJoints),
                        ci::JointVector::Constant(kJoints, 40)));
  ci::Vector6d diagonal = controller.state().commanded.stiffness.diagonal();
  EXPECT_TRUE(same_bits(diagonal, six(300, 300, 300, 30, 30, 30)));
}

TEST(YamlConfig, PerJointListMustMatchTheControllersJointCount) {
  const ci::Parameters p =
      ci::parameters_from_yaml("limits:\n  joint_torque: [87, 87, 87, 87, 12, 12]\n");
  EXPECT_TRUE(rejected_with([&] { ci::CartesianImpedanceController controller(kJoints, p); },
                            {"limits.joint_torque has 6 values", "7"}));
  EXPECT_NO_THROW(ci::CartesianImpedanceController(6, p));
}

TEST(YamlConfig, FramesAreReadAndAnInvalidFrameIsRejected) {
  ci::Parameters p =
      ci::parameters_from_yaml("stiffness:\n  frame: end_effector\nwrench:\n  frame: base\n");
  EXPECT_EQ(p.stiffness.frame, ci::Frame::end_effector);
  EXPECT_EQ(p.wrench.frame, ci::Frame::base);
  p = ci::parameters_from_yaml("stiffness:\n  frame: base\nwrench:\n  frame: end_effector\n");
  EXPECT_EQ(p.stiffness.frame, ci::Frame::base);
  EXPECT_EQ(p.wrench.frame, ci::Frame::end_effector);
  EXPECT_TRUE(yaml_rejected_with("wrench:\n  frame: tool\n",
                                 {"test.yaml:2:", "wrench.frame", "'tool'", "base, end_effector"}));
  EXPECT_TRUE(yaml_rejected_with("stiffness:\n  frame: Base\n",
                                 {"test.yaml:2:", "stiffness.frame", "'Base'"}));
}

TEST(YamlConfig, RoundTripKeepsEveryNonDefaultValueExactly) {
  ci::Parameters p = other_valid_parameters();
  // Values that need all 17 significant digits.
  p.stiffness.translation.x() = 1.0 / 3.0;
  p.filter.pose.fraction = 0.4 + 0.2;
  p.limits.pose_error.rotation = 0.1 / 3.0;
  p.limits.joint_torque[4] = 11.000000000000002;
  // The switches, all away from their defaults.
  p.dynamics.gravity_compensation = true;
  p.dynamics.inertia_shaped_damping = false;
  p.dynamics.dynamically_consistent_nullspace = true;
  {
    // Every row differs from its default, so a loader that ignores a key would show.
    const ci::Parameters defaults;
    for (const ci::ParameterInfo& info : ci::parameter_table()) {
      EXPECT_NE(ci::value_text(p, info), ci::value_text(defaults, info)) << info.name;
    }
  }
  const std::string yaml = ci::parameters_to_yaml(p);
  ci::Parameters back;
  ASSERT_NO_THROW(back = ci::parameters_from_yaml(yaml, "round trip")) << yaml;
  EXPECT_EQ(first_difference(p, back), "") << "emitted YAML:\n" << yaml;
  EXPECT_EQ(ci::parameters_to_yaml(back), yaml);
}

TEST(YamlConfig, RoundTripOfSeededRandomParameters) {
  std::mt19937 random(7);
  std::uniform_real_distribution<double> unit(0, 1);
  std::uniform_int_distribution<int> joint_count(1, ci::kMaxJoints);
  for (int iteration = 0; iteration < 50; ++iteration) {
    SCOPED_TRACE(iteration);
    ci::Parameters p;
    for (const ci::ParameterInfo& info : ci::parameter_table()) {
      const ci::ParameterField field = info.in(p);
      if (auto* frame = std::get_if<ci::Frame*>(&field)) {
        **frame = unit(random) < 0.5 ? ci::Frame::base : ci::Frame::end_effector;
        continue;
      }
      if (auto* flag = std::get_if<bool*>(&field)) {
        **flag = unit(random) < 0.5;
        continue;
      }
      if (auto* values = std::get_if<ci::JointVector*>(&field)) {
        **values = ci::JointVector::Zero(joint_count(random));
      }
      for_each_element(info, p, [&](const std::string&, double& value) {
        // Log-uniform over the valid range (down to a millionth of its top), either sign where
        // negative values are valid.
        const double low = std::max(info.min, 1e-6 * info.max);
        value = low * std::pow(info.max / low, unit(random));
        if (info.min < 0 && unit(random) < 0.5) value = -value;
      });
    }
    for (ci::Range* range :
         {&p.limits.stiffness.translation, &p.limits.stiffness.rotation, &p.limits.damping_ratio,
          &p.limits.nullspace_stiffness, &p.plausibility.dt}) {
      if (range->min > range->max) std::swap(range->min, range->max);
    }
    ASSERT_NO_THROW(ci::validate(p));
    const std::string yaml = ci::parameters_to_yaml(p);
    ci::Parameters back;
    ASSERT_NO_THROW(back = ci::parameters_from_yaml(yaml)) << yaml;
    ASSERT_EQ(first_difference(p, back), "") << yaml;
    ASSERT_EQ(ci::parameters_to_yaml(back), yaml);
  }
}

// ---------------------------------------------------------------------------------------------
// The example parameter files

std::string source_path(const std::string& relative) {
  return std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/" + relative;
}

/// Dotted keys of every leaf in a block-style YAML file (the style of config/*.yaml).
std::set<std::string> leaf_keys(const std::string& path) {
  std::ifstream file(path);
  std::set<std::string> keys;
  std::vector<std::pair<std::size_t, std::string>> parents;  // (indent, key)
  for (std::string line; std::getline(file, line);) {
    const std::size_t comment = line.find('#');
    if (comment != std::string::npos) line.erase(comment);
    const std::size_t indent = line.find_first_not_of(' ');
    const std::size_t colon = line.find(':');
    if (indent == std::string::npos || colon == std::string::npos) continue;
    while (!parents.empty() && parents.back().first >= indent) parents.pop_back();
    std::string key;
    for (const auto& parent : parents) key += parent.second + ".";
    key += line.substr(indent, colon - indent);
    if (line.find_first_not_of(' ', colon + 1) == std::string::npos) {
      parents.emplace_back(indent, line.substr(indent, colon - indent));
    } else {
      keys.insert(key);
    }
  }
  return keys;
}

void expect_example_file(const std::string& relative, const ci::JointVector& torque_limits) {
  SCOPED_TRACE(relative);
  const std::string path = source_path(relative);
  ci::Parameters p;
  ASSERT_NO_THROW(p = ci::load_parameters(path));
  EXPECT_TRUE(same_bits(ci::per_joint(p.limits.joint_torque, kJoints), torque_limits));

  // Every row of the table is set in the file, so it documents every parameter.
  const std::set<std::string> keys = leaf_keys(path);
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    EXPECT_EQ(keys.count(std::string(info.name)), 1u) << info.name << " is not set in " << path;
  }

  // A 7-joint controller runs on it; the torque stays within the robot's limits.
  std::unique_ptr<ci::CartesianImpedanceController> controller;
  ASSERT_NO_THROW(controller = std::make_unique<ci::CartesianImpedanceController>(kJoints, p));
  EXPECT_THROW(ci::CartesianImpedanceController(6, p), ci::Error) << "limits are per joint";
  const ci::RobotState robot = rig_robot();
  controller->start(robot);
  ci::Pose reference = robot.pose;
  reference.position.x() += 0.05;
  controller->set_reference_pose(reference);
  for (int cycle = 0; cycle < 500; ++cycle) {
    ASSERT_EQ(controller->update(robot, kDt), ci::Status::ok);
    for (Eigen::Index i = 0; i < kJoints; ++i) {
      ASSERT_LE(std::abs(controller->torque()[i]), torque_limits[i]);
    }
  }
  EXPECT_GT(controller->torque().cwiseAbs().maxCoeff(), 0.0);
}

TEST(ConfigFiles, PandaLoadsAndRunsASevenJointController) {
  expect_example_file("config/panda.yaml", joints({87, 87, 87, 87, 12, 12, 12}));
  const ci::Parameters p = ci::load_parameters(source_path("config/panda.yaml"));
  EXPECT_TRUE(same_bits(ci::per_joint(p.limits.joint_torque_rate, kJoints),
                        ci::JointVector::Constant(kJoints, 1000)));
}

TEST(ConfigFiles, Iiwa14LoadsAndRunsASevenJointController) {
  expect_example_file("config/iiwa14.yaml", joints({320, 320, 176, 176, 110, 40, 40}));
}

// ---------------------------------------------------------------------------------------------
// README parameter table

constexpr std::string_view kBeginMarker = "<!-- parameters:begin -->";
constexpr std::string_view kEndMarker = "<!-- parameters:end -->";
constexpr const char* kRegenerate =
    "UPDATE_README=1 build/tests/core_tests --gtest_filter='Readme*'";

/// Byte range of the text between the begin-marker line and the end-marker line.
struct Section {
  std::size_t begin;
  std::size_t end;
};

/// Finds the lines that are exactly the markers; nullopt if either is missing or out of order.
std::optional<Section> parameter_section(const std::string& text) {
  std::optional<std::size_t> content_begin;
  for (std::size_t line_begin = 0; line_begin < text.size();) {
    std::size_t line_end = text.find('\n', line_begin);
    if (line_end == std::string::npos) line_end = text.size();
    std::string_view line(text.data() + line_begin, line_end - line_begin);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (!content_begin && line == kBeginMarker) {
      content_begin = std::min(line_end + 1, text.size());
    } else if (content_begin && line == kEndMarker) {
      return Section{*content_begin, line_begin};
    }
    line_begin = line_end + 1;
  }
  return std::nullopt;
}

std::string with_section_replaced(const std::string& text, const Section& section,
                                  const std::string& table) {
  return text.substr(0, section.begin) + table + text.substr(section.end);
}

/// README.md of the repository; CARTESIAN_IMPEDANCE_README points elsewhere (e.g. a scratch copy).
std::string readme_path() {
  const char* overridden = std::getenv("CARTESIAN_IMPEDANCE_README");
  return overridden != nullptr ? overridden : source_path("README.md");
}

TEST(Readme, ParameterTableIsCurrent) {
  const std::string path = readme_path();
  std::ifstream file(path);
  ASSERT_TRUE(file) << "cannot read " << path;
  std::stringstream buffer;
  buffer << file.rdbuf();
  const std::string text = buffer.str();
  const std::optional<Section> section = parameter_section(text);
  ASSERT_TRUE(section) << path << " needs a line '" << kBeginMarker
                       << "' followed later by a line '" << kEndMarker << "'; then run\n  "
                       << kRegenerate;
  const std::string expected = ci::parameter_table_markdown();
  const std::string actual = text.substr(section->begin, section->end - section->begin);
  if (actual == expected) return;

  const char* update = std::getenv("UPDATE_README");
  if (update != nullptr && std::string(update) == "1") {
    std::ofstream(path, std::ios::binary | std::ios::trunc)
        << with_section_replaced(text, *section, expected);
    std::printf("Updated the parameter table in %s\n", path.c_str());
    return;
  }
  ADD_FAILURE() << "The parameter table in " << path
                << " is out of date. Between the markers it should read:\n"
                << expected << "\nRegenerate it with:\n  " << kRegenerate;
}

TEST(Readme, SectionIsFoundAndReplacedLeavingTheRestAlone) {
  const std::string text =
      "# Title\n\nintro\n<!-- parameters:begin -->\nold table\n<!-- parameters:end -->\nafter\n";
  const std::optional<Section> section = parameter_section(text);
  ASSERT_TRUE(section);
  EXPECT_EQ(text.substr(section->begin, section->end - section->begin), "old table\n");
  EXPECT_EQ(with_section_replaced(text, *section, "| new |\n"),
            "# Title\n\nintro\n<!-- parameters:begin -->\n| new |\n<!-- parameters:end -->\n"
            "after\n");

  const std::optional<Section> empty =
      parameter_section("<!-- parameters:begin -->\n<!-- parameters:end -->\n");
  ASSERT_TRUE(empty);
  EXPECT_EQ(empty->begin, empty->end);
  EXPECT_FALSE(parameter_section("no markers\n"));
  EXPECT_FALSE(parameter_section("<!-- parameters:end -->\n<!-- parameters:begin -->\n"));
  EXPECT_FALSE(
      parameter_section("see <!-- parameters:begin --> inline\n<!-- parameters:end -->\n"));
}

}  // namespace
