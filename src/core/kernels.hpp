#pragma once
// The kernels the control law runs every cycle, private to the core: fixed-size Jacobian
// products, the nullspace projection without forming N, the inertia-shaped damping without forming
// Lambda, and the matrix square root tracked from cycle to cycle. Each computes a formula of
// math.hpp (or of the header comment of controller.hpp) faster than its plain Eigen form; the
// tests hold them to those forms (tests/fast_law_test.cpp, tests/math_test.cpp, with the
// reference formulas in tests/support/law_reference.hpp). All noexcept and allocation-free.

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "cartesian_impedance/core/math.hpp"
#include "cartesian_impedance/core/types.hpp"

namespace cartesian_impedance {

/// Square root of a symmetric positive semi-definite 6x6 matrix that changes little from one call
/// to the next (the normalised stiffness of the inertia-shaped damping, which follows q), as
/// sqrt(N) = Q T Q^T with Q orthonormal and T symmetric and nearly diagonal. The last call's Q
/// turns the new N nearly diagonal, B = Q^T N Q, and Newton steps of the square root in that
/// basis take the rest: from diag(sqrt(b_ii)), each solves X F + F X = B - X^2 with X's diagonal
/// for X, F_ij = R_ij / (sqrt(b_ii) + sqrt(b_jj)). The first is Newton's own step (its error is
/// second order in B's off-diagonal elements); later ones each gain about the size of those
/// elements; and unlike an eigenvector correction none depends on eigenvalue gaps. While the
/// robot moves, Q drifts from N's axes; once an off-diagonal element exceeds kRefineRatio of its
/// diagonal pair, Jacobi rotations (in parallel rounds of three independent ones) turn Q back
/// first. Bounded: if B is far from diagonal (the first call, a jump of the stiffness) or
/// kMaxSweeps sweeps do not get there, Eigen's SelfAdjointEigenSolver decides instead and seeds
/// the next call. The result is matrix_sqrt(N) (math.hpp) to round-off.
class TrackingMatrixSqrt {
 public:
  /// Decomposes `spd` (symmetric; negative round-off eigenvalues count as zero).
  void compute(const Matrix6d& spd) noexcept;
  /// Q (orthonormal to round-off) and T of sqrt(N) = Q T Q^T.
  const Matrix6d& axes() const noexcept { return axes_; }
  const Matrix6d& root_in_axes() const noexcept { return root_; }
  /// Jacobi sweeps of the last call (0: Q was kept); -1 if the last call went to Eigen's solver.
  int sweeps() const noexcept { return sweeps_; }
  /// Newton steps of the last call after the first.
  int refinements() const noexcept { return refinements_; }

  /// Largest off-diagonal part of B (Frobenius norm against the diagonal's) for which Jacobi is
  /// tried, and sweeps allowed. Newton steps start while every b_ij / (sqrt(b_ii) + sqrt(b_jj))^2
  /// is at most kRefineRatio, and stop once the estimated error relative to sqrt(b_ii) + sqrt(b_jj)
  /// is at most kTargetError (below the round-off of one product), after kMaxRefinements at most.
  static constexpr double kMaxOffDiagonal = 1e-2;
  static constexpr int kMaxSweeps = 4;
  static constexpr double kRefineRatio = 1e-5;
  static constexpr double kTargetError = 1e-17;
  static constexpr int kMaxRefinements = 4;

 private:
  bool refine(const Matrix6d& b, double floor) noexcept;
  Matrix6d axes_ = Matrix6d::Identity();
  Matrix6d root_ = Matrix6d::Zero();
  int sweeps_ = -1;
  int refinements_ = 0;
  bool rotated_ = false;  // the last call rotated the axes (which may have drifted since)
};

/// sqrt(N) through a TrackingMatrixSqrt: the same as matrix_sqrt(spd) to round-off, cheaper when
/// called with slowly changing matrices.
Matrix6d matrix_sqrt(const Matrix6d& spd, TrackingMatrixSqrt& tracker) noexcept;

/// The end effector's inverse task-space inertia A = J M^-1 J^T (base frame) through one
/// L D L^T of M, kept so that the acceleration any joint torque gives the end effector,
/// J M^-1 tau, costs one forward substitution. noexcept, allocation-free.
class TaskInertia {
 public:
  /// False (and not valid()) if M is not positive definite.
  bool compute(const Jacobian& jacobian, const JointMatrix& mass) noexcept;
  bool valid() const noexcept { return valid_; }
  void invalidate() noexcept { valid_ = false; }
  /// A = J M^-1 J^T, symmetric [1/kg, ...]: a wrench F accelerates the end effector by A F.
  const Matrix6d& inverse() const noexcept { return inverse_; }
  /// J M^-1 tau: what the joint torque `tau` alone does to the end effector's twist, per second.
  void acceleration(const JointVector& tau, Vector6d& out) const noexcept;

 private:
  JointMatrix factor_;         // L below the diagonal, D(j) L(k, j) above it
  JointVector inverse_pivot_;  // D^-1
  Jacobian reduced_;           // L^-1 J^T, transposed
  Matrix6d inverse_ = Matrix6d::Zero();
  bool valid_ = false;
};

/// The inertia-shaped damping of math.hpp, D = L (2 Z^1/2 sqrt(L^-1 K L^-T) Z^1/2) L^T with
/// Lambda = L L^T = (J M^-1 J^T + lambda^2 I)^-1 (turned
/// into the stiffness frame, Lambda_f = R6^T Lambda R6 with R6 = blockdiag(R, R), when
/// `frame_rotation` is given), computed without forming Lambda: with A = Lambda_f^-1 =
/// R6^T (J M^-1 J^T + lambda^2 I) R6 = V V^T, V upper triangular (A = U E U^T from the last row
/// up, V = U E^1/2), L = V^-T is exactly the lower Cholesky factor of Lambda_f, so the normalised
/// stiffness L^-1 K L^-T is V^T K V and D = V^-T S V^-1. One L D L^T of M and one 6x6
/// factorisation instead of three factorisations and an inverse; the square root through a
/// TrackingMatrixSqrt. The same result to round-off (see the tests for the tolerances). False if
/// M or A is not positive definite. noexcept, allocation-free (bounded-size locals only).
class InertiaShapedDamping {
 public:
  bool compute(const Jacobian& jacobian, const JointMatrix& mass, double lambda,
               const Eigen::Matrix3d* frame_rotation, const Matrix6d& stiffness,
               const Vector6d& damping_ratio, Matrix6d& damping) noexcept;
  /// The task inertia of the last compute(), valid() if it got that far.
  TaskInertia& inertia() noexcept { return inertia_; }

 private:
  TrackingMatrixSqrt tracker_;
  TaskInertia inertia_;
};

/// v = J x for a 6 x n Jacobian: a sum of fixed-size columns, which at these sizes is several
/// times faster than Eigen's product with its dynamic inner dimension. `x` has n elements.
inline void jacobian_times(const Jacobian& jacobian, const JointVector& x, Vector6d& v) noexcept {
  v.setZero();
  for (Eigen::Index i = 0; i < jacobian.cols(); ++i) v += jacobian.col(i) * x[i];
}

/// out = J^T v for a 6 x n Jacobian (resized to n, within its fixed capacity): n fixed-size
/// dot products. `out` is overwritten.
inline void jacobian_transpose_times(const Jacobian& jacobian, const Vector6d& v,
                                     JointVector& out) noexcept {
  out.resize(jacobian.cols());
  for (Eigen::Index i = 0; i < jacobian.cols(); ++i) out[i] = jacobian.col(i).dot(v);
}

/// Computes N tau_0 with N = I - J^T (J J^T + lambda^2 I)^-1 J without forming N and without an
/// SVD: a 6x6 Cholesky (or an n x n one when n < 6, via J^T J, which is the same matrix
/// function), with a pivoting LDLT as fallback when the matrix is only semi-definite.
/// lambda = 0 gives the exact projector for a full-rank J. The workspace is sized once.
class NullspaceProjector {
 public:
  NullspaceProjector() = default;
  // The members are scratch space for one call; a copy starts with fresh scratch space (copying
  // Eigen's never-computed factorisations would read their uninitialised status fields).
  NullspaceProjector(const NullspaceProjector&) noexcept {}
  NullspaceProjector& operator=(const NullspaceProjector&) noexcept { return *this; }

  /// Writes N tau_0 to `projected`; `tau_0` and `projected` may not alias.
  void project(const Jacobian& jacobian, double lambda, const JointVector& tau_0,
               JointVector& projected) noexcept;

  /// Dynamically consistent projection N tau_0 with N = I - J^T Lambda J M^-1 and
  /// Lambda = (J M^-1 J^T + lambda^2 I)^-1: tau_0 then causes no end-effector acceleration (for
  /// lambda = 0), also while the arm moves. Returns false if M is not positive definite.
  bool project_dynamic(const Jacobian& jacobian, const JointMatrix& mass, double lambda,
                       const JointVector& tau_0, JointVector& projected) noexcept;

  /// N tau with the projector of the last project() or project_dynamic() call (same J and M),
  /// reusing its factorisation: a second torque projected for little more than two products.
  /// `tau` and `projected` may not alias.
  void project_again(const Jacobian& jacobian, const JointVector& tau,
                     JointVector& projected) noexcept;

  /// The static force at the end effector [N; Nm, base frame] that the joint torque `tau` presses
  /// with against a rigid contact there, in the damped least-squares sense:
  /// (J J^T + lambda^2 I)^-1 J tau (lambda at least 1e-3 where J J^T is singular). Reuses the
  /// factorisation of the last project() call when it had one.
  void task_force(const Jacobian& jacobian, double lambda, const JointVector& tau,
                  Vector6d& force) noexcept;

 private:
  // task_solution_ = task_gram_^-1 task_vector_ (the 6x6 system both projectors solve).
  void solve_task_system() noexcept;
  // x = task_gram_^-1 rhs with the factorisation solve_task_system() made.
  void solve_task_again(const Vector6d& rhs, Vector6d& x) const noexcept;

  // Which system the last projection factored: project_again() and task_force() reuse it.
  enum class Path { none, task, joint, dynamic_task, dynamic_joint };
  Path last_ = Path::none;
  bool joint_llt_ok_ = false;
  bool factored_ = false;  // task_factor_ holds the L D L^T of task_gram_ (else task_ldlt_)
  Matrix6d task_factor_;
  Vector6d task_inverse_pivot_;

  Eigen::LDLT<Matrix6d> task_ldlt_;
  Eigen::LLT<JointMatrix> joint_llt_;
  Eigen::LDLT<JointMatrix> joint_ldlt_;
  Eigen::LLT<JointMatrix> mass_llt_;
  Eigen::PartialPivLU<JointMatrix> joint_lu_;
  Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::ColMajor, kMaxJoints, 6> mass_inverse_jt_;
  Matrix6d task_gram_;
  JointMatrix joint_gram_;
  JointMatrix joint_system_;
  Vector6d task_vector_;
  Vector6d task_solution_;
  JointVector joint_vector_;
};

}  // namespace cartesian_impedance
