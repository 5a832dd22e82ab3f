#pragma once
/// @file
/// The mathematics of the control law, one small function per idea, as the specification reads:
/// the pose error, the filter gain, the limits (norm clipping, torque saturation and rate), the
/// damping rules and the stiffness saturation. All are noexcept and allocate nothing. The law
/// itself is CartesianImpedanceController (controller.hpp); the fast kernels it evaluates these
/// with each cycle (the nullspace projection, the inertia-shaped damping without forming Lambda,
/// the tracked matrix square root) are private to the core and tested against these formulas.
///
/// The default damping is shaped by the task-space inertia Lambda = (J M^-1 J^T + lambda^2 I)^-1
/// = L L^T, so that each mode of M x'' + D x' + K x = 0 has damping ratio zeta:
///
///   D = L (2 Z^1/2 sqrt(L^-1 K L^-T) Z^1/2) L^T,   d = 2 zeta sqrt(m k) in one dimension;
///
/// with dynamics.inertia_shaped_damping off, every mass counts as 1 (the published controller's
/// damping factor): D = damping_from_stiffness(K, zeta) = 2 Z^1/2 sqrt(K) Z^1/2.

#include "cartesian_impedance/core/types.hpp"

namespace cartesian_impedance {

/// Rotation vector of R R_d^T [rad], in the base frame: the axis times the angle by which the
/// desired orientation must be turned (about base axes) to reach the current one. The quaternion
/// sign is chosen for the short way, so q and -q give the same result; the angle is in [0, pi].
Eigen::Vector3d orientation_error(const Eigen::Quaterniond& current,
                                  const Eigen::Quaterniond& desired) noexcept;

/// e = [p - p_d; log(R R_d^T)] in the base frame [m; rad].
Vector6d pose_error(const Pose& current, const Pose& desired) noexcept;

/// Gain `a` of the filter a_{k+1} = (1 - a) a_k + a a_d such that `fraction` of a step is applied
/// after `time` seconds when called every `dt` seconds: a = 1 - (1 - fraction)^(dt / time). This
/// holds for any (even varying) dt, so 250 Hz and 1 kHz give the same response. time <= 0 gives 1.
double filter_gain(double dt, double time, double fraction) noexcept;

/// Scales `vector` down to `max_norm` if it is longer, keeping its direction; true if it did.
/// Exact for any finite vector (no overflow of the squared norm).
bool clip_norm(Eigen::Ref<Eigen::Vector3d> vector, double max_norm) noexcept;

/// Limits each joint's change from `previous` to +-`max_step` (e.g. rate [Nm/s] * dt [s]), joint
/// by joint; true if it limited any.
bool limit_rate(const JointVector& previous, const JointVector& max_step,
                JointVector& tau) noexcept;

/// Clamps each joint torque to [-max_torque, max_torque]; true if any was clamped.
bool saturate_torque(const JointVector& max_torque, JointVector& tau) noexcept;

/// Square root of a symmetric positive semi-definite matrix (negative round-off eigenvalues are
/// treated as zero).
Matrix6d matrix_sqrt(const Matrix6d& spd) noexcept;

/// Damping D = 2 Z^(1/2) sqrt(K) Z^(1/2) with Z = diag(zeta): for a diagonal K this is
/// d_i = 2 zeta_i sqrt(k_i); for a full K it stays symmetric positive semi-definite and shares the
/// principal axes of K when zeta is uniform.
Matrix6d damping_from_stiffness(const Matrix6d& stiffness, const Vector6d& damping_ratio) noexcept;

/// Saturates a symmetric positive semi-definite 6x6 stiffness: the eigenvalues of its
/// translational and rotational 3x3 blocks are clamped to the given ranges, and a coupling block
/// is scaled by the same congruence so the result stays positive semi-definite. For a diagonal K
/// this is a clamp of each diagonal value. Returns true if anything changed.
bool saturate_stiffness(Matrix6d& stiffness, double translation_min, double translation_max,
                        double rotation_min, double rotation_max) noexcept;

/// True if every off-diagonal element is exactly zero.
bool is_diagonal(const Matrix6d& matrix) noexcept;

/// blockdiag(R, R): maps 6-vectors [linear; angular] from a frame with orientation R to the base.
Matrix6d block_rotation(const Eigen::Matrix3d& rotation) noexcept;

}  // namespace cartesian_impedance
