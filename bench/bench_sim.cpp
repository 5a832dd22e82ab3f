// Closed-loop simulation speed: ControlLoop + MuJoCo per 1 ms step, as a real-time factor, and
// the controller's share of the step.

#include <benchmark/benchmark.h>

#include "cartesian_impedance/control_loop.hpp"
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

}  // namespace
