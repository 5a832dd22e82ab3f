// ControlLoop::step() allocates nothing with every option on: dynamics (gravity compensation,
// inertia-shaped damping, dynamically consistent projector), joint-limit avoidance, a trajectory
// being executed, commands arriving through the inbox, the state being published, and bad input;
// and with every part of the safety layer acting.

#include <gtest/gtest.h>

#include <algorithm>

#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/loop/policy_interface.hpp"
#include "support/allocation_counter.hpp"
#include "support/model_simulation.hpp"
#include "support/safety_caps.hpp"

namespace ci = cartesian_impedance;

TEST(LoopAllocation, StepAllocatesNothingWithEveryOptionOn) {
  const ci::RobotModel model = ci::RobotModel::from_urdf_file(
      std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.urdf", "panda_link0",
      "panda_link8");
  ci::Parameters parameters;
  parameters.dynamics.gravity_compensation = true;
  parameters.dynamics.inertia_shaped_damping = true;
  parameters.dynamics.dynamically_consistent_nullspace = true;
  parameters.joint_limit_avoidance = {0.3, 20.0};
  parameters.stiffness.frame = ci::Frame::end_effector;
  parameters.wrench.frame = ci::Frame::end_effector;
  ci::ControlLoop loop(model, parameters);
  ci::JointVector q(7);
  q << 0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4;
  model_simulation::Simulation sim(model, q, /*firmware_gravity=*/false);
  loop.start(sim.q, sim.dq);

  ci::JointTrajectory trajectory;
  trajectory.joint_names = model.joint_names();
  for (int k = 1; k <= 50; ++k) {
    ci::JointVector point = q;
    point[0] += 0.01 * k;
    // Into the joint-limit margin of joint 6 (3.6 rad) over 2 s, within its URDF speed limit.
    point[5] = q[5] + (3.6 - q[5]) * std::min(1.0, k / 20.0);
    trajectory.times.push_back(0.1 * k);
    trajectory.positions.emplace_back(point.data(), point.data() + 7);
  }
  loop.execute_trajectory(trajectory);
  const ci::Command wrench = ci::Wrench{(ci::Vector6d() << 2, 0, -3, 0, 0, 0).finished()};
  const ci::Command stiffness =
      ci::Stiffness::diagonal((ci::Vector6d() << 800, 800, 800, 60, 60, 60).finished());

  long allocations = 0;
  for (int k = 0; k < 6000; ++k) {
    if (k % 1000 == 10) {  // commands are validated and queued outside the counted step
      loop.send(wrench);
      loop.send(stiffness);
    }
    allocation_counter::Scope scope;
    const ci::JointVector& tau = loop.step(sim.q, sim.dq, 0.001);
    allocations += scope.allocations();
    sim.step(tau, 0.001);
  }
  ci::JointVector bad = sim.q;
  bad[2] = std::nan("");
  allocation_counter::Scope scope;
  for (int k = 0; k < 10; ++k) loop.step(bad, sim.dq, 0.001);
  loop.step(sim.q, sim.dq, -1.0);
  allocations += scope.allocations();

  EXPECT_EQ(allocations, 0);
  EXPECT_GE(loop.state().commands_applied, 12u);
  EXPECT_NE(loop.state().trajectory.state, ci::TrajectoryState::idle);
  EXPECT_GT(loop.state().controller.tau_gravity.norm(), 1.0);
}

// The safety layer allocates nothing either, with every part of it acting (support/
// safety_caps.hpp): the flange outside a small workspace box and moving further out, faster
// than the speed caps, the force caps below spring + wrench, the energy tank short of a stiffness
// raise, a payload declared; then held still, so the payload estimate runs too. The joints move
// as commanded (q integrates dq), so the speed is above the caps whatever the torque.
TEST(LoopAllocation, StepAllocatesNothingWithEverySafetyCapActing) {
  const ci::RobotModel model = ci::RobotModel::from_urdf_file(
      std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.urdf", "panda_link0",
      "panda_link8");
  ci::JointVector q(7);
  q << 0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4;
  ci::JointVector dq = ci::JointVector::Constant(7, 0.01);
  const safety_caps::Scene scene = safety_caps::scene(model, q, dq);
  ci::ControlLoop loop(model, scene.parameters);
  loop.start(scene.start, dq);
  for (const ci::Command& command : scene.commands) loop.send(command);

  safety_caps::Acted moving, still;
  long allocations = 0;
  int failed = 0;
  const auto step = [&](safety_caps::Acted& acted) {
    allocation_counter::Scope scope;
    loop.step(q, dq, 0.001);
    allocations += scope.allocations();
    if (loop.state().controller.status != ci::Status::ok) ++failed;
    acted.record(loop.state().controller.safety);
    q += 0.001 * dq;
  };
  for (int k = 0; k < 2000; ++k) step(moving);
  dq.setZero();
  // kPayloadSettleTime (0.5 s) still, and some more.
  for (int k = 0; k < 700; ++k) step(still);

  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(failed, 0) << "cycles not ok, the last: "
                       << ci::to_string(loop.state().controller.fault);
  EXPECT_EQ(moving.missing(false), "") << "these parts of the safety layer never acted";
  EXPECT_TRUE(still.payload_estimate) << "the payload estimate never became valid";
  EXPECT_GE(loop.state().commands_applied, 3u);
}

// A policy's step at 20 Hz: the action sent as commands (reference, stiffness, wrench; a sender's
// validation may allocate, outside the cycle), 50 cycles of the loop, and the observation read from
// the published state. Neither the cycles nor the observation (its SVD sized for the arm once)
// allocate.
TEST(LoopAllocation, CyclesUnderAPolicyAndItsObservationAllocateNothing) {
  const ci::RobotModel model = ci::RobotModel::from_urdf_file(
      std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.urdf", "panda_link0",
      "panda_link8");
  ci::JointVector q(7);
  q << 0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4;
  model_simulation::Simulation sim(model, q);
  ci::ControlLoop loop(model, ci::Parameters{});
  loop.start(sim.q, sim.dq);
  ci::PolicyInterface policy(model, ci::Parameters{}, /*wrench=*/true);
  policy.reset(loop.latest_state().controller.pose);
  Eigen::VectorXd observation(policy.observation_size());
  ci::PolicyInterface::Action action(18);

  long allocations = 0;
  for (int k = 0; k < 40; ++k) {
    for (int i = 0; i < 18; ++i) action[i] = std::sin(0.3 * k + i);  // a changing policy
    ci::LoopState state = loop.latest_state();  // (a copy for the test, not counted)
    policy.apply(action, loop, state.controller.pose);
    for (int cycle = 0; cycle < 50; ++cycle) {
      allocation_counter::Scope scope;
      const ci::JointVector& tau = loop.step(sim.q, sim.dq, 0.001);
      allocations += scope.allocations();
      sim.step(tau, 0.001);
    }
    state = loop.latest_state();
    allocation_counter::Scope scope;
    policy.observe(state, observation);
    allocations += scope.allocations();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_TRUE(observation.allFinite());
  EXPECT_GT(loop.latest_state().commands_applied, 100u);
}

// The collision monitor allocates nothing from the observer through detection, each reaction
// and the hold, to the Resume command (queued outside the counted steps): a push of 30 Nm on
// joint 2 of the model's own Panda (support/model_simulation.hpp, the firmware compensating
// gravity), well past the default thresholds; the observer reading the torque sent, and the
// joint torques measured.
TEST(LoopAllocation, TheCollisionMonitorAllocatesNothingFromDetectionToResume) {
  const ci::RobotModel model = ci::RobotModel::from_urdf_file(
      std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.urdf", "panda_link0",
      "panda_link8");
  ci::JointVector q(7);
  q << 0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4;
  // With the torque sent, and with the joint torques measured (collision.measured_torque).
  for (const bool measured : {false, true}) {
    for (const ci::CollisionReaction reaction :
         {ci::CollisionReaction::report, ci::CollisionReaction::stop, ci::CollisionReaction::reflex,
          ci::CollisionReaction::retract}) {
      SCOPED_TRACE(std::string(ci::reaction_name(reaction)) + (measured ? ", measured" : ""));
      ci::Parameters parameters;
      parameters.collision.reaction = reaction;
      parameters.collision.measured_torque = measured;
      ci::ControlLoop loop(model, parameters);
      model_simulation::Simulation sim(model, q);
      loop.start(sim.q, sim.dq);
      long allocations = 0;
      const auto run = [&](int steps) {
        allocation_counter::Scope scope;
        for (int k = 0; k < steps; ++k) {
          sim.step(measured ? loop.step(sim.q, sim.dq, sim.measured_torque, 0.001)
                            : loop.step(sim.q, sim.dq, 0.001),
                   0.001);
        }
        allocations += scope.allocations();
      };
      run(300);
      sim.external[1] = 30.0;
      run(50);
      EXPECT_TRUE(loop.state().controller.collision.detected);
      EXPECT_EQ(loop.state().controller.collision.joint, 1);
      sim.external[1] = 0.0;
      run(1000);  // the reflex lets the arm coast: to rest before it is held again
      loop.resume();
      run(300);
      EXPECT_EQ(allocations, 0);
      EXPECT_EQ(loop.state().controller.collision.collisions, 1);
      EXPECT_FALSE(loop.state().controller.collision.detected);
      EXPECT_EQ(loop.state().controller.status, ci::Status::ok);
    }
  }
}
