// The control thread's period while every command topic of the ROS 2 node is flooded at 1 kHz:
// the node (sim mode, 1 kHz control) runs as its own process; this program publishes valid
// commands on all six command topics at 1 kHz each for the benchmark's time and reads the
// control thread's own period statistics from full_state (measured inside the node, since the
// start of its thread). A quiet run of the same length is the baseline. Run:
//   build/ros2/test/ros2_flood_benchmark --benchmark_min_time=10
// Counters: period p50/p99/max [us], overruns, commands sent per second.

#include <benchmark/benchmark.h>

#include "harness.hpp"

namespace cartesian_impedance_ros2::test {
namespace {

namespace ci = cartesian_impedance;

struct Timing {
  std::string status;
  double p50 = 0, p99 = 0, max = 0;
  std::uint64_t overruns = 0, cycles = 0;
  geometry_msgs_msg_dds__Pose_ pose{};
};

Timing copy_timing(const FullState& m) {
  return {m.status,   m.period_p50_us, m.period_p99_us, m.period_max_us,
          m.overruns, m.cycle,         m.current_pose};
}

void run(benchmark::State& state, bool flood) {
  const std::string node_name = "/cartesian_impedance_controller";
  NodeProcess node({"--ros-args", "--params-file", repository() + "/ros2/config/sim_panda.yaml"});
  use_private_domain();
  const Participant participant;
  Latest<FullState, Timing (*)(const FullState&)> full(
      participant, "rt" + node_name + "/full_state", &copy_timing);
  if (!full.wait(15.0, [](const Timing& t) { return t.status == "ok"; })) {
    state.SkipWithError("the node did not start");
    return;
  }
  const geometry_msgs_msg_dds__Pose_ start = full.value().pose;
  Writer<PoseStamped> pose(participant, "rt" + node_name + "/reference_pose", TopicQos{});
  Writer<WrenchStamped> stiffness(participant, "rt" + node_name + "/set_cartesian_stiffness",
                                  TopicQos{});
  Writer<WrenchStamped> wrench(participant, "rt" + node_name + "/set_cartesian_wrench", TopicQos{});
  Writer<WrenchMessage> damping(participant, "rt" + node_name + "/set_damping_factors", TopicQos{});
  Writer<ControllerConfig> config(participant, "rt" + node_name + "/set_config", TopicQos{});
  Writer<JointTrajectoryMessage> trajectory(participant, "rt/joint_trajectory", TopicQos{});
  eventually(
      5.0, [&] { return pose.matched() > 0 && config.matched() > 0 && trajectory.matched() > 0; });

  PoseStamped p{};
  p.header.frame_id = const_cast<char*>("");
  p.pose = start;
  WrenchStamped k{};
  k.header.frame_id = const_cast<char*>("");
  k.wrench.force = {500, 500, 500};
  k.wrench.torque = {50, 50, 50};
  WrenchStamped f{};
  f.header.frame_id = const_cast<char*>("");
  WrenchMessage zeta{};
  zeta.force = {1, 1, 1};
  zeta.torque = {1, 1, 1};
  ControllerConfig c{};
  c.cartesian_stiffness = k.wrench;
  c.cartesian_damping_factors = zeta;
  c.nullspace_stiffness = 10;
  c.nullspace_damping_factor = 1;
  // An empty trajectory: cancels (nothing runs), the cheapest message on that topic.
  JointTrajectoryMessage t{};
  t.header.frame_id = const_cast<char*>("");

  std::uint64_t sent = 0;
  for (auto _ : state) {
    auto next = Clock::now();
    for (int i = 0; i < 1000; ++i) {  // one second at 1 kHz
      if (flood) {
        p.pose.position.x = start.position.x + 0.01 * std::sin(0.002 * M_PI * i);
        pose.write(p);
        stiffness.write(k);
        wrench.write(f);
        damping.write(zeta);
        config.write(c);
        trajectory.write(t);
        sent += 6;
      }
      next += std::chrono::microseconds(1000);
      std::this_thread::sleep_until(next);
    }
  }
  full.wait(1.0, [](const Timing&) { return true; });
  const Timing timing = full.value();
  state.counters["period_p50_us"] = timing.p50;
  state.counters["period_p99_us"] = timing.p99;
  state.counters["period_max_us"] = timing.max;
  state.counters["overruns"] = static_cast<double>(timing.overruns);
  state.counters["cycles"] = static_cast<double>(timing.cycles);
  state.counters["commands_per_s"] =
      benchmark::Counter(static_cast<double>(sent), benchmark::Counter::kIsRate);
  if (timing.status != "ok") state.SkipWithError(("status " + timing.status).c_str());
}

void BM_ControlPeriodQuiet(benchmark::State& state) {
  run(state, false);
}
void BM_ControlPeriodEveryTopicFloodedAt1kHz(benchmark::State& state) {
  run(state, true);
}

BENCHMARK(BM_ControlPeriodQuiet)->Unit(benchmark::kSecond)->Iterations(10)->UseRealTime();
BENCHMARK(BM_ControlPeriodEveryTopicFloodedAt1kHz)
    ->Unit(benchmark::kSecond)
    ->Iterations(10)
    ->UseRealTime();

}  // namespace
}  // namespace cartesian_impedance_ros2::test

BENCHMARK_MAIN();
