// Cost of one control cycle at 7 joints with every feature on, against a plainly written
// dynamic-size SVD implementation of the same law (tests/support/reference_controller.hpp).
// Reports ns per cycle (mean, and worst case over 100,000 individually timed cycles) and heap
// allocations per cycle.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <vector>

#include "cartesian_impedance/compat/cartesian_impedance_controller.hpp"
#include "cartesian_impedance/core/controller.hpp"
#include "support/allocation_counter.hpp"
#include "support/published_reference.hpp"
#include "support/random_cases.hpp"
#include "support/reference_controller.hpp"

namespace ci = cartesian_impedance;
using namespace random_cases;

namespace {

constexpr int kJoints = 7;

// Every feature of the published law on: filters still moving (long filter times), stiffness and
// wrench in the end-effector frame, damped nullspace projection, pose-error clipping, torque and
// rate limits. Unit-mass damping, as in the reference implementation it is compared with; the
// default inertia-shaped damping has its own benchmark.
ci::Parameters busy_parameters() {
  ci::Parameters parameters;
  parameters.dynamics.inertia_shaped_damping = false;
  parameters.stiffness.frame = ci::Frame::end_effector;
  parameters.wrench.frame = ci::Frame::end_effector;
  parameters.filter.pose.time = 30.0;       // the longest allowed
  parameters.filter.stiffness.time = 30.0;  // the longest allowed
  parameters.filter.nullspace.time = 30.0;  // the longest allowed
  parameters.filter.wrench.time = 30.0;     // the longest allowed
  parameters.nullspace.pseudo_inverse_damping = 0.05;
  parameters.limits.pose_error = {0.05, 0.2};
  parameters.limits.joint_torque = ci::JointVector::Constant(1, 10.0);
  parameters.limits.joint_torque_rate = ci::JointVector::Constant(1, 100.0);
  return parameters;
}

struct Setup {
  std::mt19937 rng{42};
  ci::RobotState robot = random_robot_state(kJoints, rng);
  ci::Pose reference{robot.pose.position + Eigen::Vector3d(0.1, 0.0, -0.05),
                     Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY())) *
                         robot.pose.orientation};
  ci::JointVector q_desired = robot.q + random_joints(kJoints, rng, 0.2);
  ci::Vector6d wrench = (ci::Vector6d() << 5, 0, -3, 0, 0.2, 0).finished();
  ci::Matrix6d full_stiffness = random_stiffness(rng);
  Setup() {
    // An arm-like M(q): positive definite, diagonal-dominant, condition about 100.
    const ci::JointMatrix a = ci::JointMatrix::Random(kJoints, kJoints);
    robot.mass = 0.05 * a * a.transpose() +
                 ci::JointVector::LinSpaced(kJoints, 3.0, 0.03).asDiagonal().toDenseMatrix();
  }
};

ci::CartesianImpedanceController make_controller(const Setup& setup, bool full_stiffness,
                                                 bool inertia_shaped = false) {
  ci::Parameters parameters = busy_parameters();
  parameters.dynamics.inertia_shaped_damping = inertia_shaped;
  ci::CartesianImpedanceController controller(kJoints, parameters);
  controller.start(setup.robot);
  controller.set_reference_pose(setup.reference);
  controller.set_nullspace_target(setup.q_desired);
  controller.set_wrench(setup.wrench);
  if (full_stiffness) {
    controller.set_stiffness_matrix(setup.full_stiffness);
  } else {
    controller.set_stiffness((ci::Vector6d() << 800, 600, 400, 40, 30, 20).finished());
  }
  return controller;
}

void report_allocations(benchmark::State& state, long allocations) {
  state.counters["allocs_per_cycle"] =
      static_cast<double>(allocations) / static_cast<double>(state.iterations());
}

void run_update(benchmark::State& state, bool full_stiffness, bool inertia_shaped = false) {
  Setup setup;
  ci::CartesianImpedanceController controller =
      make_controller(setup, full_stiffness, inertia_shaped);
  ci::RobotState robot = setup.robot;
  // A cycle that fails closed skips the law: time only cycles that run it.
  if (controller.update(robot, 0.001) != ci::Status::ok) {
    state.SkipWithError(ci::to_string(controller.state().fault).c_str());
    return;
  }
  allocation_counter::Scope allocations;
  for (auto _ : state) {
    robot.q[0] += 1e-9;
    benchmark::DoNotOptimize(controller.update(robot, 0.001));
    benchmark::DoNotOptimize(controller.torque().data());
  }
  report_allocations(state, allocations.allocations());
}

// Diagonal stiffness being filtered: the common case.
void BM_Update(benchmark::State& state) {
  run_update(state, false);
}
BENCHMARK(BM_Update);

// A full (coupled) stiffness being filtered: damping needs a 6x6 eigen-decomposition each cycle,
// the most expensive path of the unit-mass law.
void BM_UpdateFullStiffnessFiltering(benchmark::State& state) {
  run_update(state, true);
}
BENCHMARK(BM_UpdateFullStiffnessFiltering);

// The default damping: ratios relative to the task-space inertia Lambda = (J M^-1 J^T)^-1, which
// costs an L D L^T of M, a 6x6 Cholesky of Lambda^-1 and the square root of the normalised
// stiffness each cycle. The Jacobian stands still here, so the square root's tracked axes need
// no rotation; the next benchmark moves it.
void BM_UpdateInertiaShapedDamping(benchmark::State& state) {
  run_update(state, false, true);
}
BENCHMARK(BM_UpdateInertiaShapedDamping);

// The same with the Jacobian moving every cycle as on an arm at speed (a change of about 3e-4 of
// its entries per cycle, like 0.3 rad/s at 1 kHz), so that the square root's tracked axes are
// rotated every cycle. The moving Jacobian costs a 6x7 update per cycle on top.
void BM_UpdateInertiaShapedDampingMoving(benchmark::State& state) {
  Setup setup;
  ci::CartesianImpedanceController controller = make_controller(setup, false, true);
  ci::RobotState robot = setup.robot;
  const ci::Jacobian start = robot.jacobian;
  const ci::Jacobian direction = random_jacobian(kJoints, setup.rng);
  if (controller.update(robot, 0.001) != ci::Status::ok) {
    state.SkipWithError(ci::to_string(controller.state().fault).c_str());
    return;
  }
  double phase = 0.0;
  allocation_counter::Scope allocations;
  for (auto _ : state) {
    phase += 1e-3;
    robot.jacobian = start + (0.3 * std::sin(phase)) * direction;
    benchmark::DoNotOptimize(controller.update(robot, 0.001));
    benchmark::DoNotOptimize(controller.torque().data());
  }
  report_allocations(state, allocations.allocations());
}
BENCHMARK(BM_UpdateInertiaShapedDampingMoving);

// The published base library's API, every filter moving and the torque delta on: on the
// compatibility class (its writing overload; the published signature adds one allocation for the
// returned vector) and on the oracle of the published semantics, written as plainly as the
// published code (dynamic matrices, an SVD pseudo-inverse per call).
template <typename Controller>
void configure_published_session(Controller& controller, const Setup& setup) {
  controller.setNumberOfJoints(kJoints);
  controller.setFiltering(1000.0, 0.1, 0.1, 0.1, 0.1);  // still moving after 10^6 calls
  controller.setMaxTorqueDelta(0.5);
  controller.initDesiredPose(setup.robot.pose.position, setup.robot.pose.orientation);
  controller.initNullspaceConfig(Eigen::VectorXd(setup.robot.q));
  controller.setStiffness(800.0, 600.0, 400.0, 40.0, 30.0, 20.0, 10.0);
  controller.setReferencePose(setup.reference.position, setup.reference.orientation);
  controller.setNullspaceConfig(Eigen::VectorXd(setup.q_desired));
  controller.applyWrench(setup.wrench);
}

// Times `step(controller, q, dq, jacobian, tau)` on the published session, the caller's data as
// Eigen::VectorXd / MatrixXd, allocated before counting.
template <typename Controller, typename Step>
void run_published_session(benchmark::State& state, Controller& controller, Step step) {
  Setup setup;
  configure_published_session(controller, setup);
  Eigen::VectorXd q = setup.robot.q, tau = Eigen::VectorXd::Zero(kJoints);
  const Eigen::VectorXd dq = setup.robot.dq;
  const Eigen::MatrixXd jacobian = setup.robot.jacobian;
  allocation_counter::Scope allocations;
  for (auto _ : state) {
    q[0] += 1e-9;
    step(controller, q, dq, setup.robot.pose, jacobian, tau);
  }
  report_allocations(state, allocations.allocations());
}

void BM_CompatPublishedApi(benchmark::State& state) {
  cartesian_impedance_controller::CartesianImpedanceController controller;
  run_published_session(state, controller,
                        [](auto& c, const auto& q, const auto& dq, const ci::Pose& pose,
                           const auto& jacobian, Eigen::VectorXd& tau) {
                          benchmark::DoNotOptimize(c.calculateCommandedTorques(
                              q, dq, pose.position, pose.orientation, jacobian, tau));
                        });
  if (controller.status() != ci::Status::ok) state.SkipWithError("the compat step failed");
}
BENCHMARK(BM_CompatPublishedApi);

void BM_PublishedSemanticsSvd(benchmark::State& state) {
  published_reference::Controller controller;
  run_published_session(state, controller,
                        [](auto& c, const auto& q, const auto& dq, const ci::Pose& pose,
                           const auto& jacobian, Eigen::VectorXd&) {
                          benchmark::DoNotOptimize(c.calculateCommandedTorques(
                              q, dq, pose.position, pose.orientation, jacobian));
                        });
}
BENCHMARK(BM_PublishedSemanticsSvd);

// The same law written plainly with dynamic matrices and SVDs, its torque clipped joint by joint
// (the library shapes it in task space, which costs it about 40 ns here, where every cycle
// saturates).
void BM_ReferenceSvd(benchmark::State& state) {
  Setup setup;
  reference::Controller controller(kJoints, busy_parameters(),
                                   reference::Controller::Shaping::per_joint);
  controller.start(setup.robot.q, setup.robot.pose.position, setup.robot.pose.orientation);
  controller.commanded().position = setup.reference.position;
  controller.commanded().orientation = setup.reference.orientation;
  controller.commanded().nullspace_q = setup.q_desired;
  controller.commanded().wrench = setup.wrench;
  const Eigen::VectorXd q0 = setup.robot.q, dq = setup.robot.dq;
  const Eigen::MatrixXd jacobian = setup.robot.jacobian;
  Eigen::VectorXd q = q0;
  allocation_counter::Scope allocations;
  for (auto _ : state) {
    q[0] += 1e-9;
    benchmark::DoNotOptimize(controller.update(q, dq, setup.robot.pose.position,
                                               setup.robot.pose.orientation, jacobian, 0.001));
  }
  report_allocations(state, allocations.allocations());
}
BENCHMARK(BM_ReferenceSvd);

// Worst case: 100,000 cycles timed one by one (clock overhead of ~20-30 ns included).
void BM_UpdateWorstCase(benchmark::State& state) {
  Setup setup;
  ci::CartesianImpedanceController controller = make_controller(setup, state.range(0) != 0);
  ci::RobotState robot = setup.robot;
  std::vector<double> durations(100000);
  if (controller.update(robot, 0.001) != ci::Status::ok) {
    state.SkipWithError(ci::to_string(controller.state().fault).c_str());
    return;
  }
  for (auto _ : state) {
    for (double& duration : durations) {
      robot.q[0] += 1e-9;
      const auto begin = std::chrono::steady_clock::now();
      controller.update(robot, 0.001);
      const auto end = std::chrono::steady_clock::now();
      duration = std::chrono::duration<double, std::nano>(end - begin).count();
    }
  }
  std::sort(durations.begin(), durations.end());
  state.counters["median_ns"] = durations[durations.size() / 2];
  state.counters["p99_ns"] = durations[durations.size() * 99 / 100];
  state.counters["p99.9_ns"] = durations[durations.size() * 999 / 1000];
  state.counters["max_ns"] = durations.back();
}
BENCHMARK(BM_UpdateWorstCase)->Arg(0)->Arg(1)->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace
