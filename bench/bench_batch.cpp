// Batched closed loops (sim::BatchRunner): n independent Panda pairs (MuJoCo + ControlLoop)
// advanced by the same number of 1 ms steps per call, serially on one thread against the
// runner's thread pool, and against a runner made per call (threads started and joined each
// time). Arguments: pairs, steps per call. The counter pair_steps_per_second compares them (its
// ratio to serial is the speed-up); wall time, since the work runs on other threads.

#include <benchmark/benchmark.h>

#include <chrono>
#include <ctime>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/sim/batch_runner.hpp"
#include "cartesian_impedance/sim/closed_loop_runner.hpp"
#include "cartesian_impedance/sim/simulation.hpp"

namespace ci = cartesian_impedance;

namespace {

const std::string kSource = CARTESIAN_IMPEDANCE_SOURCE_DIR;

struct Pair {
  explicit Pair(const ci::RobotModel& model)
      : sim(make_sim(model)), loop(model), runner(sim, loop) {
    loop.start(sim.q(), sim.dq());
    ci::Pose target = loop.state().controller.pose;
    target.position.x() += 0.1;
    loop.set_reference_pose(target);
  }
  static ci::sim::Simulation make_sim(const ci::RobotModel& model) {
    ci::sim::SimulationOptions options;
    options.joint_names = model.joint_names();
    return ci::sim::Simulation::from_mjcf_file(kSource + "/models/panda/panda.xml", options);
  }
  ci::sim::Simulation sim;
  ci::ControlLoop loop;
  ci::sim::ClosedLoopRunner runner;
};

struct Batch {
  explicit Batch(int n) {
    for (int i = 0; i < n; ++i) {
      pairs.push_back(std::make_unique<Pair>(model));
      batch_pairs.push_back({&pairs.back()->sim, &pairs.back()->loop});
    }
  }
  bool ok() const {
    for (const auto& pair : pairs) {
      if (pair->loop.state().controller.status != ci::Status::ok) return false;
    }
    return true;
  }
  ci::RobotModel model = ci::RobotModel::from_urdf_file(kSource + "/models/panda/panda.urdf",
                                                        "panda_link0", "panda_link8");
  std::vector<std::unique_ptr<Pair>> pairs;
  std::vector<ci::sim::BatchPair> batch_pairs;
};

void report(benchmark::State& state, const Batch& batch) {
  if (!batch.ok()) state.SkipWithError("a loop failed closed");
  state.counters["pair_steps_per_second"] =
      benchmark::Counter(static_cast<double>(state.iterations() * state.range(0) * state.range(1)),
                         benchmark::Counter::kIsRate);
}

void BM_BatchSerial(benchmark::State& state) {
  Batch batch(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    for (auto& pair : batch.pairs) pair->runner.run(state.range(1));
  }
  report(state, batch);
}

void BM_BatchPool(benchmark::State& state) {
  Batch batch(static_cast<int>(state.range(0)));
  ci::sim::BatchRunner runner(batch.batch_pairs);
  for (auto _ : state) runner.run(state.range(1));
  report(state, batch);
}

void BM_BatchThreadsPerCall(benchmark::State& state) {
  Batch batch(static_cast<int>(state.range(0)));
  for (auto _ : state) ci::sim::BatchRunner(batch.batch_pairs).run(state.range(1));
  report(state, batch);
}

// What the pool's threads cost while they wait for the next run: the process's CPU seconds over
// 200 ms of waiting after a short run, with spin 0 (the threads sleep at once) and the longest
// spin (they keep a core busy, yielding it to anyone who wants it). Counter cpu_seconds_idle;
// the figure depends on the machine's load, so it is measured here, not asserted in a test
// (batch_runner_test checks only that a sleeping pool uses next to nothing).
void BM_BatchIdleCpu(benchmark::State& state) {
  Batch batch(2);
  const std::chrono::microseconds spin =
      state.range(0) == 0 ? std::chrono::microseconds(0) : ci::sim::BatchRunner::kMaxSpin;
  ci::sim::BatchRunner runner(batch.batch_pairs, 2, spin);
  double idle = 0.0;
  for (auto _ : state) {
    runner.run(20);
    const std::clock_t before = std::clock();
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    idle += static_cast<double>(std::clock() - before) / CLOCKS_PER_SEC;
  }
  state.counters["cpu_seconds_idle"] = idle / static_cast<double>(state.iterations());
  if (!batch.ok()) state.SkipWithError("a loop failed closed");
}

void batch_arguments(benchmark::internal::Benchmark* benchmark) {
  benchmark->ArgNames({"pairs", "steps"})->UseRealTime()->Unit(benchmark::kMillisecond);
  for (int steps : {10, 100}) {
    for (int pairs : {1, 2, 4, 8}) benchmark->Args({pairs, steps});
  }
}

}  // namespace

BENCHMARK(BM_BatchSerial)->Apply(batch_arguments);
BENCHMARK(BM_BatchPool)->Apply(batch_arguments);
BENCHMARK(BM_BatchThreadsPerCall)->Apply(batch_arguments);
BENCHMARK(BM_BatchIdleCpu)
    ->ArgNames({"spin"})
    ->Arg(0)
    ->Arg(1)
    ->Iterations(5)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
