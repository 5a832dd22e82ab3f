// The runtime's control thread: rate on absolute deadlines, overruns and their lateness, the
// measured period's quantiles (and the histogram behind them, deterministically), statistics over
// a window, the robot cycle failing closed without measurements and resuming with them, start and
// stop.
//
// Timing bounds: this runs on a shared 2-core virtual machine where other builds run at the same
// time, so no test asserts how fast anything is. What the design guarantees is checked exactly
// (never more cycles than deadlines: a cycle never starts before its deadline, and an overrun
// never triggers a burst); what depends on the scheduler gets a generous bound, justified where
// it is used.

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <optional>
#include <random>
#include <thread>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/runtime/control_thread.hpp"
#include "cartesian_impedance/runtime/timing.hpp"
#include "support/robots.hpp"

namespace ci = cartesian_impedance;
namespace rt = cartesian_impedance::runtime;
using Clock = std::chrono::steady_clock;

namespace {

using robots::panda;
using robots::panda_ready;

double seconds_between(Clock::time_point from, Clock::time_point to) {
  return std::chrono::duration<double>(to - from).count();
}

// Waits (polling every millisecond) until `condition` holds or `timeout` [s] passes.
template <typename Condition>
bool eventually(Condition condition, double timeout = 5.0) {
  const Clock::time_point end = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                                   std::chrono::duration<double>(timeout));
  while (!condition()) {
    if (Clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

// A measurement of a robot standing at q.
rt::JointMeasurement at_rest(const ci::JointVector& q) {
  rt::JointMeasurement measurement;
  measurement.q = q;
  measurement.dq = ci::JointVector::Zero(q.size());
  return measurement;
}

// Records when each cycle began (preallocated: the cycle must not allocate).
class RecordingCycle : public rt::Cycle {
 public:
  explicit RecordingCycle(std::size_t capacity) : begins_(capacity), dts_(capacity) {}
  bool prepare() override { return true; }
  rt::Freshness execute(const rt::CycleTime& time) noexcept override {
    const std::size_t k = count_.load(std::memory_order_relaxed);
    if (k < begins_.size()) {
      begins_[k] = time.now;
      dts_[k] = time.dt;
      indices_ok_ = indices_ok_ && time.index == k;
      count_.store(k + 1, std::memory_order_release);
    }
    return rt::Freshness::fresh;
  }
  std::size_t count() const { return count_.load(std::memory_order_acquire); }
  const std::vector<Clock::time_point>& begins() const { return begins_; }
  const std::vector<double>& dts() const { return dts_; }
  bool indices_ok() const { return indices_ok_; }

 private:
  std::vector<Clock::time_point> begins_;
  std::vector<double> dts_;
  bool indices_ok_ = true;
  std::atomic<std::size_t> count_{0};
};

// A sink that makes every `every`-th cycle slow on purpose by sleeping `sleep` in it.
class SleepingSink : public rt::TorqueSink {
 public:
  SleepingSink(int every, std::chrono::microseconds sleep) : every_(every), sleep_(sleep) {}
  void write(const ci::JointVector& tau, std::uint64_t /*cycle*/) noexcept override {
    finite_ = finite_ && tau.allFinite();
    if (++writes_ % every_ == 0) {
      std::this_thread::sleep_for(sleep_);
      slow_.fetch_add(1, std::memory_order_relaxed);
    }
  }
  int slow() const { return slow_.load(std::memory_order_relaxed); }
  bool finite() const { return finite_; }

 private:
  int every_;
  std::chrono::microseconds sleep_;
  int writes_ = 0;
  bool finite_ = true;
  std::atomic<int> slow_{0};
};

// A robot that reports its (motionless) joint state at about 1 kHz while `on`, like a driver;
// stamped as measured `age` before it is published if `age` is given.
class FakeRobot {
 public:
  FakeRobot(rt::MeasurementBuffer& buffer, const ci::JointVector& q,
            std::optional<std::chrono::microseconds> age = std::nullopt)
      : buffer_(buffer), measurement_(at_rest(q)) {
    thread_ = std::thread([this, age] {
      while (!quit_) {
        if (age) measurement_.sampled = rt::monotonic_now() - *age;
        if (on_) buffer_.publish(measurement_);
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    });
  }
  ~FakeRobot() {
    quit_ = true;
    thread_.join();
  }
  std::atomic<bool> on_{true};

 private:
  rt::MeasurementBuffer& buffer_;
  rt::JointMeasurement measurement_;
  std::atomic<bool> quit_{false};
  std::thread thread_;
};

rt::ControlThreadOptions options_with(double rate, int realtime_priority = 0) {
  rt::ControlThreadOptions options;
  options.rate = rate;
  options.realtime_priority = realtime_priority;
  return options;
}

// The resolution the histogram promises for a duration [us]: bins no wider than max(1 us, 1 %).
double resolution_us(double us) {
  return std::max(1.0, 0.01 * us);
}

// How far a quantile may be from the true one: max(0.5 us, 0.4 %), the furthest a duration is
// from the value of its bin.
double quantile_error_us(double us) {
  return std::max(0.5, 0.004 * us);
}

// The q-quantile of `sorted` as the histogram defines it: the ceil(q n)-th smallest.
double exact_quantile(const std::vector<double>& sorted, double q) {
  const auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(sorted.size())));
  return sorted[std::clamp<std::size_t>(rank, 1, sorted.size()) - 1];
}

// Starts `cycle` on `thread` and waits until it has run a few cycles.
void start_cycling(rt::ControlThread& thread, RecordingCycle& cycle) {
  thread.start(cycle);
  ASSERT_TRUE(eventually([&] { return cycle.count() > 2; }));
}

}  // namespace

// ---- the histogram behind the period quantiles: deterministic ----------------------------------

TEST(DurationHistogram, BinsTileTheRangeNoWiderThanTheResolution) {
  using H = rt::DurationHistogram;
  EXPECT_EQ(H::lower_ns(0), 0);
  EXPECT_GE(H::kRangeNs, 1000000000);  // at least 1 s
  EXPECT_EQ(H::lower_ns(H::kBins), H::kRangeNs);
  for (std::size_t bin = 0; bin < H::kBins; ++bin) {
    const std::int64_t lower = H::lower_ns(bin);
    const std::int64_t upper = H::lower_ns(bin + 1);
    const std::int64_t value = H::value_ns(bin);
    ASSERT_GT(upper, lower) << bin;
    // Each duration counts toward the nearest value.
    ASSERT_LE(lower, value) << bin;
    ASSERT_LT(value, upper) << bin;
    ASSERT_LE(static_cast<double>(std::max(value - lower, upper - 1 - value)),
              1e3 * quantile_error_us(1e-3 * static_cast<double>(lower)))
        << bin;
    ASSERT_EQ(H::bin_of(value), bin);
    // No coarser than max(1 us, 1 % of any duration in it).
    ASSERT_LE(static_cast<double>(upper - lower),
              std::max(1000.0, 0.01 * static_cast<double>(lower)))
        << bin;
    ASSERT_EQ(H::bin_of(lower), bin);
    ASSERT_EQ(H::bin_of(upper - 1), bin);
  }
  // Round periods of 8 ms and less, 1 ms among them, are values of their own.
  for (const std::int64_t us : {100, 250, 500, 1000, 2000, 4000, 8000}) {
    EXPECT_EQ(H::value_ns(H::bin_of(1000 * us)), 1000 * us) << us;
  }
  EXPECT_EQ(H::bin_of(-5), 0u);
  EXPECT_EQ(H::bin_of(H::kRangeNs), H::kBins);
  EXPECT_EQ(H::bin_of(3600 * std::int64_t{1000000000}), H::kBins);
}

TEST(DurationHistogram, IsZeroWhenEmpty) {
  rt::DurationHistogram histogram;
  const rt::DurationHistogram::Snapshot snapshot = histogram.snapshot();
  EXPECT_EQ(snapshot.count, 0u);
  EXPECT_EQ(snapshot.quantile_us(0.5), 0.0);
  EXPECT_EQ(snapshot.min_us(), 0.0);
  EXPECT_EQ(snapshot.max_us(), 0.0);
}

TEST(DurationHistogram, QuantilesOfKnownDurations) {
  // 1.137 us, 2.137 us, ..., 1000.137 us, once each, in a scrambled order.
  rt::DurationHistogram histogram;
  for (int k = 0; k < 1000; ++k) histogram.record((k * 7919 % 1000 + 1) * 1000 + 137);
  const rt::DurationHistogram::Snapshot snapshot = histogram.snapshot();
  EXPECT_EQ(snapshot.count, 1000u);
  EXPECT_DOUBLE_EQ(snapshot.min_us(), 1.137);  // exact
  EXPECT_DOUBLE_EQ(snapshot.max_us(), 1000.137);
  EXPECT_NEAR(snapshot.quantile_us(0.5), 500.137, quantile_error_us(500.137));
  EXPECT_NEAR(snapshot.quantile_us(0.99), 990.137, quantile_error_us(990.137));
  EXPECT_NEAR(snapshot.quantile_us(0.1), 100.137, quantile_error_us(100.137));
  EXPECT_DOUBLE_EQ(snapshot.quantile_us(0.0), 1.137);     // the smallest: the minimum
  EXPECT_DOUBLE_EQ(snapshot.quantile_us(1.0), 1000.137);  // the largest: the maximum

  // One duration many times: every quantile is that duration (clamped to min = max).
  rt::DurationHistogram constant;
  for (int k = 0; k < 1000; ++k) constant.record(1000000);
  const rt::DurationHistogram::Snapshot one = constant.snapshot();
  EXPECT_EQ(one.quantile_us(0.5), 1000.0);
  EXPECT_EQ(one.quantile_us(0.99), 1000.0);
  EXPECT_EQ(one.min_us(), 1000.0);
  EXPECT_EQ(one.max_us(), 1000.0);

  // A 1 ms period with a little jitter either way: its median is 1000 us.
  rt::DurationHistogram jitter;
  for (int k = 0; k < 1000; ++k) jitter.record(1000000 + (k % 2 == 0 ? 300 : -400) * (k % 5));
  jitter.record(1300000);
  EXPECT_EQ(jitter.snapshot().quantile_us(0.5), 1000.0);
  EXPECT_EQ(jitter.snapshot().max_us(), 1300.0);
}

TEST(DurationHistogram, QuantilesAreWithinTheResolutionOfTheSortedDurations) {
  // Log-uniform durations from 0.1 us to 0.9 s from a fixed seed.
  std::mt19937_64 random(12345);
  rt::DurationHistogram histogram;
  std::vector<double> sorted_us;
  for (int k = 0; k < 20000; ++k) {
    const double fraction = static_cast<double>(random() >> 11) * 0x1.0p-53;  // [0, 1)
    const auto ns = static_cast<std::int64_t>(100.0 * std::pow(9e6, fraction));
    histogram.record(ns);
    sorted_us.push_back(1e-3 * static_cast<double>(ns));
  }
  std::sort(sorted_us.begin(), sorted_us.end());
  const rt::DurationHistogram::Snapshot snapshot = histogram.snapshot();
  for (const double q : {0.001, 0.01, 0.1, 0.25, 0.5, 0.75, 0.9, 0.99, 0.999}) {
    const double exact = exact_quantile(sorted_us, q);
    EXPECT_NEAR(snapshot.quantile_us(q), exact, quantile_error_us(exact)) << q;
  }
  EXPECT_DOUBLE_EQ(snapshot.min_us(), sorted_us.front());
  EXPECT_DOUBLE_EQ(snapshot.max_us(), sorted_us.back());
}

TEST(DurationHistogram, CountsLongDurationsInAnOverflowBinAndKeepsTheExactMaximum) {
  rt::DurationHistogram histogram;
  for (int k = 0; k < 98; ++k) histogram.record(1000000);  // 1 ms
  histogram.record(2 * std::int64_t{1000000000});          // 2 s
  histogram.record(5 * std::int64_t{1000000000});          // 5 s
  const rt::DurationHistogram::Snapshot snapshot = histogram.snapshot();
  EXPECT_EQ(snapshot.bins[rt::DurationHistogram::kBins], 2u);
  EXPECT_EQ(snapshot.count, 100u);
  EXPECT_EQ(snapshot.max_us(), 5e6);
  EXPECT_EQ(snapshot.quantile_us(0.5), 1000.0);
  EXPECT_EQ(snapshot.quantile_us(0.98), 1000.0);
  EXPECT_EQ(snapshot.quantile_us(0.99), 5e6);  // in the overflow bin: the maximum
}

TEST(DurationHistogram, ReportsAWindowBetweenTwoSnapshots) {
  using Snapshot = rt::DurationHistogram::Snapshot;
  rt::DurationHistogram histogram;
  for (int k = 0; k < 1000; ++k) histogram.record(1000000);  // 1 ms
  histogram.record(3000000);                                 // 3 ms: the maximum so far
  const Snapshot first = histogram.snapshot();
  for (int k = 0; k < 500; ++k) histogram.record(2000000);  // 2 ms
  histogram.record(2500000);                                // 2.5 ms: not a new maximum
  const Snapshot second = histogram.snapshot();

  const Snapshot window = second.since(first);
  EXPECT_EQ(window.count, 501u);
  EXPECT_EQ(window.quantile_us(0.5), 2000.0);
  EXPECT_NEAR(window.quantile_us(0.999), 2500.0, quantile_error_us(2500.0));
  // The extremes of the window are bounded by their bins: within the resolution, on the safe side.
  EXPECT_GE(window.max_us(), 2500.0);
  EXPECT_LE(window.max_us(), 2500.0 + resolution_us(2500.0));
  EXPECT_LE(window.min_us(), 2000.0);
  EXPECT_GE(window.min_us(), 2000.0 - resolution_us(2000.0));

  histogram.record(4000000);  // a new maximum: exact in its window
  histogram.record(500000);   // and a new minimum
  const Snapshot third = histogram.snapshot();
  const Snapshot last = third.since(second);
  EXPECT_EQ(last.count, 2u);
  EXPECT_EQ(last.max_us(), 4000.0);
  EXPECT_EQ(last.min_us(), 500.0);
  EXPECT_EQ(third.since(third).count, 0u);
  EXPECT_EQ(third.since(third).quantile_us(0.5), 0.0);

  // Reset in between: the window is everything since.
  histogram.reset();
  histogram.record(7000);
  const Snapshot after = histogram.snapshot();
  EXPECT_EQ(after.since(third).count, 1u);
  EXPECT_EQ(after.since(third).max_us(), 7.0);
  EXPECT_EQ(after.since(Snapshot{}).count, 1u);
}

// ---- the control thread
// --------------------------------------------------------------------------

TEST(ControlThread, KeepsItsRateOnAbsoluteDeadlines) {
  rt::ControlThreadOptions options;
  options.rate = 500.0;
  rt::ControlThread thread(options);
  RecordingCycle cycle(2000);
  const Clock::time_point started = Clock::now();
  thread.start(cycle);
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  thread.stop();
  const Clock::time_point stopped = Clock::now();

  const std::size_t count = cycle.count();
  ASSERT_GT(count, 10u);
  EXPECT_EQ(thread.statistics().cycles, count);
  EXPECT_TRUE(cycle.indices_ok());
  // Exact: a cycle never begins before its deadline and overruns do not run missed cycles, so
  // there are never more cycles than deadlines in the interval.
  const double period = 1.0 / options.rate;
  EXPECT_LE(static_cast<double>(count), seconds_between(started, stopped) / period + 1.0);
  // Mean period from the first to the last cycle. It cannot be shorter than the period (no early
  // wake-ups), however loaded the machine. How much longer it gets depends on the load (a cycle
  // that starts more than a whole period late restarts the schedule from then), so that figure is
  // measured by bench_runtime (BM_ControlThreadPeriod), not asserted here.
  const double mean = seconds_between(cycle.begins()[0], cycle.begins()[count - 1]) /
                      static_cast<double>(count - 1);
  EXPECT_GE(mean, 0.999 * period);
  // dt is the time between cycle begins; the first is one period.
  EXPECT_NEAR(cycle.dts()[0], period, 1e-9);
  for (std::size_t k = 1; k < count; ++k) {
    EXPECT_NEAR(cycle.dts()[k], seconds_between(cycle.begins()[k - 1], cycle.begins()[k]), 1e-9);
  }
  EXPECT_EQ(thread.state(), rt::ControlThread::State::stopped);
}

TEST(ControlThread, ReportsThePeriodItMeasured) {
  rt::ControlThread thread(options_with(1000.0));
  RecordingCycle cycle(5000);
  thread.start(cycle);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  thread.stop();
  const std::size_t count = cycle.count();
  ASSERT_GT(count, 20u);
  ASSERT_LT(count, 5000u);

  // Exact: the histogram counted each cycle's dt but the first (which is not measured).
  const rt::ControlThreadSnapshot snapshot = thread.snapshot();
  EXPECT_EQ(snapshot.period.count, count - 1);
  std::vector<double> sorted_us;
  for (std::size_t k = 1; k < count; ++k) sorted_us.push_back(1e6 * cycle.dts()[k]);
  std::sort(sorted_us.begin(), sorted_us.end());
  const rt::ControlThreadStatistics statistics = thread.statistics();
  EXPECT_NEAR(statistics.period_min_us, sorted_us.front(), 1e-6);
  EXPECT_NEAR(statistics.period_max_us, sorted_us.back(), 1e-6);
  EXPECT_NEAR(statistics.period_p50_us, exact_quantile(sorted_us, 0.5),
              quantile_error_us(exact_quantile(sorted_us, 0.5)));
  EXPECT_NEAR(statistics.period_p99_us, exact_quantile(sorted_us, 0.99),
              quantile_error_us(exact_quantile(sorted_us, 0.99)));
  EXPECT_LE(statistics.period_min_us, statistics.period_p50_us);
  EXPECT_LE(statistics.period_p50_us, statistics.period_p99_us);
  EXPECT_LE(statistics.period_p99_us, statistics.period_max_us);
  // Units, whatever the load: on absolute deadlines no cycle starts early, so the median dt is
  // not below half the 1 ms period (milliseconds or seconds reported as microseconds would be),
  // and no dt exceeds the run (nanoseconds reported as microseconds would).
  EXPECT_GT(statistics.period_p50_us, 500.0);
  EXPECT_LT(statistics.period_max_us, 1e6 * 0.5);
}

TEST(ControlThread, CountsOverrunsOfASlowCycleWithHowLateTheyWere) {
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model);
  rt::MeasurementBuffer measurements(7);
  measurements.publish(at_rest(panda_ready()));
  // 2 ms period; every 10th cycle sleeps 5 ms in the sink, so it ends at least 3 ms after the
  // next deadline.
  SleepingSink sink(10, std::chrono::microseconds(5000));
  rt::ControlThreadOptions options;
  options.rate = 500.0;
  rt::ControlThread thread(options);
  const Clock::time_point started = Clock::now();
  thread.start(loop, measurements, &sink);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const rt::ControlThreadSnapshot middle = thread.snapshot();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  thread.stop();
  const Clock::time_point stopped = Clock::now();

  const rt::ControlThreadStatistics statistics = thread.statistics();
  ASSERT_GT(sink.slow(), 3);
  EXPECT_GE(statistics.overruns, static_cast<std::uint64_t>(sink.slow()));
  EXPECT_GE(statistics.worst_lateness_us, 3000.0);
  EXPECT_GT(statistics.latest_lateness_us, 0.0);
  EXPECT_LE(statistics.latest_lateness_us, statistics.worst_lateness_us);
  // No burst after an overrun: never more cycles than deadlines.
  EXPECT_LE(static_cast<double>(statistics.cycles),
            seconds_between(started, stopped) * options.rate + 1.0);
  EXPECT_TRUE(sink.finite());
  EXPECT_EQ(loop.state().cycle, statistics.cycles);

  // The second half as a window: its counts add up to the whole; its worst lateness is there only
  // if it had overruns.
  const rt::ControlThreadSnapshot end = thread.snapshot();
  const rt::ControlThreadStatistics window = end.since(middle);
  const rt::ControlThreadStatistics first_half = middle.statistics();
  EXPECT_EQ(window.cycles + first_half.cycles, statistics.cycles);
  EXPECT_EQ(window.overruns + first_half.overruns, statistics.overruns);
  EXPECT_EQ(end.period.since(middle.period).count + middle.period.count, statistics.cycles - 1);
  EXPECT_EQ(window.worst_lateness_us > 0.0, window.overruns > 0);
  // Exact: the worst overrun was in one half, and a window that set the maximum knows it.
  EXPECT_EQ(std::max(window.worst_lateness_us, first_half.worst_lateness_us),
            statistics.worst_lateness_us);
  EXPECT_LE(window.period_max_us, statistics.period_max_us);
  // A snapshot from before this start() (another thread's counts): the window is since start().
  EXPECT_EQ(end.since(rt::ControlThreadSnapshot{}).cycles, statistics.cycles);
}

TEST(ControlThread, FailsClosedWithoutMeasurementsAndResumesWhenTheyReturn) {
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model);
  rt::MeasurementBuffer measurements(7);
  rt::TorqueOutbox torques(7);
  rt::ControlThreadOptions options;
  options.rate = 1000.0;
  options.measurement_timeout = 0.05;
  rt::ControlThread thread(options);
  thread.start(loop, measurements, &torques);
  // Nothing measured yet: the thread waits for a first measurement and does not cycle.
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  EXPECT_EQ(thread.state(), rt::ControlThread::State::preparing);
  EXPECT_EQ(thread.statistics().cycles, 0u);

  FakeRobot robot(measurements, panda_ready());
  ASSERT_TRUE(eventually([&] { return thread.running() && loop.latest_state().cycle > 50; }));
  EXPECT_EQ(loop.latest_state().controller.status, ci::Status::ok);
  EXPECT_FALSE(thread.statistics().stale);

  robot.on_ = false;  // the robot connection is lost
  ASSERT_TRUE(eventually([&] {
    return loop.latest_state().controller.status == ci::Status::invalid_robot_state &&
           thread.statistics().stale;
  }));
  // The torque ramps to zero (the controller's fail-closed reaction), and the sink sees it.
  ci::runtime::TorqueSample sample;
  ASSERT_TRUE(eventually(
      [&] { return torques.wait(0.1, sample) && sample.tau.cwiseAbs().maxCoeff() < 1e-9; }));

  robot.on_ = true;
  ASSERT_TRUE(eventually([&] {
    return loop.latest_state().controller.status == ci::Status::ok && !thread.statistics().stale;
  }));
  thread.stop();
  EXPECT_EQ(thread.statistics().stale_episodes, 1u);
}

// The age of a measurement runs from the driver's stamp, else from its receipt, to the cycle that
// uses it: the stamp's age plus up to one of the robot's periods (about 1.1 ms) and the
// scheduler's delay.
TEST(ControlThread, ReportsTheAgeOfTheMeasurementsItUsedFromTheirStamps) {
  const ci::RobotModel model = panda();
  for (const int age_us : {0, 5000, 20000}) {
    SCOPED_TRACE(age_us);
    ci::ControlLoop loop(model);
    rt::MeasurementBuffer measurements(7);
    rt::ControlThread thread(options_with(1000.0));
    const auto age = age_us > 0 ? std::optional(std::chrono::microseconds(age_us)) : std::nullopt;
    FakeRobot robot(measurements, panda_ready(), age);
    thread.start(loop, measurements, nullptr);
    ASSERT_TRUE(eventually([&] { return thread.statistics().cycles > 300; }));
    const rt::ControlThreadStatistics statistics = thread.statistics();
    thread.stop();
    EXPECT_GE(statistics.measurement_age_p50_us, age_us);
    EXPECT_LE(statistics.measurement_age_p50_us, age_us + 3000.0);
    EXPECT_LE(statistics.measurement_age_p50_us, statistics.measurement_age_p99_us);
    EXPECT_LE(statistics.measurement_age_p99_us, statistics.measurement_age_max_us);
    EXPECT_GE(statistics.measurement_age_max_us, age_us + 500.0);  // a robot period goes by
  }
}

TEST(ControlThread, StartsAtTheFirstCompleteFiniteMeasurement) {
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model);
  rt::MeasurementBuffer measurements(7);
  rt::ControlThread thread;
  thread.start(loop, measurements, nullptr);
  rt::JointMeasurement measured = at_rest(panda_ready());
  measured.q[2] = std::nan("");
  measurements.publish(measured);
  ASSERT_TRUE(eventually([&] { return thread.rejected_starts().count == 1; }));
  EXPECT_STREQ(thread.rejected_starts().latest->fault().input, "q");
  EXPECT_EQ(thread.state(), rt::ControlThread::State::preparing);

  measured.q[2] = 0.1;
  measurements.publish(measured);
  ASSERT_TRUE(eventually([&] { return loop.latest_state().cycle > 0; }));
  EXPECT_NEAR(loop.latest_state().q[2], 0.1, 1e-12);
  thread.stop();
}

// A first measurement the controller cannot start from is what a running cycle fails closed on:
// the thread rejects it (naming the fault), keeps waiting and starts at the next good one, as the
// cycle would resume there. Each measurement is tried once.
TEST(ControlThread, RejectsFirstMeasurementsItCannotStartFromAndStartsAtTheNextGoodOne) {
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model);
  rt::MeasurementBuffer measurements(7);
  rt::JointMeasurement measured = at_rest(panda_ready());
  measured.dq[3] = 50.0;  // [rad/s] beyond plausibility.joint_velocity (10 rad/s)
  measurements.publish(measured);
  rt::ControlThread thread;
  thread.start(loop, measurements, nullptr);
  ASSERT_TRUE(eventually([&] { return thread.rejected_starts().count == 1; }));
  // 20 periods later: still waiting, the same measurement not tried again, nothing stepped.
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(thread.state(), rt::ControlThread::State::preparing);
  EXPECT_EQ(thread.statistics().cycles, 0u);
  rt::RejectedStarts rejected = thread.rejected_starts();
  EXPECT_EQ(rejected.count, 1u);
  ASSERT_TRUE(rejected.latest.has_value());
  EXPECT_STREQ(rejected.latest->fault().input, "dq");
  EXPECT_EQ(rejected.latest->fault().index, 3);
  EXPECT_EQ(rejected.latest->fault().value, 50.0);

  measured.dq[3] = 0.0;
  measured.q[3] = 1.0;  // joint 4 of the Panda bends the other way only: outside its limits
  measurements.publish(measured);
  ASSERT_TRUE(eventually([&] { return thread.rejected_starts().count == 2; }));
  rejected = thread.rejected_starts();
  EXPECT_STREQ(rejected.latest->fault().input, "q");
  EXPECT_NE(std::string(rejected.latest->what()).find("outside the joint's limits"),
            std::string::npos)
      << rejected.latest->what();
  EXPECT_EQ(thread.state(), rt::ControlThread::State::preparing);

  measured.q = panda_ready();
  measurements.publish(measured);
  ASSERT_TRUE(eventually([&] { return thread.running() && loop.latest_state().cycle > 0; }));
  EXPECT_EQ(loop.latest_state().controller.status, ci::Status::ok);
  EXPECT_NEAR(loop.latest_state().q[3], panda_ready()[3], 1e-12);
  EXPECT_EQ(thread.failure(), "");
  thread.stop();
  // A new start() counts its own rejections.
  rt::MeasurementBuffer nothing(7);
  thread.start(loop, nothing, nullptr);
  EXPECT_EQ(thread.rejected_starts().count, 0u);
  EXPECT_FALSE(thread.rejected_starts().latest.has_value());
  thread.stop();
}

// Any other exception of prepare() ends the thread in State::failed with its message.
class FailingCycle : public rt::Cycle {
 public:
  bool prepare() override { throw ci::Error("the simulation cannot start"); }
  rt::Freshness execute(const rt::CycleTime&) noexcept override { return rt::Freshness::fresh; }
};

TEST(ControlThread, ReportsWhyACycleCouldNotStart) {
  FailingCycle failing;
  rt::ControlThread thread;
  thread.start(failing);
  ASSERT_TRUE(eventually([&] { return thread.state() == rt::ControlThread::State::failed; }));
  EXPECT_EQ(thread.failure(), "the simulation cannot start");
  EXPECT_EQ(thread.statistics().cycles, 0u);
  // A failed thread may be started again.
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model);
  rt::MeasurementBuffer measurements(7);
  measurements.publish(at_rest(panda_ready()));
  thread.start(loop, measurements, nullptr);
  ASSERT_TRUE(eventually([&] { return thread.running(); }));
  EXPECT_EQ(thread.failure(), "");
  thread.stop();
}

TEST(ControlThread, StopsPromptlyWhileCyclingAndWhilePreparing) {
  // Stopping takes at most one period plus the cycle in progress (here 10 ms and nothing): the
  // bound of 1 s only catches a thread that does not stop.
  rt::ControlThread thread(options_with(100.0));
  RecordingCycle cycle(1000);
  start_cycling(thread, cycle);
  if (::testing::Test::HasFatalFailure()) return;
  Clock::time_point before = Clock::now();
  thread.stop();
  EXPECT_LT(seconds_between(before, Clock::now()), 1.0);
  const std::size_t count = cycle.count();
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  EXPECT_EQ(cycle.count(), count);
  EXPECT_EQ(thread.state(), rt::ControlThread::State::stopped);

  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model);
  rt::MeasurementBuffer nothing(7);
  thread.start(loop, nothing, nullptr);
  EXPECT_THROW(thread.start(cycle), ci::Error);  // one thread at a time
  before = Clock::now();
  thread.stop();
  EXPECT_LT(seconds_between(before, Clock::now()), 1.0);
  EXPECT_EQ(thread.state(), rt::ControlThread::State::stopped);
  thread.stop();  // again: nothing happens
}

TEST(ControlThread, FallsBackToNormalSchedulingAndSaysWhy) {
  rt::ControlThread thread(options_with(1000.0, 20));
  RecordingCycle cycle(100);
  start_cycling(thread, cycle);
  if (::testing::Test::HasFatalFailure()) return;
  // Either granted (the process may raise its priority) or refused with a reason: it runs anyway.
  EXPECT_EQ(thread.statistics().realtime, thread.scheduling_error() == 0);
  thread.stop();
}

TEST(ControlThread, RejectsBadOptions) {
  rt::ControlThreadOptions options;
  options.rate = 0.0;
  EXPECT_THROW(rt::ControlThread{options}, ci::Error);
  options.rate = std::nan("");
  EXPECT_THROW(rt::ControlThread{options}, ci::Error);
  // Periods count whole nanoseconds: 1e-11 Hz (1e20 ns) would overflow them, and 1e7 Hz is
  // no control cycle.
  options.rate = 1e-11;
  EXPECT_THROW(rt::ControlThread{options}, ci::Error);
  options.rate = 1e7;
  EXPECT_THROW(rt::ControlThread{options}, ci::Error);
  options = {};
  options.measurement_timeout = -1.0;
  EXPECT_THROW(rt::ControlThread{options}, ci::Error);
  options.measurement_timeout = 1e300;
  EXPECT_THROW(rt::ControlThread{options}, ci::Error);
  options = {};
  options.realtime_priority = 100;
  EXPECT_THROW(rt::ControlThread{options}, ci::Error);

  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model);
  rt::MeasurementBuffer six(6);
  rt::ControlThread thread;
  EXPECT_THROW(thread.start(loop, six, nullptr), ci::Error);
  EXPECT_THROW(rt::MeasurementBuffer(0), ci::Error);
  EXPECT_THROW(rt::TorqueOutbox(ci::kMaxJoints + 1), ci::Error);
}

TEST(TorqueOutbox, HandsEachCycleOnOnceAndWakesForShutdown) {
  rt::TorqueOutbox outbox(3);
  rt::TorqueSample sample;
  EXPECT_FALSE(outbox.wait(0.01, sample));  // nothing yet
  outbox.write(ci::JointVector::Constant(3, 1.0), 1);
  outbox.write(ci::JointVector::Constant(3, 2.0), 2);
  ASSERT_TRUE(outbox.wait(0.01, sample));  // the newest
  EXPECT_EQ(sample.cycle, 2u);
  EXPECT_EQ(sample.tau, ci::JointVector::Constant(3, 2.0));
  EXPECT_FALSE(outbox.wait(0.01, sample));  // the second post: the same cycle, not again
  outbox.wake();
  EXPECT_FALSE(outbox.wait(1.0, sample));
}

TEST(TorqueOutbox, AWakeBeforeAnyTorqueReturnsNoTorque) {
  // The outbox starts with a zero torque in its buffer that no cycle wrote: a consumer woken for
  // shutdown before the first cycle must not get it as one (it would send the robot zero).
  rt::TorqueOutbox outbox(3);
  rt::TorqueSample sample;
  outbox.wake();
  EXPECT_FALSE(outbox.wait(1.0, sample));
  outbox.write(ci::JointVector::Constant(3, 1.0), 0);  // a sink may number its first cycle 0
  ASSERT_TRUE(outbox.wait(0.01, sample));
  EXPECT_EQ(sample.cycle, 0u);
  EXPECT_EQ(sample.tau, ci::JointVector::Constant(3, 1.0));
}

TEST(MeasurementBuffer, NumbersAndStampsEachMeasurement) {
  rt::MeasurementBuffer buffer(2);
  rt::JointMeasurement out;
  buffer.read(out);
  EXPECT_EQ(out.sequence, 0u);
  EXPECT_EQ(out.q, ci::JointVector::Zero(2));
  rt::JointMeasurement in;
  in.q = ci::JointVector::Constant(2, 0.5);
  in.dq = ci::JointVector::Zero(2);
  in.effort = ci::JointVector::Constant(2, 3.0);
  in.sequence = 99;  // replaced
  const Clock::time_point before = rt::monotonic_now();
  buffer.publish(in);
  buffer.publish(in);
  buffer.read(out);
  EXPECT_EQ(out.sequence, 2u);
  EXPECT_EQ(out.q, in.q);
  EXPECT_EQ(out.effort, in.effort);
  EXPECT_GE(out.received, before);
  EXPECT_LE(out.received, rt::monotonic_now());
  EXPECT_EQ(out.sampled, out.received);  // no stamp: measured when received

  in.sampled = before - std::chrono::milliseconds(7);  // a driver's stamp is kept
  buffer.publish(in);
  buffer.read(out);
  EXPECT_EQ(out.sampled, in.sampled);
  in.sampled = rt::monotonic_now() + std::chrono::seconds(1);  // a clock ahead of ours
  buffer.publish(in);
  buffer.read(out);
  EXPECT_EQ(out.sampled, out.received);
}
