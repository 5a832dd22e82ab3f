#pragma once
/// @file
/// The ROS-free control thread every shell runs its control cycle on (ROS 1 and ROS 2 nodes, a
/// user's own robot driver, a simulation at real-time rate): a cycle at a fixed rate on absolute
/// deadlines, stale measurements failing the controller closed, and timing statistics (overruns,
/// their lateness, the measured period's quantiles) that any thread can read. The user provides
/// the cycle (usually a ControlLoop with a measurement source and a torque sink); the thread owns
/// the timing.
///
/// Timing: deadlines are absolute on CLOCK_MONOTONIC (clock_nanosleep with TIMER_ABSTIME), so
/// wake-up latency does not accumulate. A cycle that ends after the next deadline is an overrun:
/// the next cycle starts at once; if the thread fell more than a whole period behind, the
/// schedule restarts from now rather than running the missed cycles in a burst.
///
/// Threads: start() and stop() from one controlling thread; statistics(), snapshot(), state() and
/// failure() from any thread. Nothing in the cycle (the thread's own code between deadlines, and
/// the cycle implementations of this library) allocates, locks or throws.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/runtime/robot_io.hpp"
#include "cartesian_impedance/runtime/timing.hpp"

namespace cartesian_impedance::runtime {

/// When a cycle runs, as the control thread measured it.
struct CycleTime {
  std::chrono::steady_clock::time_point now{};  ///< when the cycle began (monotonic_now())
  double dt = 0.0;          ///< [s] since the previous cycle began; one period for the first
  std::uint64_t index = 0;  ///< cycles before this one since the thread started
};

/// Whether a cycle had a fresh measurement to work with.
enum class Freshness {
  fresh,  ///< a measurement newer than the timeout (or a simulation, always fresh)
  stale,  ///< none within the timeout: the controller was stepped with an invalid measurement
};

/// What Cycle::prepare() throws when it cannot start from what it has now but may later: the
/// robot cycle's measurement that the controller cannot start from (not finite, outside the joint
/// limits, faster than plausibility.joint_velocity). The thread keeps preparing, calls prepare()
/// again the next period, and counts and keeps the error (ControlThread::rejected_starts()), as a
/// cycle fails closed on such a measurement and resumes at the next good one. The error's fault()
/// names the input, as the cycle's would.
class StartRejected : public Error {
 public:
  /// The rejection of `cause` (its message and fault).
  explicit StartRejected(const Error& cause) : Error(cause) {}
};

/// What the control thread runs. Implementations in this library: the robot cycle behind
/// ControlThread::start(loop, measurements, sink), and sim::ClosedLoopRunner (a simulation stepped
/// once per cycle).
class Cycle {
 public:
  virtual ~Cycle() = default;

  /// Called in the control thread before the first cycle, again once per period for as long as it
  /// returns false (e.g. while waiting for the first measurement). Start the controller here.
  /// Not real-time: may allocate and throw. StartRejected means "not from this, try again" (the
  /// thread keeps preparing); any other exception ends the thread in State::failed with its
  /// message.
  virtual bool prepare() = 0;

  /// One control cycle. Real-time: must not allocate, lock or block.
  virtual Freshness execute(const CycleTime& time) noexcept = 0;
};

/// Fixed when the thread is created.
struct ControlThreadOptions {
  /// [Hz] cycles per second, within [kMinRate, kMaxRate]: a period from 1 us to 1000 s, counted
  /// in whole nanoseconds far from their overflow.
  double rate = 1000.0;
  /// [s] robot cycle: a measurement older than this counts as lost; > 0 and at most
  /// kMaxMeasurementTimeout (nanoseconds of the monotonic clock hold it without overflow).
  double measurement_timeout = 0.1;
  /// SCHED_FIFO priority of the thread, 1..99; 0 = normal scheduling. Without the permission
  /// (CAP_SYS_NICE or an rtprio limit) the thread runs at normal priority and
  /// ControlThread::scheduling_error() says why.
  int realtime_priority = 0;
};

/// The ranges of ControlThreadOptions.
inline constexpr double kMinRate = 1e-3;               ///< [Hz] a period of 1000 s
inline constexpr double kMaxRate = 1e6;                ///< [Hz] a period of 1 us
inline constexpr double kMaxMeasurementTimeout = 1e6;  ///< [s]

/// The starts that Cycle::prepare() rejected (StartRejected) since ControlThread::start().
struct RejectedStarts {
  std::uint64_t count = 0;      ///< how many (for the robot cycle: how many measurements)
  std::optional<Error> latest;  ///< the newest: its message and fault(); empty if none
};

/// Counters of the running (or last) thread, read from any thread (ControlThread::statistics()),
/// or over a window between two snapshots (ControlThreadSnapshot::since()). Each counter is read
/// atomically on its own; fields may be from neighbouring cycles.
struct ControlThreadStatistics {
  std::uint64_t cycles = 0;    ///< cycles run
  std::uint64_t overruns = 0;  ///< cycles that ended after the next cycle's deadline
  /// [us] how long after the next deadline the most recent overrun ended (0 before any).
  double latest_lateness_us = 0.0;
  double worst_lateness_us = 0.0;    ///< [us] the largest such lateness (0 without overruns)
  bool stale = false;                ///< the latest cycle had no fresh measurement
  std::uint64_t stale_episodes = 0;  ///< transitions from fresh to stale
  bool realtime = false;             ///< the thread runs with SCHED_FIFO priority
  /// [us] the measured period, the time between consecutive cycle starts (CycleTime::dt of every
  /// cycle but the first): smallest, median, 99th percentile and largest; 0 before the second
  /// cycle. The quantiles are within max(0.5 us, 0.4 %) (DurationHistogram). Min, max and the
  /// worst lateness are exact since start(); over a window, exact if the window set a new extreme,
  /// else a bound within max(1 us, 0.8 %).
  double period_min_us = 0.0;
  double period_p50_us = 0.0;
  double period_p99_us = 0.0;
  double period_max_us = 0.0;
  /// [us] the age of the measurement each robot cycle used (start(loop, measurements, sink)):
  /// from when the robot measured it (JointMeasurement::sampled, the driver's stamp, else when it
  /// was received) to the cycle's start; median, 99th percentile and largest, within the same
  /// bounds as the period's. The controller acts on the arm as it was this long ago, plus the
  /// torque's way back: the delay that sets the stiffness the arm can hold (README, "No silent
  /// limit cycle"). 0 before the first fresh measurement; stale cycles are not counted.
  double measurement_age_p50_us = 0.0;
  double measurement_age_p99_us = 0.0;
  double measurement_age_max_us = 0.0;
};

/// Everything the thread counted, at one moment: ControlThread::snapshot(). About 45 kB of
/// values (three histograms); taking one reads a few thousand atomics and allocates nothing.
struct ControlThreadSnapshot {
  std::uint64_t start = 0;  ///< which start() of the thread these counts are from (1, 2, ...)
  std::uint64_t cycles = 0;
  std::uint64_t overruns = 0;
  std::int64_t latest_lateness_ns = 0;
  bool stale = false;
  std::uint64_t stale_episodes = 0;
  bool realtime = false;
  DurationHistogram::Snapshot period;           ///< [ns] between consecutive cycle starts
  DurationHistogram::Snapshot lateness;         ///< [ns] of each overrun after the next deadline
  DurationHistogram::Snapshot measurement_age;  ///< [ns] of each fresh measurement used

  /// Since start().
  ControlThreadStatistics statistics() const noexcept;
  /// Over the window from `earlier` (a snapshot of the same thread) to this one: counts and
  /// period quantiles of the cycles in between, the worst lateness of the overruns in between;
  /// stale, realtime and latest_lateness_us as of now. Since start() if `earlier` is from
  /// before the latest start().
  ControlThreadStatistics since(const ControlThreadSnapshot& earlier) const noexcept;
};

/// The log line for the overruns in a window of `window_seconds` of a thread with a period of
/// `period_seconds`, e.g. "control cycle: 37 overruns of the 1 ms period in the last 5 s (worst
/// 412 us late); period p50 1000 us, p99 1130 us, max 1520 us". What the nodes log.
std::string overrun_summary(const ControlThreadStatistics& window, double period_seconds,
                            double window_seconds);

class ControlThread {
 public:
  enum class State {
    idle,       ///< not started
    preparing,  ///< started; Cycle::prepare() has not returned true yet
    running,    ///< cycling
    failed,     ///< Cycle::prepare() threw: see failure()
    stopped,    ///< stop() ended it
  };

  /// @throws Error naming the field if an option is out of range.
  explicit ControlThread(const ControlThreadOptions& options = {});
  /// Stops the thread (stop()).
  ~ControlThread();
  ControlThread(const ControlThread&) = delete;
  ControlThread& operator=(const ControlThread&) = delete;

  /// Starts a thread that prepares `cycle` and then executes it once per period until stop().
  /// `cycle` must outlive the thread. Resets the statistics. Sets the SCHED_FIFO priority of the
  /// options, falling back to normal scheduling if that is not permitted (scheduling_error()).
  /// @throws Error if a thread is preparing or running (stop() it first; one that failed is
  ///         replaced); std::system_error if no thread can be created.
  void start(Cycle& cycle);

  /// The robot cycle: each period reads the newest measurement from `measurements`; if it was
  /// received within options.measurement_timeout, steps `loop` with it (dt = the measured time
  /// since the previous cycle), otherwise steps it with NaN q and dq, so that the controller fails
  /// closed (status invalid_robot_state, the torque ramping toward zero within the rate limit)
  /// until measurements return; then hands the torque to `sink` (if not null). Prepare: waits
  /// for the first measurement the loop can start from and starts it there (ControlLoop::start).
  /// Each measurement is tried once; one that start() refuses (not finite, outside the joint
  /// limits, too fast: what would fail a cycle closed) is a StartRejected, counted in
  /// rejected_starts() with its fault, and the thread waits for the next one. `loop`,
  /// `measurements` and `sink` must outlive the thread.
  /// @throws Error as start(Cycle&), or if the buffer's joint count is not the loop's.
  void start(ControlLoop& loop, const MeasurementBuffer& measurements, TorqueSink* sink);

  /// Asks the thread to end and joins it: returns after the cycle in progress (or within one
  /// period while it is sleeping or preparing). Nothing happens if none runs.
  void stop() noexcept;

  State state() const noexcept { return state_.load(std::memory_order_acquire); }
  /// True from the first cycle until stop().
  bool running() const noexcept { return state() == State::running; }
  /// Why prepare failed (the exception's message), once state() is State::failed; else "".
  std::string failure() const;
  /// What prepare() rejected since start() (StartRejected), e.g. first measurements the
  /// controller cannot start from; a shell logs them while state() is State::preparing. Any
  /// thread; takes a lock that the cycle never takes.
  RejectedStarts rejected_starts() const;

  /// Counters, lateness and period quantiles since start() (snapshot().statistics()).
  ControlThreadStatistics statistics() const noexcept;
  /// Everything counted since start(), for statistics over a window: a logger keeps the snapshot
  /// of its last report and reports snapshot().since(last).
  ControlThreadSnapshot snapshot() const noexcept;
  /// The error number (errno value) pthread_setschedparam gave for the requested SCHED_FIFO
  /// priority, 0 if it was granted or none was requested.
  int scheduling_error() const noexcept { return scheduling_error_; }
  const ControlThreadOptions& options() const noexcept { return options_; }
  /// [s] 1 / rate.
  double period() const noexcept { return 1.0 / options_.rate; }

 private:
  void join_ended();
  bool prepare(Cycle& cycle);
  void body(Cycle& cycle) noexcept;
  void record(const CycleTime& time, Freshness freshness, std::int64_t end_ns,
              std::int64_t& deadline_ns) noexcept;

  ControlThreadOptions options_;
  std::int64_t period_ns_;
  std::unique_ptr<Cycle> robot_cycle_;  // what start(loop, measurements, sink) runs
  std::thread thread_;
  std::atomic<bool> stop_requested_{false};
  std::atomic<State> state_{State::idle};
  std::string failure_;  // written by the thread before it stores State::failed
  int scheduling_error_ = 0;
  mutable std::mutex rejections_mutex_;  // prepare() and rejected_starts(); never the cycle
  RejectedStarts rejections_;

  std::atomic<std::uint64_t> starts_{0};
  std::atomic<std::uint64_t> cycles_{0};
  std::atomic<std::uint64_t> overruns_{0};
  std::atomic<std::int64_t> latest_lateness_ns_{0};
  DurationHistogram period_;           // between consecutive cycle starts
  DurationHistogram lateness_;         // of each overrun
  DurationHistogram measurement_age_;  // of the measurement each robot cycle used
  std::atomic<bool> stale_{false};
  std::atomic<std::uint64_t> stale_episodes_{0};
  std::atomic<bool> realtime_{false};
};

}  // namespace cartesian_impedance::runtime
