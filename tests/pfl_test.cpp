// Power and force limiting after ISO/TS 15066 (safety.pfl), on a synthetic arm whose effective
// mass is known in closed form: six joints, J = I (joint i moves the end effector along axis i),
// M = diag(m), so the end effector's effective mass along a translation axis is that joint's m.

#include <gtest/gtest.h>

#include <cmath>

#include "cartesian_impedance/core/controller.hpp"

namespace ci = cartesian_impedance;

namespace {

ci::RobotState unit_arm(const ci::JointVector& masses) {
  ci::RobotState robot = ci::make_robot_state(6);
  robot.jacobian = ci::Jacobian::Identity(6, 6);
  robot.mass = masses.asDiagonal();
  return robot;
}

// v = F_T / sqrt(k mu), 1/mu = 1/m_H + 1/m_R.
double expected_speed(ci::BodyRegion region, double arm_mass) {
  const ci::BodyRegionLimits limits = ci::body_region_limits(region);
  const double mu = 1.0 / (1.0 / limits.mass + 1.0 / arm_mass);
  return limits.transient_force / std::sqrt(limits.spring_constant * mu);
}

}  // namespace

// The standard's published figures, as the table holds them: a few regions spelled out.
TEST(PowerAndForceLimiting, TheBodyRegionsCarryTheStandardsFigures) {
  const ci::BodyRegionLimits chest = ci::body_region_limits(ci::BodyRegion::chest);
  EXPECT_EQ(chest.quasi_static_force, 140.0);
  EXPECT_EQ(chest.transient_force, 280.0);
  EXPECT_EQ(chest.spring_constant, 25000.0);
  EXPECT_EQ(chest.mass, 40.0);
  const ci::BodyRegionLimits hand = ci::body_region_limits(ci::BodyRegion::hand);
  EXPECT_EQ(hand.quasi_static_force, 140.0);
  EXPECT_EQ(hand.spring_constant, 75000.0);
  EXPECT_EQ(hand.mass, 0.6);
  const ci::BodyRegionLimits skull = ci::body_region_limits(ci::BodyRegion::skull);
  EXPECT_EQ(skull.transient_force, skull.quasi_static_force) << "no transient contact allowed";
  EXPECT_EQ(ci::body_region_limits(ci::BodyRegion::none).transient_force, 0.0);
}

// The speed cap in force follows the effective mass along the motion: moving along x (joint 1,
// 2 kg) and along y (joint 2, 8 kg), the heavier direction is slower, each exactly the closed
// form; the force cap in force is the quasi-static limit; a configured cap that is tighter
// stays; with the region off nothing changes.
TEST(PowerAndForceLimiting, TheSpeedCapFollowsTheEffectiveMassAlongTheMotion) {
  const ci::JointVector masses = (ci::JointVector(6) << 2.0, 8.0, 4.0, 1.0, 1.0, 1.0).finished();
  ci::Parameters p;
  p.safety.pfl.body_region = ci::BodyRegion::chest;
  p.safety.max_force.force = 500.0;
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = unit_arm(masses);
  controller.start(robot);
  for (const int axis : {0, 1}) {
    robot.dq.setZero();
    robot.dq[axis] = 0.05;  // moving along this axis
    ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
    const ci::SafetyState& safety = controller.state().safety;
    EXPECT_NEAR(safety.pfl_effective_mass, masses[axis], 1e-9 * masses[axis]);
    EXPECT_NEAR(safety.pfl_speed_limit, expected_speed(ci::BodyRegion::chest, masses[axis]), 1e-9);
    EXPECT_EQ(safety.max_speed_in_force.translation, safety.pfl_speed_limit);
    EXPECT_EQ(safety.max_force_in_force.force, 140.0);
  }
  EXPECT_LT(expected_speed(ci::BodyRegion::chest, 8.0), expected_speed(ci::BodyRegion::chest, 2.0));

  // A configured speed cap below the region's speed stays in force.
  p.safety.max_speed.translation = 0.1;
  controller.set_parameters(p);
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  EXPECT_EQ(controller.state().safety.max_speed_in_force.translation, 0.1);

  p.safety.pfl.body_region = ci::BodyRegion::none;
  controller.set_parameters(p);
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  EXPECT_EQ(controller.state().safety.pfl_speed_limit, 0.0);
  EXPECT_EQ(controller.state().safety.max_force_in_force.force, 500.0);
}

// At rest with the reference ahead, the direction toward it counts; with neither a motion nor a
// reference ahead, the heaviest direction (the slowest speed). Without M(q), the arm counts as
// infinitely heavy: the region's own mass bounds the impact.
TEST(PowerAndForceLimiting, WithoutAMotionTheReferenceOrTheHeaviestDirectionCounts) {
  const ci::JointVector masses = (ci::JointVector(6) << 2.0, 8.0, 4.0, 1.0, 1.0, 1.0).finished();
  ci::Parameters p;
  p.safety.pfl.body_region = ci::BodyRegion::hand;
  ci::CartesianImpedanceController controller(6, p);
  ci::RobotState robot = unit_arm(masses);
  controller.start(robot);
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  EXPECT_NEAR(controller.state().safety.pfl_effective_mass, 8.0, 1e-9);
  ci::Pose ahead = robot.pose;
  ahead.position.z() += 0.1;
  controller.set_reference_pose(ahead);
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  EXPECT_NEAR(controller.state().safety.pfl_effective_mass, 4.0, 1e-9);

  robot.mass.resize(0, 0);
  p.dynamics.inertia_shaped_damping = false;
  controller.set_parameters(p);
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  const ci::BodyRegionLimits hand = ci::body_region_limits(ci::BodyRegion::hand);
  EXPECT_NEAR(controller.state().safety.pfl_speed_limit,
              hand.transient_force / std::sqrt(hand.spring_constant * hand.mass), 1e-9);
}
