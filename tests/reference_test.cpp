// Cross-check of the library's control law against the plainly written SVD-based reference in
// support/reference_controller.hpp, on random cases.

#include <gtest/gtest.h>

#include <random>

#include "cartesian_impedance/core/controller.hpp"
#include "support/random_cases.hpp"
#include "support/reference_controller.hpp"

namespace ci = cartesian_impedance;
using namespace random_cases;

namespace {

// Parameters with every filter off and every limit out of the way, so one update() evaluates the
// bare law on the commanded targets.
ci::Parameters bare_law_parameters() {
  ci::Parameters p;
  for (ci::FilterSettings* filter :
       {&p.filter.pose, &p.filter.stiffness, &p.filter.nullspace, &p.filter.wrench}) {
    filter->time = 0.0;
  }
  p.limits.stiffness.translation.max = 1e5;
  p.limits.stiffness.rotation.max = 1e4;
  p.limits.damping_ratio.max = 10.0;
  p.limits.nullspace_stiffness.max = 1e4;
  p.limits.wrench = {1e4, 1e3};
  p.limits.pose_error = {10.0, M_PI};
  p.limits.joint_torque = ci::JointVector::Constant(1, 1e4);
  p.limits.joint_torque_rate = ci::JointVector::Constant(1, 1e6);
  p.dynamics.inertia_shaped_damping = false;  // the published controller's unit-mass damping
  p.minimum_damping = {0.0, 0.0, 0.0};        // the reference has no damping floor
  return p;
}

double max_abs_difference(const ci::JointVector& a, const Eigen::VectorXd& b) {
  return (Eigen::VectorXd(a) - b).cwiseAbs().maxCoeff();
}

}  // namespace

// The tolerance: both sides solve with normal equations or an SVD of a Jacobian whose condition
// number is below 100, so their round-off is at most about cond^2 * eps * |terms| ~ 1e4 * 2.2e-16
// * 1e3 Nm ~ 2e-9 in the worst corner; 1e-10 relative to the largest torque term is what random
// cases of this size reach in practice with margin (the largest seen is below 1e-12).
TEST(ReferenceCrossCheck, LawMatchesSvdReferenceOnThousandRandomCases) {
  std::mt19937 rng(20261121);
  double worst_relative = 0.0;
  for (int trial = 0; trial < 1000; ++trial) {
    const int n = trial % 3 == 0 ? 6 : (trial % 3 == 1 ? 7 : 4 + trial % 5);
    ci::Parameters parameters = bare_law_parameters();
    parameters.stiffness.frame = trial % 2 ? ci::Frame::end_effector : ci::Frame::base;
    parameters.wrench.frame = trial % 4 < 2 ? ci::Frame::end_effector : ci::Frame::base;
    parameters.nullspace.pseudo_inverse_damping = trial % 5 == 0 ? 0.0 : uniform(rng, 0.0, 0.3);
    parameters.nullspace.damping_ratio = uniform(rng, 0.0, 2.0);
    parameters.wrench.force = 20.0 * random_unit_vector(rng);
    parameters.wrench.torque = 2.0 * random_unit_vector(rng);
    for (int i = 0; i < 3; ++i) {
      parameters.stiffness.translation[i] = uniform(rng, 0.0, 3000.0);
      parameters.stiffness.rotation[i] = uniform(rng, 0.0, 300.0);
      parameters.damping_ratio.translation[i] = uniform(rng, 0.0, 2.0);
      parameters.damping_ratio.rotation[i] = uniform(rng, 0.0, 2.0);
    }
    parameters.nullspace.stiffness = random_joints(n, rng, 50.0).cwiseAbs();

    const ci::RobotState robot = random_robot_state(n, rng);
    ci::CartesianImpedanceController controller(n, parameters);
    controller.start(robot);
    const bool full_stiffness = trial % 3 == 2;
    if (full_stiffness) controller.set_stiffness_matrix(random_stiffness(rng));
    // Reference orientations up to 3 rad away, so that the angle-axis of the reference is unique.
    const Eigen::Quaterniond offset(
        Eigen::AngleAxisd(uniform(rng, 0.0, 3.0), random_unit_vector(rng)));
    const ci::Pose reference{robot.pose.position + 0.2 * random_unit_vector(rng),
                             offset * robot.pose.orientation};
    controller.set_reference_pose(reference);
    const ci::JointVector q_desired = robot.q + random_joints(n, rng, 0.5);
    controller.set_nullspace_target(q_desired);
    // dt = 10 ms: the rate limit (1e6 Nm/s, its largest valid value) then allows any change up
    // to the torque limit, so tau is the bare law's sum.
    ASSERT_EQ(controller.update(robot, 0.01), ci::Status::ok);

    const ci::Targets& commanded = controller.state().commanded;
    reference::Targets targets;
    targets.position = reference.position;
    targets.orientation = reference.orientation;
    targets.stiffness = commanded.stiffness;
    targets.damping_ratio = commanded.damping_ratio;
    targets.nullspace_q = q_desired;
    targets.nullspace_stiffness = commanded.nullspace_stiffness;
    targets.nullspace_damping_ratio = parameters.nullspace.damping_ratio;
    targets.wrench = commanded.wrench;
    const reference::Torques expected =
        reference::law(robot.q, robot.dq, robot.pose.position, robot.pose.orientation,
                       robot.jacobian, targets, controller.parameters());

    const ci::ControllerState& state = controller.state();
    const double scale =
        std::max({1.0, expected.cartesian.cwiseAbs().maxCoeff(),
                  expected.nullspace.cwiseAbs().maxCoeff(), expected.wrench.cwiseAbs().maxCoeff()});
    const double tolerance = 1e-10 * scale;
    SCOPED_TRACE("trial " + std::to_string(trial) + ", n = " + std::to_string(n));
    EXPECT_LE(max_abs_difference(state.tau_cartesian, expected.cartesian), tolerance);
    EXPECT_LE(max_abs_difference(state.tau_nullspace, expected.nullspace), tolerance);
    EXPECT_LE(max_abs_difference(state.tau_wrench, expected.wrench), tolerance);
    EXPECT_LE(max_abs_difference(state.tau, expected.total), tolerance);
    worst_relative =
        std::max(worst_relative, max_abs_difference(state.tau, expected.total) / scale);
  }
  RecordProperty("worst_relative_difference", std::to_string(worst_relative));
}

// With filters and limits on, the library and the reference controller agree cycle by cycle.
TEST(ReferenceCrossCheck, FilteredLimitedRunMatchesReferenceController) {
  std::mt19937 rng(7);
  const int n = 7;
  ci::Parameters parameters;
  parameters.minimum_damping = {0.0, 0.0, 0.0};  // the reference has no damping floor
  parameters.dynamics.inertia_shaped_damping = false;
  parameters.limits.pose_error = {10.0, M_PI};
  parameters.limits.joint_torque = ci::JointVector::Constant(1, 30.0);
  parameters.limits.joint_torque_rate = ci::JointVector::Constant(1, 400.0);
  // The reference has no passivity controller, and the random states are no arm's motion.
  parameters.safety.passivity.threshold = 0.0;
  ci::RobotState robot = random_robot_state(n, rng);
  ci::CartesianImpedanceController controller(n, parameters);
  reference::Controller baseline(n, parameters);
  controller.start(robot);
  baseline.start(robot.q, robot.pose.position, robot.pose.orientation);

  const ci::Pose reference{
      robot.pose.position + Eigen::Vector3d(0.05, -0.02, 0.03),
      Eigen::Quaterniond(Eigen::AngleAxisd(0.4, random_unit_vector(rng))) * robot.pose.orientation};
  controller.set_reference_pose(reference);
  baseline.commanded().position = reference.position;
  baseline.commanded().orientation = reference.orientation;
  const ci::Vector6d wrench = (ci::Vector6d() << 5, -3, 2, 0.3, 0.1, -0.2).finished();
  controller.set_wrench(wrench);
  baseline.commanded().wrench = wrench;

  bool rate_limited = false;
  for (int k = 0; k < 2000; ++k) {
    robot.q += 0.001 * robot.dq;
    robot.dq = 0.3 * Eigen::VectorXd::Constant(n, std::sin(0.005 * k));
    ASSERT_EQ(controller.update(robot, 0.001), ci::Status::ok);
    const Eigen::VectorXd expected = baseline.update(robot.q, robot.dq, robot.pose.position,
                                                     robot.pose.orientation, robot.jacobian, 0.001);
    rate_limited |= controller.state().limits.torque_rate_limited;
    ASSERT_LE(max_abs_difference(controller.torque(), expected), 1e-9) << "cycle " << k;
  }
  EXPECT_TRUE(rate_limited) << "the run should exercise the rate limiter";
}
