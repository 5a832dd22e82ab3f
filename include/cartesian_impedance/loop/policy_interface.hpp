#pragma once
/// @file
/// What a learned policy commands and sees of a control loop, apart from its task: the action (a
/// pose increment, the Cartesian stiffness per axis, optionally a wrench, each normalised to
/// [-1, 1]) turned into the loop's commands, and the robot part of the observation read from a
/// LoopState. The simulated environments (Python's cartesian_impedance.envs) and a policy driving a
/// robot through a ControlLoop use this one class, so an action means the same commands and an
/// observation the same numbers in both.
///
/// Threads: one thread (the policy's) calls reset(), apply() and observe(); apply() sends commands,
/// which ControlLoop lets any thread do while another steps the loop. Not for the control cycle:
/// it runs at the policy's rate (e.g. 20 Hz). observe() allocates nothing; apply() allocates
/// only as any sender does (ControlLoop's validation of a command), never in the loop's cycle.

#include <array>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SVD>

#include "cartesian_impedance/core/command.hpp"
#include "cartesian_impedance/core/parameters.hpp"
#include "cartesian_impedance/core/types.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/model/robot_model.hpp"

namespace cartesian_impedance {

/// What the normalised action [-1, 1] maps onto.
struct PolicyActionLimits {
  /// [m] the reference moves by at most this per policy step (at 20 Hz, 0.2 m/s).
  double max_translation_step = 0.01;
  /// [rad] the reference turns by at most this per policy step (at 20 Hz, 1 rad/s).
  double max_rotation_step = 0.05;
  /// [N/m] -1 asks for min, +1 for max, linear in between; max is lowered to the parameters'
  /// limits.stiffness.translation.max.
  Range stiffness_translation{100.0, 2000.0};
  /// [Nm/rad] as stiffness_translation, lowered to limits.stiffness.rotation.max.
  Range stiffness_rotation{5.0, 150.0};
  /// [N] commanded force per axis at +-1 (wrench actions only), lowered to limits.wrench.force.
  double max_force = 30.0;
  /// [Nm] commanded torque per axis at +-1, lowered to limits.wrench.torque.
  double max_torque = 3.0;
  /// ([m], [rad]) the reference stays within this of the measured pose, so that a policy
  /// pushing against a surface does not wind the reference up. Empty: the parameters'
  /// limits.pose_error (translation, rotation).
  std::optional<std::array<double, 2>> reference_leash;
};

class PolicyInterface {
 public:
  static constexpr int kPoseActionSize = 12;    ///< translation, rotation, stiffness (6)
  static constexpr int kWrenchActionSize = 18;  ///< ... and force, torque
  /// A checked action: finite, clipped to [-1, 1], action_size() values.
  using Action = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kWrenchActionSize, 1>;

  /// `parameters`: the loop's (their limits bound the stiffness, the wrench and the leash).
  /// `wrench`: the action includes a commanded wrench.
  /// @throws Error naming the field: a limit that is not finite, a step or a force that is
  ///         negative, a stiffness range with min > max or min < 0, a leash that is not > 0.
  PolicyInterface(const RobotModel& model, const Parameters& parameters, bool wrench,
                  const PolicyActionLimits& limits = {});

  int action_size() const noexcept { return wrench_ ? kWrenchActionSize : kPoseActionSize; }
  bool wrench() const noexcept { return wrench_; }
  int num_joints() const noexcept { return workspace_.model().num_joints(); }
  /// The robot part of the observation: 2 n + 32 values (see observe()).
  static int observation_size(int num_joints) noexcept { return 2 * num_joints + 32; }
  int observation_size() const noexcept { return observation_size(num_joints()); }
  /// The limits as given.
  const PolicyActionLimits& limits() const noexcept { return limits_; }
  /// What -1 and +1 of the stiffness part ask for, after the parameters' limits [N/m x3;
  /// Nm/rad x3].
  const Vector6d& stiffness_low() const noexcept { return stiffness_low_; }
  const Vector6d& stiffness_high() const noexcept { return stiffness_high_; }
  /// [N], [Nm] per axis at +-1, after the parameters' limits.
  double max_force() const noexcept { return max_force_; }
  double max_torque() const noexcept { return max_torque_; }
  /// The leash in force ([m], [rad]).
  const std::array<double, 2>& leash() const noexcept { return leash_; }

  /// The field action[index] sets ("translation.x", ..., "stiffness.rotation.z", "torque.z").
  static const char* field(int index) noexcept;
  /// "translation [0:3], rotation [3:6], ..." for this action size.
  std::string layout() const;

  /// `action` clipped to [-1, 1]. @throws Error naming the size expected, or the first element
  /// that is not finite (index, value, field).
  Action check(const Eigen::Ref<const Eigen::VectorXd>& action) const;

  /// The diagonal stiffness a checked action asks for [N/m x3; Nm/rad x3].
  Vector6d stiffness(const Action& checked) const noexcept;
  /// The inverse: the action values [6:12] that ask for `stiffness`, clipped to [-1, 1].
  Vector6d stiffness_action(const Vector6d& stiffness) const noexcept;

  /// Puts the reference at `measured` (the flange's pose at the start of an episode).
  void reset(const Pose& measured) noexcept;
  /// Moves the reference by the checked action's increment, keeps it within the leash of
  /// `measured` (the flange's pose now), and sends the reference, the stiffness (base frame) and
  /// with wrench() the wrench (base frame) to `loop` in one send_all. The reference is kept only
  /// if the loop took the commands.
  /// @throws what ControlLoop::send_all throws (QueueFull: the inbox is full).
  void apply(const Action& checked, ControlLoop& loop, const Pose& measured);
  /// The reference the last apply() sent (or reset() set); unit quaternion with w >= 0.
  const Pose& reference() const noexcept { return reference_; }

  /// Writes the robot part of the observation (observation_size() values) from `state`:
  /// q (n) [rad], dq (n) [rad/s], flange position (3) [m] and orientation (quaternion x, y, z,
  /// w; w >= 0) in the base frame, flange twist J dq (6) [m/s; rad/s], the controller's estimate
  /// of the external wrench on the flange (6) [N; Nm], the reference position (3) and
  /// orientation (4), the stiffness in force (diagonal of the filtered K in the base frame, 6).
  ///
  /// The external wrench is what the Cartesian and wrench torques balance at rest:
  /// F = -(J^T)^+ (tau_cartesian + tau_wrench), base frame (least squares, singular values below
  /// 1e-9 of the largest dropped). It reads a contact pressed on; while the arm accelerates it
  /// includes the inertial force, and joint friction shows in it. Where the Jacobian cannot be
  /// computed (a measurement that is not finite), twist and wrench are zero.
  /// Allocates nothing. `out` must have observation_size() rows.
  void observe(const LoopState& state, Eigen::Ref<Eigen::VectorXd> out) noexcept;

 private:
  using JacobianTranspose =
      Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::ColMajor, kMaxJoints, 6>;

  PolicyActionLimits limits_;
  bool wrench_ = false;
  Vector6d stiffness_low_;
  Vector6d stiffness_high_;
  double max_force_ = 0.0;
  double max_torque_ = 0.0;
  std::array<double, 2> leash_{};
  Pose reference_;
  ModelWorkspace workspace_;
  Kinematics kinematics_;
  JacobianTranspose jacobian_transpose_;
  Eigen::JacobiSVD<JacobianTranspose> svd_;
  std::vector<Command> commands_;  // apply()'s, reserved once
};

}  // namespace cartesian_impedance
