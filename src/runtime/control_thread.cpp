#include "cartesian_impedance/runtime/control_thread.hpp"

#include <pthread.h>
#include <sched.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>

#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance::runtime {

namespace {

constexpr std::int64_t kNanosecondsPerSecond = 1000000000;

std::int64_t now_ns() noexcept {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<std::int64_t>(now.tv_sec) * kNanosecondsPerSecond + now.tv_nsec;
}

// Sleeps until the absolute CLOCK_MONOTONIC time `deadline_ns` (at once if it has passed).
void sleep_until_ns(std::int64_t deadline_ns) noexcept {
  timespec deadline{};
  deadline.tv_sec = static_cast<time_t>(deadline_ns / kNanosecondsPerSecond);
  deadline.tv_nsec = static_cast<long>(deadline_ns % kNanosecondsPerSecond);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &deadline, nullptr) == EINTR) {
  }
}

std::chrono::steady_clock::time_point time_point_of(std::int64_t ns) noexcept {
  return std::chrono::steady_clock::time_point(std::chrono::nanoseconds(ns));
}

// Within [min, max] (min itself excluded if `min_exclusive`); NaN is outside.
void check_range(const char* name, double value, const char* unit, double min, double max,
                 bool min_exclusive) {
  const bool above_min = min_exclusive ? value > min : value >= min;
  if (!(above_min && value <= max)) {
    throw Error(std::string("control thread: ") + name + " = " + format_number(value) + " " + unit +
                " is outside " + (min_exclusive ? "(" : "[") + format_number(min) + ", " +
                format_number(max) + "]");
  }
}

// The cycle of ControlThread::start(loop, measurements, sink): a robot measured by a driver.
class RobotCycle final : public Cycle {
 public:
  RobotCycle(ControlLoop& loop, const MeasurementBuffer& measurements, TorqueSink* sink,
             double timeout, DurationHistogram& ages)
      : loop_(loop),
        measurements_(measurements),
        sink_(sink),
        ages_(ages),
        timeout_(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
            std::chrono::duration<double>(timeout))),
        invalid_(
            JointVector::Constant(loop.num_joints(), std::numeric_limits<double>::quiet_NaN())) {
    measurement_.q = measurement_.dq = measurement_.effort = JointVector::Zero(loop.num_joints());
  }

  // The first measurement the controller can start from starts it at the measured pose. One it
  // cannot start from is what a running cycle would fail closed on: rejected (with start()'s
  // fault), not fatal, and each measurement is tried once.
  bool prepare() override {
    measurements_.read(measurement_);
    if (measurement_.sequence == 0 || measurement_.sequence == tried_) return false;
    tried_ = measurement_.sequence;
    try {
      loop_.start(measurement_.q, measurement_.dq);
    } catch (const Error& error) {
      throw StartRejected(error);
    }
    return true;
  }

  Freshness execute(const CycleTime& time) noexcept override {
    measurements_.read(measurement_);
    // A lost robot connection is a bad measurement: the cycle reports invalid_robot_state and
    // ramps the torque toward zero within the rate limit, as for any invalid input.
    const bool fresh = time.now - measurement_.received <= timeout_;
    if (fresh) {
      ages_.record(
          std::chrono::duration_cast<std::chrono::nanoseconds>(time.now - measurement_.sampled)
              .count());
    }
    // The effort the robot reported is its measured joint torque, which the loop reads only with
    // collision.measured_torque.
    const JointVector& tau =
        fresh ? loop_.step(measurement_.q, measurement_.dq, measurement_.effort, time.dt)
              : loop_.step(invalid_, invalid_, time.dt);
    if (sink_ != nullptr) sink_->write(tau, loop_.state().cycle);
    return fresh ? Freshness::fresh : Freshness::stale;
  }

 private:
  ControlLoop& loop_;
  const MeasurementBuffer& measurements_;
  TorqueSink* sink_;
  DurationHistogram& ages_;
  std::chrono::steady_clock::duration timeout_;
  JointVector invalid_;
  JointMeasurement measurement_;
  std::uint64_t tried_ = 0;  // sequence of the measurement prepare() tried last
};

}  // namespace

ControlThread::ControlThread(const ControlThreadOptions& options) : options_(options) {
  check_range("rate", options.rate, "Hz", kMinRate, kMaxRate, false);
  check_range("measurement_timeout", options.measurement_timeout, "s", 0.0, kMaxMeasurementTimeout,
              true);
  const int highest = sched_get_priority_max(SCHED_FIFO);
  if (options.realtime_priority < 0 || options.realtime_priority > highest) {
    throw Error("control thread: realtime_priority = " + std::to_string(options.realtime_priority) +
                " is outside [0, " + std::to_string(highest) + "] (0 = normal scheduling)");
  }
  period_ns_ = std::llround(1e9 / options.rate);
}

ControlThread::~ControlThread() {
  stop();
}

void ControlThread::start(ControlLoop& loop, const MeasurementBuffer& measurements,
                          TorqueSink* sink) {
  join_ended();
  if (measurements.num_joints() != loop.num_joints()) {
    throw Error("control thread: the measurement buffer has " +
                std::to_string(measurements.num_joints()) + " joints, the control loop " +
                std::to_string(loop.num_joints()));
  }
  robot_cycle_ = std::make_unique<RobotCycle>(loop, measurements, sink,
                                              options_.measurement_timeout, measurement_age_);
  start(*robot_cycle_);
}

// A thread that failed has ended by itself: join it. One preparing or running is in the way.
void ControlThread::join_ended() {
  if (!thread_.joinable()) return;
  if (state() != State::failed) {
    throw Error("the control thread is already running: stop() it first");
  }
  thread_.join();
}

void ControlThread::start(Cycle& cycle) {
  join_ended();
  stop_requested_ = false;
  failure_.clear();
  scheduling_error_ = 0;
  starts_.store(starts_.load() + 1);
  cycles_ = 0;
  overruns_ = 0;
  latest_lateness_ns_ = 0;
  period_.reset();
  lateness_.reset();
  measurement_age_.reset();
  stale_ = false;
  stale_episodes_ = 0;
  realtime_ = false;
  {
    const std::lock_guard<std::mutex> lock(rejections_mutex_);
    rejections_ = {};
  }
  state_.store(State::preparing, std::memory_order_release);
  thread_ = std::thread([this, &cycle] { body(cycle); });
  if (options_.realtime_priority > 0) {
    sched_param parameters{};
    parameters.sched_priority = options_.realtime_priority;
    scheduling_error_ = pthread_setschedparam(thread_.native_handle(), SCHED_FIFO, &parameters);
    realtime_ = scheduling_error_ == 0;
  }
}

void ControlThread::stop() noexcept {
  stop_requested_ = true;
  if (!thread_.joinable()) return;
  try {
    thread_.join();
  } catch (...) {  // join() throws only for a thread that is not joinable or is this one
  }
}

std::string ControlThread::failure() const {
  return state() == State::failed ? failure_ : std::string();
}

RejectedStarts ControlThread::rejected_starts() const {
  const std::lock_guard<std::mutex> lock(rejections_mutex_);
  return rejections_;
}

bool ControlThread::prepare(Cycle& cycle) {
  try {
    return cycle.prepare();
  } catch (const StartRejected& rejection) {
    const std::lock_guard<std::mutex> lock(rejections_mutex_);
    ++rejections_.count;
    rejections_.latest.emplace(rejection);
    return false;
  }
}

ControlThreadStatistics ControlThread::statistics() const noexcept {
  return snapshot().statistics();
}

ControlThreadSnapshot ControlThread::snapshot() const noexcept {
  constexpr auto relaxed = std::memory_order_relaxed;
  ControlThreadSnapshot snapshot;
  snapshot.start = starts_.load(relaxed);
  snapshot.cycles = cycles_.load(relaxed);
  snapshot.overruns = overruns_.load(relaxed);
  snapshot.latest_lateness_ns = latest_lateness_ns_.load(relaxed);
  snapshot.stale = stale_.load(relaxed);
  snapshot.stale_episodes = stale_episodes_.load(relaxed);
  snapshot.realtime = realtime_.load(relaxed);
  snapshot.period = period_.snapshot();
  snapshot.lateness = lateness_.snapshot();
  snapshot.measurement_age = measurement_age_.snapshot();
  return snapshot;
}

namespace {

// The fields that do not depend on the window.
ControlThreadStatistics statistics_of(const ControlThreadSnapshot& snapshot,
                                      const DurationHistogram::Snapshot& period,
                                      const DurationHistogram::Snapshot& lateness,
                                      const DurationHistogram::Snapshot& age) noexcept {
  ControlThreadStatistics statistics;
  statistics.latest_lateness_us = 1e-3 * static_cast<double>(snapshot.latest_lateness_ns);
  statistics.worst_lateness_us = lateness.max_us();
  statistics.stale = snapshot.stale;
  statistics.realtime = snapshot.realtime;
  statistics.period_min_us = period.min_us();
  statistics.period_p50_us = period.quantile_us(0.5);
  statistics.period_p99_us = period.quantile_us(0.99);
  statistics.period_max_us = period.max_us();
  statistics.measurement_age_p50_us = age.quantile_us(0.5);
  statistics.measurement_age_p99_us = age.quantile_us(0.99);
  statistics.measurement_age_max_us = age.max_us();
  return statistics;
}

std::uint64_t difference(std::uint64_t later, std::uint64_t earlier) noexcept {
  return later >= earlier ? later - earlier : later;
}

}  // namespace

ControlThreadStatistics ControlThreadSnapshot::statistics() const noexcept {
  ControlThreadStatistics statistics = statistics_of(*this, period, lateness, measurement_age);
  statistics.cycles = cycles;
  statistics.overruns = overruns;
  statistics.stale_episodes = stale_episodes;
  return statistics;
}

ControlThreadStatistics ControlThreadSnapshot::since(
    const ControlThreadSnapshot& earlier) const noexcept {
  if (earlier.start != start) return statistics();
  ControlThreadStatistics statistics =
      statistics_of(*this, period.since(earlier.period), lateness.since(earlier.lateness),
                    measurement_age.since(earlier.measurement_age));
  statistics.cycles = difference(cycles, earlier.cycles);
  statistics.overruns = difference(overruns, earlier.overruns);
  statistics.stale_episodes = difference(stale_episodes, earlier.stale_episodes);
  return statistics;
}

void ControlThread::body(Cycle& cycle) noexcept {
  try {
    while (!prepare(cycle)) {
      if (stop_requested_.load(std::memory_order_relaxed)) {
        state_.store(State::stopped, std::memory_order_release);
        return;
      }
      sleep_until_ns(now_ns() + period_ns_);
    }
  } catch (const std::exception& error) {
    failure_ = error.what();
    state_.store(State::failed, std::memory_order_release);
    return;
  } catch (...) {
    failure_ = "unknown exception";
    state_.store(State::failed, std::memory_order_release);
    return;
  }
  state_.store(State::running, std::memory_order_release);

  // From here on: no allocation, no lock, no exception.
  std::int64_t deadline_ns = now_ns();  // when the cycle in progress was due
  std::int64_t previous_ns = 0;
  CycleTime time;
  while (!stop_requested_.load(std::memory_order_relaxed)) {
    const std::int64_t begin_ns = now_ns();
    time.now = time_point_of(begin_ns);
    time.dt = 1e-9 * static_cast<double>(time.index == 0 ? period_ns_ : begin_ns - previous_ns);
    if (time.index != 0) period_.record(begin_ns - previous_ns);
    previous_ns = begin_ns;
    const Freshness freshness = cycle.execute(time);
    record(time, freshness, now_ns(), deadline_ns);
    ++time.index;
    sleep_until_ns(deadline_ns);
  }
  state_.store(State::stopped, std::memory_order_release);
}

// Counts the cycle that just ended at `end_ns` and moves `deadline_ns` to the next cycle's.
void ControlThread::record(const CycleTime& time, Freshness freshness, std::int64_t end_ns,
                           std::int64_t& deadline_ns) noexcept {
  constexpr auto relaxed = std::memory_order_relaxed;
  const bool stale = freshness == Freshness::stale;
  if (stale != stale_.load(relaxed)) {
    if (stale) stale_episodes_.store(stale_episodes_.load(relaxed) + 1, relaxed);
    stale_.store(stale, relaxed);
  }
  cycles_.store(time.index + 1, relaxed);

  deadline_ns += period_ns_;
  const std::int64_t lateness = end_ns - deadline_ns;
  if (lateness > 0) {
    overruns_.store(overruns_.load(relaxed) + 1, relaxed);
    latest_lateness_ns_.store(lateness, relaxed);
    lateness_.record(lateness);
    // Far behind: skip the missed cycles instead of running them in a burst.
    if (lateness > period_ns_) deadline_ns = end_ns;
  }
}

std::string overrun_summary(const ControlThreadStatistics& window, double period_seconds,
                            double window_seconds) {
  char line[256];
  std::snprintf(line, sizeof line,
                "control cycle: %llu overrun%s of the %g ms period in the last %.0f s (worst %.0f "
                "us late); period p50 %.0f us, p99 %.0f us, max %.0f us",
                static_cast<unsigned long long>(window.overruns), window.overruns == 1 ? "" : "s",
                1e3 * period_seconds, window_seconds, window.worst_lateness_us,
                window.period_p50_us, window.period_p99_us, window.period_max_us);
  return line;
}

}  // namespace cartesian_impedance::runtime
