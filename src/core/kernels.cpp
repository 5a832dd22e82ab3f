#include "kernels.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

namespace cartesian_impedance {

namespace {

// Factors a symmetric positive definite 6x6 A = L D L^T (only its lower triangle is read): L's
// strictly lower part goes to `factor`'s lower triangle, D^-1 to `inverse_pivot`. Written out
// because at this size Eigen's LLT spends most of its time in the set-up of its general blocked
// triangular solver; and L D L^T rather than Cholesky because the cost here is the chain of
// latencies from one column to the next, and L D L^T has one division in it per column where
// Cholesky has a square root and a division. Right-looking (each column updates the rest at
// once), so that the next pivot waits for one multiply-subtract after the division, not for a sum
// over all earlier columns; the loops have constant bounds, which the compiler unrolls
// completely. False if A is not positive definite.
inline __attribute__((always_inline)) bool ldlt_factor(const Matrix6d& system, Matrix6d& factor,
                                                       Vector6d& inverse_pivot) noexcept {
  Matrix6d a = system;  // a local, so that the unrolled code keeps it in registers
#pragma GCC unroll 6
  for (int j = 0; j < 6; ++j) {
    const double pivot = a(j, j);
    if (!(pivot > 0.0)) return false;
    inverse_pivot[j] = 1.0 / pivot;
    Vector6d unscaled;  // D(j) L(i, j)
#pragma GCC unroll 6
    for (int i = j + 1; i < 6; ++i) {
      unscaled[i] = a(i, j);
      a(i, j) = unscaled[i] * inverse_pivot[j];
    }
#pragma GCC unroll 6
    for (int k = j + 1; k < 6; ++k) {
#pragma GCC unroll 6
      for (int i = k; i < 6; ++i) a(i, k) -= a(i, j) * unscaled[k];
    }
  }
  factor = a;
  return true;
}

// x = A^-1 b with A = L D L^T as ldlt_factor() left it.
inline __attribute__((always_inline)) void ldlt_solve(const Matrix6d& factor,
                                                      const Vector6d& inverse_pivot,
                                                      const Vector6d& rhs, Vector6d& x) noexcept {
  Vector6d b = rhs;
#pragma GCC unroll 6
  for (int i = 0; i < 6; ++i) {  // L y = b
#pragma GCC unroll 6
    for (int k = 0; k < i; ++k) b[i] -= factor(i, k) * b[k];
  }
#pragma GCC unroll 6
  for (int i = 0; i < 6; ++i) b[i] *= inverse_pivot[i];  // D z = y
#pragma GCC unroll 6
  for (int i = 5; i >= 0; --i) {  // L^T x = z
#pragma GCC unroll 6
    for (int k = i + 1; k < 6; ++k) b[i] -= factor(k, i) * b[k];
  }
  x = b;
}

// out = left * right^T for two 6 x n matrices. Column c of the result is
// sum_i right(c, i) left.col(i); three columns at a time give nine independent chains of
// additions held in registers.
void outer_sum(const Jacobian& left, const Jacobian& right, Matrix6d& out) noexcept {
  const Eigen::Index n = left.cols();
  for (int c = 0; c < 6; c += 3) {
    Vector6d first = Vector6d::Zero(), second = Vector6d::Zero(), third = Vector6d::Zero();
    for (Eigen::Index i = 0; i < n; ++i) {
      const Vector6d column = left.col(i);
      first += column * right(c, i);
      second += column * right(c + 1, i);
      third += column * right(c + 2, i);
    }
    out.col(c) = first;
    out.col(c + 1) = second;
    out.col(c + 2) = third;
  }
}

}  // namespace

void NullspaceProjector::solve_task_system() noexcept {
  // L D L^T is the fast path; a singular J with lambda = 0 makes the matrix only semi-definite,
  // and Eigen's pivoting LDLT then still returns a finite least-squares answer. The factor is
  // kept for solve_task_again() (the tank's nullspace dissipation and the caps solve again in
  // most cycles); the solve works on the local copy, still in registers.
  Matrix6d factor;
  factored_ = ldlt_factor(task_gram_, factor, task_inverse_pivot_);
  if (factored_) {
    ldlt_solve(factor, task_inverse_pivot_, task_vector_, task_solution_);
    task_factor_ = factor;
  } else {
    task_ldlt_.compute(task_gram_);
    task_solution_ = task_ldlt_.solve(task_vector_);
  }
}

void NullspaceProjector::solve_task_again(const Vector6d& rhs, Vector6d& x) const noexcept {
  if (factored_) {
    ldlt_solve(task_factor_, task_inverse_pivot_, rhs, x);
  } else {
    x = task_ldlt_.solve(rhs);
  }
}

void NullspaceProjector::project(const Jacobian& jacobian, double lambda, const JointVector& tau_0,
                                 JointVector& projected) noexcept {
  const Eigen::Index n = jacobian.cols();
  const double lambda_squared = lambda * lambda;
  last_ = n >= 6 ? Path::task : Path::joint;
  if (n >= 6) {
    // N tau_0 = tau_0 - J^T (J J^T + lambda^2 I)^-1 (J tau_0): O(6n) beyond the 6x6 factorisation.
    // (The factorisation reads the lower triangle of J J^T only.)
    outer_sum(jacobian, jacobian, task_gram_);
    task_gram_.diagonal().array() += lambda_squared;
    jacobian_times(jacobian, tau_0, task_vector_);
    solve_task_system();
    jacobian_transpose_times(jacobian, task_solution_, projected);
    projected = tau_0 - projected;
  } else {
    // Push-through identity: J^T (J J^T + l^2 I)^-1 J = J^T J (J^T J + l^2 I)^-1, an n x n system,
    // which stays regular when n < 6 makes J J^T singular.
    joint_gram_.noalias() = jacobian.transpose() * jacobian;
    joint_system_ = joint_gram_;
    joint_system_.diagonal().array() += lambda_squared;
    joint_llt_.compute(joint_system_);
    joint_llt_ok_ = joint_llt_.info() == Eigen::Success;
    if (joint_llt_ok_) {
      joint_vector_ = joint_llt_.solve(tau_0);
    } else {
      joint_ldlt_.compute(joint_system_);
      joint_vector_ = joint_ldlt_.solve(tau_0);
    }
    projected = tau_0;
    projected.noalias() -= joint_gram_ * joint_vector_;
  }
}

bool NullspaceProjector::project_dynamic(const Jacobian& jacobian, const JointMatrix& mass,
                                         double lambda, const JointVector& tau_0,
                                         JointVector& projected) noexcept {
  const Eigen::Index n = jacobian.cols();
  mass_llt_.compute(mass);
  if (mass_llt_.info() != Eigen::Success) {
    last_ = Path::none;
    return false;
  }
  last_ = n >= 6 ? Path::dynamic_task : Path::dynamic_joint;
  mass_inverse_jt_ = mass_llt_.solve(jacobian.transpose());  // M^-1 J^T, n x 6
  joint_vector_ = mass_llt_.solve(tau_0);                    // M^-1 tau_0
  if (n >= 6) {
    // tau_0 - J^T (J M^-1 J^T + l^2 I)^-1 J M^-1 tau_0
    task_gram_.noalias() = jacobian * mass_inverse_jt_;
    task_gram_.diagonal().array() += lambda * lambda;
    task_vector_.noalias() = jacobian * joint_vector_;
    solve_task_system();
    projected = tau_0;
    projected.noalias() -= jacobian.transpose() * task_solution_;
  } else {
    // Push-through as in project(): J^T (J W J^T + l^2 I)^-1 J W = J^T J (W J^T J + l^2 I)^-1 W
    // with W = M^-1; the n x n matrix is not symmetric, hence LU.
    joint_gram_.noalias() = jacobian.transpose() * jacobian;
    joint_system_.noalias() = mass_inverse_jt_ * jacobian;
    joint_system_.diagonal().array() += lambda * lambda;
    joint_lu_.compute(joint_system_);
    JointVector solved = joint_lu_.solve(joint_vector_);
    projected = tau_0;
    projected.noalias() -= joint_gram_ * solved;
  }
  return true;
}

void NullspaceProjector::project_again(const Jacobian& jacobian, const JointVector& tau,
                                       JointVector& projected) noexcept {
  switch (last_) {
    case Path::none:
      projected = tau;
      return;
    case Path::task:
      jacobian_times(jacobian, tau, task_vector_);
      solve_task_again(task_vector_, task_solution_);
      jacobian_transpose_times(jacobian, task_solution_, projected);
      projected = tau - projected;
      return;
    case Path::joint:
      joint_vector_ =
          joint_llt_ok_ ? JointVector(joint_llt_.solve(tau)) : JointVector(joint_ldlt_.solve(tau));
      projected = tau;
      projected.noalias() -= joint_gram_ * joint_vector_;
      return;
    case Path::dynamic_task:
      joint_vector_ = mass_llt_.solve(tau);
      task_vector_.noalias() = jacobian * joint_vector_;
      solve_task_again(task_vector_, task_solution_);
      projected = tau;
      projected.noalias() -= jacobian.transpose() * task_solution_;
      return;
    case Path::dynamic_joint: {
      joint_vector_ = mass_llt_.solve(tau);
      const JointVector solved = joint_lu_.solve(joint_vector_);
      projected = tau;
      projected.noalias() -= joint_gram_ * solved;
      return;
    }
  }
}

void NullspaceProjector::task_force(const Jacobian& jacobian, double lambda, const JointVector& tau,
                                    Vector6d& force) noexcept {
  jacobian_times(jacobian, tau, task_vector_);
  if (last_ == Path::task) {
    // The last projection factored J J^T + lambda^2 I already.
    solve_task_again(task_vector_, force);
    return;
  }
  // A damping of at least 1e-3 keeps the system regular where J loses rank (an arm with fewer
  // than six joints, a singular pose with lambda = 0).
  Matrix6d gram;
  outer_sum(jacobian, jacobian, gram);
  gram.diagonal().array() += std::max(lambda * lambda, 1e-6);
  Matrix6d factor;
  Vector6d inverse_pivot;
  if (ldlt_factor(gram, factor, inverse_pivot)) {
    ldlt_solve(factor, inverse_pivot, task_vector_, force);
  } else {
    force.setZero();
  }
}

namespace {

constexpr double kEpsilon = std::numeric_limits<double>::epsilon();

// The Jacobi rotation J (J(p,p) = J(q,q) = c, J(p,q) = -J(q,p) = s) for which J^T b J has a zero
// at (p, q); t = tan(angle) is the smaller root of t^2 + 2 tau t - 1 = 0 (Golub and Van Loan,
// sym.schur2), which keeps the angle below 45 degrees.
struct Rotation {
  int p, q;
  double c, s, t;
};

Rotation make_rotation(const Matrix6d& b, int p, int q) noexcept {
  const double apq = b(p, q);
  const double tau = (b(q, q) - b(p, p)) / (2.0 * apq);
  // For |tau| > 1e8, t = 1 / (2 tau) and c = 1 are exact to round-off (the next terms are
  // relatively 1 / (4 tau^2) and t^2 / 2); the common case once Q tracks, and the square roots
  // of the general formula are the longest latencies of a sweep.
  if (std::abs(tau) > 1e8) return {p, q, 1.0, 0.5 / tau, 0.5 / tau};
  const double t = std::copysign(1.0, tau) / (std::abs(tau) + std::sqrt(1.0 + tau * tau));
  const double c = 1.0 / std::sqrt(1.0 + t * t);
  return {p, q, c, t * c, t};
}

// b = J^T b J and axes = axes J.
void apply(const Rotation& r, Matrix6d& b, Matrix6d& axes) noexcept {
  const int p = r.p, q = r.q;
  const double apq = b(p, q), app = b(p, p), aqq = b(q, q);
  const Vector6d column_p = b.col(p), column_q = b.col(q);
  b.col(p) = r.c * column_p - r.s * column_q;
  b.col(q) = r.s * column_p + r.c * column_q;
  b.row(p) = b.col(p).transpose();
  b.row(q) = b.col(q).transpose();
  b(p, p) = app - r.t * apq;
  b(q, q) = aqq + r.t * apq;
  b(p, q) = 0.0;
  b(q, p) = 0.0;
  const Vector6d axis_p = axes.col(p), axis_q = axes.col(q);
  axes.col(p) = r.c * axis_p - r.s * axis_q;
  axes.col(q) = r.s * axis_p + r.c * axis_q;
}

// The 15 pairs of six indices in five rounds of three disjoint pairs: the rotations of a round
// read only elements the others leave alone, so their square roots and divisions overlap.
constexpr int kRounds[5][3][2] = {{{0, 1}, {2, 3}, {4, 5}},
                                  {{0, 2}, {1, 4}, {3, 5}},
                                  {{0, 3}, {1, 5}, {2, 4}},
                                  {{0, 4}, {1, 3}, {2, 5}},
                                  {{0, 5}, {1, 2}, {3, 4}}};

}  // namespace

void TrackingMatrixSqrt::compute(const Matrix6d& spd) noexcept {
  // One Newton-Schulz step, Q (3 I - Q^T Q) / 2, undoes the drift from orthonormality that
  // thousands of calls' worth of rotations would accumulate (quadratically: 1e-14 leaves 1e-28);
  // only rotations cause drift.
  if (rotated_) {
    const Matrix6d gram = axes_.transpose() * axes_;
    axes_ = axes_ * (1.5 * Matrix6d::Identity() - 0.5 * gram);
  }
  rotated_ = false;
  Matrix6d b = axes_.transpose() * spd * axes_;
  b = 0.5 * (b + b.transpose());
  const double diagonal = b.diagonal().squaredNorm();
  const double off_diagonal = b.squaredNorm() - diagonal;
  // Elements below eps times the trace are the round-off N came with (they matter only where
  // both diagonal elements are as small, and there the square root is undetermined to about
  // sqrt(eps) anyway); they are left out of the tests and of the Newton steps.
  const double floor = kEpsilon * std::abs(b.trace());
  refinements_ = 0;
  // Jacobi converges quadratically from a nearly diagonal start; far from one, the sweeps
  // would cost more than Eigen's tridiagonal QR.
  if (diagonal > 0.0 && off_diagonal <= kMaxOffDiagonal * kMaxOffDiagonal * diagonal) {
    for (sweeps_ = 0; sweeps_ <= kMaxSweeps; ++sweeps_) {
      if (refine(b, floor)) return;
      if (sweeps_ == kMaxSweeps) break;
      for (const auto& round : kRounds) {
        Rotation rotations[3];
        int count = 0;
        for (const auto& pair : round) {
          if (b(pair[0], pair[1]) != 0.0) rotations[count++] = make_rotation(b, pair[0], pair[1]);
        }
        for (int k = 0; k < count; ++k) apply(rotations[k], b, axes_);
        rotated_ = rotated_ || count > 0;
      }
    }
  }
  sweeps_ = -1;
  const Eigen::SelfAdjointEigenSolver<Matrix6d> solver(spd);
  axes_ = solver.eigenvectors();
  root_ = solver.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
}

bool TrackingMatrixSqrt::refine(const Matrix6d& b, double floor) noexcept {
  const Vector6d roots = b.diagonal().cwiseMax(0.0).cwiseSqrt();
  // Newton steps X += F on X^2 = B, each solving X F + F X = R = B - X^2 with X's diagonal part
  // S = diag(s) for X: F_ij = R_ij / (s_i + s_j), whatever the eigenvalue gaps. From X = S the
  // step is Newton's own and leaves an error of about r0^2 (r0 the largest |b_ij| / (s_i + s_j)^2
  // over i != j); every later step is off Newton's by X - S, whose elements are at most
  // r0 (s_i + s_j), so a correction of relative size r leaves about r (r + 6 r0). Only the upper
  // triangles are computed; X stays exactly symmetric.
  root_ = roots.asDiagonal();
  Matrix6d residual = b;  // B - S^2: B's off-diagonal part
  residual.diagonal().setZero();
  Matrix6d inverse_sum;  // 1 / (s_i + s_j), upper triangle, once a correction needs it
  bool have_inverse_sum = false;
  double first = 0.0;
  for (int step = 0;; ++step) {
    double ratio = 0.0;
    for (int q = 0; q < 6; ++q) {
      for (int p = 0; p <= q; ++p) {
        const double sum = roots[p] + roots[q];
        // A correction below the target error (of X's scale) is left out: at rest, all are,
        // and the call costs no division.
        if (std::abs(residual(p, q)) <= std::max(floor, kTargetError * sum * sum) || !(sum > 0.0)) {
          continue;
        }
        if (!have_inverse_sum) {
          for (int j = 0; j < 6; ++j) {
            for (int i = 0; i <= j; ++i) inverse_sum(i, j) = 1.0 / (roots[i] + roots[j]);
          }
          have_inverse_sum = true;
        }
        const double correction = residual(p, q) * inverse_sum(p, q);
        ratio = std::max(ratio, std::abs(correction * inverse_sum(p, q)));
        root_(p, q) += correction;
        if (p != q) root_(q, p) += correction;
      }
    }
    if (step == 0) {
      if (ratio > kRefineRatio) return false;  // far from diagonal: a Jacobi sweep first
      first = ratio;
    } else if (ratio > first) {
      return false;  // a guard: for r0 <= kRefineRatio the steps contract by about 6 r0
    }
    const double error = ratio * (step == 0 ? ratio : std::max(ratio, 6.0 * first));
    if (error <= kTargetError) return true;
    if (step == kMaxRefinements) return false;
    ++refinements_;
    for (int q = 0; q < 6; ++q) {
      for (int p = 0; p <= q; ++p) residual(p, q) = b(p, q) - root_.col(p).dot(root_.col(q));
    }
  }
}

Matrix6d matrix_sqrt(const Matrix6d& spd, TrackingMatrixSqrt& tracker) noexcept {
  tracker.compute(spd);
  return tracker.axes() * tracker.root_in_axes() * tracker.axes().transpose();
}

// A = J M^-1 J^T through M = L D L^T (right-looking, lower triangle only, as Eigen's LLT reads
// it; no square roots): A = (L^-1 J^T)^T D^-1 (L^-1 J^T). False if M is not positive definite.
bool TaskInertia::compute(const Jacobian& jacobian, const JointMatrix& mass) noexcept {
  valid_ = false;
  const Eigen::Index n = jacobian.cols();
  factor_ = mass;
  inverse_pivot_.resize(n);
  for (Eigen::Index j = 0; j < n; ++j) {
    const double pivot = factor_(j, j);
    if (!(pivot > 0.0)) return false;
    inverse_pivot_[j] = 1.0 / pivot;
    for (Eigen::Index k = j + 1; k < n; ++k) {
      const double unscaled = factor_(k, j);
      // Columns k > j are updated column by column; row j of the upper triangle (unused by the
      // factorisation) keeps D(j) L(k, j) for the update.
      factor_(j, k) = unscaled;
      factor_(k, j) = unscaled * inverse_pivot_[j];
    }
    for (Eigen::Index k = j + 1; k < n; ++k) {
      const double unscaled = factor_(j, k);
      for (Eigen::Index i = k; i < n; ++i) factor_(i, k) -= factor_(i, j) * unscaled;
    }
  }
  // Column i of `reduced_` is row i of L^-1 J^T: forward substitution with fixed-size columns.
  reduced_.resize(6, n);
  Jacobian weighted(6, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    Vector6d column = jacobian.col(i);
    for (Eigen::Index k = 0; k < i; ++k) column -= factor_(i, k) * reduced_.col(k);
    reduced_.col(i) = column;
    weighted.col(i) = column * inverse_pivot_[i];
  }
  outer_sum(reduced_, weighted, inverse_);  // only its upper triangle is summed in order
  inverse_.triangularView<Eigen::StrictlyLower>() = inverse_.transpose();
  valid_ = true;
  return true;
}

void TaskInertia::acceleration(const JointVector& tau, Vector6d& out) const noexcept {
  // J M^-1 tau = (L^-1 J^T)^T D^-1 (L^-1 tau): one forward substitution with L.
  // With z = D^-1 y, L(i, k) y[k] = (D(k) L(i, k)) z[k], and D(k) L(i, k) is kept above the
  // diagonal: row i of L is read down column i of factor_, contiguously.
  const Eigen::Index n = reduced_.cols();
  out.setZero();
  double z[kMaxJoints];
  for (Eigen::Index i = 0; i < n; ++i) {
    double value = tau[i];
    for (Eigen::Index k = 0; k < i; ++k) value -= factor_(k, i) * z[k];
    z[i] = value * inverse_pivot_[i];
    out += reduced_.col(i) * z[i];
  }
}

bool InertiaShapedDamping::compute(const Jacobian& jacobian, const JointMatrix& mass, double lambda,
                                   const Eigen::Matrix3d* frame_rotation, const Matrix6d& stiffness,
                                   const Vector6d& damping_ratio, Matrix6d& damping) noexcept {
  if (!inertia_.compute(jacobian, mass)) return false;
  Matrix6d a = inertia_.inverse();  // J M^-1 J^T; only the upper triangle is read below
  a.diagonal().array() += lambda * lambda;
  if (frame_rotation != nullptr) {
    // R6^T A R6 block by block (R6 = blockdiag(R, R) is half zeros); only the upper triangle of
    // A holds the sums of products in the same order the base frame uses, so it is mirrored first.
    a.triangularView<Eigen::StrictlyLower>() = a.transpose();
    const Eigen::Matrix3d& r = *frame_rotation;
    const Eigen::Matrix3d top = r.transpose() * a.topLeftCorner<3, 3>() * r;
    const Eigen::Matrix3d coupling = r.transpose() * a.topRightCorner<3, 3>() * r;
    const Eigen::Matrix3d bottom = r.transpose() * a.bottomRightCorner<3, 3>() * r;
    a.topLeftCorner<3, 3>() = top;
    a.topRightCorner<3, 3>() = coupling;
    a.bottomRightCorner<3, 3>() = bottom;
  }
  // A = U E U^T with U unit upper triangular and E diagonal, from the last column backwards
  // (right-looking; one division per column in the chain from column to column), then
  // V = U E^1/2, so A = V V^T with the square roots off that chain.
  Matrix6d v = Matrix6d::Zero();
  v.triangularView<Eigen::Upper>() = a.triangularView<Eigen::Upper>();
  Vector6d pivots;
#pragma GCC unroll 6
  for (int j = 5; j >= 0; --j) {
    const double pivot = v(j, j);
    if (!(pivot > 0.0)) return false;
    pivots[j] = pivot;
    const double inverse_pivot = 1.0 / pivot;
    Vector6d unscaled;  // E(j) U(i, j)
#pragma GCC unroll 6
    for (int i = 0; i < j; ++i) {
      unscaled[i] = v(i, j);
      v(i, j) *= inverse_pivot;
    }
#pragma GCC unroll 6
    for (int k = 0; k < j; ++k) {
#pragma GCC unroll 6
      for (int i = 0; i <= k; ++i) v(i, k) -= v(i, j) * unscaled[k];
    }
  }
  const Vector6d roots = pivots.cwiseSqrt();
  const Vector6d inverse_diagonal = roots.cwiseInverse();
#pragma GCC unroll 6
  for (int j = 0; j < 6; ++j) {
    v.col(j).head(j) *= roots[j];
    v(j, j) = roots[j];
  }
  // L^-1 K L^-T = V^T K V, and with its square root Q T Q^T and L = V^-T,
  // D = L (2 Z^1/2 Q T Q^T Z^1/2) L^T = 2 P T P^T with P = V^-T Z^1/2 Q: a forward substitution
  // with V^T, row by row (each row a fixed-size vector operation).
  Matrix6d normalised;
  if (is_diagonal(stiffness)) {  // the common case: one 6x6 product instead of two
    normalised.noalias() = (v.transpose() * stiffness.diagonal().asDiagonal()) * v;
  } else {
    normalised.noalias() = v.transpose() * stiffness * v;
  }
  normalised = 0.5 * (normalised + normalised.transpose());
  tracker_.compute(normalised);
  const Vector6d zeta_root = damping_ratio.cwiseSqrt();
  Eigen::Matrix<double, 6, 6, Eigen::RowMajor> projection =
      zeta_root.asDiagonal() * tracker_.axes();
#pragma GCC unroll 6
  for (int i = 0; i < 6; ++i) {
#pragma GCC unroll 6
    for (int k = 0; k < i; ++k) projection.row(i) -= v(k, i) * projection.row(k);
    projection.row(i) *= inverse_diagonal[i];
  }
  damping.noalias() = 2.0 * projection * tracker_.root_in_axes() * projection.transpose();
  damping = 0.5 * (damping + damping.transpose()).eval();  // exactly symmetric, as D must be
  return damping.allFinite();
}

}  // namespace cartesian_impedance
