#pragma once
/// @file
/// What can be commanded while the robot runs: one plain value type per kind of command, and
/// `Command`, the variant of them all. `validate_command()` is the one place a command is checked
/// (it throws Error naming the field, value and range); what it returns, a ValidCommand, can be
/// applied inside the control cycle without checks, allocation or exceptions. This is how
/// commands cross from other threads into the cycle:
///
///     controller.apply(ci::Wrench{{0, 0, -5, 0, 0, 0}});           // validates, then applies
///     loop.send(ci::Stiffness::diagonal({800, 800, 800, 60, 60, 60}));  // validates, queues
///
/// The setters of CartesianImpedanceController and ControlLoop (set_wrench(), ...) are one-line
/// wrappers around these. Code that handles commands visits the variant (std::visit with one
/// overload per alternative, see Overloaded), so that a new command is one alternative here and one
/// overload wherever the compiler asks for it; nothing keeps a second list of them.

#include <optional>
#include <variant>

#include "cartesian_impedance/core/parameters.hpp"
#include "cartesian_impedance/core/types.hpp"

namespace cartesian_impedance {

/// Reference pose T_base_ref. The quaternion must have unit norm within 1e-3 (it is normalised);
/// the position must be within 1000 m of the base.
struct ReferencePose {
  static constexpr const char* kName = "reference_pose";
  Pose pose_base;
};

/// Cartesian stiffness [N/m, N/rad; N, Nm/rad]: symmetric positive semi-definite, diagonal or
/// full, in `frame` (none: the configured stiffness.frame). Each entry within the range of the
/// stiffness parameters.
struct Stiffness {
  static constexpr const char* kName = "stiffness";
  Matrix6d stiffness = Matrix6d::Zero();
  std::optional<Frame> frame;

  Stiffness() = default;
  explicit Stiffness(const Matrix6d& stiffness_, std::optional<Frame> frame_ = std::nullopt)
      : stiffness(stiffness_), frame(frame_) {}
  /// Diagonal stiffness [N/m x3, Nm/rad x3].
  static Stiffness diagonal(const Vector6d& diagonal, std::optional<Frame> frame = std::nullopt) {
    return Stiffness(diagonal.asDiagonal(), frame);
  }
};

/// Damping ratio per axis of the stiffness frame [-].
struct DampingRatio {
  static constexpr const char* kName = "damping_ratio";
  Vector6d ratio = Vector6d::Ones();
};

/// Nullspace target q_d [rad or m], one value per joint, within the joint limits (checked by a
/// ControlLoop, which knows them).
struct NullspaceTarget {
  static constexpr const char* kName = "nullspace_target";
  JointVector q_desired;

  NullspaceTarget() = default;
  /// @throws Error if `q_desired` has more than kMaxJoints values (the rest is checked by
  /// validate_command()).
  explicit NullspaceTarget(const Eigen::Ref<const Eigen::VectorXd>& q_desired);
};

/// Nullspace stiffness [Nm/rad]: one value for all joints or one per joint.
struct NullspaceStiffness {
  static constexpr const char* kName = "nullspace_stiffness";
  JointVector stiffness;

  NullspaceStiffness() = default;
  /// @throws Error if `stiffness` has more than kMaxJoints values.
  explicit NullspaceStiffness(const Eigen::Ref<const Eigen::VectorXd>& stiffness);
};

/// Nullspace damping ratio [-].
struct NullspaceDampingRatio {
  static constexpr const char* kName = "nullspace_damping_ratio";
  double ratio = 1.0;
};

/// Commanded wrench [N; Nm] in `frame` (none: the configured wrench.frame).
struct Wrench {
  static constexpr const char* kName = "wrench";
  Vector6d wrench = Vector6d::Zero();
  std::optional<Frame> frame;

  Wrench() = default;
  explicit Wrench(const Vector6d& wrench_, std::optional<Frame> frame_ = std::nullopt)
      : wrench(wrench_), frame(frame_) {}
};

/// Ends a collision's reaction (CollisionState::detected, collision.reaction other than report):
/// the arm holds where it is now, with the stiffness and wrench as commanded (a stiffness the
/// reflex dropped comes back through its filter and the energy tank), and follows the reference
/// poses, nullspace targets and trajectories sent from now on. Without a latched collision it
/// does nothing.
struct Resume {
  static constexpr const char* kName = "resume";
};

/// Any command (each alternative's kName names it). `Parameters` replaces the whole configuration,
/// including the commanded stiffness (as a diagonal), damping ratios, nullspace stiffness and
/// damping and the wrench; `ParameterUpdate` (parameters.hpp) sets only the rows it names.
using Command =
    std::variant<ReferencePose, Stiffness, DampingRatio, NullspaceTarget, NullspaceStiffness,
                 NullspaceDampingRatio, Wrench, Parameters, ParameterUpdate, Resume>;

/// A visitor made of one lambda per alternative: std::visit(Overloaded{[](const Wrench&) {...},
/// ...}, command). A missing alternative does not compile.
template <typename... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <typename... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

/// A command that passed validate_command() for an arm of num_joints() joints; only that
/// function (and the control loop, which hands validated commands to its cycle) makes one.
class ValidCommand {
 public:
  const Command& command() const noexcept { return command_; }
  /// Joint count it was validated for (0 if it does not depend on it).
  int num_joints() const noexcept { return num_joints_; }

 private:
  ValidCommand(Command command, int num_joints) noexcept
      : command_(std::move(command)), num_joints_(num_joints) {}

  Command command_;
  int num_joints_ = 0;

  friend ValidCommand validate_command(Command command, int num_joints);
  friend class ControlLoop;
};

/// Checks `command` for an arm of `num_joints` joints and returns it normalised (unit quaternion,
/// symmetric stiffness).
/// @throws Error naming the field, the value and the valid range; e.g.
///         `stiffness.translation.x = -5 N/m is outside [0, 100000]`.
ValidCommand validate_command(Command command, int num_joints);

/// "reference_pose", "stiffness", ..., "parameters": the command's name in messages and logs.
const char* command_name(const Command& command) noexcept;

}  // namespace cartesian_impedance
