// The control law through the controller: analytic springs, dampers and wrenches, nullspace,
// filters at several rates, saturations, clipping, torque and rate limits, start-up continuity.

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "cartesian_impedance/core/controller.hpp"
#include "support/bare_law.hpp"
#include "support/law_reference.hpp"
#include "support/random_cases.hpp"

namespace ci = cartesian_impedance;
using namespace random_cases;
using bare_law::bare_parameters;
using bare_law::cartesian_robot;
using bare_law::modelless_parameters;

namespace {

ci::Vector6d six(double a, double b, double c, double d, double e, double f) {
  return (ci::Vector6d() << a, b, c, d, e, f).finished();
}

// One unit in the last place of x: the resolution of a stored torque.
double ulp(double x) {
  return std::nextafter(std::abs(x), INFINITY) - std::abs(x);
}

}  // namespace

// --- the law on analytic cases
// --------------------------------------------------------------------

TEST(SpringLaw, TranslationAndRotationPushBackWithKTimesError) {
  ci::CartesianImpedanceController controller(6, bare_parameters());
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  controller.set_stiffness(six(100, 200, 300, 10, 20, 30));
  robot.pose.position += Eigen::Vector3d(0.01, -0.02, 0.03);
  robot.pose.orientation = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ());
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  const ci::Vector6d expected = six(-1.0, 4.0, -9.0, 0.0, 0.0, -3.0);
  EXPECT_LE((controller.torque() - expected).cwiseAbs().maxCoeff(), 1e-12);
}

// tau = -J^T K e on a random arm; 1e-12 relative covers the round-off of a 6 x n product.
TEST(SpringLaw, TorqueIsJacobianTransposeTimesSpringForce) {
  std::mt19937 rng(11);
  for (int n : {6, 7}) {
    ci::CartesianImpedanceController controller(n, bare_parameters());
    ci::RobotState robot = random_robot_state(n, rng);
    robot.dq.setZero();
    controller.start(robot);
    const ci::Vector6d k = six(800, 500, 300, 40, 30, 20);
    controller.set_stiffness(k);
    const ci::Vector6d offset = six(0.02, -0.01, 0.015, 0.05, -0.02, 0.03);
    const ci::Pose reference{robot.pose.position - offset.head<3>(),
                             Eigen::Quaterniond(Eigen::AngleAxisd(-offset.tail<3>().norm(),
                                                                  offset.tail<3>().normalized())) *
                                 robot.pose.orientation};
    controller.set_reference_pose(reference);
    ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
    const ci::JointVector expected = -robot.jacobian.transpose() * k.cwiseProduct(offset);
    EXPECT_LE((controller.state().pose_error - offset).cwiseAbs().maxCoeff(), 1e-14);
    EXPECT_LE((controller.torque() - expected).cwiseAbs().maxCoeff(), 1e-12 * expected.norm())
        << "n = " << n;
  }
}

// Stiffness in the end-effector frame: with the end effector turned 90 deg about z, its y axis is
// the base's -x axis, so a base-x error meets the end-effector y stiffness.
TEST(SpringLaw, EndEffectorFrameStiffnessRotatesWithTheTool) {
  ci::CartesianImpedanceController controller(6, bare_parameters());
  ci::RobotState robot = cartesian_robot();
  robot.pose.orientation = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ());
  controller.start(robot);
  controller.set_stiffness(six(100, 200, 300, 10, 20, 30), ci::Frame::end_effector);
  robot.pose.position.x() += 0.01;
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  EXPECT_LE((controller.torque() - six(-2.0, 0, 0, 0, 0, 0)).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(controller.state().stiffness_base()(0, 0), 200.0, 1e-12);
  EXPECT_NEAR(controller.state().stiffness_base()(1, 1), 100.0, 1e-12);
}

// D = 2 zeta sqrt(K) opposes the end-effector velocity.
TEST(SpringLaw, DampingOpposesVelocity) {
  ci::CartesianImpedanceController controller(6, bare_parameters());
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  controller.set_stiffness(six(100, 400, 900, 4, 16, 25));
  controller.set_damping_ratio(six(1, 0.5, 0.7, 1, 1, 2));
  robot.dq = six(0.1, 0.2, -0.1, 1.0, -1.0, 0.5);
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  const ci::Vector6d damping = six(20, 20, 42, 4, 8, 20);
  EXPECT_LE((controller.torque() + damping.cwiseProduct(robot.dq)).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(ScheduledImpedance, ExplicitFullDampingIsUsedUntilACommandReplacesIt) {
  // J = I: the torque is the Cartesian force itself, -K e - D v, with D not derivable from K.
  ci::CartesianImpedanceController controller(6, bare_parameters());
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  ci::ScheduledImpedance impedance;
  impedance.reference = robot.pose;
  impedance.reference.position += Eigen::Vector3d(0.01, -0.02, 0.0);
  impedance.stiffness = six(300, 300, 300, 20, 20, 20).asDiagonal();
  impedance.damping = six(50, 60, 70, 3, 4, 5).asDiagonal();
  impedance.damping(0, 1) = impedance.damping(1, 0) = 10.0;  // a coupled damper
  impedance.nullspace_q = robot.q;
  impedance.nullspace_stiffness = ci::JointVector::Zero(6);
  impedance.nullspace_damping = ci::JointVector::Zero(6);
  impedance.wrench = six(0, 0, 2, 0, 0, 0);
  controller.schedule(impedance);
  EXPECT_TRUE(controller.scheduled());
  robot.dq = six(0.1, -0.2, 0.05, 0.3, 0.0, -0.1);
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  ci::Vector6d error;
  error << robot.pose.position - impedance.reference.position, 0, 0, 0;
  const ci::Vector6d expected =
      -impedance.stiffness * error - impedance.damping * robot.dq + impedance.wrench;
  EXPECT_LE((controller.torque() - expected).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(controller.state().damping, impedance.damping);

  // A stiffness command ends the schedule: the damping follows the ratio rule again.
  controller.set_stiffness(six(400, 400, 400, 25, 25, 25));
  EXPECT_FALSE(controller.scheduled());
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  EXPECT_DOUBLE_EQ(controller.state().damping(0, 0), 2.0 * std::sqrt(400.0));
  EXPECT_EQ(controller.state().damping(0, 1), 0.0);
}

TEST(WrenchLaw, TorqueIsJacobianTransposeTimesWrenchInEitherFrame) {
  std::mt19937 rng(12);
  for (int n : {6, 7}) {
    ci::Parameters parameters = bare_parameters();
    parameters.stiffness.translation.setZero();
    parameters.stiffness.rotation.setZero();
    ci::CartesianImpedanceController controller(n, parameters);
    const ci::RobotState robot = random_robot_state(n, rng);
    controller.start(robot);
    const ci::Vector6d wrench = six(10, -5, 3, 0.5, 0.2, -1);
    controller.set_wrench(wrench, ci::Frame::base);
    ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
    const ci::JointVector expected = robot.jacobian.transpose() * wrench;
    EXPECT_LE((controller.state().tau_wrench - expected).cwiseAbs().maxCoeff(), 1e-12);

    controller.set_wrench(wrench, ci::Frame::end_effector);
    ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
    const Eigen::Matrix3d rotation = robot.pose.orientation.toRotationMatrix();
    ci::Vector6d wrench_base;
    wrench_base << rotation * wrench.head<3>(), rotation * wrench.tail<3>();
    const ci::JointVector expected_ee = robot.jacobian.transpose() * wrench_base;
    EXPECT_LE((controller.state().tau_wrench - expected_ee).cwiseAbs().maxCoeff(), 1e-12);
  }
}

// The nullspace torque drives q toward q_d but exerts no force at the end effector: J tau_ns = 0
// (lambda = 0), and it equals N tau_0 with tau_0 = -K_ns (q - q_d) - 2 zeta sqrt(K_ns) dq.
TEST(NullspaceLaw, HoldsConfigurationWithoutTaskSpaceForce) {
  std::mt19937 rng(13);
  ci::Parameters parameters = bare_parameters();
  parameters.nullspace.stiffness = ci::JointVector::Constant(1, 20.0);
  parameters.nullspace.damping_ratio = 0.8;
  ci::CartesianImpedanceController controller(7, parameters);
  const ci::RobotState robot = random_robot_state(7, rng);
  controller.start(robot);
  const ci::JointVector q_desired = robot.q + random_joints(7, rng, 0.3);
  controller.set_nullspace_target(q_desired);
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  const ci::JointVector& tau_ns = controller.state().tau_nullspace;
  const ci::Vector6d task = robot.jacobian * tau_ns;
  EXPECT_LE(task.cwiseAbs().maxCoeff(), 1e-10);
  const ci::JointVector tau_0 =
      -20.0 * (robot.q - q_desired) - 2.0 * 0.8 * std::sqrt(20.0) * robot.dq;
  ci::NullspaceProjector projector;
  const ci::JointVector expected =
      law_reference::nullspace_matrix(projector, robot.jacobian, 0.0) * tau_0;
  EXPECT_LE((tau_ns - expected).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_GT(tau_ns.norm(), 0.1) << "a redundant arm has a nullspace to act in";
}

// Zero stiffness is hand guiding: no spring, no damping from the Cartesian part.
TEST(Teaching, ZeroStiffnessGivesNoCartesianTorque) {
  std::mt19937 rng(14);
  ci::CartesianImpedanceController controller(7, bare_parameters());
  ci::RobotState robot = random_robot_state(7, rng);
  controller.start(robot);
  controller.set_stiffness(ci::Vector6d::Zero());
  robot.pose.position += Eigen::Vector3d(0.2, 0.1, -0.1);
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  EXPECT_EQ(controller.state().tau_cartesian.cwiseAbs().maxCoeff(), 0.0);
}

// The damping floor: with zero stiffness (teaching) the arm is still damped, by exactly the floor;
// where 2 zeta sqrt(K) is larger the floor changes nothing.
TEST(Teaching, MinimumDampingKeepsASoftArmDamped) {
  ci::Parameters parameters = bare_parameters();
  parameters.minimum_damping = {10.0, 1.0, 0.5};
  parameters.stiffness.translation = Eigen::Vector3d(0.0, 0.0, 400.0);  // z: D = 40 > floor
  parameters.stiffness.rotation.setZero();
  parameters.nullspace.stiffness = ci::JointVector::Constant(1, 0.0);
  ci::CartesianImpedanceController controller(6, parameters);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  robot.dq = six(0.1, -0.2, 0.3, 1.0, 0.5, -1.0);
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  const ci::Vector6d expected = -six(10, 10, 40, 1, 1, 1).cwiseProduct(robot.dq);
  EXPECT_LE((controller.state().tau_cartesian - expected).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(controller.state().damping.diagonal(), six(10, 10, 40, 1, 1, 1));
}

// --- filters ------------------------------------------------------------------------------------

// A step of every commanded quantity reaches 95 % after the configured 0.2 s at 250, 500 and
// 1000 Hz alike. The only error is floating-point accumulation over at most 200 steps (~1e-13).
class FilterRate : public ::testing::TestWithParam<double> {};

TEST_P(FilterRate, StepReachesConfiguredFractionAtConfiguredTime) {
  const double rate = GetParam();
  const double dt = 1.0 / rate;
  ci::Parameters parameters = bare_parameters();
  for (ci::FilterSettings* f : {&parameters.filter.pose, &parameters.filter.stiffness,
                                &parameters.filter.nullspace, &parameters.filter.wrench}) {
    *f = ci::FilterSettings{0.2, 0.95};
  }
  parameters.stiffness.translation.setConstant(100.0);
  parameters.stiffness.rotation.setConstant(10.0);
  parameters.nullspace.stiffness = ci::JointVector::Constant(1, 10.0);
  ci::CartesianImpedanceController controller(7, parameters);
  std::mt19937 rng(15);
  const ci::RobotState robot = random_robot_state(7, rng);
  controller.start(robot);
  // Let the wrench settle at its (zero) command first; start() left it at zero already.
  const ci::Pose start_pose = robot.pose;
  const Eigen::Vector3d axis = random_unit_vector(rng);
  controller.set_reference_pose(
      {start_pose.position + Eigen::Vector3d(0.1, 0, 0),
       Eigen::Quaterniond(Eigen::AngleAxisd(0.5, axis)) * start_pose.orientation});
  controller.set_stiffness(six(200, 200, 200, 50, 50, 50));
  controller.set_nullspace_target(robot.q + ci::JointVector::Constant(7, 0.2));
  controller.set_nullspace_stiffness(ci::JointVector::Constant(1, 30.0));
  controller.set_wrench(six(10, 0, 0, 0, 0, 0));

  const int steps = static_cast<int>(std::lround(0.2 * rate));
  for (int k = 0; k < steps; ++k) ASSERT_EQ(controller.update(robot, dt), ci::Status::ok);

  const ci::Targets& filtered = controller.state().filtered;
  const double tolerance = 1e-12;
  EXPECT_NEAR(filtered.pose.position.x() - start_pose.position.x(), 0.095, tolerance);
  EXPECT_NEAR(ci::orientation_error(filtered.pose.orientation, start_pose.orientation).norm(),
              0.475, 1e-9);
  EXPECT_NEAR(filtered.stiffness(0, 0), 195.0, 1e-9);
  EXPECT_NEAR(filtered.stiffness(3, 3), 10.0 + 0.95 * 40.0, 1e-9);
  EXPECT_NEAR(filtered.nullspace_q[0] - robot.q[0], 0.19, tolerance);
  EXPECT_NEAR(filtered.nullspace_stiffness[3], 29.0, 1e-9);
  EXPECT_NEAR(filtered.wrench[0], 9.5, 1e-9);
  // Damping follows the filtered stiffness: D = 2 sqrt(195) along x.
  EXPECT_NEAR(controller.state().damping_base()(0, 0), 2.0 * std::sqrt(195.0), 1e-9);
}

INSTANTIATE_TEST_SUITE_P(Rates, FilterRate, ::testing::Values(250.0, 500.0, 1000.0));

TEST(Filter, CanBeSwitchedOffPerQuantity) {
  ci::Parameters parameters = bare_parameters();
  parameters.filter.stiffness = {0.5, 0.95};  // only stiffness is filtered
  ci::CartesianImpedanceController controller(6, parameters);
  const ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  controller.set_reference_pose(
      {robot.pose.position + Eigen::Vector3d(0, 0, 0.05), robot.pose.orientation});
  controller.set_stiffness(six(1000, 1000, 1000, 10, 10, 10));
  controller.set_wrench(six(0, 3, 0, 0, 0, 0));
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  const ci::Targets& filtered = controller.state().filtered;
  EXPECT_EQ(filtered.pose.position, controller.state().commanded.pose.position);
  EXPECT_EQ(filtered.wrench, controller.state().commanded.wrench);
  EXPECT_LT(filtered.stiffness(0, 0), 600.0);
  EXPECT_GT(filtered.stiffness(0, 0), 500.0);
}

// --- saturation and clipping
// ----------------------------------------------------------------------

TEST(Saturation, CommandsAreClampedToUserLimits) {
  ci::Parameters parameters = bare_parameters();
  parameters.limits.stiffness.translation = {50.0, 1000.0};
  parameters.limits.stiffness.rotation = {5.0, 100.0};
  parameters.limits.damping_ratio = {0.3, 1.5};
  parameters.limits.nullspace_stiffness = {0.0, 40.0};
  parameters.limits.wrench = {10.0, 1.0};
  ci::CartesianImpedanceController controller(7, parameters);
  controller.set_stiffness(six(2000, 10, 500, 200, 1, 50));
  EXPECT_EQ(controller.state().commanded.stiffness.diagonal(), six(1000, 50, 500, 100, 5, 50));
  EXPECT_TRUE(controller.state().limits.stiffness_saturated);
  controller.set_damping_ratio(six(0.1, 1, 3, 1, 1, 1));
  EXPECT_EQ(controller.state().commanded.damping_ratio, six(0.3, 1, 1.5, 1, 1, 1));
  EXPECT_TRUE(controller.state().limits.damping_ratio_saturated);
  controller.set_nullspace_stiffness(ci::JointVector::Constant(1, 100.0));
  EXPECT_EQ(controller.state().commanded.nullspace_stiffness, ci::JointVector::Constant(7, 40.0));
  EXPECT_TRUE(controller.state().limits.nullspace_stiffness_saturated);
  // The wrench keeps its direction: (30, 40, 0) N becomes (6, 8, 0) N.
  controller.set_wrench(six(30, 40, 0, 0, 0, 0.5));
  EXPECT_LE((controller.state().commanded.wrench - six(6, 8, 0, 0, 0, 0.5)).norm(), 1e-12);
  EXPECT_TRUE(controller.state().limits.wrench_saturated);
  // Widening the limits lets the last request through.
  parameters = controller.parameters();
  parameters.limits.wrench = {100.0, 10.0};
  controller.set_parameters(parameters);
  EXPECT_LE((controller.state().commanded.wrench - six(30, 40, 0, 0, 0, 0.5)).norm(), 1e-12);
  EXPECT_FALSE(controller.state().limits.wrench_saturated);
}

// A flag belongs to its quantity: an unrelated command leaves it, a new command of that quantity
// sets it afresh.
TEST(Saturation, FlagsLastUntilTheirQuantityIsCommandedAgain) {
  ci::Parameters parameters = bare_parameters();
  parameters.limits.stiffness.translation = {0.0, 1000.0};
  ci::CartesianImpedanceController controller(7, parameters);
  controller.set_stiffness(six(2000, 500, 500, 50, 50, 50));
  EXPECT_TRUE(controller.state().limits.stiffness_saturated);
  controller.set_nullspace_stiffness(ci::JointVector::Constant(1, 5.0));
  controller.set_wrench(six(1, 0, 0, 0, 0, 0));
  EXPECT_TRUE(controller.state().limits.stiffness_saturated);
  controller.set_stiffness(six(800, 500, 500, 50, 50, 50));
  EXPECT_FALSE(controller.state().limits.stiffness_saturated);
}

TEST(Saturation, PoseErrorIsClippedKeepingDirection) {
  ci::Parameters parameters = bare_parameters();
  parameters.limits.pose_error = {0.05, 0.2};
  ci::CartesianImpedanceController controller(6, parameters);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  controller.set_stiffness(six(400, 400, 400, 30, 30, 30));
  robot.pose.position += Eigen::Vector3d(0.3, 0.4, 0.0);  // 0.5 m away
  robot.pose.orientation = Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitX());
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  const ci::ControllerState& state = controller.state();
  EXPECT_TRUE(state.limits.translation_error_clipped);
  EXPECT_TRUE(state.limits.rotation_error_clipped);
  EXPECT_LE((state.pose_error - six(0.03, 0.04, 0, 0.2, 0, 0)).norm(), 1e-12);
  EXPECT_LE((controller.torque() - six(-12, -16, 0, -6, 0, 0)).norm(), 1e-10);
}

// A spring the joints cannot deliver is scaled as a whole, keeping its direction: clipping each
// joint on its own would give (-5, 5, 0, 0, 0, -0.5), a force pointing 27 degrees away from the
// reference.
TEST(Saturation, JointTorqueBeyondTheBoundScalesTheSpringKeepingItsDirection) {
  ci::Parameters parameters = bare_parameters();
  parameters.limits.joint_torque = (ci::JointVector(6) << 5, 5, 5, 1, 1, 1).finished();
  ci::CartesianImpedanceController controller(6, parameters);
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  controller.set_stiffness(six(1000, 1000, 1000, 100, 100, 100));
  robot.pose.position += Eigen::Vector3d(0.01, -0.02, 0.0);  // -10 N, +20 N wanted
  robot.pose.orientation = Eigen::AngleAxisd(0.005, Eigen::Vector3d::UnitZ());  // -0.5 Nm
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  const ci::ActiveLimits& limits = controller.state().limits;
  EXPECT_TRUE(limits.joint_torque_saturated);
  EXPECT_EQ(limits.torque_shaping, ci::TorqueShaping::spring);
  // J = I: the largest scale that fits is min(5 / 10, 5 / 20, 1 / 0.5) = 0.25.
  EXPECT_NEAR(limits.torque_shaping_scale, 0.25, 1e-12);
  EXPECT_LE((controller.torque() - six(-2.5, 5, 0, 0, 0, -0.125)).norm(), 1e-12);
}

// --- torque rate
// ----------------------------------------------------------------------------------

// Over a long run with random command changes and a moving robot, no joint's torque ever changes
// by more than rate * dt in a cycle (up to one rounding of tau), and a limited joint moves the
// way the law wanted.
TEST(RateLimit, NeverExceededOverLongRandomRun) {
  std::mt19937 rng(16);
  for (int n : {6, 7}) {
    ci::Parameters parameters = modelless_parameters();
    // Random states that jump every 50 cycles are no arm's motion: the passivity controller
    // would read energy into them and halve the stiffness this run draws.
    parameters.safety.passivity.threshold = 0.0;
    parameters.limits.joint_torque = ci::JointVector::Constant(1, 1e4);
    parameters.limits.joint_torque_rate = random_joints(n, rng, 800.0).cwiseAbs().array() + 100.0;
    ci::CartesianImpedanceController controller(n, parameters);
    ci::RobotState robot = random_robot_state(n, rng);
    controller.start(robot, random_joints(n, rng, 20.0));
    int limited_cycles = 0;
    for (int k = 0; k < 20000; ++k) {
      if (k % 500 == 0) {
        controller.set_reference_pose(
            {robot.pose.position + 0.1 * random_unit_vector(rng),
             Eigen::Quaterniond(Eigen::AngleAxisd(uniform(rng, 0, 0.5), random_unit_vector(rng))) *
                 robot.pose.orientation});
        controller.set_stiffness(six(uniform(rng, 0, 3000), uniform(rng, 0, 3000),
                                     uniform(rng, 0, 3000), uniform(rng, 0, 300),
                                     uniform(rng, 0, 300), uniform(rng, 0, 300)));
        controller.set_wrench(six(uniform(rng, -20, 20), 0, uniform(rng, -20, 20), 0, 0, 1));
        controller.set_nullspace_target(robot.q + random_joints(n, rng, 0.3));
      }
      if (k % 50 == 0) robot = random_robot_state(n, rng);  // abrupt jumps in the measured state
      const double dt = uniform(rng, 0.0005, 0.004);
      const ci::JointVector previous = controller.torque();
      ASSERT_EQ(controller.update(robot, dt), ci::Status::ok);
      const ci::ControllerState& state = controller.state();
      const ci::JointVector change = state.tau - previous;
      for (int i = 0; i < n; ++i) {
        const double bound = parameters.limits.joint_torque_rate[i] * dt;
        ASSERT_LE(std::abs(change[i]), bound + 4 * ulp(state.tau[i]))
            << "joint " << i << " at cycle " << k;
      }
      if (state.limits.torque_rate_limited) {
        ++limited_cycles;
        const ci::JointVector wanted =
            state.tau_cartesian + state.tau_nullspace + state.tau_wrench - previous;
        for (int i = 0; i < n; ++i) ASSERT_GE(change[i] * wanted[i], 0.0) << "joint " << i;
      }
    }
    EXPECT_GT(limited_cycles, 1000) << "the run must exercise the limiter";
  }
}

// --- start
// ----------------------------------------------------------------------------------------

// start() takes the measured pose and q as targets and the torque the robot already receives as
// the previous command, so the first commands continue from it within the rate limit.
TEST(Start, FirstCommandsAreContinuous) {
  std::mt19937 rng(17);
  ci::Parameters parameters = modelless_parameters();
  parameters.limits.joint_torque_rate = ci::JointVector::Constant(1, 1000.0);
  ci::CartesianImpedanceController controller(7, parameters);
  const ci::RobotState robot = random_robot_state(7, rng);
  EXPECT_EQ(controller.update(robot, 0.001), ci::Status::not_started);
  EXPECT_EQ(controller.torque(), ci::JointVector::Zero(7));
  const ci::JointVector tau_previous = random_joints(7, rng, 10.0);
  controller.start(robot, tau_previous);
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  // Equal up to the rounding of one filter step, (1 - a) x + a x.
  EXPECT_LE(controller.state().pose_error.cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LE((controller.state().filtered.nullspace_q - robot.q).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LE((controller.torque() - tau_previous).cwiseAbs().maxCoeff(), 1.0 + 1e-12);
}

// --- frames change online without a jump
// ----------------------------------------------------------

TEST(FrameChange, FilteredStiffnessIsCarriedIntoTheNewFrame) {
  ci::Parameters parameters = modelless_parameters();
  parameters.filter.stiffness = {0.2, 0.95};
  parameters.stiffness.translation = Eigen::Vector3d(100, 300, 500);
  ci::CartesianImpedanceController controller(6, parameters);
  ci::RobotState robot = cartesian_robot();
  robot.pose.orientation = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ());
  controller.start(robot);
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  const ci::Matrix6d before = controller.state().stiffness_base();
  // Same numbers, now meant along the tool axes: base x meets tool y (300 N/m) eventually.
  parameters.stiffness.frame = ci::Frame::end_effector;
  controller.set_parameters(parameters);
  ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
  const double a = ci::filter_gain(0.001, 0.2, 0.95);
  EXPECT_NEAR(controller.state().stiffness_base()(0, 0), (1 - a) * before(0, 0) + a * 300.0, 1e-9);
  for (int k = 0; k < 2000; ++k) controller.update(robot, 0.001);
  EXPECT_NEAR(controller.state().stiffness_base()(0, 0), 300.0, 1e-6);
  EXPECT_NEAR(controller.state().stiffness_base()(1, 1), 100.0, 1e-6);
}
