#pragma once
// Test oracle: a reference implementation of the semantics of the published base library class
// cartesian_impedance_controller::CartesianImpedanceController (GitHub repository
// matthias-mayr/Cartesian-Impedance-Controller, header
// include/cartesian_impedance_controller/cartesian_impedance_controller.hpp and
// src/cartesian_impedance_controller.cpp, with the damped pseudo-inverse of
// src/pseudo_inversion.h). It was written anew from reading that source: the behaviour was taken,
// not the code. The public method names and signatures are the published ones, so a single
// templated test driver can run this oracle and our compatibility class side by side and compare.
//
// Published behaviour is kept on purpose, oddities included; every oddity is marked "Quirk:".
// Where the published code asserts on bad input, this file does what a release build (NDEBUG)
// of the published code does, without asserting. The one intended deviation is marked
// "Deviation:". Speed and allocations do not matter here: dynamic Eigen types throughout.
//
// Precondition, as in the published class: call setNumberOfJoints() before anything that touches
// joint-space quantities; until then the joint vectors and the Jacobian are empty.

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstddef>

namespace published_reference {

namespace detail {

// min(max(x, lo), hi) in exactly this order, so NaN passes through as it does in the original.
inline double clamp_value(double x, double lo, double hi) {
  return std::min(std::max(x, lo), hi);
}

// Fraction of the remaining distance to the target covered in one control cycle. The filter
// parameter p is turned into a time constant kappa = -1 / ln(1 - p) (p capped just below 1 so the
// logarithm stays finite), and the step is 1 / (kappa * f + 1) for update frequency f.
inline double filter_step(double update_frequency, double filter_param) {
  const double capped = std::min(filter_param, 0.999999);
  const double kappa = -1 / (std::log(1 - capped));
  return 1.0 / (kappa * update_frequency + 1.0);
}

// Linear blend current -> target by the given step, written as (1 - s) * current + s * target.
template <typename T>
T blend(const T& target, const T& current, double step) {
  return (1.0 - step) * current + step * target;
}

// Damped least-squares pseudo-inverse of a (rows x cols) from a full SVD with damping 0.2:
// result = V * S' * U^T, where S' is the transposed singular value matrix with each value s
// replaced by s / (s^2 + 0.2^2). Zero singular values therefore map to zero.
inline Eigen::MatrixXd damped_pinv(const Eigen::MatrixXd& a) {
  const double lambda = 0.2;
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::VectorXd s = svd.singularValues();
  Eigen::MatrixXd s_inv = Eigen::MatrixXd::Zero(a.cols(), a.rows());
  for (Eigen::Index i = 0; i < s.size(); ++i) {
    s_inv(i, i) = s(i) / (s(i) * s(i) + lambda * lambda);
  }
  return Eigen::MatrixXd(svd.matrixV() * s_inv * svd.matrixU().transpose());
}

// Rotation error as a rotation vector (angle * axis) of measured * desired^-1, i.e. expressed in
// the base frame. The measured quaternion is negated first when it lies in the other hemisphere
// from the desired one (negative 4D dot product), so the shorter rotation is reported.
inline Eigen::Vector3d rotation_error(const Eigen::Quaterniond& desired,
                                      Eigen::Quaterniond measured) {
  if (desired.coeffs().dot(measured.coeffs()) < 0.0) {
    measured.coeffs() = -measured.coeffs();
  }
  const Eigen::Quaterniond difference(measured * desired.inverse());
  const Eigen::AngleAxisd rotation(difference);
  return rotation.axis() * rotation.angle();
}

}  // namespace detail

class Controller {
 public:
  Controller() {
    // Quirk: the constructor installs the default stiffness 200/200/200/20/20/20 with nullspace
    // stiffness 0 (and automatic damping, so the nullspace damping target becomes 0 too), but
    // copies only the Cartesian stiffness and damping into the current values. The current
    // nullspace stiffness and damping keep their member defaults of 1.0 until a filter step
    // moves them.
    setStiffness(200., 200., 200., 20., 20., 20., 0.);
    cartesian_stiffness_ = cartesian_stiffness_target_;
    cartesian_damping_ = cartesian_damping_target_;
  }

  // Sets the reference pose target and the current reference at once (no filtering).
  void initDesiredPose(const Eigen::Vector3d& position_d_target,
                       const Eigen::Quaterniond& orientation_d_target) {
    setReferencePose(position_d_target, orientation_d_target);
    position_d_ = position_d_target;
    // Quirk: the target was normalised by setReferencePose, but the current reference takes the
    // caller's quaternion as given, unnormalised.
    orientation_d_ = orientation_d_target;
  }

  // Sets the nullspace configuration target and the current one at once (no filtering).
  void initNullspaceConfig(const Eigen::VectorXd& q_d_nullspace_target) {
    setNullspaceConfig(q_d_nullspace_target);
    q_d_nullspace_ = q_d_nullspace_target_;
  }

  // Resizes (and zeroes) all joint-space state: q, dq, Jacobian, nullspace configuration and its
  // target, and the last commanded torques.
  void setNumberOfJoints(size_t n_joints) {
    // Quirk: the original rejects "negative" joint counts, which a size_t can never be, so no
    // input is ever rejected. Nothing is checked here either.
    n_joints_ = n_joints;
    const Eigen::Index n = static_cast<Eigen::Index>(n_joints_);
    q_ = Eigen::VectorXd::Zero(n);
    dq_ = Eigen::VectorXd::Zero(n);
    jacobian_ = Eigen::MatrixXd::Zero(6, n);
    q_d_nullspace_ = Eigen::VectorXd::Zero(n);
    q_d_nullspace_target_ = q_d_nullspace_;
    tau_c_ = Eigen::VectorXd::Zero(n);
  }

  // Stiffness targets: entries 0..5 are the Cartesian diagonal, entry 6 the nullspace stiffness.
  void setStiffness(const Eigen::Matrix<double, 7, 1>& stiffness, bool auto_damping = true) {
    // Release-build behaviour of the original: a negative entry becomes 0 (debug builds assert).
    // The test is "< 0", so a NaN entry is stored as NaN.
    for (int i = 0; i < 6; ++i) {
      cartesian_stiffness_target_(i, i) = stiffness(i) < 0.0 ? 0.0 : stiffness(i);
    }
    nullspace_stiffness_target_ = stiffness(6) < 0.0 ? 0.0 : stiffness(6);
    // Quirk: the damping targets are explicit values, recomputed from the stiffness only here
    // (when auto_damping is true) and in setDampingFactors. With auto_damping false they keep
    // whatever was last computed, even if it no longer matches the stiffness.
    if (auto_damping) applyDamping();
  }

  void setStiffness(double t_x, double t_y, double t_z, double r_x, double r_y, double r_z,
                    double n, bool auto_damping = true) {
    Eigen::Matrix<double, 7, 1> values;
    values << t_x, t_y, t_z, r_x, r_y, r_z, n;
    setStiffness(values, auto_damping);
  }

  // Cartesian stiffness only: the nullspace stiffness target is passed through unchanged.
  void setStiffness(double t_x, double t_y, double t_z, double r_x, double r_y, double r_z,
                    bool auto_damping = true) {
    setStiffness(t_x, t_y, t_z, r_x, r_y, r_z, nullspace_stiffness_target_, auto_damping);
  }

  // Damping factors (Cartesian x y z, rotational a b c, nullspace); always recomputes the damping
  // targets from the current stiffness targets.
  void setDampingFactors(double d_x, double d_y, double d_z, double d_a, double d_b, double d_c,
                         double d_n) {
    Eigen::Matrix<double, 7, 1> factors;
    factors << d_x, d_y, d_z, d_a, d_b, d_c, d_n;
    // Release-build behaviour of the original: a negative factor leaves that entry's previous
    // factor in place (debug builds assert). NaN is not negative and is stored.
    for (int i = 0; i < 7; ++i) {
      if (factors(i) < 0) factors(i) = damping_factors_(i);
    }
    damping_factors_ = factors;
    applyDamping();
  }

  // New pose target; reached through the pose filter. The orientation target is normalised.
  void setReferencePose(const Eigen::Vector3d& position_d,
                        const Eigen::Quaterniond& orientation_d) {
    position_d_target_ = position_d;
    orientation_d_target_.coeffs() = orientation_d.coeffs();
    orientation_d_target_.normalize();
  }

  // New nullspace configuration target; reached through the nullspace filter.
  void setNullspaceConfig(const Eigen::VectorXd& q_d_nullspace_target) {
    // The original requires q_d_nullspace_target.size() == n_joints (debug assert) and writes it
    // into the existing vector without resizing. In a release build a shorter input overwrites
    // only the leading entries; a longer one is undefined behaviour there. This oracle copies the
    // overlapping leading entries and never resizes.
    const Eigen::Index count = std::min(q_d_nullspace_target_.size(), q_d_nullspace_target.size());
    q_d_nullspace_target_.head(count) = q_d_nullspace_target.head(count);
  }

  // Update frequency plus the four filter parameters. A parameter of exactly 1.0 disables that
  // filter (the value is copied straight to the current one each cycle).
  void setFiltering(double update_frequency, double nullspace, double stiffness, double pose,
                    double wrench) {
    setUpdateFrequency(update_frequency);
    setFilterValue(nullspace, &filter_params_nullspace_config_);
    setFilterValue(stiffness, &filter_params_stiffness_);
    setFilterValue(pose, &filter_params_pose_);
    setFilterValue(wrench, &filter_params_wrench_);
  }

  void setMaxTorqueDelta(double d) {
    // Quirk: the original only asserts d >= 0; a release build stores a negative value as is.
    // The rate limiter then clamps into an empty interval and every command drops by |d| per
    // cycle.
    delta_tau_max_ = d;
  }

  void setMaxTorqueDelta(double d, double update_frequency) {
    setMaxTorqueDelta(d);
    setUpdateFrequency(update_frequency);
  }

  // Wrench target in the root frame; reached through the wrench filter.
  void applyWrench(const Eigen::Matrix<double, 6, 1>& cartesian_wrench) {
    cartesian_wrench_target_ = cartesian_wrench;
  }

  // Stores the measured robot state, then runs one control cycle.
  Eigen::VectorXd calculateCommandedTorques(const Eigen::VectorXd& q, const Eigen::VectorXd& dq,
                                            const Eigen::Vector3d& position,
                                            Eigen::Quaterniond orientation,
                                            const Eigen::MatrixXd& jacobian) {
    q_ = q;
    dq_ = dq;
    position_ = position;
    // The measured orientation is stored as given, not normalised.
    orientation_.coeffs() = orientation.coeffs();
    // The original writes into the existing 6 x n Jacobian (sizes must match there); plain
    // assignment gives the same result for correctly sized input.
    jacobian_ = jacobian;
    return calculateCommandedTorques();
  }

  // One control cycle on the stored state: a filter step, then the control law, then the torque
  // rate limit. Returns the (rate limited) commanded torques.
  Eigen::VectorXd calculateCommandedTorques() {
    // Quirk: this order matters. With the stiffness filter disabled its step also snaps the
    // nullspace configuration to its target, undoing whatever the nullspace filter just did.
    updateFilteredNullspaceConfig();
    updateFilteredStiffness();
    updateFilteredPose();
    updateFilteredWrench();

    // Pose error: measured minus reference for the position, rotation vector for the orientation.
    error_.head<3>() = position_ - position_d_;
    error_.tail<3>() = detail::rotation_error(orientation_d_, orientation_);

    const Eigen::Index n = static_cast<Eigen::Index>(n_joints_);
    const Eigen::MatrixXd jt = jacobian_.transpose();

    // Cartesian spring-damper, mapped to joints by J^T.
    const Eigen::VectorXd tau_task =
        jt * (-cartesian_stiffness_ * error_ - cartesian_damping_ * (jacobian_ * dq_));

    // Joint-space spring-damper towards the nullspace configuration (scalar stiffness and
    // damping), projected with I - J^T pinv(J^T), pinv being the damped (lambda 0.2) one.
    // Deviation: the original builds the identity as a fixed 7 x 7 matrix regardless of the
    // number of joints; this oracle uses n x n with n = number of joints, which is the same for
    // 7-joint robots and well defined for the others.
    const Eigen::MatrixXd projector =
        Eigen::MatrixXd::Identity(n, n) - jt * detail::damped_pinv(jt);
    const Eigen::VectorXd tau_nullspace =
        projector * (nullspace_stiffness_ * (q_d_nullspace_ - q_) - nullspace_damping_ * dq_);

    // Commanded (filtered) wrench mapped to joints.
    const Eigen::VectorXd tau_ext = jt * cartesian_wrench_;

    const Eigen::VectorXd tau_d = tau_task + tau_nullspace + tau_ext;

    // Torque-rate limit: each command moves from its previous value towards tau_d by at most
    // delta_tau_max per call (not per second; the update frequency plays no part here).
    for (Eigen::Index i = 0; i < tau_d.size(); ++i) {
      tau_c_(i) += detail::clamp_value(tau_d(i) - tau_c_(i), -delta_tau_max_, delta_tau_max_);
    }
    return tau_c_;
  }

  // Measured state plus the current (filtered) reference, stiffness and damping.
  void getState(Eigen::VectorXd* q, Eigen::VectorXd* dq, Eigen::Vector3d* position,
                Eigen::Quaterniond* orientation, Eigen::Vector3d* position_d,
                Eigen::Quaterniond* orientation_d, Eigen::Matrix<double, 6, 6>* cartesian_stiffness,
                double* nullspace_stiffness, Eigen::VectorXd* q_d_nullspace,
                Eigen::Matrix<double, 6, 6>* cartesian_damping) const {
    *q = q_;
    *dq = dq_;
    *position = position_;
    orientation->coeffs() = orientation_.coeffs();
    getState(position_d, orientation_d, cartesian_stiffness, nullspace_stiffness, q_d_nullspace,
             cartesian_damping);
  }

  // Current (filtered) values, not the targets. Quirk: the nullspace damping is not reported.
  void getState(Eigen::Vector3d* position_d, Eigen::Quaterniond* orientation_d,
                Eigen::Matrix<double, 6, 6>* cartesian_stiffness, double* nullspace_stiffness,
                Eigen::VectorXd* q_d_nullspace,
                Eigen::Matrix<double, 6, 6>* cartesian_damping) const {
    *position_d = position_d_;
    orientation_d->coeffs() = orientation_d_.coeffs();
    *cartesian_stiffness = cartesian_stiffness_;
    *nullspace_stiffness = nullspace_stiffness_;
    *q_d_nullspace = q_d_nullspace_;
    *cartesian_damping = cartesian_damping_;
  }

  Eigen::VectorXd getLastCommands() const { return tau_c_; }

  // The current, filtered wrench (not the target set by applyWrench).
  Eigen::Matrix<double, 6, 1> getAppliedWrench() const { return cartesian_wrench_; }

  // Pose error of the last control cycle.
  Eigen::Matrix<double, 6, 1> getPoseError() const { return error_; }

 private:
  // Damping target = factor * 2 * sqrt(stiffness target), per Cartesian axis and for the
  // nullspace. Stiffness targets are never negative here, so the root is always defined.
  void applyDamping() {
    for (int i = 0; i < 6; ++i) {
      cartesian_damping_target_(i, i) =
          damping_factors_(i) * (2 * std::sqrt(cartesian_stiffness_target_(i, i)));
    }
    nullspace_damping_target_ = damping_factors_(6) * (2 * std::sqrt(nullspace_stiffness_target_));
  }

  // Release-build behaviour of the original: negative frequencies become 0 (debug asserts). With
  // frequency 0 every filter step is 1, i.e. filters jump straight to the target.
  void setUpdateFrequency(double frequency) { update_frequency_ = std::max(frequency, 0.0); }

  // Release-build behaviour of the original: the value is saturated into [1e-7, 1] (debug asserts
  // 0 < value <= 1).
  void setFilterValue(double value, double* stored) {
    *stored = detail::clamp_value(value, 0.0000001, 1.0);
  }

  void updateFilteredNullspaceConfig() {
    if (filter_params_nullspace_config_ == 1.0) {
      q_d_nullspace_ = q_d_nullspace_target_;
      return;
    }
    const double step = detail::filter_step(update_frequency_, filter_params_nullspace_config_);
    q_d_nullspace_ = detail::blend(q_d_nullspace_target_, q_d_nullspace_, step);
  }

  // Stiffness and damping are blended linearly, element by element, like any other quantity.
  void updateFilteredStiffness() {
    if (filter_params_stiffness_ == 1.0) {
      cartesian_stiffness_ = cartesian_stiffness_target_;
      cartesian_damping_ = cartesian_damping_target_;
      nullspace_stiffness_ = nullspace_stiffness_target_;
      // Quirk: the unfiltered stiffness branch also snaps the nullspace configuration to its
      // target, so the nullspace configuration filter only acts while stiffness filtering is on.
      q_d_nullspace_ = q_d_nullspace_target_;
      nullspace_damping_ = nullspace_damping_target_;
      return;
    }
    const double step = detail::filter_step(update_frequency_, filter_params_stiffness_);
    cartesian_stiffness_ = detail::blend(cartesian_stiffness_target_, cartesian_stiffness_, step);
    cartesian_damping_ = detail::blend(cartesian_damping_target_, cartesian_damping_, step);
    nullspace_stiffness_ = detail::blend(nullspace_stiffness_target_, nullspace_stiffness_, step);
    nullspace_damping_ = detail::blend(nullspace_damping_target_, nullspace_damping_, step);
  }

  void updateFilteredPose() {
    if (filter_params_pose_ == 1.0) {
      position_d_ = position_d_target_;
      orientation_d_.coeffs() = orientation_d_target_.coeffs();
      return;
    }
    const double step = detail::filter_step(update_frequency_, filter_params_pose_);
    position_d_ = detail::blend(position_d_target_, position_d_, step);
    // Quirk: Eigen's slerp towards the target, used as is: the result is never renormalised, so
    // rounding drift, or an unnormalised start from initDesiredPose, is carried along.
    orientation_d_ = orientation_d_.slerp(step, orientation_d_target_);
  }

  void updateFilteredWrench() {
    if (filter_params_wrench_ == 1.0) {
      cartesian_wrench_ = cartesian_wrench_target_;
      return;
    }
    const double step = detail::filter_step(update_frequency_, filter_params_wrench_);
    cartesian_wrench_ = detail::blend(cartesian_wrench_target_, cartesian_wrench_, step);
  }

  // Member defaults follow the published header.
  size_t n_joints_{7};

  Eigen::Matrix<double, 6, 6> cartesian_stiffness_{Eigen::Matrix<double, 6, 6>::Identity()};
  Eigen::Matrix<double, 6, 6> cartesian_damping_{Eigen::Matrix<double, 6, 6>::Identity()};
  Eigen::Matrix<double, 6, 6> cartesian_stiffness_target_{Eigen::Matrix<double, 6, 6>::Identity()};
  Eigen::Matrix<double, 6, 6> cartesian_damping_target_{Eigen::Matrix<double, 6, 6>::Identity()};
  Eigen::Matrix<double, 7, 1> damping_factors_{Eigen::Matrix<double, 7, 1>::Ones()};

  Eigen::VectorXd q_d_nullspace_;
  Eigen::VectorXd q_d_nullspace_target_;
  // Quirk: the current nullspace stiffness and damping start at 1.0 (see the constructor).
  double nullspace_stiffness_{1.0};
  double nullspace_stiffness_target_{1.0};
  double nullspace_damping_{1.0};
  double nullspace_damping_target_{1.0};

  Eigen::VectorXd q_;
  Eigen::VectorXd dq_;
  Eigen::MatrixXd jacobian_;  // 6 x n; rows: translation, then rotation

  // The original leaves the pose error uninitialised until the first control cycle; zero here so
  // getPoseError() before then is defined.
  Eigen::Matrix<double, 6, 1> error_{Eigen::Matrix<double, 6, 1>::Zero()};
  Eigen::Vector3d position_{Eigen::Vector3d::Zero()};
  Eigen::Vector3d position_d_{Eigen::Vector3d::Zero()};
  Eigen::Vector3d position_d_target_{Eigen::Vector3d::Zero()};
  Eigen::Quaterniond orientation_{Eigen::Quaterniond::Identity()};
  Eigen::Quaterniond orientation_d_{Eigen::Quaterniond::Identity()};
  Eigen::Quaterniond orientation_d_target_{Eigen::Quaterniond::Identity()};

  Eigen::Matrix<double, 6, 1> cartesian_wrench_{Eigen::Matrix<double, 6, 1>::Zero()};
  Eigen::Matrix<double, 6, 1> cartesian_wrench_target_{Eigen::Matrix<double, 6, 1>::Zero()};

  Eigen::VectorXd tau_c_;  // last commanded torques

  double update_frequency_{1000};
  // Quirk: all filters start disabled (1.0 means "no filtering").
  double filter_params_nullspace_config_{1.0};
  double filter_params_stiffness_{1.0};
  double filter_params_pose_{1.0};
  double filter_params_wrench_{1.0};

  // Quirk: the default rate limit is 100 (Nm per call), effectively no limit.
  double delta_tau_max_{1.0};
};

}  // namespace published_reference
