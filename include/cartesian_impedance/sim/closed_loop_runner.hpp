#pragma once
/// @file
/// The one closed loop of a simulation and its controllers: each step, every ControlLoop computes
/// the torque for its slice of the simulated joints from their measured state, and the simulation
/// applies the torques and advances one timestep. Scenarios, benchmarks and Python run it as fast
/// as they can in simulated time (run(), run_for()); the ROS node runs it at real-time rate on a
/// runtime::ControlThread, which executes one step per cycle.
///
/// Threads: one thread at a time drives the runner (start, step, run, or a ControlThread running
/// it). Other threads may send commands to the loops meanwhile (ControlLoop is made for that)
/// and may call request_stop(). The simulation itself is not thread-safe: do not touch it from
/// elsewhere while the runner runs.

#include <atomic>
#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/runtime/control_thread.hpp"
#include "cartesian_impedance/sim/simulation.hpp"

namespace cartesian_impedance::sim {

class ClosedLoopRunner final : public runtime::Cycle {
 public:
  /// Replaces the torque the loops computed before the simulation applies it (all loops' torques
  /// in the simulation's joint order, [Nm or N]). Runs inside step(): it must not throw or
  /// allocate. Used to break a controller on purpose in tests of the tests; a non-finite result
  /// is not applied (the previous torque stays).
  using TorqueHook = std::function<void(JointVector& tau)>;
  /// Called by run() after each step with the number of steps done in this run (1, 2, ...), e.g.
  /// to record samples. It may call request_stop(), and may throw: run() then ends with that
  /// exception (the step already done stays done).
  using StepObserver = std::function<void(std::int64_t steps_done)>;

  /// One loop driving every joint the simulation exchanges.
  /// @throws Error if the loop's model has other joints (or another order) than
  ///         simulation.joint_names().
  ClosedLoopRunner(Simulation& simulation, ControlLoop& loop);
  /// Several loops on one simulation, each driving its own consecutive slice of the simulation's
  /// joints, in the order given: the first loop the first num_joints() joints, and so on (load
  /// the simulation with SimulationOptions::joint_names = the models' joint names one after the
  /// other). With `prefixes` (one per loop), the simulation names loop i's joints
  /// prefixes[i] + the model's names, as make_robots_scene() does. The simulation and the loops
  /// must outlive the runner.
  /// @throws Error if `loops` is empty, holds a null pointer, `prefixes` is neither empty nor one
  ///         per loop, or the models' joint names one after the other (prefixed) are not
  ///         simulation.joint_names().
  ClosedLoopRunner(Simulation& simulation, const std::vector<ControlLoop*>& loops,
                   const std::vector<std::string>& prefixes = {});

  ClosedLoopRunner(const ClosedLoopRunner&) = delete;
  ClosedLoopRunner& operator=(const ClosedLoopRunner&) = delete;

  /// Starts (or restarts) every loop from the simulation's current state of its joints
  /// (ControlLoop::start). Loops started otherwise need not be started again.
  /// @throws Error as ControlLoop::start.
  void start();

  /// Set once before running (not while a thread runs the runner); an empty hook removes it.
  void set_torque_hook(TorqueHook hook) { torque_hook_ = std::move(hook); }

  /// One closed-loop step: tau_i = loop_i.step(q_i, dq_i, measured torque_i,
  /// simulation.timestep()) for each loop (the torque sensors' reading is used with
  /// collision.measured_torque),
  /// the torque hook, simulation.set_torque(tau), simulation.step(). Returns the torque
  /// commanded (before the simulation clips it to its actuators' ranges) [Nm or N]. noexcept, no
  /// allocation, no lock. A loop that was not started fails closed (ControlLoop::step).
  const JointVector& step() noexcept;

  /// Runs `steps` steps, calling `observer` (if any) after each, and returns how many ran: fewer
  /// if request_stop() was called (from the observer or another thread).
  /// @throws Error if steps < 0 or a loop has not been started; what the observer throws.
  std::int64_t run(std::int64_t steps, const StepObserver& observer = {});
  /// run() for round(seconds / simulation.timestep()) steps.
  /// @throws Error if seconds is not finite and >= 0; as run().
  std::int64_t run_for(double seconds, const StepObserver& observer = {});

  /// Ends the run() in progress after its current step. Any thread. A request made while no
  /// run() is in progress is forgotten when the next one begins.
  void request_stop() noexcept { stop_requested_.store(true, std::memory_order_relaxed); }

  /// The torque of the last step, as commanded (after the hook) [Nm or N]; zero before any.
  const JointVector& torque() const noexcept { return tau_; }
  Simulation& simulation() noexcept { return simulation_; }

  // ---- runtime::Cycle: a ControlThread runs one step per cycle -------------------------------

  /// start(), then ready. @throws Error as start().
  bool prepare() override;
  /// step(); the simulation is its own measurement, always fresh. The thread's dt is not used:
  /// each cycle advances simulated time by one timestep.
  runtime::Freshness execute(const runtime::CycleTime& time) noexcept override;

 private:
  struct Part {
    ControlLoop* loop;
    int offset;     // first joint in the simulation's order
    JointVector q;  // this loop's slice of the measured state
    JointVector dq;
    JointVector measured_torque;
  };

  Simulation& simulation_;
  std::vector<Part> parts_;
  JointVector tau_;
  TorqueHook torque_hook_;
  std::atomic<bool> stop_requested_{false};
};

}  // namespace cartesian_impedance::sim
