// The closed-loop runner: the same trajectory, bit for bit, as the hand-written loop it replaces
// (one arm, and two arms on one simulation), its torque hook, early stop, its errors, no
// allocation per step, and one step per cycle when a control thread runs it at real-time rate.

#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/runtime/control_thread.hpp"
#include "cartesian_impedance/sim/closed_loop_runner.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "support/robots.hpp"

#ifdef CARTESIAN_IMPEDANCE_COUNT_ALLOCATIONS
#include "support/allocation_counter.hpp"
#endif

namespace ci = cartesian_impedance;
namespace sim = cartesian_impedance::sim;
using ci::JointVector;

namespace {

const std::string kSource = CARTESIAN_IMPEDANCE_SOURCE_DIR;

using robots::iiwa;
using robots::panda;

sim::Simulation simulate(const std::string& relative, const std::vector<ci::RobotModel*>& models,
                         double timestep = 0.001) {
  sim::SimulationOptions options;
  options.timestep = timestep;
  for (const ci::RobotModel* model : models) {
    options.joint_names.insert(options.joint_names.end(), model->joint_names().begin(),
                               model->joint_names().end());
  }
  return sim::Simulation::from_mjcf_file(kSource + "/models/" + relative, options);
}

// Moves the reference 10 cm along x and down 5 cm: the arm travels, so q changes every step.
void send_step(ci::ControlLoop& loop) {
  ci::Pose target = loop.state().controller.pose;
  target.position += Eigen::Vector3d(0.1, 0.0, -0.05);
  loop.set_reference_pose(target);
}

// One arm on its own simulation, started and sent a reference step.
struct Arm {
  ci::RobotModel model = panda();
  sim::Simulation simulation = simulate("panda/panda.xml", {&model});
  ci::ControlLoop loop{model};
  Arm() {
    loop.start(simulation.q(), simulation.dq());
    send_step(loop);
  }
};

}  // namespace

TEST(ClosedLoopRunner, GivesTheTrajectoryOfTheHandWrittenLoopBitForBit) {
  Arm by_hand, by_runner;
  constexpr int kSteps = 1500;
  std::vector<JointVector> expected;
  for (int k = 0; k < kSteps; ++k) {
    const double dt = by_hand.simulation.timestep();
    by_hand.simulation.set_torque(
        by_hand.loop.step(by_hand.simulation.q(), by_hand.simulation.dq(), dt));
    by_hand.simulation.step();
    expected.push_back(by_hand.simulation.q());
  }

  sim::ClosedLoopRunner runner(by_runner.simulation, by_runner.loop);
  std::vector<JointVector> measured;
  const std::int64_t done = runner.run(kSteps, [&](std::int64_t steps_done) {
    EXPECT_EQ(steps_done, static_cast<std::int64_t>(measured.size()) + 1);
    measured.push_back(by_runner.simulation.q());
  });
  EXPECT_EQ(done, kSteps);
  ASSERT_EQ(measured.size(), expected.size());
  for (int k = 0; k < kSteps; ++k) ASSERT_EQ(measured[k], expected[k]) << "step " << k;
  EXPECT_GT((measured.back() - measured.front()).norm(), 0.05);  // it did move
  EXPECT_EQ(runner.torque(), by_runner.loop.state().controller.tau);
  EXPECT_EQ(by_runner.loop.state().controller.status, ci::Status::ok);
}

TEST(ClosedLoopRunner, DrivesTwoArmsOnOneSimulationEachOnItsJoints) {
  ci::RobotModel left_model = panda(), right_model = iiwa();
  sim::Simulation by_hand = simulate("scenes/two_arms.xml", {&left_model, &right_model});
  sim::Simulation by_runner = simulate("scenes/two_arms.xml", {&left_model, &right_model});
  ci::ControlLoop hand_left(left_model), hand_right(right_model);
  ci::ControlLoop runner_left(left_model), runner_right(right_model);

  const int n = left_model.num_joints(), m = right_model.num_joints();
  hand_left.start(by_hand.q().head(n), by_hand.dq().head(n));
  hand_right.start(by_hand.q().tail(m), by_hand.dq().tail(m));
  sim::ClosedLoopRunner runner(by_runner, {&runner_left, &runner_right});
  runner.start();
  send_step(hand_right);
  send_step(runner_right);

  JointVector q_left(n), dq_left(n), q_right(m), dq_right(m), tau(n + m);
  for (int k = 0; k < 1000; ++k) {
    q_left = by_hand.q().head(n);
    dq_left = by_hand.dq().head(n);
    q_right = by_hand.q().tail(m);
    dq_right = by_hand.dq().tail(m);
    tau.head(n) = hand_left.step(q_left, dq_left, 0.001);
    tau.tail(m) = hand_right.step(q_right, dq_right, 0.001);
    by_hand.set_torque(tau);
    by_hand.step();
    runner.step();
    ASSERT_EQ(by_runner.q(), by_hand.q()) << "step " << k;
    ASSERT_EQ(runner.torque(), tau) << "step " << k;
  }
  // The right arm moved toward its new reference, the left one held.
  EXPECT_GT(runner_right.state().controller.pose_error.head<3>().norm(), 0.0);
  EXPECT_LT((runner_right.state().controller.pose.position -
             runner_right.state().controller.filtered.pose.position)
                .norm(),
            0.1);
  EXPECT_EQ(runner_left.state().cycle, 1000u);
  EXPECT_EQ(runner_right.state().cycle, 1000u);
}

TEST(ClosedLoopRunner, RejectsLoopsThatDoNotMatchTheSimulationsJoints) {
  ci::RobotModel left_model = panda(), right_model = iiwa();
  sim::Simulation scene = simulate("scenes/two_arms.xml", {&left_model, &right_model});
  ci::ControlLoop left(left_model), right(right_model);
  EXPECT_THROW(sim::ClosedLoopRunner(scene, left), ci::Error);             // half of them
  EXPECT_THROW(sim::ClosedLoopRunner(scene, {&right, &left}), ci::Error);  // wrong order
  EXPECT_THROW(sim::ClosedLoopRunner(scene, std::vector<ci::ControlLoop*>{}), ci::Error);
  EXPECT_THROW(sim::ClosedLoopRunner(scene, {&left, nullptr}), ci::Error);
  try {
    sim::ClosedLoopRunner(scene, {&right, &left});
  } catch (const ci::Error& error) {
    EXPECT_NE(std::string(error.what()).find("panda_joint1"), std::string::npos) << error.what();
  }

  sim::ClosedLoopRunner runner(scene, {&left, &right});
  EXPECT_THROW(runner.run(10), ci::Error);  // not started
  runner.start();
  EXPECT_THROW(runner.run(-1), ci::Error);
  EXPECT_THROW(runner.run_for(-0.1), ci::Error);
  EXPECT_THROW(runner.run_for(std::nan("")), ci::Error);
  // More timesteps than the counter holds: named as such (it used to wrap to a negative count).
  try {
    runner.run_for(1e300);
    ADD_FAILURE() << "1e300 s was accepted";
  } catch (const ci::Error& error) {
    EXPECT_EQ(std::string(error.what()),
              "seconds = 1e+300 is 1e+303 timesteps of 0.001 s, more than the 9e+18 a run can "
              "count");
  }
  EXPECT_EQ(runner.run_for(0.0104), 10);  // rounded to whole timesteps
}

TEST(ClosedLoopRunner, TorqueHookReplacesTheTorqueBeforeItIsApplied) {
  Arm arm;
  sim::ClosedLoopRunner runner(arm.simulation, arm.loop);
  runner.set_torque_hook([](JointVector& tau) { tau = -tau; });
  runner.run(20);  // short: the flipped law drives the arm away, until the controller faults
  EXPECT_GT(arm.loop.state().controller.tau.norm(), 0.1);
  EXPECT_EQ(runner.torque(), -arm.loop.state().controller.tau);
  EXPECT_EQ(arm.simulation.torque(), runner.torque());  // within the Panda's torque ranges

  runner.set_torque_hook([](JointVector& tau) { tau.setZero(); });
  runner.step();
  EXPECT_EQ(arm.simulation.torque(), JointVector::Zero(7));
  // A hook's non-finite torque is not applied: the previous one stays.
  runner.set_torque_hook([](JointVector& tau) { tau[0] = std::nan(""); });
  runner.step();
  EXPECT_EQ(arm.simulation.torque(), JointVector::Zero(7));
  runner.set_torque_hook({});
  runner.step();
  EXPECT_EQ(arm.simulation.torque(), arm.loop.state().controller.tau);
}

TEST(ClosedLoopRunner, StopsEarlyWhenAsked) {
  Arm arm;
  sim::ClosedLoopRunner runner(arm.simulation, arm.loop);
  const double start = arm.simulation.time();
  const std::int64_t done = runner.run_for(10.0, [&](std::int64_t steps_done) {
    if (steps_done == 37) runner.request_stop();
  });
  EXPECT_EQ(done, 37);
  EXPECT_NEAR(arm.simulation.time() - start, 37 * arm.simulation.timestep(), 1e-12);
  // A new run begins afresh; an observer's exception ends it.
  EXPECT_EQ(runner.run(5), 5);
  EXPECT_THROW(runner.run(100,
                          [](std::int64_t steps_done) {
                            if (steps_done == 3) throw std::runtime_error("interrupted");
                          }),
               std::runtime_error);
  EXPECT_EQ(arm.loop.state().cycle, 37u + 5u + 3u);
}

TEST(ClosedLoopRunner, RunsOneStepPerCycleOnAControlThread) {
  // The ROS node's sim mode: the runner as the cycle of a control thread at real-time rate, the
  // simulation's timestep equal to the period.
  ci::RobotModel model = panda();
  sim::Simulation simulation = simulate("panda/panda.xml", {&model}, 0.002);
  ci::ControlLoop loop(model);
  sim::ClosedLoopRunner runner(simulation, loop);
  ci::runtime::ControlThreadOptions options;
  options.rate = 500.0;
  ci::runtime::ControlThread thread(options);
  thread.start(runner);  // prepare() starts the loop from the simulated state
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  thread.stop();
  const std::uint64_t cycles = thread.statistics().cycles;
  EXPECT_GT(cycles, 0u);  // how many in 300 ms depends on the machine's load; each is checked
  EXPECT_EQ(loop.state().cycle, cycles);
  EXPECT_NEAR(simulation.time(), static_cast<double>(cycles) * 0.002, 1e-9);
  EXPECT_EQ(loop.state().controller.status, ci::Status::ok);
  EXPECT_FALSE(thread.statistics().stale);
}

#ifdef CARTESIAN_IMPEDANCE_COUNT_ALLOCATIONS
TEST(ClosedLoopRunner, StepAllocatesNothingWithTwoLoopsAndAHook) {
  ci::RobotModel left_model = panda(), right_model = iiwa();
  sim::Simulation scene = simulate("scenes/two_arms.xml", {&left_model, &right_model});
  ci::ControlLoop left(left_model), right(right_model);
  sim::ClosedLoopRunner runner(scene, {&left, &right});
  runner.set_torque_hook([](JointVector& tau) { tau *= 0.5; });
  runner.start();
  send_step(left);
  long allocations = 0;
  {
    allocation_counter::Scope scope;
    for (int k = 0; k < 2000; ++k) runner.step();
    allocations = scope.allocations();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(left.state().cycle, 2000u);
}
#endif
