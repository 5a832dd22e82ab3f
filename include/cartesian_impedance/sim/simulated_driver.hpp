#pragma once
/// @file
/// A stand-in for a robot's driver: a simulated arm that runs in real time on a thread of its
/// own and exchanges joint states and torques with the control thread exactly as a real driver
/// does (runtime/robot_io.hpp), so a program, a test or a Python policy runs the control thread
/// (runtime::ControlThread::start(loop, measurements, &torques)) against it unchanged.
///
/// Each tick, on absolute deadlines one simulation timestep apart (1 kHz for a 1 ms timestep):
/// take the newest torque from the TorqueOutbox (the driver is its one consumer), apply it, step
/// the simulation once, publish the measured q and dq to the MeasurementBuffer (the driver is its
/// one writer; stamped with when they were measured, Simulation::measurement_age() before the
/// tick) and publish the state for readers (state()). The thread is a runtime::ControlThread
/// running the tick as its cycle, so the ticks' timing is measured the same way (statistics()).
///
/// Torques, like a Panda on FCI:
/// - Before the first torque the arm is held, as by its brakes before control starts: the
///   simulation does not step, so nothing moves while the control thread is starting; q and dq
///   are published every tick all the same, so that the control thread can start.
/// - Once torques arrive, a tick without a new one applies the last one again (a lost packet).
/// - After options.torque_timeout without a new torque (FCI stops the arm after 20 lost packets
///   in a row at 1 kHz, libfranka's communication_constraints_violation) the arm is braked: its
///   velocity is set to zero and the simulation stops stepping until a new torque arrives. A
///   controller that stopped (or was never started) therefore leaves the arm where it was
///   instead of letting it fall or be pushed by a stale torque.
/// A torque of the wrong size or with a value that is not finite is not applied and counted
/// (SimulatedDriverState::rejected_torques): a drive refuses it; the last good torque stays.
///
/// Threads: start() and stop() from one controlling thread; state(), statistics() and
/// pause_measurements() from any thread. While the driver runs, nothing else may touch the
/// Simulation (it is not thread-safe), publish to the MeasurementBuffer or wait() on the
/// TorqueOutbox: read the arm through state() or the MeasurementBuffer.

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include "cartesian_impedance/core/types.hpp"
#include "cartesian_impedance/runtime/control_thread.hpp"
#include "cartesian_impedance/runtime/robot_io.hpp"
#include "cartesian_impedance/sim/simulation.hpp"

namespace cartesian_impedance::sim {

/// Fixed when the driver is created.
struct SimulatedDriverOptions {
  /// [s] of wall-clock time without a new torque after which the arm is braked; in
  /// (0, kMaxTorqueTimeout]. 0.02 s: the 20 lost packets at 1 kHz after which FCI stops a Panda.
  double torque_timeout = 0.02;
  /// SCHED_FIFO priority of the driver's thread, 1..99; 0 = normal scheduling (as
  /// runtime::ControlThreadOptions::realtime_priority).
  int realtime_priority = 0;
  /// A body of the simulation whose contact wrench each tick reports
  /// (SimulatedDriverState::contact_wrench; Simulation::contact_wrench_beyond: the flange with
  /// the hand and fingers beyond it); "" for none.
  std::string contact_body;
};

inline constexpr double kMaxTorqueTimeout = 1e6;  ///< [s]
/// [s] the longest pause_measurements() accepts.
inline constexpr double kMaxMeasurementPause = 1e6;

/// The simulated arm as of the driver's latest tick (or of start() before the first tick).
/// Fixed-size storage: copying it does not allocate.
struct SimulatedDriverState {
  double time = 0.0;  ///< [s] simulated time (advances one timestep per tick while not held)
  JointVector q;      ///< [rad or m] joint positions, in the simulation's joint order
  JointVector dq;     ///< [rad/s or m/s] joint velocities
  /// [Nm or N] the commanded torque applied in the tick (after the simulation's clipping to its
  /// actuators' ranges, without its gravity compensation); zero while held.
  JointVector tau;
  /// The arm is held (not stepped): before the first torque, and braked after a torque timeout.
  bool held = true;
  /// Ticks since start(), and those that ended after the next tick's deadline (the thread's
  /// statistics(): cycles and overruns, read when the state is).
  std::uint64_t ticks = 0;
  std::uint64_t late_ticks = 0;
  std::uint64_t steps = 0;             ///< simulation steps since start() (ticks not held)
  std::uint64_t torques = 0;           ///< new torques taken from the outbox since start()
  std::uint64_t torque_cycle = 0;      ///< the loop cycle of the newest one (TorqueSample::cycle)
  std::uint64_t torque_timeouts = 0;   ///< times the arm was braked because torques stopped
  std::uint64_t rejected_torques = 0;  ///< torques not applied: wrong size or not finite
  std::uint64_t measurements = 0;      ///< measurements published since start()
  bool measurements_paused = false;    ///< the latest tick published none (pause_measurements())
  /// [N; Nm] what everything else exerts on options.contact_body and the bodies beyond it, world
  /// frame, torque about the body's origin; zero without a contact body.
  Vector6d contact_wrench = Vector6d::Zero();
};

class SimulatedDriver {
 public:
  /// A driver for `simulation`, publishing to `measurements` and applying the torques of
  /// `torques`. All three must outlive the driver and have the same joint count; the joint order
  /// is the simulation's (Simulation::joint_names()), which the control loop's model must share.
  /// Its period is the simulation's timestep.
  /// @throws Error naming the joint counts if they differ, the option out of range, or a
  ///         contact_body the simulation does not have.
  SimulatedDriver(Simulation& simulation, runtime::MeasurementBuffer& measurements,
                  runtime::TorqueOutbox& torques, const SimulatedDriverOptions& options = {});
  /// Stops the driver (stop()).
  ~SimulatedDriver();
  SimulatedDriver(const SimulatedDriver&) = delete;
  SimulatedDriver& operator=(const SimulatedDriver&) = delete;

  /// Starts the thread: it publishes the simulation's current state at once and then ticks every
  /// timestep, the arm held until the first torque. Resets the counters of state().
  /// @throws Error if the driver is running (stop() it first); std::system_error if no thread
  ///         can be created.
  void start();
  /// Ends the thread after its current tick and joins it. Nothing happens if none runs. The
  /// simulation then stays as the last tick left it.
  void stop() noexcept;
  /// True from start() until stop().
  bool running() const noexcept;

  /// Makes the driver publish no measurement for the next `seconds` of wall-clock time while the
  /// arm goes on moving, as a driver that lost its connection: the control thread sees
  /// its measurements go stale and fails closed, and resumes when they return. 0 ends a pause.
  /// Any thread.
  /// @throws Error if seconds is not within [0, kMaxMeasurementPause].
  void pause_measurements(double seconds);

  /// The newest state (lock-free; any thread, also while running).
  SimulatedDriverState state() const noexcept;
  /// The ticks' timing since start(): cycles (ticks), overruns (late ticks), the measured period.
  runtime::ControlThreadStatistics statistics() const noexcept { return thread_.statistics(); }
  const SimulatedDriverOptions& options() const noexcept { return options_; }
  /// [s] the period of the ticks: the simulation's timestep.
  double period() const noexcept { return thread_.period(); }

 private:
  class Tick;  // the runtime::Cycle the thread runs

  SimulatedDriverOptions options_;
  std::unique_ptr<Tick> tick_;
  runtime::ControlThread thread_;  // last: stopped before the tick it runs goes away
};

}  // namespace cartesian_impedance::sim
