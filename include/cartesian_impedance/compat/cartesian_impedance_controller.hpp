#pragma once
/// @file
/// A drop-in for the C++ API of the published base library (Mayr and Salt Ducaju, "A C++
/// Implementation of a Cartesian Impedance Controller for Robotic Manipulators", class
/// `cartesian_impedance_controller::CartesianImpedanceController`): code written against it
/// compiles unchanged against this header and gets the same torques, computed by this library.
///
/// The published semantics are kept exactly:
/// - every filter closes a fraction of the remaining gap per second at the given update
///   frequency, with the published step 1 / (kappa f + 1), kappa = -1 / ln(1 - p); a parameter
///   of exactly 1 switches a filter off;
/// - the damping is a matrix of its own, D = factor * 2 sqrt(K) per axis ("unit mass"),
///   recomputed when the damping factors change or the stiffness changes with auto_damping, and
///   filtered like the stiffness;
/// - the nullspace projector uses the damped pseudo-inverse with lambda = 0.2;
/// - the commanded torque changes by at most the torque delta per call.
///
/// What differs (docs/compat.md): invalid input throws cartesian_impedance::Error naming the
/// argument and the value and changes nothing, where the published library asserts in debug
/// builds and otherwise clamps or ignores it; a measured state that is wrongly sized, not finite
/// or implausible fails the call closed (the torque steps toward zero by at most the torque delta,
/// status() and fault() say why) instead of producing NaN torques; the default constructor is
/// ready for 7 joints; any joint count up to cartesian_impedance::kMaxJoints works (the published
/// projector is fixed at 7).
///
/// The published signature of calculateCommandedTorques() returns an Eigen::VectorXd, which
/// allocates once per call; the overload that writes into a caller's vector allocates nothing.

#include <Eigen/Dense>
#include <cstddef>

#include "cartesian_impedance/core/controller.hpp"

namespace cartesian_impedance_controller {

class CartesianImpedanceController {
 public:
  /// Ready for 7 joints, stiffness (200, 200, 200, 20, 20, 20), nullspace stiffness 0, damping
  /// factors 1, no filtering at 1000 Hz, torque delta 100 Nm per call.
  CartesianImpedanceController();

  /// Sets the reference pose, also as the filtered one (no filtering).
  void initDesiredPose(const Eigen::Vector3d& position_d_target,
                       const Eigen::Quaterniond& orientation_d_target);
  /// Sets the nullspace configuration, also as the filtered one (no filtering).
  void initNullspaceConfig(const Eigen::VectorXd& q_d_nullspace_target);
  /// Resets the joint state, the nullspace configuration and the last torques to zero.
  /// @throws cartesian_impedance::Error unless 1 <= n_joints <= kMaxJoints.
  void setNumberOfJoints(size_t n_joints);

  /// Stiffness targets [N/m x3, Nm/rad x3, nullspace Nm/rad]; with auto_damping the damping
  /// targets become factor * 2 sqrt(stiffness).
  void setStiffness(const Eigen::Matrix<double, 7, 1>& stiffness, bool auto_damping = true);
  void setStiffness(double t_x, double t_y, double t_z, double r_x, double r_y, double r_z,
                    double n, bool auto_damping = true);
  /// As above, keeping the nullspace stiffness target.
  void setStiffness(double t_x, double t_y, double t_z, double r_x, double r_y, double r_z,
                    bool auto_damping = true);
  /// Damping factors (1 is "critical" for a unit mass); applies the damping rule at once.
  void setDampingFactors(double d_x, double d_y, double d_z, double d_a, double d_b, double d_c,
                         double d_n);

  /// Reference pose target, approached through the pose filter; the quaternion is normalised.
  void setReferencePose(const Eigen::Vector3d& position_d, const Eigen::Quaterniond& orientation_d);
  /// Nullspace configuration target, approached through the nullspace filter.
  void setNullspaceConfig(const Eigen::VectorXd& q_d_nullspace_target);

  /// Update frequency [Hz] and, per filter, the fraction in (0, 1] of the remaining gap closed
  /// per second; 1 switches a filter off.
  void setFiltering(double update_frequency, double filter_params_nullspace_config,
                    double filter_params_stiffness, double filter_params_pose,
                    double filter_params_wrench);
  /// Largest change of the commanded torque per call [Nm].
  void setMaxTorqueDelta(double d);
  void setMaxTorqueDelta(double d, double update_frequency);
  /// Wrench target [N; Nm] in the root frame, approached through the wrench filter.
  void applyWrench(const Eigen::Matrix<double, 6, 1>& cartesian_wrench);

  /// One control step at the last measured state.
  Eigen::VectorXd calculateCommandedTorques();
  /// One control step: stores the measured state, performs a filtering step and returns the
  /// commanded torques [Nm] (one heap allocation, for the returned vector).
  Eigen::VectorXd calculateCommandedTorques(const Eigen::VectorXd& q, const Eigen::VectorXd& dq,
                                            const Eigen::Vector3d& position,
                                            Eigen::Quaterniond orientation,
                                            const Eigen::MatrixXd& jacobian);
  /// The same step writing the torques into `tau` (sized n): allocates nothing, throws nothing.
  /// Returns status(); if `tau` is wrongly sized nothing is computed (invalid_robot_state).
  cartesian_impedance::Status calculateCommandedTorques(
      const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& dq,
      const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
      const Eigen::Ref<const Eigen::MatrixXd>& jacobian, Eigen::Ref<Eigen::VectorXd> tau) noexcept;

  /// The last measured state and the filtered targets the last step used. Null outputs are
  /// skipped; vector outputs are resized.
  void getState(Eigen::VectorXd* q, Eigen::VectorXd* dq, Eigen::Vector3d* position,
                Eigen::Quaterniond* orientation, Eigen::Vector3d* position_d,
                Eigen::Quaterniond* orientation_d, Eigen::Matrix<double, 6, 6>* cartesian_stiffness,
                double* nullspace_stiffness, Eigen::VectorXd* q_d_nullspace,
                Eigen::Matrix<double, 6, 6>* cartesian_damping) const;
  void getState(Eigen::Vector3d* position_d, Eigen::Quaterniond* orientation_d,
                Eigen::Matrix<double, 6, 6>* cartesian_stiffness, double* nullspace_stiffness,
                Eigen::VectorXd* q_d_nullspace,
                Eigen::Matrix<double, 6, 6>* cartesian_damping) const;
  /// The torques of the last step [Nm].
  Eigen::VectorXd getLastCommands() const;
  /// The filtered wrench of the last step [N; Nm].
  Eigen::Matrix<double, 6, 1> getAppliedWrench() const;
  /// [p - p_d; rotation vector of R R_d^T] of the last step [m; rad].
  Eigen::Matrix<double, 6, 1> getPoseError() const;

  // Beyond the published API.

  /// Outcome of the last step: ok, or why it failed closed.
  cartesian_impedance::Status status() const noexcept { return status_; }
  /// Which input made the last step fail closed (empty input if it did not).
  const cartesian_impedance::Fault& fault() const noexcept { return fault_; }
  /// The library controller that evaluates the law (its state() has every torque component).
  const cartesian_impedance::CartesianImpedanceController& controller() const noexcept {
    return controller_;
  }

 private:
  // What the published law is evaluated with; held twice, as targets and as their filtered
  // values (which the law uses).
  struct Impedance {
    Eigen::Vector3d position_d = Eigen::Vector3d::Zero();
    Eigen::Quaterniond orientation_d = Eigen::Quaterniond::Identity();
    cartesian_impedance::Matrix6d stiffness = cartesian_impedance::Matrix6d::Identity();
    cartesian_impedance::Matrix6d damping = cartesian_impedance::Matrix6d::Identity();
    cartesian_impedance::JointVector q_d_nullspace;
    // As published: the current nullspace stiffness and damping start at 1 and reach their
    // targets at the first step (at once without stiffness filtering).
    double nullspace_stiffness = 1.0;
    double nullspace_damping = 1.0;
    cartesian_impedance::Vector6d wrench = cartesian_impedance::Vector6d::Zero();
  };

  // `caller` names the public setter in messages.
  void reconfigure(const char* caller, double max_torque_delta, double update_frequency);
  void apply_damping_rule();
  void update_filter_steps();
  void filter_step(Impedance& next) const noexcept;
  // One cycle at `measured`; `measurement_checked`: q and dq were checked already.
  cartesian_impedance::Status step(const cartesian_impedance::RobotState& measured,
                                   bool measurement_checked = false) noexcept;

  int n_joints_ = 7;
  cartesian_impedance::CartesianImpedanceController controller_;
  cartesian_impedance::ScheduledImpedance schedule_;
  cartesian_impedance::RobotState measured_;  // last valid measurement
  cartesian_impedance::RobotState input_;     // this call's measurement, until it is checked
  cartesian_impedance::Status status_ = cartesian_impedance::Status::not_started;
  cartesian_impedance::Fault fault_;

  Impedance targets_;
  Impedance filtered_;
  Impedance next_;
  Eigen::Matrix<double, 7, 1> damping_factors_ = Eigen::Matrix<double, 7, 1>::Ones();

  double update_frequency_ = 1000.0;  // [Hz]
  double max_torque_delta_ = 100.0;   // [Nm] per call
  // Filter parameters (1 = off) and the per-call steps derived from them.
  double filter_nullspace_ = 1.0, filter_stiffness_ = 1.0, filter_pose_ = 1.0, filter_wrench_ = 1.0;
  double step_nullspace_ = 1.0, step_stiffness_ = 1.0, step_pose_ = 1.0, step_wrench_ = 1.0;
};

}  // namespace cartesian_impedance_controller

namespace cartesian_impedance::compat {
/// The drop-in class under this library's namespace.
using CartesianImpedanceController = cartesian_impedance_controller::CartesianImpedanceController;
}  // namespace cartesian_impedance::compat
