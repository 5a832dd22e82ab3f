// The runtime's control thread on this machine: how close to its deadlines it runs. What the
// tests cannot assert (it depends on the machine's load) is measured here: the mean period from
// the first cycle to the last against the nominal one, and the median and worst dt from the
// thread's own histogram, for a cycle that does nothing (the thread's own cost and the kernel's
// wake-up latency). Wall time: the work runs on the control thread.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <thread>

#include "cartesian_impedance/runtime/control_thread.hpp"

namespace rt = cartesian_impedance::runtime;

namespace {

class CountingCycle : public rt::Cycle {
 public:
  bool prepare() override { return true; }
  rt::Freshness execute(const rt::CycleTime& time) noexcept override {
    if (count_.load(std::memory_order_relaxed) == 0) first_ = time.now;
    last_ = time.now;
    count_.fetch_add(1, std::memory_order_release);
    return rt::Freshness::fresh;
  }
  std::uint64_t count() const { return count_.load(std::memory_order_acquire); }
  double span_seconds() const { return std::chrono::duration<double>(last_ - first_).count(); }

 private:
  std::atomic<std::uint64_t> count_{0};
  std::chrono::steady_clock::time_point first_{}, last_{};
};

// Argument: the rate [Hz]. Each iteration runs the thread for 0.5 s.
void BM_ControlThreadPeriod(benchmark::State& state) {
  const double rate = static_cast<double>(state.range(0));
  double mean_ratio = 0.0, p50 = 0.0, worst = 0.0;
  for (auto _ : state) {
    rt::ControlThreadOptions options;
    options.rate = rate;
    rt::ControlThread thread(options);
    CountingCycle cycle;
    thread.start(cycle);
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    thread.stop();
    const rt::ControlThreadStatistics statistics = thread.statistics();
    if (cycle.count() < 2) {
      state.SkipWithError("the control thread ran fewer than two cycles");
      return;
    }
    mean_ratio += cycle.span_seconds() / static_cast<double>(cycle.count() - 1) * rate;
    p50 += statistics.period_p50_us;
    worst = std::max(worst, statistics.period_max_us);
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["mean_period_over_nominal"] = mean_ratio / n;
  state.counters["p50_us"] = p50 / n;
  state.counters["max_us"] = worst;
}

}  // namespace

BENCHMARK(BM_ControlThreadPeriod)
    ->ArgName("rate")
    ->Arg(500)
    ->Arg(1000)
    ->Iterations(3)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
