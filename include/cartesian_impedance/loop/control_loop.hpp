#pragma once
/// @file
/// The object every integration drives (simulation, ROS, Python, a user's own robot driver): a
/// robot model, a controller and a trajectory executor behind one `step(q, dq, dt) -> tau`.
///
/// Threads: one thread runs start()/step() (the cycle). Any thread may send commands (the
/// setters, execute_trajectory(), cancel_trajectory()) and read latest_state(). Commands are
/// validated by the sender (which gets the Error), copied whole into a lock-free inbox and applied
/// at the beginning of the next step; the state leaves through a lock-free outbox. Nothing a
/// sender or reader does can block the cycle, and step() itself is noexcept, allocates nothing
/// and takes no lock. Several loops, each with its own model, can run side by side.

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <type_traits>
#include <variant>
#include <vector>

#include "cartesian_impedance/core/checks.hpp"
#include "cartesian_impedance/core/command.hpp"
#include "cartesian_impedance/core/command_setters.hpp"
#include "cartesian_impedance/core/controller.hpp"
#include "cartesian_impedance/core/mailbox.hpp"
#include "cartesian_impedance/core/trajectory.hpp"
#include "cartesian_impedance/model/robot_model.hpp"

namespace cartesian_impedance {

/// Where trajectory execution stands.
enum class TrajectoryState {
  idle,       ///< no trajectory has run yet
  executing,  ///< following the trajectory (also while settling within goal_time_tolerance)
  finished,   ///< the end was reached and every joint came within trajectory.goal_tolerance
  aborted,    ///< the goal was not reached within trajectory.goal_time_tolerance after the end
  cancelled,  ///< cancel_trajectory(), or a reference pose / nullspace target command, stopped it
};

const char* to_string(TrajectoryState state) noexcept;

struct TrajectoryProgress {
  TrajectoryState state = TrajectoryState::idle;
  std::uint64_t id = 0;     ///< id returned by execute_trajectory() of the one reported here
  double time = 0.0;        ///< [s] since it started
  double duration = 0.0;    ///< [s] of its last point
  double goal_error = 0.0;  ///< [rad or m] largest |q - q_goal| (once past the end)
};

/// What one step leaves in the outbox. (ControlLoop::publish_state() copies it field by field: a
/// new field goes there too.)
struct LoopState {
  ControllerState controller;  ///< the law's snapshot: errors, targets, torque parts, limits
  JointVector q;               ///< measured joint positions [rad or m]
  JointVector dq;              ///< measured joint velocities [rad/s or m/s]
  TrajectoryProgress trajectory;
  std::uint64_t cycle = 0;             ///< steps since start(), including failed ones
  double time = 0.0;                   ///< [s] sum of the plausible dt since start()
  std::uint64_t commands_applied = 0;  ///< commands taken from the inbox since construction
  /// Parameter commands applied after start() that changed a safety setting (safety_settings():
  /// safety.*, limits.*, plausibility.*, payload.*, collision.*), which only a loop whose owner
  /// allowed it accepts (ControlLoop::allow_runtime_safety_changes()).
  std::uint64_t safety_changes = 0;
  /// ParameterUpdates the cycle refused because, merged into the parameters then in force, they
  /// broke a rule tying parameters together (consistency_fault()): another update that came first
  /// changed what they were checked against. Nothing of such an update was applied.
  std::uint64_t updates_refused = 0;
};

/// Sizes fixed at construction.
struct LoopCapacity {
  int commands = 64;              ///< inbox slots
  int trajectory_points = 10000;  ///< largest trajectory accepted
  /// [s] how long a sender waits for room in a full inbox (or for a free trajectory buffer),
  /// sleeping in its own thread, before it throws QueueFull; 0 = throw at once. The cycle
  /// applies 8 commands per step, so at 1 kHz a full inbox of 64 has room again within 8 ms.
  double send_timeout = 0.0;
};

class ControlLoop : public CommandSetters<ControlLoop> {
 public:
  /// @throws Error if the parameters are invalid for the model's joint count, or if their
  ///         dynamics options need M(q) while a joint moves no mass (check_dynamics(); a
  ///         parameter set sent later is refused for the same reason).
  explicit ControlLoop(const RobotModel& model, const Parameters& parameters = {},
                       LoopCapacity capacity = {});
  ~ControlLoop();
  ControlLoop(const ControlLoop&) = delete;
  ControlLoop& operator=(const ControlLoop&) = delete;

  const RobotModel& model() const noexcept;
  int num_joints() const noexcept;

  /// Lets commands change safety settings (safety_settings(): safety.*, limits.*,
  /// plausibility.*, payload.*, collision.*) while the loop runs. By default they are locked from
  /// start() on: set_parameters() or update_parameters() that would change one is refused with an
  /// Error that names the setting and the lock, so that no other program (a second node on the
  /// network, a learning script) can switch a cap off. Only the program that owns the loop decides,
  /// before start(); every accepted change is counted in LoopState::safety_changes.
  /// @throws Error after start().
  void allow_runtime_safety_changes(bool allow = true);
  bool runtime_safety_changes_allowed() const noexcept { return allow_safety_changes_; }

  // ---- the cycle: one thread -----------------------------------------------------------------

  /// Starts (or restarts) from the measured state: reference pose = current pose, nullspace
  /// target = q. The previous torque is taken as g(q) when dynamics.gravity_compensation is on
  /// (that is what the robot needs to hold still), else zero, unless `tau_previous` is given.
  /// Commands queued before start() are applied first, so a queued stiffness or wrench holds;
  /// a queued reference pose or nullspace target is then replaced by the measured state (send
  /// those after start()).
  /// @throws Error for wrongly sized or non-finite q, dq, tau_previous, a q outside the joint
  /// limits by more than plausibility.joint_position_margin or a dq beyond
  /// plausibility.joint_velocity.
  void start(const Eigen::Ref<const Eigen::VectorXd>& q,
             const Eigen::Ref<const Eigen::VectorXd>& dq);
  void start(const Eigen::Ref<const Eigen::VectorXd>& q,
             const Eigen::Ref<const Eigen::VectorXd>& dq,
             const Eigen::Ref<const Eigen::VectorXd>& tau_previous);

  /// One control cycle: applies queued commands (at most 8; more wait for the next cycles),
  /// advances the trajectory, computes the model at q, evaluates the law and publishes the state.
  /// Returns the joint torque to command [Nm]. noexcept, no allocation, no lock, bounded time.
  /// It fails closed - status in state().controller.status, the input named in
  /// state().controller.fault, the torque ramping toward zero (or toward g(q) with
  /// dynamics.gravity_compensation) within the rate limit - on a wrongly sized or non-finite q or
  /// dq, a q outside the URDF limits by more than plausibility.joint_position_margin, a joint
  /// faster than plausibility.joint_velocity, a dt outside plausibility.dt, and a model that
  /// cannot be evaluated at q. The next good cycle resumes.
  const JointVector& step(const JointVector& q, const JointVector& dq, double dt) noexcept;
  /// The same with the joint torques the robot measures [Nm or N] (link side, gravity included;
  /// Franka's tau_J): read only with collision.measured_torque, which then needs them every cycle
  /// (a step without them, or with a wrongly sized or non-finite one, fails closed naming
  /// measured_torque).
  const JointVector& step(const JointVector& q, const JointVector& dq,
                          const JointVector& measured_torque, double dt) noexcept;

  /// True once start() has succeeded.
  bool started() const noexcept { return controller_.started(); }

  /// The state after the last step (cycle thread only, and read before the next step, which may
  /// reuse its storage; other threads use latest_state()).
  const LoopState& state() const noexcept { return *published_; }
  /// The controller, for inspection from the cycle thread.
  const CartesianImpedanceController& controller() const noexcept { return controller_; }

  // ---- commands: any thread ------------------------------------------------------------------
  // Each validates (throwing Error on bad input, which queues nothing) and queues the command for
  // the next step. If the inbox stays full for LoopCapacity::send_timeout they throw QueueFull
  // (an Error), and nothing is queued.

  /// Any command (see command.hpp); the setters below are one-line wrappers around it. A
  /// nullspace target is also checked against the URDF's joint limits.
  void send(const Command& command);
  /// Validates every command first and queues them in order only if all are valid, so a bad one
  /// changes nothing. (A QueueFull part-way through leaves the earlier ones queued.)
  void send_all(const std::vector<Command>& commands);
  // set_parameters(), set_reference_pose(), set_stiffness(), ... and start_teaching() come from
  // CommandSetters: each validates its command (throwing Error) and sends it.

  /// Validates `trajectory` against the model (names, sizes, times, position limits), copies it
  /// into preallocated storage and queues it. It starts at the next step from the current
  /// state (or from where the running trajectory is, which it preempts, so nothing jumps).
  /// Returns its id, as reported in LoopState::trajectory.
  /// @throws Error on a bad trajectory; QueueFull if all trajectory buffers or the inbox stay in
  /// use for LoopCapacity::send_timeout.
  std::uint64_t execute_trajectory(const JointTrajectory& trajectory);
  /// Stops a running trajectory; the robot holds where it is.
  void cancel_trajectory();

  /// A copy of the newest published state (any thread).
  LoopState latest_state() const;
  /// Parameters in force as of the last step (any thread).
  Parameters latest_parameters() const;

 private:
  friend class CommandSetters<ControlLoop>;
  void submit_command(const Command& command) { send(command); }

  const JointVector& cycle(const JointVector& q, const JointVector& dq,
                           const JointVector* measured_torque, double dt) noexcept;

  struct Slot;
  struct TrajectorySlot;
  struct ParameterSlot;
  struct ParameterSet {
    int slot = -1;
  };
  struct TrajectoryStart {
    int buffer = -1;
    std::uint64_t id = 0;
  };
  struct TrajectoryCancel {};
  // What crosses the inbox into the cycle: each command as it is (validated by the sender), but
  // a parameter set, which is large, by the index of the slot it waits in; a trajectory by the
  // index of its buffer. Made from Command's own list, so a new command crosses with no edit here.
  struct ParameterUpdateSet : ParameterSet {};
  template <typename T>
  using InboxForm = std::conditional_t<
      std::is_same_v<T, Parameters>, ParameterSet,
      std::conditional_t<std::is_same_v<T, ParameterUpdate>, ParameterUpdateSet, T>>;
  template <typename Variant>
  struct InboxOf;
  template <typename... Commands>
  struct InboxOf<std::variant<Commands...>> {
    using type = std::variant<InboxForm<Commands>..., TrajectoryStart, TrajectoryCancel>;
  };
  using Message = typename InboxOf<Command>::type;

  // Commands applied per step at most, so that a flood of commands cannot stretch a cycle; the
  // rest wait in the inbox for the next steps (in order).
  static constexpr std::size_t kCommandsPerCycle = 8;

  void enqueue(const Message& message);
  void check_safety_lock(const Command& command) const;
  template <typename SlotType>
  int claim(std::vector<std::unique_ptr<SlotType>>& slots) const;
  void apply_messages(std::size_t at_most) noexcept;
  void apply_parameter_set(int slot) noexcept;
  ValidCommand validate(const Command& command) const;
  void apply_command(const Command& command) noexcept;
  checks::MeasurementBounds measurement_bounds() const noexcept;
  void begin_trajectory(int buffer, std::uint64_t id) noexcept;
  void end_trajectory(TrajectoryState state, bool hold_measured) noexcept;
  void advance_trajectory(double dt) noexcept;
  void joint_limit_torque() noexcept;
  void publish_state() noexcept;

  RobotModel model_;
  ModelWorkspace workspace_;
  ModelWorkspace reference_workspace_;
  CartesianImpedanceController controller_;
  Kinematics kinematics_;
  Kinematics reference_kinematics_;
  RobotState robot_;
  LoopState state_;  // the loop's own fields; `controller` only where a publication was dropped
  const LoopState* published_ = &state_;  // the last state published (an outbox slot or state_)

  CommandQueue<Message> inbox_;
  SnapshotBuffer<LoopState, 4> outbox_;
  SnapshotBuffer<Parameters, 4> parameters_outbox_;

  // Trajectory buffers: a sender claims a free one, fills it, and queues its index; the cycle
  // releases it when another replaces it. Only atomics change hands, so the cycle never frees.
  std::vector<std::unique_ptr<TrajectorySlot>> buffers_;
  std::vector<std::unique_ptr<ParameterSlot>> parameter_sets_;
  double send_timeout_ = 0.0;
  std::atomic<std::uint64_t> next_trajectory_id_{1};
  int active_buffer_ = -1;
  JointVector trajectory_q_, trajectory_dq_;
  JointVector lower_limits_, upper_limits_;
  JointVector armature_;  // dynamics.armature per joint, added to M(q)
  std::uint64_t commands_applied_ = 0;
  std::uint64_t safety_changes_ = 0;
  std::uint64_t updates_refused_ = 0;
  bool allow_safety_changes_ = false;
  std::atomic<bool> running_{false};  // start() succeeded (read by senders for the lock)
  Parameters parameters_before_;      // the cycle's copy, to see what a parameter command changed
  bool was_holding_ = false;          // ActiveLimits::holding of the last step
};

}  // namespace cartesian_impedance
