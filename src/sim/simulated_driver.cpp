#include "cartesian_impedance/sim/simulated_driver.hpp"

#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/mailbox.hpp"

namespace cartesian_impedance::sim {

namespace {

std::int64_t nanoseconds_of(std::chrono::steady_clock::time_point time) noexcept {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(time.time_since_epoch()).count();
}

// `value` within (0, max] (or [0, max] if `zero_allowed`), else an Error whose fault names it.
void check_seconds(const char* field, double value, double max, bool zero_allowed) {
  const bool above_min = zero_allowed ? value >= 0.0 : value > 0.0;
  if (above_min && value <= max) return;
  const std::string range =
      std::string(zero_allowed ? "[" : "(") + "0, " + format_number(max) + "]";
  const std::string reason = "is outside " + range;
  Fault fault{field, -1, value, reason.c_str(), max, true, "s"};
  throw Error(fault, std::string("simulated driver: ") + field + " = " + format_number(value) +
                         " s " + reason);
}

runtime::ControlThreadOptions thread_options(const Simulation& simulation,
                                             const SimulatedDriverOptions& options) {
  runtime::ControlThreadOptions thread;
  thread.rate = 1.0 / simulation.timestep();
  // The tick is its own measurement: the thread never sees one go stale.
  thread.measurement_timeout = runtime::kMaxMeasurementTimeout;
  thread.realtime_priority = options.realtime_priority;
  return thread;
}

}  // namespace

// What the driver's thread runs each tick. Everything here is the thread's own but `states_`
// (read by any thread) and `pause_until_ns_` (written by any thread).
class SimulatedDriver::Tick final : public runtime::Cycle {
 public:
  Tick(Simulation& simulation, runtime::MeasurementBuffer& measurements,
       runtime::TorqueOutbox& torques, double torque_timeout, std::string contact_body)
      : simulation_(simulation),
        contact_body_(std::move(contact_body)),
        measurements_(measurements),
        torques_(torques),
        torque_timeout_(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
            std::chrono::duration<double>(torque_timeout))),
        sensing_delay_(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
            std::chrono::duration<double>(simulation.measurement_age()))),
        zero_(JointVector::Zero(simulation.num_joints())) {
    incoming_.tau = zero_;
    measurement_.q = measurement_.dq = measurement_.effort = zero_;
    reset();
  }

  // Before a start: the arm held until the first torque, the counters at zero. Not while the
  // thread runs.
  void reset() noexcept {
    counts_ = {};
    held_ = true;
    publish_state(false);
  }

  // A driver publishes the robot's state as soon as it connects: the control thread can start
  // before the first tick.
  bool prepare() override {
    publish_measurement(runtime::monotonic_now());
    publish_state(false);
    return true;
  }

  runtime::Freshness execute(const runtime::CycleTime& time) noexcept override {
    if (torques_.wait(0.0, incoming_)) take(incoming_, time.now);
    if (!held_ && time.now - last_torque_ > torque_timeout_) brake();
    if (!held_) {
      simulation_.step();
      ++counts_.steps;
    }
    const bool paused = nanoseconds_of(time.now) < pause_until_ns_.load(std::memory_order_relaxed);
    if (!paused) publish_measurement(time.now);
    publish_state(paused);
    return runtime::Freshness::fresh;
  }

  void pause_until(std::int64_t ns) noexcept { pause_until_ns_.store(ns); }

  SimulatedDriverState state() const noexcept {
    SimulatedDriverState state;
    states_.read(state);
    return state;
  }

 private:
  // A torque the drive accepts: the right size, every value finite.
  void take(const runtime::TorqueSample& sample, std::chrono::steady_clock::time_point now) {
    if (sample.tau.size() != zero_.size() || !sample.tau.allFinite()) {
      ++counts_.rejected_torques;
      return;
    }
    try {
      simulation_.set_torque(sample.tau);  // checked above: cannot throw
    } catch (...) {
      ++counts_.rejected_torques;
      return;
    }
    held_ = false;
    last_torque_ = now;
    ++counts_.torques;
    counts_.torque_cycle = sample.cycle;
  }

  // Torques stopped: the brakes stop the arm where it is, and hold it there.
  void brake() noexcept {
    held_ = true;
    ++counts_.torque_timeouts;
    const JointVector q = simulation_.q();
    try {
      simulation_.set_torque(zero_);
      simulation_.set_state(q, zero_);  // q is the simulation's own: finite, the right size
    } catch (...) {
    }
  }

  // Read at `now`, the reading is the plant's sensing delay old: its stamp says so.
  void publish_measurement(std::chrono::steady_clock::time_point now) noexcept {
    measurement_.sampled = now - sensing_delay_;
    measurement_.q = simulation_.q();
    measurement_.dq = simulation_.dq();
    measurement_.effort = simulation_.measured_torque();  // its joint torque sensors
    measurements_.publish(measurement_);
    ++counts_.measurements;
  }

  void publish_state(bool paused) noexcept {
    states_.publish_with([&](SimulatedDriverState& state) {
      state = counts_;
      state.time = simulation_.time();
      state.q = simulation_.q();
      state.dq = simulation_.dq();
      state.tau = held_ ? zero_ : simulation_.torque();
      state.held = held_;
      state.measurements_paused = paused;
      // The body was found at construction: this cannot throw.
      state.contact_wrench = contact_body_.empty()
                                 ? Vector6d::Zero()
                                 : simulation_.contact_wrench_beyond(contact_body_);
    });
  }

  Simulation& simulation_;
  std::string contact_body_;
  runtime::MeasurementBuffer& measurements_;
  runtime::TorqueOutbox& torques_;
  std::chrono::steady_clock::duration torque_timeout_;
  std::chrono::steady_clock::duration sensing_delay_;
  JointVector zero_;
  runtime::TorqueSample incoming_;
  runtime::JointMeasurement measurement_;
  bool held_ = true;
  std::chrono::steady_clock::time_point last_torque_{};
  SimulatedDriverState counts_;  // the counters; the arm's fields are filled when published
  SnapshotBuffer<SimulatedDriverState> states_;
  std::atomic<std::int64_t> pause_until_ns_{std::numeric_limits<std::int64_t>::min()};
};

SimulatedDriver::SimulatedDriver(Simulation& simulation, runtime::MeasurementBuffer& measurements,
                                 runtime::TorqueOutbox& torques,
                                 const SimulatedDriverOptions& options)
    : options_(options), thread_(thread_options(simulation, options)) {
  check_seconds("torque_timeout", options.torque_timeout, kMaxTorqueTimeout, false);
  const int n = simulation.num_joints();
  if (measurements.num_joints() != n || torques.num_joints() != n) {
    throw Error("simulated driver: the simulation has " + std::to_string(n) +
                " joints, the measurement buffer " + std::to_string(measurements.num_joints()) +
                " and the torque outbox " + std::to_string(torques.num_joints()) +
                "; all three must have the same");
  }
  if (!options.contact_body.empty()) simulation.contact_wrench_beyond(options.contact_body);
  tick_ = std::make_unique<Tick>(simulation, measurements, torques, options.torque_timeout,
                                 options.contact_body);
}

SimulatedDriver::~SimulatedDriver() {
  stop();
}

void SimulatedDriver::start() {
  if (running()) throw Error("the simulated driver is already running: stop() it first");
  tick_->reset();
  thread_.start(*tick_);
}

void SimulatedDriver::stop() noexcept {
  thread_.stop();
}

bool SimulatedDriver::running() const noexcept {
  const runtime::ControlThread::State state = thread_.state();
  return state == runtime::ControlThread::State::preparing ||
         state == runtime::ControlThread::State::running;
}

void SimulatedDriver::pause_measurements(double seconds) {
  check_seconds("seconds", seconds, kMaxMeasurementPause, true);
  const std::int64_t now = nanoseconds_of(runtime::monotonic_now());
  tick_->pause_until(now + std::llround(seconds * 1e9));
}

SimulatedDriverState SimulatedDriver::state() const noexcept {
  SimulatedDriverState state = tick_->state();
  const runtime::ControlThreadStatistics timing = thread_.statistics();
  state.ticks = timing.cycles;
  state.late_ticks = timing.overruns;
  return state;
}

}  // namespace cartesian_impedance::sim
