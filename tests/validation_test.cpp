// Bad input to the controller's commands: the constructor, the setters and start(). The project's
// rule is checked everywhere: a rejected input raises cartesian_impedance::Error whose message
// names the field, the offending value and the valid range, and a rejected command changes nothing
// (parameters, commanded and filtered targets, and the torque of every later cycle, compared bit
// for bit with a twin that never saw the call). The same for set_parameters() in
// parameter_validation_test.cpp, the control cycle in cycle_safety_test.cpp and the YAML loader in
// yaml_config_test.cpp; the harness is support/validation_harness.hpp.

#include <gtest/gtest.h>

#include <array>
#include <string>
#include <vector>

#include "cartesian_impedance/core/controller.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/parameters.hpp"
#include "support/validation_harness.hpp"

namespace ci = cartesian_impedance;
using namespace validation_harness;

namespace {

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
                    {"robot.jacobian", std::to_string(size) + " columns", "expected 7"});
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

}  // namespace
