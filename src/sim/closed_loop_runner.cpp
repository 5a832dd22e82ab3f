#include "cartesian_impedance/sim/closed_loop_runner.hpp"

#include <cmath>
#include <string>

#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance::sim {

namespace {

std::string listed(const std::vector<std::string>& names) {
  std::string text;
  for (const std::string& name : names) text += (text.empty() ? "" : ", ") + name;
  return "[" + text + "]";
}

}  // namespace

ClosedLoopRunner::ClosedLoopRunner(Simulation& simulation, ControlLoop& loop)
    : ClosedLoopRunner(simulation, std::vector<ControlLoop*>{&loop}) {}

ClosedLoopRunner::ClosedLoopRunner(Simulation& simulation, const std::vector<ControlLoop*>& loops,
                                   const std::vector<std::string>& prefixes)
    : simulation_(simulation) {
  if (loops.empty()) throw Error("a closed loop needs at least one control loop");
  if (!prefixes.empty() && prefixes.size() != loops.size()) {
    throw Error("a closed loop of " + std::to_string(loops.size()) + " control loops got " +
                std::to_string(prefixes.size()) + " joint name prefixes; give one per loop");
  }
  std::vector<std::string> names;
  int offset = 0;
  for (std::size_t i = 0; i < loops.size(); ++i) {
    ControlLoop* loop = loops[i];
    if (loop == nullptr) throw Error("a closed loop's control loop is null");
    for (const std::string& joint : loop->model().joint_names()) {
      names.push_back(prefixes.empty() ? joint : prefixes[i] + joint);
    }
    const int n = loop->num_joints();
    parts_.push_back(
        {loop, offset, JointVector::Zero(n), JointVector::Zero(n), JointVector::Zero(n)});
    offset += n;
  }
  if (names != simulation.joint_names()) {
    throw Error("the simulation exchanges joints " + listed(simulation.joint_names()) +
                " but the control loops' models have " + listed(names) +
                ": load the simulation with joint_names = the models' joint names, in the loops' "
                "order");
  }
  tau_ = JointVector::Zero(offset);
}

void ClosedLoopRunner::start() {
  for (Part& part : parts_) {
    const int n = part.loop->num_joints();
    part.loop->start(simulation_.q().segment(part.offset, n),
                     simulation_.dq().segment(part.offset, n));
  }
}

const JointVector& ClosedLoopRunner::step() noexcept {
  const double dt = simulation_.timestep();
  if (parts_.size() == 1) {
    tau_ = parts_.front().loop->step(simulation_.q(), simulation_.dq(),
                                     simulation_.measured_torque(), dt);
  } else {
    for (Part& part : parts_) {
      const Eigen::Index n = part.q.size();
      part.q = simulation_.q().segment(part.offset, n);
      part.dq = simulation_.dq().segment(part.offset, n);
      part.measured_torque = simulation_.measured_torque().segment(part.offset, n);
      tau_.segment(part.offset, n) = part.loop->step(part.q, part.dq, part.measured_torque, dt);
    }
  }
  if (torque_hook_) torque_hook_(tau_);
  try {
    // The loops' torques are finite and sized, so this throws only for a hook's non-finite
    // torque, which is then not applied.
    simulation_.set_torque(tau_);
  } catch (...) {
  }
  simulation_.step();
  return tau_;
}

std::int64_t ClosedLoopRunner::run(std::int64_t steps, const StepObserver& observer) {
  if (steps < 0) throw Error("steps = " + std::to_string(steps) + " must be >= 0");
  for (const Part& part : parts_) {
    if (!part.loop->started()) {
      throw Error(
          "the control loop has not been started: call start() (or loop.start(q, dq)) first");
    }
  }
  stop_requested_.store(false, std::memory_order_relaxed);
  std::int64_t done = 0;
  while (done < steps) {
    step();
    ++done;
    if (observer) observer(done);
    if (stop_requested_.load(std::memory_order_relaxed)) break;
  }
  return done;
}

std::int64_t ClosedLoopRunner::run_for(double seconds, const StepObserver& observer) {
  if (!(seconds >= 0.0) || !std::isfinite(seconds)) {
    throw Error("seconds = " + format_number(seconds) + " must be finite and >= 0");
  }
  // The count of timesteps must fit the step counter (llround of a larger value is undefined).
  const double steps = seconds / simulation_.timestep();
  constexpr double kMaxSteps = 9e18;  // below 2^63
  if (!(steps <= kMaxSteps)) {
    throw Error("seconds = " + format_number(seconds) + " is " + format_number(steps) +
                " timesteps of " + format_number(simulation_.timestep()) + " s, more than the " +
                format_number(kMaxSteps) + " a run can count");
  }
  return run(std::llround(steps), observer);
}

bool ClosedLoopRunner::prepare() {
  start();
  return true;
}

runtime::Freshness ClosedLoopRunner::execute(const runtime::CycleTime& /*time*/) noexcept {
  step();
  return runtime::Freshness::fresh;
}

}  // namespace cartesian_impedance::sim
