// PolicyInterface: a policy's normalised action turned into a control loop's commands (reference
// increment within the leash, stiffness, wrench), and the robot part of its observation, checked
// against the model and against the physics of a pushed arm.

#include "cartesian_impedance/loop/policy_interface.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <string>

#include "cartesian_impedance/core/error.hpp"
#include "support/errors.hpp"
#include "support/model_simulation.hpp"
#include "support/robots.hpp"

namespace ci = cartesian_impedance;
using ci::PolicyInterface;
using ci::Vector6d;
using test_errors::error_of;

namespace {

// The Panda at its ready pose under a started loop; `run` advances the model simulation with
// the loop's torque.
struct PandaRig {
  ci::RobotModel model = robots::panda();
  ci::Parameters parameters;
  ci::ControlLoop loop{model, parameters};
  model_simulation::Simulation sim{model, robots::panda_ready()};

  PandaRig() { loop.start(sim.q, sim.dq); }

  void run(double seconds) {
    for (int k = 0; k < static_cast<int>(seconds * 1000.0 + 0.5); ++k) {
      sim.step(loop.step(sim.q, sim.dq, 0.001), 0.001);
    }
  }
  ci::Pose measured() const { return loop.latest_state().controller.pose; }
};

PolicyInterface::Action action_of(std::initializer_list<double> values) {
  PolicyInterface::Action action(static_cast<Eigen::Index>(values.size()));
  Eigen::Index i = 0;
  for (double value : values) action[i++] = value;
  return action;
}

}  // namespace

TEST(PolicyInterface, StiffnessRangeIsLoweredToTheParametersLimits) {
  const ci::RobotModel model = robots::panda();
  ci::Parameters parameters;
  parameters.limits.stiffness.translation.max = 1500.0;
  parameters.limits.wrench.force = 10.0;
  const PolicyInterface policy(model, parameters, /*wrench=*/true);
  EXPECT_EQ(policy.action_size(), 18);
  EXPECT_EQ(policy.observation_size(), 2 * 7 + 32);
  EXPECT_EQ(policy.stiffness_high(), (Vector6d() << 1500, 1500, 1500, 150, 150, 150).finished());
  EXPECT_EQ(policy.stiffness_low(), (Vector6d() << 100, 100, 100, 5, 5, 5).finished());
  EXPECT_EQ(policy.max_force(), 10.0);
  EXPECT_EQ(policy.max_torque(), 3.0);
  // No leash given: the pose error limits.
  EXPECT_EQ(policy.leash()[0], parameters.limits.pose_error.translation);
  EXPECT_EQ(policy.leash()[1], parameters.limits.pose_error.rotation);
  // -1, 0, +1 of the stiffness part: low, the middle, high; and back.
  const PolicyInterface::Action action =
      action_of({0, 0, 0, 0, 0, 0, -1, 0, 1, -1, 0, 1, 0, 0, 0, 0, 0, 0});
  const Vector6d stiffness = policy.stiffness(action);
  EXPECT_EQ(stiffness, (Vector6d() << 100, 800, 1500, 5, 77.5, 150).finished());
  EXPECT_TRUE(policy.stiffness_action(stiffness).isApprox(action.segment<6>(6), 1e-15));
}

TEST(PolicyInterface, CheckClipsAndNamesTheElementThatIsNotFinite) {
  const PolicyInterface policy(robots::panda(), ci::Parameters{}, false);
  Eigen::VectorXd action = Eigen::VectorXd::Zero(12);
  action[0] = 3.0;
  action[7] = -2.0;
  const PolicyInterface::Action checked = policy.check(action);
  EXPECT_EQ(checked[0], 1.0);
  EXPECT_EQ(checked[7], -1.0);
  action[10] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(error_of([&] { policy.check(action); }),
            "action[10] = nan is not finite; expected a value in [-1, 1] (stiffness.rotation.y)");
  EXPECT_NE(error_of([&] {
              policy.check(Eigen::VectorXd::Zero(18));
            }).find("action has 18 values, expected 12 (translation [0:3]"),
            std::string::npos);
}

TEST(PolicyInterface, LimitsThatMakeNoSenseAreRefusedByName) {
  const ci::RobotModel model = robots::panda();
  ci::PolicyActionLimits limits;
  limits.stiffness_translation = {300.0, 200.0};
  EXPECT_EQ(error_of([&] { PolicyInterface(model, ci::Parameters{}, false, limits); }),
            "action limits: stiffness_translation = [300, 200] has min > max");
  limits = {};
  limits.max_translation_step = -0.01;
  EXPECT_EQ(error_of([&] { PolicyInterface(model, ci::Parameters{}, false, limits); }),
            "action limits: max_translation_step = -0.01 must be finite and >= 0");
  limits = {};
  limits.reference_leash = std::array<double, 2>{0.05, 0.0};
  EXPECT_EQ(error_of([&] { PolicyInterface(model, ci::Parameters{}, false, limits); }),
            "action limits: reference_leash[1] (rotation) = 0 must be finite and > 0");
}

// An increment moves the reference by action x step in translation and by the rotation vector
// action x step in rotation, in the base frame; the stiffness and the wrench reach the controller.
TEST(PolicyInterface, ApplyMovesTheReferenceAndSendsStiffnessAndWrench) {
  PandaRig rig;
  rig.run(0.01);
  PolicyInterface policy(rig.model, rig.parameters, /*wrench=*/true);
  const ci::Pose start = rig.measured();
  policy.reset(start);
  const PolicyInterface::Action action =
      action_of({0.5, -1, 0.2, 0, 0, 1, 1, 1, 1, 1, 1, 1, 0, 0, -0.5, 0, 0, 0});
  policy.apply(action, rig.loop, rig.measured());
  const ci::Pose& reference = policy.reference();
  EXPECT_TRUE(
      reference.position.isApprox(start.position + Eigen::Vector3d(0.005, -0.01, 0.002), 1e-15));
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitZ()));
  EXPECT_NEAR(reference.orientation.angularDistance(turn * start.orientation), 0.0, 1e-12);
  EXPECT_GE(reference.orientation.w(), 0.0);

  rig.run(0.001);  // the loop takes the commands
  const ci::ControllerState& state = rig.loop.latest_state().controller;
  EXPECT_TRUE(state.commanded.pose.position.isApprox(reference.position, 1e-15));
  EXPECT_EQ(state.commanded.stiffness.diagonal(),
            (Vector6d() << 2000, 2000, 2000, 150, 150, 150).finished());
  EXPECT_EQ(state.commanded.wrench, (Vector6d() << 0, 0, -15, 0, 0, 0).finished());
}

// A policy that keeps pushing against something cannot wind the reference up: it stays within
// the leash of the measured pose.
TEST(PolicyInterface, TheReferenceStaysOnTheLeashOfTheMeasuredPose) {
  PandaRig rig;
  rig.run(0.01);
  ci::PolicyActionLimits limits;
  limits.reference_leash = std::array<double, 2>{0.03, 0.2};
  PolicyInterface policy(rig.model, rig.parameters, false, limits);
  ci::Pose measured = rig.measured();
  policy.reset(measured);
  const PolicyInterface::Action action = action_of({1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0});
  for (int k = 0; k < 10; ++k) policy.apply(action, rig.loop, measured);  // arm held in place
  EXPECT_NEAR((policy.reference().position - measured.position).norm(), 0.03, 1e-12);
  EXPECT_NEAR((policy.reference().position - measured.position).normalized().x(), 1.0, 1e-12);
  EXPECT_NEAR(policy.reference().orientation.angularDistance(measured.orientation), 0.2, 1e-12);
  // Ten steps of 0.01 m without the leash would be 0.1 m.
}

// The observation's layout, against the model: q, dq, the flange pose, J dq, the reference and
// the stiffness in force.
TEST(PolicyInterface, ObservationIsTheStateInItsDocumentedLayout) {
  PandaRig rig;
  rig.sim.dq.setConstant(0.1);
  rig.run(0.05);
  PolicyInterface policy(rig.model, rig.parameters, false);
  policy.reset(rig.measured());
  const ci::LoopState state = rig.loop.latest_state();
  Eigen::VectorXd observation(policy.observation_size());
  policy.observe(state, observation);
  ci::ModelWorkspace workspace(rig.model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  ASSERT_TRUE(workspace.compute(state.q, state.dq, kinematics, false));
  EXPECT_EQ(observation.head(7), state.q);
  EXPECT_EQ(observation.segment(7, 7), state.dq);
  EXPECT_EQ(observation.segment<3>(14), state.controller.pose.position);
  const Eigen::Quaterniond orientation(observation[20], observation[17], observation[18],
                                       observation[19]);
  EXPECT_NEAR(orientation.angularDistance(state.controller.pose.orientation), 0.0, 1e-12);
  EXPECT_GE(observation[20], 0.0);
  EXPECT_TRUE(observation.segment<6>(21).isApprox(kinematics.jacobian * state.dq, 1e-12));
  EXPECT_GT(observation.segment<6>(21).norm(), 0.01);  // it moves
  EXPECT_EQ(observation.segment<3>(33), policy.reference().position);
  EXPECT_EQ(observation.segment<6>(40), state.controller.stiffness_base().diagonal());
}

// At rest against a push F at the flange, the spring balances it: tau_cartesian = -J^T F, so the
// estimate -(J^T)^+ (tau_cartesian + tau_wrench) is F (the nullspace torque has no part in J^T's
// range). Wrong sign or zero torque would read -F or 0.
TEST(PolicyInterface, ExternalWrenchEstimateReadsAPushOnTheFlangeAtRest) {
  PandaRig rig;
  rig.run(0.01);
  PolicyInterface policy(rig.model, rig.parameters, false);
  const Vector6d push = (Vector6d() << 6, 0, -10, 0, 0.5, 0).finished();
  for (int k = 0; k < 4000; ++k) {  // the push follows the flange: J(q)^T F at each step
    rig.sim.external = rig.sim.jacobian().transpose() * push;
    rig.run(0.001);
  }
  ASSERT_LT(rig.sim.dq.norm(), 1e-5);
  Eigen::VectorXd observation(policy.observation_size());
  policy.observe(rig.loop.latest_state(), observation);
  // The arm still creeps (|dq| < 1e-5 rad/s through D ~ 100 N s/m): far below 0.01 N.
  EXPECT_TRUE(((observation.segment<6>(27) - push).array().abs() < 0.01).all())
      << observation.segment<6>(27).transpose();
}
