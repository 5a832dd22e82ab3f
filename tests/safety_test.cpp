// The safety layer on analytic cases (parameters safety.* and payload.*): a 6-joint "Cartesian"
// robot with J = I, so joint torques are the wrench at the end effector and each cap's effect can
// be written down exactly. Closed-loop behaviour is in safety_behaviour_test.cpp, the energy
// tank's properties in energy_tank_test.cpp.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "cartesian_impedance/core/controller.hpp"
#include "support/bare_law.hpp"

namespace ci = cartesian_impedance;

namespace {

ci::Vector6d six(double a, double b, double c, double d, double e, double f) {
  return (ci::Vector6d() << a, b, c, d, e, f).finished();
}

// The bare law without damping (each test switches on what it checks).
ci::Parameters bare() {
  ci::Parameters p = bare_law::bare_parameters();
  p.damping_ratio.translation.setZero();
  p.damping_ratio.rotation.setZero();
  return p;
}

using bare_law::cartesian_robot;

constexpr double kDt = 0.001;

}  // namespace

// --- safety.max_force

// A reference 5 cm inside a surface at 3000 N/m plus a 20 N wrench into it asks for 170 N; the
// cap leaves 40 N in the same direction, split between the two in their proportion.
TEST(ForceCap, SpringAndWrenchPressAtMostTheCapInTheirDirection) {
  ci::Parameters p = bare();
  p.stiffness.translation.setConstant(3000.0);
  p.stiffness.rotation.setConstant(100.0);
  p.safety.max_force = {40.0, 5.0};
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  ci::Pose reference = robot.pose;
  reference.position.z() -= 0.05;
  reference.orientation = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX());  // 10 Nm wanted
  controller.set_reference_pose(reference);
  controller.set_wrench(six(0, 0, -20, 0, 0, 0));
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  const ci::SafetyState& safety = controller.state().safety;
  EXPECT_NEAR(safety.force_scale, 40.0 / 170.0, 1e-12);
  EXPECT_NEAR(safety.torque_scale, 0.5, 1e-9);
  const ci::Vector6d expected = six(0, 0, -40, 5, 0, 0);
  EXPECT_LE((controller.torque() - expected).norm(), 1e-9) << controller.torque().transpose();
  // Spring and wrench each keep their share: 150 : 20 of the 40 N.
  EXPECT_NEAR(controller.state().tau_wrench[2], -20.0 * 40.0 / 170.0, 1e-9);
  EXPECT_NEAR(controller.state().tau_cartesian[2], -150.0 * 40.0 / 170.0, 1e-9);

  // Off, the same command presses with all of it.
  p.safety.max_force = {0.0, 0.0};
  controller.set_parameters(p);
  controller.set_reference_pose(reference);
  controller.set_wrench(six(0, 0, -20, 0, 0, 0));
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.torque()[2], -170.0, 1e-9);
  EXPECT_EQ(controller.state().safety.force_scale, 1.0);
}

// The damping is not a press on the environment: it passes the cap.
TEST(ForceCap, DampingIsNotCapped) {
  ci::Parameters p = bare();
  p.minimum_damping.translation = 100.0;
  p.safety.max_force = {10.0, 0.0};
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  robot.dq = six(0.5, 0, 0, 0, 0, 0);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.torque()[0], -50.0, 1e-9);
}

// --- safety.max_speed

TEST(SpeedCap, TheReferenceMovesNoFasterThanTheCap) {
  ci::Parameters p = bare();
  p.safety.max_speed = {0.2, 0.5};
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  ci::Pose far = robot.pose;
  far.position.x() += 0.3;
  far.orientation = Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitZ());
  controller.set_reference_pose(far);
  for (int k = 1; k <= 100; ++k) {
    ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
    const ci::Pose& filtered = controller.state().filtered.pose;
    ASSERT_NEAR(filtered.position.x() - robot.pose.position.x(), 0.2 * kDt * k, 1e-12) << k;
    ASSERT_NEAR(filtered.orientation.angularDistance(robot.pose.orientation), 0.5 * kDt * k, 1e-9)
        << k;
    EXPECT_TRUE(controller.state().safety.reference_speed_limited);
  }
  // Without the cap (and without a filter) the reference is there at once.
  p.safety.max_speed = {0.0, 0.0};
  controller.set_parameters(p);
  controller.set_reference_pose(far);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.state().filtered.pose.position.x(), far.position.x(), 1e-15);
}

// Near the cap the spring stops pushing along the motion (linearly from 0.8 x the speed the
// governor holds, kSpeedCapAim x the cap, none there); the push across the motion stays.
TEST(SpeedCap, TheSpringStopsPushingAlongTheMotionAtTheCap) {
  ci::Parameters p = bare();
  p.stiffness.translation.setConstant(1000.0);
  p.safety.max_speed = {0.2, 0.0};
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  ci::Pose reference = robot.pose;
  reference.position += Eigen::Vector3d(0.01, 0.02, 0.0);  // 10 N along x, 20 N along y
  controller.set_reference_pose(reference);
  // The reference itself moves at the cap: 22 mm take 112 cycles.
  for (int k = 0; k < 200; ++k) ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  const double held = ci::CartesianImpedanceController::kSpeedCapAim * 0.2;
  for (const auto& [fraction, kept] :
       {std::pair{0.5, 1.0}, std::pair{0.8, 1.0}, std::pair{0.9, 0.5}, std::pair{1.0, 0.0}}) {
    const double speed = fraction * held;
    robot.dq = six(speed, 0, 0, 0, 0, 0);
    ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
    EXPECT_NEAR(controller.torque()[0], 10.0 * kept, 1e-9) << speed;
    EXPECT_NEAR(controller.torque()[1], 20.0, 1e-9) << speed;
    EXPECT_NEAR(controller.state().safety.translation_drive_scale, kept, 1e-9) << speed;
    EXPECT_FALSE(controller.state().safety.braking);
  }
  // A spring pulling against the motion is not a drive: it is kept whole at any speed.
  robot.dq = six(-0.3, 0, 0, 0, 0, 0);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.torque()[0], 10.0, 1e-9);
}

// A commanded wrench is a drive like the spring.
TEST(SpeedCap, TheCommandedWrenchStopsPushingAlongTheMotionAtTheCap) {
  ci::Parameters p = bare();
  p.safety.max_speed = {0.2, 0.0};
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  controller.set_wrench(six(30, 0, 0, 0, 0, 0));
  robot.dq = six(ci::CartesianImpedanceController::kSpeedCapAim * 0.2, 0, 0, 0, 0, 0);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.torque()[0], 0.0, 1e-9);
}

// Pushed beyond the cap from outside, the arm is braked with the law's damping strength on the
// speed beyond what the governor holds (kSpeedCapAim x the cap; without M(q), as here); the
// spring (here zero: teaching) adds nothing.
TEST(SpeedCap, ExcessSpeedIsBrakedWithDampingNotStiffness) {
  ci::Parameters p = bare();
  p.stiffness.translation.setZero();
  p.stiffness.rotation.setZero();
  p.minimum_damping = {40.0, 2.0, 0.0};
  p.safety.max_speed = {0.2, 1.0};
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  robot.dq = six(0.0, 0.3, 0.4, 0, 0, 1.5);  // 0.5 m/s, 1.5 rad/s
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_TRUE(controller.state().safety.braking);
  const double aim = ci::CartesianImpedanceController::kSpeedCapAim;
  const Eigen::Vector3d direction(0.0, 0.6, 0.8);
  const Eigen::Vector3d force =
      -40.0 * Eigen::Vector3d(0.0, 0.3, 0.4) - 40.0 * (0.5 - aim * 0.2) * direction;
  EXPECT_LE((controller.torque().head<3>() - force).norm(), 1e-9);
  EXPECT_NEAR(controller.torque()[5], -2.0 * 1.5 - 2.0 * (1.5 - aim * 1.0), 1e-9);
  // Below the cap only the damping acts.
  robot.dq = six(0.0, 0.1, 0.0, 0, 0, 0);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_FALSE(controller.state().safety.braking);
  EXPECT_NEAR(controller.torque()[1], -4.0, 1e-12);
}

// --- safety.workspace

TEST(Workspace, AReferenceOutsideTheBoxIsClippedIntoIt) {
  ci::Parameters p = bare();
  p.stiffness.translation.setConstant(100.0);
  p.safety.workspace.min = Eigen::Vector3d(0.0, -0.5, 0.2);
  p.safety.workspace.max = Eigen::Vector3d(0.8, 0.5, 1.0);
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  ci::Pose reference = robot.pose;
  reference.position = Eigen::Vector3d(1.2, 0.1, 0.0);
  controller.set_reference_pose(reference);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  const ci::ControllerState& state = controller.state();
  EXPECT_TRUE(state.safety.reference_clipped);
  EXPECT_EQ(state.filtered.pose.position, Eigen::Vector3d(0.8, 0.1, 0.2));
  EXPECT_EQ(state.commanded.pose.position, Eigen::Vector3d(0.8, 0.1, 0.2));
  // The spring pulls toward the clipped reference: (0.4, 0.1, -0.3) m at 100 N/m.
  EXPECT_LE((controller.torque().head<3>() - Eigen::Vector3d(40, 10, -30)).norm(), 1e-9);
}

// Outside the box a damped wall pushes the end effector back, with zero Cartesian stiffness too;
// its damper acts only on motion further out.
TEST(Workspace, AWallPushesTheEndEffectorBackAlsoWhileTeaching) {
  ci::Parameters p = bare();
  p.stiffness.translation.setZero();
  p.stiffness.rotation.setZero();
  p.safety.workspace.min = Eigen::Vector3d(-1.0, -1.0, 0.3);
  p.safety.workspace.max = Eigen::Vector3d(0.39, 1.0, 1.0);
  p.safety.workspace.stiffness = 2000.0;
  p.safety.workspace.damping = 150.0;
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();  // x = 0.4: 1 cm beyond the wall
  controller.start(robot);
  robot.dq = six(0.1, 0.2, 0, 0, 0, 0);  // moving out, and along the wall
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  const ci::SafetyState& safety = controller.state().safety;
  EXPECT_NEAR(safety.workspace_penetration.x(), 0.01, 1e-12);
  EXPECT_NEAR(controller.torque()[0], -2000.0 * 0.01 - 150.0 * 0.1, 1e-9);
  EXPECT_NEAR(controller.torque()[1], 0.0, 1e-12);
  EXPECT_NEAR(safety.wall_force.x(), controller.torque()[0], 1e-12);
  robot.dq = six(-0.1, 0, 0, 0, 0, 0);  // moving back in: the spring alone
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.torque()[0], -20.0, 1e-9);
  // Walls off: nothing.
  p.safety.workspace.stiffness = 0.0;
  controller.set_parameters(p);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.torque()[0], 0.0, 1e-12);
}

// --- payload

// J^T [m g; r x m g] with r = R c: a 1.5 kg load 10 cm along the tool's z, the tool tilted 90
// degrees about y so that its z points along the base's x.
TEST(Payload, TheDeclaredPayloadsGravityIsCompensated) {
  ci::Parameters p = bare();
  p.payload.mass = 1.5;
  p.payload.center_of_mass = Eigen::Vector3d(0.0, 0.0, 0.1);
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  robot.pose.orientation = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY());
  controller.start(robot);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  const double weight = 1.5 * ci::CartesianImpedanceController::kGravity;
  // r = (0.1, 0, 0): torque r x (0, 0, w) = (0, -0.1 w, 0).
  EXPECT_LE((controller.torque() - six(0, 0, weight, 0, -0.1 * weight, 0)).norm(), 1e-12);
  EXPECT_EQ(controller.state().tau_gravity, controller.torque());
}

TEST(Payload, ARunTimeChangeIsFilteredWithTheWrenchFilter) {
  ci::Parameters p = bare();
  p.filter.wrench = {0.1, 0.95};
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  p.payload.mass = 2.0;
  controller.set_parameters(p);
  for (int k = 0; k < 100; ++k) ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.state().safety.payload_mass, 0.95 * 2.0, 1e-9);
  EXPECT_NEAR(controller.torque()[2], 0.95 * 2.0 * ci::CartesianImpedanceController::kGravity,
              1e-9);
}

// With the damping shaped by the inertia, a 1 kg point mass at the flange adds 1 kg to every
// translational mode: M = I (1 kg per axis) becomes 2 kg, so d = 2 sqrt(2 k).
TEST(Payload, ItsMassEntersTheInertiaShapedDamping) {
  ci::Parameters p = bare();
  p.dynamics.inertia_shaped_damping = true;
  p.stiffness.translation.setConstant(800.0);
  p.damping_ratio.translation.setOnes();
  p.damping_ratio.rotation.setOnes();
  p.payload.mass = 1.0;
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = cartesian_robot();
  robot.mass = ci::JointMatrix::Identity(6, 6);
  controller.start(robot);
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.state().damping(0, 0), 2.0 * std::sqrt(2.0 * 800.0), 1e-9);
  p.payload.mass = 0.0;
  controller.set_parameters(p);
  for (int k = 0; k < 3; ++k) ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_NEAR(controller.state().damping(0, 0), 2.0 * std::sqrt(800.0), 1e-9);
}

// The Cartesian robot (J = I) held at `robot` by 1000 N/m and 100 Nm/rad, for the payload
// estimate: a sag of m g / 1000 carries m.
ci::CartesianImpedanceController payload_controller(const ci::RobotState& robot) {
  ci::Parameters p = bare();
  p.stiffness.translation.setConstant(1000.0);
  p.stiffness.rotation.setConstant(100.0);
  ci::CartesianImpedanceController controller(6, p);
  controller.start(robot);
  return controller;
}

// Held still, what the spring carries is read as a payload: 0.8 kg at r = (0.02, -0.03, .) in
// the base frame gives the spring force (0, 0, m g) and torque r x (0, 0, m g).
TEST(Payload, TheEstimateExplainsTheStaticWrench) {
  ci::RobotState robot = cartesian_robot();
  ci::CartesianImpedanceController controller = payload_controller(robot);
  const double mass = 0.8;
  const double weight = mass * ci::CartesianImpedanceController::kGravity;
  const Eigen::Vector3d r(0.02, -0.03, 0.0);
  const Eigen::Vector3d torque = r.cross(Eigen::Vector3d(0, 0, weight));
  // The sag that makes the spring carry it: e = -F / K.
  robot.pose.position.z() -= weight / 1000.0;
  robot.pose.orientation =
      Eigen::Quaterniond(Eigen::AngleAxisd(torque.norm() / 100.0, -torque.normalized()));
  const int settle = static_cast<int>(ci::CartesianImpedanceController::kPayloadSettleTime / kDt);
  for (int k = 0; k < settle - 2; ++k) ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_FALSE(controller.state().safety.payload_estimate_valid);
  for (int k = 0; k < 3; ++k) ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  const ci::SafetyState& safety = controller.state().safety;
  EXPECT_TRUE(safety.payload_estimate_valid);
  EXPECT_NEAR(safety.payload_estimate_mass, mass, 1e-9);
  // In the end-effector frame (rotated by the small sag of the orientation).
  const Eigen::Vector3d expected = robot.pose.orientation.inverse() * r;
  EXPECT_LE((safety.payload_estimate_center_of_mass - expected).norm(), 1e-3 * r.norm());
  // Moving: no estimate.
  robot.dq[0] = 0.1;
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_FALSE(controller.state().safety.payload_estimate_valid);
}

// A real arm's velocities carry noise: 4 mm/s of white noise on each axis of the flange (about
// 7 mm/s in all, above kStillSpeed) does not read as motion, and the estimate settles as it does
// without; a real motion still ends it at once.
TEST(Payload, NoiseInTheVelocitiesDoesNotReadAsMotion) {
  ci::RobotState robot = cartesian_robot();
  ci::CartesianImpedanceController controller = payload_controller(robot);
  const double mass = 0.8;
  robot.pose.position.z() -= mass * ci::CartesianImpedanceController::kGravity / 1000.0;
  std::mt19937 random(5);
  std::normal_distribution<double> noise(0.0, 0.004);
  const int settle = static_cast<int>(ci::CartesianImpedanceController::kPayloadSettleTime / kDt);
  double fastest = 0.0;
  for (int k = 0; k < settle + 100; ++k) {
    for (int i = 0; i < 6; ++i) robot.dq[i] = noise(random);
    fastest = std::max(fastest, robot.dq.head<3>().norm());
    ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  }
  EXPECT_GT(fastest, 2.0 * ci::CartesianImpedanceController::kStillSpeed);  // noise, not rest
  EXPECT_TRUE(controller.state().safety.payload_estimate_valid);
  EXPECT_NEAR(controller.state().safety.payload_estimate_mass, mass, 1e-6);
  robot.dq.setZero();
  robot.dq[2] = 0.06;
  ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
  EXPECT_FALSE(controller.state().safety.payload_estimate_valid);
}

// --- validation of the new rows' relations

TEST(SafetyParameters, AnInvertedBoxAndAnOverfullTankAreRefusedNamingBothValues) {
  ci::Parameters p;
  p.safety.workspace.min.y() = 0.5;
  p.safety.workspace.max.y() = 0.2;
  try {
    ci::validate(p);
    FAIL() << "an inverted box was accepted";
  } catch (const ci::Error& error) {
    EXPECT_EQ(std::string(error.what()),
              "safety.workspace.min.y = 0.5 m is greater than safety.workspace.max.y = 0.2 m");
  }
  p = ci::Parameters{};
  p.safety.energy_tank.initial = 1.0;
  try {
    ci::validate(p);
    FAIL() << "a tank fuller than its capacity was accepted";
  } catch (const ci::Error& error) {
    EXPECT_EQ(std::string(error.what()),
              "safety.energy_tank.initial = 1 J is greater than safety.energy_tank.capacity = "
              "0.005 J");
  }
  // A rejected set changes nothing.
  ci::CartesianImpedanceController controller(6);
  EXPECT_THROW(controller.set_parameters(p), ci::Error);
  EXPECT_EQ(controller.parameters().safety.energy_tank.initial, 0.005);
}
