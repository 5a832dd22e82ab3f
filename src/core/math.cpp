#include "cartesian_impedance/core/math.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

namespace cartesian_impedance {

Eigen::Vector3d orientation_error(const Eigen::Quaterniond& current,
                                  const Eigen::Quaterniond& desired) noexcept {
  Eigen::Quaterniond relative = current * desired.conjugate();
  if (relative.w() < 0.0) relative.coeffs() = -relative.coeffs();
  const double sin_half = relative.vec().norm();
  // atan2 keeps full precision near pi, where acos(w) would lose half the digits. Up to 60
  // degrees asin(sin_half) is as precise (its slope is below 1.16 there; the product of two
  // normalised quaternions is unit to a few eps) and costs a quarter of glibc's atan2.
  if (sin_half < 1e-9) return (2.0 / relative.w()) * relative.vec();
  const double angle =
      2.0 * (sin_half <= 0.5 ? std::asin(sin_half) : std::atan2(sin_half, relative.w()));
  return (angle / sin_half) * relative.vec();
}

Vector6d pose_error(const Pose& current, const Pose& desired) noexcept {
  Vector6d error;
  error.head<3>() = current.position - desired.position;
  error.tail<3>() = orientation_error(current.orientation, desired.orientation);
  return error;
}

double filter_gain(double dt, double time, double fraction) noexcept {
  if (!(time > 0.0) || !(dt > 0.0)) return 1.0;
  // 1 - (1 - f)^(dt/T), written with log1p/expm1 so that small dt/T keeps its precision.
  return -std::expm1((dt / time) * std::log1p(-fraction));
}

bool clip_norm(Eigen::Ref<Eigen::Vector3d> vector, double max_norm) noexcept {
  // Squared norms first: the common, unclipped case needs no square root. Above about 1e154 the
  // square overflows; the norm is then taken of the vector scaled by its largest entry, so a huge
  // vector is clipped to max_norm along its direction instead of collapsing to zero.
  const double squared_norm = vector.squaredNorm();
  if (squared_norm <= max_norm * max_norm) return false;
  if (std::isfinite(squared_norm)) {
    vector *= max_norm / std::sqrt(squared_norm);
  } else {
    const Eigen::Vector3d direction = vector / vector.cwiseAbs().maxCoeff();
    vector = direction * (max_norm / direction.norm());
  }
  return true;
}

bool limit_rate(const JointVector& previous, const JointVector& max_step,
                JointVector& tau) noexcept {
  // Each joint on its own, like the drives' own limits. Scaling the whole change by the most
  // limited joint's factor would keep its direction, but it also slows every other joint's
  // damping torque down to that joint's pace: the delayed damping then feeds energy in, and at
  // high stiffness the arm settles into a limit cycle (measured: 6 and 10 of 60 reference steps
  // at 3000 N/m on the Panda and the iiwa; none with this per-joint clamp).
  bool limited = false;
  for (Eigen::Index i = 0; i < tau.size(); ++i) {
    const double change = tau[i] - previous[i];
    if (change > max_step[i]) {
      tau[i] = previous[i] + max_step[i];
      limited = true;
    } else if (change < -max_step[i]) {
      tau[i] = previous[i] - max_step[i];
      limited = true;
    }
  }
  return limited;
}

bool saturate_torque(const JointVector& max_torque, JointVector& tau) noexcept {
  bool saturated = false;
  for (Eigen::Index i = 0; i < tau.size(); ++i) {
    if (std::abs(tau[i]) > max_torque[i]) {
      tau[i] = std::copysign(max_torque[i], tau[i]);
      saturated = true;
    }
  }
  return saturated;
}

Matrix6d matrix_sqrt(const Matrix6d& spd) noexcept {
  const Eigen::SelfAdjointEigenSolver<Matrix6d> solver(spd);
  const Vector6d roots = solver.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return solver.eigenvectors() * roots.asDiagonal() * solver.eigenvectors().transpose();
}

bool is_diagonal(const Matrix6d& matrix) noexcept {
  for (int col = 0; col < 6; ++col) {
    for (int row = 0; row < 6; ++row) {
      if (row != col && matrix(row, col) != 0.0) return false;
    }
  }
  return true;
}

Matrix6d damping_from_stiffness(const Matrix6d& stiffness, const Vector6d& damping_ratio) noexcept {
  if (is_diagonal(stiffness)) {
    return (2.0 * damping_ratio.cwiseProduct(stiffness.diagonal().cwiseMax(0.0).cwiseSqrt()))
        .asDiagonal();
  }
  const Vector6d zeta_root = damping_ratio.cwiseSqrt();
  return 2.0 * zeta_root.asDiagonal() * matrix_sqrt(stiffness) * zeta_root.asDiagonal();
}

namespace {

// Clamps the eigenvalues of one symmetric 3x3 block and returns the congruence T with
// T A T = clamped A on the block's range (directions with a zero eigenvalue get scale 0 there;
// positive semi-definiteness of K guarantees the coupling block vanishes along them).
bool clamp_block(Eigen::Ref<Eigen::Matrix3d> block, double min, double max,
                 Eigen::Matrix3d& congruence) noexcept {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(block);
  const Eigen::Vector3d values = solver.eigenvalues();
  const Eigen::Vector3d clamped = values.cwiseMax(min).cwiseMin(max);
  if (clamped == values) {
    congruence.setIdentity();
    return false;
  }
  Eigen::Vector3d scale;
  for (int i = 0; i < 3; ++i) {
    scale[i] =
        values[i] > 1e-12 * std::max(1.0, clamped[i]) ? std::sqrt(clamped[i] / values[i]) : 0.0;
  }
  const Eigen::Matrix3d& axes = solver.eigenvectors();
  congruence = axes * scale.asDiagonal() * axes.transpose();
  block = axes * clamped.asDiagonal() * axes.transpose();
  return true;
}

}  // namespace

bool saturate_stiffness(Matrix6d& stiffness, double translation_min, double translation_max,
                        double rotation_min, double rotation_max) noexcept {
  if (is_diagonal(stiffness)) {
    const Vector6d original = stiffness.diagonal();
    Vector6d clamped;
    clamped << original.head<3>().cwiseMax(translation_min).cwiseMin(translation_max),
        original.tail<3>().cwiseMax(rotation_min).cwiseMin(rotation_max);
    stiffness.diagonal() = clamped;
    return clamped != original;
  }
  Eigen::Matrix3d translation_congruence, rotation_congruence;
  const bool translation_changed = clamp_block(stiffness.topLeftCorner<3, 3>(), translation_min,
                                               translation_max, translation_congruence);
  const bool rotation_changed = clamp_block(stiffness.bottomRightCorner<3, 3>(), rotation_min,
                                            rotation_max, rotation_congruence);
  if (!translation_changed && !rotation_changed) return false;
  const Eigen::Matrix3d coupling =
      translation_congruence * stiffness.topRightCorner<3, 3>() * rotation_congruence;
  stiffness.topRightCorner<3, 3>() = coupling;
  stiffness.bottomLeftCorner<3, 3>() = coupling.transpose();
  return true;
}

Matrix6d block_rotation(const Eigen::Matrix3d& rotation) noexcept {
  Matrix6d result = Matrix6d::Zero();
  result.topLeftCorner<3, 3>() = rotation;
  result.bottomRightCorner<3, 3>() = rotation;
  return result;
}

}  // namespace cartesian_impedance
