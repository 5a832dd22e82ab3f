#pragma once
/// @file
/// The convenience setters shared by CartesianImpedanceController (which applies a command at
/// once) and ControlLoop (which queues it for its next step): each is one line that builds the
/// command value of command.hpp and hands it to the owner. Written once, here.

#include <optional>

#include "cartesian_impedance/core/command.hpp"

namespace cartesian_impedance {

/// `Owner` provides `void submit_command(const Command&)`: validate (throwing Error, changing
/// nothing), then apply or queue.
template <typename Owner>
class CommandSetters {
 public:
  /// Replaces the whole configuration, including the commanded stiffness (as a diagonal),
  /// damping ratios, nullspace stiffness and damping, and wrench, which are then approached
  /// through their filters. Commands are re-saturated to the new limits.
  void set_parameters(const Parameters& parameters) { submit(parameters); }
  /// Sets the parameters `update` names and keeps every other one (see ParameterUpdate; made by
  /// ParameterUpdate::of() or decode_parameter_update()).
  void update_parameters(const ParameterUpdate& update) { submit(update); }
  /// Reference pose T_base_ref. The quaternion must have unit norm (within 1e-3; it is then
  /// normalised).
  void set_reference_pose(const Pose& pose_base) { submit(ReferencePose{pose_base}); }
  /// Diagonal stiffness [N/m x3, Nm/rad x3] in `frame` (default: the configured frame).
  void set_stiffness(const Vector6d& diagonal, std::optional<Frame> frame = std::nullopt) {
    submit(Stiffness::diagonal(diagonal, frame));
  }
  /// Full symmetric positive semi-definite stiffness [N/m, N/rad; N, Nm/rad] in `frame`.
  void set_stiffness_matrix(const Matrix6d& stiffness, std::optional<Frame> frame = std::nullopt) {
    submit(Stiffness(stiffness, frame));
  }
  /// Damping ratio per axis of the stiffness frame [-].
  void set_damping_ratio(const Vector6d& damping_ratio) { submit(DampingRatio{damping_ratio}); }
  /// Nullspace target configuration q_d [rad], one value per joint (a ControlLoop also requires
  /// it within the URDF's joint limits).
  void set_nullspace_target(const Eigen::Ref<const Eigen::VectorXd>& q_desired) {
    submit(NullspaceTarget(q_desired));
  }
  /// Nullspace stiffness [Nm/rad], one value for all joints or one per joint.
  void set_nullspace_stiffness(const Eigen::Ref<const Eigen::VectorXd>& stiffness) {
    submit(NullspaceStiffness(stiffness));
  }
  /// Nullspace damping ratio [-].
  void set_nullspace_damping_ratio(double damping_ratio) {
    submit(NullspaceDampingRatio{damping_ratio});
  }
  /// Commanded wrench [N; Nm] in `frame` (default: the configured frame).
  void set_wrench(const Vector6d& wrench, std::optional<Frame> frame = std::nullopt) {
    submit(Wrench(wrench, frame));
  }
  /// Kinesthetic teaching (hand guiding): zero Cartesian stiffness, and zero nullspace stiffness
  /// unless `keep_nullspace` is true. The arm then only feels its damping and friction and stays
  /// where it is left. Any later stiffness command ends it; the changes are filtered.
  void start_teaching(bool keep_nullspace = false) {
    submit(Stiffness{});
    if (!keep_nullspace) submit(NullspaceStiffness(JointVector::Zero(1)));
  }
  /// Ends a collision's reaction (see Resume): the arm holds where it is and follows the
  /// references sent from now on.
  void resume() { submit(Resume{}); }

 private:
  void submit(const Command& command) { static_cast<Owner&>(*this).submit_command(command); }
};

}  // namespace cartesian_impedance
