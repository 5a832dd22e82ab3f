// Closed-loop simulation speed: ControlLoop + MuJoCo or DART per 1 ms step, as a real-time
// factor, and the controller's share of the step.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "cartesian_impedance/config/yaml.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/sim/closed_loop_runner.hpp"
#include "cartesian_impedance/sim/simulation.hpp"

namespace ci = cartesian_impedance;

namespace {

const std::string kSource = CARTESIAN_IMPEDANCE_SOURCE_DIR;

struct PandaRig {
  ci::RobotModel model = ci::RobotModel::from_urdf_file(kSource + "/models/panda/panda.urdf",
                                                        "panda_link0", "panda_link8");
  ci::sim::Simulation sim = make_sim(model);
  ci::ControlLoop loop{model};

  static ci::sim::Simulation make_sim(const ci::RobotModel& model) {
    ci::sim::SimulationOptions options;
    options.joint_names = model.joint_names();
    return ci::sim::Simulation::from_mjcf_file(kSource + "/models/panda/panda.xml", options);
  }
  PandaRig() {
    loop.start(sim.q(), sim.dq());
    ci::Pose target = loop.state().controller.pose;
    target.position.x() += 0.1;
    loop.set_reference_pose(target);
  }
};

void report_real_time_factor(benchmark::State& state) {
  // Each iteration simulates 1 ms.
  state.counters["real_time_factor"] = benchmark::Counter(
      1e-3 * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

// Controller + simulation: one control cycle and one physics step, as the closed-loop runner
// does them for the scenarios, Python and the ROS node.
void BM_ClosedLoopPanda(benchmark::State& state) {
  PandaRig rig;
  ci::sim::ClosedLoopRunner runner(rig.sim, rig.loop);
  for (auto _ : state) benchmark::DoNotOptimize(runner.step().data());
  if (rig.loop.state().controller.status != ci::Status::ok) {  // a fail-closed cycle is no figure
    state.SkipWithError(ci::to_string(rig.loop.state().controller.fault).c_str());
  }
  report_real_time_factor(state);
}
BENCHMARK(BM_ClosedLoopPanda);

// The simulation alone, with the torque held.
void BM_SimulationStepPanda(benchmark::State& state) {
  PandaRig rig;
  rig.sim.set_torque(ci::JointVector::Constant(7, 0.5));
  for (auto _ : state) rig.sim.step();
  report_real_time_factor(state);
}
BENCHMARK(BM_SimulationStepPanda);

// The Panda from its URDF on either engine, as the demo's rig sets it up: config/panda.yaml, the
// simulation's rotor inertia the controller's dynamics.armature, started at the ready pose.
struct PandaUrdfRig {
  ci::Parameters parameters = ci::load_parameters(kSource + "/config/panda.yaml");
  ci::RobotModel model = ci::RobotModel::from_urdf_file(kSource + "/models/panda/panda.urdf",
                                                        "panda_link0", "panda_link8");
  ci::sim::Simulation sim;
  ci::ControlLoop loop{model, parameters};

  explicit PandaUrdfRig(ci::sim::Engine engine) : sim(make_sim(engine, model, parameters)) {
    loop.start(sim.q(), sim.dq());
  }
  static ci::sim::Simulation make_sim(ci::sim::Engine engine, const ci::RobotModel& model,
                                      const ci::Parameters& parameters) {
    ci::sim::SimulationOptions options;
    options.engine = engine;
    options.timestep = 0.001;
    options.joint_names = model.joint_names();
    options.start_q.resize(7);
    options.start_q << 0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4;
    options.armature = parameters.dynamics.armature;
    return ci::sim::Simulation::from_urdf_file(kSource + "/models/panda/panda.urdf", options);
  }
};

// One simulated millisecond of the closed loop (ControlLoop::step, then Simulation::step) on each
// engine, with the arm in motion and touching nothing: the reference jumps 10 cm back and forth
// along y every simulated second, so the arm never comes to rest (a resting arm would flatter
// the engines whose solvers converge faster at rest). mean_joint_speed shows that it moved.
void BM_ClosedLoopMillisecond(benchmark::State& state, ci::sim::Engine engine) {
  std::string reason;
  if (!ci::sim::engine_available(engine, &reason)) {
    state.SkipWithError(reason.c_str());
    return;
  }
  PandaUrdfRig rig(engine);
  ci::sim::ClosedLoopRunner runner(rig.sim, rig.loop);
  const ci::Pose home = rig.loop.state().controller.pose;
  constexpr int kStepsPerLeg = 1000;
  int step = 0;
  bool left = false;
  double speed_sum = 0.0;
  for (auto _ : state) {
    if (step++ % kStepsPerLeg == 0) {
      left = !left;
      ci::Pose target = home;
      target.position.y() += left ? 0.05 : -0.05;
      rig.loop.set_reference_pose(target);
    }
    benchmark::DoNotOptimize(runner.step().data());
    speed_sum += rig.sim.dq().norm();
  }
  if (rig.loop.state().controller.status != ci::Status::ok) {
    state.SkipWithError(ci::to_string(rig.loop.state().controller.fault).c_str());
  }
  report_real_time_factor(state);
  state.counters["mean_joint_speed"] =
      benchmark::Counter(speed_sum / static_cast<double>(std::max<int>(step, 1)));
}
BENCHMARK_CAPTURE(BM_ClosedLoopMillisecond, mujoco, ci::sim::Engine::mujoco)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_ClosedLoopMillisecond, dart, ci::sim::Engine::dart)
    ->Unit(benchmark::kMicrosecond);

}  // namespace
