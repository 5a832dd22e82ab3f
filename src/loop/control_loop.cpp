#include "cartesian_impedance/loop/control_loop.hpp"

#include "cartesian_impedance/model/robot_limits.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <thread>

#include "cartesian_impedance/core/checks.hpp"
#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance {

namespace {
constexpr int kTrajectoryBuffers = 4;  // running, queued, being written, one spare
// Parameter sets are large (every field of the configuration); they wait in their own slots, and
// the inbox carries only the slot's index. The cycle applies at most kCommandsPerCycle per step.
constexpr int kParameterSets = 8;

}  // namespace

// Storage a sender fills and the cycle reads, and who owns it: free -> (sender) filling ->
// queued -> (cycle) running -> free. Only the owner touches the contents; ownership changes
// through `state`, so the cycle never allocates or frees.
struct ControlLoop::Slot {
  enum State : int { free, filling, queued, running };
  std::atomic<int> state{free};
};
struct ControlLoop::TrajectorySlot : Slot {
  TrajectorySlot(int num_joints, int max_points) : buffer(num_joints, max_points) {}
  TrajectoryBuffer buffer;
};
struct ControlLoop::ParameterSlot : Slot {
  std::optional<ValidCommand> parameters;
};

const char* to_string(TrajectoryState state) noexcept {
  switch (state) {
    case TrajectoryState::idle:
      return "idle";
    case TrajectoryState::executing:
      return "executing";
    case TrajectoryState::finished:
      return "finished";
    case TrajectoryState::aborted:
      return "aborted";
    case TrajectoryState::cancelled:
      return "cancelled";
  }
  return "unknown";
}

ControlLoop::ControlLoop(const RobotModel& model, const Parameters& parameters,
                         LoopCapacity capacity)
    : model_(model),
      workspace_(model_),
      reference_workspace_(model_),
      controller_(model_.num_joints(), with_robot_limits(parameters, model_)),
      kinematics_(workspace_.make_kinematics()),
      reference_kinematics_(reference_workspace_.make_kinematics()),
      robot_(make_robot_state(model_.num_joints())),
      inbox_(static_cast<std::size_t>(capacity.commands < 2 ? 2 : capacity.commands)) {
  const int n = model_.num_joints();
  check_dynamics(model_, controller_.parameters().dynamics);
  if (capacity.trajectory_points < 1) {
    throw Error("LoopCapacity.trajectory_points = " + std::to_string(capacity.trajectory_points) +
                " must be at least 1");
  }
  if (!(capacity.send_timeout >= 0.0 && capacity.send_timeout <= 60.0)) {
    throw Error("LoopCapacity.send_timeout = " + format_number(capacity.send_timeout) +
                " s is outside [0, 60]");
  }
  send_timeout_ = capacity.send_timeout;
  for (int i = 0; i < kTrajectoryBuffers; ++i) {
    buffers_.push_back(std::make_unique<TrajectorySlot>(n, capacity.trajectory_points));
  }
  for (int i = 0; i < kParameterSets; ++i)
    parameter_sets_.push_back(std::make_unique<ParameterSlot>());
  trajectory_q_ = JointVector::Zero(n);
  trajectory_dq_ = JointVector::Zero(n);
  lower_limits_ = model_.limits().position_lower;
  upper_limits_ = model_.limits().position_upper;
  robot_.mass = JointMatrix::Zero(n, n);
  robot_.gravity = JointVector::Zero(n);
  robot_.secondary_torque = JointVector::Zero(n);
  armature_ = per_joint(controller_.parameters().dynamics.armature, n);
  state_.q = JointVector::Zero(n);
  state_.dq = JointVector::Zero(n);
  publish_state();
  parameters_outbox_.publish(controller_.parameters());
}

ControlLoop::~ControlLoop() = default;

const RobotModel& ControlLoop::model() const noexcept {
  return model_;
}
int ControlLoop::num_joints() const noexcept {
  return model_.num_joints();
}

checks::MeasurementBounds ControlLoop::measurement_bounds() const noexcept {
  checks::MeasurementBounds bounds;
  bounds.lower = &lower_limits_;
  bounds.upper = &upper_limits_;
  bounds.margin = controller_.parameters().plausibility.joint_position_margin;
  bounds.speed = &controller_.joint_velocity_bound();
  return bounds;
}

void ControlLoop::start(const Eigen::Ref<const Eigen::VectorXd>& q,
                        const Eigen::Ref<const Eigen::VectorXd>& dq) {
  checks::raise(checks::measurement(q, dq, num_joints(), measurement_bounds()));
  const JointVector joints = q;
  // M and g as in every cycle (Coriolis is zero at rest): a start fails where they cannot be had.
  if (!workspace_.compute(joints, JointVector::Zero(num_joints()), kinematics_,
                          ModelTerms::mass | ModelTerms::gravity)) {
    throw Error("the robot model cannot be evaluated at q");
  }
  start(q, dq,
        controller_.parameters().dynamics.gravity_compensation
            ? Eigen::VectorXd(kinematics_.gravity)
            : Eigen::VectorXd::Zero(num_joints()));
}

void ControlLoop::start(const Eigen::Ref<const Eigen::VectorXd>& q,
                        const Eigen::Ref<const Eigen::VectorXd>& dq,
                        const Eigen::Ref<const Eigen::VectorXd>& tau_previous) {
  // The checks of every cycle (step()), thrown: first what needs no parameters, so that a bad
  // measurement changes nothing; then, once the commands sent before start took effect (in
  // order), the bounds they may have changed.
  checks::raise(checks::measurement(q, dq, num_joints()));
  apply_messages(inbox_.capacity());
  checks::raise(checks::measurement(q, dq, num_joints(), measurement_bounds()));
  const JointVector joints = q, velocities = dq;
  if (!workspace_.compute(joints, JointVector::Zero(num_joints()), kinematics_,
                          ModelTerms::mass | ModelTerms::gravity)) {
    throw Error("the robot model cannot be evaluated at q");
  }
  fill_robot_state(joints, velocities, kinematics_, robot_);
  controller_.start(robot_, tau_previous);
  if (active_buffer_ >= 0) end_trajectory(TrajectoryState::cancelled, false);
  state_.cycle = 0;
  state_.time = 0.0;
  state_.q = joints;
  state_.dq = velocities;
  state_.safety_changes = safety_changes_;
  state_.updates_refused = updates_refused_;
  publish_state();
  running_.store(true, std::memory_order_release);
}

namespace {
// Calls `attempt` until it succeeds or `timeout` [s] has passed, sleeping between attempts (the
// sender's thread waits; the cycle never does).
template <typename Attempt>
bool retry_for(double timeout, Attempt attempt) {
  if (attempt()) return true;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout);
  while (std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::microseconds(200));
    if (attempt()) return true;
  }
  return false;
}
}  // namespace

void ControlLoop::enqueue(const Message& message) {
  if (!retry_for(send_timeout_, [&] { return inbox_.push(message); })) {
    throw QueueFull("control loop inbox is full (" + std::to_string(inbox_.capacity()) +
                    " commands" +
                    (send_timeout_ > 0.0 ? " for " + format_number(send_timeout_) + " s" : "") +
                    "): is the loop stepping?");
  }
}

template <typename SlotType>
int ControlLoop::claim(std::vector<std::unique_ptr<SlotType>>& slots) const {
  int claimed = -1;
  retry_for(send_timeout_, [&] {
    for (std::size_t i = 0; i < slots.size(); ++i) {
      int expected = Slot::free;
      if (slots[i]->state.compare_exchange_strong(expected, Slot::filling)) {
        claimed = static_cast<int>(i);
        return true;
      }
    }
    return false;
  });
  return claimed;
}

void ControlLoop::allow_runtime_safety_changes(bool allow) {
  if (running_.load(std::memory_order_acquire)) {
    throw Error(
        "allow_runtime_safety_changes() after start(): whether safety settings may change "
        "while the robot runs is decided before it starts");
  }
  allow_safety_changes_ = allow;
}

void ControlLoop::check_safety_lock(const Command& command) const {
  if (allow_safety_changes_ || !running_.load(std::memory_order_acquire)) return;
  const Parameters* values = nullptr;
  ParameterNames named;
  if (const auto* whole = std::get_if<Parameters>(&command)) {
    values = whole;
    named.set();
  } else if (const auto* update = std::get_if<ParameterUpdate>(&command)) {
    values = &update->values;
    named = update->names;
  } else {
    return;
  }
  const Parameters current = latest_parameters();
  const ParameterNames locked = changed_parameters(current, *values) & named & safety_settings();
  if (locked.none()) return;
  const std::vector<ParameterInfo>& table = parameter_table();
  std::string names;
  for (std::size_t i = 0; i < table.size(); ++i) {
    if (!locked[i]) continue;
    const std::string unit = table[i].unit.empty() || table[i].unit == "-"
                                 ? std::string()
                                 : " " + std::string(table[i].unit);
    names += std::string(names.empty() ? "" : ", ") + std::string(table[i].name) + " = " +
             value_text(*values, table[i]) + unit + " (in force: " + value_text(current, table[i]) +
             unit + ")";
  }
  throw Error("safety settings are locked while the robot runs, and this would change " + names +
              "; only the program that owns the controller can allow run-time changes, before it "
              "starts (ControlLoop::allow_runtime_safety_changes(); in Python "
              "ControlLoop(..., allow_runtime_safety_changes=True); the nodes' setting "
              "allow_runtime_safety_changes); nothing was changed");
}

ValidCommand ControlLoop::validate(const Command& command) const {
  // Parameters are checked as the controller will use them: the torque bound the URDF gives
  // filled in, or a given one above it refused.
  const auto* given = std::get_if<Parameters>(&command);
  const auto* update = std::get_if<ParameterUpdate>(&command);
  Command checked = command;
  if (given != nullptr) {
    checked = with_robot_limits(*given, model_);
  } else if (update != nullptr) {
    checked = ParameterUpdate{with_robot_limits(update->values, model_), update->names};
  }
  ValidCommand valid = validate_command(std::move(checked), num_joints());
  if (const auto* valid_update = std::get_if<ParameterUpdate>(&valid.command())) {
    // Merged into the parameters in force as the cycle will merge it (unless another command
    // comes first: the cycle then checks again, and refuses it if it no longer fits).
    Parameters merged = latest_parameters();
    copy_parameters(valid_update->values, merged, valid_update->names);
    checks::raise(consistency_fault(merged));
  }
  check_safety_lock(valid.command());
  // What only the loop knows: a nullspace target within the URDF's joint limits (outside them the
  // nullspace spring would fight the limit).
  std::visit(Overloaded{[this](const NullspaceTarget& target) {
                          for (int i = 0; i < num_joints(); ++i) {
                            const double value = target.q_desired[i];
                            if (value < lower_limits_[i]) {
                              checks::raise(Fault{"nullspace_target", i, value,
                                                  "is below its joint's lower limit",
                                                  lower_limits_[i], true});
                            }
                            if (value > upper_limits_[i]) {
                              checks::raise(Fault{"nullspace_target", i, value,
                                                  "is above its joint's upper limit",
                                                  upper_limits_[i], true});
                            }
                          }
                        },
                        [](const auto&) {}},
             valid.command());
  // And whether the model can give what the dynamics options need.
  if (const auto* parameters = std::get_if<Parameters>(&valid.command())) {
    check_dynamics(model_, parameters->dynamics);
  } else if (const auto* checked_update = std::get_if<ParameterUpdate>(&valid.command())) {
    check_dynamics(model_, checked_update->values.dynamics);
  }
  return valid;
}

void ControlLoop::send(const Command& command) {
  ValidCommand valid = validate(command);
  const auto queue_parameters = [&](auto set) {
    const int claimed = claim(parameter_sets_);
    if (claimed < 0) {
      throw QueueFull("all " + std::to_string(parameter_sets_.size()) +
                      " parameter sets are queued: is the loop stepping?");
    }
    ParameterSlot& slot = *parameter_sets_[static_cast<std::size_t>(claimed)];
    slot.parameters = std::move(valid);
    slot.state.store(Slot::queued, std::memory_order_release);
    try {
      set.slot = claimed;
      enqueue(set);
    } catch (...) {
      slot.state.store(Slot::free, std::memory_order_release);
      throw;
    }
  };
  std::visit(Overloaded{[&](const Parameters&) { queue_parameters(ParameterSet{}); },
                        [&](const ParameterUpdate&) { queue_parameters(ParameterUpdateSet{}); },
                        [&](const auto& small) { enqueue(Message(small)); }},
             valid.command());
}

void ControlLoop::send_all(const std::vector<Command>& commands) {
  for (const Command& command : commands) validate(command);
  for (const Command& command : commands) send(command);
}

std::uint64_t ControlLoop::execute_trajectory(const JointTrajectory& trajectory) {
  const int claimed = claim(buffers_);
  if (claimed < 0) {
    throw QueueFull("all " + std::to_string(buffers_.size()) +
                    " trajectory buffers are in use (queued or running): is the loop stepping?");
  }
  TrajectorySlot& slot = *buffers_[static_cast<std::size_t>(claimed)];
  try {
    // The first segment runs from wherever the arm is when the trajectory begins, which is close
    // to the state last published (or to the running trajectory's, which tracks it).
    // Its speed is the arm's, not the trajectory's: clamped to the limits, it cannot make a
    // trajectory sent to a fast-moving arm (after a push) fail the check on its own.
    const LoopState latest = latest_state();
    const JointVector& speed_limit = model_.limits().velocity;
    const TrajectoryStartState from{latest.q,
                                    latest.dq.cwiseMax(-speed_limit).cwiseMin(speed_limit)};
    const bool started = latest.controller.status != Status::not_started;
    slot.buffer.assign(trajectory, model_.joint_names(),
                       TrajectoryLimits{lower_limits_, upper_limits_, model_.limits().velocity},
                       started ? &from : nullptr);
    const TrajectoryStart start{claimed, next_trajectory_id_.fetch_add(1)};
    slot.state.store(Slot::queued, std::memory_order_release);
    enqueue(start);
    return start.id;
  } catch (...) {
    slot.state.store(Slot::free, std::memory_order_release);
    throw;
  }
}

void ControlLoop::cancel_trajectory() {
  enqueue(TrajectoryCancel{});
}

LoopState ControlLoop::latest_state() const {
  return outbox_.read();
}
Parameters ControlLoop::latest_parameters() const {
  return parameters_outbox_.read();
}

// GCC 12 under -fsanitize=address reports the inactive members of the std::variant built below
// as "maybe uninitialized" when it copies it (a known false positive of its variant analysis;
// the copy reads only the active member).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
void ControlLoop::apply_messages(std::size_t at_most) noexcept {
  Message message;
  bool parameters_changed = false;
  // A new reference or nullspace target from outside ends a running trajectory, which would
  // otherwise overwrite it in the same cycle.
  const auto end_running_trajectory = [this] {
    if (active_buffer_ >= 0) end_trajectory(TrajectoryState::cancelled, false);
  };
  for (std::size_t applied = 0; applied < at_most && inbox_.pop(message); ++applied) {
    ++commands_applied_;
    std::visit(Overloaded{
                   [&](const TrajectoryStart& start) { begin_trajectory(start.buffer, start.id); },
                   [&](const TrajectoryCancel&) {
                     if (active_buffer_ >= 0) end_trajectory(TrajectoryState::cancelled, true);
                   },
                   [&](const ParameterSet& set) {
                     apply_parameter_set(set.slot);
                     parameters_changed = true;
                   },
                   [&](const ParameterUpdateSet& set) {
                     apply_parameter_set(set.slot);
                     parameters_changed = true;
                   },
                   [&](const ReferencePose& command) {
                     end_running_trajectory();
                     apply_command(command);
                     parameters_changed = true;
                   },
                   [&](const NullspaceTarget& command) {
                     end_running_trajectory();
                     apply_command(command);
                     parameters_changed = true;
                   },
                   [&](const auto& command) {
                     apply_command(command);
                     parameters_changed = true;
                   },
               },
               message);
  }
  if (parameters_changed) {
    const Parameters& parameters = controller_.parameters();
    armature_ = per_joint(parameters.dynamics.armature, num_joints());
    parameters_outbox_.publish(parameters);
  }
}

void ControlLoop::apply_parameter_set(int index) noexcept {
  ParameterSlot& slot = *parameter_sets_[static_cast<std::size_t>(index)];
  parameters_before_ = controller_.parameters();
  if (!controller_.apply(*slot.parameters)) ++updates_refused_;
  slot.state.store(Slot::free, std::memory_order_release);
  if (controller_.started() &&
      (changed_parameters(parameters_before_, controller_.parameters()) & safety_settings())
          .any()) {
    ++safety_changes_;
  }
}

void ControlLoop::apply_command(const Command& command) noexcept {
  controller_.apply(ValidCommand(command, num_joints()));
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

void ControlLoop::begin_trajectory(int buffer, std::uint64_t id) noexcept {
  // Continue from where the running trajectory is, or from the measured state.
  if (active_buffer_ >= 0) {
    buffers_[static_cast<std::size_t>(active_buffer_)]->state.store(Slot::free,
                                                                    std::memory_order_release);
  } else {
    trajectory_q_ = state_.q;
    trajectory_dq_ = state_.dq;
  }
  TrajectorySlot& slot = *buffers_[static_cast<std::size_t>(buffer)];
  slot.state.store(Slot::running, std::memory_order_relaxed);
  slot.buffer.begin(trajectory_q_, trajectory_dq_);
  active_buffer_ = buffer;
  state_.trajectory =
      TrajectoryProgress{TrajectoryState::executing, id, 0.0, slot.buffer.duration(), 0.0};
}

void ControlLoop::end_trajectory(TrajectoryState end_state, bool hold_measured) noexcept {
  buffers_[static_cast<std::size_t>(active_buffer_)]->state.store(Slot::free,
                                                                  std::memory_order_release);
  active_buffer_ = -1;
  state_.trajectory.state = end_state;
  controller_.stop_tracking();
  if (hold_measured) {
    // Hold where the robot is rather than keep pulling toward a target it did not reach.
    controller_.track(kinematics_.pose, Vector6d::Zero(), state_.q,
                      JointVector::Zero(num_joints()));
  }
}

void ControlLoop::advance_trajectory(double dt) noexcept {
  if (active_buffer_ < 0) return;
  const TrajectoryBuffer& buffer = buffers_[static_cast<std::size_t>(active_buffer_)]->buffer;
  TrajectoryProgress& progress = state_.trajectory;
  progress.time += dt;
  buffer.sample(progress.time, trajectory_q_, trajectory_dq_);
  // Reference pose by forward kinematics of the sampled joints, with the twist J(q_d) dq_d as
  // velocity feed-forward; the nullspace follows the joints themselves.
  reference_workspace_.compute(trajectory_q_, trajectory_dq_, reference_kinematics_, false);
  Vector6d twist;
  twist.noalias() = reference_kinematics_.jacobian * trajectory_dq_;
  controller_.track(reference_kinematics_.pose, twist, trajectory_q_, trajectory_dq_);
  if (progress.time < progress.duration) return;
  const TrajectoryParameters& tolerances = controller_.parameters().trajectory;
  progress.goal_error = (state_.q - trajectory_q_).cwiseAbs().maxCoeff();
  if (progress.goal_error <= tolerances.goal_tolerance) {
    end_trajectory(TrajectoryState::finished, false);
  } else if (progress.time > progress.duration + tolerances.goal_time_tolerance) {
    end_trajectory(TrajectoryState::aborted, true);
  }
}

void ControlLoop::joint_limit_torque() noexcept {
  // A spring that pushes each joint out of the margin next to its limits, added to tau_0 so the
  // end effector does not feel it. Joints without limits (continuous) have infinite bounds.
  const JointLimitAvoidanceParameters& avoidance = controller_.parameters().joint_limit_avoidance;
  JointVector& torque = robot_.secondary_torque;
  JointVector& wall = robot_.joint_wall_torque;
  JointVector& ceiling = robot_.joint_limit_ceiling;
  JointVector& floor = robot_.joint_limit_floor;
  if (!(avoidance.stiffness > 0.0)) {
    torque.resize(0);
    wall.resize(0);
    ceiling.resize(0);
    floor.resize(0);
    return;
  }
  torque.setZero(num_joints());
  // While teaching nothing holds the end effector, so a push moves the joints in task space,
  // where a projected torque cannot act: a joint-space wall takes over in the margin. It rises
  // to the joint's torque bound at the limit and is critically damped (with M(q)'s diagonal,
  // 1 kg m^2 without a model) on motion toward the limit, so a push the joint can hold stops
  // inside the margin instead of at the limit (where the robot's own safety would stop).
  // Otherwise the task itself can drive a joint into its limit (a reference whose nearest joint
  // configuration lies past it), which the projected spring cannot stop either: the torque
  // toward the limit is bounded instead, from the joint's bound at the margin down to zero
  // halfway to the limit, less a critical damping of the motion toward it. The task keeps its
  // pull on the other joints, and the arm is held off the limit instead of pressing it until the
  // robot's reflex stops it.
  const ControllerState& state = controller_.state();
  const bool margin = avoidance.margin > 0.0;
  const bool teaching = margin && state.commanded.stiffness.isZero(0.0);
  const bool bounded = margin && !teaching;
  if (margin) {
    wall.setZero(num_joints());
  } else {
    wall.resize(0);
  }
  if (bounded) {
    ceiling.setConstant(num_joints(), std::numeric_limits<double>::infinity());
    floor.setConstant(num_joints(), -std::numeric_limits<double>::infinity());
  } else {
    ceiling.resize(0);
    floor.resize(0);
  }
  const bool with_mass = robot_.mass.rows() == num_joints();
  for (int i = 0; i < num_joints(); ++i) {
    const double upper = upper_limits_[i] - avoidance.margin;
    const double lower = lower_limits_[i] + avoidance.margin;
    const double q = robot_.q[i];
    const double depth = q > upper ? q - upper : (q < lower ? q - lower : 0.0);
    if (depth == 0.0) continue;
    torque[i] = -avoidance.stiffness * depth;
    if (!margin) continue;
    const double bound = state.joint_torque_limit[i];
    const double inertia = with_mass ? robot_.mass(i, i) : 1.0;
    const double dq = robot_.dq[i];
    if (bounded) {
      // The bound takes only the drive, never the damping and the speed caps' brake, so a joint
      // that arrives fast can still pass the halfway point: from there a wall (added torque,
      // under the caps like the teaching wall) pushes it back and brakes it.
      const double half = 0.5 * avoidance.margin;
      const double stiffness = bound / half;
      const double damping = 2.0 * std::sqrt(stiffness * inertia);
      if (depth > 0.0) {
        ceiling[i] = bound - stiffness * depth - damping * std::max(dq, 0.0);
      } else {
        floor[i] = -bound - stiffness * depth - damping * std::min(dq, 0.0);
      }
      const double past = depth > half ? depth - half : (depth < -half ? depth + half : 0.0);
      if (past == 0.0) continue;
      wall[i] = -stiffness * past;
      if (dq * past > 0.0) wall[i] -= damping * dq;
      continue;
    }
    const double stiffness = bound / avoidance.margin;
    wall[i] = -stiffness * depth;
    if (dq * depth > 0.0) wall[i] -= 2.0 * std::sqrt(stiffness * inertia) * dq;
  }
}

const JointVector& ControlLoop::step(const JointVector& q, const JointVector& dq,
                                     double dt) noexcept {
  return cycle(q, dq, nullptr, dt);
}

const JointVector& ControlLoop::step(const JointVector& q, const JointVector& dq,
                                     const JointVector& measured_torque, double dt) noexcept {
  return cycle(q, dq, &measured_torque, dt);
}

const JointVector& ControlLoop::cycle(const JointVector& q, const JointVector& dq,
                                      const JointVector* measured_torque, double dt) noexcept {
  apply_messages(kCommandsPerCycle);
  const Parameters& parameters = controller_.parameters();
  const DynamicsParameters& dynamics = parameters.dynamics;
  // Only the terms the options use: the model computes nothing else (never Coriolis). The speed
  // caps' governor measures a push by the acceleration it causes, through M(q).
  const MaxSpeedParameters& speed_cap = parameters.safety.max_speed;
  // Power and force limiting takes the arm's effective mass from M(q) too.
  const bool need_mass_for_options = parameters.safety.pfl.body_region != BodyRegion::none ||
                                     dynamics.inertia_shaped_damping ||
                                     dynamics.dynamically_consistent_nullspace ||
                                     speed_cap.translation > 0.0 || speed_cap.rotation > 0.0;
  // The collision monitor's momentum observer needs M(q) and C^T dq.
  const bool need_collision = parameters.collision.detection;
  const bool need_mass = need_mass_for_options || need_collision;
  // A measured torque is read by the observer less g(q).
  const bool need_measured = need_collision && parameters.collision.measured_torque;
  const bool need_gravity = dynamics.gravity_compensation || need_measured;
  const ModelTerms terms = (need_mass ? ModelTerms::mass : ModelTerms::none) |
                           (need_gravity ? ModelTerms::gravity : ModelTerms::none) |
                           (need_collision ? ModelTerms::coriolis_transposed : ModelTerms::none);
  const bool dt_plausible =
      dt >= parameters.plausibility.dt.min && dt <= parameters.plausibility.dt.max;
  // A bad measurement, or one the model cannot be evaluated at, fails the cycle closed before
  // anything of it reaches the robot state: nothing computed from an earlier q (pose, Jacobian,
  // M) is ever paired with a newer one.
  // The measurement is checked here once (with the joint limits, which only the loop knows), and
  // not again by the controller (update_measured()).
  if (const Fault fault = checks::measurement(q, dq, num_joints(), measurement_bounds())) {
    controller_.fail_closed(Status::invalid_robot_state, fault, dt);
  } else if (!workspace_.compute(q, dq, kinematics_, terms)) {
    controller_.fail_closed(Status::model_error,
                            Fault{"q", -1, 0.0, "gives a pose, Jacobian or M(q) that is not finite",
                                  0.0, false, "", Fault::Form::statement},
                            dt);
  } else {
    fill_robot_state(q, dq, kinematics_, robot_);
    state_.q = q;
    state_.dq = dq;
    if (dt_plausible && controller_.started()) advance_trajectory(dt);
    // A term the options do not use stays empty, so the law cannot read a stale one.
    if (need_mass) {
      robot_.mass = kinematics_.mass;
      robot_.mass.diagonal() += armature_;
    } else {
      robot_.mass.resize(0, 0);
    }
    if (need_gravity) {
      robot_.gravity = kinematics_.gravity;
    } else {
      robot_.gravity.resize(0);
    }
    if (need_collision) {
      robot_.coriolis_transposed = kinematics_.coriolis_transposed;
    } else {
      robot_.coriolis_transposed.resize(0);
    }
    if (need_measured && measured_torque != nullptr) {
      robot_.measured_torque = *measured_torque;
    } else {
      robot_.measured_torque.resize(0);
    }
    joint_limit_torque();
    controller_.update_measured(robot_, dt);
  }
  // The controller stopped pulling the arm back into a motion it could not make: a running
  // trajectory would pull it on, so it ends here (aborted, holding where the arm is).
  const bool holding = controller_.state().limits.holding;
  // A collision's reaction (other than report) holds the reference until Resume: a trajectory
  // ends there, and one started meanwhile at once (the reaction chose where the arm holds).
  const CollisionState& collision = controller_.state().collision;
  if (collision.detected && collision.reaction != CollisionReaction::report &&
      active_buffer_ >= 0) {
    end_trajectory(TrajectoryState::aborted, false);
  } else if (holding && !was_holding_ && active_buffer_ >= 0) {
    end_trajectory(TrajectoryState::aborted, true);
  }
  was_holding_ = holding;
  if (controller_.started()) {
    ++state_.cycle;  // every step, also those that failed closed
    if (dt_plausible) state_.time += dt;
  }
  state_.commands_applied = commands_applied_;
  state_.safety_changes = safety_changes_;
  state_.updates_refused = updates_refused_;
  publish_state();
  return controller_.torque();
}

void ControlLoop::publish_state() noexcept {
  // Written straight into the outbox's free slot: the controller's snapshot is kilobytes, and a
  // second copy through state_ cost a tenth of a default step.
  const auto fill = [this](LoopState& out) noexcept {
    out.controller = controller_.state();
    if (&out == &state_) return;
    out.q = state_.q;
    out.dq = state_.dq;
    out.trajectory = state_.trajectory;
    out.cycle = state_.cycle;
    out.time = state_.time;
    out.commands_applied = state_.commands_applied;
    out.safety_changes = state_.safety_changes;
    out.updates_refused = state_.updates_refused;
  };
  published_ = outbox_.publish_with(fill);
  if (published_ == nullptr) {  // every other slot being read: this cycle's snapshot is dropped
    fill(state_);
    published_ = &state_;
  }
}

}  // namespace cartesian_impedance
