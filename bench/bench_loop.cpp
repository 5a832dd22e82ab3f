// Cost of one full ControlLoop::step() for the Panda (model + law + hand-off), and of its parts,
// so the README can say what dominates; each on the native model backend and on KDL.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/loop/policy_interface.hpp"
#include "support/allocation_counter.hpp"
#include "support/safety_caps.hpp"

namespace ci = cartesian_impedance;

namespace {

ci::RobotModel panda() {
  return ci::RobotModel::from_urdf_file(
      std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.urdf", "panda_link0",
      "panda_link8");
}

ci::JointVector ready() {
  return (ci::JointVector(7) << 0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4).finished();
}

// Every joint moves a little each cycle, as measured joints do: KDL caches each joint's rotation
// while its angle stays the same, which a measurement where only one joint moves would flatter.
constexpr double kDrift = 1e-7;

// `measured`: the joint torques the robot measures, given to every step.
void run_loop(benchmark::State& state, const ci::Parameters& parameters,
              ci::ModelBackend backend = ci::ModelBackend::native,
              const ci::JointVector* measured = nullptr) {
  ci::ControlLoop loop(panda().with_backend(backend), parameters);
  ci::JointVector q = ready(), dq = ci::JointVector::Constant(7, 0.01);
  loop.start(q, dq);
  ci::Pose target = loop.state().controller.pose;
  target.position.z() -= 0.05;
  loop.set_reference_pose(target);
  allocation_counter::Scope allocations;
  for (auto _ : state) {
    q.array() += kDrift;
    benchmark::DoNotOptimize(
        (measured ? loop.step(q, dq, *measured, 0.001) : loop.step(q, dq, 0.001)).data());
  }
  state.counters["allocs_per_step"] =
      static_cast<double>(allocations.allocations()) / static_cast<double>(state.iterations());
  // A step that fails closed skips the law: the figure would mean nothing.
  if (loop.state().controller.status != ci::Status::ok) {
    state.SkipWithError(ci::to_string(loop.state().controller.fault).c_str());
  }
}

// Defaults: kinematics (pose + Jacobian) and M(q) (damping shaped by the task-space inertia),
// law, joint-limit avoidance, state published; on each model backend.
void BM_LoopStep(benchmark::State& state, ci::ModelBackend backend) {
  run_loop(state, ci::Parameters{}, backend);
}
BENCHMARK_CAPTURE(BM_LoopStep, native, ci::ModelBackend::native);
BENCHMARK_CAPTURE(BM_LoopStep, kdl, ci::ModelBackend::kdl);

// The defaults without the collision monitor (collision.detection off: no C^T dq, no observer):
// BM_LoopStep/native less this is what the monitor costs.
void BM_LoopStepWithoutCollisionMonitor(benchmark::State& state) {
  ci::Parameters parameters;
  parameters.collision.detection = false;
  run_loop(state, parameters);
}
BENCHMARK(BM_LoopStepWithoutCollisionMonitor);

// The defaults with the observer on measured joint torques (collision.measured_torque): the
// model adds g(q) for it. Compare with BM_LoopStep/native.
void BM_LoopStepWithMeasuredTorque(benchmark::State& state) {
  ci::Parameters parameters;
  parameters.collision.measured_torque = true;
  const ci::RobotModel model = panda();
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  workspace.compute(ready(), ci::JointVector::Zero(7), kinematics, true);
  const ci::JointVector holding = kinematics.gravity;  // what holds the arm at rest
  run_loop(state, parameters, ci::ModelBackend::native, &holding);
}
BENCHMARK(BM_LoopStepWithMeasuredTorque);

// The same step with every part of the safety layer acting every cycle (support/safety_caps.hpp:
// the speed caps far below the flange's speed, so the reference is held back, the push along
// the motion taken away and the excess braked; the force and torque caps; the flange outside a
// small workspace box and moving out of it; the energy tank paying for a stiffness raise it
// cannot afford; a declared payload in gravity and M(q)). Its flags are checked at the end, so
// the figure cannot silently time a cheaper path. Compare with BM_LoopStep/native.
void BM_LoopStepEveryCap(benchmark::State& state) {
  const ci::RobotModel model = panda();
  ci::JointVector q = ready(), dq = ci::JointVector::Constant(7, 0.01);
  const safety_caps::Scene scene = safety_caps::scene(model, q, dq);
  ci::ControlLoop loop(model, scene.parameters);
  loop.start(scene.start, dq);
  for (const ci::Command& command : scene.commands) loop.send(command);
  loop.step(q, dq, 0.001);  // applies the commands; the reference is clipped into the box
  safety_caps::Acted first;
  first.record(loop.state().controller.safety);
  // The wrench ramps in through its filter (0.2 s): from then on every cap acts in every step.
  for (int k = 0; k < 1000; ++k) loop.step(q, dq, 0.001);
  allocation_counter::Scope allocations;
  for (auto _ : state) {
    q.array() += kDrift;
    benchmark::DoNotOptimize(loop.step(q, dq, 0.001).data());
  }
  state.counters["allocs_per_step"] =
      static_cast<double>(allocations.allocations()) / static_cast<double>(state.iterations());
  const ci::ControllerState& last = loop.state().controller;
  state.counters["torque_shaped"] = last.limits.joint_torque_saturated ? 1.0 : 0.0;
  // Every part but the payload estimate (the arm moves) acted in the last step; the clip, which
  // moves the reference into the box once, in the first.
  safety_caps::Acted in_last;
  in_last.record(last.safety);
  in_last.reference_clipped = first.reference_clipped;
  const std::string missing = in_last.missing(false);
  if (last.status != ci::Status::ok) {
    state.SkipWithError(ci::to_string(last.fault).c_str());
  } else if (!missing.empty()) {
    state.SkipWithError(("did not act in the last step: " + missing).c_str());
  }
}
BENCHMARK(BM_LoopStepEveryCap);

// The published controller's unit-mass damping: kinematics only, no M(q) (nor the collision
// monitor, which needs it).
void BM_LoopStepUnitMassDamping(benchmark::State& state, ci::ModelBackend backend) {
  ci::Parameters parameters;
  parameters.dynamics.inertia_shaped_damping = false;
  parameters.collision.detection = false;
  run_loop(state, parameters, backend);
}
BENCHMARK_CAPTURE(BM_LoopStepUnitMassDamping, native, ci::ModelBackend::native);
BENCHMARK_CAPTURE(BM_LoopStepUnitMassDamping, kdl, ci::ModelBackend::kdl);

// The step that starts a trajectory of range(0) points: the same cost for 10 as for 10,000,
// because the velocities are derived when the trajectory is sent (timed: the step only).
void BM_StepThatStartsATrajectory(benchmark::State& state) {
  const int points = static_cast<int>(state.range(0));
  ci::ControlLoop loop(panda(), {}, ci::LoopCapacity{64, points});
  ci::JointVector q = ready(), dq = ci::JointVector::Zero(7);
  loop.start(q, dq);
  ci::JointTrajectory trajectory;
  trajectory.joint_names = loop.model().joint_names();
  for (int k = 1; k <= points; ++k) {
    ci::JointVector point = q;
    point[0] += 0.1 * std::sin(0.001 * k);
    trajectory.times.push_back(0.001 * k);
    trajectory.positions.emplace_back(point.data(), point.data() + point.size());
  }
  // The sender's copy of a long trajectory leaves the caches cold; so does this, for any length,
  // so that the comparison shows the step's own work.
  std::vector<char> scratch(8 << 20);
  for (auto _ : state) {
    loop.execute_trajectory(trajectory);
    std::fill(scratch.begin(), scratch.end(), static_cast<char>(state.iterations()));
    benchmark::ClobberMemory();
    const auto begin = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(loop.step(q, dq, 0.001).data());
    const auto end = std::chrono::steady_clock::now();
    state.SetIterationTime(std::chrono::duration<double>(end - begin).count());
  }
}
BENCHMARK(BM_StepThatStartsATrajectory)->Arg(10)->Arg(10000)->UseManualTime();

// The most expensive step a flood can cause: the inbox full (64 commands), the first 8 of them
// whole parameter sets (the largest command to apply). The step applies those 8 and leaves the
// rest for the next steps (timed: that step only; the queue is drained between iterations).
void BM_StepWithAFullInbox(benchmark::State& state) {
  ci::ControlLoop loop(panda());
  ci::JointVector q = ready(), dq = ci::JointVector::Zero(7);
  loop.start(q, dq);
  const ci::Parameters parameters;
  const ci::Wrench wrench((ci::Vector6d() << 1, 0, 0, 0, 0, 0).finished());
  for (auto _ : state) {
    for (int i = 0; i < 8; ++i) loop.set_parameters(parameters);
    try {
      for (;;) loop.send(wrench);
    } catch (const ci::QueueFull&) {
    }
    const auto begin = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(loop.step(q, dq, 0.001).data());
    const auto end = std::chrono::steady_clock::now();
    state.SetIterationTime(std::chrono::duration<double>(end - begin).count());
    for (int k = 1; k < 8; ++k) loop.step(q, dq, 0.001);  // 8 per step: empty again
  }
}
BENCHMARK(BM_StepWithAFullInbox)->UseManualTime();

// Every model-based option: M(q) and g(q) as well (the loop never asks for Coriolis).
void BM_LoopStepAllDynamics(benchmark::State& state, ci::ModelBackend backend) {
  ci::Parameters parameters;
  parameters.dynamics.gravity_compensation = true;
  parameters.dynamics.inertia_shaped_damping = true;
  parameters.dynamics.dynamically_consistent_nullspace = true;
  run_loop(state, parameters, backend);
}
BENCHMARK_CAPTURE(BM_LoopStepAllDynamics, native, ci::ModelBackend::native);
BENCHMARK_CAPTURE(BM_LoopStepAllDynamics, kdl, ci::ModelBackend::kdl);

// The model alone: pose and Jacobian plus `terms`.
void run_model(benchmark::State& state, ci::ModelBackend backend, ci::ModelTerms terms) {
  const ci::RobotModel model = panda().with_backend(backend);
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  ci::JointVector q = ready(), dq = ci::JointVector::Constant(7, 0.1);
  allocation_counter::Scope allocations;
  for (auto _ : state) {
    q.array() += kDrift;
    benchmark::DoNotOptimize(workspace.compute(q, dq, kinematics, terms));
    benchmark::ClobberMemory();
  }
  state.counters["allocs_per_call"] =
      static_cast<double>(allocations.allocations()) / static_cast<double>(state.iterations());
}

void BM_PoseJacobian(benchmark::State& state, ci::ModelBackend backend) {
  run_model(state, backend, ci::ModelTerms::none);
}
BENCHMARK_CAPTURE(BM_PoseJacobian, native, ci::ModelBackend::native);
BENCHMARK_CAPTURE(BM_PoseJacobian, kdl, ci::ModelBackend::kdl);

void BM_PoseJacobianMass(benchmark::State& state, ci::ModelBackend backend) {
  run_model(state, backend, ci::ModelTerms::mass);
}
BENCHMARK_CAPTURE(BM_PoseJacobianMass, native, ci::ModelBackend::native);
BENCHMARK_CAPTURE(BM_PoseJacobianMass, kdl, ci::ModelBackend::kdl);

void BM_PoseJacobianGravity(benchmark::State& state, ci::ModelBackend backend) {
  run_model(state, backend, ci::ModelTerms::gravity);
}
BENCHMARK_CAPTURE(BM_PoseJacobianGravity, native, ci::ModelBackend::native);
BENCHMARK_CAPTURE(BM_PoseJacobianGravity, kdl, ci::ModelBackend::kdl);

void BM_PoseJacobianCoriolis(benchmark::State& state, ci::ModelBackend backend) {
  run_model(state, backend, ci::ModelTerms::coriolis);
}
BENCHMARK_CAPTURE(BM_PoseJacobianCoriolis, native, ci::ModelBackend::native);
BENCHMARK_CAPTURE(BM_PoseJacobianCoriolis, kdl, ci::ModelBackend::kdl);

// The terms of the law's options (C^T dq, the collision monitor's, has its own figure: the kdl
// backend takes it from 2n mass matrices).
void BM_PoseJacobianAllTerms(benchmark::State& state, ci::ModelBackend backend) {
  run_model(state, backend,
            ci::ModelTerms::mass | ci::ModelTerms::gravity | ci::ModelTerms::coriolis);
}
BENCHMARK_CAPTURE(BM_PoseJacobianAllTerms, native, ci::ModelBackend::native);
BENCHMARK_CAPTURE(BM_PoseJacobianAllTerms, kdl, ci::ModelBackend::kdl);

// What the collision monitor asks of the model: M(q) and C^T dq.
void BM_PoseJacobianMassCoriolisTransposed(benchmark::State& state) {
  run_model(state, ci::ModelBackend::native,
            ci::ModelTerms::mass | ci::ModelTerms::coriolis_transposed);
}
BENCHMARK(BM_PoseJacobianMassCoriolisTransposed);

// What the loop asked for before terms could be chosen: all (dynamics:1) or none (dynamics:0).
void BM_ModelKinematics(benchmark::State& state, ci::ModelBackend backend) {
  run_model(state, backend, state.range(0) != 0 ? ci::ModelTerms::all : ci::ModelTerms::none);
}
BENCHMARK_CAPTURE(BM_ModelKinematics, native, ci::ModelBackend::native)
    ->Arg(0)
    ->Arg(1)
    ->ArgName("dynamics");
BENCHMARK_CAPTURE(BM_ModelKinematics, kdl, ci::ModelBackend::kdl)
    ->Arg(0)
    ->Arg(1)
    ->ArgName("dynamics");

// A policy's step at 20 Hz without the 50 cycles in between: the action into the loop's commands
// (PolicyInterface::apply: reference on the leash, stiffness, wrench; validated and queued) and
// the observation (observe: J dq and the external wrench by SVD). The loop steps once per
// iteration so that its inbox is emptied; BM_LoopStep gives that step's own cost.
void BM_PolicyApplyAndObserve(benchmark::State& state) {
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model, ci::Parameters{});
  ci::JointVector q = ready(), dq = ci::JointVector::Constant(7, 0.01);
  loop.start(q, dq);
  ci::PolicyInterface policy(model, ci::Parameters{}, /*wrench=*/true);
  policy.reset(loop.latest_state().controller.pose);
  ci::PolicyInterface::Action action(18);
  Eigen::VectorXd observation(policy.observation_size());
  ci::LoopState loop_state = loop.latest_state();
  int k = 0;
  for (auto _ : state) {
    for (int i = 0; i < 18; ++i) action[i] = std::sin(0.1 * ++k);
    policy.apply(action, loop, loop_state.controller.pose);
    loop.step(q, dq, 0.001);
    loop_state = loop.latest_state();
    policy.observe(loop_state, observation);
    benchmark::DoNotOptimize(observation.data());
    q += 0.001 * dq;
  }
}
BENCHMARK(BM_PolicyApplyAndObserve);

// observe() alone.
void BM_PolicyObserve(benchmark::State& state) {
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model, ci::Parameters{});
  loop.start(ready(), ci::JointVector::Constant(7, 0.01));
  ci::PolicyInterface policy(model, ci::Parameters{}, false);
  const ci::LoopState loop_state = loop.latest_state();
  Eigen::VectorXd observation(policy.observation_size());
  for (auto _ : state) {
    policy.observe(loop_state, observation);
    benchmark::DoNotOptimize(observation.data());
  }
}
BENCHMARK(BM_PolicyObserve);

}  // namespace
BENCHMARK_MAIN();
