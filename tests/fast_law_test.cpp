// The cycle's fast routines against the straightforward Eigen computations they replace: the
// tracking matrix square root against matrix_sqrt (SelfAdjointEigenSolver), the inertia-shaped
// damping without Lambda against inertia_shaped_damping(task_space_inertia()), the projector's
// unrolled L D L^T against an LLT solve, and the fixed-size Jacobian products against Eigen's.
//
// Tolerances. Both square roots are backward stable: each is the exact root of N + E with
// |E| ~ eps |N|, and such an E moves sqrt(N) by up to |E| / (2 sqrt(lambda_min)); relative to
// |sqrt(N)| = sqrt(lambda_max) that is eps sqrt(kappa) / 2 for each of them. The tests allow
// 64 eps sqrt(kappa) (the constant covers the 6x6 sums), and sqrt(eps) times a constant where N is
// singular (there the root of the round-off is undetermined to about sqrt(eps |N|)).

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <random>

#include "cartesian_impedance/core/math.hpp"
#include "support/law_reference.hpp"
#include "support/random_cases.hpp"

namespace ci = cartesian_impedance;
using namespace random_cases;

namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

ci::Matrix6d random_axes(std::mt19937& rng) {
  ci::Matrix6d a;
  for (Eigen::Index i = 0; i < a.size(); ++i) a.data()[i] = uniform(rng, -1, 1);
  return Eigen::HouseholderQR<ci::Matrix6d>(a).householderQ();
}

ci::Matrix6d compose(const ci::Matrix6d& axes, const ci::Vector6d& values) {
  const ci::Matrix6d m = axes * values.asDiagonal() * axes.transpose();
  return 0.5 * (m + m.transpose());
}

// Eigenvalues spread log-uniformly over [1, kappa] times a random scale, some of them repeated.
ci::Vector6d spread_values(std::mt19937& rng, double kappa, bool repeated) {
  const double scale = std::pow(10.0, uniform(rng, -2, 4));
  ci::Vector6d values;
  for (int i = 0; i < 6; ++i) values[i] = scale * std::pow(kappa, uniform(rng, 0, 1));
  values[0] = scale;
  values[1] = scale * kappa;
  if (repeated) values[3] = values[4] = values[5];
  return values;
}

double relative_difference(const ci::Matrix6d& a, const ci::Matrix6d& b) {
  return (a - b).norm() / std::max(b.norm(), 1e-300);
}

double tolerance(double kappa) {
  return 64 * kEps * std::sqrt(kappa);
}

}  // namespace

// A fresh tracker (Eigen's solver decides) and a second call on the same matrix (Jacobi from the
// first call's axes) give matrix_sqrt() on well and ill conditioned matrices, with and without
// repeated eigenvalues.
TEST(TrackingMatrixSqrt, AgreesWithEigenOnRandomMatrices) {
  std::mt19937 rng(21);
  for (double kappa : {1.0, 10.0, 1e4, 1e8}) {
    for (bool repeated : {false, true}) {
      for (int trial = 0; trial < 50; ++trial) {
        const ci::Matrix6d n = compose(random_axes(rng), spread_values(rng, kappa, repeated));
        const ci::Matrix6d expected = ci::matrix_sqrt(n);
        ci::TrackingMatrixSqrt tracker;
        EXPECT_LE(relative_difference(ci::matrix_sqrt(n, tracker), expected), tolerance(kappa));
        if (kappa > 1.0) {
          EXPECT_EQ(tracker.sweeps(), -1);  // nothing to track yet
        }
        EXPECT_LE(relative_difference(ci::matrix_sqrt(n, tracker), expected), tolerance(kappa))
            << "kappa " << kappa << (repeated ? " repeated" : "");
        EXPECT_GE(tracker.sweeps(), 0);
      }
    }
  }
}

// Singular and zero matrices (a stiffness with some axes at zero, teaching mode).
TEST(TrackingMatrixSqrt, AgreesWithEigenOnSingularMatrices) {
  std::mt19937 rng(22);
  ci::TrackingMatrixSqrt tracker;
  EXPECT_EQ(ci::matrix_sqrt(ci::Matrix6d::Zero(), tracker), ci::Matrix6d::Zero());
  EXPECT_EQ(ci::matrix_sqrt(ci::Matrix6d::Zero(), tracker), ci::Matrix6d::Zero());
  for (int rank : {1, 3, 5}) {
    for (int trial = 0; trial < 30; ++trial) {
      ci::Vector6d values = spread_values(rng, 100.0, false);
      values.tail(6 - rank).setZero();
      const ci::Matrix6d n = compose(random_axes(rng), values);
      const ci::Matrix6d expected = ci::matrix_sqrt(n);
      for (int call = 0; call < 3; ++call) {
        EXPECT_LE(relative_difference(ci::matrix_sqrt(n, tracker), expected), 64 * std::sqrt(kEps))
            << "rank " << rank;
      }
    }
  }
}

// A slowly turning and stretching matrix, as the normalised stiffness is along a motion (steps of
// 1e-3, 1e-5 and 1e-7 relative): every call agrees with Eigen, and the tracker never falls back to
// Eigen's solver, needs few sweeps, and at the slower steps mostly none, also through a crossing
// of two eigenvalues. Then sudden jumps to
// unrelated matrices: the fallback takes them, and the result is still right.
TEST(TrackingMatrixSqrt, FollowsSlowlyChangingMatricesAndSurvivesJumps) {
  std::mt19937 rng(23);
  for (double step : {1e-3, 1e-5, 1e-7}) {
    const ci::Matrix6d base = random_axes(rng);
    Eigen::Matrix<double, 6, 6> generator;  // skew-symmetric: exp(t G) turns the axes
    for (Eigen::Index i = 0; i < generator.size(); ++i) generator.data()[i] = uniform(rng, -1, 1);
    generator = 0.5 * (generator - generator.transpose()).eval();
    const ci::Vector6d start = spread_values(rng, 1e3, false);
    ci::TrackingMatrixSqrt tracker;
    int fallbacks = 0, max_sweeps = 0, without_sweep = 0, refined = 0;
    double worst = 0.0;
    for (int k = 0; k < 2000; ++k) {
      const double t = step * k;
      // exp(t G) to round-off through its eigen-decomposition would be circular; a Cayley
      // transform is orthogonal too and turns just as smoothly.
      const ci::Matrix6d half = 0.5 * t * generator;
      const ci::Matrix6d turn = (ci::Matrix6d::Identity() - half)
                                    .partialPivLu()
                                    .solve(ci::Matrix6d(ci::Matrix6d::Identity() + half));
      ci::Vector6d values = start;
      values[2] = start[3] * std::exp(5 * step * (k - 1000));  // crosses values[3] at k = 1000
      const ci::Matrix6d n = compose(base * turn, values);
      const double kappa = values.maxCoeff() / values.minCoeff();
      worst = std::max(worst, relative_difference(ci::matrix_sqrt(n, tracker), ci::matrix_sqrt(n)) /
                                  tolerance(kappa));
      if (k > 0) {
        fallbacks += tracker.sweeps() < 0;
        max_sweeps = std::max(max_sweeps, tracker.sweeps());
        without_sweep += tracker.sweeps() == 0;
        refined += tracker.sweeps() == 0 && tracker.refinements() > 0;
      }
    }
    EXPECT_LE(worst, 1.0) << "step " << step;
    EXPECT_EQ(fallbacks, 0) << "step " << step;
    EXPECT_LE(max_sweeps, step > 1e-4 ? 3 : 2) << "step " << step;
    // Slow turning mostly needs no rotation at all: the last axes still nearly diagonalise, and
    // Newton steps finish (the accuracy above includes those calls).
    if (step < 1e-4) {
      EXPECT_GE(without_sweep, step < 1e-6 ? 1900 : 500) << "step " << step;
      EXPECT_GE(refined, step < 1e-6 ? 1900 : 500) << "step " << step;
    }
    // Orthonormal axes after 2000 calls' worth of rotations.
    EXPECT_LE((tracker.axes().transpose() * tracker.axes() - ci::Matrix6d::Identity()).norm(),
              16 * kEps);
  }
  ci::TrackingMatrixSqrt tracker;
  for (int k = 0; k < 40; ++k) {
    const ci::Matrix6d n = compose(random_axes(rng), spread_values(rng, 1e3, k % 3 == 0));
    EXPECT_LE(relative_difference(ci::matrix_sqrt(n, tracker), ci::matrix_sqrt(n)), tolerance(1e3));
  }
}

namespace {

struct DynamicsCase {
  ci::Jacobian jacobian;
  ci::JointMatrix mass;
  ci::Matrix6d stiffness;
  ci::Vector6d zeta;
  Eigen::Matrix3d rotation;
};

DynamicsCase random_dynamics(int n, std::mt19937& rng, double mass_condition) {
  DynamicsCase c;
  c.jacobian = random_jacobian(n, rng);
  ci::JointMatrix a(n, n);
  for (Eigen::Index i = 0; i < a.size(); ++i) a.data()[i] = uniform(rng, -1, 1);
  const Eigen::HouseholderQR<ci::JointMatrix> qr(a);
  const ci::JointMatrix axes = qr.householderQ();
  ci::JointVector values(n);
  for (int i = 0; i < n; ++i) values[i] = std::pow(mass_condition, uniform(rng, 0, 1));
  c.mass = axes * values.asDiagonal() * axes.transpose();
  c.mass = (0.5 * (c.mass + c.mass.transpose())).eval();
  c.stiffness = random_stiffness(rng);
  for (int i = 0; i < 6; ++i) c.zeta[i] = uniform(rng, 0.3, 2.0);
  c.rotation = random_rotation(rng).toRotationMatrix();
  return c;
}

// The condition number of A = J M^-1 J^T + lambda^2 I, which bounds how far the two routes'
// round-off (inverting A once or twice) can take them apart.
double condition(const DynamicsCase& c, double lambda) {
  Eigen::MatrixXd a = c.jacobian * c.mass.llt().solve(c.jacobian.transpose());
  a.diagonal().array() += lambda * lambda;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(a);
  return solver.eigenvalues().maxCoeff() / solver.eigenvalues().minCoeff();
}

}  // namespace

// D without Lambda against inertia_shaped_damping(task_space_inertia()): base and end-effector
// frames, uniform and per-axis zeta (which makes D depend on the factor being the lower Cholesky
// one of Lambda), 6, 7 and 9 joints, a well and a badly conditioned M. The old route inverts A and
// factors the inverse: its error grows like eps cond(A), which sets the tolerance.
TEST(InertiaShapedDamping, AgreesWithTheRouteThroughLambda) {
  std::mt19937 rng(24);
  for (int n : {6, 7, 9}) {
    for (double mass_condition : {10.0, 1e4}) {
      for (int trial = 0; trial < 40; ++trial) {
        DynamicsCase c = random_dynamics(n, rng, mass_condition);
        if (trial % 2 == 0) c.zeta.setConstant(0.8);
        const double lambda = trial % 3 == 0 ? 0.0 : 0.05;
        const bool end_effector = trial % 4 < 2;
        ci::Matrix6d inertia;
        ASSERT_TRUE(law_reference::task_space_inertia(c.jacobian, c.mass, lambda, inertia));
        if (end_effector) {
          const ci::Matrix6d rotation6 = ci::block_rotation(c.rotation);
          inertia = rotation6.transpose() * inertia * rotation6;
        }
        const ci::Matrix6d expected =
            law_reference::inertia_shaped_damping(c.stiffness, c.zeta, inertia);
        ci::InertiaShapedDamping fast;
        ci::Matrix6d damping;
        for (int call = 0; call < 2; ++call) {  // the fallback, then Jacobi from its axes
          ASSERT_TRUE(fast.compute(c.jacobian, c.mass, lambda, end_effector ? &c.rotation : nullptr,
                                   c.stiffness, c.zeta, damping));
          EXPECT_LE(relative_difference(damping, expected), 16 * kEps * condition(c, lambda))
              << "n " << n << " cond(M) " << mass_condition << " trial " << trial;
        }
        EXPECT_EQ(damping, damping.transpose());
      }
    }
  }
}

// A mass matrix that is not positive definite, or not finite, is refused like task_space_inertia
// refuses it.
TEST(InertiaShapedDamping, RefusesAnIndefiniteMass) {
  std::mt19937 rng(25);
  DynamicsCase c = random_dynamics(7, rng, 10.0);
  ci::InertiaShapedDamping fast;
  ci::Matrix6d damping;
  ci::Matrix6d inertia;
  c.mass(3, 3) = -1.0;
  EXPECT_FALSE(law_reference::task_space_inertia(c.jacobian, c.mass, 0.05, inertia));
  EXPECT_FALSE(fast.compute(c.jacobian, c.mass, 0.05, nullptr, c.stiffness, c.zeta, damping));
  c.mass(3, 3) = std::nan("");
  EXPECT_FALSE(fast.compute(c.jacobian, c.mass, 0.05, nullptr, c.stiffness, c.zeta, damping));
}

// The fixed-size column loops against Eigen's products, and the projector (unrolled 6x6 L D L^T)
// against N tau_0 from an LLT solve, for 6 to 16 joints. The products differ in summation order
// only (a few ulps of the terms); the projector by eps cond(J J^T + lambda^2 I) at most.
TEST(FastProducts, AgreeWithEigen) {
  std::mt19937 rng(26);
  ci::NullspaceProjector projector;
  for (int n = 1; n <= ci::kMaxJoints; ++n) {
    const ci::Jacobian jacobian = random_jacobian(n, rng);
    const ci::JointVector x = random_joints(n, rng, 2.0);
    const ci::Vector6d v = ci::Vector6d::Random();
    ci::Vector6d jx;
    ci::JointVector jtv;
    ci::jacobian_times(jacobian, x, jx);
    ci::jacobian_transpose_times(jacobian, v, jtv);
    const ci::Vector6d jx_expected = jacobian * x;
    const ci::JointVector jtv_expected = jacobian.transpose() * v;
    EXPECT_LE((jx - jx_expected).norm(), 8 * kEps * jacobian.norm() * x.norm());
    EXPECT_LE((jtv - jtv_expected).norm(), 8 * kEps * jacobian.norm() * v.norm());
    if (n < 6) continue;
    const double lambda = 0.05;
    Eigen::MatrixXd gram = jacobian * jacobian.transpose();
    gram.diagonal().array() += lambda * lambda;
    const Eigen::VectorXd solved = gram.llt().solve(Eigen::VectorXd(jacobian * x));
    const Eigen::VectorXd expected = x - jacobian.transpose() * solved;
    ci::JointVector projected;
    projector.project(jacobian, lambda, x, projected);
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(gram);
    const double kappa = solver.eigenvalues().maxCoeff() / solver.eigenvalues().minCoeff();
    EXPECT_LE((projected - expected).norm(), 16 * kEps * kappa * x.norm()) << "n " << n;
  }
}
