// Cost of one full ControlLoop::step() for the Panda (model + law + hand-off), and of its parts,
// so the README can say what dominates.

#include <benchmark/benchmark.h>

#include "cartesian_impedance/control_loop.hpp"
#include "support/allocation_counter.hpp"

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

void run_loop(benchmark::State& state, const ci::Parameters& parameters) {
  ci::ControlLoop loop(panda(), parameters);
  ci::JointVector q = ready(), dq = ci::JointVector::Constant(7, 0.01);
  loop.start(q, dq);
  ci::Pose target = loop.state().controller.pose;
  target.position.z() -= 0.05;
  loop.set_reference_pose(target);
  allocation_counter::Scope allocations;
  for (auto _ : state) {
    q[0] += 1e-7;
    benchmark::DoNotOptimize(loop.step(q, dq, 0.001).data());
  }
  state.counters["allocs_per_step"] =
      static_cast<double>(allocations.allocations()) / static_cast<double>(state.iterations());
}

// Defaults: kinematics (pose + Jacobian) from KDL, law, joint-limit avoidance, state published.
void BM_LoopStep(benchmark::State& state) {
  run_loop(state, ci::Parameters{});
}
BENCHMARK(BM_LoopStep);

// Every model-based option: KDL mass matrix, gravity and Coriolis as well.
void BM_LoopStepAllDynamics(benchmark::State& state) {
  ci::Parameters parameters;
  parameters.dynamics.gravity_compensation = true;
  parameters.dynamics.inertia_shaped_damping = true;
  parameters.dynamics.dynamically_consistent_nullspace = true;
  run_loop(state, parameters);
}
BENCHMARK(BM_LoopStepAllDynamics);

// The model alone.
void BM_ModelKinematics(benchmark::State& state) {
  const ci::RobotModel model = panda();
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  ci::JointVector q = ready(), dq = ci::JointVector::Zero(7);
  for (auto _ : state) {
    q[0] += 1e-7;
    benchmark::DoNotOptimize(workspace.compute(q, dq, kinematics, state.range(0) != 0));
  }
}
BENCHMARK(BM_ModelKinematics)->Arg(0)->Arg(1)->ArgName("dynamics");

}  // namespace
BENCHMARK_MAIN();
