// ControlLoop::step() allocates nothing with every option on: dynamics (gravity compensation,
// inertia-shaped damping, dynamically consistent projector), joint-limit avoidance, a trajectory
// being executed, commands arriving through the inbox, the state being published, and bad input.

#include <gtest/gtest.h>

#include <algorithm>

#include "cartesian_impedance/loop/control_loop.hpp"
#include "support/allocation_counter.hpp"
#include "support/model_simulation.hpp"

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
