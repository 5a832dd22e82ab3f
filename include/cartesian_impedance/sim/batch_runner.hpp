#pragma once
/// @file
/// Many independent closed loops (a simulation and the control loop that drives it, e.g. the
/// environments of a learning batch or the samples of a parameter search) advanced by the same
/// simulated time on a small pool of threads. Each pair runs whole on one thread at a time and
/// shares nothing with the others, so every pair ends bit for bit where it would have ended
/// alone (ClosedLoopRunner::run_for on it): the threads change only how fast, never what.
///
/// Threads: one thread at a time calls run(), run_for() and the accessors; it runs pairs
/// itself beside the pool's threads. Other threads may send commands to the loops meanwhile
/// (ControlLoop is made for that) and may call request_stop(). Nothing else may touch the
/// simulations while a run is in progress. The threads live as long as the runner: a run only wakes
/// them.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/sim/closed_loop_runner.hpp"
#include "cartesian_impedance/sim/simulation.hpp"

namespace cartesian_impedance::sim {

/// One closed loop of a batch: a simulation and the control loop that drives all of its joints
/// (its model's joint names are the simulation's, in the same order). Both must outlive the
/// runner.
struct BatchPair {
  Simulation* simulation = nullptr;
  ControlLoop* loop = nullptr;
};

class BatchRunner {
 public:
  /// Called on the thread that called run() about every `poll_interval` [s] of wall time while
  /// the pairs run (between two steps of a pair that thread runs, or while it waits for the
  /// pool) (e.g. to let Python see Ctrl+C). It may call request_stop(), and may throw:
  /// the run then stops every pair after its current step and rethrows once all have stopped.
  using Poll = std::function<void()>;

  /// The largest pool a runner makes (threads = 0 chooses one per core up to this).
  static constexpr int kMaxThreads = 64;

  /// The default of `spin`: waking a sleeping thread takes up to half a millisecond on a virtual
  /// machine, as long as 100 steps of a pair, and a learning loop's next run comes within
  /// microseconds.
  static constexpr std::chrono::microseconds kDefaultSpin{2000};
  /// The longest spin accepted (1 s).
  static constexpr std::chrono::microseconds kMaxSpin{1000000};

  /// `threads`: how many threads run the pairs, at most one per pair (more would idle); 0 = one
  /// per core (std::thread::hardware_concurrency()). The thread that calls run() is one of them;
  /// the runner starts the others, which live as long as it does.
  /// `spin`: after a run, each pool thread looks for the next run without sleeping for this long
  /// (yielding the core to any thread that wants it) before it sleeps. 0 = sleep at once: no CPU
  /// used between runs, for processes that share their cores, at the cost of a wake-up per run.
  /// @throws Error naming the pair by its index: a null simulation or loop, a simulation or a
  ///         loop given in two pairs (they would race), a loop whose model's joints are not the
  ///         simulation's (names and order); if `pairs` is empty, or threads is outside
  ///         [0, kMaxThreads], or spin is outside [0, kMaxSpin].
  explicit BatchRunner(const std::vector<BatchPair>& pairs, int threads = 0,
                       std::chrono::microseconds spin = kDefaultSpin);
  ~BatchRunner();
  BatchRunner(const BatchRunner&) = delete;
  BatchRunner& operator=(const BatchRunner&) = delete;

  /// Number of pairs.
  std::size_t size() const noexcept { return runners_.size(); }
  /// Threads that run the pairs: the caller's and threads() - 1 of the pool.
  int threads() const noexcept { return threads_; }
  /// How long a pool thread spins after a run before it sleeps.
  std::chrono::microseconds spin() const noexcept { return spin_; }

  /// Advances every pair by `steps` closed-loop steps (ClosedLoopRunner::step: each loop's
  /// torque applied, the simulation one timestep further). Returns the steps each pair ran, in
  /// the pairs' order: `steps` for every pair unless request_stop() or the poll ended the run
  /// early. Allocates nothing.
  /// @throws Error before anything runs: steps < 0, or naming the first pair whose loop has not
  ///         been started; what the poll throws (after every pair stopped).
  const std::vector<std::int64_t>& run(std::int64_t steps, const Poll& poll = {},
                                       double poll_interval = 0.1);
  /// Advances every pair by round(seconds / its simulation's timestep) steps, as
  /// ClosedLoopRunner::run_for does for each alone (pairs may have different timesteps).
  /// @throws Error before anything runs: seconds not finite and >= 0 or too many timesteps for
  ///         a pair (named), poll_interval not > 0, as run().
  const std::vector<std::int64_t>& run_for(double seconds, const Poll& poll = {},
                                           double poll_interval = 0.1);

  /// Ends the run in progress: each pair stops after its current step. Any thread. A request
  /// made while no run is in progress is forgotten when the next one begins.
  void request_stop() noexcept { stop_requested_.store(true, std::memory_order_relaxed); }

  /// The closed loop of pair `index` (its torque(), its simulation()); not while a run is in
  /// progress. @throws Error if index >= size().
  ClosedLoopRunner& runner(std::size_t index);

 private:
  // The caller's thread checks whether a poll is due this often [steps].
  static constexpr std::int64_t kPollCheckSteps = 64;

  void run_planned(const Poll& poll, double poll_interval);
  void work(bool caller) noexcept;
  void poll_if_due() noexcept;
  void serve() noexcept;
  void stop_workers() noexcept;

  std::vector<std::unique_ptr<ClosedLoopRunner>> runners_;
  std::vector<ControlLoop*> loops_;
  std::vector<std::int64_t> planned_;  // steps each pair runs in this run
  std::vector<std::int64_t> done_;     // steps each pair ran in the last run
  std::atomic<std::size_t> next_pair_{0};
  std::atomic<bool> stop_requested_{false};
  int threads_ = 1;

  // The poll of the run in progress; the caller's thread alone uses these.
  const Poll* poll_ = nullptr;
  std::chrono::duration<double> poll_interval_{0.1};
  std::chrono::steady_clock::time_point last_poll_;
  std::exception_ptr poll_error_;

  // The pool: a run bumps generation_ and waits until busy_ is back at 0.
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable finished_;
  std::uint64_t generation_ = 0;
  std::atomic<std::uint64_t> published_generation_{0};  // generation_, read without the lock
  std::chrono::microseconds spin_ = kDefaultSpin;
  int busy_ = 0;
  bool exiting_ = false;
  std::vector<std::thread> workers_;
};

}  // namespace cartesian_impedance::sim
