#include "cartesian_impedance/sim/batch_runner.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <string>
#include <utility>

#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance::sim {

namespace {

std::string pair_name(std::size_t index) {
  return "pair " + std::to_string(index);
}

// As ClosedLoopRunner::run_for counts them, so a batch advances each pair exactly as far.
std::int64_t steps_for(double seconds, const Simulation& simulation, std::size_t index) {
  const double steps = seconds / simulation.timestep();
  constexpr double kMaxSteps = 9e18;  // below 2^63: llround of more is undefined
  if (!(steps <= kMaxSteps)) {
    throw Error(pair_name(index) + ": seconds = " + format_number(seconds) + " is " +
                format_number(steps) + " timesteps of " + format_number(simulation.timestep()) +
                " s, more than the " + format_number(kMaxSteps) + " a run can count");
  }
  return std::llround(steps);
}

}  // namespace

BatchRunner::BatchRunner(const std::vector<BatchPair>& pairs, int threads,
                         std::chrono::microseconds spin)
    : spin_(spin) {
  if (pairs.empty()) throw Error("a batch needs at least one (simulation, control loop) pair");
  if (spin.count() < 0 || spin > kMaxSpin) {
    throw Error("spin = " + std::to_string(spin.count()) + " us is outside [0, " +
                std::to_string(kMaxSpin.count()) + "] us");
  }
  if (threads < 0 || threads > kMaxThreads) {
    throw Error("threads = " + std::to_string(threads) + " is outside [0, " +
                std::to_string(kMaxThreads) + "] (0 = one per core)");
  }
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const BatchPair& pair = pairs[i];
    if (pair.simulation == nullptr) throw Error(pair_name(i) + ": the simulation is null");
    if (pair.loop == nullptr) throw Error(pair_name(i) + ": the control loop is null");
    for (std::size_t j = 0; j < i; ++j) {
      if (pairs[j].simulation == pair.simulation) {
        throw Error(pair_name(i) + ": its simulation is also pair " + std::to_string(j) +
                    "'s; each pair needs its own (they would run in parallel)");
      }
      if (pairs[j].loop == pair.loop) {
        throw Error(pair_name(i) + ": its control loop is also pair " + std::to_string(j) +
                    "'s; each pair needs its own (they would run in parallel)");
      }
    }
    try {
      runners_.push_back(std::make_unique<ClosedLoopRunner>(*pair.simulation, *pair.loop));
      loops_.push_back(pair.loop);
    } catch (const Error& error) {
      throw Error(pair_name(i) + ": " + error.what());
    }
  }
  planned_.assign(pairs.size(), 0);
  done_.assign(pairs.size(), 0);

  if (threads == 0) {
    threads = static_cast<int>(std::min<unsigned>(std::max(1u, std::thread::hardware_concurrency()),
                                                  static_cast<unsigned>(kMaxThreads)));
  }
  threads = std::min(threads, static_cast<int>(pairs.size()));
  threads_ = threads;
  // The caller's thread is one of them: it runs pairs too instead of only waiting, which saves
  // a thread wake per run (with one thread there is no pool at all).
  workers_.reserve(static_cast<std::size_t>(threads - 1));
  try {
    for (int k = 1; k < threads; ++k) workers_.emplace_back([this] { serve(); });
  } catch (...) {
    stop_workers();  // a thread that could not be started: end those that were
    throw;
  }
}

BatchRunner::~BatchRunner() {
  stop_workers();
}

void BatchRunner::stop_workers() noexcept {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    exiting_ = true;
    published_generation_.store(~std::uint64_t{0}, std::memory_order_release);  // no more spin
  }
  wake_.notify_all();
  for (std::thread& worker : workers_) {
    if (worker.joinable()) worker.join();
  }
}

ClosedLoopRunner& BatchRunner::runner(std::size_t index) {
  if (index >= runners_.size()) {
    throw Error("pair index " + std::to_string(index) + " is outside [0, " +
                std::to_string(runners_.size()) + ")");
  }
  return *runners_[index];
}

const std::vector<std::int64_t>& BatchRunner::run(std::int64_t steps, const Poll& poll,
                                                  double poll_interval) {
  if (steps < 0) throw Error("steps = " + std::to_string(steps) + " must be >= 0");
  std::fill(planned_.begin(), planned_.end(), steps);
  run_planned(poll, poll_interval);
  return done_;
}

const std::vector<std::int64_t>& BatchRunner::run_for(double seconds, const Poll& poll,
                                                      double poll_interval) {
  if (!(seconds >= 0.0) || !std::isfinite(seconds)) {
    throw Error("seconds = " + format_number(seconds) + " must be finite and >= 0");
  }
  for (std::size_t i = 0; i < runners_.size(); ++i) {
    planned_[i] = steps_for(seconds, runners_[i]->simulation(), i);
  }
  run_planned(poll, poll_interval);
  return done_;
}

void BatchRunner::run_planned(const Poll& poll, double poll_interval) {
  if (!(poll_interval > 0.0) || !std::isfinite(poll_interval)) {
    throw Error("poll_interval = " + format_number(poll_interval) + " s must be finite and > 0");
  }
  for (std::size_t i = 0; i < runners_.size(); ++i) {
    if (!loops_[i]->started()) {
      throw Error(pair_name(i) +
                  ": the control loop has not been started: call loop.start(q, dq) with the "
                  "simulation's state first");
    }
  }
  stop_requested_.store(false, std::memory_order_relaxed);
  next_pair_.store(0, std::memory_order_relaxed);
  std::fill(done_.begin(), done_.end(), 0);

  std::unique_lock<std::mutex> lock(mutex_);
  busy_ = static_cast<int>(workers_.size());
  ++generation_;
  published_generation_.store(generation_, std::memory_order_release);
  lock.unlock();
  wake_.notify_all();

  poll_ = poll ? &poll : nullptr;
  poll_interval_ = std::chrono::duration<double>(poll_interval);
  last_poll_ = std::chrono::steady_clock::now();
  poll_error_ = nullptr;
  work(true);
  lock.lock();
  const auto all_done = [this] { return busy_ == 0; };
  // The pool's threads may still be on their last pairs: wait for them, polling meanwhile.
  while (!finished_.wait_for(lock, poll_interval_, all_done)) {
    lock.unlock();
    poll_if_due();
    lock.lock();
  }
  poll_ = nullptr;
  if (poll_error_) std::rethrow_exception(std::exchange(poll_error_, nullptr));
}

void BatchRunner::poll_if_due() noexcept {
  if (poll_ == nullptr || poll_error_) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_poll_ < poll_interval_) return;
  try {
    (*poll_)();
  } catch (...) {
    poll_error_ = std::current_exception();
    request_stop();
  }
  last_poll_ = std::chrono::steady_clock::now();
}

void BatchRunner::work(bool caller) noexcept {
  // Each pair runs whole on the thread that takes it, so its steps run in order, as alone.
  for (std::size_t i = next_pair_.fetch_add(1, std::memory_order_relaxed); i < runners_.size();
       i = next_pair_.fetch_add(1, std::memory_order_relaxed)) {
    ClosedLoopRunner& runner = *runners_[i];
    const std::int64_t steps = planned_[i];
    std::int64_t done = 0;
    while (done < steps && !stop_requested_.load(std::memory_order_relaxed)) {
      runner.step();
      ++done;
      if (caller && done % kPollCheckSteps == 0) poll_if_due();
    }
    done_[i] = done;
  }
}

void BatchRunner::serve() noexcept {
  std::uint64_t seen = 0;
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    // Waking a sleeping thread takes up to half a millisecond on a virtual machine, as long as
    // 100 steps of a pair: after a run, look for the next one without sleeping for spin_ (a
    // learning loop's next call comes within microseconds), then sleep.
    lock.unlock();
    const auto spin_end = std::chrono::steady_clock::now() + spin_;
    while (published_generation_.load(std::memory_order_acquire) == seen &&
           std::chrono::steady_clock::now() < spin_end) {
      std::this_thread::yield();
    }
    lock.lock();
    wake_.wait(lock, [&] { return exiting_ || generation_ != seen; });
    if (exiting_) return;
    seen = generation_;
    lock.unlock();
    work(false);
    lock.lock();
    if (--busy_ == 0) finished_.notify_all();
  }
}

}  // namespace cartesian_impedance::sim
