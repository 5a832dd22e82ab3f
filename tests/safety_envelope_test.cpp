// Issue 40 on analytic cases, with the 6-joint "Cartesian" robot (J = I, joint torques are the
// wrench): the caps act on the sum of every Cartesian term (the envelope), the tank pays for every
// parameter that stores energy, the payload estimate knows a contact, and a partial update
// changes only what it names. Closed-loop regressions of the table are in
// safety_composition_test.cpp.

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>

#include "cartesian_impedance/core/controller.hpp"
#include "cartesian_impedance/core/parameter_tree.hpp"
#include "support/bare_law.hpp"
#include "support/errors.hpp"

namespace ci = cartesian_impedance;

namespace {

using test_errors::error_of;

ci::Vector6d six(double a, double b, double c, double d, double e, double f) {
  return (ci::Vector6d() << a, b, c, d, e, f).finished();
}

ci::Parameters bare() {
  ci::Parameters p = bare_law::bare_parameters();
  p.damping_ratio.translation.setZero();
  p.damping_ratio.rotation.setZero();
  return p;
}

using bare_law::cartesian_robot;

constexpr double kDt = 0.001;
constexpr double kG = ci::CartesianImpedanceController::kGravity;

}  // namespace

// --- the payload under the force cap

// A declared payload heavier than the force cap could hold is refused, naming both values: the
// cap could bound the press either with the load carried or without it, never both.
TEST(PayloadEnvelope, APayloadTheForceCapCannotHoldIsRefused) {
  ci::Parameters p;
  p.safety.max_force = {40.0, 20.0};
  p.payload.mass = 10.0;
  const std::string message = error_of([&] { ci::validate(p, 7); });
  EXPECT_NE(message.find("payload.mass = 10 kg"), std::string::npos) << message;
  EXPECT_NE(message.find("safety.max_force.force / g = 4.077471967 kg"), std::string::npos)
      << message;
  p.payload.mass = 4.0;
  EXPECT_NO_THROW(ci::validate(p, 7));
  // Its moment under the torque cap, the same way.
  p.payload.center_of_mass = Eigen::Vector3d(0.6, 0.0, 0.0);
  const std::string moment = error_of([&] { ci::validate(p, 7); });
  EXPECT_NE(moment.find("payload.center_of_mass = 0.6 m"), std::string::npos) << moment;
  // With the caps off any payload in range goes.
  p.safety.max_force = {0.0, 0.0};
  p.payload.mass = 10.0;
  EXPECT_NO_THROW(ci::validate(p, 7));
}

// The compensation of a declared 3 kg (29.4 N up) and a spring asking 150 N up: the sum pushes
// with at most the 40 N cap if the load is not there, and the spring alone with at most 40 N if
// it is: the spring keeps 40 - 29.4 N.
TEST(PayloadEnvelope, TheSumPressesWithAtMostTheCapCarriedOrNot) {
  ci::Parameters p = bare();
  p.stiffness.translation.setConstant(3000.0);
  p.safety.max_force = {40.0, 0.0};
  p.payload.mass = 3.0;
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  ci::Pose above = robot.pose;
  above.position.z() += 0.05;
  controller.set_reference_pose(above);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  const ci::ControllerState& state = controller.state();
  // tau_gravity holds the compensation (g(q) is off), tau_cartesian the capped spring.
  const double compensation = state.tau_gravity[2];
  EXPECT_NEAR(compensation, 3.0 * kG, 1e-9);
  EXPECT_NEAR(state.tau_cartesian[2] + compensation, 40.0, 1e-9);
  EXPECT_NEAR(state.safety.force_scale, (40.0 - 3.0 * kG) / 150.0, 1e-9);

  // Pressing down: the spring alone at the cap leaves the sum (carried: spring; not carried:
  // spring + 29.4 N) within it both ways.
  ci::Pose below = robot.pose;
  below.position.z() -= 0.05;
  controller.set_reference_pose(below);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(state.tau_cartesian[2], -40.0, 1e-9);
  EXPECT_LE(std::abs(state.tau_cartesian[2] + compensation), 40.0 + 1e-9);
}

// The landed cap left the payload's torque out: a commanded 30 N up with a declared 3 kg pressed
// a ceiling with 59 N under a 40 N cap.
TEST(PayloadEnvelope, AWrenchWithAPayloadStaysUnderTheCap) {
  ci::Parameters p = bare();
  p.safety.max_force = {40.0, 0.0};
  p.payload.mass = 3.0;
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  controller.set_wrench(six(0, 0, 30, 0, 0, 0));
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.torque()[2], 40.0, 1e-9);
}

// --- the walls under the caps

// A wall 5 cm past the flange at 2000 N/m asks for 100 N: capped at 40 N with the rest of the sum.
TEST(WallEnvelope, TheWallsSpringIsUnderTheForceCap) {
  ci::Parameters p = bare();
  p.stiffness.translation.setZero();
  p.safety.workspace.stiffness = 2000.0;
  p.safety.workspace.damping = 0.0;
  p.safety.workspace.max = Eigen::Vector3d(0.35, 10, 10);
  p.safety.max_force = {40.0, 0.0};
  p.safety.energy_tank = {true, 0.005, 0.005};
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();  // x = 0.4: 5 cm outside
  controller.start(robot);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  // At start the box in force is grown to the flange: the wall stores no more than the tank's
  // 5 mJ (sqrt(2 E / k) = 2.2 mm, 4.5 N), and it closes in only as the flange moves in.
  const double paid = std::sqrt(2 * 0.005 / 2000.0);
  EXPECT_NEAR(controller.state().safety.workspace_in_force.max.x(), 0.4 - paid, 1e-6);
  EXPECT_NEAR(controller.torque()[0], -2000.0 * paid, 1e-3);
  EXPECT_NEAR(controller.state().safety.workspace_penetration.x(), 0.05, 1e-12);
  // Pushed 5 cm further out, the wall pushes back with the cap.
  robot.pose.position.x() = 0.45;
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.torque()[0], -40.0, 1e-9);
  EXPECT_NEAR(controller.state().safety.wall_force.x(), -40.0, 1e-9);
}

// Near the speed cap a wall stops pushing along the motion like the spring does.
TEST(WallEnvelope, TheSpeedGovernorTakesTheWallsPush) {
  ci::Parameters p = bare();
  p.stiffness.translation.setZero();
  p.safety.workspace.stiffness = 2000.0;
  p.safety.workspace.damping = 0.0;
  p.safety.workspace.max = Eigen::Vector3d(0.35, 10, 10);
  p.safety.max_speed = {0.1, 0.0};
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  robot.pose.position.x() = 0.3;
  controller.start(robot);
  robot.pose.position.x() = 0.37;  // 2 cm outside, the wall pushes -40 N
  const double held = ci::CartesianImpedanceController::kSpeedCapAim * 0.1;
  robot.dq = six(-held, 0, 0, 0, 0, 0);  // moving back in at the speed the governor holds
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.torque()[0], 0.0, 1e-9) << "at the cap nothing pushes along the motion";
  robot.dq = six(-0.9 * held, 0, 0, 0, 0, 0);  // halfway through the band: half the push
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.torque()[0], -20.0, 1e-9);
  robot.dq = six(0.05, 0, 0, 0, 0, 0);  // moving out: the wall's push against the motion stays
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.torque()[0], -40.0, 1e-9);
}

// --- the tank pays for every parameter that stores energy

// A box moved 15 cm past the flange (a run-time parameter set) would store 22.5 J in a 2000 N/m
// wall: the box in force stops its face at the flange (free) and follows it in.
TEST(TankPaysForParameters, ABoxMovedPastTheFlangeStopsAtIt) {
  ci::Parameters p = bare();
  p.safety.energy_tank = {true, 0.005, 0.005};
  p.stiffness.translation.setZero();
  p.safety.workspace.stiffness = 2000.0;
  p.safety.workspace.damping = 0.0;
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  p.safety.workspace.max.x() = 0.25;
  controller.set_parameters(p);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  const ci::SafetyState& safety = controller.state().safety;
  EXPECT_TRUE(safety.settings_held);
  // The face may pass the flange by what the 5 mJ pay: sqrt(2 E / k) = 2.2 mm.
  EXPECT_GE(safety.workspace_in_force.max.x(), 0.4 - std::sqrt(2 * 0.005 / 2000.0) - 1e-6);
  EXPECT_LE(std::abs(controller.torque()[0]), std::sqrt(2 * 0.005 * 2000.0) + 1e-6);
  // The reference is clipped into the configured box at once; as the flange moves in, the face
  // follows it (free) until it is where it was sent.
  for (double x = 0.4; x >= 0.2; x -= 0.01) {
    robot.pose.position.x() = x;
    ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
    EXPECT_LE(std::abs(controller.state().safety.wall_force.x()),
              std::sqrt(2 * 0.005 * 2000.0) + 1e-6)
        << x;
  }
  EXPECT_NEAR(safety.workspace_in_force.max.x(), 0.25, 1e-12);
  EXPECT_FALSE(safety.settings_held);

  // Without the tank the box moves at once (and the wall throws the flange back).
  p.safety.energy_tank.enabled = false;
  p.safety.workspace.max.x() = 10.0;
  controller.set_parameters(p);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  robot.pose.position.x() = 0.4;
  p.safety.workspace.max.x() = 0.25;
  controller.set_parameters(p);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.torque()[0], -300.0, 1e-9);
}

// The clip raised while the error is beyond it stores k e (c' - c) - k (c'^2 - c^2) / 2: charged.
// Lowered, it returns the energy (applied at once).
TEST(TankPaysForParameters, ThePoseErrorClipIsCharged) {
  ci::Parameters p = bare();
  p.stiffness.translation.setConstant(3000.0);
  p.safety.energy_tank = {true, 0.005, 0.005};
  p.limits.pose_error.translation = 0.01;
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  robot.pose.position.x() += 0.2;  // 20 cm from the reference: the spring pulls 30 N
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.torque()[0], -30.0, 1e-9);
  p.limits.pose_error.translation = 10.0;
  controller.set_parameters(p);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  const ci::SafetyState& safety = controller.state().safety;
  // 5 mJ pay for dc with k e dc = 0.005 J, dc = 8.3 um: the spring pulls about 30 N still.
  const double clip = safety.pose_error_in_force.translation;
  EXPECT_NEAR(clip, 0.01 + 0.005 / (3000.0 * 0.19), 1e-9);
  EXPECT_NEAR(controller.torque()[0], -3000.0 * clip, 1e-9);
  EXPECT_TRUE(safety.settings_held);
  EXPECT_NEAR(safety.tank_level, 0.0, 1e-6);
  // Lowered back: at once, and the tank refills (to its capacity).
  p.limits.pose_error.translation = 0.01;
  controller.set_parameters(p);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_EQ(safety.pose_error_in_force.translation, 0.01);
  EXPECT_NEAR(safety.tank_level, 0.005, 1e-9);
  // Near the reference the clip is free to rise.
  robot.pose.position.x() -= 0.2;
  p.limits.pose_error.translation = 10.0;
  controller.set_parameters(p);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_EQ(safety.pose_error_in_force.translation, 10.0);
  EXPECT_FALSE(safety.settings_held);
}

// A nullspace stiffness raised while a joint is off its target is paid (1/2 e^T dK e).
TEST(TankPaysForParameters, TheNullspaceStiffnessIsCharged) {
  ci::Parameters p = bare();
  p.safety.energy_tank = {true, 0.005, 0.005};
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  robot.q[3] = 0.1;
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  controller.set_nullspace_stiffness(ci::JointVector::Constant(1, 100.0));
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  // 1/2 k 0.01 = 5 mJ buys k = 1 Nm/rad.
  EXPECT_NEAR(controller.state().filtered.nullspace_stiffness[3], 1.0, 1e-9);
  EXPECT_NEAR(controller.state().safety.tank_level, 0.0, 1e-12);
  // Without the error the raise is free.
  robot.q[3] = 0.0;
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.state().filtered.nullspace_stiffness[3], 100.0, 1e-9);
}

// --- the payload estimate

// A reference 4 cm into a table: the spring presses down with 120 N. No hanging load can pull
// up on the flange: the estimate is not valid, and never negative (landed: -12 kg, valid).
TEST(PayloadEstimate, AContactIsNotALoad) {
  ci::Parameters p = bare();
  p.stiffness.translation.setConstant(3000.0);
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  ci::Pose into = robot.pose;
  into.position.z() -= 0.04;
  controller.set_reference_pose(into);
  for (int k = 0; k < 1000; ++k) ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  const ci::SafetyState& safety = controller.state().safety;
  EXPECT_FALSE(safety.payload_estimate_valid);
  EXPECT_TRUE(safety.static_wrench_unexplained);
  EXPECT_GE(safety.payload_estimate_mass, 0.0);
  // A sideways press is no load either.
  into = robot.pose;
  into.position.x() += 0.01;
  controller.set_reference_pose(into);
  for (int k = 0; k < 1000; ++k) ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_FALSE(safety.payload_estimate_valid);
  // A load hanging 2 cm below the reference (the spring holds it up): valid.
  into = robot.pose;
  into.position.z() += 0.02;
  controller.set_reference_pose(into);
  for (int k = 0; k < 1000; ++k) ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_TRUE(safety.payload_estimate_valid);
  EXPECT_NEAR(safety.payload_estimate_mass, 60.0 / kG, 1e-3);
  EXPECT_TRUE(safety.payload_mismatch) << "declared 0 kg";
}

// Declared but not carried: the spring holds the compensation back at rest, the estimate reads
// zero, and the mismatch is reported within a second.
TEST(PayloadEstimate, ADeclaredPayloadThatIsNotThereIsReported) {
  ci::Parameters p = bare();
  p.stiffness.translation.setConstant(1000.0);
  p.payload.mass = 2.0;
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  // At rest where the spring balances the compensation: 2 kg g / 1000 N/m above the reference.
  robot.pose.position.z() += 2.0 * kG / 1000.0;
  bool reported = false;
  for (int k = 0; k < 1000 && !reported; ++k) {
    ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
    reported = controller.state().safety.payload_mismatch;
  }
  EXPECT_TRUE(reported);
  EXPECT_NEAR(controller.state().safety.payload_estimate_mass, 0.0, 1e-9);
  // At the reference (the load is carried) nothing is reported.
  robot.pose.position.z() -= 2.0 * kG / 1000.0;
  for (int k = 0; k < 1000; ++k) ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_TRUE(controller.state().safety.payload_estimate_valid);
  EXPECT_FALSE(controller.state().safety.payload_mismatch);
  EXPECT_NEAR(controller.state().safety.payload_estimate_mass, 2.0, 1e-3);
}

// --- partial updates

// An update names what it changes: a full stiffness matrix commanded before survives an update
// of filter.pose.time, and the other parameters keep their values.
TEST(ParameterUpdate, ChangesOnlyWhatItNames) {
  ci::Parameters p = bare();
  p.safety.max_speed.translation = 0.25;
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  ci::Matrix6d full = ci::Vector6d::Constant(300.0).asDiagonal();
  full(0, 1) = full(1, 0) = 50.0;
  controller.set_stiffness_matrix(full);
  ci::Parameters values;  // the library's defaults: nothing but filter.pose.time is read
  values.filter.pose.time = 0.5;
  controller.update_parameters(ci::ParameterUpdate::of(values, {"filter.pose.time"}));
  EXPECT_EQ(controller.parameters().filter.pose.time, 0.5);
  EXPECT_EQ(controller.parameters().safety.max_speed.translation, 0.25);
  EXPECT_EQ(controller.state().commanded.stiffness, full);
  // Naming a stiffness row re-commands the stiffness from the parameters.
  values.stiffness.translation.setConstant(700.0);
  controller.update_parameters(ci::ParameterUpdate::of(values, {"stiffness"}));
  EXPECT_EQ(controller.state().commanded.stiffness(0, 0), 700.0);
  EXPECT_EQ(controller.state().commanded.stiffness(0, 1), 0.0);
  // The decoder names what a tree gives.
  const ci::ParameterUpdate decoded = ci::decode_parameter_update(
      ci::ParameterValue::map({{"payload.mass", ci::ParameterValue::number(1.0), ""}}),
      controller.parameters());
  ASSERT_EQ(decoded.row_names().size(), 1u);
  EXPECT_EQ(decoded.row_names()[0], "payload.mass");
  controller.update_parameters(decoded);
  EXPECT_EQ(controller.parameters().payload.mass, 1.0);
  EXPECT_EQ(controller.parameters().safety.max_speed.translation, 0.25);
  EXPECT_EQ(controller.parameters().filter.pose.time, 0.5);
}

// An update that no longer fits the parameters in force (another one came first) is refused
// whole.
TEST(ParameterUpdate, OneThatNoLongerFitsIsRefused) {
  ci::Parameters p = bare();
  ci::CartesianImpedanceController controller(6, p);
  ci::Parameters values = p;
  values.safety.workspace.min.x() = 0.5;  // fits the default max of 10
  const ci::ParameterUpdate raise_min = ci::ParameterUpdate::of(values, {"safety.workspace.min"});
  p.safety.workspace.max.x() = 0.2;
  controller.set_parameters(p);
  const std::string message = error_of([&] { controller.update_parameters(raise_min); });
  EXPECT_NE(message.find("safety.workspace.min.x = 0.5 m is greater than safety.workspace.max.x"),
            std::string::npos)
      << message;
  EXPECT_EQ(controller.parameters().safety.workspace.min.x(), -10.0);
  const ci::ValidCommand valid = ci::validate_command(raise_min, 6);
  EXPECT_FALSE(controller.apply(valid));
  EXPECT_EQ(controller.parameters().safety.workspace.min.x(), -10.0);
}

TEST(ParameterUpdate, NamesThatAreNoRowsAreRefused) {
  const std::string message =
      error_of([] { ci::ParameterUpdate::of(ci::Parameters{}, {"safety.max_sped"}); });
  EXPECT_NE(message.find("unknown parameter 'safety.max_sped'"), std::string::npos) << message;
  EXPECT_EQ(ci::ParameterUpdate::of(ci::Parameters{}, {"safety.max_speed"}).row_names().size(), 2u);
}

TEST(SafetySettings, AreTheSafetyLimitsPlausibilityAndPayloadRows) {
  EXPECT_TRUE(ci::is_safety_setting("safety.max_speed.translation"));
  EXPECT_TRUE(ci::is_safety_setting("limits.pose_error.translation"));
  EXPECT_TRUE(ci::is_safety_setting("plausibility.dt.max"));
  EXPECT_TRUE(ci::is_safety_setting("payload.mass"));
  EXPECT_FALSE(ci::is_safety_setting("stiffness.translation"));
  EXPECT_FALSE(ci::is_safety_setting("safetyx"));
  std::size_t count = 0;
  for (const ci::ParameterInfo& row : ci::parameter_table()) {
    count += ci::safety_settings()[ci::parameter_index(row)];
    EXPECT_EQ(ci::safety_settings()[ci::parameter_index(row)], ci::is_safety_setting(row.name))
        << row.name;
  }
  EXPECT_GT(count, 20u);
}
