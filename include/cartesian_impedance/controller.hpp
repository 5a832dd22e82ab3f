#pragma once
/// @file
/// The Cartesian impedance control law with nullspace joint impedance and a commanded wrench:
///
///   tau = J^T (-K e - D J dq) + N tau_0 + J^T F,   tau_0 = -K_ns (q - q_d) - D_ns dq,
///   N = I - J^T (J J^T + lambda^2 I)^-1 J,          D = 2 Z^(1/2) sqrt(K) Z^(1/2),
///
/// with every commanded quantity low-pass filtered, saturated to user limits, the pose error
/// clipped, and the torque limited in magnitude and rate. Setters validate and throw `Error`
/// (a rejected command changes nothing); `update` is noexcept, allocates nothing, takes no lock and
/// does no I/O. One controller serves one robot; it is not thread-safe (see the control loop for
/// hand-off between threads).

#include <optional>
#include <string>

#include "cartesian_impedance/command.hpp"
#include "cartesian_impedance/command_setters.hpp"
#include "cartesian_impedance/math.hpp"
#include "cartesian_impedance/parameters.hpp"
#include "cartesian_impedance/types.hpp"

namespace cartesian_impedance {

/// Outcome of one control cycle. Every status but ok and not_started is a cycle that failed
/// closed: the torque ramps toward zero (toward g(q) with dynamics.gravity_compensation) within
/// the rate limit, ControllerState::fault names the input, and the next good cycle resumes.
enum class Status {
  ok,                   ///< torque computed from the law
  not_started,          ///< start() has not been called; torque is zero
  invalid_dt,           ///< dt not finite or outside plausibility.dt
  invalid_robot_state,  ///< q, dq, pose or Jacobian wrongly sized, not finite or implausible
  numerical_error,      ///< the law produced a non-finite value
  missing_dynamics,     ///< an option needs robot.mass or robot.gravity, which were not given
  model_error,          ///< the robot model could not be evaluated at the measured q
};

/// "ok", "not_started", ...
const char* to_string(Status status) noexcept;

/// Which input made a cycle fail closed, without allocating: e.g. input "dq", index 4, value
/// NaN, reason "is not finite"; or "dt" = 1e9 "is above plausibility.dt.max" with bound 0.02.
struct Fault {
  const char* input = "";  ///< "dt", "q", "dq", "pose", "jacobian", "mass", "gravity", "model", ...
  int index = -1;          ///< element (joint) index, or -1
  double value = 0.0;      ///< the offending value (for a wrong size: the size)
  const char* reason = "";  ///< "is not finite", "has the wrong size", "is above ...", ...
  double bound = 0.0;       ///< the bound it broke, where `reason` names one
  bool has_bound = false;
};

/// "dq[4] = nan is not finite", "dt = 1000000000 is above plausibility.dt.max = 0.02"; "" if
/// there is no fault (input empty).
std::string to_string(const Fault& fault);

/// The quantities the law is evaluated with: either as commanded or after filtering.
struct Targets {
  Pose pose;                         ///< reference pose T_base_ref
  Matrix6d stiffness;                ///< K in the stiffness frame [N/m, Nm/rad]
  Vector6d damping_ratio;            ///< zeta per axis of the stiffness frame [-]
  JointVector nullspace_q;           ///< nullspace target q_d [rad]
  JointVector nullspace_stiffness;   ///< K_ns per joint [Nm/rad]
  double nullspace_damping_ratio{};  ///< zeta_ns [-]
  Vector6d wrench;                   ///< F in the wrench frame [N, Nm]
  /// Velocity feed-forward of a tracked reference (not filtered; zero unless track() is used):
  Vector6d twist;            ///< reference twist [m/s; rad/s], base frame
  JointVector nullspace_dq;  ///< nullspace target velocity [rad/s]
};

/// Which limits shaped the commands and the last cycle. A command saturation flag says whether
/// the last command of that quantity was saturated (new parameters re-command them all); the
/// others describe the last cycle.
struct ActiveLimits {
  bool stiffness_saturated = false;
  bool damping_ratio_saturated = false;
  bool nullspace_stiffness_saturated = false;
  bool wrench_saturated = false;
  bool translation_error_clipped = false;
  bool rotation_error_clipped = false;
  bool joint_torque_saturated = false;
  bool torque_rate_limited = false;
  /// limits.joint_torque was lowered below the torque being commanded: the bound in force
  /// (ControllerState::joint_torque_limit) is ramping down to it at the torque-rate limit.
  bool joint_torque_limit_ramping = false;
};

/// Snapshot written by every update().
struct ControllerState {
  Status status = Status::not_started;
  Pose pose;            ///< measured end-effector pose T_base_ee
  Vector6d pose_error;  ///< e = [p - p_d; log(R R_d^T)], base frame, after clipping [m; rad]
  Targets commanded;    ///< targets as last commanded (after validation and saturation)
  Targets filtered;     ///< targets the law used this cycle
  Matrix6d damping;     ///< D the law used, in the stiffness frame
  Frame stiffness_frame = Frame::base;  ///< frame of the stiffness and damping targets
  Frame wrench_frame = Frame::base;     ///< frame of the wrench targets
  Vector6d wrench_base;                 ///< filtered F in the base frame
  JointVector tau_cartesian;            ///< J^T (-K e - D J dq) [Nm]
  JointVector tau_nullspace;            ///< N tau_0 [Nm]
  JointVector tau_wrench;               ///< J^T F [Nm]
  JointVector tau_gravity;              ///< g(q) if dynamics.gravity_compensation, else 0 [Nm]
  JointVector tau;                      ///< commanded torque after torque and rate limits [Nm]
  /// Torque bound in force per joint [Nm]: limits.joint_torque, or above it while ramping down
  /// to a lowered limit (|tau| never exceeds this, and this never falls faster than the rate).
  JointVector joint_torque_limit;
  ActiveLimits limits;
  Fault fault;  ///< why the last cycle failed closed (input empty when status is ok)

  /// Filtered K and the damping D the law used, in the base frame (rotated on request; the cycle
  /// itself works in the stiffness frame).
  Matrix6d stiffness_base() const noexcept;
  Matrix6d damping_base() const noexcept;
};

/// The impedance of one cycle as its caller schedules it: every quantity the law uses, with the
/// damping given explicitly instead of derived from damping ratios. See
/// CartesianImpedanceController::schedule().
struct ScheduledImpedance {
  Pose reference;                   ///< reference pose T_base_ref (unit quaternion)
  Matrix6d stiffness;               ///< K in the stiffness frame [N/m, Nm/rad], symmetric PSD
  Matrix6d damping;                 ///< D in the stiffness frame [N s/m, Nm s/rad], symmetric PSD
  JointVector nullspace_q;          ///< nullspace target q_d [rad or m]
  JointVector nullspace_stiffness;  ///< K_ns per joint [Nm/rad]
  JointVector nullspace_damping;    ///< D_ns per joint [Nm s/rad]
  Vector6d wrench;                  ///< F in the wrench frame [N; Nm]
};

class CartesianImpedanceController : public CommandSetters<CartesianImpedanceController> {
 public:
  /// @throws Error if num_joints is outside [1, kMaxJoints] or the parameters are invalid.
  explicit CartesianImpedanceController(int num_joints, const Parameters& parameters = {});

  int num_joints() const noexcept { return num_joints_; }

  /// Current configuration. The diagonal setters keep it up to date, so a read-modify-write
  /// through set_parameters() preserves them.
  const Parameters& parameters() const noexcept { return parameters_; }

  /// Starts (or restarts) from the measured state: reference pose = current pose, nullspace
  /// target = current q, filtered stiffness and damping = commanded, filtered wrench = 0 (it
  /// ramps in through its filter), previous torque = `tau_previous` (zero if not given), so the
  /// first commands are continuous with what the robot already receives.
  /// @throws Error if `robot` is wrongly sized or not finite.
  void start(const RobotState& robot);
  void start(const RobotState& robot, const Eigen::Ref<const Eigen::VectorXd>& tau_previous);
  bool started() const noexcept { return started_; }

  // set_parameters(), set_reference_pose(), set_stiffness(), ... and start_teaching() come from
  // CommandSetters: each validates its command (throwing Error, changing nothing) and applies it.

  /// Validates and applies any command (see command.hpp); the setters are this.
  /// @throws Error naming the field, value and valid range; nothing changes then.
  void apply(const Command& command);
  /// Applies a validated command: noexcept and allocation-free, so a control loop can apply
  /// commands handed over from other threads inside its cycle. Returns false (and changes
  /// nothing) if the command was validated for a different joint count.
  bool apply(const ValidCommand& command) noexcept;

  /// Drives the reference directly, bypassing the pose and nullspace filters, for a caller that
  /// already produces a smooth reference (trajectory execution): reference pose and twist
  /// [m/s; rad/s] in the base frame, nullspace target and its velocity. The twist and joint
  /// velocity are feed-forward: the damping acts on J dq - twist and dq - dq_desired. noexcept,
  /// no allocation; the caller guarantees finite values of the right size.
  void track(const Pose& pose_base, const Vector6d& twist_base, const JointVector& q_desired,
             const JointVector& dq_desired) noexcept;
  /// Ends tracking: the reference stays where it is, the feed-forward velocities become zero.
  void stop_tracking() noexcept;

  /// Sets the commanded and filtered impedance of the next cycles directly, bypassing the
  /// filters, the saturation of commands and the damping rule: for a caller that schedules K and
  /// D itself (a learned variable-impedance policy, or the compatibility API with the published
  /// controller's filter semantics). The law, the minimum damping, the pose-error clipping, the
  /// torque and rate limits and the fail-closed checks still apply. The explicit damping holds
  /// until the next command other than a reference pose or nullspace target. noexcept, no
  /// allocation; the caller guarantees finite values of the right sizes and a unit quaternion.
  void schedule(const ScheduledImpedance& impedance) noexcept;
  /// True while a schedule() is in force (no command has replaced it).
  bool scheduled() const noexcept { return scheduled_; }

  /// One control cycle: filters the targets with the elapsed `dt` [s], evaluates the law at the
  /// measured `robot` state and applies the limits. The result is torque() and state(). Never
  /// throws and never allocates. It fails closed (a status other than ok, state().fault naming
  /// the input, the torque ramping toward zero within the rate limit) on a dt that is not finite
  /// or outside plausibility.dt, and on a robot state that is wrongly sized, not finite, has a
  /// non-unit orientation or a joint faster than plausibility.joint_velocity.
  Status update(const RobotState& robot, double dt) noexcept;

  /// A cycle without a usable measurement, for a caller that found the fault itself (the control
  /// loop: a position outside the joint limits, a model that could not be evaluated): ramps the
  /// torque toward zero (or g) within the rate limit over `dt` [s] (the last valid dt if `dt` is
  /// not plausible) and reports `status` and `fault`. noexcept, no allocation.
  Status fail_closed(Status status, const Fault& fault, double dt) noexcept;

  /// Commanded joint torque of the last update() [Nm].
  const JointVector& torque() const noexcept { return state_.tau; }
  /// Snapshot of the last update().
  const ControllerState& state() const noexcept { return state_; }

 private:
  friend class CommandSetters<CartesianImpedanceController>;
  void submit_command(const Command& command) { apply(command); }

  struct FilterGains {
    double dt = -1.0;
    double pose = 1.0, stiffness = 1.0, nullspace = 1.0, wrench = 1.0;
  };

  void check_robot_state(const RobotState& robot) const;
  bool find_fault(const RobotState& robot, Fault& fault) const noexcept;
  void limit_torque(double dt) noexcept;
  void apply_saturation(Targets& commanded, ActiveLimits& limits,
                        const Command& command) const noexcept;
  void commit(const Parameters& parameters, const Command& command, Targets commanded) noexcept;
  void refresh_damping_mode() noexcept;
  void change_frames(Frame stiffness_frame, Frame wrench_frame) noexcept;
  void update_gains(double dt) noexcept;
  void filter_targets() noexcept;
  void compute_torque(const RobotState& robot) noexcept;

  int num_joints_;
  Parameters parameters_;
  JointVector joint_torque_limit_;
  JointVector joint_torque_rate_limit_;
  JointVector joint_velocity_bound_;
  bool started_ = false;
  FilterGains gains_;
  double last_valid_dt_ = 1e-3;
  ControllerState state_;

  // Per-cycle workspace, sized once.
  JointVector tau_previous_;
  JointVector max_step_;
  JointVector tau_0_;
  Matrix6d damping_frame_;
  bool stiffness_diagonal_ = true;
  Matrix6d damping_computed_for_stiffness_;  // filtered K the damping was last computed for
  Vector6d damping_computed_for_ratio_;      // filtered zeta the damping was last computed for
  NullspaceProjector projector_;
  InertiaShapedDamping inertia_damping_;  // tracks the square root's axes from cycle to cycle
  JointVector nullspace_damping_;         // D_ns of the cycle
  // Set by schedule(): the damping then comes from the caller, not from the damping ratios.
  bool scheduled_ = false;
  bool scheduled_damping_diagonal_ = true;
  Matrix6d scheduled_damping_;
  JointVector scheduled_nullspace_damping_;
};

}  // namespace cartesian_impedance
