#pragma once
// The law's formulas in their plain Eigen form, as the tests hold the core's fast kernels to them
// (src/core/kernels.hpp): the task-space inertia, the damping shaped by it, and the nullspace
// projector as a whole matrix.

#include <Eigen/Cholesky>

#include "cartesian_impedance/core/math.hpp"
#include "src/core/kernels.hpp"

namespace law_reference {

namespace ci = cartesian_impedance;

/// Task-space inertia Lambda = (J M^-1 J^T + lambda^2 I)^-1 [kg, kg m^2]; false if M is not
/// positive definite. `lambda` keeps it finite at singular configurations.
inline bool task_space_inertia(const ci::Jacobian& jacobian, const ci::JointMatrix& mass,
                               double lambda, ci::Matrix6d& inertia) {
  const Eigen::LLT<ci::JointMatrix> mass_llt(mass);
  if (mass_llt.info() != Eigen::Success) return false;
  const Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::ColMajor, ci::kMaxJoints, 6> x =
      mass_llt.solve(jacobian.transpose());
  ci::Matrix6d inverse_inertia = jacobian * x;
  inverse_inertia.diagonal().array() += lambda * lambda;
  const Eigen::LLT<ci::Matrix6d> llt(inverse_inertia);
  if (llt.info() != Eigen::Success) return false;
  inertia = llt.solve(ci::Matrix6d::Identity());
  return inertia.allFinite();
}

/// Damping shaped by the task-space inertia: D = L (2 Z^1/2 sqrt(L^-1 K L^-T) Z^1/2) L^T with
/// Lambda = L L^T, so that each mode of the mass-spring system M x'' + D x' + K x = 0 has damping
/// ratio zeta (for a uniform zeta): d = 2 zeta sqrt(m k) in one dimension. All matrices in the
/// same frame.
inline ci::Matrix6d inertia_shaped_damping(const ci::Matrix6d& stiffness,
                                           const ci::Vector6d& damping_ratio,
                                           const ci::Matrix6d& inertia) {
  const Eigen::LLT<ci::Matrix6d> llt(0.5 * (inertia + inertia.transpose()));
  const ci::Matrix6d lower = llt.matrixL();
  // K in coordinates where the inertia is the identity: L^-1 K L^-T.
  ci::Matrix6d normalised = lower.triangularView<Eigen::Lower>().solve(stiffness);
  normalised = lower.triangularView<Eigen::Lower>().solve(normalised.transpose()).transpose();
  const ci::Vector6d zeta_root = damping_ratio.cwiseSqrt();
  const ci::Matrix6d inner = 2.0 * zeta_root.asDiagonal() *
                             ci::matrix_sqrt(0.5 * (normalised + normalised.transpose())) *
                             zeta_root.asDiagonal();
  return lower * inner * lower.transpose();
}

/// The n x n matrix N the projector applies, column by column through project() (or, with a mass
/// matrix, project_dynamic()): the kernel's own N, for checking its properties.
inline ci::JointMatrix nullspace_matrix(ci::NullspaceProjector& projector,
                                        const ci::Jacobian& jacobian, double lambda) {
  const Eigen::Index n = jacobian.cols();
  ci::JointMatrix result(n, n);
  ci::JointVector column(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const ci::JointVector unit = ci::JointVector::Unit(n, i);
    projector.project(jacobian, lambda, unit, column);
    result.col(i) = column;
  }
  return result;
}

inline ci::JointMatrix nullspace_matrix(ci::NullspaceProjector& projector,
                                        const ci::Jacobian& jacobian, const ci::JointMatrix& mass,
                                        double lambda) {
  const Eigen::Index n = jacobian.cols();
  ci::JointMatrix result(n, n);
  ci::JointVector column(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const ci::JointVector unit = ci::JointVector::Unit(n, i);
    projector.project_dynamic(jacobian, mass, lambda, unit, column);
    result.col(i) = column;
  }
  return result;
}

}  // namespace law_reference
