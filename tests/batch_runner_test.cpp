// The batch runner: independent closed loops on a pool of threads end bit for bit where each
// ends alone (MuJoCo and DART, two timesteps, several runs with new commands in between), its
// errors name the pair and run nothing, a stop or a throwing poll ends every pair, and a run
// allocates nothing.

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/sim/batch_runner.hpp"
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

enum class Kind { panda_mujoco, iiwa_mujoco, panda_mujoco_2ms, panda_dart };

bool dart_available() {
  return sim::engine_available(sim::Engine::dart);
}

// A simulation and the loop that drives it, started; kept in place (the loop refers to the model).
struct Arm {
  explicit Arm(Kind kind)
      : model(kind == Kind::iiwa_mujoco ? robots::iiwa() : robots::panda()),
        simulation(load(kind, model)),
        loop(model) {
    loop.start(simulation.q(), simulation.dq());
  }
  static sim::Simulation load(Kind kind, const ci::RobotModel& model) {
    sim::SimulationOptions options;
    options.joint_names = model.joint_names();
    switch (kind) {
      case Kind::iiwa_mujoco:
        return sim::Simulation::from_mjcf_file(kSource + "/models/iiwa14/iiwa14.xml", options);
      case Kind::panda_mujoco_2ms:
        options.timestep = 0.002;
        return sim::Simulation::from_mjcf_file(kSource + "/models/panda/panda.xml", options);
      case Kind::panda_dart:
        options.engine = sim::Engine::dart;
        options.start_q = robots::panda_ready();
        return sim::Simulation::from_urdf_file(kSource + "/models/panda/panda.urdf", options);
      case Kind::panda_mujoco:
        break;
    }
    return sim::Simulation::from_mjcf_file(kSource + "/models/panda/panda.xml", options);
  }
  // A new reference for run `call` of pair `index`: each pair and each run its own, so that a
  // mix-up of pairs or of runs shows.
  void command(int index, int call) {
    ci::Pose target = loop.state().controller.pose;
    target.position += Eigen::Vector3d(0.02 * (index + 1), -0.01 * call, 0.015 * (call % 2));
    loop.set_reference_pose(target);
  }
  ci::RobotModel model;
  sim::Simulation simulation;
  ci::ControlLoop loop;
};

using Arms = std::vector<std::unique_ptr<Arm>>;

Arms make_arms(const std::vector<Kind>& kinds) {
  Arms arms;
  for (Kind kind : kinds) arms.push_back(std::make_unique<Arm>(kind));
  return arms;
}

std::vector<sim::BatchPair> pairs_of(const Arms& arms) {
  std::vector<sim::BatchPair> pairs;
  for (const auto& arm : arms) pairs.push_back({&arm->simulation, &arm->loop});
  return pairs;
}

std::vector<Kind> mixed_kinds() {
  std::vector<Kind> kinds = {Kind::panda_mujoco, Kind::iiwa_mujoco, Kind::panda_mujoco_2ms,
                             Kind::panda_mujoco, Kind::iiwa_mujoco};
  if (dart_available()) kinds.push_back(Kind::panda_dart);
  return kinds;
}

}  // namespace

TEST(BatchRunner, EndsEachPairBitForBitWhereItEndsAlone) {
  const std::vector<Kind> kinds = mixed_kinds();
  Arms alone = make_arms(kinds), batched = make_arms(kinds);
  sim::BatchRunner batch(pairs_of(batched), 2);
  EXPECT_EQ(batch.threads(), 2);
  EXPECT_EQ(batch.size(), kinds.size());
  const double durations[] = {0.3, 0.0, 0.25, 0.4};
  for (int call = 0; call < 4; ++call) {
    for (std::size_t i = 0; i < kinds.size(); ++i) {
      alone[i]->command(static_cast<int>(i), call);
      batched[i]->command(static_cast<int>(i), call);
      sim::ClosedLoopRunner(alone[i]->simulation, alone[i]->loop).run_for(durations[call]);
    }
    const std::vector<std::int64_t>& done = batch.run_for(durations[call]);
    for (std::size_t i = 0; i < kinds.size(); ++i) {
      const Arm& a = *alone[i];
      const Arm& b = *batched[i];
      EXPECT_EQ(done[i], std::llround(durations[call] / a.simulation.timestep()));
      ASSERT_EQ(b.simulation.time(), a.simulation.time()) << "pair " << i << ", run " << call;
      ASSERT_EQ(b.simulation.q(), a.simulation.q()) << "pair " << i << ", run " << call;
      ASSERT_EQ(b.simulation.dq(), a.simulation.dq()) << "pair " << i << ", run " << call;
      ASSERT_EQ(b.simulation.torque(), a.simulation.torque()) << "pair " << i << ", run " << call;
      ASSERT_EQ(b.loop.state().controller.tau, a.loop.state().controller.tau) << "pair " << i;
      ASSERT_EQ(b.loop.state().cycle, a.loop.state().cycle) << "pair " << i;
    }
  }
  // The runs did something: every arm moved toward its references, without a fault.
  for (std::size_t i = 0; i < kinds.size(); ++i) {
    const Arm& b = *batched[i];
    EXPECT_EQ(b.loop.state().controller.status, ci::Status::ok) << "pair " << i;
    EXPECT_GT(b.simulation.dq().norm(), 0.0) << "pair " << i;
    EXPECT_NEAR(b.simulation.time(), 0.95, 1e-9) << "pair " << i;
  }
  EXPECT_EQ(batch.runner(2).torque(), batched[2]->loop.state().controller.tau);
}

TEST(BatchRunner, UsesOneThreadPerCoreAtMostOnePerPair) {
  Arms arms = make_arms({Kind::panda_mujoco, Kind::panda_mujoco, Kind::panda_mujoco});
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  EXPECT_EQ(sim::BatchRunner(pairs_of(arms)).threads(), std::min(cores, 3));
  EXPECT_EQ(sim::BatchRunner(pairs_of(arms), 8).threads(), 3);
  EXPECT_EQ(sim::BatchRunner(pairs_of(arms), 1).threads(), 1);
}

// With spin 0 the pool's thread sleeps as soon as a run ends: the process uses next to no CPU
// while it waits for the next run (under 20 ms of the 200 it waits), however loaded the machine
// (a sleeping thread asks for none). Spinning, the thread keeps a core busy for up to the spin;
// how much of it the thread gets depends on the machine's load (a loaded CI machine gave it 7 ms
// of 200), so that figure is measured in bench_batch (BM_BatchIdleCpu), not asserted here. The
// results are the same either way.
TEST(BatchRunner, WithoutSpinThePoolSleepsBetweenRuns) {
  using std::chrono::microseconds;
  Arms alone = make_arms({Kind::panda_mujoco, Kind::panda_mujoco});
  Arms quiet = make_arms({Kind::panda_mujoco, Kind::panda_mujoco});
  Arms busy = make_arms({Kind::panda_mujoco, Kind::panda_mujoco});
  sim::BatchRunner sleeper(pairs_of(quiet), 2, microseconds(0));
  EXPECT_EQ(sleeper.spin(), microseconds(0));
  EXPECT_EQ(sim::BatchRunner(pairs_of(alone), 2).spin(), sim::BatchRunner::kDefaultSpin);
  const auto cpu_seconds_while_idle = [](sim::BatchRunner& batch) {
    batch.run_for(0.02);
    const std::clock_t before = std::clock();
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    return static_cast<double>(std::clock() - before) / CLOCKS_PER_SEC;
  };
  EXPECT_LT(cpu_seconds_while_idle(sleeper), 0.02);
  sim::BatchRunner spinner(pairs_of(busy), 2, sim::BatchRunner::kMaxSpin);
  spinner.run_for(0.02);
  for (std::size_t i = 0; i < 2; ++i) {
    sim::ClosedLoopRunner(alone[i]->simulation, alone[i]->loop).run_for(0.02);
    EXPECT_EQ(quiet[i]->simulation.q(), alone[i]->simulation.q());
    EXPECT_EQ(busy[i]->simulation.q(), alone[i]->simulation.q());
  }
  EXPECT_THROW(sim::BatchRunner(pairs_of(alone), 2, microseconds(-1)), ci::Error);
  try {
    sim::BatchRunner(pairs_of(alone), 2, microseconds(2000000));
    ADD_FAILURE() << "a spin of 2 s was accepted";
  } catch (const ci::Error& error) {
    EXPECT_STREQ(error.what(), "spin = 2000000 us is outside [0, 1000000] us");
  }
}

TEST(BatchRunner, NamesThePairThatDoesNotFitAndRunsNothing) {
  Arms arms = make_arms({Kind::panda_mujoco, Kind::panda_mujoco, Kind::iiwa_mujoco});
  const auto message_of = [](const auto& call) -> std::string {
    try {
      call();
    } catch (const ci::Error& error) {
      return error.what();
    }
    return "(no error)";
  };
  // The iiwa's loop on a Panda simulation: its joints are not the simulation's.
  std::vector<sim::BatchPair> pairs = pairs_of(arms);
  pairs[2].simulation = &arms[1]->simulation;
  pairs[1].simulation = &arms[2]->simulation;
  EXPECT_NE(message_of([&] { sim::BatchRunner batch(pairs); })
                .find("pair 1: the simulation "
                      "exchanges joints"),
            std::string::npos);
  // The same simulation, or the same loop, in two pairs.
  pairs = pairs_of(arms);
  pairs[2] = pairs[0];
  EXPECT_EQ(message_of([&] { sim::BatchRunner batch(pairs); }),
            "pair 2: its simulation is also pair 0's; each pair needs its own (they would run in "
            "parallel)");
  pairs = pairs_of(arms);
  pairs[1].loop = nullptr;
  EXPECT_EQ(message_of([&] { sim::BatchRunner batch(pairs); }), "pair 1: the control loop is null");
  EXPECT_THROW(sim::BatchRunner(std::vector<sim::BatchPair>{}), ci::Error);
  EXPECT_EQ(message_of([&] { sim::BatchRunner batch(pairs_of(arms), -1); }),
            "threads = -1 is outside [0, 64] (0 = one per core)");

  // A loop that was not started: named, and no pair moves (time, cycles).
  ci::ControlLoop unstarted(arms[2]->model);
  pairs = pairs_of(arms);
  pairs[2].loop = &unstarted;
  sim::BatchRunner batch(pairs, 2);
  EXPECT_EQ(message_of([&] { batch.run_for(0.1); }),
            "pair 2: the control loop has not been started: call loop.start(q, dq) with the "
            "simulation's state first");
  EXPECT_EQ(message_of([&] { batch.run_for(-0.1); }), "seconds = -0.1 must be finite and >= 0");
  EXPECT_EQ(message_of([&] { batch.run(-3); }), "steps = -3 must be >= 0");
  for (const auto& arm : arms) {
    EXPECT_EQ(arm->simulation.time(), 0.0);
    EXPECT_EQ(arm->loop.state().cycle, 0u);
  }
  EXPECT_EQ(unstarted.state().cycle, 0u);
  EXPECT_THROW(batch.runner(3), ci::Error);
  // Once started, the same batch runs.
  unstarted.start(arms[2]->simulation.q(), arms[2]->simulation.dq());
  const std::vector<std::int64_t>& done = batch.run(5);
  EXPECT_EQ(done, std::vector<std::int64_t>(3, 5));
  EXPECT_EQ(unstarted.state().cycle, 5u);
}

TEST(BatchRunner, AStopOrAThrowingPollEndsEveryPair) {
  Arms arms = make_arms({Kind::panda_mujoco, Kind::panda_mujoco, Kind::panda_mujoco});
  sim::BatchRunner batch(pairs_of(arms), 2);
  // A 1000 s run (a million steps per pair) stopped by the first poll after 10 ms.
  const std::vector<std::int64_t>& stopped = batch.run_for(
      1000.0, [&] { batch.request_stop(); }, 0.01);
  for (std::size_t i = 0; i < arms.size(); ++i) {
    EXPECT_LT(stopped[i], 1000000) << "pair " << i;
    EXPECT_EQ(static_cast<std::int64_t>(arms[i]->loop.state().cycle), stopped[i]);
  }
  // The next run runs whole.
  EXPECT_EQ(batch.run(3), std::vector<std::int64_t>(3, 3));
  // A poll that throws: every pair stops, then the exception arrives.
  int polls = 0;
  EXPECT_THROW(batch.run_for(
                   1000.0,
                   [&] {
                     ++polls;
                     throw std::runtime_error("interrupted");
                   },
                   0.01),
               std::runtime_error);
  EXPECT_EQ(polls, 1);
  for (const auto& arm : arms) EXPECT_LT(arm->simulation.time(), 500.0);
  EXPECT_THROW(batch.run(
                   1, [] {}, 0.0),
               ci::Error);  // poll_interval
}

#ifdef CARTESIAN_IMPEDANCE_COUNT_ALLOCATIONS
TEST(BatchRunner, RunAllocatesNothing) {
  Arms arms = make_arms({Kind::panda_mujoco, Kind::iiwa_mujoco, Kind::panda_mujoco});
  sim::BatchRunner batch(pairs_of(arms), 2);
  for (std::size_t i = 0; i < arms.size(); ++i) arms[i]->command(static_cast<int>(i), 0);
  batch.run(10);  // first wake of the threads
  int polls = 0;
  const sim::BatchRunner::Poll poll = [&polls] { ++polls; };
  long allocations = 0;
  {
    allocation_counter::Scope scope;  // counts every thread's allocations
    batch.run(500);
    batch.run_for(0.5, poll, 0.001);
    allocations = scope.allocations();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(polls, 0);  // the polling path ran too
  EXPECT_EQ(arms[1]->loop.state().cycle, 1010u);
}
#endif
