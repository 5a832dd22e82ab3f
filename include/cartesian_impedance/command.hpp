#pragma once
/// @file
/// A validated command for the controller. The factory functions check everything (and throw
/// Error naming the field, value and range); a Command that exists is known to be good, so
/// CartesianImpedanceController::apply() can take it inside the control cycle without checks,
/// allocation or exceptions. This is how commands cross from other threads into the cycle.

#include <optional>

#include "cartesian_impedance/parameters.hpp"
#include "cartesian_impedance/types.hpp"

namespace cartesian_impedance {

class CartesianImpedanceController;

class Command {
 public:
  enum class Kind {
    reference_pose,
    stiffness,
    damping_ratio,
    nullspace_target,
    nullspace_stiffness,
    nullspace_damping_ratio,
    wrench,
    parameters,
  };

  /// Reference pose T_base_ref; the quaternion must have unit norm within 1e-3.
  static Command reference_pose(const Pose& pose_base);
  /// Diagonal stiffness [N/m x3, Nm/rad x3] in `frame` (default: the configured frame).
  static Command stiffness(const Vector6d& diagonal, std::optional<Frame> frame = std::nullopt);
  /// Full symmetric positive semi-definite stiffness in `frame` (default: the configured frame).
  static Command stiffness_matrix(const Matrix6d& stiffness,
                                  std::optional<Frame> frame = std::nullopt);
  /// Damping ratio per axis of the stiffness frame [-].
  static Command damping_ratio(const Vector6d& damping_ratio);
  /// Nullspace target q_d [rad], one value per joint of a `num_joints` arm.
  static Command nullspace_target(const Eigen::Ref<const Eigen::VectorXd>& q_desired,
                                  int num_joints);
  /// Nullspace stiffness [Nm/rad]: one value for all joints or one per joint.
  static Command nullspace_stiffness(const Eigen::Ref<const Eigen::VectorXd>& stiffness,
                                     int num_joints);
  static Command nullspace_damping_ratio(double damping_ratio);
  /// Commanded wrench [N; Nm] in `frame` (default: the configured frame).
  static Command wrench(const Vector6d& wrench, std::optional<Frame> frame = std::nullopt);
  /// The whole configuration, validated for a `num_joints` arm.
  static Command parameters(const Parameters& parameters, int num_joints);

  Kind kind() const noexcept { return kind_; }
  /// Joint count the command was validated for (0 if it does not depend on it).
  int num_joints() const noexcept { return num_joints_; }

  // Read access, for logging and tests.
  const Pose& pose() const noexcept { return pose_; }
  const Vector6d& vector() const noexcept { return vector_; }
  const Matrix6d& matrix() const noexcept { return matrix_; }
  const JointVector& joints() const noexcept { return joints_; }
  double scalar() const noexcept { return scalar_; }
  std::optional<Frame> frame() const noexcept { return frame_; }
  const Parameters& parameter_values() const noexcept { return parameters_; }

 private:
  explicit Command(Kind kind) : kind_(kind) {}

  Kind kind_;
  int num_joints_ = 0;
  Pose pose_;
  Vector6d vector_ = Vector6d::Zero();
  Matrix6d matrix_ = Matrix6d::Zero();
  bool full_matrix_ = false;
  JointVector joints_;
  double scalar_ = 0.0;
  std::optional<Frame> frame_;
  Parameters parameters_;

  friend class CartesianImpedanceController;
};

}  // namespace cartesian_impedance
